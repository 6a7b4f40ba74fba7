//! `host-sim design`: the bound it searches on is the bound `observability`
//! reports, its coarse steps change σ by less than 1 %, it never proposes a
//! path past the gimbal limit, and the scenario it writes meets its targets
//! in `host-sim observability` in less time than the reference path.

use crate::support;
use support::{assert_success, host_sim};

use host_sim::analysis::observe::analyse;
use host_sim::design::{pattern_of, Goal, NamedAxis, Pattern, Problem, Rotation};
use host_sim::sim::scenario::{Scenario, ARCSEC};
use host_sim::sim::truth::{simulate, SimOptions};
use rollcal::models::{ConfigId, ErrorModel};

fn rotation(axis: &str, angle: f64, rate: f64) -> Rotation {
    Rotation::new(NamedAxis::named(axis).unwrap(), angle, rate)
}

#[test]
fn the_search_bound_is_the_observability_bound() {
    // The design evaluates paths from the library's commanded increments;
    // `observability` from the truth simulator's. Same σ to 1e-4.
    let s = Scenario::paper();
    let sim = simulate(
        &s,
        SimOptions {
            seed: 0,
            noise: false,
            earth_rate: true,
        },
    );
    for id in [ConfigId::M2Ps, ConfigId::M1Pa] {
        let obs = analyse(id, &s, &sim, true, false).unwrap();
        let problem = Problem::new(id, &s, 60.0);
        let p = pattern_of(&s).unwrap();
        let o = problem.evaluate(&p, Goal::Budget { periods: 5400 }, true, false);
        assert_eq!(o.k, 1);
        assert_eq!(o.periods, 5400);
        for (st, sig) in obs.states.iter().zip(&o.sigma_end) {
            let rel = (sig / st.sigma_crlb_rad - 1.0).abs();
            assert!(rel < 1e-4, "{id} {}: {rel:e}", st.name);
        }
    }
}

/// South 180°, dwell 180 s, east 90°, dwell 60 s, at 1°/s, repeated.
fn fast_with_dwells() -> Pattern {
    let mut a = rotation("south", 180.0, 1.0);
    a.dwell_s = 180.0;
    let mut b = rotation("east", 90.0, 1.0);
    b.dwell_s = 60.0;
    Pattern {
        rotations: vec![a, b],
        repeat: true,
    }
}

#[test]
fn the_search_bound_of_a_path_with_dwells_is_the_observability_bound() {
    // A candidate with dwells, written as a scenario (segments with
    // `dwell_s`) and run through the truth simulator and `observability`'s
    // analysis: the same σ to 1e-4 as the search's own evaluation, and the
    // written scenario read back as a reference pattern is evaluated bit
    // for bit like the candidate.
    let base = Scenario::paper();
    let p = fast_with_dwells();
    let periods = 1234; // 2 cycles of 510 s, then south 180° + 34 s of dwell
    let mut s = base.clone();
    s.path = p.segments(periods, 1.0);
    s.timing.duration_s = periods as f64;
    s.validate().unwrap();
    let dwells: Vec<f64> = s.path.iter().map(|g| g.dwell_s).collect();
    assert_eq!(dwells, [180.0, 60.0, 180.0, 60.0, 34.0]);
    let text = toml::to_string(&s).unwrap();
    let s = Scenario::from_toml(&text).unwrap();
    let sim = simulate(
        &s,
        SimOptions {
            seed: 0,
            noise: false,
            earth_rate: true,
        },
    );
    let explicit = pattern_of(&s).unwrap();
    for id in [ConfigId::M2Ps, ConfigId::M1Pa] {
        let obs = analyse(id, &s, &sim, true, false).unwrap();
        let problem = Problem::new(id, &s, 60.0);
        let goal = Goal::Budget { periods };
        let o = problem.evaluate(&p, goal, true, false);
        assert_eq!((o.k, o.periods), (1, periods));
        let mut worst: f64 = 0.0;
        for (st, sig) in obs.states.iter().zip(&o.sigma_end) {
            let rel = (sig / st.sigma_crlb_rad - 1.0).abs();
            worst = worst.max(rel);
            assert!(rel < 1e-4, "{id} {}: {rel:e}", st.name);
        }
        eprintln!("{id}: dwells, search bound vs observability: {worst:.1e}");
        let e = problem.evaluate(&explicit, goal, true, false);
        assert_eq!(e.sigma_end, o.sigma_end, "{id}: explicit path");
        // Coarse steps divide the dwells: 30 = gcd(180, 180, 90, 60), cut
        // to 10 at 1°/s; with the budget's 1234 periods, 2.
        assert_eq!(problem.step_periods(&p, 0, false), 10);
        assert_eq!(problem.evaluate(&p, goal, false, false).k, 2);
        let c = problem.evaluate(&p, Goal::Budget { periods: 1530 }, false, false);
        assert_eq!(c.k, 10);
        let f = problem.evaluate(&p, Goal::Budget { periods: 1530 }, true, false);
        let change = problem_change(&c.sigma_end, &f.sigma_end, id);
        assert!(
            change < 0.01,
            "{id}: coarse steps with dwells moved σ by {change}"
        );
    }
}

/// Largest relative change of σ over the parameters (not the attitude).
fn problem_change(a: &[f64], b: &[f64], id: ConfigId) -> f64 {
    id.states()
        .iter()
        .enumerate()
        .filter(|(_, st)| st.group != rollcal::models::Group::Attitude)
        .map(|(i, _)| (a[i] / b[i] - 1.0).abs())
        .fold(0.0, f64::max)
}

#[test]
fn a_dwell_in_place_of_rotation_costs_the_gyro_angles() {
    // During a dwell the commanded rate is zero: the gyro angles, excited
    // by rotation, gain less in the same time than from rotating on.
    let s = Scenario::paper();
    let mut problem = Problem::new(ConfigId::M2Ps, &s, 60.0);
    let thg: Vec<usize> = ConfigId::M2Ps
        .states()
        .iter()
        .enumerate()
        .filter(|(_, st)| st.name.starts_with("thg"))
        .map(|(i, _)| i)
        .collect();
    problem.targets = thg.iter().map(|&i| (i, 1.0)).collect();
    let plain = Pattern {
        rotations: vec![rotation("south", 180.0, 1.0), rotation("east", 90.0, 1.0)],
        repeat: true,
    };
    let goal = Goal::Budget { periods: 1530 };
    let a = problem.evaluate(&plain, goal, true, false);
    let b = problem.evaluate(&fast_with_dwells(), goal, true, false);
    assert!(a.gimbal_lock.is_none() && b.gimbal_lock.is_none());
    for &i in &thg {
        assert!(b.sigma_end[i] > a.sigma_end[i], "state {i}");
    }
}

#[test]
fn design_accepts_a_reference_path_with_dwells() {
    // The paper's path with a 600 s dwell after its first half-turn is a
    // reference like any other: the targets are its final σ_CRLB, and a
    // short budgeted search runs on it (seeded only by the scenario: the
    // bound has no noise).
    let dir = std::env::temp_dir().join(format!("rollcal-design-dwell-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = host_sim::sim::scenario::PAPER_TOML;
    let first = "rate_deg_s = 0.1";
    let at = text.find(first).unwrap() + first.len();
    let reference = format!("{}\ndwell_s = 600.0{}", &text[..at], &text[at..])
        .replace("duration_s = 5400.0", "duration_s = 6000.0");
    let f = dir.join("ref.toml");
    std::fs::write(&f, reference).unwrap();
    let json = dir.join("d.json");
    let out = host_sim()
        .args([
            "design",
            "--config",
            "m1-pa",
            "--budget-s",
            "600",
            "--max-rotations",
            "1",
            "--refine-starts",
            "1",
            "--axes",
            "north,east",
            "--scenario",
        ])
        .arg(&f)
        .arg("--out")
        .arg(dir.join("d.toml"))
        .arg("--figure")
        .arg(dir.join("d.png"))
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert_success(&out);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["reference_duration_s"], 6000.0);
    assert_eq!(v["limits"]["dwell_steps_s"][2], 600.0);
    // The targets are the reference's σ_CRLB as `observability` has it.
    let s = Scenario::from_file(&f).unwrap();
    let sim = simulate(
        &s,
        SimOptions {
            seed: 0,
            noise: false,
            earth_rate: true,
        },
    );
    let obs = analyse(ConfigId::M1Pa, &s, &sim, true, false).unwrap();
    for t in v["targets"].as_array().unwrap() {
        let st = obs
            .states
            .iter()
            .find(|x| x.name == t["state"].as_str().unwrap())
            .unwrap();
        let r = t["reference_sigma_rad"].as_f64().unwrap();
        assert!((r / st.sigma_crlb_rad - 1.0).abs() < 1e-12, "{}", st.name);
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn coarse_steps_change_sigma_by_less_than_one_percent() {
    let s = Scenario::paper();
    let paper = pattern_of(&s).unwrap();
    let fast = Pattern {
        rotations: vec![rotation("south", 180.0, 1.0), rotation("east", 90.0, 1.0)],
        repeat: true,
    };
    for id in [ConfigId::M2Ps, ConfigId::M1Pa] {
        let problem = Problem::new(id, &s, 60.0);
        for (p, periods) in [(&paper, 5400), (&fast, 1620)] {
            let goal = Goal::Budget { periods };
            let c = problem.evaluate(p, goal, false, false);
            let f = problem.evaluate(p, goal, true, false);
            assert!(c.k > 1, "the coarse evaluation merges periods");
            let worst = id
                .states()
                .iter()
                .enumerate()
                .filter(|(_, st)| st.group != rollcal::models::Group::Attitude)
                .map(|(i, _)| (c.sigma_end[i] / f.sigma_end[i] - 1.0).abs())
                .fold(0.0, f64::max);
            assert!(worst < 0.01, "{id}, k = {}: {worst}", c.k);
        }
    }
}

#[test]
fn a_rotation_into_gimbal_lock_is_infeasible() {
    // About Up from the aligned start the middle gimbal angle β grows with
    // the rotation: past 60° the candidate stops and is never reached.
    let s = Scenario::paper();
    let mut problem = Problem::new(ConfigId::M2Ps, &s, 60.0);
    problem.targets = vec![(9, 1e-12)];
    let p = Pattern {
        rotations: vec![rotation("up", 90.0, 1.0)],
        repeat: true,
    };
    // Coarse steps (10 periods) see it at the end of the step that passes
    // 60°, period by period (the final check of every design) at once.
    let o = problem.evaluate(&p, Goal::Reach { cutoff: 600 }, false, false);
    let at = o.gimbal_lock.expect("β limit");
    assert!((60..=70).contains(&at), "locked at {at} s");
    assert!(o.reach.is_none());
    let o = problem.evaluate(&p, Goal::Reach { cutoff: 600 }, true, false);
    let at = o.gimbal_lock.expect("β limit");
    assert!((60..=61).contains(&at), "locked at {at} s");
    assert!(!o.feasible(Goal::Reach { cutoff: 600 }));
    let o = problem.evaluate(&p, Goal::Budget { periods: 120 }, false, false);
    assert!(!o.feasible(Goal::Budget { periods: 120 }));
}

#[test]
fn design_writes_a_shorter_scenario_that_meets_its_targets() {
    let dir = std::env::temp_dir().join(format!("rollcal-design-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (toml, json, png) = (dir.join("d.toml"), dir.join("d.json"), dir.join("d.png"));
    // A small search (single and paired rotations, no refinement) keeps the
    // test short; the default search is larger.
    let out = host_sim()
        .args([
            "design",
            "--config",
            "m1-pa",
            "--max-rotations",
            "2",
            "--refine-starts",
            "1",
            "--axes",
            "north,east,south",
            "--target-scale",
            "2",
            "--out",
        ])
        .arg(&toml)
        .arg("--json")
        .arg(&json)
        .arg("--figure")
        .arg(&png)
        .output()
        .unwrap();
    assert_success(&out);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["all_targets_met"], true);
    let duration = v["duration_s"].as_f64().unwrap();
    assert!(duration < 5400.0, "{duration}");
    assert!(v["coarse_step_max_change"].as_f64().unwrap() < 0.01);
    assert!(std::fs::metadata(&png).unwrap().len() > 10_000);
    // The scenario, read back and analysed as `observability` does.
    let s = Scenario::from_file(&toml).unwrap();
    assert_eq!(s.timing.duration_s, duration);
    let sim = simulate(
        &s,
        SimOptions {
            seed: 0,
            noise: false,
            earth_rate: true,
        },
    );
    assert!(sim
        .samples
        .iter()
        .all(|x| x.truth.gimbal.y.abs() <= 60f64.to_radians()));
    let obs = analyse(ConfigId::M1Pa, &s, &sim, true, false).unwrap();
    let targets = v["targets"].as_array().unwrap();
    assert_eq!(targets.len(), 9);
    for t in targets {
        let name = t["state"].as_str().unwrap();
        let st = obs.states.iter().find(|x| x.name == name).unwrap();
        let target = t["target_rad"].as_f64().unwrap();
        assert!(
            st.sigma_crlb_rad <= target,
            "{name}: {} > {}",
            st.sigma_crlb_rad / ARCSEC,
            target / ARCSEC
        );
        // Twice the reference σ.
        let r = t["reference_sigma_rad"].as_f64().unwrap();
        assert!((target / r - 2.0).abs() < 1e-9);
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_design_arguments_give_one_line_errors() {
    for args in [
        vec!["--target", "nope=1"],
        vec!["--target", "thgC"],
        vec!["--axes", "sideways"],
        vec!["--budget-s", "0.5"],
        vec!["--max-beta-deg", "95"],
        vec!["--max-rate-deg-s", "-1"],
    ] {
        let out = host_sim()
            .args(["design", "--config", "M2-ps"])
            .args(&args)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        let lines: Vec<&str> = err.lines().filter(|l| l.contains("error")).collect();
        assert_eq!(lines.len(), 1, "{args:?}: {err}");
    }
}

#[test]
fn the_search_proposes_a_dwell_where_it_helps() {
    // M1-pa at 1°/s within 900 s (deterministic: a budget search has no
    // pruning, the bound no noise): the best path holds still for 60 s
    // after a rotation, and it beats the best path the search finds
    // without dwells (1.925 against 2.005 of the worst σ/target when
    // written). Each search takes a few seconds in release.
    let dir = std::env::temp_dir().join(format!("rollcal-design-helps-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run = |extra: &[&str], tag: &str| -> serde_json::Value {
        let json = dir.join(format!("{tag}.json"));
        let out = host_sim()
            .args([
                "design",
                "--config",
                "m1-pa",
                "--max-rate-deg-s",
                "1",
                "--budget-s",
                "900",
                "--refine-starts",
                "2",
            ])
            .args(extra)
            .arg("--out")
            .arg(dir.join(format!("{tag}.toml")))
            .arg("--figure")
            .arg(dir.join(format!("{tag}.png")))
            .arg("--json")
            .arg(&json)
            .output()
            .unwrap();
        assert_success(&out);
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
    };
    let worst = |v: &serde_json::Value| -> f64 {
        v["targets"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["designed_sigma_rad"].as_f64().unwrap() / t["target_rad"].as_f64().unwrap())
            .fold(0.0, f64::max)
    };
    let with = run(&[], "with");
    let without = run(&["--no-dwells"], "without");
    let dwells: Vec<f64> = with["path"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|s| s["dwell_s"].as_f64())
        .collect();
    assert!(!dwells.is_empty(), "no dwell in {}", with["path"]);
    // Whole periods (1 s), and the written scenario is what was analysed.
    assert!(dwells.iter().all(|d| *d > 0.0 && d.fract() == 0.0));
    assert!(without["path"]
        .as_array()
        .unwrap()
        .iter()
        .all(|s| s.get("dwell_s").is_none()));
    let (a, b) = (worst(&with), worst(&without));
    eprintln!("worst σ/target in 900 s: {a:.4} with dwells, {b:.4} without");
    assert!(a < b, "{a} ≥ {b}");
    let s = Scenario::from_file(&dir.join("with.toml")).unwrap();
    assert_eq!(s.timing.duration_s, 900.0);
    assert!(s.path.iter().any(|g| g.dwell_s > 0.0));
    std::fs::remove_dir_all(&dir).ok();
}

/// The instrumented scenario (the paper's path and the instrument errors
/// of docs/model.md §The instrumented scenario).
fn instrumented() -> (std::path::PathBuf, Scenario) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/instrumented.toml");
    let s = Scenario::from_file(&path).unwrap();
    (path, s)
}

/// The full model's bound of `s` as `host-sim observability --errors full`
/// computes it.
fn full_obs(id: ConfigId, s: &Scenario) -> host_sim::analysis::observe::ConfigObs {
    let sim = simulate(
        s,
        SimOptions {
            seed: 0,
            noise: false,
            earth_rate: s.site.earth_rate,
        },
    );
    let run = host_sim::analysis::runner::SimulatedRun::new(id, s, &sim, s.site.earth_rate)
        .with_errors(ErrorModel::Full);
    host_sim::analysis::observe::analyse_run(run, false).unwrap()
}

#[test]
fn the_search_bound_of_the_full_model_is_the_observability_bound() {
    // With the instrument terms too (their truth and prior from the
    // scenario): the σ the search scores is `observability --errors full`'s.
    let (_, s) = instrumented();
    let id = ConfigId::M1Pa;
    let obs = full_obs(id, &s);
    let problem = Problem::with_errors(id, ErrorModel::Full, &s, 60.0);
    let p = pattern_of(&s).unwrap();
    let o = problem.evaluate(&p, Goal::Budget { periods: 5400 }, true, false);
    assert_eq!(o.sigma_end.len(), 48);
    for (st, sig) in obs.states.iter().zip(&o.sigma_end) {
        if st.sigma_crlb_rad == 0.0 {
            // Not estimated: held at zero by both.
            assert_eq!(*sig, 0.0, "{id} {}", st.name);
            continue;
        }
        let rel = (sig / st.sigma_crlb_rad - 1.0).abs();
        assert!(rel < 1e-4, "{id} {}: {rel:e}", st.name);
    }
}

#[test]
fn design_full_separates_the_weak_terms_and_reports_a_target_out_of_reach() {
    // M1-pa on the paper's path: Dgpa_zx, Dgpa_zy and kg_z weak (one roll
    // rate, one sense of rotation). A small search (pairs of rotations about
    // three axes, 2700 s) finds a path on which they are observable in
    // practice; the D_g diagonal's 0.005 °/h/g is out of reach there, and the
    // report says so with the bound.
    let (scenario, s) = instrumented();
    let id = ConfigId::M1Pa;
    let reference = full_obs(id, &s);
    let verdict = |o: &host_sim::analysis::observe::ConfigObs, n: &str| {
        o.states.iter().find(|x| x.name == n).unwrap().observable
    };
    let weak = ["Dgpa_zx", "Dgpa_zy", "kg_z"];
    for n in weak {
        assert!(
            !verdict(&reference, n),
            "{n} observable on the paper's path"
        );
    }
    let dir = std::env::temp_dir().join(format!("rollcal-design-full-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (toml, json, png) = (dir.join("d.toml"), dir.join("d.json"), dir.join("d.png"));
    let out = host_sim()
        .args([
            "design",
            "--config",
            "M1-pa",
            "--errors",
            "full",
            "--max-rotations",
            "2",
            "--refine-starts",
            "1",
            "--axes",
            "north,east,south",
            "--no-dwells",
            "--max-duration-s",
            "2700",
            "--scenario",
        ])
        .arg(&scenario)
        .arg("--out")
        .arg(&toml)
        .arg("--json")
        .arg(&json)
        .arg("--figure")
        .arg(&png)
        .output()
        .unwrap();
    // Every target was asked for and some are out of reach: exit status 1,
    // the best path within the limits written all the same.
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("out of reach within the limits (listed above): the best path within them is written to"),
        "{stderr}"
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("Out of reach within the limits"),
        "{stdout}"
    );
    // The second figure: the instrument terms.
    assert!(
        std::fs::metadata(dir.join("d-instruments.png"))
            .unwrap()
            .len()
            > 10_000
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["errors"], "full");
    let targets = v["targets"].as_array().unwrap();
    // The 9 installation parameters and the 21 instrument terms.
    assert_eq!(targets.len(), 30);
    // The written scenario, analysed as `observability --errors full` does.
    let designed = Scenario::from_file(&toml).unwrap();
    assert_eq!(designed.timing.duration_s, 2700.0);
    let obs = full_obs(id, &designed);
    for n in weak {
        assert!(verdict(&obs, n), "{n} not observable on the designed path");
    }
    let sigma = |n: &str| {
        obs.states
            .iter()
            .find(|x| x.name == n)
            .unwrap()
            .sigma_crlb_rad
    };
    // Every target out of reach is missed by the bound of the written
    // scenario, by the σ reported; every other target is met.
    let missed = v["out_of_reach"].as_array().unwrap();
    assert!(missed.iter().any(|m| m["state"] == "Dgpa_xx"));
    for t in targets {
        let n = t["state"].as_str().unwrap();
        let target = t["target_rad"].as_f64().unwrap();
        match missed.iter().find(|m| m["state"] == n) {
            Some(m) => {
                let reported = m["sigma"].as_f64().unwrap();
                assert!((reported / sigma(n) - 1.0).abs() < 1e-12, "{n}");
                assert!(reported > target, "{n}");
                assert_eq!(m["target"].as_f64().unwrap(), target);
                // What reaches it: later than the limit, or faster.
                if let Some(ts) = m["time_s"].as_f64() {
                    assert!(ts > 2700.0, "{n}: {ts}");
                }
                if let Some(r) = m["rate_deg_s"].as_f64() {
                    assert!(r > 1.0, "{n}: {r}");
                    assert!(m["sigma_at_rate"].as_f64().unwrap() <= target, "{n}");
                }
            }
            None => assert!(sigma(n) <= target, "{n}"),
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
