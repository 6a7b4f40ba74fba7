//! Convergence from a zero start (docs/model.md §Estimator): the estimator ends consistent
//! and near the information limit on the paper's scenario and on others.
//!
//! The σ bounds are about 2× the information limit (issue 2); a filter far
//! above them, or with larger errors, has a wrong model or a wrong filter.

use host_sim::analysis::runner::{expected_observable, run_filter, Estimator, RunResult};
use host_sim::sim::scenario::{Scenario, ARCSEC, DEG};
use host_sim::sim::truth::{simulate, SimOptions};
use rollcal::models::{ConfigId, Group};

fn run(id: ConfigId, scenario: &Scenario, seed: u64) -> RunResult {
    let sim = simulate(
        scenario,
        SimOptions {
            seed,
            noise: true,
            earth_rate: true,
        },
    );
    let r = run_filter(id, scenario, &sim, true, Estimator::default(), None, false).unwrap();
    // The NIS gate (30) refuses a clean update of the last pass with
    // probability 4e-5 (χ² with 6 degrees of freedom): allowed, but rare;
    // any other failure is not.
    let gated = r
        .failures
        .iter()
        .filter(|(_, e)| *e == rollcal::ekf::Error::Gated)
        .count();
    assert!(
        r.failures.len() == gated && gated * 1000 <= r.nis.len(),
        "{id} seed {seed}: failed updates {:?}",
        &r.failures[..r.failures.len().min(3)]
    );
    r
}

fn group(name: &str) -> Group {
    Group::from_name(name).unwrap_or(Group::Attitude)
}

/// The σ bound (″) of issue 2 for a claimed state.
fn sigma_bound(id: ConfigId, group: &str) -> f64 {
    match group {
        "thaT" => 0.03,
        "thaC" => 0.8,
        "thgC" | "thgT" if id == ConfigId::M2Ps => 4.0,
        "thgC" | "thgT" => 6.0,
        "lam" => 1.0,
        _ => f64::INFINITY,
    }
}

/// Every claimed state within 4σ and under its σ bound; returns the worst ratio.
fn check_converged(r: &RunResult, seed: u64, bounds: bool) -> f64 {
    let mut worst: f64 = 0.0;
    for s in r
        .states
        .iter()
        .filter(|s| expected_observable(r.config, s.name, group(s.group)))
    {
        let ratio = s.ratio();
        worst = worst.max(ratio);
        assert!(
            ratio <= 4.0,
            "{} seed {seed}: {} error {:.4}″ = {ratio:.2}σ (σ {:.4}″)",
            r.config,
            s.name,
            s.error() / ARCSEC,
            s.sigma_rad / ARCSEC
        );
        if bounds {
            let b = sigma_bound(r.config, s.group);
            assert!(
                s.sigma_rad / ARCSEC <= b,
                "{} seed {seed}: σ of {} is {:.4}″ > {b}″",
                r.config,
                s.name,
                s.sigma_rad / ARCSEC
            );
        }
    }
    worst
}

#[test]
fn firmware_configurations_converge_from_zero_on_the_paper_scenario() {
    let scenario = Scenario::paper();
    for id in [ConfigId::M1Pa, ConfigId::M4Pa, ConfigId::M2Ps] {
        // Seed 6: pass 1 ends 169″ off in M1-pa and one linearised pass is
        // not enough (it was 24σ off in θaT_3 before the passes iterated).
        for seed in [1, 2, 3, 4, 6] {
            let r = run(id, &scenario, seed);
            let worst = check_converged(&r, seed, true);
            eprintln!("{id} seed {seed}: worst |error|/σ {worst:.2}");
        }
    }
}

/// Not converged: σ stays above a third of the prior (a three-way tie leaves
/// 1/√3 ≈ 0.58 of it), and the estimate is still consistent with it.
fn check_not_converged(r: &RunResult, names: &[&str], prior: f64) {
    for s in r.states.iter().filter(|s| names.contains(&s.name)) {
        assert!(
            s.sigma_rad > prior / 3.0,
            "{}: {} σ {:.1}″ should stay large",
            r.config,
            s.name,
            s.sigma_rad / ARCSEC
        );
        assert!(
            s.ratio() <= 4.0,
            "{}: {} error {:.2}σ",
            r.config,
            s.name,
            s.ratio()
        );
    }
}

#[test]
fn ps_frame_configurations_estimate_only_the_non_orthogonalities() {
    let scenario = Scenario::paper();
    let prior = scenario.prior.sigma_deg * DEG;
    for id in [ConfigId::M1Ps, ConfigId::M3Ps, ConfigId::M4Ps] {
        let r = run(id, &scenario, 1);
        for s in r
            .states
            .iter()
            .filter(|s| s.group == "thgT" || s.group == "thaT")
        {
            assert!(s.ratio() <= 4.0, "{id}: {} at {:.2}σ", s.name, s.ratio());
            let b = sigma_bound(ConfigId::M1Pa, s.group);
            assert!(
                s.sigma_rad / ARCSEC <= b,
                "{id}: σ of {} {:.3}″ > {b}″",
                s.name,
                s.sigma_rad / ARCSEC
            );
        }
        let misalignments: Vec<&str> = r
            .states
            .iter()
            .filter(|s| s.group == "thgC" || s.group == "thaC")
            .map(|s| s.name)
            .collect();
        assert_eq!(misalignments.len(), 6);
        check_not_converged(&r, &misalignments, prior);
    }
}

#[test]
fn m3_pa_estimates_the_instruments_but_not_the_base() {
    let scenario = Scenario::paper();
    let r = run(ConfigId::M3Pa, &scenario, 1);
    check_converged(&r, 1, true);
    check_not_converged(
        &r,
        &[
            "lam_x",
            "lam_y",
            "lam_z",
            "thA_alpha",
            "thA_beta",
            "thA_gamma",
        ],
        scenario.prior.sigma_deg * DEG,
    );
}

#[test]
fn other_scenarios_converge_too() {
    for file in ["reordered-fast.toml", "southern-slow.toml"] {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../scenarios")
            .join(file);
        let scenario = Scenario::from_file(&path).unwrap();
        let prior = scenario.prior.sigma_deg * DEG;
        for id in [ConfigId::M1Pa, ConfigId::M4Pa, ConfigId::M2Ps] {
            let r = run(id, &scenario, 7);
            let worst = check_converged(&r, 7, false);
            // Observable in practice (docs/model.md §Observability): σ below 1 % of the prior.
            for s in r
                .states
                .iter()
                .filter(|s| expected_observable(id, s.name, group(s.group)))
            {
                assert!(
                    s.sigma_rad < 0.01 * prior,
                    "{file} {id}: σ of {} {:.2}″",
                    s.name,
                    s.sigma_rad / ARCSEC
                );
            }
            eprintln!("{file} {id}: worst |error|/σ {worst:.2}");
        }
    }
}

#[test]
fn filter_sigma_is_at_the_cramer_rao_bound() {
    let scenario = Scenario::paper();
    for id in [ConfigId::M1Pa, ConfigId::M2Ps] {
        let sim = simulate(
            &scenario,
            SimOptions {
                seed: 5,
                noise: true,
                earth_rate: true,
            },
        );
        let r = run_filter(id, &scenario, &sim, true, Estimator::default(), None, false).unwrap();
        let crlb = host_sim::analysis::runner::crlb_sigma(id, &scenario, &sim, true).unwrap();
        for (s, c) in r.states.iter().zip(&crlb) {
            if expected_observable(id, s.name, group(s.group)) {
                let ratio = s.sigma_rad / c;
                assert!(
                    (0.9..=1.1).contains(&ratio),
                    "{id}: σ/σ_CRLB of {} is {ratio:.3}",
                    s.name
                );
            }
        }
    }
}
