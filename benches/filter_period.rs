//! Time of one filter period (`Filter::step`: predict + update) in f64, for
//! M1-pa and M2-ps: the first pass of the default estimator (EKF with the
//! second-order innovation covariance, `default`), its second, linearised
//! pass about a nominal trajectory (`linearised`), and a plain EKF (`plain`).
//!
//! The data are the paper scenario recorded by the host-sim truth simulator
//! (noisy, Earth rate on, seed 1; `tests/data/paper_seed1.bin`, decoded with
//! the library's wire decoder, see `tests/it/support`). Each filter starts cold (zero state, prior σ from
//! the scenario, 1°) and is first warmed up over `WARM_UP` periods, every
//! step of which must succeed, so the benchmark measures a converging filter
//! rather than the first steps. The timed loop then steps one filter through
//! the following samples in order; at the end of the run it restarts from a
//! copy of the warmed-up filter (the reset is one memcpy every few thousand
//! periods). Every timed step must succeed too: errors are counted and
//! checked after each benchmark.
//!
//! The same group holds the reference the host goals are set against,
//! `dense/18x6` and `dense/12x3`: the naive dense covariance arithmetic of
//! one period of that size in static nalgebra f64 (dense `Φ P Φᵀ + Q`, `S`,
//! its Cholesky factor, the gain, the Joseph form, symmetrisation), on
//! fixed well-conditioned matrices; no model evaluation.
//!
//! The full models `m1pa-full/linearised` (48 states) and
//! `m2ps-full/linearised` (54: the installation states and the 36
//! instrument states, those of the errors that wander included) run on the
//! same stream with the default instrument priors (docs/model.md
//! §Instrument errors), beside `dense/48x3` and `dense/54x6`.
//!
//! `cargo bench --bench filter_period -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::{SVector, Vector3};
use rollcal::ekf::{M1PaFilter, M2PsFilter};
use rollcal::models::{Group, Model};
use rollcal::wire::CalibratorConfig;
use rollcal::{Filter, Observation, Options};

mod dense;
#[path = "../tests/it/support/mod.rs"]
mod support;

/// Periods processed before timing starts.
const WARM_UP: usize = 600;

/// One recorded period in f64.
struct PeriodSample {
    k: u32,
    dt: f64,
    dtheta_cmd: Vector3<f64>,
    obs: Observation<f64>,
}

fn observation(s: &PeriodSample) -> Observation<f64> {
    s.obs
}

/// The prior σ of every state of `M`: `angle_rad` on the installation
/// states, the default instrument priors (docs/model.md §Instrument
/// errors: 1 °/h, 1 °/h/g, 2000 ppm,
/// 1000 µg, 1000 ppm, in rad/s, rad/s/g, 1, g, 1) on those of the full
/// model.
fn prior<M: Model<N, Z>, const N: usize, const Z: usize>(angle_rad: f64) -> SVector<f64, N> {
    let deg_h = 1f64.to_radians() / 3600.0;
    SVector::from_iterator(M::states().iter().map(|s| match s.group {
        Group::GyroDrift | Group::GyroGDrift => deg_h,
        Group::GyroScale => 2e-3,
        Group::AccelBias | Group::AccelScale => 1e-3,
        _ => angle_rad,
    }))
}

/// A cold-started filter stepped over the first `WARM_UP` samples.
fn warmed_up<M: Model<N, Z>, const N: usize, const Z: usize>(
    settings: &CalibratorConfig,
    samples: &[PeriodSample],
    options: Options,
    linearised: bool,
) -> Filter<f64, M, N, Z> {
    let cfg = support::filter_config(settings, options);
    let sigma0 = prior::<M, N, Z>(settings.prior_sigma_rad);
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
    settings: &CalibratorConfig,
    samples: &[PeriodSample],
    options: Options,
    linearised: bool,
) {
    let warm = warmed_up::<M, N, Z>(settings, samples, options, linearised);
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

fn bench_dense<const N: usize, const Z: usize>(c: &mut Criterion, name: &str) {
    let (phi, p, q, h, r) = dense::inputs::<N, Z>();
    c.benchmark_group("period").bench_function(name, |b| {
        b.iter(|| {
            dense::period(
                black_box(&phi),
                black_box(&p),
                black_box(&q),
                black_box(&h),
                black_box(&r),
            )
        })
    });
}

fn filter_period(c: &mut Criterion) {
    bench_dense::<18, 6>(c, "dense/18x6");
    bench_dense::<12, 3>(c, "dense/12x3");
    bench_dense::<54, 6>(c, "dense/54x6");
    bench_dense::<48, 3>(c, "dense/48x3");
    let (settings, stream) = support::paper_stream();
    let samples: &[PeriodSample] = &stream
        .iter()
        .map(|s| {
            let (dt, dtheta_cmd) = support::period(s);
            PeriodSample {
                k: s.seq,
                dt,
                dtheta_cmd,
                obs: support::observation(s),
            }
        })
        .collect::<Vec<_>>();
    for (label, options, linearised) in [
        ("default", Options::default(), false),
        // Without the NIS gate: linearised about the zero state the model
        // error (≈ 0.3° of true errors, second-order terms ≈ 30× the noise)
        // gives NIS ≫ 30 and the default gate refuses the warm-up's third
        // update; a refused step skips the covariance update and would be
        // timed cheaper. The gate is one comparison per step.
        (
            "linearised",
            Options {
                nis_gate: 0.0,
                ..Options::default()
            },
            true,
        ),
        ("plain", Options::plain(), false),
    ] {
        bench_period::<rollcal::models::M1Pa, 12, 3>(
            c,
            &format!("m1pa/{label}"),
            &settings,
            samples,
            options,
            linearised,
        );
        bench_period::<rollcal::models::M2Ps, 18, 6>(
            c,
            &format!("m2ps/{label}"),
            &settings,
            samples,
            options,
            linearised,
        );
        // The full models (the installation states and the instruments'
        // 36 states), on the same stream: their linearised pass only. The
        // first pass of the full models from a zero start may refuse
        // updates at the NIS gate on this stream (M1-pa: 1 of 5400,
        // `host-sim run --config M1-pa --errors full --passes 1`), and a
        // refused step would be timed cheaper.
        if label != "linearised" {
            continue;
        }
        bench_period::<rollcal::models::M1PaFull, 48, 3>(
            c,
            &format!("m1pa-full/{label}"),
            &settings,
            samples,
            options,
            linearised,
        );
        bench_period::<rollcal::models::M2PsFull, 54, 6>(
            c,
            &format!("m2ps-full/{label}"),
            &settings,
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
