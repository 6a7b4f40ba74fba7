//! `calibrate` without a truth (issue 11, item 2): the table of estimate,
//! σ and the bound at the estimate, the data checks and their exit status.
//! Deterministic: every stream is seeded.

use crate::support;
use std::path::PathBuf;
use std::process::Output;
use support::{assert_success, host_sim, json_file};

use host_sim::analysis::checks::{cases, judge_simulated, DataVerdict, WARNING_EXIT};
use host_sim::sim::scenario::Scenario;
use rollcal::models::ConfigId;

fn dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rollcal-checks-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Records M2-ps, paper scenario, `seed`, with `extra` record options, and
/// calibrates it without a truth; returns the output and the JSON.
fn record_and_calibrate(tag: &str, seed: &str, extra: &[&str]) -> (Output, serde_json::Value) {
    let d = dir(tag);
    let (bin, json) = (d.join("run.bin"), d.join("cal.json"));
    let rec = host_sim()
        .args(["record", "--config", "M2-ps", "--seed", seed])
        .args(extra)
        .arg("--out")
        .arg(&bin)
        .output()
        .unwrap();
    assert!(
        rec.status.success(),
        "{}",
        String::from_utf8_lossy(&rec.stderr)
    );
    let out = host_sim()
        .args(["calibrate", "--input"])
        .arg(&bin)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let v = json_file(&json);
    let _ = std::fs::remove_dir_all(&d);
    (out, v)
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn failed_checks(v: &serde_json::Value) -> Vec<(String, String)> {
    v["data_verdict"]["failed"]
        .as_array()
        .map(|a| {
            a.iter()
                .map(|c| {
                    (
                        c["name"].as_str().unwrap_or("").to_string(),
                        c["scope"].as_str().unwrap_or("").to_string(),
                    )
                })
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn clean_stream_is_consistent_without_failed_or_nan() {
    let (out, v) = record_and_calibrate("clean", "1", &[]);
    let text = stdout(&out);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(!text.contains("FAILED"), "{text}");
    assert!(!text.contains("NaN"), "{text}");
    assert!(text.contains("data verdict: consistent"), "{text}");
    assert!(text.contains("bound ") && text.contains("observable in practice"));
    assert_eq!(v["data_verdict"]["verdict"], "consistent");
    let checks = v["checks"].as_array().unwrap();
    // 1 + 4 segments NIS, 6 whiteness, 4 × 6 bias.
    assert_eq!(checks.len(), 5 + 6 + 24, "{checks:?}");
    assert!(checks.iter().all(|c| c["passed"] == true));
    // The path's distance from gimbal lock: the paper path keeps the
    // middle gimbal within a few degrees of upright.
    let path = &v["path_check"];
    assert_eq!(path["name"], "gimbal_lock");
    assert_eq!(path["passed"], true);
    let beta = path["statistic"].as_f64().unwrap();
    assert!(beta > 0.0 && beta < 10.0, "{path}");
    assert!(text.contains("path: gimbal_lock"), "{text}");
    // The bound at the estimate: every parameter, λy the weakest (≈ 27″).
    let b = v["bound_at_estimate_sigma_rad"].as_array().unwrap();
    assert_eq!(b.len(), 18);
    let lam_y = b[16].as_f64().unwrap() / (std::f64::consts::PI / 648_000.0);
    assert!((20.0..35.0).contains(&lam_y), "{lam_y}");
    assert!(v["observability"]
        .as_array()
        .unwrap()
        .iter()
        .all(|w| w == "observable"));
}

#[test]
fn accel_noise_three_times_is_flagged_by_nis() {
    let (out, v) = record_and_calibrate("noise", "1", &["--accel-noise-scale", "3"]);
    let text = stdout(&out);
    assert_eq!(out.status.code(), Some(i32::from(WARNING_EXIT)), "{text}");
    assert!(!text.contains("FAILED") && !text.contains("NaN"), "{text}");
    assert!(text.contains("data verdict: warning: nis "), "{text}");
    assert_eq!(v["data_verdict"]["verdict"], "warning");
    let failed = failed_checks(&v);
    assert!(
        failed.contains(&("nis".into(), "overall".into())),
        "{failed:?}"
    );
}

#[test]
fn unmodelled_accel_bias_is_flagged_by_segment_bias() {
    let (out, v) = record_and_calibrate("bias", "1", &["--accel-bias-ug", "10,10,10"]);
    let text = stdout(&out);
    assert_eq!(out.status.code(), Some(i32::from(WARNING_EXIT)), "{text}");
    assert!(!text.contains("FAILED") && !text.contains("NaN"), "{text}");
    let failed = failed_checks(&v);
    assert!(
        failed
            .iter()
            .any(|(n, s)| n == "bias" && s.starts_with("segment ") && s.contains("accel")),
        "{failed:?}"
    );
}

/// A log of M2-ps whose middle gimbal comes within 5° of gimbal lock is
/// flagged by the path check (docs/estimator.md, "Fast rolls": the model breaks down
/// there), exit status 3, the check first among the failed ones; `record`
/// refuses such a path, so the log is written from the truth simulator
/// here: the paper's settings, 87° about Up at 1°/s (β reaches 86.9°),
/// with noise. M1's model holds no gimbal angles: no path check on the same
/// log (`tests/serial.rs` also calibrates an M1-pa stream whose gimbal
/// angles reach 89.65°: exit 0).
#[test]
fn a_log_near_gimbal_lock_is_flagged() {
    use host_sim::sim::truth::{simulate, SimOptions};
    let d = dir("lock");
    let scenario = support::paper_with_path(&d, "lock", &[("up", 87.0, 1.0)], "87.0");
    let sc = Scenario::from_file(&scenario).unwrap();
    let sim = simulate(
        &sc,
        SimOptions {
            seed: 6,
            noise: true,
            earth_rate: true,
        },
    );
    let samples: Vec<_> = sim
        .samples
        .iter()
        .map(host_sim::io::stream::to_sample)
        .collect();
    let (csv, json) = (d.join("run.csv"), d.join("cal.json"));
    std::fs::write(&csv, host_sim::io::csvlog::write(&samples)).unwrap();
    // The largest angle from upright, from the samples as sent.
    let (k, worst) = samples
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let beta = f64::from(s.gimbal.unwrap()[1]);
            (k, beta.cos().abs().acos().to_degrees())
        })
        .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
    assert!(worst > 86.0 && worst < 87.0, "{worst}");
    for id in [ConfigId::M2Ps, ConfigId::M1Pa] {
        let out = host_sim()
            .args(["calibrate", "--config", &id.to_string(), "--input"])
            .arg(&csv)
            .arg("--platform")
            .arg(&scenario)
            .arg("--json")
            .arg(&json)
            .output()
            .unwrap();
        let v = json_file(&json);
        let text = stdout(&out);
        if id == ConfigId::M1Pa {
            // No path check for M1-pa; a turn about Up alone observes
            // little of it: not an answer.
            assert_eq!(out.status.code(), Some(4), "{text}");
            assert!(v["path_check"].is_null(), "{}", v["path_check"]);
            assert!(!text.contains("path: "), "{text}");
            continue;
        }
        // The path turns about Up alone: the warning, and M2-ps's claimed
        // states (θgC, θaC, λx, λz) unobserved, so not an answer (exit 4
        // outranks 3).
        assert_eq!(out.status.code(), Some(4), "{text}");
        assert!(
            v["data_verdict"]["verdict"] == "warning",
            "{}",
            v["data_verdict"]
        );
        assert!(
            text.contains("answer: NOT an answer") && text.contains("kept σ ≥ 0.01"),
            "{text}"
        );
        let path = &v["path_check"];
        assert_eq!(path["name"], "gimbal_lock");
        assert_eq!(path["passed"], false, "{path}");
        assert!(
            (path["statistic"].as_f64().unwrap() - worst).abs() < 1e-12,
            "{path}"
        );
        let at = format!("record {}, t = {} s", k + 1, k + 1);
        assert!(path["detail"].as_str().unwrap().contains(&at), "{path}");
        assert_eq!(failed_checks(&v)[0], ("gimbal_lock".into(), "path".into()));
        assert!(
            text.contains("path: gimbal_lock") && text.contains("FAIL"),
            "{text}"
        );
        assert!(
            text.contains("data verdict: warning: gimbal_lock path"),
            "{text}"
        );
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn one_pass_is_not_checked_and_exits_0() {
    let d = dir("one-pass");
    let bin = d.join("run.bin");
    let rec = host_sim()
        .args(["record", "--config", "M1-pa", "--seed", "2", "--out"])
        .arg(&bin)
        .output()
        .unwrap();
    assert!(rec.status.success());
    let out = host_sim()
        .args(["calibrate", "--passes", "1", "--input"])
        .arg(&bin)
        .output()
        .unwrap();
    let _ = std::fs::remove_dir_all(&d);
    let text = stdout(&out);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(text.contains("data verdict: not checked"), "{text}");
    assert!(text.contains("final passes"), "{text}");
    assert!(!text.contains("FAILED") && !text.contains("NaN"), "{text}");
}

#[test]
fn with_a_truth_the_table_keeps_the_truth_columns_and_the_checks() {
    let d = dir("truth");
    let (bin, truth, json) = (d.join("run.bin"), d.join("truth.json"), d.join("cal.json"));
    let rec = host_sim()
        .args(["record", "--config", "M2-ps", "--seed", "3", "--out"])
        .arg(&bin)
        .arg("--truth")
        .arg(&truth)
        .output()
        .unwrap();
    assert!(rec.status.success());
    let out = host_sim()
        .args(["calibrate", "--input"])
        .arg(&bin)
        .arg("--truth")
        .arg(&truth)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let v = json_file(&json);
    let _ = std::fs::remove_dir_all(&d);
    let text = stdout(&out);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(
        text.contains("truth ") && text.contains("converged"),
        "{text}"
    );
    assert_eq!(v["data_verdict"]["verdict"], "consistent");
}

/// M1-pa in process (as `host-sim checks`): the clean run is consistent,
/// both defects are flagged, the noise by the NIS.
#[test]
fn m1_pa_in_process_cases() {
    let sc = Scenario::paper();
    let [clean, noise, bias] = cases([10.0, 10.0, 10.0]);
    let j = judge_simulated(
        ConfigId::M1Pa,
        rollcal::models::ErrorModel::Installation,
        &sc,
        1,
        &clean.defect,
    )
    .unwrap();
    assert_eq!(j.verdict, DataVerdict::Consistent, "{}", j.verdict);
    let j = judge_simulated(
        ConfigId::M1Pa,
        rollcal::models::ErrorModel::Installation,
        &sc,
        1,
        &noise.defect,
    )
    .unwrap();
    assert!(
        j.checks
            .iter()
            .any(|c| c.name == "nis" && c.scope == "overall" && !c.passed),
        "{}",
        j.verdict
    );
    let j = judge_simulated(
        ConfigId::M1Pa,
        rollcal::models::ErrorModel::Installation,
        &sc,
        1,
        &bias.defect,
    )
    .unwrap();
    assert!(j.verdict.is_warning(), "{}", j.verdict);
}

/// `host-sim checks` in process: the table, the JSON, both defects flagged.
#[test]
fn the_rates_command_measures_the_cases() {
    let d = dir("rates");
    let json = d.join("rates.json");
    let out = host_sim()
        .args(["checks", "--config", "M1-pa", "--seeds", "2", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    let text = stdout(&out);
    assert_success(&out);
    assert!(
        text.contains("accel noise 3×") && text.contains("(10, 10, 10) µg"),
        "{text}"
    );
    let v = json_file(&json);
    let _ = std::fs::remove_dir_all(&d);
    let rates = v["rates"].as_array().unwrap();
    assert_eq!(rates.len(), 3);
    assert_eq!(rates[0]["case"], "clean");
    for r in &rates[1..] {
        assert_eq!(r["flagged"], 2, "{r}");
    }
    // Bad defect arguments: clap's exit status 2, one line.
    let out = host_sim()
        .args([
            "record",
            "--config",
            "M1-pa",
            "--accel-bias-ug",
            "1,2",
            "--out",
            "-",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let out = host_sim()
        .args([
            "record",
            "--config",
            "M1-pa",
            "--accel-noise-scale",
            "0.5",
            "--out",
            "-",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}
