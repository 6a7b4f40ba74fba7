//! Whole-scenario performance (issue 3's goals): the seven configurations'
//! estimators of record ([`rollcal::estimator::estimate`], the default
//! multi-pass estimator) over the full paper scenario (5400 periods), run in
//! parallel on the machine's cores as `host-sim paper` does. The data are
//! the recorded paper stream (noise seed 1, `tests/data/paper_seed1.bin`,
//! see `tests/it/support`).
//!
//! The other benchmark of the group, one M2-ps Monte Carlo run (simulation
//! and estimator, `paper_scenario/m2ps_montecarlo_run`), needs the truth
//! simulator and lives in `host-sim/benches/paper_scenario.rs`; both:
//!
//! `cargo bench --workspace --bench paper_scenario`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::SVector;
use rayon::prelude::*;
use rollcal::estimator::{estimate, EstimatorOptions, LogRecord, SliceLog};
use rollcal::models::{ConfigId, Model};
use rollcal::wire::CalibratorConfig;
use rollcal::Options;

#[path = "../tests/it/support/mod.rs"]
mod support;

/// The estimator of record of configuration `M` over `records` from a cold
/// start; the failed updates of its last pass.
fn failed_updates<M: Model<N, Z>, const N: usize, const Z: usize>(
    settings: &CalibratorConfig,
    records: &[LogRecord<f64>],
) -> Option<usize> {
    let cfg = support::filter_config(settings, Options::default());
    let sigma0 = SVector::<f64, N>::repeat(settings.prior_sigma_rad);
    let mut storage = records.to_vec();
    let mut log = SliceLog::from_records(&mut storage);
    let (mut pass, mut failures) = (0, 0);
    estimate::<f64, M, N, Z, _, _>(
        &cfg,
        &SVector::zeros(),
        &sigma0,
        &mut log,
        &EstimatorOptions::default(),
        |ev| {
            if ev.pass != pass {
                (pass, failures) = (ev.pass, 0);
            }
            failures += usize::from(ev.result.is_err());
        },
    )
    .ok()
    .map(|_| failures)
}

fn bench(c: &mut Criterion) {
    let (settings, samples) = support::paper_stream();
    let records: Vec<LogRecord<f64>> = samples.iter().map(support::log_record).collect();
    let mut g = c.benchmark_group("paper_scenario");
    g.sample_size(10);
    g.bench_function("all_seven_configs_parallel", |b| {
        b.iter(|| {
            let ok = ConfigId::ALL
                .par_iter()
                .map(|&id| {
                    rollcal::with_config!(id, |M, N, Z| failed_updates::<M, N, Z>(
                        &settings, &records
                    ))
                })
                .filter(|r| matches!(r, Some(0)))
                .count();
            assert_eq!(ok, 7, "every configuration runs without failed updates");
            black_box(ok)
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
