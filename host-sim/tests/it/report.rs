//! `--report DIR` (issue 11, item 4): the page and its figures, the truth
//! columns only with a truth, the refusal of a DIR that is a file. The
//! browser check of the page is `tools/check-report.sh` (CI).

use crate::support;
use std::path::{Path, PathBuf};
use std::process::Command;
use support::{assert_success, host_sim, paper_with_path, scratch};

/// The paper's scenario on a short path that observes every claimed state
/// (the paper's path at 3× and 1.5× the rate: 180° about South at 3 °/s,
/// 90° about East at 1.5 °/s, twice: 240 periods, three switches).
fn short_scenario(dir: &Path) -> PathBuf {
    let segments = [
        ("south", 180.0, 3.0),
        ("east", 90.0, 1.5),
        ("south", 180.0, 3.0),
        ("east", 90.0, 1.5),
    ];
    paper_with_path(dir, "short", &segments, "240.0")
}

fn ok(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    assert_success(&out);
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The `<img>` sources of a page and its expected figure count.
fn figures(page: &str) -> (Vec<String>, usize) {
    let srcs = page
        .split("<img class=\"figure\" src=\"")
        .skip(1)
        .map(|s| s.split('"').next().unwrap().to_string())
        .collect();
    let n = page
        .split("data-expected-figures=\"")
        .nth(1)
        .and_then(|s| s.split('"').next())
        .unwrap()
        .parse()
        .unwrap();
    (srcs, n)
}

fn is_png(path: &Path) -> bool {
    std::fs::read(path).is_ok_and(|b| b.starts_with(b"\x89PNG\r\n\x1a\n"))
}

#[test]
fn run_report_has_table_figures_and_checks() {
    let dir = scratch("report-run");
    let sc = short_scenario(&dir);
    let rep = dir.join("rep");
    ok(host_sim()
        .args(["run", "--config", "M1-pa", "--seed", "2", "--scenario"])
        .arg(&sc)
        .arg("--report")
        .arg(&rep));
    let page = std::fs::read_to_string(rep.join("index.html")).unwrap();
    let (srcs, n) = figures(&page);
    // M1-pa: attitude, thgC, thgT, thaT: σ(t) and error figures, + innovations.
    assert_eq!(n, 9, "{srcs:?}");
    assert_eq!(srcs.len(), n);
    for s in &srcs {
        assert!(is_png(&rep.join(s)), "{s}");
        assert!(!s.contains('/') && !s.starts_with("http"), "{s}");
    }
    for want in [
        "<th>truth</th>",
        "<th>σ_CRLB</th>",
        "<th class=\"l\">unit</th>",
        "<td class=\"l\">″</td>",
        "Consistency checks",
        "<td class=\"l\">nis</td>",
        "<td class=\"l\">whiteness</td>",
        "data-report-check=\"pending\"",
        "4 path segment(s)",
    ] {
        assert!(page.contains(want), "missing {want}");
    }
    // Self-contained: nothing fetched from the network.
    assert!(!page.contains("http://") && !page.contains("https://"));
    assert!(!page.contains("NaN"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn calibrate_report_without_truth_has_no_truth_columns() {
    let dir = scratch("report-cal");
    let sc = short_scenario(&dir);
    let stream = dir.join("s.bin");
    let truth = dir.join("truth.json");
    ok(host_sim()
        .args(["record", "--config", "M1-pa", "--seed", "2", "--scenario"])
        .arg(&sc)
        .arg("--out")
        .arg(&stream)
        .arg("--truth")
        .arg(&truth));
    let (bare, with) = (dir.join("bare"), dir.join("with"));
    ok(host_sim()
        .args(["calibrate", "--input"])
        .arg(&stream)
        .arg("--report")
        .arg(&bare));
    ok(host_sim()
        .args(["calibrate", "--input"])
        .arg(&stream)
        .arg("--truth")
        .arg(&truth)
        .arg("--report")
        .arg(&with));
    let page = std::fs::read_to_string(bare.join("index.html")).unwrap();
    for absent in [
        "<th>truth</th>",
        "<th>error</th>",
        "|err|/σ",
        "<th>σ_CRLB</th>",
        "NaN",
        "error-",
    ] {
        assert!(!page.contains(absent), "{absent} without a truth");
    }
    let (srcs, n) = figures(&page);
    assert_eq!(n, 5, "{srcs:?}"); // four σ(t) groups + innovations
    assert!(srcs.contains(&"innovations.png".to_string()));
    assert!(srcs.iter().all(|s| is_png(&bare.join(s))));
    let page = std::fs::read_to_string(with.join("index.html")).unwrap();
    assert!(page.contains("<th>truth</th>") && page.contains("<th>σ_CRLB</th>"));
    let (srcs, n) = figures(&page);
    // With the truth sidecar: error figures of the three parameter groups
    // (the attitude's truth over time is not in the sidecar).
    assert_eq!(n, 8, "{srcs:?}");
    assert!(srcs.iter().all(|s| is_png(&with.join(s))));
    assert!(!page.contains("error-attitude"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_report_dir_that_is_a_file_is_refused_in_one_line() {
    let dir = scratch("report-file");
    let file = dir.join("taken");
    std::fs::write(&file, "x").unwrap();
    for args in [
        vec!["run", "--config", "M1-pa", "--report"],
        vec!["calibrate", "--input", "-", "--report"],
    ] {
        let out = host_sim().args(&args).arg(&file).output().unwrap();
        assert_eq!(out.status.code(), Some(1));
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(e.contains("exists and is not a directory"), "{e}");
        assert_eq!(e.trim_end().lines().count(), 1, "{e}");
    }
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
    std::fs::remove_dir_all(&dir).ok();
}
