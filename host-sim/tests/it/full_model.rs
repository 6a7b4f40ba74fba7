//! The full model (installation errors followed by the instruments' 21
//! errors, docs/model.md §Full model) on the host: `run --errors full`
//! against the truth simulator's instrument errors and the Cramér–Rao
//! bound, a Monte Carlo of it, and the command line.

use crate::support;

use host_sim::analysis::montecarlo::monte_carlo;
use host_sim::analysis::runner::{Estimator, SimulatedRun};
use host_sim::sim::scenario::Scenario;
use host_sim::sim::truth::{simulate, SimOptions};
use rollcal::models::{ConfigId, ErrorModel, Group};

fn instrumented() -> Scenario {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/instrumented.toml"
    );
    Scenario::load(Some(std::path::Path::new(path))).unwrap()
}

/// The instrumented scenario and its noisy run of seed 1 with the Earth
/// rate.
fn instrumented_seed1() -> (Scenario, host_sim::sim::truth::Simulation) {
    let scenario = instrumented();
    let opts = SimOptions {
        seed: 1,
        noise: true,
        earth_rate: true,
    };
    let sim = simulate(&scenario, opts);
    (scenario, sim)
}

/// On the instrumented scenario (seed 1), the full model of M2-ps and M1-pa
/// ends with every non-attitude state within 4σ of the truth, σ within 5 %
/// of σ_CRLB, and the instrument truths those of docs/model.md §The instrumented
/// scenario.
#[test]
fn full_model_run_is_consistent_with_its_bound() {
    let (scenario, sim) = instrumented_seed1();
    for id in [ConfigId::M2Ps, ConfigId::M1Pa] {
        let run = SimulatedRun::new(id, &scenario, &sim, true).with_errors(ErrorModel::Full);
        let r = run.run(Estimator::default(), None, false).unwrap();
        let crlb = run.crlb().unwrap();
        assert_eq!(r.states.len(), id.layout_with(ErrorModel::Full).n());
        assert_eq!(r.states.len(), id.layout().n() + 36);
        for (s, c) in r.states.iter().zip(&crlb) {
            if s.info.group == Group::Attitude {
                continue;
            }
            assert!(s.ratio() <= 4.0, "{id} {}: |err|/σ {}", s.name, s.ratio());
            if *c == 0.0 {
                // Not estimated (no bias instability in this scenario).
                assert_eq!((s.sigma_rad, s.estimate_rad), (0.0, 0.0), "{id} {}", s.name);
                continue;
            }
            let q = s.sigma_rad / c;
            assert!((0.95..=1.05).contains(&q), "{id} {}: σ/σ_CRLB {q}", s.name);
        }
        let ba_y = r.states.iter().find(|s| s.name == "ba_y").unwrap();
        assert!(
            (ba_y.truth_rad * 1e6 + 20.0).abs() < 1e-9,
            "{}",
            ba_y.truth_rad
        );
        let kg_z = r.states.iter().find(|s| s.name == "kg_z").unwrap();
        assert!(
            (kg_z.truth_rad * 1e6 - 80.0).abs() < 1e-9,
            "{}",
            kg_z.truth_rad
        );
    }
}

/// The same run through the installation model alone is far off: the
/// instruments' errors, unmodelled, bias the installation estimates by
/// many σ (the reason for the full model).
#[test]
fn installation_model_is_biased_by_the_instrument_errors() {
    let (scenario, sim) = instrumented_seed1();
    let r = SimulatedRun::new(ConfigId::M2Ps, &scenario, &sim, true)
        .run(Estimator::default(), None, false)
        .unwrap();
    let worst = r
        .states
        .iter()
        .filter(|s| s.info.group == Group::ThetaAT)
        .map(|s| s.ratio())
        .fold(0.0, f64::max);
    assert!(worst > 20.0, "worst |err|/σ of θaT {worst}");
}

/// A 20-run Monte Carlo of the full M2-ps model on the instrumented
/// scenario: the parameter-block NEES and the NIS inside their 95 % bands,
/// the block's mean (RMS/σ_CRLB)² near 1 and the filter's σ on the bound.
#[test]
fn monte_carlo_of_the_full_model_is_consistent() {
    let mc = monte_carlo(
        ConfigId::M2Ps,
        ErrorModel::Full,
        &instrumented(),
        20,
        Estimator::default(),
        &|_| {},
    )
    .unwrap();
    assert!(mc.nees.inside(), "NEES {:?}", mc.nees);
    assert!(mc.nis.inside(), "NIS {:?}", mc.nis);
    let block: Vec<_> = mc.states.iter().filter(|s| s.in_parameter_block).collect();
    assert!(block.len() >= 30, "block of {} states", block.len());
    assert!(block.iter().any(|s| s.name == "Dg_zz"));
    let mean_sq = block.iter().map(|s| s.rms_over_crlb.powi(2)).sum::<f64>() / block.len() as f64;
    assert!((0.8..=1.2).contains(&mean_sq), "mean (RMS/CRLB)² {mean_sq}");
    for s in &block {
        let q = s.mean_sigma_rad / s.sigma_crlb_rad;
        assert!((0.95..=1.05).contains(&q), "{}: σ/σ_CRLB {q}", s.name);
    }
}

/// `run --errors full --json`: the installation states under `states` as
/// before, the 21 instrument states under `instruments` in their printed
/// units; a bad `--errors` and `--report` with the full model are one-line
/// errors.
#[test]
fn run_errors_full_on_the_command_line() {
    let dir = support::scratch("full-model-cli");
    let json = dir.join("r.json");
    let scenario = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/instrumented.toml"
    );
    let out = support::host_sim()
        .args([
            "run",
            "--config",
            "M1-pa",
            "--errors",
            "full",
            "--scenario",
            scenario,
        ])
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    support::assert_success(&out);
    let v = support::json_file(&json);
    assert_eq!(v["errors"], "full");
    assert_eq!(v["states"].as_array().unwrap().len(), 12);
    let inst = v["instruments"].as_array().unwrap();
    assert_eq!(inst.len(), 36);
    assert_eq!(inst[3]["name"], "Dgpa_xx");
    assert_eq!(inst[15]["unit"], "µg");
    assert!((inst[15]["truth"].as_f64().unwrap() - 30.0).abs() < 1e-9);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout
            .lines()
            .any(|l| l.starts_with("ka_z ") && l.contains(" ppm ")),
        "{stdout}"
    );

    let bad = support::host_sim()
        .args(["run", "--config", "M1-pa", "--errors", "some"])
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(support::stderr(&bad).contains("expected installation or full"));
    let first = support::host_sim()
        .args([
            "run", "--config", "M1-pa", "--errors", "full", "--passes", "1",
        ])
        .output()
        .unwrap();
    support::assert_success(&first);
    assert!(support::stderr(&first).contains("first pass alone is biased"));
    // The full model's report: every instrument group with its figure.
    let report = support::host_sim()
        .args(["run", "--config", "M1-pa", "--errors", "full", "--report"])
        .arg(dir.join("rep"))
        .output()
        .unwrap();
    support::assert_success(&report);
    let page = std::fs::read_to_string(dir.join("rep").join("index.html")).unwrap();
    for group in ["dg", "Dg", "kg", "ba", "ka"] {
        assert!(
            page.contains(&format!("sigma-{group}.png")),
            "σ(t) of {group}"
        );
        assert!(
            page.contains(&format!("error-{group}.png")),
            "error of {group}"
        );
    }
    assert!(
        page.contains("<td class=\"l\">µg</td>") && page.contains("<td class=\"l\">°/h/g</td>")
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A prior given as one σ (the installation model's, as `calibrate` gives
/// it) holds for every state: each result carries it, so the verdicts
/// read `converged`, not `not observable`.
#[test]
fn a_single_prior_sigma_holds_for_every_state() {
    use host_sim::analysis::runner::{result, Passes};
    struct Fixed(usize);
    impl host_sim::analysis::runner::DynFilter for Fixed {
        fn step(
            &mut self,
            _: &host_sim::sim::truth::PeriodSample,
        ) -> Result<f64, rollcal::ekf::Error> {
            Ok(0.0)
        }
        fn state(&self) -> Vec<f64> {
            vec![0.0; self.0]
        }
        fn sigma(&self) -> Vec<f64> {
            vec![1e-6; self.0]
        }
        fn covariance(&self) -> Vec<f64> {
            vec![0.0; self.0 * self.0]
        }
    }
    let n = ConfigId::M2Ps.layout().n();
    let p = Passes {
        filter: Box::new(Fixed(n)),
        history: Vec::new(),
        nis: Vec::new(),
        updates: Vec::new(),
        segments: Vec::new(),
        failures: Vec::new(),
        passes: 1,
    };
    let r = result(
        ConfigId::M2Ps,
        ErrorModel::Installation,
        &p,
        &vec![0.0; n],
        &[0.01],
    );
    assert_eq!(r.states.len(), n);
    assert!(r.states.iter().all(|s| s.prior == 0.01), "{:?}", r.states);
}

/// The observability of the full model on the paper's path: with the
/// Earth rate off, M1-pa loses the azimuth misalignment and the trace of
/// `D_g^pa` (a g-sensitive drift `c·I` turns the platform about the
/// specific force, which no accelerometer sees); with the Earth rate on,
/// both come back as weakly observable and every other instrument term is
/// outside the null space. M2-ps (gimbal angles measured) observes all 21.
#[test]
fn full_model_observability_on_the_paper_path() {
    use host_sim::analysis::observe::{analyse_run, Verdict};
    let scenario = Scenario::paper();
    for earth_rate in [false, true] {
        let sim = simulate(
            &scenario,
            SimOptions {
                seed: 0,
                noise: false,
                earth_rate,
            },
        );
        let analyse = |id| {
            analyse_run(
                SimulatedRun::new(id, &scenario, &sim, earth_rate).with_errors(ErrorModel::Full),
                false,
            )
            .unwrap()
        };
        let m1 = analyse(ConfigId::M1Pa);
        assert_eq!(m1.n, 36);
        let verdict = |name: &str| m1.states.iter().find(|s| s.name == name).unwrap().verdict;
        if earth_rate {
            assert_eq!(m1.rank, 36);
            assert_eq!(verdict("Dgpa_xx"), Verdict::WeaklyObservable);
            assert_eq!(verdict("psi_y"), Verdict::WeaklyObservable);
        } else {
            assert_eq!(m1.rank, 34);
            let trace: Vec<_> = m1
                .null_space
                .iter()
                .find(|c| c.iter().any(|t| t.state == "Dgpa_xx"))
                .unwrap()
                .iter()
                .map(|t| (t.state, (t.coef.abs() * 1e3).round()))
                .collect();
            assert_eq!(
                trace,
                [("Dgpa_xx", 577.0), ("Dgpa_yy", 577.0), ("Dgpa_zz", 577.0)]
            );
            assert_eq!(verdict("psi_y"), Verdict::StructurallyUnobservable);
        }
        for s in m1.states.iter().filter(|s| s.group.is_instrument()) {
            let in_trace = ["Dgpa_xx", "Dgpa_yy", "Dgpa_zz"].contains(&s.name);
            if earth_rate || !in_trace {
                assert_ne!(s.verdict, Verdict::StructurallyUnobservable, "{}", s.name);
            }
        }
        let m2 = analyse(ConfigId::M2Ps);
        assert!(m2
            .states
            .iter()
            .filter(|s| s.group.is_instrument() && !s.group.is_nuisance())
            .all(|s| s.verdict == Verdict::Observable));
    }
}

/// With errors that wander (the realistic scenario) the structure is that
/// of the constant terms: the nuisances (Gauss–Markov parts and warm-ups)
/// are left out of the rank, so no constant term is reported in a null
/// space with a warm-up (a warm-up seen without its decay is a constant:
/// left in, `dg_x` and `dg_wu_x` shared a null direction), and every
/// constant instrument term of M2-ps and M1-pa keeps a finite bound.
#[test]
fn full_model_observability_with_errors_that_wander() {
    use host_sim::analysis::observe::{analyse_run, Verdict};
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/realistic.toml");
    let scenario = Scenario::load(Some(std::path::Path::new(path))).unwrap();
    let sim = simulate(
        &scenario,
        SimOptions {
            seed: 0,
            noise: false,
            earth_rate: true,
        },
    );
    for (id, n) in [(ConfigId::M2Ps, 42), (ConfigId::M1Pa, 36)] {
        let obs = analyse_run(
            SimulatedRun::new(id, &scenario, &sim, true).with_errors(ErrorModel::Full),
            false,
        )
        .unwrap();
        assert_eq!((obs.n, obs.rank), (n, n), "{id:?}");
        assert!(obs.null_space.is_empty(), "{id:?}: {:?}", obs.null_space);
        for s in obs.states.iter().filter(|s| s.group.is_instrument()) {
            if s.group.is_nuisance() {
                assert_eq!(s.verdict, Verdict::Nuisance, "{id:?} {}", s.name);
            } else {
                assert_ne!(
                    s.verdict,
                    Verdict::StructurallyUnobservable,
                    "{id:?} {}",
                    s.name
                );
            }
        }
    }
}

/// `paper --errors full`: the observability tables of the seven full
/// models (Earth rate off and on, with the instrument columns), the runs,
/// and the summary with the instrument states in their units; the paper's
/// verdicts on the installation errors still hold under the full model.
#[test]
fn paper_errors_full() {
    let dir = support::scratch("paper-full");
    let out = support::host_sim()
        .args(["paper", "--errors", "full", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    support::assert_success(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains(
            "| config | rank/n | attitude | θgC | θgT | θaC | θaT | λ | dg | D_g | kg | ba | ka | k2 |"
        ),
        "{stdout}"
    );
    assert!(stdout.contains("| M1-pa | 34/36 |"), "{stdout}");
    assert!(stdout.contains("| M2-ps | 42/42 |"), "{stdout}");
    let json = support::json_file(&dir.join("summary.json"));
    assert_eq!(json["errors"], "full");
    assert!(json["command"].as_str().unwrap().contains("--errors full"));
    let md = std::fs::read_to_string(dir.join("summary.md")).unwrap();
    assert!(md.contains("| dg_x | °/h |"), "summary.md");
    std::fs::remove_dir_all(&dir).unwrap();
}
