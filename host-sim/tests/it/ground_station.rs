//! The host answers the wire (issue 42, item 7): a ground station written
//! from docs/wire.md alone (`tools/ground_station.py`: Python, its frames
//! built from the page, the replies decoded by `tools/wire_decode.py`)
//! talks to `calibrate --replies serial` over a pseudo-terminal and gets
//! every reply: the periodic running Estimates, the answer to
//! EstimateRequest and CheckpointRequest, a refused Configure and a refused
//! restore as `Refused` with their reasons (the run goes on), and Finish's
//! final Estimate, which is the answer `--json` reports, to the bit.

#![cfg(target_os = "linux")]

use std::path::Path;

use crate::support;
use support::{assert_success, host_sim, json_file, paper_with_path, scratch};

#[test]
fn a_ground_station_from_the_page_gets_every_reply_over_a_pty() {
    let dir = scratch("ground-station");
    let segments = [
        ("south", 180.0, 3.0),
        ("east", 90.0, 1.5),
        ("south", 180.0, 3.0),
        ("east", 90.0, 1.5),
    ];
    let sc = paper_with_path(&dir, "short", &segments, "240.0");
    let stream = dir.join("m1pa.bin");
    assert_success(
        &host_sim()
            .args(["record", "--config", "M1-pa", "--seed", "2", "--scenario"])
            .arg(&sc)
            .arg("--out")
            .arg(&stream)
            .output()
            .unwrap(),
    );
    let json = dir.join("cal.json");
    let tool = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools/ground_station.py");
    let out = std::process::Command::new("python3")
        .arg(&tool)
        .args(["--host-sim", env!("CARGO_BIN_EXE_host-sim"), "--stream"])
        .arg(&stream)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{text}{}", support::stderr(&out));
    // Every reply, in order of the requests: two periodic estimates before
    // the requests (60 and 120 samples), the requested one, the checkpoint,
    // the two refusals, two more periodic ones, the final answer.
    // (Consecutive running estimates are printed as one line.)
    let replies: Vec<&str> = text.lines().filter(|l| l.starts_with("<- ")).collect();
    let kinds: Vec<String> = replies
        .iter()
        .map(|l| l.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .collect();
    assert_eq!(
        kinds,
        [
            "<- Estimate Running",
            "<- Checkpoint config=M1-pa",
            "<- Refused message=3",
            "<- Refused message=2",
            "<- Estimate Running",
            "<- Estimate Final(passes=3,",
        ],
        "{text}"
    );
    assert!(
        text.contains("<- Estimate Running x3: seq 60 ... 120"),
        "{text}"
    );
    assert!(
        text.contains("<- Estimate Running x2: seq 180 ... 240"),
        "{text}"
    );
    assert!(
        text.contains("replies: Checkpoint=1 Estimate Final=1 Estimate Running=5 Refused=2"),
        "{text}"
    );
    assert!(
        text.contains("<- Refused message=3 reason=Filter(OutOfRange)"),
        "{text}"
    );
    assert!(
        text.contains("<- Refused message=2 reason=ConfigMismatch(expected=M1-pa, found=M4-pa)"),
        "{text}"
    );
    assert!(text.contains("calibrate exit status 0"), "{text}");
    // The refusals changed nothing: the run went on to all 240 samples,
    // and Finish's answer on the wire is the answer --json reports.
    let v = json_file(&json);
    assert_eq!(v["stream"]["accepted"], 240);
    assert_eq!(
        v["refused"].as_array().unwrap().len(),
        2,
        "{}",
        v["refused"]
    );
    assert_eq!(v["answer"]["usable"], true);
    let last = replies.last().unwrap();
    let state0: f64 = last
        .split("state[0]=")
        .nth(1)
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    assert_eq!(state0, v["states"][0]["estimate_rad"].as_f64().unwrap());
    std::fs::remove_dir_all(&dir).ok();
}
