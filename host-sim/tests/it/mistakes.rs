//! What a user sees for each common mistake (issue 42, items 2 and 9): a
//! CSV log of `record --config M2-ps --seed 3 --format csv` (the paper's
//! scenario) altered as a logger or a platform file gets it wrong, then
//! `calibrate --input LOG --platform FILE`: its exit status and its exact
//! one-line message (`host-sim: error: …`), or, for a data warning, the
//! exact likely cause. docs/own-platform.md §Common mistakes tables them.

use std::path::{Path, PathBuf};
use std::process::Output;

use rand::seq::SliceRandom;
use rand::SeedableRng;

use crate::support;
use support::{assert_success, host_sim, scratch, stderr};

/// The platform file of the paper's settings (scenarios/platform-example.toml).
fn platform() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/platform-example.toml")
}

/// The clean log: `record --config M2-ps --seed 3 --format csv`, as lines.
fn clean_log(dir: &Path) -> Vec<String> {
    let log = dir.join("log.csv");
    assert_success(
        &host_sim()
            .args(["record", "--config", "M2-ps", "--seed", "3"])
            .args(["--format", "csv", "--out"])
            .arg(&log)
            .output()
            .unwrap(),
    );
    std::fs::read_to_string(&log)
        .unwrap()
        .lines()
        .map(String::from)
        .collect()
}

/// The log with every value of the columns `cols` multiplied by `k`.
fn scaled(lines: &[String], cols: &[&str], k: f64) -> Vec<String> {
    let head: Vec<&str> = lines[0].split(',').collect();
    let idx: Vec<usize> = cols
        .iter()
        .map(|c| head.iter().position(|h| h == c).unwrap())
        .collect();
    let mut out = vec![lines[0].clone()];
    for l in &lines[1..] {
        let mut f: Vec<String> = l.split(',').map(String::from).collect();
        for &i in &idx {
            if !f[i].is_empty() {
                f[i] = format!("{:?}", f[i].parse::<f64>().unwrap() * k);
            }
        }
        out.push(f.join(","));
    }
    out
}

/// The log without the columns `cols`.
fn without(lines: &[String], cols: &[&str]) -> Vec<String> {
    let head: Vec<&str> = lines[0].split(',').collect();
    let keep: Vec<usize> = (0..head.len())
        .filter(|i| !cols.contains(&head[*i]))
        .collect();
    lines
        .iter()
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            keep.iter().map(|&i| f[i]).collect::<Vec<_>>().join(",")
        })
        .collect()
}

/// `calibrate --input LOG --platform PLATFORM [extra]` of `lines`.
fn calibrate(dir: &Path, name: &str, lines: &[String], platform: &Path, extra: &[&str]) -> Output {
    let log = dir.join(format!("{name}.csv"));
    std::fs::write(&log, lines.join("\n") + "\n").unwrap();
    host_sim()
        .arg("calibrate")
        .arg("--input")
        .arg(&log)
        .arg("--platform")
        .arg(platform)
        .args(extra)
        .output()
        .unwrap()
}

/// The one line `host-sim: error: …` of a run.
fn error_line(out: &Output) -> String {
    let err = stderr(out);
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("host-sim: error"))
        .collect();
    assert_eq!(lines.len(), 1, "{err}");
    assert!(!err.contains("panicked"), "{err}");
    lines[0].to_string()
}

/// The `likely cause:` line of a run's stdout.
fn cause_line(out: &Output) -> String {
    let text = String::from_utf8_lossy(&out.stdout);
    text.lines()
        .find(|l| l.starts_with("likely cause: "))
        .unwrap_or_else(|| panic!("no likely cause in\n{text}"))
        .to_string()
}

/// A platform file: the example's with `from` replaced by `to`.
fn platform_with(dir: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    let text = std::fs::read_to_string(platform()).unwrap();
    assert!(text.contains(from), "{from}");
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text.replace(from, to)).unwrap();
    path
}

#[test]
fn a_log_the_calibrator_mostly_threw_away_is_not_an_answer() {
    let dir = scratch("mistakes-units");
    let log = clean_log(&dir);
    let p = platform();
    let mut shuffled = log.clone();
    shuffled[1..].shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(1));
    let deg = 180.0 / std::f64::consts::PI;
    let gimbal = ["gimbal_alpha_rad", "gimbal_beta_rad", "gimbal_gamma_rad"];
    let dtheta = ["dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad"];
    let accel = ["accel_x_g", "accel_y_g", "accel_z_g"];
    let more = " (and 3 more reason(s), the `answer:` lines above)";
    let cases: Vec<(&str, Vec<String>, PathBuf, String)> = vec![
        (
            "shuffled",
            shuffled,
            p.clone(),
            format!("not an answer: 5392 of 5400 samples rejected (99.9 %; out_of_order 5392: the lines are out of order: sort the log by seq){more}"),
        ),
        (
            "gimbal-deg",
            scaled(&log, &gimbal, deg),
            p.clone(),
            format!("not an answer: 5269 of 5400 samples rejected (97.6 %; gimbal_range 5269: gimbal angles in degrees (6.290 would be 0.1098 rad): gimbal_*_rad are radians){more}"),
        ),
        (
            "dtheta-deg",
            scaled(&log, &dtheta, deg),
            p.clone(),
            // The increments in degrees that pass the range check drive the
            // filter off: how many more periods it refuses is chaos, the
            // reason named first is not.
            "~samples rejected (| %; increment_range 1800: increments in degrees (0.1000 would be 0.001745 rad): dtheta_*_rad are radians) (and 2 more reason(s), the `answer:` lines above)".into(),
        ),
        (
            "t-ms",
            scaled(&log, &["t_s"], 1000.0),
            p.clone(),
            "not an answer: 5399 of 5400 samples rejected (100.0 %; time_mismatch 5399: time in milliseconds: t_s advances 1000 per period of dt_s (t_s is seconds)) (and 2 more reason(s), the `answer:` lines above)".into(),
        ),
        (
            "t-dt-ms",
            scaled(&log, &["t_s", "dt_s"], 1000.0),
            p.clone(),
            "not an answer: no sample accepted (5400 rejected, 0 bad frames; period 5400: time in milliseconds: dt_s = 1000 for a period of 1 s (t_s and dt_s are seconds))".into(),
        ),
        (
            "accel-m-s2",
            scaled(&log, &accel, 9.80665),
            p.clone(),
            "not an answer: no sample accepted (5400 rejected, 0 bad frames; accel_range 5400: accelerometers in m/s² (|f| = 9.807, 1 g = 9.807 m/s²): the log wants g)".into(),
        ),
        (
            "accel-mg",
            scaled(&log, &accel, 1000.0),
            p.clone(),
            "not an answer: no sample accepted (5400 rejected, 0 bad frames; accel_range 5400: accelerometers in mg (|f| = 1000.0): the log wants g)".into(),
        ),
        (
            "no-gimbal",
            without(&log, &gimbal),
            p.clone(),
            "not an answer: no sample accepted (5400 rejected, 0 bad frames; missing_gimbal 5400: M2-ps measures the gimbal angles: the log has no gimbal_alpha_rad, gimbal_beta_rad, gimbal_gamma_rad columns)".into(),
        ),
        (
            "period",
            log.clone(),
            platform_with(&dir, "period", "period_s = 1.0 ", "period_s = 0.5 "),
            "not an answer: no sample accepted (5400 rejected, 0 bad frames; period 5400: the platform's period (0.5 s, timing.period_s) is not the log's (dt_s = 1 s): give the log's period)".into(),
        ),
    ];
    let print = std::env::var_os("MISTAKES_PRINT").is_some();
    for (name, lines, platform, want) in cases {
        let out = calibrate(&dir, name, &lines, &platform, &[]);
        let line = error_line(&out);
        if print {
            println!("{name}: {:?} {line}", out.status.code());
            continue;
        }
        assert_eq!(out.status.code(), Some(4), "{name}: {}", stderr(&out));
        match want.strip_prefix('~') {
            Some(part) => {
                let (head, tail) = part.split_once('|').unwrap();
                assert!(
                    line.starts_with("host-sim: error: not an answer: ")
                        && line.contains(head)
                        && line.contains(tail),
                    "{name}: {line}"
                );
            }
            None => assert_eq!(line, format!("host-sim: error: {want}"), "{name}"),
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_data_warning_names_the_cause_the_data_fit() {
    let dir = scratch("mistakes-causes");
    let log = clean_log(&dir);
    let p = platform();
    let mut flipped = log.clone();
    let head: Vec<&str> = log[0].split(',').collect();
    let ax = head.iter().position(|h| *h == "accel_x_g").unwrap();
    for l in flipped.iter_mut().skip(1) {
        let mut f: Vec<String> = l.split(',').map(String::from).collect();
        f[ax] = format!("{:?}", -f[ax].parse::<f64>().unwrap());
        *l = f.join(",");
    }
    let noisy = {
        let path = dir.join("noisy.csv");
        assert_success(
            &host_sim()
                .args(["record", "--config", "M2-ps", "--seed", "3"])
                .args(["--accel-noise-scale", "3", "--format", "csv", "--out"])
                .arg(&path)
                .output()
                .unwrap(),
        );
        std::fs::read_to_string(&path)
            .unwrap()
            .lines()
            .map(String::from)
            .collect::<Vec<_>>()
    };
    let cases: Vec<(&str, Vec<String>, PathBuf, i32, &str)> = vec![
        ("noise", noisy, p.clone(), 3, "likely cause: the noise level: noise.accel_g = 3.043e-6 g fits the data (the platform's is 1.000e-6 g) (with it the data fit the model: mean NIS 6.006, not 17.410)"),
        ("latitude", log.clone(), platform_with(&dir, "lat", "latitude_deg = 34.25", "latitude_deg = 45.0"), 3, "likely cause: the latitude: the data fit latitude 34.24° (the platform's is 45.00°) (with it the data fit the model: mean NIS 6.002, not 2.138e5)"),
        ("latitude-sign", log.clone(), platform_with(&dir, "south", "latitude_deg = 34.25", "latitude_deg = -34.25"), 3, "likely cause: the latitude's sign: the data fit latitude 34.25° (the platform's is -34.25°) (with it the data fit the model: mean NIS 6.002, not 3.150e5)"),
        ("earth-rate", log.clone(), platform_with(&dir, "noearth", "earth_rate = true", "earth_rate = false"), 3, "likely cause: the Earth rate: the data fit with it on at latitude 34.25° (site.earth_rate = true) (with it the data fit the model: mean NIS 6.002, not 5.940e8)"),
        ("sign", flipped, p.clone(), 4, "likely cause: a sign: the data fit with accel_x_g negated (the log's accelerometer x axis points the other way) (with it the data fit the model: mean NIS 6.002, not 3.121e40)"),
    ];
    let print = std::env::var_os("MISTAKES_PRINT").is_some();
    for (name, lines, platform, status, want) in cases {
        let out = calibrate(&dir, name, &lines, &platform, &[]);
        let cause = cause_line(&out);
        if print {
            println!("{name}: {:?} {cause}", out.status.code());
            continue;
        }
        assert_eq!(out.status.code(), Some(status), "{name}: {}", stderr(&out));
        assert_eq!(cause, want, "{name}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn options_that_cannot_be_served_are_refused_before_reading() {
    let dir = scratch("mistakes-options");
    // record: what a CSV log cannot carry is refused, not ignored.
    let out = host_sim()
        .args([
            "record", "--config", "M2-ps", "--format", "csv", "--errors", "full", "--out",
        ])
        .arg(dir.join("x.csv"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        error_line(&out),
        "host-sim: error: --errors full: a CSV log has no Configure to carry it (give errors = \"full\" in the platform file, or calibrate --errors full): not with --format csv"
    );
    assert!(!dir.join("x.csv").exists());
    // calibrate: replies back on a serial device that is not the input, an
    // output into a directory that does not exist; nothing read, no report
    // folder made.
    let missing = dir.join("nowhere").join("cal.json");
    for (args, want) in [
        (
            vec!["--replies", "serial"],
            "host-sim: error: --replies serial writes back on the serial device of --input, and /dev/null/none.bin is not one".to_string(),
        ),
        (
            vec!["--json", missing.to_str().unwrap()],
            format!(
                "host-sim: error: --json {}: the directory {} does not exist",
                missing.display(),
                dir.join("nowhere").display()
            ),
        ),
    ] {
        let out = host_sim()
            .args(["calibrate", "--config", "M2-ps", "--input", "/dev/null/none.bin"])
            .arg("--report")
            .arg(dir.join("rep"))
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
        assert_eq!(error_line(&out), want);
        assert!(!dir.join("rep").exists(), "no report folder");
        assert!(!stderr(&out).contains("calibrating"), "nothing read");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A stream's frames with a `Configure` refused mid-stream (an Earth rate
/// of 2e-3 rad/s, above the filter's bound; a negative bias instability,
/// refused naming the field) and a restore of another
/// configuration's checkpoint: each is answered `Refused`, the calibrator
/// stays as it was and the run goes on to the same answer as without them.
#[test]
fn a_refused_configure_or_restore_leaves_the_run_going() {
    use rollcal::models::ConfigId;
    use rollcal::session::AnyCalibrator;
    use rollcal::wire::{encode, CalibratorConfig, Message, MAX_FRAME_LEN};
    let dir = scratch("mistakes-refused");
    let bytes = recorded_m1pa_stream(&dir);
    let frames: Vec<&[u8]> = bytes.split_inclusive(|b| *b == 0).collect();
    let frame = |m: &Message| {
        let mut buf = vec![0u8; MAX_FRAME_LEN];
        let n = encode(m, &mut buf).unwrap();
        buf.truncate(n);
        buf
    };
    let bad = frame(&Message::Configure(CalibratorConfig {
        earth_rate_n: [2e-3, 0.0, 0.0],
        ..CalibratorConfig::paper(ConfigId::M1Pa)
    }));
    // A data-sheet figure with its sign lost: refused naming the field
    // (issue 43).
    let mut negative = CalibratorConfig::paper(ConfigId::M1Pa);
    negative.wander.gyro_markov_sigma = -1.5e-8;
    let negative = frame(&Message::Configure(negative));
    let other = AnyCalibrator::<f64>::new(CalibratorConfig::paper(ConfigId::M4Pa)).unwrap();
    let restore = frame(&Message::Checkpoint(other.checkpoint()));
    let mut altered: Vec<u8> = Vec::new();
    for (k, f) in frames.iter().enumerate() {
        if k == 2000 {
            altered.extend(&bad);
            altered.extend(&negative);
            altered.extend(&restore);
        }
        altered.extend(*f);
    }
    let altered_path = dir.join("altered.bin");
    std::fs::write(&altered_path, &altered).unwrap();
    let run = |input: &Path, json: &Path| {
        host_sim()
            .args(["calibrate", "--input"])
            .arg(input)
            .arg("--json")
            .arg(json)
            .output()
            .unwrap()
    };
    let (a, b) = (dir.join("a.json"), dir.join("b.json"));
    let clean = run(&dir.join("s.bin"), &a);
    let out = run(&altered_path, &b);
    assert_eq!(out.status.code(), clean.status.code(), "{}", stderr(&out));
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("refused: Configure ×1: filter: environment or noise level out of range"),
        "{text}"
    );
    assert!(
        text.contains(
            "refused: Checkpoint (restore) ×1: configuration M4-pa given to a M1-pa calibrator"
        ),
        "{text}"
    );
    assert!(
        text.contains(
            "refused: Configure ×1: wander.gyro_markov_sigma is not finite, negative or outside 0 or 1e-15..4.848e-3 rad/s"
        ),
        "{text}"
    );
    let (va, vb) = (support::json_file(&a), support::json_file(&b));
    assert_eq!(va["states"], vb["states"], "the same answer");
    assert_eq!(vb["refused"].as_array().unwrap().len(), 3);
    std::fs::remove_dir_all(&dir).ok();
}

/// With `--truth`, the instrument terms are judged as the angles are: a
/// truth 12σ from `ba_z`'s estimate is `FAILED`, the others `converged`.
#[test]
fn with_a_truth_every_state_is_judged() {
    let dir = scratch("mistakes-truth");
    let sc = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/instrumented.toml");
    let (stream, truth) = (dir.join("s.bin"), dir.join("t.json"));
    assert_success(
        &host_sim()
            .args(["record", "--config", "M1-pa", "--scenario"])
            .arg(&sc)
            .arg("--out")
            .arg(&stream)
            .arg("--truth")
            .arg(&truth)
            .output()
            .unwrap(),
    );
    let calibrate = |truth: &Path| {
        let out = host_sim()
            .args(["calibrate", "--errors", "full", "--input"])
            .arg(&stream)
            .arg("--truth")
            .arg(truth)
            .output()
            .unwrap();
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let verdict = |text: &str, name: &str| {
        let row = text
            .lines()
            .find(|l| l.starts_with(&format!("{name} ")))
            .unwrap();
        row.split_whitespace().skip(9).collect::<Vec<_>>().join(" ")
    };
    let text = calibrate(&truth);
    for name in ["ba_x", "ba_z", "ka_y", "dg_x", "thaT_1"] {
        assert_eq!(verdict(&text, name), "converged", "{text}");
    }
    // ba_z's truth moved by 12 of its σ (the table's σ column, µg): FAILED.
    let sigma_ug: f64 = text
        .lines()
        .find(|l| l.starts_with("ba_z "))
        .and_then(|row| row.split_whitespace().nth(5))
        .unwrap()
        .parse()
        .unwrap();
    let mut t = support::json_file(&truth);
    let ba_z = 17;
    let was = t["instrument_truth"][ba_z].as_f64().unwrap();
    t["instrument_truth"][ba_z] = (was + 12.0 * sigma_ug * 1e-6).into();
    let moved = dir.join("moved.json");
    std::fs::write(&moved, t.to_string()).unwrap();
    let text = calibrate(&moved);
    assert_eq!(verdict(&text, "ba_z"), "FAILED", "{text}");
    assert_eq!(verdict(&text, "ba_x"), "converged", "{text}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A stream whose only `Configure` carries a bad data-sheet figure (a `k2`
/// prior of 100 g/g²: the data sheet's µg/g² taken for g/g²): refused
/// naming the field, no calibrator runs, and `calibrate` says so and
/// exits with status 1 (an error: docs/cli.md).
#[test]
fn a_stream_whose_only_configure_is_refused_names_the_field() {
    use rollcal::wire::{encode, FrameDecoder, Message, MAX_FRAME_LEN};
    let dir = scratch("mistakes-bad-field");
    let bytes = recorded_m1pa_stream(&dir);
    let mut altered: Vec<u8> = Vec::new();
    for f in bytes.split_inclusive(|b| *b == 0) {
        let mut got = None;
        FrameDecoder::new().feed(f, |m| got = Some(m));
        match got {
            Some(Message::Configure(mut c)) => {
                c.instrument_prior.k2 = 100.0;
                let mut buf = vec![0u8; MAX_FRAME_LEN];
                let n = encode(&Message::Configure(c), &mut buf).unwrap();
                altered.extend(&buf[..n]);
            }
            _ => altered.extend(f),
        }
    }
    let path = dir.join("altered.bin");
    std::fs::write(&path, &altered).unwrap();
    let out = host_sim()
        .args(["calibrate", "--input"])
        .arg(&path)
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let why = "instrument_prior.k2 is not finite, negative or outside 0 or 1e-12..0.01 g/g²";
    assert!(
        err.contains(&format!("note: Configure refused ({why})")),
        "{err}"
    );
    assert!(
        err.contains(&format!(
            "host-sim: error: the stream's Configure was refused ({why}): no calibrator ran"
        )),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// The frames of an M1-pa stream of the paper's scenario (seed 1),
/// recorded into `dir` as `s.bin`.
fn recorded_m1pa_stream(dir: &std::path::Path) -> Vec<u8> {
    let stream = dir.join("s.bin");
    assert_success(
        &host_sim()
            .args(["record", "--config", "M1-pa", "--seed", "1", "--out"])
            .arg(&stream)
            .output()
            .unwrap(),
    );
    std::fs::read(&stream).unwrap()
}
