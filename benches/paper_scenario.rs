//! Whole-scenario performance (issue 3's goals): the seven configurations'
//! estimators over the full paper scenario (5400 periods, the default
//! multi-pass estimator), run in parallel on the machine's cores as
//! `host-sim paper` does, and one M2-ps Monte Carlo run (simulation and
//! estimator), the unit of `host-sim montecarlo`.
//!
//! `cargo bench --bench paper_scenario`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use host_sim::runner::{run_filter, Estimator};
use host_sim::scenario::Scenario;
use host_sim::truth::{simulate, SimOptions};
use rayon::prelude::*;
use rollcal::models::ConfigId;

fn options(seed: u64) -> SimOptions {
    SimOptions {
        seed,
        noise: true,
        earth_rate: true,
    }
}

fn bench(c: &mut Criterion) {
    let scenario = Scenario::paper();
    let sim = simulate(&scenario, options(1));
    let mut g = c.benchmark_group("paper_scenario");
    g.sample_size(10);
    g.bench_function("all_seven_configs_parallel", |b| {
        b.iter(|| {
            let ok = ConfigId::ALL
                .par_iter()
                .map(|&id| {
                    run_filter(id, &scenario, &sim, true, Estimator::default(), None, false)
                        .map(|r| r.failures.len())
                })
                .filter(|r| matches!(r, Ok(0)))
                .count();
            assert_eq!(ok, 7, "every configuration runs without failed updates");
            black_box(ok)
        })
    });
    g.bench_function("m2ps_montecarlo_run", |b| {
        b.iter(|| {
            let sim = simulate(&scenario, options(2));
            let r = run_filter(
                ConfigId::M2Ps,
                &scenario,
                &sim,
                true,
                Estimator::default(),
                None,
                false,
            );
            black_box(r.map(|r| r.passes))
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
