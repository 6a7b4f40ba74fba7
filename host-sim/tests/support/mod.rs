//! Helpers shared by the host-sim integration tests: each test file
//! includes this module (`mod support;`), and not every file uses every
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
