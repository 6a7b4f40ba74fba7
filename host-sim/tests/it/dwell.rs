//! Dwells in the rolling path (`dwell_s` on a `[[path]]` segment): the
//! platform holds still (zero commanded path rate) for whole periods after
//! the rotation. A dwell runs through the simulator, `run` and
//! `observability`; `dwell_s = 0` changes nothing, bit for bit.

use crate::support;
use std::path::{Path, PathBuf};
use support::host_sim;

use host_sim::sim::scenario::{Scenario, PAPER_TOML};
use host_sim::sim::truth::{simulate, SimOptions};
use rollcal::command::CommandFrame;

/// The paper's scenario with `extra` lines after its first segment's rate
/// and the duration set to `duration_s`.
fn paper_with(extra: &str, duration_s: f64) -> String {
    let first = "rate_deg_s = 0.1";
    let at = PAPER_TOML.find(first).unwrap() + first.len();
    let mut text = String::from(&PAPER_TOML[..at]);
    text.push('\n');
    text.push_str(extra);
    text.push_str(&PAPER_TOML[at..]);
    text.replace(
        "duration_s = 5400.0",
        &format!("duration_s = {duration_s:.1}"),
    )
}

fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rollcal-dwell-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn run_json(cmd: &str, config: Option<&str>, scenario: &Path, json: &Path) -> serde_json::Value {
    let mut c = host_sim();
    c.arg(cmd);
    if let Some(config) = config {
        c.args(["--config", config, "--seed", "7"]);
    }
    let out = c
        .arg("--scenario")
        .arg(scenario)
        .arg("--json")
        .arg(json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{cmd}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
}

const DWELL_S: f64 = 600.0;
/// The first segment (South 180° at 0.1°/s) ends here; the dwell follows.
const DWELL_START: usize = 1800;

#[test]
fn the_platform_holds_still_during_a_dwell() {
    let s = Scenario::from_toml(&paper_with("dwell_s = 600.0", 6000.0)).unwrap();
    let sim = simulate(
        &s,
        SimOptions {
            seed: 1,
            noise: false,
            earth_rate: true,
        },
    );
    assert_eq!(sim.samples.len(), 6000);
    // Sample k is at t_k = k s; samples[k - 1].
    let at = |k: usize| &sim.samples[k - 1].truth;
    let start = at(DWELL_START);
    let end = at(DWELL_START + DWELL_S as usize);
    // The computed frame is exactly still; the true platform only drifts by
    // the gyro installation errors acting on the Earth rate (≈ 4e-7 rad/s).
    let c_err = (end.c_c_n - start.c_c_n).amax();
    let ps_err = (end.c_ps_n - start.c_ps_n).amax();
    let gimbal_err = (end.gimbal - start.gimbal).amax();
    eprintln!("over the {DWELL_S} s dwell: C^c_n {c_err:.1e}, C^ps_n {ps_err:.1e}, gimbal {gimbal_err:.1e} rad");
    assert!(c_err < 1e-12, "computed frame moved {c_err:e}");
    assert!(ps_err < 1e-3, "platform moved {ps_err:e}");
    assert!(gimbal_err < 1e-3, "gimbals moved {gimbal_err:e}");
    // Over the same time before the dwell the platform turned 60°.
    let before = (start.c_c_n - at(DWELL_START - DWELL_S as usize).c_c_n).amax();
    assert!(before > 0.4, "{before}");
    // The commanded increments mean zero path rate to rollcal::command,
    // and the 0.1°/s rotation resumes after the dwell.
    let mut frame = CommandFrame::aligned(sim.earth_rate_n);
    for (i, p) in sim.samples.iter().enumerate() {
        let k = i + 1;
        let u = frame.path_rate(&p.dtheta_cmd, p.dt);
        let dwelling = k > DWELL_START && k <= DWELL_START + DWELL_S as usize;
        if dwelling {
            assert!(u.amax() < 1e-12, "period {k}: path rate {u}");
        } else if k <= 5400 + DWELL_S as usize {
            assert!(
                (u.norm() - 0.1f64.to_radians()).abs() < 1e-10,
                "period {k}: |u| {}",
                u.norm()
            );
        }
        frame.advance(&frame.period(&p.dtheta_cmd, p.dt));
    }
}

#[test]
fn a_dwell_runs_through_run_and_observability() {
    let dir = temp_dir("cli");
    let scenario = dir.join("dwell.toml");
    std::fs::write(&scenario, paper_with("dwell_s = 600.0", 6000.0)).unwrap();
    let run = run_json("run", Some("m2-ps"), &scenario, &dir.join("run.json"));
    assert_eq!(run["duration_s"], 6000.0);
    let obs = run_json("observability", None, &scenario, &dir.join("obs.json"));
    let crlb = obs["configs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["config"] == run["config"])
        .unwrap();
    let states = run["states"].as_array().unwrap();
    assert_eq!(states.len(), 18);
    for st in states {
        let name = st["name"].as_str().unwrap();
        let f = |k: &str| st[k].as_f64().unwrap();
        let (truth, est, sigma) = (f("truth_rad"), f("estimate_rad"), f("sigma_rad"));
        assert!(truth.is_finite() && est.is_finite() && sigma.is_finite() && sigma > 0.0);
        let z = (est - truth) / sigma;
        assert!(z.abs() < 5.0, "{name}: error {z:.2} σ");
        // The filter's σ is the Cramér–Rao bound of the same path.
        let bound = crlb["states"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["name"] == name)
            .unwrap()["sigma_crlb_rad"]
            .as_f64()
            .unwrap();
        let ratio = sigma / bound;
        assert!((ratio - 1.0).abs() < 0.01, "{name}: σ / σ_CRLB = {ratio}");
    }
}

#[test]
fn a_zero_dwell_changes_nothing() {
    let plain = Scenario::paper();
    let zero = Scenario::from_toml(&paper_with("dwell_s = 0.0", 5400.0)).unwrap();
    assert_eq!(plain, zero);
    let opts = SimOptions {
        seed: 4,
        noise: true,
        earth_rate: true,
    };
    let (a, b) = (simulate(&plain, opts), simulate(&zero, opts));
    assert_eq!(a.samples, b.samples);
    // And through the CLI, bit for bit.
    let dir = temp_dir("zero");
    let (p0, p1) = (dir.join("plain.toml"), dir.join("zero.toml"));
    std::fs::write(&p0, PAPER_TOML).unwrap();
    std::fs::write(&p1, paper_with("dwell_s = 0.0", 5400.0)).unwrap();
    for (cmd, config) in [("run", Some("m1-pa")), ("observability", None)] {
        let j0 = run_json(cmd, config, &p0, &dir.join(format!("{cmd}-plain.json")));
        let j1 = run_json(cmd, config, &p1, &dir.join(format!("{cmd}-zero.json")));
        assert_eq!(j0, j1, "{cmd}");
    }
}

#[test]
fn bad_dwells_are_one_line_errors() {
    for (dwell, says) in [
        ("-60.0", "dwell_s"),
        ("nan", "dwell_s"),
        ("inf", "dwell_s"),
        ("0.5", "whole number"),
    ] {
        let text = paper_with(&format!("dwell_s = {dwell}"), 6000.0);
        let e = Scenario::from_toml(&text).unwrap_err().0;
        assert!(e.contains(says) && !e.contains('\n'), "{dwell}: {e}");
    }
    // Too long for the duration.
    let e = Scenario::from_toml(&paper_with("dwell_s = 600.0", 5400.0))
        .unwrap_err()
        .0;
    assert!(e.contains("path lasts 6000"), "{e}");
    // A pure dwell (angle 0) is allowed; an empty segment is not.
    let pure = PAPER_TOML.replacen(
        "[[path]]",
        "[[path]]\naxis = \"up\"\nangle_deg = 0.0\nrate_deg_s = 0.1\ndwell_s = 60.0\n\n[[path]]",
        1,
    );
    let s =
        Scenario::from_toml(&pure.replace("duration_s = 5400.0", "duration_s = 5460.0")).unwrap();
    assert_eq!(s.path[0].duration_s(), 60.0);
    let empty = PAPER_TOML.replacen(
        "[[path]]",
        "[[path]]\naxis = \"up\"\nangle_deg = 0.0\nrate_deg_s = 0.1\n\n[[path]]",
        1,
    );
    let e = Scenario::from_toml(&empty).unwrap_err().0;
    assert!(e.contains("angle_deg"), "{e}");
    // The CLI reports it on one line.
    let dir = temp_dir("bad");
    let f = dir.join("bad.toml");
    std::fs::write(&f, paper_with("dwell_s = -1.0", 6000.0)).unwrap();
    let out = host_sim()
        .args(["run", "--config", "m1-pa", "--scenario"])
        .arg(&f)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("dwell_s") && err.trim().lines().count() == 1,
        "{err}"
    );
}
