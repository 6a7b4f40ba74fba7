//! Single precision, proven (docs/model.md §Estimator): the estimator of record with its
//! covariance arithmetic in f32 ends where the f64 one does, on every
//! shipped scenario, and its Monte Carlo sits on the Cramér–Rao bound.
//!
//! The figures of docs/estimator.md, "Single precision", are printed by
//! `cargo test --release -p host-sim --test it f32:: -- --nocapture`.

use std::path::Path;

use host_sim::analysis::montecarlo::monte_carlo;
use host_sim::analysis::runner::{Estimator, Precision, RunResult, SimulatedRun};
use host_sim::sim::scenario::Scenario;
use host_sim::sim::truth::{simulate, SimOptions};
use rollcal::models::{ConfigId, ErrorModel};

fn scenario(name: &str) -> Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios")
        .join(format!("{name}.toml"));
    Scenario::from_file(&path).expect("shipped scenario loads")
}

fn run(id: ConfigId, sc: &Scenario, errors: ErrorModel, precision: Precision) -> RunResult {
    let sim = simulate(
        sc,
        SimOptions {
            seed: 1,
            noise: true,
            earth_rate: sc.site.earth_rate,
        },
    );
    let est = Estimator {
        precision,
        ..Estimator::default()
    };
    SimulatedRun::new(id, sc, &sim, sc.site.earth_rate)
        .with_errors(errors)
        .run(est, None, false)
        .expect("the estimator runs")
}

/// Prints the table's header.
fn print_header() {
    println!(
        "| scenario | config | passes f64/f32 | max abs(x32 - x64)/sigma64 | sigma32/sigma64 |"
    );
    println!("|---|---|---|---|---|");
}

/// Prints the row of f64 run `a` against f32 run `b` and returns what is
/// off: a state more than 0.1σ from f64, or σ beyond 1.05× either way. A
/// torquer scale factor `kg` (full model) may be further apart only within
/// `f32::EPSILON`, f32's resolution of a scale factor (printed).
fn f32_off_f64(name: &str, id: ConfigId, a: &RunResult, b: &RunResult) -> Option<String> {
    let (mut dx, mut lo, mut hi) = (0.0_f64, f64::INFINITY, 0.0_f64);
    for (s64, s32) in a.states.iter().zip(&b.states) {
        let d = (s32.estimate_rad - s64.estimate_rad).abs();
        let r = s32.sigma_rad / s64.sigma_rad;
        (lo, hi) = (lo.min(r), hi.max(r));
        if s64.group == "kg" && d / s64.sigma_rad > 0.1 && d <= f64::from(f32::EPSILON) {
            println!(
                "  {name} {id} {}: {:.3} sigma = {:.3} ppm, within f32's resolution",
                s64.name,
                d / s64.sigma_rad,
                d * 1e6
            );
            continue;
        }
        dx = dx.max(d / s64.sigma_rad);
    }
    println!(
        "| {name} | {id} | {}/{} | {dx:.4} | {lo:.4}..{hi:.4} |",
        a.passes, b.passes
    );
    (!(dx <= 0.1 && hi <= 1.05 && lo >= 1.0 / 1.05))
        .then(|| format!("{name} {id}: {dx:.3} sigma, ratio {lo:.4}..{hi:.4}"))
}

#[test]
fn f32_ends_within_a_tenth_of_sigma_of_f64_on_every_scenario() {
    print_header();
    let mut bad = Vec::new();
    for name in ["paper", "reordered-fast", "southern-slow"] {
        let sc = scenario(name);
        for id in [ConfigId::M1Pa, ConfigId::M4Pa, ConfigId::M2Ps] {
            let errors = ErrorModel::Installation;
            let (a, b) = (
                run(id, &sc, errors, Precision::F64),
                run(id, &sc, errors, Precision::F32),
            );
            bad.extend(f32_off_f64(name, id, &a, &b));
        }
    }
    assert!(bad.is_empty(), "f32 off f64: {bad:?}");
}

#[test]
fn f32_monte_carlo_of_m2ps_is_at_the_bound_and_consistent() {
    let runs = 100;
    let est = Estimator {
        precision: Precision::F32,
        ..Estimator::default()
    };
    let mc = monte_carlo(
        ConfigId::M2Ps,
        ErrorModel::Installation,
        &Scenario::paper(),
        runs,
        est,
        &|_| {},
    )
    .unwrap();
    assert_eq!(mc.runs, runs);
    let block: Vec<_> = mc.states.iter().filter(|s| s.in_parameter_block).collect();
    assert_eq!(block.len(), 14, "12 instrument angles + lam_x, lam_z");
    let worst = block
        .iter()
        .map(|s| (s.rms_over_crlb, s.name))
        .fold((0.0, ""), |a, b| if b.0 > a.0 { b } else { a });
    println!(
        "f32 Monte Carlo, M2-ps, paper, {runs} runs: max RMS/sigma_CRLB {:.3} ({}), NEES {:.3} in [{:.3}, {:.3}], NIS {:.3} in [{:.3}, {:.3}]",
        worst.0,
        worst.1,
        mc.nees.mean,
        mc.nees.lower,
        mc.nees.upper,
        mc.nis.mean,
        mc.nis.lower,
        mc.nis.upper
    );
    assert!(
        worst.0 <= 1.1,
        "{}: RMS/sigma_CRLB = {:.3}",
        worst.1,
        worst.0
    );
    assert!(
        mc.nees.inside(),
        "NEES {:.3} outside [{:.3}, {:.3}]",
        mc.nees.mean,
        mc.nees.lower,
        mc.nees.upper
    );
}

/// The full model (issue 32 item 2) in f32 ends where the f64 one does:
/// M1-pa, M4-pa and M2-ps on the instrumented scenario and on the
/// designed full-model paths, every state (installation and instrument
/// errors) within 0.1σ, σ within 1.05×.
#[test]
fn f32_full_model_ends_within_a_tenth_of_sigma_of_f64() {
    print_header();
    let mut bad = Vec::new();
    for (name, ids) in [
        (
            "instrumented",
            &[ConfigId::M1Pa, ConfigId::M4Pa, ConfigId::M2Ps][..],
        ),
        ("designed-full-m1pa", &[ConfigId::M1Pa, ConfigId::M4Pa][..]),
        ("designed-full-m2ps", &[ConfigId::M2Ps][..]),
    ] {
        let sc = scenario(name);
        for &id in ids {
            let errors = ErrorModel::Full;
            let (a, b) = (
                run(id, &sc, errors, Precision::F64),
                run(id, &sc, errors, Precision::F32),
            );
            assert_eq!(a.states.len(), id.layout_with(errors).n());
            bad.extend(f32_off_f64(name, id, &a, &b));
        }
    }
    assert!(bad.is_empty(), "f32 off f64: {bad:?}");
}
