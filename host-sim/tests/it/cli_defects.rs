//! User-facing defects of the command line (issue 11, item 7), one test
//! each: progress a log can read, resource limits before allocation, a path
//! the duration would cut, binary on a terminal, empty studies, and the
//! verdict words of docs/cli.md.

use crate::support;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use support::{host_sim, paper_with_path, scratch, stderr};

use host_sim::analysis::verdict::Verdict;

/// The paper's scenario with a short path (45° about South, then 45° about
/// East, at 0.5 °/s) and `duration_s`.
fn short_scenario(dir: &Path, duration_s: &str) -> PathBuf {
    let segments = [("south", 45.0, 0.5), ("east", 45.0, 0.5)];
    paper_with_path(dir, &format!("short-{duration_s}"), &segments, duration_s)
}

/// A one-line error with exit status 1, mentioning `needle`.
fn assert_one_line_error(out: &Output, needle: &str) {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("host-sim: error"))
        .collect();
    assert_eq!(lines.len(), 1, "{err}");
    assert!(lines[0].contains(needle), "{err}");
    assert!(
        !err.contains("panicked") && !err.contains("memory allocation"),
        "{err}"
    );
}

/// The progress lines of `label` in a captured (non-terminal) stderr.
fn progress_lines<'a>(err: &'a str, label: &str) -> Vec<&'a str> {
    let prefix = format!("{label}: ");
    err.lines().filter(|l| l.starts_with(&prefix)).collect()
}

#[test]
fn calibrate_progress_in_a_log_is_lines_ending_at_the_final_count() {
    let dir = scratch("defects-calprogress");
    let stream = dir.join("m1pa.bin");
    let out = host_sim()
        .args(["record", "--config", "m1-pa", "--out"])
        .arg(&stream)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let out = host_sim()
        .args(["calibrate", "--config", "m1-pa", "--passes", "1", "--input"])
        .arg(&stream)
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        !err.contains('\r'),
        "a log gets lines, not a \\r bar: {err:?}"
    );
    let lines = progress_lines(&err, "calibrate");
    // A line every 5 % of the 5400 expected samples, and the final one.
    assert!(lines.len() >= 15, "{err}");
    let last = lines.last().unwrap();
    assert!(
        last.contains("5400/5400 samples accepted (100 %), 0 rejected, 0 bad frames"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn montecarlo_and_paper_show_progress_in_a_log() {
    let dir = scratch("defects-progress");
    let sc = short_scenario(&dir, "180.0");
    let out = host_sim()
        .args([
            "montecarlo",
            "--config",
            "m1-pa",
            "--runs",
            "3",
            "--scenario",
        ])
        .arg(&sc)
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    let lines = progress_lines(&err, "montecarlo");
    assert!(lines.len() >= 2, "{err}");
    assert!(lines.last().unwrap().contains("3/3 runs (100 %)"), "{err}");

    // On a short path some states cannot converge: the exit status may be
    // 1, the progress is what is checked.
    let out = host_sim()
        .args(["paper", "--scenario"])
        .arg(&sc)
        .arg("--out")
        .arg(dir.join("paper-out"))
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(!err.contains("panicked"), "{err}");
    let lines = progress_lines(&err, "paper");
    assert!(lines.len() >= 5, "{err}");
    let steps = host_sim::analysis::paper::PROGRESS_STEPS;
    assert!(
        lines
            .last()
            .unwrap()
            .contains(&format!("{steps}/{steps} steps (100 %)")),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_huge_duration_is_refused_before_allocating() {
    let dir = scratch("defects-huge");
    let sc = short_scenario(&dir, "1e10");
    for cmd in ["run", "record"] {
        let mut c = host_sim();
        c.args([cmd, "--config", "m1-pa", "--scenario"]).arg(&sc);
        if cmd == "record" {
            c.args(["--out"]).arg(dir.join("x.bin"));
        }
        let out = c.output().unwrap();
        assert_one_line_error(&out, "periods");
    }
    // The same limit on the durations `design` takes from its arguments
    // (before it, 1e10 s grew to gigabytes within seconds).
    for opt in ["--max-duration-s", "--budget-s"] {
        let out = host_sim()
            .args(["design", "--config", "m1-pa", opt, "1e10", "--out"])
            .arg(dir.join("d.toml"))
            .arg("--figure")
            .arg(dir.join("d.png"))
            .output()
            .unwrap();
        assert_one_line_error(&out, "periods");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_duration_shorter_than_the_path_is_an_error() {
    let dir = scratch("defects-cut");
    // The path lasts 180 s.
    let sc = short_scenario(&dir, "120.0");
    let out = host_sim()
        .args(["run", "--config", "m1-pa", "--scenario"])
        .arg(&sc)
        .output()
        .unwrap();
    assert_one_line_error(&out, "path would be cut");
    // Longer than the path is fine (the platform holds still).
    let sc = short_scenario(&dir, "240.0");
    let out = host_sim()
        .args(["run", "--config", "m1-pa", "--scenario"])
        .arg(&sc)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn record_refuses_to_write_binary_into_a_terminal() {
    use host_sim::io::stream::refuse_terminal;
    assert!(refuse_terminal("-", true).is_err());
    assert!(refuse_terminal("-", false).is_ok());
    assert!(refuse_terminal("run.bin", true).is_ok());
    // Through a real pseudo-terminal when util-linux `script` is there.
    let bin = env!("CARGO_BIN_EXE_host-sim");
    let Ok(out) = Command::new("script")
        .args(["-qec", &format!("{bin} record --config m1-pa"), "/dev/null"])
        .output()
    else {
        eprintln!("no `script`: the pseudo-terminal case is skipped");
        return;
    };
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("record writes binary frames"), "{text}");
    assert!(
        text.len() < 1000,
        "binary reached the terminal: {} bytes",
        text.len()
    );
}

#[test]
fn empty_studies_are_refused() {
    let out = host_sim()
        .args(["remedies", "--seeds", "0"])
        .output()
        .unwrap();
    assert_one_line_error(&out, "--seeds");
    assert!(out.stdout.is_empty(), "no table of zeros");
    let out = host_sim()
        .args(["montecarlo", "--config", "m2-ps", "--runs", "0"])
        .output()
        .unwrap();
    // Argument syntax (clap, exit status 2): at least 2 runs.
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("--runs"), "{}", stderr(&out));
    assert!(out.stdout.is_empty());
}

/// The words the "Verdict words" list of docs/cli.md defines.
fn readme_verdict_words() -> Vec<String> {
    let readme = include_str!("../../../docs/cli.md");
    let start = readme
        .find("### Verdict words")
        .expect("docs/cli.md has a Verdict words section");
    readme[start..]
        .lines()
        .skip(1)
        .take_while(|l| !l.starts_with('#'))
        .filter_map(|l| {
            let l = l.strip_prefix("- `")?;
            Some(l[..l.find('`')?].to_string())
        })
        .collect()
}

#[test]
fn printed_verdicts_are_the_words_the_readme_defines() {
    let words = readme_verdict_words();
    let mut enum_words: Vec<String> = Verdict::ALL.iter().map(|v| v.to_string()).collect();
    let mut sorted = words.clone();
    sorted.sort();
    enum_words.sort();
    assert_eq!(sorted, enum_words, "README's list and the Verdict enum");

    let dir = scratch("defects-verdicts");
    let sc = short_scenario(&dir, "180.0");
    // `run`: the last column after name, unit and seven numbers.
    let out = host_sim()
        .args(["run", "--config", "m2-ps", "--scenario"])
        .arg(&sc)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    let mut seen = 0;
    for line in text
        .lines()
        .skip_while(|l| !l.starts_with("state "))
        .skip(1)
    {
        let cols: Vec<&str> = line.split_whitespace().collect();
        if cols.len() < 10 || !cols[0].contains('_') {
            break;
        }
        let verdict = cols[9..].join(" ");
        assert!(
            words.contains(&verdict),
            "run verdict '{verdict}' not in {words:?}"
        );
        seen += 1;
    }
    assert_eq!(seen, 18, "{text}");
    // `observability`: the last column after name, unit and two numbers.
    let out = host_sim()
        .args(["observability", "--scenario"])
        .arg(&sc)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    let mut seen = 0;
    let mut in_table = false;
    for line in text.lines() {
        if line.trim_start().starts_with("state ") && line.ends_with("verdict") {
            in_table = true;
            continue;
        }
        let cols: Vec<&str> = line.split_whitespace().collect();
        if in_table && cols.len() >= 5 && cols[0].contains('_') {
            let verdict = cols[4..].join(" ");
            assert!(
                words.contains(&verdict),
                "observability verdict '{verdict}' not in {words:?}"
            );
            seen += 1;
        } else {
            in_table = false;
        }
    }
    assert_eq!(seen, 12 + 15 + 18 + 15 + 18 + 12 + 15, "{text}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A path through gimbal lock (90° about South, then 90° about East, at
/// 1 °/s: |β| reaches 89.7°) is refused for M2-ps, which measures the gimbal
/// angles (it diverged there: σ to 1e26″), by `run`, `record` and
/// `montecarlo`; M1-pa, which does not use them, runs it.
#[test]
fn a_path_through_gimbal_lock_is_refused_where_the_gimbal_angles_are_measured() {
    let dir = scratch("defects-gimbal-lock");
    let sc = paper_with_path(
        &dir,
        "lock",
        &[("south", 90.0, 1.0), ("east", 90.0, 1.0)],
        "180.0",
    );
    let stream = dir.join("lock.bin");
    for args in [
        vec!["run", "--config", "M2-ps", "--scenario"],
        vec![
            "montecarlo",
            "--config",
            "M2-ps",
            "--runs",
            "2",
            "--scenario",
        ],
    ] {
        let out = host_sim().args(&args).arg(&sc).output().unwrap();
        assert_one_line_error(&out, "of gimbal lock (|β| = 89.");
    }
    let out = host_sim()
        .args(["record", "--config", "M2-ps", "--out"])
        .arg(&stream)
        .arg("--scenario")
        .arg(&sc)
        .output()
        .unwrap();
    assert_one_line_error(&out, "keep |β| ≤ 85°");
    let out = host_sim()
        .args(["run", "--config", "M1-pa", "--scenario"])
        .arg(&sc)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    std::fs::remove_dir_all(&dir).ok();
}

/// A state the configuration observes but the path does not excite keeps
/// σ near the prior: `run` calls it `not observable` on that path, not
/// `converged` (M2-ps rolled about North only: λx keeps σ ≈ 0.4°).
#[test]
fn an_unexcited_claimed_state_is_not_called_converged() {
    let dir = scratch("defects-unexcited");
    let sc = paper_with_path(&dir, "north", &[("north", 180.0, 0.5)], "360.0");
    let out = host_sim()
        .args(["run", "--config", "M2-ps", "--scenario"])
        .arg(&sc)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let table = String::from_utf8_lossy(&out.stdout).into_owned();
    let row = |name: &str| {
        table
            .lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .unwrap_or_else(|| panic!("no {name} row: {table}"))
            .to_string()
    };
    let lam_x = row("lam_x");
    assert!(lam_x.ends_with("not observable"), "{lam_x}");
    // θaT is excited by any roll about a horizontal axis.
    assert!(row("thaT_1").ends_with("converged"), "{table}");
    std::fs::remove_dir_all(&dir).ok();
}
