//! Lost data loses only itself: the paper's stream through `record` with
//! link and platform impairments, then `calibrate`. Every run must finish
//! with every observable parameter within 4σ of the truth, and count what
//! it bridged, re-acquired, re-anchored, gated and rejected.

use crate::support;
use std::path::PathBuf;
use std::process::Command;
use support::host_sim;

use host_sim::analysis::runner::expected_observable;
use rollcal::models::{ConfigId, Group};

fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rollcal-robust-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn run(cmd: &mut Command) {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{cmd:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `record` (seed 1) with `impair`, then `calibrate --truth`; the JSON.
fn calibrate(
    dir: &std::path::Path,
    id: ConfigId,
    case: &str,
    impair: &[&str],
) -> serde_json::Value {
    let stream = dir.join(format!("{id}-{case}.bin"));
    let truth = dir.join(format!("{id}-truth.json"));
    let json = dir.join(format!("{id}-{case}.json"));
    run(host_sim()
        .args(["record", "--config", id.as_str(), "--seed", "1", "--out"])
        .arg(&stream)
        .arg("--truth")
        .arg(&truth)
        .args(impair));
    run(host_sim()
        .args(["calibrate", "--config", id.as_str(), "--input"])
        .arg(&stream)
        .arg("--truth")
        .arg(&truth)
        .arg("--json")
        .arg(&json));
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

/// The largest |error|/σ over the parameters the paper calls observable.
fn worst(id: ConfigId, v: &serde_json::Value) -> (f64, String) {
    v["states"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|s| {
            let name = s["name"].as_str().unwrap();
            let group = Group::from_name(name).unwrap_or(Group::Attitude);
            expected_observable(id, name, group).then(|| {
                let e = s["estimate_rad"].as_f64().unwrap() - s["truth_rad"].as_f64().unwrap();
                (e.abs() / s["sigma_rad"].as_f64().unwrap(), name.to_string())
            })
        })
        .fold((0.0, String::new()), |a, b| if b.0 > a.0 { b } else { a })
}

/// The largest σ/σ_CRLB (bound of the received samples) over the
/// parameters the paper calls observable.
fn sigma_over_bound(id: ConfigId, v: &serde_json::Value) -> (f64, String) {
    let bound = v["crlb_sigma_rad"].as_array().unwrap();
    v["states"]
        .as_array()
        .unwrap()
        .iter()
        .zip(bound)
        .filter_map(|(s, b)| {
            let name = s["name"].as_str().unwrap();
            let group = Group::from_name(name).unwrap_or(Group::Attitude);
            expected_observable(id, name, group).then(|| {
                (
                    s["sigma_rad"].as_f64().unwrap() / b.as_f64().unwrap(),
                    name.to_string(),
                )
            })
        })
        .fold((0.0, String::new()), |a, b| if b.0 > a.0 { b } else { a })
}

fn counter(v: &serde_json::Value, key: &str) -> u64 {
    v["stream"][key].as_u64().unwrap()
}

#[test]
fn every_loss_case_finishes_within_4_sigma() {
    let dir = temp_dir("loss");
    for id in [ConfigId::M2Ps, ConfigId::M1Pa] {
        let cases: [(&str, &[&str]); 7] = [
            ("clean", &[]),
            ("burst", &["--drop-burst", "2000:1000"]),
            ("random", &["--drop-random", "0.5"]),
            ("switch", &["--drop-burst", "1801:1"]),
            ("clock", &["--clock-step", "2700:2"]),
            ("flips", &["--bit-flips", "1e-3"]),
            ("outliers", &["--outliers", "0.01"]),
        ];
        for (case, impair) in cases {
            let v = calibrate(&dir, id, case, impair);
            let (w, name) = worst(id, &v);
            assert!(w <= 4.0, "{id} {case}: {name} {w:.2}σ");
            // The answer of record, and its σ at the bound of what was received.
            assert_eq!(v["answer"]["kind"], "final", "{id} {case}: {}", v["answer"]);
            assert_eq!(v["crlb_of"], "received samples", "{id} {case}");
            let r = sigma_over_bound(id, &v);
            assert!(r.0 <= 1.1, "{id} {case}: σ/σ_CRLB {:.3} ({})", r.0, r.1);
            let accepted = counter(&v, "accepted");
            let bridged = counter(&v, "bridged");
            let reacquired = counter(&v, "reacquired");
            match case {
                "clean" | "outliers" => assert_eq!((accepted, bridged), (5400, 0), "{id} {case}"),
                // The burst contains one path switch (at 2700 s): its motion is found.
                "burst" => assert_eq!((accepted, bridged, reacquired), (4400, 1000, 0), "{id}"),
                "random" => {
                    assert!((2500..2900).contains(&accepted), "{id} random: {accepted}");
                    // Every period is accepted or bridged (but lost ones at the very end).
                    assert!((5390..=5400).contains(&(accepted + bridged)), "{id} random");
                }
                "switch" => assert_eq!((accepted, bridged, reacquired), (5399, 1, 0), "{id}"),
                "clock" => {
                    assert_eq!((accepted, bridged), (5399, 1), "{id} clock");
                    assert_eq!(counter(&v, "clock_steps"), 1, "{id} clock");
                    assert_eq!(v["stream"]["rejects"]["time_mismatch"], 1, "{id} clock");
                }
                "flips" => {
                    let bad = v["stream"]["frames"]["corrupt"].as_u64().unwrap()
                        + v["stream"]["frames"]["truncated"].as_u64().unwrap();
                    assert!(bad > 100, "{id} flips: {bad} bad frames");
                    let covered = accepted + bridged + reacquired_periods(&v);
                    assert!((5390..=5400).contains(&covered), "{id} flips: {covered}");
                }
                _ => unreachable!(),
            }
            if case == "outliers" {
                // 1 % of 5400 samples carry a 100σ spike: the gate refuses them.
                let gated = counter(&v, "gated");
                assert!((40..=80).contains(&gated), "{id} outliers: {gated} gated");
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

fn reacquired_periods(v: &serde_json::Value) -> u64 {
    counter(v, "reacquired_periods")
}
