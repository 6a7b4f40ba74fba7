//! The command-line interface: output formats are an interface, and bad
//! arguments or data give clear errors, never a panic.

use std::process::Command;

fn host_sim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
}

#[test]
fn run_writes_the_documented_json_and_csv() {
    let dir = std::env::temp_dir().join(format!("rollcal-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (json, csv) = (dir.join("run.json"), dir.join("run.csv"));
    let out = host_sim()
        .args(["run", "--config", "m4-PA", "--seed", "3", "--json"])
        .arg(&json)
        .arg("--csv")
        .arg(&csv)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["config"], "M4-pa");
    assert_eq!(v["seed"], 3);
    assert_eq!(v["earth_rate"], true);
    assert_eq!(v["duration_s"], 5400.0);
    let states = v["states"].as_array().unwrap();
    let names: Vec<&str> = states.iter().map(|s| s["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "thp_alpha",
            "thp_beta",
            "thp_gamma",
            "thgCpa_x",
            "thgCpa_y",
            "thgCpa_z",
            "thgT_1",
            "thgT_2",
            "thgT_3",
            "thaT_1",
            "thaT_2",
            "thaT_3"
        ]
    );
    for s in states {
        for key in ["truth_rad", "estimate_rad", "sigma_rad"] {
            assert!(
                s[key].as_f64().unwrap().is_finite(),
                "{key} of {}",
                s["name"]
            );
        }
        assert!(s["group"].is_string());
    }
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header[0], "t_s");
    assert_eq!(header[1], "thp_alpha_rad");
    assert_eq!(header[2], "thp_alpha_sigma_rad");
    assert_eq!(header.len(), 1 + 2 * 12);
    assert_eq!(lines.count(), 5400);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_arguments_and_files_are_reported_not_panicked() {
    let out = host_sim()
        .args(["run", "--config", "M5-xx"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown configuration"));

    let dir = std::env::temp_dir().join(format!("rollcal-cli-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    let paper = include_str!("../../scenarios/paper.toml");
    for (edit, expect) in [
        (
            paper.replace("rate_deg_s = 0.1", "rate_deg_s = 0.07"),
            "whole number",
        ),
        (
            paper.replace("axis = \"south\"", "axis = \"sideways\""),
            "unknown axis",
        ),
        (
            paper.replace("latitude_deg = 34.25", "latitude_deg = nan"),
            "latitude",
        ),
        ("not toml at all [".to_string(), "scenario file"),
    ] {
        std::fs::write(&bad, edit).unwrap();
        let out = host_sim()
            .args(["run", "--config", "m1-pa", "--scenario"])
            .arg(&bad)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains(expect), "expected '{expect}' in: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
