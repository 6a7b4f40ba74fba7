//! The analysis commands end to end: `paper` (the default), `observability`
//! and `montecarlo` write their documented files, and refuse bad arguments
//! with a clear error.

use std::process::Command;

fn host_sim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
}

fn temp_dir(tag: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("rollcal-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn paper_writes_summary_figures_and_tables() {
    let dir = temp_dir("paper");
    let out = host_sim()
        .args(["paper", "--seed", "2", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("every verdict agrees with the paper"),
        "{stdout}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(v["seed"], 2);
    let configs = v["configs"].as_array().unwrap();
    assert_eq!(configs.len(), 7);
    let mut figures = 0;
    for c in configs {
        for s in c["states"].as_array().unwrap() {
            for key in [
                "name",
                "truth_rad",
                "estimate_rad",
                "error_rad",
                "sigma_filter_rad",
                "sigma_crlb_rad",
                "verdict",
                "paper_observable",
                "agrees_with_paper",
            ] {
                assert!(s.get(key).is_some(), "{} lacks {key}", c["config"]);
            }
            assert_ne!(s["verdict"], "failed", "{} {}", c["config"], s["name"]);
        }
        for f in c["figures"].as_array().unwrap() {
            let png = std::fs::read(dir.join(f.as_str().unwrap())).unwrap();
            assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
            figures += 1;
        }
    }
    // Per configuration: θaT, θgT, θgC, attitude, plus θaC (ps), λ (M2, M3).
    assert_eq!(figures, 7 * 4 + 4 + 3);
    assert!(std::fs::read_to_string(dir.join("summary.md"))
        .unwrap()
        .contains("Which errors can each model observe?"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn observability_json_has_the_documented_schema() {
    let dir = temp_dir("obs");
    let json = dir.join("obs.json");
    let out = host_sim()
        .args(["observability", "--no-earth-rate", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["earth_rate"], false);
    let m1ps = v["configs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["config"] == "M1-ps")
        .unwrap();
    assert_eq!(m1ps["n"], 15);
    assert_eq!(m1ps["rank"], 11);
    let null = m1ps["null_space"].as_array().unwrap();
    assert_eq!(null.len(), 4);
    // The x-axis gauge, as named combination.
    assert!(null.iter().any(|comb| {
        let names: Vec<&str> = comb
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["state"].as_str().unwrap())
            .collect();
        names == ["psi_x", "thgC_x", "thaC_x"]
    }));
    let s0 = &m1ps["states"][0];
    for key in ["name", "sigma_crlb_rad", "ratio", "observable"] {
        assert!(s0.get(key).is_some(), "state lacks {key}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn analysis_commands_reject_bad_arguments() {
    for args in [
        &["montecarlo", "--config", "M2-ps", "--runs", "1"][..],
        &["montecarlo", "--config", "M9-ps", "--runs", "4"][..],
        &["montecarlo", "--runs", "4"][..],
        &["observability", "--bogus"][..],
    ] {
        let out = host_sim().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    // An output directory that cannot be created.
    let dir = temp_dir("paper-bad");
    let file = dir.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let out = host_sim()
        .args(["paper", "--out"])
        .arg(file.join("sub"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("cannot create"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}
