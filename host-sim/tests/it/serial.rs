//! The serial path proven (issue 11, item 5): `calibrate --input <device>
//! --baud 115200` on a real pseudo-terminal pair gives exactly the answer
//! of the same stream read from a file.
//!
//! The test opens a pty pair (`openpty`), sets it raw, starts
//! `host-sim calibrate` on the slave side (a character device: the serial
//! port path of `read_input`, through the `serialport` crate at 115200 Bd),
//! writes a recorded stream into the master at the rate of a 115200 Bd
//! 8N1 link (1152 bytes every 100 ms) and lets the idle timeout end the
//! read. Same bytes, same decoder, same calibrator: the final estimate, σ
//! and pass-1 answer must be bit-identical to the file run's.

#![cfg(target_os = "linux")]

use crate::support;
use support::{assert_success, host_sim, paper_with_path, scratch};

use std::io::Write;
use std::os::fd::{FromRawFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::{Duration, Instant};

/// The paper's scenario on a short path that observes M1-pa's claimed
/// states (180° about South at 3 °/s, 90° about East at 1.5 °/s, twice:
/// 240 periods), so the paced stream takes a few seconds.
fn short_scenario(dir: &Path) -> PathBuf {
    let segments = [
        ("south", 180.0, 3.0),
        ("east", 90.0, 1.5),
        ("south", 180.0, 3.0),
        ("east", 90.0, 1.5),
    ];
    paper_with_path(dir, "short", &segments, "240.0")
}

/// A raw pty pair: (master, slave, slave path).
fn open_pty() -> (std::fs::File, OwnedFd, String) {
    let (mut master, mut slave) = (-1, -1);
    // SAFETY: openpty writes two descriptors into the given ints; the name,
    // termios and winsize pointers may be null.
    let rc = unsafe {
        libc::openpty(
            &mut master,
            &mut slave,
            std::ptr::null_mut(),
            std::ptr::null(),
            std::ptr::null(),
        )
    };
    assert_eq!(rc, 0, "openpty: {}", std::io::Error::last_os_error());
    // SAFETY: both descriptors were just opened by openpty and are owned
    // here alone.
    let (master, slave) = unsafe {
        (
            std::fs::File::from_raw_fd(master),
            OwnedFd::from_raw_fd(slave),
        )
    };
    let mut buf = [0 as libc::c_char; 128];
    use std::os::fd::AsRawFd;
    // SAFETY: the buffer is valid for its length; ptsname_r NUL-terminates.
    let rc = unsafe { libc::ptsname_r(master.as_raw_fd(), buf.as_mut_ptr(), buf.len()) };
    assert_eq!(rc, 0, "ptsname_r");
    // SAFETY: NUL-terminated by ptsname_r.
    let name = unsafe { std::ffi::CStr::from_ptr(buf.as_ptr()) }
        .to_string_lossy()
        .into_owned();
    // Raw mode on the pair before any byte arrives (no echo, no CR/LF
    // translation, no line editing): the line discipline processes input
    // with the termios in force when it arrives.
    // SAFETY: termios is plain data; tcgetattr fills it, cfmakeraw edits it.
    unsafe {
        let mut t: libc::termios = std::mem::zeroed();
        assert_eq!(libc::tcgetattr(slave.as_raw_fd(), &mut t), 0);
        libc::cfmakeraw(&mut t);
        assert_eq!(libc::cfsetspeed(&mut t, libc::B115200), 0);
        assert_eq!(libc::tcsetattr(slave.as_raw_fd(), libc::TCSANOW, &t), 0);
    }
    (master, slave, name)
}

/// Whether process `pid` has `path` open.
fn has_open(pid: u32, path: &str) -> bool {
    let Ok(dir) = std::fs::read_dir(format!("/proc/{pid}/fd")) else {
        return false;
    };
    dir.flatten().any(|e| {
        std::fs::read_link(e.path())
            .map(|l| l == Path::new(path))
            .unwrap_or(false)
    })
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn calibrate_on_a_pty_at_115200_baud_equals_the_file_run() {
    let dir = scratch("serial-pty");
    let scenario = short_scenario(&dir);
    let stream = dir.join("short.bin");
    let out = host_sim()
        .args(["record", "--config", "M1-pa", "--seed", "2", "--scenario"])
        .arg(&scenario)
        .arg("--out")
        .arg(&stream)
        .output()
        .unwrap();
    assert_success(&out);
    let bytes = std::fs::read(&stream).unwrap();
    assert!(bytes.len() > 10_000, "{} bytes", bytes.len());

    // The file run.
    let file_json = dir.join("file.json");
    let out = host_sim()
        .args(["calibrate", "--input"])
        .arg(&stream)
        .arg("--json")
        .arg(&file_json)
        .output()
        .unwrap();
    assert_success(&out);

    // The pty run: the calibrator reads the slave as a serial device.
    let (mut master, slave, slave_path) = open_pty();
    let pty_json = dir.join("pty.json");
    let stderr_path = dir.join("pty.stderr");
    let mut child = host_sim()
        .args(["calibrate", "--input", &slave_path, "--baud", "115200"])
        .args(["--idle-timeout", "3", "--json"])
        .arg(&pty_json)
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&stderr_path).unwrap())
        .spawn()
        .unwrap();
    // Wait until the calibrator has opened the device (bytes written before
    // would wait in the pty's buffer anyway; this keeps the pacing honest).
    let t0 = Instant::now();
    while !has_open(child.id(), &slave_path) {
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "calibrate never opened {slave_path}: {}",
            std::fs::read_to_string(&stderr_path).unwrap_or_default()
        );
        if let Some(status) = child.try_wait().unwrap() {
            panic!(
                "calibrate exited ({status}) before opening {slave_path}: {}",
                std::fs::read_to_string(&stderr_path).unwrap_or_default()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    // 115200 Bd, 8N1: 11520 bytes/s, written as 1152 bytes every 100 ms.
    let start = Instant::now();
    for (k, chunk) in bytes.chunks(1152).enumerate() {
        master.write_all(chunk).unwrap();
        let due = start + Duration::from_millis(100 * (k as u64 + 1));
        std::thread::sleep(due.saturating_duration_since(Instant::now()));
    }
    master.flush().unwrap();
    // The idle timeout ends the read; keep the master open until then (a
    // closed master is a hang-up, an error on the slave).
    let deadline = Instant::now() + Duration::from_secs(60);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > deadline {
            child.kill().ok();
            panic!("calibrate did not end after the idle timeout");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    drop(master);
    drop(slave);
    let stderr = std::fs::read_to_string(&stderr_path).unwrap();
    assert!(status.success(), "{stderr}");
    assert!(
        stderr.contains("no data for 3.0 s: end of stream"),
        "not read as a serial device: {stderr}"
    );

    let (f, p) = (json(&file_json), json(&pty_json));
    assert_eq!(p["stream"]["frames"]["ok"], f["stream"]["frames"]["ok"]);
    assert_eq!(p["stream"]["frames"]["corrupt"], 0);
    assert_eq!(p["stream"]["accepted"], 240);
    assert_eq!(p["stream"], f["stream"], "stream counters");
    assert_eq!(p["answer"], f["answer"], "answer kind");
    assert_eq!(p["pass1"], f["pass1"], "pass-1 estimate");
    // Exactly equal, state by state (the JSON holds every f64 exactly).
    let (fs, ps) = (
        f["states"].as_array().unwrap(),
        p["states"].as_array().unwrap(),
    );
    assert_eq!(fs.len(), ps.len());
    for (a, b) in fs.iter().zip(ps) {
        for key in ["name", "estimate_rad", "sigma_rad"] {
            assert_eq!(a[key], b[key], "{key} of {}", a["name"]);
        }
        assert!(a["estimate_rad"].as_f64().unwrap().is_finite());
    }
    std::fs::remove_dir_all(&dir).ok();
}
