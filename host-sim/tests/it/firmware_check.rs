//! The helper of firmware/run-qemu.sh: its end-of-stream frame decodes as an
//! `EstimateRequest`, and `compare` passes or fails on the tolerance.

use std::path::Path;
use std::process::Command;

use rollcal::models::ConfigId;
use rollcal::wire::{
    encode, Estimate, EstimateKind, FrameDecoder, Message, Progress, MAX_FRAME_LEN,
};

const BIN: &str = env!("CARGO_BIN_EXE_firmware-check");

#[test]
fn end_frame_is_an_estimate_request_then_finish() {
    let out = Command::new(BIN).arg("end-frame").output().unwrap();
    assert!(out.status.success());
    assert_eq!(
        out.stdout.last(),
        Some(&0),
        "a frame ends with its delimiter"
    );
    let mut msgs = Vec::new();
    let mut d = FrameDecoder::new();
    d.feed(&out.stdout, |m| msgs.push(m));
    assert_eq!(d.stats().errors(), 0);
    assert_eq!(msgs, vec![Message::EstimateRequest, Message::Finish]);
}

/// A final estimate of record after `passes` passes.
fn estimate(x: &[f64]) -> Estimate {
    estimate_of(
        x,
        EstimateKind::Final {
            passes: 2,
            converged: true,
        },
    )
}

fn estimate_of(x: &[f64], kind: EstimateKind) -> Estimate {
    let mut e = Estimate {
        config: ConfigId::M1Pa,
        errors: rollcal::models::ErrorModel::Installation,
        seq: 7,
        updates: 7,
        state: Default::default(),
        sigma: Default::default(),
        progress: Progress::default(),
        frame_errors: 0,
        kind,
    };
    for v in x {
        e.state.push(*v).unwrap();
        e.sigma.push(1e-6).unwrap();
    }
    e
}

fn write_frames(path: &Path, msgs: &[Message]) {
    let mut bytes = Vec::new();
    let mut buf = [0u8; MAX_FRAME_LEN];
    for m in msgs {
        let n = encode(m, &mut buf).unwrap();
        bytes.extend_from_slice(&buf[..n]);
    }
    std::fs::write(path, bytes).unwrap();
}

fn compare(fw: &Path, host: &Path, tol: f64) -> (bool, String) {
    let out = Command::new(BIN)
        .args(["compare", "--tol", &tol.to_string(), "--firmware"])
        .arg(fw)
        .arg("--host")
        .arg(host)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

#[test]
fn compare_uses_the_last_estimate_and_the_tolerance() {
    let dir = std::env::temp_dir().join(format!("firmware-check-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let host_x: Vec<f64> = (0..12).map(|i| 1e-3 * f64::from(i) - 4e-3).collect();
    let states: Vec<_> = ConfigId::M1Pa
        .states()
        .iter()
        .zip(&host_x)
        .map(|(s, x)| serde_json::json!({"name": s.name, "estimate_rad": x, "sigma_rad": 1e-6}))
        .collect();
    let host = dir.join("host.json");
    std::fs::write(
        &host,
        serde_json::json!({"config": "M1-pa", "states": states, "answer": {"passes": 2}})
            .to_string(),
    )
    .unwrap();
    // An early estimate far off, then the final one 3e-10 rad off on one state.
    let mut close = host_x.clone();
    close[5] += 3e-10;
    let far: Vec<f64> = host_x.iter().map(|x| x + 1e-3).collect();
    let fw = dir.join("fw.bin");
    write_frames(
        &fw,
        &[
            Message::Estimate(estimate(&far)),
            Message::Estimate(estimate(&close)),
        ],
    );
    let (ok, text) = compare(&fw, &host, 1e-9);
    assert!(ok, "{text}");
    assert!(text.contains("2 Estimate frames"), "{text}");
    let (ok, text) = compare(&fw, &host, 1e-10);
    assert!(!ok, "{text}");
    assert!(text.contains("FAIL"), "{text}");
    // A running estimate, however close, is not the answer of record; nor
    // is a final one after another number of passes than the host's.
    for kind in [
        EstimateKind::Running,
        EstimateKind::Final {
            passes: 3,
            converged: true,
        },
    ] {
        write_frames(&fw, &[Message::Estimate(estimate_of(&host_x, kind))]);
        let (ok, text) = compare(&fw, &host, 1e-9);
        assert!(!ok, "{text}");
    }
    // No estimate at all is an error, not a pass.
    write_frames(&fw, &[Message::EstimateRequest]);
    let (ok, _) = compare(&fw, &host, 1.0);
    assert!(!ok);
    std::fs::remove_dir_all(&dir).ok();
}
