//! Every printed table in its units (issue 42, item 1): each table of
//! `run`, `calibrate` (with and without `--truth`), `montecarlo`,
//! `observability` and `paper`'s summary.md names every state's unit in its
//! `unit` column, and its numbers are the JSON's, converted by the test's
//! own factors (not the code's), for every group of the full model.
//!
//! The factors from a state's internal unit to the printed one are written
//! out here from the physics (1 rad = 180·3600/π ″, 1 rad/s = 180·3600/π
//! °/h, 1 = 10⁶ ppm, 1 g = 10⁶ µg); the printed unit must be the one of
//! the state's internal unit (`°/h` for `rad/s`, …). A group that prints a
//! unit not listed here fails the test, naming it.

use std::path::{Path, PathBuf};

use crate::support;
use support::{assert_success, host_sim, json_file, scratch};

const RAD_TO_ARCSEC: f64 = 180.0 * 3600.0 / std::f64::consts::PI;

/// The factor internal → printed of a printed unit, and the internal units
/// it may print.
fn factor(printed: &str) -> (f64, &'static [&'static str]) {
    match printed {
        "″" => (RAD_TO_ARCSEC, &["rad"]),
        "°/h" => (RAD_TO_ARCSEC, &["rad/s"]),
        "°/h/g" => (RAD_TO_ARCSEC, &["rad/s/g"]),
        "ppm" => (1e6, &["1"]),
        "µg" => (1e6, &["g"]),
        "µg/g²" => (1e6, &["1/g", "g/g²", "g/g^2"]),
        other => panic!("a table prints the unit {other:?}, unknown to this test"),
    }
}

/// The instrumented scenario (the instruments' own errors, so that every
/// group's truth is not zero) on a short path: 180° about South at 2 °/s,
/// 90° about East at 1 °/s, 180° about South at 2 °/s (270 periods).
fn short_instrumented(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/instrumented.toml"),
    )
    .unwrap();
    let a = text.find("[[path]]").unwrap();
    let b = text.find("[noise]").unwrap();
    let path: String = [
        ("south", 180.0, 2.0),
        ("east", 90.0, 1.0),
        ("south", 180.0, 2.0),
    ]
    .iter()
    .map(|(axis, angle, rate)| {
        format!("[[path]]\naxis = \"{axis}\"\nangle_deg = {angle:?}\nrate_deg_s = {rate:?}\n\n")
    })
    .collect();
    let text = format!("{}{path}{}", &text[..a], &text[b..])
        .replace("duration_s = 5400.0", "duration_s = 270.0");
    assert!(text.contains("duration_s = 270.0"));
    let file = dir.join("short-instrumented.toml");
    std::fs::write(&file, text).unwrap();
    file
}

/// A table's row of state `name`: the unit and the numbers after it (the
/// first `n` fields that parse as numbers), from whitespace-separated
/// `text` (or `|`-separated when `markdown`).
fn row(text: &str, name: &str, n: usize, markdown: bool) -> (String, Vec<f64>) {
    let fields: Vec<String> = text
        .lines()
        .map(|l| {
            if markdown {
                l.split('|')
                    .map(|f| f.trim().to_string())
                    .filter(|f| !f.is_empty())
                    .collect::<Vec<_>>()
            } else {
                l.split_whitespace().map(String::from).collect()
            }
        })
        .find(|f| f.first().map(String::as_str) == Some(name))
        .unwrap_or_else(|| panic!("no row {name} in\n{text}"));
    let unit = fields.get(1).cloned().unwrap_or_default();
    let numbers: Vec<f64> = fields[2..]
        .iter()
        .take(n)
        .map(|f| f.parse().unwrap())
        .collect();
    assert_eq!(numbers.len(), n, "row {name}: {fields:?}");
    (unit, numbers)
}

/// Asserts that a printed value `shown` (with `decimals` decimals) is
/// `internal` (in the state's internal unit) in the printed `unit`.
fn holds(what: &str, shown: f64, internal: f64, unit: &str, decimals: i32) {
    let want = internal * factor(unit).0;
    let tol = 0.5 * 10f64.powi(-decimals) * 1.0001 + 1e-9 * want.abs();
    assert!(
        (shown - want).abs() <= tol,
        "{what}: printed {shown} {unit}, the JSON gives {want} {unit}"
    );
}

/// A JSON state of `run`/`calibrate`'s `--json`: name, internal unit, and
/// the value of `key` in the internal unit (`states` hold `*_rad`;
/// `instruments` hold printed values with their `unit`, converted back by
/// the test's factor).
fn states_of(v: &serde_json::Value) -> Vec<(String, String, serde_json::Value)> {
    let mut out = Vec::new();
    for s in v["states"].as_array().unwrap() {
        out.push((
            s["name"].as_str().unwrap().to_string(),
            "rad".to_string(),
            s.clone(),
        ));
    }
    for s in v["instruments"].as_array().into_iter().flatten() {
        out.push((
            s["name"].as_str().unwrap().to_string(),
            s["unit"].as_str().unwrap().to_string(),
            s.clone(),
        ));
    }
    out
}

/// `key` of a JSON state in its internal unit: `<key>_rad` of an
/// installation state, `<key>` / factor of an instrument state (printed).
fn internal(s: &serde_json::Value, printed_unit: &str, key: &str) -> f64 {
    match s.get(format!("{key}_rad")) {
        Some(v) => v.as_f64().unwrap(),
        None => s[key].as_f64().unwrap() / factor(printed_unit).0,
    }
}

/// Every group of the full model appears (so that every group was held).
fn assert_every_group(v: &serde_json::Value, config: &str) {
    let groups: std::collections::BTreeSet<&str> = v["states"]
        .as_array()
        .unwrap()
        .iter()
        .chain(v["instruments"].as_array().into_iter().flatten())
        .map(|s| s["group"].as_str().unwrap())
        .collect();
    let id: rollcal::models::ConfigId = config.parse().unwrap();
    for s in id.states_with(rollcal::models::ErrorModel::Full) {
        assert!(
            groups.contains(s.group.as_str()),
            "{config}: group {} missing",
            s.group.as_str()
        );
    }
}

/// Checks the truth table (`run`, `calibrate --truth`) against its JSON:
/// truth, estimate, error, σ, |err|/σ, σ_CRLB (from `crlb_sigma_rad` or
/// `crlb`, internal units).
fn check_truth_table(text: &str, v: &serde_json::Value, crlb: Option<&[f64]>, what: &str) {
    for (i, (name, json_unit, s)) in states_of(v).iter().enumerate() {
        let (unit, x) = row(text, name, 7, false);
        let printed_unit = if json_unit == "rad" {
            "″"
        } else {
            json_unit.as_str()
        };
        assert_eq!(unit, printed_unit, "{what}: {name}");
        assert!(
            factor(&unit).1.contains(&internal_unit(v, name).as_str()),
            "{what}: {name} printed in {unit}"
        );
        let t = internal(s, &unit, "truth");
        let e = internal(s, &unit, "estimate");
        let sg = internal(s, &unit, "sigma");
        holds(&format!("{what} {name} truth"), x[0], t, &unit, 3);
        holds(&format!("{what} {name} estimate"), x[1], e, &unit, 3);
        holds(&format!("{what} {name} σ"), x[3], sg, &unit, 4);
        if let Some(c) = crlb {
            holds(&format!("{what} {name} σ_CRLB"), x[5], c[i], &unit, 4);
        }
    }
}

/// The internal unit of state `name` of a `run`/`calibrate` JSON: `rad`
/// for `states`, the core's unit for `instruments` (from `--matrices`'s
/// `all_states.units` when given, else by the printed unit's pair).
fn internal_unit(v: &serde_json::Value, name: &str) -> String {
    if v["states"]
        .as_array()
        .unwrap()
        .iter()
        .any(|s| s["name"] == name)
    {
        return "rad".into();
    }
    let id: rollcal::models::ConfigId = v["config"].as_str().unwrap().parse().unwrap();
    id.states_with(rollcal::models::ErrorModel::Full)
        .iter()
        .find(|s| s.name == name)
        .map(|s| s.unit.to_string())
        .unwrap()
}

fn run(args: &[&str], dir: &Path, json: &str) -> (String, serde_json::Value) {
    let path = dir.join(json);
    let out = host_sim()
        .args(args)
        .arg("--json")
        .arg(&path)
        .output()
        .unwrap();
    // Whatever the answer's status (an answer, a warning, not an answer on
    // this short path), the table is printed.
    assert!(
        out.status
            .code()
            .is_some_and(|c| c == 0 || c == 3 || c == 4),
        "{args:?}: {}",
        support::stderr(&out)
    );
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        json_file(&path),
    )
}

fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap_or(f64::NAN))
        .collect()
}

#[test]
fn run_and_calibrate_tables_are_the_json_in_units() {
    let dir = scratch("tables-cal");
    let sc = short_instrumented(&dir);
    let sc = sc.to_str().unwrap();
    for config in ["M1-pa", "M2-ps"] {
        // run, full model: the truth table.
        let (text, v) = run(
            &[
                "run",
                "--config",
                config,
                "--errors",
                "full",
                "--scenario",
                sc,
            ],
            &dir,
            "run.json",
        );
        assert_every_group(&v, config);
        // run's JSON has no σ_CRLB: that column is held by calibrate's below.
        check_truth_table(&text, &v, None, &format!("run {config}"));

        // calibrate of the same scenario as frames, with its truth sidecar.
        let stream = dir.join("s.bin");
        let truth = dir.join("t.json");
        let out = host_sim()
            .args(["record", "--config", config, "--scenario", sc, "--out"])
            .arg(&stream)
            .arg("--truth")
            .arg(&truth)
            .output()
            .unwrap();
        assert_success(&out);
        let (s, t) = (stream.to_str().unwrap(), truth.to_str().unwrap());
        let (text, v) = run(
            &["calibrate", "--input", s, "--truth", t, "--errors", "full"],
            &dir,
            "cal.json",
        );
        assert_every_group(&v, config);
        check_truth_table(
            &text,
            &v,
            Some(&floats(&v["crlb_sigma_rad"])),
            &format!("calibrate --truth {config}"),
        );

        // Without a truth: estimate, σ, bound (the real platform's table).
        for errors in ["installation", "full"] {
            let (text, v) = run(
                &["calibrate", "--input", s, "--errors", errors],
                &dir,
                "cal.json",
            );
            let bound = floats(&v["bound_at_estimate_sigma_rad"]);
            for (i, (name, json_unit, st)) in states_of(&v).iter().enumerate() {
                let (unit, x) = row(&text, name, 4, false);
                let printed_unit = if json_unit == "rad" {
                    "″"
                } else {
                    json_unit.as_str()
                };
                assert_eq!(unit, printed_unit, "calibrate {config} {errors}: {name}");
                assert!(
                    factor(&unit).1.contains(&internal_unit(&v, name).as_str()),
                    "{name} in {unit}"
                );
                let what = format!("calibrate {config} {errors} {name}");
                holds(
                    &format!("{what} estimate"),
                    x[0],
                    internal(st, &unit, "estimate"),
                    &unit,
                    3,
                );
                holds(
                    &format!("{what} σ"),
                    x[1],
                    internal(st, &unit, "sigma"),
                    &unit,
                    4,
                );
                holds(&format!("{what} bound"), x[2], bound[i], &unit, 4);
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn montecarlo_observability_and_paper_tables_are_the_json_in_units() {
    let dir = scratch("tables-studies");
    let sc = short_instrumented(&dir);
    let sc = sc.to_str().unwrap();
    // montecarlo: RMS error, mean error, mean σ, σ_CRLB (internal units,
    // the instrument states' `unit` beside them).
    let (text, v) = run(
        &[
            "montecarlo",
            "--config",
            "M2-ps",
            "--errors",
            "full",
            "--runs",
            "2",
            "--scenario",
            sc,
        ],
        &dir,
        "mc.json",
    );
    let states = v["states"].as_array().unwrap();
    assert_eq!(states.len(), 54);
    for s in states {
        let name = s["name"].as_str().unwrap();
        let (unit, x) = row(&text, name, 4, false);
        let internal_unit = s["unit"].as_str().unwrap_or("rad");
        assert!(
            factor(&unit).1.contains(&internal_unit),
            "montecarlo {name}: {internal_unit} printed in {unit}"
        );
        for (k, key) in [
            "rms_error_rad",
            "mean_error_rad",
            "mean_sigma_rad",
            "sigma_crlb_rad",
        ]
        .iter()
        .enumerate()
        {
            holds(
                &format!("montecarlo {name} {key}"),
                x[k],
                s[key].as_f64().unwrap(),
                &unit,
                4,
            );
        }
    }

    // observability: σ_CRLB per state.
    let (text, v) = run(
        &["observability", "--errors", "full", "--scenario", sc],
        &dir,
        "obs.json",
    );
    let m2 = v["configs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["config"] == "M2-ps")
        .unwrap();
    let block = &text[text.find("M2-ps:").unwrap()..];
    for s in m2["states"].as_array().unwrap() {
        let name = s["name"].as_str().unwrap();
        let (unit, x) = row(block, name, 1, false);
        let internal_unit = s["unit"].as_str().unwrap_or("rad");
        assert!(
            factor(&unit).1.contains(&internal_unit),
            "observability {name}: {internal_unit} in {unit}"
        );
        holds(
            &format!("observability {name}"),
            x[0],
            s["sigma_crlb_rad"].as_f64().unwrap(),
            &unit,
            4,
        );
    }

    // paper: summary.md against summary.json.
    let out_dir = dir.join("paper");
    let out = host_sim()
        .args(["paper", "--errors", "full", "--scenario", sc, "--out"])
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(out.status.code().is_some(), "{}", support::stderr(&out));
    let md = std::fs::read_to_string(out_dir.join("summary.md")).unwrap();
    let v = json_file(&out_dir.join("summary.json"));
    let m1 = v["configs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["config"] == "M1-pa")
        .unwrap();
    let section = &md[md.find("## M1-pa").unwrap()..];
    for s in m1["states"].as_array().unwrap() {
        let name = s["name"].as_str().unwrap();
        let (unit, x) = row(section, name, 5, true);
        let internal_unit = s["unit"].as_str().unwrap_or("rad");
        assert!(
            factor(&unit).1.contains(&internal_unit),
            "paper {name}: {internal_unit} in {unit}"
        );
        for (k, (key, d)) in [
            ("truth_rad", 3),
            ("estimate_rad", 3),
            ("error_rad", 4),
            ("sigma_filter_rad", 4),
            ("sigma_crlb_rad", 4),
        ]
        .iter()
        .enumerate()
        {
            holds(
                &format!("paper {name} {key}"),
                x[k],
                s[key].as_f64().unwrap(),
                &unit,
                *d,
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
