//! `host-sim design`'s answer: for one's own platform (`--platform`, no
//! truth: the bound at nominal values), and a headline that agrees with
//! the numbers under it and with the path it writes, whichever search gave
//! it (the shortest path, the budget search, or the full model's budget
//! search standing in for a shortest path it could not find).

use crate::support;
use std::path::{Path, PathBuf};
use std::process::Output;
use support::{json_file, scratch, stderr};

use host_sim::sim::scenario::Scenario;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

/// `design ARGS` in `dir`, writing `d.toml`, `d.png`, `d.json`.
fn design(dir: &Path, args: &[&str]) -> Output {
    support::host_sim()
        .current_dir(dir)
        .arg("design")
        .args(args)
        .args(["--out", "d.toml", "--figure", "d.png", "--json", "d.json"])
        .output()
        .unwrap()
}

/// The number after `prefix` on the first stdout line that has it.
fn number_after(out: &str, prefix: &str) -> Option<f64> {
    let at = out.find(prefix)? + prefix.len();
    let rest = &out[at..];
    let end = rest
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
        .unwrap_or(rest.len());
    rest[..end].parse().ok()
}

/// The headline against the numbers and the files: the duration it states
/// is the written scenario's and the JSON's, and every target is met when
/// it says so (and not otherwise).
fn check_headline(dir: &Path, out: &Output) -> serde_json::Value {
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let json = json_file(&dir.join("d.json"));
    let written = Scenario::from_file(&dir.join("d.toml")).unwrap();
    let duration = json["duration_s"].as_f64().unwrap();
    assert_eq!(written.timing.duration_s, duration, "{text}");
    let ratios: Vec<f64> = json["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["designed_sigma_rad"].as_f64().unwrap() / t["target_rad"].as_f64().unwrap())
        .collect();
    let worst = ratios.iter().copied().fold(0.0, f64::max);
    let met = json["all_targets_met"].as_bool().unwrap();
    assert_eq!(met, worst <= 1.0, "{text}");
    let to_every = [
        "Shortest path to every target: ",
        "A path to every target: ",
    ]
    .iter()
    .find_map(|p| number_after(&text, p));
    match to_every {
        Some(t) => {
            assert_eq!(t, duration, "{text}");
            assert!(met, "{text}");
            if text.contains("Every target is met within the limits") {
                assert!(
                    text.contains(&format!("), at {duration} s.")),
                    "the met line names another time than the headline: {text}"
                );
            }
        }
        None => {
            // A budget: the headline's worst ratio is the JSON's.
            let said = [
                "Best worst-case σ/target within ",
                "No path to every target within ",
            ]
            .iter()
            .find_map(|p| number_after(&text, p))
            .expect("a headline");
            assert_eq!(said, duration, "{text}");
            let shown = number_after(&text, "σ/target of ")
                .or_else(|| number_after(&text, &format!("within {duration} s: ")))
                .expect("the worst ratio in the headline");
            assert!(
                (shown - worst).abs() <= 5e-4 * worst.max(1.0),
                "{shown} vs {worst}: {text}"
            );
        }
    }
    json
}

/// The full model's shortest-path search finds no path in its coarse
/// stage; the budget search stands in. When its best path meets every
/// target it is cut there and called a path to every target (not the
/// shortest); when it does not, the headline says no path reaches them,
/// the written path is the limit's, and the exit status is 1.
#[test]
fn the_headline_agrees_with_the_numbers_and_the_written_path() {
    let dir = scratch("design-headline");
    let instrumented = repo("scenarios/instrumented.toml");
    let full = [
        "--config",
        "M2-ps",
        "--errors",
        "full",
        "--scenario",
        instrumented.to_str().unwrap(),
        "--refine-starts",
        "1",
        "--axes",
        "west,south,north",
        "--no-dwells",
    ];
    // Stage 1 finds none, the budget search's best meets every target.
    let out = design(&dir, &[&full[..], &["--max-rotations", "2"]].concat());
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(text.contains("A path to every target: "), "{text}");
    assert!(text.contains("Not the shortest"), "{text}");
    assert!(!text.contains("optimality: exact"), "{text}");
    let json = check_headline(&dir, &out);
    assert_eq!(json["fallback"], true);
    assert_eq!(json["goal"], "shortest");
    assert!(json["duration_s"].as_f64().unwrap() < 5400.0);

    // One rotation per pattern: nothing meets every target within 5400 s.
    let out = design(&dir, &[&full[..], &["--max-rotations", "1"]].concat());
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("out of reach within the limits (listed above): the best path within them is written to d.toml"), "{err}");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        text.contains("No path to every target within 5400 s"),
        "{text}"
    );
    assert!(text.contains("Out of reach within the limits"), "{text}");
    let json = check_headline(&dir, &out);
    assert_eq!(json["duration_s"], 5400.0);
    assert_eq!(json["all_targets_met"], false);
    assert!(!json["out_of_reach"].as_array().unwrap().is_empty());

    // The installation model: a shortest path, and a budget.
    let small = [
        "--config",
        "M1-pa",
        "--max-rotations",
        "2",
        "--refine-starts",
        "1",
        "--axes",
        "north,east",
        "--no-dwells",
    ];
    let out = design(&dir, &small);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    check_headline(&dir, &out);
    let out = design(&dir, &[&small[..], &["--budget-s", "1800"]].concat());
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let json = check_headline(&dir, &out);
    assert_eq!(json["duration_s"], 1800.0);
    std::fs::remove_dir_all(&dir).ok();
}

/// A platform file (`calibrate`'s, no truth) designs at nominal values:
/// its `[[path]]` is the reference (the paper's when it has none), and the
/// answer is close to the paper scenario's, whose truth it lacks: the
/// bound depends weakly on the nominal values (docs/path-design.md, "Your
/// own platform").
#[test]
fn a_platform_file_designs_at_nominal_values() {
    let dir = scratch("design-platform");
    let small = [
        "--max-rotations",
        "2",
        "--refine-starts",
        "1",
        "--axes",
        "north,east",
        "--no-dwells",
    ];
    let example = repo("scenarios/platform-example.toml");
    // The example names M2-ps and has no [[path]]: the paper's reference.
    let out = design(
        &dir,
        &[&["--platform", example.to_str().unwrap()][..], &small].concat(),
    );
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("the bound at nominal values"), "{err}");
    assert!(err.contains("has no [[path]]: the reference path (the default targets, the duration limit) is the paper's, 5400 s"), "{err}");
    let nominal = check_headline(&dir, &out);
    assert_eq!(nominal["config"], "M2-ps");
    // The same search on the paper's scenario (its truth): the same
    // targets to 2.5 %, the same path length to 1 %.
    let out = design(&dir, &[&["--config", "M2-ps"][..], &small].concat());
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let truth = json_file(&dir.join("d.json"));
    for (a, b) in nominal["targets"]
        .as_array()
        .unwrap()
        .iter()
        .zip(truth["targets"].as_array().unwrap())
    {
        assert_eq!(a["state"], b["state"]);
        let r = a["target_rad"].as_f64().unwrap() / b["target_rad"].as_f64().unwrap();
        assert!((r - 1.0).abs() < 0.025, "{}: {r}", a["state"]);
    }
    let (tn, tt) = (
        nominal["duration_s"].as_f64().unwrap(),
        truth["duration_s"].as_f64().unwrap(),
    );
    assert!((tn / tt - 1.0).abs() < 0.01, "{tn} vs {tt}");

    // A platform file with its own path and another configuration.
    let text = std::fs::read_to_string(&example).unwrap().replace("config = \"M2-ps\"", "config = \"M1-pa\"")
        + "\n[[path]]\naxis = \"south\"\nangle_deg = 180.0\nrate_deg_s = 0.1\n\n[[path]]\naxis = \"east\"\nangle_deg = 90.0\nrate_deg_s = 0.1\n";
    let own = dir.join("own.toml");
    std::fs::write(
        &own,
        text.replace("duration_s = 5400.0", "duration_s = 2700.0"),
    )
    .unwrap();
    let out = design(
        &dir,
        &[&["--platform", own.to_str().unwrap()][..], &small].concat(),
    );
    let err = stderr(&out);
    assert!(!err.contains("has no [[path]]"), "{err}");
    let json = json_file(&dir.join("d.json"));
    assert_eq!(json["config"], "M1-pa");
    assert_eq!(json["reference_duration_s"], 2700.0);
    assert!(
        out.status.code() == Some(0) || err.contains("no path in the search space"),
        "{err}"
    );

    // --config must agree with the file's, --scenario and --platform exclude each other,
    // and without either a configuration is asked for.
    let out = design(
        &dir,
        &["--platform", own.to_str().unwrap(), "--config", "M2-ps"],
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out)
            .contains("--config M2-ps contradicts the configuration M1-pa of the platform file"),
        "{}",
        stderr(&out)
    );
    let out = design(
        &dir,
        &[
            "--platform",
            own.to_str().unwrap(),
            "--scenario",
            repo("scenarios/paper.toml").to_str().unwrap(),
        ],
    );
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let out = design(&dir, &["--max-rotations", "1"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("give --config"), "{}", stderr(&out));
    std::fs::remove_dir_all(&dir).ok();
}
