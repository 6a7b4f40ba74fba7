//! The seed corpus of the `decoder` fuzz target (`fuzz/corpus/decoder/`):
//! valid frames of every message type (and a stream of several), so that the
//! fuzzer starts past the CRC. Without seeds it never forges a CRC and stalls
//! at the COBS/length checks (fuzz/README.md).
//!
//! This test checks that the committed seeds are exactly what the current
//! encoder produces; regenerate them after a wire change with
//!
//! ```text
//! ROLLCAL_WRITE_FUZZ_SEEDS=1 cargo test --test it fuzz_seeds
//! ```
//!
//! A seed is the decoder target's input: one byte of chunk size (the target
//! feeds the decoder in chunks of that many bytes), then the frames.

use crate::support;

use std::path::PathBuf;

use rollcal::calibrator::Calibrator;
use rollcal::models::{ConfigId, M1Pa, M2Ps};
use rollcal::wire::{
    crc32, encode, CalibratorConfig, EstimateKind, FrameDecoder, Message, Refusal, RefusalReason,
    Sample, SinglePassReason, MAX_FRAME_LEN, VERSION,
};

fn frame(m: &Message) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let n = encode(m, &mut buf).unwrap();
    buf.truncate(n);
    buf
}

/// A frame with a valid CRC around any version and payload.
fn raw_frame(version: u8, payload: &[u8]) -> Vec<u8> {
    let mut body = vec![version];
    body.extend_from_slice(payload);
    let crc = crc32(&body);
    body.extend_from_slice(&crc.to_le_bytes());
    let mut framed = support::cobs_reference(&body);
    framed.push(0);
    framed
}

fn sample(seq: u32, gimbal: bool) -> Sample {
    Sample {
        seq,
        t_us: u64::from(seq) * 1_000_000,
        dt: 1.0,
        dtheta_cmd: [0.01, -0.02, 0.005],
        c_cn_quat: [0.999_9, 0.01, 0.0, -0.005],
        accel_mean: [0.001, 0.999_9, -0.002],
        gimbal: gimbal.then_some([0.1, -0.2, 0.3]),
    }
}

/// (name, input) of every seed.
fn seeds() -> Vec<(String, Vec<u8>)> {
    let m1 = CalibratorConfig::paper(ConfigId::M1Pa);
    let m2 = CalibratorConfig::paper(ConfigId::M2Ps);
    // A calibrator a few samples in, for an estimate and a checkpoint with
    // realistic values (12 states, and 18 for the largest frame).
    let mut c1 = Calibrator::<f64, M1Pa, 12, 3>::new(m1).unwrap();
    let mut c2 = Calibrator::<f64, M2Ps, 18, 6>::new(m2).unwrap();
    for k in 1..=3 {
        let _ = c1.push(&sample(k, false));
        let _ = c2.push(&sample(k, true));
    }
    let running = c1.estimate();
    let mut messages: Vec<(&str, Message)> = vec![
        ("sample", Message::Sample(sample(7, false))),
        ("sample-gimbal", Message::Sample(sample(8, true))),
        ("estimate-running", Message::Estimate(running.clone())),
        (
            "estimate-final",
            Message::Estimate(rollcal::wire::Estimate {
                kind: EstimateKind::Final {
                    passes: 3,
                    converged: true,
                },
                ..running.clone()
            }),
        ),
        (
            "estimate-single-pass",
            Message::Estimate(rollcal::wire::Estimate {
                kind: EstimateKind::SinglePass {
                    reason: SinglePassReason::LogFull,
                    logged: 64,
                },
                ..running.clone()
            }),
        ),
        ("checkpoint-m1pa", Message::Checkpoint(c1.checkpoint())),
        ("checkpoint-m2ps", Message::Checkpoint(c2.checkpoint())),
        ("reset", Message::Reset),
        ("checkpoint-request", Message::CheckpointRequest),
        ("estimate-request", Message::EstimateRequest),
        ("finish", Message::Finish),
        (
            "refused",
            Message::Refused(Refusal {
                message: 3,
                reason: RefusalReason::Filter(rollcal::ekf::Error::OutOfRange),
            }),
        ),
        (
            "refused-field",
            Message::Refused(Refusal {
                message: 3,
                reason: RefusalReason::InvalidField(rollcal::wire::ConfigField::WarmupTau),
            }),
        ),
    ];
    let mut out = Vec::new();
    for id in ConfigId::ALL {
        out.push((
            format!("configure-{}", id.as_str()),
            frame(&Message::Configure(CalibratorConfig::paper(id))),
        ));
    }
    for id in ConfigId::ALL {
        messages.push(("configure", Message::Configure(CalibratorConfig::paper(id))));
    }
    // The payload mode's seeds: a 0 byte, then a message's postcard payload
    // (the target frames it), one of each kind.
    let mut payloads = Vec::new();
    for (name, m) in &messages {
        if *name != "configure"
            || payloads
                .iter()
                .all(|(n, _): &(String, _)| n != "payload-configure")
        {
            let mut buf = vec![0u8; MAX_FRAME_LEN];
            let n = postcard::to_slice(m, &mut buf).unwrap().len();
            let mut input = vec![0u8];
            input.extend_from_slice(&buf[..n]);
            payloads.push((format!("payload-{name}"), input));
        }
    }
    messages.retain(|(name, _)| *name != "configure");
    for (name, m) in messages.drain(..) {
        out.push((name.to_string(), frame(&m)));
    }
    // One chunk per input (the largest chunk byte).
    let mut out: Vec<(String, Vec<u8>)> = out
        .into_iter()
        .map(|(name, f)| {
            let mut input = vec![0xFF];
            input.extend(f);
            (name, input)
        })
        .chain(payloads)
        .collect();
    // A stream of several frames, fed in small chunks, with a partial frame
    // before it (the receiver joining mid-stream) and an empty frame.
    let mut stream = vec![3u8, 0x42, 0x17, 0x00, 0x00];
    stream.extend(frame(&Message::Configure(m1)));
    for k in 1..=4 {
        stream.extend(frame(&Message::Sample(sample(k, false))));
    }
    stream.extend(frame(&Message::EstimateRequest));
    stream.extend(frame(&Message::Finish));
    out.push(("stream".to_string(), stream));
    // Valid CRCs around what is not a message of this version: another
    // version, an unknown tag, trailing bytes.
    let reset_payload = [4u8];
    out.push((
        "wrong-version".to_string(),
        [&[0xFF][..], &raw_frame(VERSION + 1, &reset_payload)].concat(),
    ));
    out.push((
        "malformed-tag".to_string(),
        [&[0xFF][..], &raw_frame(VERSION, &[0x7F])].concat(),
    ));
    out.push((
        "malformed-trailing".to_string(),
        [&[0xFF][..], &raw_frame(VERSION, &[4, 0])].concat(),
    ));
    out.into_iter()
        .map(|(name, input)| (format!("seed-{name}"), input))
        .collect()
}

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus/decoder")
}

#[test]
fn decoder_seeds_are_current_valid_frames() {
    let seeds = seeds();
    // Every seed but the deliberately invalid ones decodes to messages only.
    for (name, input) in &seeds {
        if let Some(payload) = input.strip_prefix(&[0u8][..]) {
            let message: Message = postcard::from_bytes(payload).unwrap();
            assert_eq!(
                frame(&message),
                raw_frame(VERSION, payload),
                "{name}: the payload of a message"
            );
            continue;
        }
        let mut d = FrameDecoder::new();
        let mut n = 0;
        d.feed(&input[1..], |_| n += 1);
        let s = d.stats();
        if name.contains("malformed") {
            assert_eq!((n, s.malformed), (0, 1), "{name}");
        } else if name.contains("wrong-version") {
            assert_eq!((n, s.wrong_version), (0, 1), "{name}");
        } else if name == "seed-stream" {
            assert_eq!((n, s.ok, s.errors(), s.truncated), (7, 7, 1, 1), "{name}");
        } else {
            assert_eq!((n, s.ok, s.errors()), (1, 1, 0), "{name}");
        }
    }
    let total: usize = seeds.iter().map(|(_, i)| i.len()).sum();
    assert!(total < 16 * 1024, "{total} bytes of seeds");
    if std::env::var_os("ROLLCAL_WRITE_FUZZ_SEEDS").is_some() {
        std::fs::create_dir_all(dir()).unwrap();
        for entry in std::fs::read_dir(dir()).unwrap() {
            let path = entry.unwrap().path();
            if path
                .file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("seed-")
            {
                std::fs::remove_file(path).unwrap();
            }
        }
        for (name, input) in &seeds {
            std::fs::write(dir().join(name), input).unwrap();
        }
    }
    let mut committed: Vec<String> = std::fs::read_dir(dir())
        .unwrap_or_else(|e| {
            panic!(
                "{}: {e} (ROLLCAL_WRITE_FUZZ_SEEDS=1 writes it)",
                dir().display()
            )
        })
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("seed-"))
        .collect();
    committed.sort();
    let mut names: Vec<String> = seeds.iter().map(|(n, _)| n.clone()).collect();
    names.sort();
    assert_eq!(
        committed, names,
        "regenerate: ROLLCAL_WRITE_FUZZ_SEEDS=1 cargo test --test it fuzz_seeds"
    );
    for (name, input) in &seeds {
        let on_disk = std::fs::read(dir().join(name)).unwrap();
        assert!(
            &on_disk == input,
            "{name} is stale: ROLLCAL_WRITE_FUZZ_SEEDS=1 cargo test --test it fuzz_seeds"
        );
    }
}
