//! `calibrate --errors full`: the full model through the no_std session on
//! a recorded stream (protocol version 5), against `run --errors full` on
//! the same seed (one estimator), the truth sidecar's instrument errors,
//! the platform file's `errors` and `[instruments.prior]`, and a stream of
//! another protocol version.

use crate::support;

const INSTRUMENTED: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../scenarios/instrumented.toml"
);

/// A state of a JSON answer: name, estimate, σ (internal units).
type StateRow = (String, f64, f64);

/// The full model's states of `calibrate`'s JSON and `run`'s, paired by
/// name (every state of the configuration, in the same order in both).
fn paired_states(
    cal_json: &std::path::Path,
    run_json: &std::path::Path,
    config: &str,
) -> Vec<(StateRow, StateRow)> {
    let (c, r) = (support::json_file(cal_json), support::json_file(run_json));
    assert_eq!(c["errors"], "full");
    let (c, r) = (states(&c), states(&r));
    assert_eq!(c.len(), if config == "M2-ps" { 54 } else { 48 });
    assert_eq!(c.len(), r.len());
    for (a, b) in c.iter().zip(&r) {
        assert_eq!(a.0, b.0);
    }
    c.into_iter().zip(r).collect()
}

/// Every state's (estimate, σ) of a `--json` file: the installation states
/// (rad), then the instrument errors (printed units).
fn states(v: &serde_json::Value) -> Vec<StateRow> {
    let mut out = Vec::new();
    for s in v["states"].as_array().unwrap() {
        out.push((
            s["name"].as_str().unwrap().to_string(),
            s["estimate_rad"].as_f64().unwrap(),
            s["sigma_rad"].as_f64().unwrap(),
        ));
    }
    for s in v["instruments"].as_array().unwrap_or(&Vec::new()) {
        out.push((
            s["name"].as_str().unwrap().to_string(),
            s["estimate"].as_f64().unwrap(),
            s["sigma"].as_f64().unwrap(),
        ));
    }
    out
}

/// A stream of the instrumented scenario recorded with the installation
/// model's `Configure`, calibrated with `--errors full`, equals `run
/// --errors full` of the same seed within 0.05σ (the stream's f32 samples
/// are the only difference), every state within 4σ of the sidecar's truth;
/// `record --errors full` asks for it in the stream itself; `--matrices`
/// carries every state.
#[test]
fn calibrate_errors_full_is_run_errors_full() {
    let dir = support::scratch("calibrate-full");
    for (config, record_errors) in [("M1-pa", "installation"), ("M2-ps", "full")] {
        let (bin, truth) = (dir.join("s.bin"), dir.join("t.json"));
        let rec = support::host_sim()
            .args(["record", "--config", config, "--scenario", INSTRUMENTED])
            .args(["--errors", record_errors, "--out"])
            .arg(&bin)
            .arg("--truth")
            .arg(&truth)
            .output()
            .unwrap();
        support::assert_success(&rec);
        let (cal_json, run_json) = (dir.join("c.json"), dir.join("r.json"));
        let mut cal = support::host_sim();
        cal.args(["calibrate", "--input"]).arg(&bin);
        if record_errors == "installation" {
            cal.args(["--errors", "full"]);
        }
        let matrices = dir.join("m.json");
        let cal = cal
            .arg("--truth")
            .arg(&truth)
            .arg("--json")
            .arg(&cal_json)
            .arg("--matrices")
            .arg(&matrices)
            .output()
            .unwrap();
        support::assert_success(&cal);
        assert!(
            String::from_utf8_lossy(&cal.stdout).contains("data verdict: consistent"),
            "{config}"
        );
        let run = support::host_sim()
            .args(["run", "--config", config, "--errors", "full", "--scenario"])
            .arg(INSTRUMENTED)
            .arg("--json")
            .arg(&run_json)
            .output()
            .unwrap();
        support::assert_success(&run);
        let pairs = paired_states(&cal_json, &run_json, config);
        for (a, b) in &pairs {
            if b.2 == 0.0 {
                // Not estimated (the Gauss–Markov parts of an instrument
                // without bias instability): held at zero by both.
                assert_eq!((a.1, a.2, b.1), (0.0, 0.0, 0.0), "{config} {}", a.0);
                continue;
            }
            let dx = (a.1 - b.1).abs() / b.2;
            assert!(dx < 0.05, "{config} {}: {dx}σ from run's", a.0);
            assert!((a.2 / b.2 - 1.0).abs() < 1e-3, "{config} {} σ", a.0);
        }
        // The matrices carry every state of the full model.
        let m = support::json_file(&matrices);
        assert_eq!(m["errors"], "full");
        assert_eq!(
            m["all_states"]["names"].as_array().unwrap().len(),
            pairs.len()
        );
        let v = support::json_file(&cal_json);
        // The passes stop on their tolerance: the states held at zero do
        // not keep them from converging (they did, every full-model answer
        // ending "converged: false" after the most passes).
        assert_eq!(v["answer"]["converged"], true, "{config}: {}", v["answer"]);
        for s in v["instruments"].as_array().unwrap() {
            if s["sigma"].as_f64() == Some(0.0) {
                continue; // not estimated (no bias instability here)
            }
            let err = (s["estimate"].as_f64().unwrap() - s["truth"].as_f64().unwrap()).abs()
                / s["sigma"].as_f64().unwrap();
            assert!(err < 4.0, "{config} {}: {err}σ", s["name"]);
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

const REALISTIC: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/realistic.toml");

/// Issue 43 item 1: `calibrate` on a recorded stream of the realistic
/// scenario (the full model's `Configure` in the stream: the wandering
/// errors, the `k2` prior) equals `run --errors full` of the same seed
/// within 0.05σ for every state, M2-ps and M1-pa, with the same σ to 0.1 %
/// (the stream's f32 samples are the only difference); the largest
/// difference is printed.
#[test]
fn calibrate_on_a_realistic_stream_is_run() {
    let dir = support::scratch("calibrate-full-realistic");
    for config in ["M2-ps", "M1-pa"] {
        let bin = dir.join("s.bin");
        let rec = support::host_sim()
            .args(["record", "--config", config, "--scenario", REALISTIC])
            .args(["--seed", "5", "--errors", "full", "--out"])
            .arg(&bin)
            .output()
            .unwrap();
        support::assert_success(&rec);
        let (cal_json, run_json) = (dir.join("c.json"), dir.join("r.json"));
        let cal = support::host_sim()
            .args(["calibrate", "--input"])
            .arg(&bin)
            .arg("--json")
            .arg(&cal_json)
            .output()
            .unwrap();
        support::assert_success(&cal);
        let run = support::host_sim()
            .args(["run", "--config", config, "--errors", "full", "--seed", "5"])
            .args(["--scenario", REALISTIC, "--json"])
            .arg(&run_json)
            .output()
            .unwrap();
        support::assert_success(&run);
        let mut worst = (0.0, String::new());
        for (a, b) in paired_states(&cal_json, &run_json, config) {
            // Every state is estimated: the realistic scenario models
            // every wandering term.
            assert!(b.2 > 0.0, "{config} {}", a.0);
            let dx = (a.1 - b.1).abs() / b.2;
            assert!(dx < 0.05, "{config} {}: {dx}σ from run's", a.0);
            assert!((a.2 / b.2 - 1.0).abs() < 1e-3, "{config} {} σ", a.0);
            if dx > worst.0 {
                worst = (dx, a.0.clone());
            }
        }
        println!("{config}: largest difference {:.4}σ ({})", worst.0, worst.1);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A platform file names the error model and the instruments' prior; a
/// platform file with instrument values, or a prior ≤ 0, is refused naming
/// the field; a stream of protocol version 4 is refused naming both
/// versions.
#[test]
fn platform_file_errors_and_old_streams() {
    let dir = support::scratch("calibrate-full-platform");
    let csv = dir.join("log.csv");
    let rec = support::host_sim()
        .args(["record", "--config", "M1-pa", "--scenario", INSTRUMENTED])
        .args(["--format", "csv", "--out"])
        .arg(&csv)
        .output()
        .unwrap();
    support::assert_success(&rec);
    let platform = |extra: &str| {
        let p = dir.join("platform.toml");
        std::fs::write(
            &p,
            format!(
                "config = \"M1-pa\"\n{extra}\n[site]\nlatitude_deg = 34.25\nearth_rate = true\n\
                 [noise]\naccel_g = 1e-6\ngyro_deg_h = 0.1\ngimbal_arcsec = 10.0\n\
                 [timing]\nperiod_s = 1.0\n[prior]\nsigma_deg = 1.0\n"
            ),
        )
        .unwrap();
        support::host_sim()
            .args(["calibrate", "--input"])
            .arg(&csv)
            .arg("--platform")
            .arg(&p)
            .arg("--json")
            .arg(dir.join("c.json"))
            .output()
            .unwrap()
    };
    let out = platform("errors = \"full\"");
    support::assert_success(&out);
    let v = support::json_file(&dir.join("c.json"));
    assert_eq!(v["errors"], "full");
    assert_eq!(v["data_verdict"]["verdict"], "consistent");
    // Without the instrument errors in the model the log is flagged.
    let out = platform("");
    assert_eq!(out.status.code(), Some(3), "{}", support::stderr(&out));
    assert!(String::from_utf8_lossy(&out.stdout).contains("--errors full"));
    let out = platform("errors = \"full\"\n[instruments]\nba_ug = [1.0, 2.0, 3.0]");
    assert!(!out.status.success());
    let err = support::stderr(&out);
    assert!(err.contains("ba_ug"), "{err}");
    let out = platform("[instruments.prior]\nsigma_ba_ug = -1.0");
    assert!(!out.status.success());
    assert!(
        support::stderr(&out).contains("instruments.prior.sigma_ba_ug = -1 must be finite and ≥ 0")
    );
    let out = platform("errors = \"bias\"");
    assert!(support::stderr(&out).contains("errors: 'bias'"));

    // A version-4 frame: the worked example of docs/wire.md before version 5.
    let v4 = dir.join("v4.bin");
    std::fs::write(
        &v4,
        hex("02 04 05 01 c0 84 3d 01 0b 80 3f 3c 7b e9 10 71 98 5c bf 01 01 01 01 01 01 01 01 01 01 01 01 01 01 01 09 f9 ff 7f 3f 39 c3 64 ba 01 01 01 01 01 01 01 01 01 01 01 01 01 03 80 3f 01 01 01 01 05 aa e7 24 71 00"),
    )
    .unwrap();
    let out = support::host_sim()
        .args(["calibrate", "--input"])
        .arg(&v4)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = support::stderr(&out);
    assert!(
        err.contains("protocol version 4")
            && err.contains(&format!("reads version {}", rollcal::wire::VERSION)),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect()
}
