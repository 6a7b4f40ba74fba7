//! A log may start anywhere on the path: the second half of the paper's
//! path (samples 2701–5400, seed 1), for M2-ps and M1-pa and both error
//! models, as a CSV log with a platform file and as a frame stream that
//! `Reset`s after sample 2700, calibrates from the start its first sample
//! reports (docs/own-platform.md, "A log may start anywhere"): the final
//! passes' answer (exit 0, or 4 naming only states the half's path does not
//! observe), every state within 4σ of the truth, σ at the bound
//! of the received samples, and the same answer, bit for bit, from both
//! inputs.

use crate::support;
use std::path::{Path, PathBuf};
use support::{assert_success, host_sim, json_file, scratch, stderr};

use rollcal::wire::{encode, FrameDecoder, Message, MAX_FRAME_LEN};

/// The first sample of the second half (0-based index).
const HALF: usize = 2700;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

/// The paper's platform file for configuration `config`.
fn platform(dir: &Path, config: &str) -> PathBuf {
    let text = std::fs::read_to_string(repo("scenarios/platform-example.toml"))
        .unwrap()
        .replace("config = \"M2-ps\"", &format!("config = \"{config}\""));
    let file = dir.join(format!("platform-{config}.toml"));
    std::fs::write(&file, text).unwrap();
    file
}

/// `record` of the paper's path (seed 1) for `config`, cut after sample
/// 2700: the CSV log of samples 2701–5400, the frame stream with a `Reset`
/// after sample 2700, and the truth sidecar (its final states are the
/// second half's, which ends where the path does).
fn second_half(dir: &Path, config: &str) -> (PathBuf, PathBuf, PathBuf) {
    let (csv, bin, truth) = (
        dir.join(format!("{config}.csv")),
        dir.join(format!("{config}.bin")),
        dir.join(format!("{config}-truth.json")),
    );
    for (format, out) in [("csv", &csv), ("frames", &bin)] {
        let rec = host_sim()
            .args([
                "record", "--config", config, "--seed", "1", "--format", format,
            ])
            .arg("--out")
            .arg(out)
            .arg("--truth")
            .arg(&truth)
            .output()
            .unwrap();
        assert_success(&rec);
    }
    let text = std::fs::read_to_string(&csv).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 5401);
    let half: Vec<&str> = [lines[0]]
        .into_iter()
        .chain(lines[HALF + 1..].iter().copied())
        .collect();
    assert!(half[1].starts_with("2701,"));
    let half_csv = dir.join(format!("{config}-half.csv"));
    std::fs::write(&half_csv, half.join("\n") + "\n").unwrap();

    let mut messages = Vec::new();
    FrameDecoder::new().feed(&std::fs::read(&bin).unwrap(), |m| messages.push(m));
    assert!(matches!(messages[0], Message::Configure(_)));
    assert_eq!(messages.len(), 5401);
    messages.insert(HALF + 1, Message::Reset);
    let mut bytes = Vec::new();
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    for m in &messages {
        let n = encode(m, &mut buf).unwrap();
        bytes.extend_from_slice(&buf[..n]);
    }
    let reset_bin = dir.join(format!("{config}-reset.bin"));
    std::fs::write(&reset_bin, bytes).unwrap();
    (half_csv, reset_bin, truth)
}

/// `calibrate ARGS --errors ERRORS --json OUT`: the JSON and stderr. Exit
/// 0, or 4 ("not an answer") for the one reason half a path may give: the
/// states it names are ones this log's path does not observe (their bound
/// on the received samples as wide as σ), not ones the calibrator failed
/// to learn.
fn calibrate(args: &[&std::ffi::OsStr], errors: &str, out: &Path) -> (serde_json::Value, String) {
    let run = host_sim()
        .arg("calibrate")
        .args(args)
        .args(["--errors", errors, "--json"])
        .arg(out)
        .output()
        .unwrap();
    let v = json_file(out);
    match run.status.code() {
        Some(0) => assert_eq!(v["answer"]["usable"], true),
        Some(4) => {
            let why = v["answer"]["not_an_answer"].as_array().unwrap();
            assert_eq!(why.len(), 1, "{}", stderr(&run));
            assert_eq!(why[0]["kind"], "unobserved", "{}", stderr(&run));
            assert_eq!(why[0]["path_limited"], true, "{}", stderr(&run));
        }
        _ => assert_success(&run),
    }
    (v, stderr(&run))
}

/// Every state (installation and instrument terms) as (name, estimate, σ,
/// truth), in the units of the JSON.
fn states(v: &serde_json::Value) -> Vec<(String, f64, f64, f64)> {
    let f = |s: &serde_json::Value, k: &str| s[k].as_f64().unwrap_or(f64::NAN);
    let installation = v["states"].as_array().unwrap().iter().map(|s| {
        (
            s["name"].as_str().unwrap().to_string(),
            f(s, "estimate_rad"),
            f(s, "sigma_rad"),
            f(s, "truth_rad"),
        )
    });
    let instruments = v["instruments"].as_array().into_iter().flatten().map(|s| {
        (
            s["name"].as_str().unwrap().to_string(),
            f(s, "estimate"),
            f(s, "sigma"),
            f(s, "truth"),
        )
    });
    installation.chain(instruments).collect()
}

/// What a calibration against its truth came to: the answer, the worst
/// |error|/σ over every state, and the range of σ/σ_CRLB (received
/// samples, at the truth) over the installation states whose bound is
/// below 0.1°.
struct Judged {
    answer: String,
    worst: (f64, String),
    ratio: (f64, f64),
}

/// Judges the JSON of `calibrate --truth`: every state within 4σ of the
/// truth.
fn judge(tag: &str, v: &serde_json::Value) -> Judged {
    // The installation states' bound (rad; the instrument terms follow in
    // internal units, their σ in the JSON in printed units).
    let installation = v["states"].as_array().unwrap().len();
    let crlb = &v["crlb_sigma_rad"].as_array().unwrap()[..installation];
    let mut worst = (0.0, String::new());
    let mut ratio = (f64::INFINITY, 0.0f64);
    for (k, (name, x, s, t)) in states(v).into_iter().enumerate() {
        // A state the model does not estimate (prior σ 0: the wandering
        // errors of a scenario without them) is not judged.
        if s == 0.0 {
            assert_eq!(x, t, "{tag}: {name} not estimated");
            continue;
        }
        let z = (x - t).abs() / s;
        assert!(z <= 4.0, "{tag}: {name} {z:.2}σ off the truth");
        if z > worst.0 {
            worst = (z, name.clone());
        }
        match crlb.get(k).and_then(serde_json::Value::as_f64) {
            Some(b) if b < 0.1 * 1f64.to_radians() => {
                ratio = (ratio.0.min(s / b), ratio.1.max(s / b));
            }
            _ => {}
        }
    }
    let a = &v["answer"];
    Judged {
        answer: format!(
            "{}, {} passes{}",
            a["kind"].as_str().unwrap(),
            a["passes"],
            if a["converged"] == true {
                ", converged"
            } else {
                ""
            }
        ),
        worst,
        ratio,
    }
}

/// Prints a row of the table in docs/own-platform.md.
fn row(config: &str, errors: &str, log: &str, v: &serde_json::Value, j: &Judged) {
    let unobserved: Vec<&str> = v["answer"]["not_an_answer"]
        .as_array()
        .into_iter()
        .flatten()
        .flat_map(|w| w["states"].as_array().into_iter().flatten())
        .filter_map(serde_json::Value::as_str)
        .collect();
    let exit = if unobserved.is_empty() {
        "0".to_string()
    } else {
        format!(
            "4: the log's path does not observe {}",
            unobserved.join(", ")
        )
    };
    eprintln!(
        "| {config} | {errors} | {log} | {exit} | {} | {:.2} ({}) | {:.3}–{:.3} |",
        j.answer, j.worst.0, j.worst.1, j.ratio.0, j.ratio.1
    );
}

#[test]
fn the_second_half_of_the_path_calibrates_as_a_log_of_its_own() {
    let dir = scratch("mid-path");
    // The first half, from the path's start, for comparison: the paper's
    // first two segments (South 180°, East 90°), the same shape of path as
    // the second half.
    let first = support::paper_with_path(
        &dir,
        "first-half",
        &[("south", 180.0, 0.1), ("east", 90.0, 0.1)],
        "2700.0",
    );
    for config in ["M2-ps", "M1-pa"] {
        let (csv, reset, truth) = second_half(&dir, config);
        let plat = platform(&dir, config);
        let (first_csv, first_truth) = (dir.join("first.csv"), dir.join("first-truth.json"));
        let rec = host_sim()
            .args([
                "record",
                "--config",
                config,
                "--format",
                "csv",
                "--scenario",
            ])
            .arg(&first)
            .arg("--out")
            .arg(&first_csv)
            .arg("--truth")
            .arg(&first_truth)
            .output()
            .unwrap();
        assert_success(&rec);
        for errors in ["installation", "full"] {
            let tag = format!("{config}-{errors}");
            let (a, _) = calibrate(
                &[
                    "--input".as_ref(),
                    csv.as_os_str(),
                    "--platform".as_ref(),
                    plat.as_os_str(),
                    "--truth".as_ref(),
                    truth.as_os_str(),
                ],
                errors,
                &dir.join(format!("{tag}-csv.json")),
            );
            assert_eq!(a["answer"]["kind"], "final", "{tag}: {}", a["answer"]);
            assert_eq!(a["crlb_of"], "received samples", "{tag}");
            assert_eq!(a["stream"]["accepted"], 2700, "{tag}");
            let j = judge(&tag, &a);
            // σ at the bound of the received samples for the installation
            // model (the full model's, on half the path: below).
            if errors == "installation" {
                assert!(j.ratio.0 > 0.95 && j.ratio.1 < 1.05, "{tag}: {:?}", j.ratio);
            }
            row(config, errors, "samples 2701–5400", &a, &j);

            // The frame stream that resets after sample 2700: the same
            // answer, bit for bit.
            let (b, notes) = calibrate(
                &[
                    "--input".as_ref(),
                    reset.as_os_str(),
                    "--truth".as_ref(),
                    truth.as_os_str(),
                ],
                errors,
                &dir.join(format!("{tag}-reset.json")),
            );
            assert!(
                notes.contains("Reset mid-stream: restarting the calibrator"),
                "{notes}"
            );
            assert_eq!(
                states(&a),
                states(&b),
                "{tag}: CSV half against the reset stream"
            );
            assert_eq!(a["answer"], b["answer"], "{tag}");

            // Without a truth: σ is the bound at the estimate.
            let (c, _) = calibrate(
                &[
                    "--input".as_ref(),
                    csv.as_os_str(),
                    "--platform".as_ref(),
                    plat.as_os_str(),
                ],
                errors,
                &dir.join(format!("{tag}-notruth.json")),
            );
            let at = c["bound_at_estimate_sigma_rad"].as_array().unwrap();
            for (s, b) in c["states"].as_array().unwrap().iter().zip(at) {
                let ratio = s["sigma_rad"].as_f64().unwrap() / b.as_f64().unwrap();
                assert!(
                    (ratio - 1.0).abs() < 0.01,
                    "{tag}: {} σ/bound {ratio:.4}",
                    s["name"]
                );
            }

            // The first half, from the path's start.
            let (f, _) = calibrate(
                &[
                    "--input".as_ref(),
                    first_csv.as_os_str(),
                    "--platform".as_ref(),
                    plat.as_os_str(),
                    "--truth".as_ref(),
                    first_truth.as_os_str(),
                ],
                errors,
                &dir.join(format!("{tag}-first.json")),
            );
            row(config, errors, "samples 1–2700", &f, &judge(&tag, &f));
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A CSV log without the `ccn_q*` columns is integrated from the path's
/// start (`C^c_n = I`): one that starts elsewhere is refused with a line
/// that says so, not calibrated wrong.
#[test]
fn a_log_without_frames_that_does_not_start_at_the_paths_start_is_refused() {
    let dir = scratch("mid-path-noframes");
    let (csv, _, _) = second_half(&dir, "M1-pa");
    let text = std::fs::read_to_string(&csv).unwrap();
    let cut: String = text
        .lines()
        .map(|l| l.split(',').take(12).collect::<Vec<_>>().join(","))
        .collect::<Vec<_>>()
        .join("\n");
    let no_frames = dir.join("no-frames.csv");
    std::fs::write(&no_frames, cut + "\n").unwrap();
    let run = host_sim()
        .args(["calibrate", "--input"])
        .arg(&no_frames)
        .arg("--platform")
        .arg(platform(&dir, "M1-pa"))
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(1), "{}", stderr(&run));
    let err = stderr(&run);
    assert!(err.contains("needs the ccn_q* columns"), "{err}");
    assert_eq!(
        err.lines().filter(|l| l.contains("error")).count(),
        1,
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
