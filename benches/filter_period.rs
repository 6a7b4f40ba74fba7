//! Time of one filter period (`Filter::step`: predict + update) in f64, for
//! M1-pa and M2-ps: the first pass of the default estimator (EKF with the
//! second-order innovation covariance, `default`), its second, linearised
//! pass about a nominal trajectory (`linearised`), and a plain EKF (`plain`).
//!
//! The data are the paper scenario from the host-sim truth simulator (noisy,
//! Earth rate on, seed 1). Each filter starts cold (zero state, prior σ from
//! the scenario, 1°) and is first warmed up over `WARM_UP` periods, every
//! step of which must succeed, so the benchmark measures a converging filter
//! rather than the first steps. The timed loop then steps one filter through
//! the following samples in order; at the end of the run it restarts from a
//! copy of the warmed-up filter (the reset is one memcpy every few thousand
//! periods). Every timed step must succeed too: errors are counted and
//! checked after each benchmark.
//!
//! `cargo bench --bench filter_period -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use host_sim::runner::filter_config;
use host_sim::scenario::{Scenario, DEG};
use host_sim::truth::{simulate, PeriodSample, SimOptions};
use nalgebra::SVector;
use rollcal::ekf::{M1PaFilter, M2PsFilter};
use rollcal::models::Model;
use rollcal::{Filter, Observation, Options};

/// Periods processed before timing starts.
const WARM_UP: usize = 600;

fn observation(s: &PeriodSample) -> Observation<f64> {
    Observation {
        accel_mean: s.accel_mean,
        gimbal: Some(s.gimbal),
    }
}

/// A cold-started filter stepped over the first `WARM_UP` samples.
fn warmed_up<M: Model<N, Z>, const N: usize, const Z: usize>(
    scenario: &Scenario,
    samples: &[PeriodSample],
    options: Options,
    linearised: bool,
) -> Filter<f64, M, N, Z> {
    let cfg = filter_config(scenario, true, options);
    let sigma0 = SVector::<f64, N>::repeat(scenario.prior.sigma_deg * DEG);
    let mut f = Filter::<f64, M, N, Z>::new(cfg, SVector::zeros(), sigma0)
        .expect("filter configuration is valid");
    if linearised {
        // The per-period cost does not depend on where the nominal is.
        f.set_nominal(Some(SVector::zeros()));
    }
    for s in samples.iter().take(WARM_UP) {
        if let Err(e) = f.step(&s.dtheta_cmd, s.dt, &observation(s)) {
            panic!("warm-up step {} failed: {e:?}", s.k);
        }
    }
    assert_eq!(f.updates() as usize, WARM_UP);
    assert!(f
        .state()
        .iter()
        .chain(f.covariance().iter())
        .all(|v| v.is_finite()));
    f
}

fn bench_period<M: Model<N, Z> + Clone, const N: usize, const Z: usize>(
    c: &mut Criterion,
    name: &str,
    scenario: &Scenario,
    samples: &[PeriodSample],
    options: Options,
    linearised: bool,
) {
    let warm = warmed_up::<M, N, Z>(scenario, samples, options, linearised);
    let timed = samples
        .get(WARM_UP..)
        .expect("the run is longer than the warm-up");
    assert!(!timed.is_empty());
    let mut f = warm.clone();
    let mut next = 0;
    let mut steps = 0u64;
    let mut failures = 0u64;
    c.benchmark_group("period").bench_function(name, |b| {
        b.iter(|| {
            let s = match timed.get(next) {
                Some(s) => s,
                None => {
                    f = warm.clone();
                    next = 0;
                    &timed[0]
                }
            };
            next += 1;
            steps += 1;
            let r = f.step(
                black_box(&s.dtheta_cmd),
                black_box(s.dt),
                black_box(&observation(s)),
            );
            failures += u64::from(r.is_err());
            black_box(r)
        })
    });
    assert_eq!(
        failures, 0,
        "{name}: {failures} of {steps} timed steps failed"
    );
}

fn filter_period(c: &mut Criterion) {
    let scenario = Scenario::paper();
    let sim = simulate(
        &scenario,
        SimOptions {
            seed: 1,
            noise: true,
            earth_rate: true,
        },
    );
    let samples = &sim.samples;
    for (label, options, linearised) in [
        ("default", Options::default(), false),
        ("linearised", Options::default(), true),
        ("plain", Options::plain(), false),
    ] {
        bench_period::<rollcal::models::M1Pa, 12, 3>(
            c,
            &format!("m1pa/{label}"),
            &scenario,
            samples,
            options,
            linearised,
        );
        bench_period::<rollcal::models::M2Ps, 18, 6>(
            c,
            &format!("m2ps/{label}"),
            &scenario,
            samples,
            options,
            linearised,
        );
    }
}

// The aliases the benchmark is about; checked here so a change to them
// (dimensions or model) fails to compile rather than silently benchmarking
// another configuration.
const _: fn(M1PaFilter<f64>) -> Filter<f64, rollcal::models::M1Pa, 12, 3> = |f| f;
const _: fn(M2PsFilter<f64>) -> Filter<f64, rollcal::models::M2Ps, 18, 6> = |f| f;

criterion_group!(benches, filter_period);
criterion_main!(benches);
