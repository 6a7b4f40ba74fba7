//! Whole-scenario performance (issue 3's goals), the part that needs the
//! truth simulator: one M2-ps Monte Carlo run (simulation and estimator),
//! the unit of `host-sim montecarlo`. The seven configurations' estimators
//! over the paper scenario (`paper_scenario/all_seven_configs_parallel`)
//! are the root crate's `benches/paper_scenario.rs`; both:
//!
//! `cargo bench --workspace --bench paper_scenario`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use host_sim::analysis::runner::{run_filter, Estimator};
use host_sim::sim::scenario::Scenario;
use host_sim::sim::truth::{simulate, SimOptions};
use rollcal::models::ConfigId;

fn bench(c: &mut Criterion) {
    let scenario = Scenario::paper();
    let mut g = c.benchmark_group("paper_scenario");
    g.sample_size(10);
    g.bench_function("m2ps_montecarlo_run", |b| {
        b.iter(|| {
            let sim = simulate(
                &scenario,
                SimOptions {
                    seed: 2,
                    noise: true,
                    earth_rate: true,
                },
            );
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
