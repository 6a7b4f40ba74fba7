//! The CSV log and platform files (docs/csv.md): a real platform's inputs.
//! Deterministic: every record is seeded.

use crate::support;
use std::path::{Path, PathBuf};
use std::process::Output;
use support::{assert_success, host_sim, json_file, stderr};

use host_sim::io::csvlog;
use host_sim::sim::scenario::Platform;
use rollcal::wire::{FrameDecoder, Message, Sample};

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

fn dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rollcal-csv-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn ok(out: Output) -> Output {
    assert_success(&out);
    out
}

fn record(config: &str, seed: &str, format: &str, out: &Path) {
    ok(host_sim()
        .args([
            "record", "--config", config, "--seed", seed, "--format", format,
        ])
        .arg("--out")
        .arg(out)
        .output()
        .unwrap());
}

fn frame_samples(path: &Path) -> Vec<Sample> {
    let mut d = FrameDecoder::new();
    let mut v = Vec::new();
    d.feed(&std::fs::read(path).unwrap(), |m| {
        if let Message::Sample(s) = m {
            v.push(s);
        }
    });
    v
}

/// `record --format csv` writes the samples of `record` (frames) of the same
/// seed, and parsing the CSV gives them back bit for bit: floats are written
/// in Rust's shortest round-trip form, the time as exact microseconds.
#[test]
fn csv_round_trips_the_frame_samples() {
    let d = dir("roundtrip");
    let (bin, csv) = (d.join("a.bin"), d.join("a.csv"));
    record("M2-ps", "4", "frames", &bin);
    record("M2-ps", "4", "csv", &csv);
    let frames = frame_samples(&bin);
    assert_eq!(frames.len(), 5400);
    let text = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(text.lines().next().unwrap(), csvlog::header());
    let log = csvlog::parse(&text).unwrap();
    assert!(log.has_frames);
    assert_eq!(log.samples, frames);
    // And back: writing the parsed samples reproduces the file.
    assert_eq!(csvlog::write(&log.samples), text);
    // Without the ccn_q* columns the computed frame is integrated from the
    // increments: the same quaternions to f32 rounding.
    let short: String = text
        .lines()
        .map(|l| l.split(',').take(12).collect::<Vec<_>>().join(",") + "\n")
        .collect();
    let mut log = csvlog::parse(&short).unwrap();
    assert!(!log.has_frames);
    let settings = rollcal::wire::CalibratorConfig::paper(rollcal::models::ConfigId::M2Ps);
    csvlog::fill_frames(&mut log.samples, &settings).unwrap();
    for (a, b) in log.samples.iter().zip(&frames) {
        for (x, y) in a.c_cn_quat.iter().zip(&b.c_cn_quat) {
            assert!((x - y).abs() < 1e-6, "seq {}: {x} vs {y}", a.seq);
        }
    }
    std::fs::remove_dir_all(&d).ok();
}

/// Frames → CSV → calibrate gives bit-identical final estimates and σ to
/// calibrating the frames: the samples are bit-identical (above), the
/// platform file's settings are the `Configure` message's to the bit (the
/// same arithmetic from the same numbers), and the calibrator is driven
/// the same way (`Configure`, then the samples).
#[test]
fn calibrating_the_csv_equals_calibrating_the_frames() {
    let d = dir("same");
    let (bin, csv) = (d.join("b.bin"), d.join("b.csv"));
    for config in ["M2-ps", "M1-pa"] {
        record(config, "2", "frames", &bin);
        record(config, "2", "csv", &csv);
        let (fj, cj, pj) = (d.join("f.json"), d.join("c.json"), d.join("p.json"));
        ok(host_sim()
            .args(["calibrate", "--input"])
            .arg(&bin)
            .arg("--json")
            .arg(&fj)
            .output()
            .unwrap());
        // A scenario file read as a platform file (its truth ignored).
        ok(host_sim()
            .args(["calibrate", "--config", config, "--input"])
            .arg(&csv)
            .arg("--platform")
            .arg(repo("scenarios/paper.toml"))
            .arg("--json")
            .arg(&cj)
            .output()
            .unwrap());
        let (f, c) = (json_file(&fj), json_file(&cj));
        assert_eq!(f["config"], config);
        assert_eq!(c["stream"]["format"], "csv");
        assert_eq!(f["stream"]["accepted"], c["stream"]["accepted"]);
        assert_eq!(f["passes"], c["passes"]);
        for (a, b) in f["states"]
            .as_array()
            .unwrap()
            .iter()
            .zip(c["states"].as_array().unwrap())
        {
            assert_eq!(a["name"], b["name"]);
            assert_eq!(
                a["estimate_rad"], b["estimate_rad"],
                "{config} {}",
                a["name"]
            );
            assert_eq!(a["sigma_rad"], b["sigma_rad"], "{config} {}", a["name"]);
        }
        assert_eq!(f["pass1"], c["pass1"], "{config}");
        if config == "M2-ps" {
            // The example platform file (no truth, names M2-ps): the same answer.
            ok(host_sim()
                .args(["calibrate", "--input"])
                .arg(&csv)
                .arg("--platform")
                .arg(repo("scenarios/platform-example.toml"))
                .arg("--json")
                .arg(&pj)
                .output()
                .unwrap());
            let p = json_file(&pj);
            assert_eq!(p["states"], c["states"]);
        }
    }
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn a_platform_file_needs_no_truth() {
    let text = "config = \"m4-pa\"\n\
        [site]\nlatitude_deg = -30.0\nearth_rate = true\n\
        [noise]\naccel_g = 5e-7\ngyro_deg_h = 0.2\ngimbal_arcsec = 20.0\n\
        [timing]\nperiod_s = 1.0\n\
        [prior]\nsigma_deg = 1.0\n";
    let p = Platform::from_toml(text).unwrap();
    assert_eq!(p.config_id(), Some(rollcal::models::ConfigId::M4Pa));
    assert!(p.path.is_empty());
    let p = Platform::from_file(&repo("scenarios/platform-example.toml")).unwrap();
    assert_eq!(p.config_id(), Some(rollcal::models::ConfigId::M2Ps));
    // Bad fields: one line naming the field.
    for (bad, word) in [
        (text.replace("-30.0", "-95.0"), "latitude_deg"),
        (text.replace("m4-pa", "M9-xx"), "unknown configuration"),
        (text.replace("accel_g = 5e-7", "accel_g = 0.0"), "accel_g"),
        (text.replace("[prior]\nsigma_deg = 1.0\n", ""), "prior"),
        (text.replace("period_s", "periode_s"), "periode_s"),
    ] {
        let e = Platform::from_toml(&bad).unwrap_err().to_string();
        assert!(e.contains(word) && !e.trim().contains('\n'), "{word}: {e}");
    }
}

/// The error line (the last line of stderr).
fn error_line(out: &Output) -> String {
    let e = stderr(out);
    let last = e.lines().last().unwrap_or_default().to_string();
    assert!(last.starts_with("host-sim: error: "), "{e}");
    assert!(!e.contains("panicked"), "{e}");
    last
}

#[test]
fn a_contradicting_config_is_an_error_naming_both() {
    let d = dir("contra");
    let (bin, csv) = (d.join("c.bin"), d.join("c.csv"));
    record("M2-ps", "1", "frames", &bin);
    record("M2-ps", "1", "csv", &csv);
    // Against the platform file's configuration.
    let out = host_sim()
        .args(["calibrate", "--config", "M1-pa", "--input"])
        .arg(&csv)
        .arg("--platform")
        .arg(repo("scenarios/platform-example.toml"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let e = error_line(&out);
    assert!(e.contains("M1-pa") && e.contains("M2-ps"), "{e}");
    assert_eq!(stderr(&out).lines().count(), 1, "{}", stderr(&out));
    // Against the stream's Configure.
    let out = host_sim()
        .args(["calibrate", "--config", "M1-pa", "--input"])
        .arg(&bin)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let e = error_line(&out);
    assert!(e.contains("M1-pa") && e.contains("M2-ps"), "{e}");
    // The stream's Configure against the platform file's configuration.
    let m1 = d.join("m1.toml");
    std::fs::write(
        &m1,
        std::fs::read_to_string(repo("scenarios/platform-example.toml"))
            .unwrap()
            .replace("config = \"M2-ps\"", "config = \"M1-pa\""),
    )
    .unwrap();
    let out = host_sim()
        .args(["calibrate", "--input"])
        .arg(&bin)
        .arg("--platform")
        .arg(&m1)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let e = error_line(&out);
    assert!(e.contains("M1-pa") && e.contains("M2-ps"), "{e}");
    // A CSV log without any configuration.
    let out = host_sim()
        .args(["calibrate", "--input"])
        .arg(&csv)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(error_line(&out).contains("--config"));
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn a_malformed_csv_line_is_a_one_line_error_with_its_number() {
    let h = csvlog::header();
    let good = "1,1.000000,1,0.001,0,0,0,1,0,0,0,0,1,0,0,0";
    let cases = [
        (format!("{h}\n{good}\n1,2.0,1,0,0\n"), "line 3", "5 columns"),
        (
            format!("# a comment\n{h}\n{good}\n2,2.0,1,0.001,0,0,zero,1,0,0,0,0,1,0,0,0\n"),
            "line 4",
            "accel_x_g",
        ),
        (format!("{h}\n-1,{}\n", &good[2..]), "line 2", "seq"),
        ("seq,t_s\n".to_string(), "line 1", "dt_s"),
        // An unknown column is ignored: the missing required one is the error.
        ("seq,t_s,bogus\n".to_string(), "line 1", "dt_s"),
    ];
    for (text, line, word) in &cases {
        let e = csvlog::parse(text).unwrap_err().to_string();
        assert!(e.contains(line) && e.contains(word), "{e}");
        assert!(!e.contains('\n'), "{e}");
    }
    // Through the command line: exit 1, the file and the line named.
    let d = dir("malformed");
    let bad = d.join("bad.csv");
    std::fs::write(&bad, &cases[1].0).unwrap();
    let out = host_sim()
        .args(["calibrate", "--input"])
        .arg(&bad)
        .arg("--platform")
        .arg(repo("scenarios/platform-example.toml"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let e = error_line(&out);
    assert!(e.contains("bad.csv: line 4: column accel_x_g"), "{e}");
    // --format overrides the extension: a CSV named .log is read as CSV.
    let log = d.join("good.log");
    std::fs::write(&log, format!("{h}\n{good}\n")).unwrap();
    let out = host_sim()
        .args(["calibrate", "--format", "csv", "--passes", "1", "--input"])
        .arg(&log)
        .arg("--platform")
        .arg(repo("scenarios/platform-example.toml"))
        .output()
        .unwrap();
    assert!(!stderr(&out).contains("panicked"), "{}", stderr(&out));
    std::fs::remove_dir_all(&d).ok();
}

/// The CSV of `record` (M1-pa, seed 2) with a line's fields rewritten by
/// `edit` (the header too), written to `dir/name`.
fn rewritten(dir: &Path, name: &str, edit: impl Fn(usize, Vec<String>) -> Vec<String>) -> PathBuf {
    let src = dir.join("src.csv");
    if !src.exists() {
        record("M1-pa", "2", "csv", &src);
    }
    let text: String = std::fs::read_to_string(&src)
        .unwrap()
        .lines()
        .enumerate()
        .map(|(i, l)| edit(i, l.split(',').map(String::from).collect()).join(",") + "\n")
        .collect();
    let out = dir.join(name);
    std::fs::write(&out, text).unwrap();
    out
}

/// `calibrate --input LOG --platform (M1-pa) --json OUT`: the JSON and stderr.
fn calibrate_csv(dir: &Path, log: &Path) -> (serde_json::Value, String) {
    let platform = dir.join("m1pa.toml");
    let text = std::fs::read_to_string(repo("scenarios/platform-example.toml"))
        .unwrap()
        .replace("config = \"M2-ps\"", "config = \"M1-pa\"");
    std::fs::write(&platform, text).unwrap();
    let json = dir.join("out.json");
    let out = ok(host_sim()
        .args(["calibrate", "--input"])
        .arg(log)
        .arg("--platform")
        .arg(&platform)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap());
    (json_file(&json), stderr(&out))
}

/// A column docs/csv.md does not name (a temperature, a status word) is
/// read past and named in one note on stderr; the answer is the log's
/// without it, bit for bit.
#[test]
fn unknown_columns_are_ignored_with_a_note() {
    let d = dir("extra");
    let plain = rewritten(&d, "plain.csv", |_, f| f);
    let extra = rewritten(&d, "extra.csv", |i, mut f| {
        let t = if i == 0 {
            "temperature_c".to_string()
        } else {
            format!("{:.2}", 21.5 + i as f64 * 1e-3)
        };
        f.insert(3, t);
        f.push(if i == 0 {
            "status".into()
        } else {
            "0x0".into()
        });
        f
    });
    let (a, note_a) = calibrate_csv(&d, &plain);
    let (b, note_b) = calibrate_csv(&d, &extra);
    assert!(!note_a.contains("ignored"), "{note_a}");
    let notes: Vec<&str> = note_b.lines().filter(|l| l.contains("ignored")).collect();
    assert_eq!(notes.len(), 1, "{note_b}");
    assert!(
        notes[0].contains("'temperature_c', 'status' ignored"),
        "{}",
        notes[0]
    );
    assert_eq!(a["states"], b["states"]);
    assert_eq!(a["answer"], b["answer"]);
    std::fs::remove_dir_all(&d).ok();
}

/// Lines are taken in file order, as a stream's samples: a line whose
/// sequence number is not above the last accepted one is rejected
/// (`out_of_order`), and a line that comes early opens a gap that its
/// `C^c_n` bridges. Two lines swapped lose one period; a log in reverse
/// order keeps only its first line.
#[test]
fn lines_out_of_time_order_are_rejected_as_a_streams_samples_are() {
    let d = dir("order");
    let swapped = rewritten(&d, "swapped.csv", |_, f| f);
    let text = std::fs::read_to_string(&swapped).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    lines.swap(100, 101);
    std::fs::write(&swapped, lines.join("\n") + "\n").unwrap();
    let (a, _) = calibrate_csv(&d, &swapped);
    assert_eq!(a["stream"]["accepted"], 5399, "{}", a["stream"]);
    assert_eq!(a["stream"]["bridged"], 1, "{}", a["stream"]);
    assert_eq!(a["stream"]["rejects"]["out_of_order"], 1, "{}", a["stream"]);
    let reversed = d.join("reversed.csv");
    let body: Vec<&str> = lines[1..].iter().rev().copied().collect();
    std::fs::write(&reversed, format!("{}\n{}\n", lines[0], body.join("\n"))).unwrap();
    let json = d.join("rev.json");
    let out = host_sim()
        .args(["calibrate", "--input"])
        .arg(&reversed)
        .arg("--platform")
        .arg(d.join("m1pa.toml"))
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert!(!stderr(&out).contains("panicked"), "{}", stderr(&out));
    let r = json_file(&json);
    assert_eq!(r["stream"]["accepted"], 1, "{}", r["stream"]);
    assert_eq!(
        r["stream"]["rejects"]["out_of_order"], 5399,
        "{}",
        r["stream"]
    );
    std::fs::remove_dir_all(&d).ok();
}

/// docs/csv.md's quaternion convention, held to the code: scalar first,
/// the passive DCM `C^c_n = R(θ)`; the paper path's first second (0.1°
/// about South) and a quarter turn about Up.
#[test]
fn the_quaternion_convention_is_the_documented_one() {
    use rollcal::geometry::{dcm, quaternion_from_dcm, r2};
    let deg = std::f64::consts::PI / 180.0;
    let south = quaternion_from_dcm(&dcm(&nalgebra::Vector3::new(-0.1 * deg, 0.0, 0.0)));
    assert_eq!(
        south.map(|v| v as f32),
        [0.99999964, -0.0008726645, 0.0, 0.0]
    );
    let up = quaternion_from_dcm(&r2(90.0 * deg));
    // docs/csv.md's digits of cos 45° = sin 45°.
    let half = std::f64::consts::FRAC_1_SQRT_2;
    assert_eq!(format!("{half:.7}"), "0.7071068");
    let want = [half, 0.0, half, 0.0];
    assert!(
        up.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-15),
        "{up:?}"
    );
}
