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
/// is the written scenario's and the JSON's, and every target (every
/// target above its floor, when some lie below theirs) is met when it says
/// so (and not otherwise).
fn check_headline(dir: &Path, out: &Output) -> serde_json::Value {
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let json = json_file(&dir.join("d.json"));
    let written = Scenario::from_file(&dir.join("d.toml")).unwrap();
    let duration = json["duration_s"].as_f64().unwrap();
    assert_eq!(written.timing.duration_s, duration, "{text}");
    let targets = json["targets"].as_array().unwrap();
    let ratio = |t: &serde_json::Value| {
        t["designed_sigma_rad"].as_f64().unwrap() / t["target_rad"].as_f64().unwrap()
    };
    let worst = targets.iter().map(ratio).fold(0.0, f64::max);
    let met = json["all_targets_met"].as_bool().unwrap();
    assert_eq!(met, worst <= 1.0, "{text}");
    // The targets searched for: those not below their floor.
    let below = targets.iter().filter(|t| t["below_floor"] == true).count();
    let worst_above = targets
        .iter()
        .filter(|t| t["below_floor"] != true)
        .map(ratio)
        .fold(0.0, f64::max);
    if let Some(m) = json["targets_above_floor_met"].as_bool() {
        assert_eq!(m, worst_above <= 1.0, "{text}");
    }
    let every = if below > 0 {
        "every target above its floor"
    } else {
        "every target"
    };
    assert_eq!(
        below > 0,
        text.contains("Out of reach of any path of any length"),
        "{text}"
    );
    let to_every = [
        format!("Shortest path to {every}: "),
        format!("A path to {every}: "),
    ]
    .iter()
    .find_map(|p| number_after(&text, p));
    match to_every {
        Some(t) => {
            assert_eq!(t, duration, "{text}");
            assert!(worst_above <= 1.0, "{text}");
            let met_line = if below > 0 {
                "Every target above its floor is met within the limits"
            } else {
                "Every target is met within the limits"
            };
            if text.contains(met_line) {
                assert!(
                    text.contains(&format!("), at {duration} s.")),
                    "the met line names another time than the headline: {text}"
                );
            }
        }
        None => {
            // A budget: the headline's worst ratio is the JSON's, over the
            // targets searched for.
            let said = [
                "Best worst-case σ/target within ".to_string(),
                "Best worst-case σ/target (over the targets above their floor) within ".into(),
                format!("No path to {every} within "),
            ]
            .iter()
            .find_map(|p| number_after(&text, p))
            .expect("a headline");
            assert_eq!(said, duration, "{text}");
            let shown = number_after(&text, "σ/target of ")
                .or_else(|| {
                    number_after(&text, "σ/target (over the targets above their floor) of ")
                })
                .or_else(|| number_after(&text, &format!("within {duration} s: ")))
                .expect("the worst ratio in the headline");
            assert!(
                (shown - worst_above).abs() <= 5e-4 * worst_above.max(1.0),
                "{shown} vs {worst_above}: {text}"
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

/// A target below the floor the wandering errors leave (the realistic
/// scenario's accelerometer bias: Gauss–Markov and random walk) is out of
/// reach of every path: set apart, not searched for, and reported with the
/// floor `observability --errors full` computes (`analysis::floor`); every
/// other target is met on the shortest path to them (the same path as
/// without it), and the exit status is 1. A small search: every default
/// target × 100, ba_y at 2 µg (above its floor: it binds), ba_x at 0.5 µg
/// (below its floor of 1.09 µg).
#[test]
fn a_target_below_its_floor_is_out_of_reach_with_the_floor() {
    let dir = scratch("design-floor");
    let realistic = repo("scenarios/realistic.toml");
    let scenario = Scenario::from_file(&realistic).unwrap();
    let floors = host_sim::analysis::floor::scenario_floors(&scenario);
    let ba = floors.iter().find(|f| f.0 == "ba").unwrap().2;
    let small = [
        "--config",
        "M2-ps",
        "--errors",
        "full",
        "--scenario",
        realistic.to_str().unwrap(),
        "--max-rotations",
        "2",
        "--refine-starts",
        "1",
        "--axes",
        "north,east",
        "--no-dwells",
        "--target-scale",
        "100",
        "--target",
        "ba_y=2",
    ];
    let out = design(
        &dir,
        &[&small[..], &["--target", "ba_x=0.5", "--csv", "d.csv"]].concat(),
    );
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("1 target(s) below the floor the wandering errors leave, out of reach of any path (listed above): the shortest path to every other target is written to d.toml"), "{err}");
    let json = check_headline(&dir, &out);
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        text.contains("Shortest path to every target above its floor: "),
        "{text}"
    );
    assert_eq!(json["all_targets_met"], false);
    assert_eq!(json["targets_above_floor_met"], true);
    // ba_x: below its floor, with the floor of analysis::floor (the JSON's
    // number, to its round trip), and the written path above the floor.
    let missed = json["out_of_reach"].as_array().unwrap();
    assert_eq!(missed.len(), 1, "{missed:?}");
    let m = &missed[0];
    assert_eq!(m["state"], "ba_x");
    assert_eq!(m["below_floor"], true);
    assert_eq!(m["target"].as_f64().unwrap(), 0.5e-6);
    let floor = m["floor"].as_f64().unwrap();
    assert!(
        (floor / ba.limit - 1.0).abs() < 1e-12,
        "{floor} vs {}",
        ba.limit
    );
    assert!(ba.limit > 0.5e-6 && ba.limit < 2e-6, "{:e}", ba.limit);
    assert_eq!(m["flat_after_s"].as_f64(), ba.flat_after_s);
    assert!(m["sigma"].as_f64().unwrap() >= ba.limit);
    // The table and the headline print it (µg, 4 decimals).
    let shown = format!("ba_x target 0.5000 µg < floor {:.4} µg", ba.limit * 1e6);
    assert!(text.contains(&shown), "{shown}: {text}");
    // Every other target is met, ba_y (above its floor) among them, and
    // carries its floor too.
    let targets = json["targets"].as_array().unwrap();
    let by_name = |n: &str| targets.iter().find(|t| t["state"] == n).unwrap().clone();
    let ba_y = by_name("ba_y");
    assert_eq!(ba_y["below_floor"], false);
    assert_eq!(ba_y["floor"], m["floor"]);
    assert!(ba_y["designed_sigma_rad"].as_f64().unwrap() <= 2e-6);
    for t in targets.iter().filter(|t| t["state"] != "ba_x") {
        assert!(
            t["designed_sigma_rad"].as_f64().unwrap() <= t["target_rad"].as_f64().unwrap(),
            "{t}"
        );
    }
    assert_eq!(by_name("thgC_x")["floor"], serde_json::Value::Null);
    // The CSV: a target row and a floor row, analysis::floor's number.
    let csv = std::fs::read_to_string(dir.join("d.csv")).unwrap();
    let row = |label: &str| -> Vec<String> {
        let line = csv.lines().find(|l| l.starts_with(&format!("{label},")));
        line.unwrap().split(',').map(str::to_string).collect()
    };
    let header = row("path");
    let col = |n: &str| header.iter().position(|h| h == &format!("{n}_sigma_rad"));
    let (x, c) = (col("ba_x").unwrap(), col("thgC_x").unwrap());
    assert_eq!(row("floor")[x].parse::<f64>().unwrap(), ba.limit);
    assert_eq!(row("target")[x].parse::<f64>().unwrap(), 0.5e-6);
    assert_eq!(row("floor")[c], "");
    // Not searched for: the same path as without it, exit status 0.
    let duration = json["duration_s"].as_f64().unwrap();
    let pattern = json["pattern"].clone();
    let out = design(&dir, &small);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let json = check_headline(&dir, &out);
    assert_eq!(json["duration_s"].as_f64().unwrap(), duration);
    assert_eq!(json["pattern"], pattern);
    assert_eq!(json["out_of_reach"].as_array().unwrap().len(), 0);
    std::fs::remove_dir_all(&dir).ok();
}
