//! Helpers shared by the host-sim integration tests: each test module
//! uses this module (`use crate::support;`), and not every module uses every
//! helper.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `host-sim` binary under test.
pub fn host_sim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
}

/// A scratch directory `rollcal-<tag>-<pid>` in the system's temporary
/// directory (created; a test removes it when it passes).
pub fn scratch(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rollcal-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The JSON value of the file at `path`.
pub fn json_file(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// A finished command's stderr as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Asserts that a finished command succeeded, showing its stderr if not.
pub fn assert_success(out: &Output) {
    assert!(out.status.success(), "{}", stderr(out));
}

/// The repository's paper scenario.
pub const PAPER: &str = include_str!("../../../../scenarios/paper.toml");

/// Writes `dir/<name>.toml`: the paper's scenario with its path replaced by
/// `segments` (axis, angle in degrees, rate in °/s), its `duration_s` by
/// `duration_s` (written as given, e.g. `"1e10"`) and its name by `name`.
pub fn paper_with_path(
    dir: &Path,
    name: &str,
    segments: &[(&str, f64, f64)],
    duration_s: &str,
) -> PathBuf {
    let a = PAPER.find("[[path]]").unwrap();
    let b = PAPER.find("[noise]").unwrap();
    let path: String = segments
        .iter()
        .map(|(axis, angle, rate)| {
            format!("[[path]]\naxis = \"{axis}\"\nangle_deg = {angle:?}\nrate_deg_s = {rate:?}\n\n")
        })
        .collect();
    let text = format!("{}{path}{}", &PAPER[..a], &PAPER[b..])
        .replace("duration_s = 5400.0", &format!("duration_s = {duration_s}"))
        .replace("name = \"paper\"", &format!("name = \"{name}\""));
    assert!(text.contains(&format!("duration_s = {duration_s}")));
    let file = dir.join(format!("{name}.toml"));
    std::fs::write(&file, text).unwrap();
    file
}
