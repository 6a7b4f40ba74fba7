//! The wire protocol: frames round-trip, the byte layout matches an
//! independent reference encoder (and `docs/wire.md`), and the decoder
//! counts and skips every kind of bad input without panicking.

use crate::support;

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rollcal::ekf::Options;
use rollcal::models::ConfigId;
use rollcal::wire::{
    crc32, decode_frame, decode_frame_into, encode, CalibratorConfig, Checkpoint, Decoder,
    DecoderStats, Estimate, EstimateKind, FrameDecoder, FrameError, Message, Progress,
    RejectCounts, Sample, SinglePassReason, MAX_FACTOR, MAX_FRAME_LEN, MAX_STATES, VERSION,
};

fn frame(msg: &Message) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let n = encode(msg, &mut buf).unwrap();
    buf.truncate(n);
    buf
}

/// A frame built as `docs/wire.md` describes it, from postcard and the CRC.
fn reference_frame(version: u8, payload: &[u8]) -> Vec<u8> {
    let mut raw = vec![version];
    raw.extend_from_slice(payload);
    let crc = crc32(&raw);
    raw.extend_from_slice(&crc.to_le_bytes());
    let mut f = support::cobs_reference(&raw);
    f.push(0);
    f
}

fn sample(seq: u32) -> Sample {
    Sample {
        seq,
        t_us: u64::from(seq) * 1_000_000,
        dt: 1.0,
        dtheta_cmd: [-1.745_329_3e-3, 3.1e-9, 7.2e-7],
        accel_mean: [0.001_234, 0.999_998_8, -0.003_5],
        gimbal: Some([0.003_665, -0.001_396, 0.002_269]),
        c_cn_quat: [0.999_999_6, -8.726_6e-4, 1.5e-9, 3.6e-7],
    }
}

fn big_checkpoint() -> Checkpoint {
    let v: heapless::Vec<f64, MAX_STATES> = (0..MAX_STATES).map(|i| -1e-3 * i as f64).collect();
    Checkpoint {
        config: ConfigId::M2Ps,
        errors: rollcal::models::ErrorModel::Full,
        state: v.clone(),
        factor: (0..MAX_FACTOR).map(|i| 1e-300 * i as f64).collect(),
        nominal: Some(v),
        c_cn: [f64::MAX; 9],
        updates: u32::MAX,
        gated_run: u32::MAX,
        gate_open: true,
        progress: Progress {
            last_seq: Some(u32::MAX),
            last_t_us: Some(u64::MAX),
            last_increment: [f64::MIN; 3],
            clock_candidate: Some((u32::MAX, u64::MAX)),
            last_nis: 1.5,
            accepted: u32::MAX,
            bridged: u32::MAX,
            reacquired: u32::MAX,
            reacquired_periods: u32::MAX,
            clock_steps: u32::MAX,
            logged: u32::MAX,
            log_incomplete: Some(SinglePassReason::LogMismatch),
            gated: u32::MAX,
            since_estimate: u32::MAX,
            rejects: RejectCounts {
                non_finite: u32::MAX,
                period: u32::MAX,
                accel_range: u32::MAX,
                increment_range: u32::MAX,
                gimbal_range: u32::MAX,
                missing_gimbal: u32::MAX,
                duplicate: u32::MAX,
                out_of_order: u32::MAX,
                time_backwards: u32::MAX,
                time_mismatch: u32::MAX,
                frame_attitude: u32::MAX,
                filter: u32::MAX,
            },
        },
    }
}

fn all_messages() -> Vec<Message> {
    let est = Estimate {
        config: ConfigId::M1Pa,
        errors: rollcal::models::ErrorModel::Installation,
        seq: 77,
        updates: 76,
        state: (0..12).map(|i| i as f64 * 1e-5).collect(),
        sigma: (0..12).map(|i| i as f64 * 1e-7 + 1e-9).collect(),
        progress: Progress {
            last_nis: 0.5, // the default NaN would defeat PartialEq
            ..Progress::default()
        },
        frame_errors: 3,
        kind: EstimateKind::SinglePass {
            reason: SinglePassReason::Reacquired,
            logged: 1699,
        },
    };
    vec![
        Message::Sample(sample(1)),
        Message::Sample(Sample {
            gimbal: None,
            ..sample(u32::MAX)
        }),
        Message::Estimate(est),
        Message::Checkpoint(big_checkpoint()),
        Message::Configure(CalibratorConfig::paper(ConfigId::M2Ps)),
        Message::Reset,
        Message::CheckpointRequest,
        Message::EstimateRequest,
        Message::Finish,
    ]
}

fn decode_all<const CAP: usize>(
    dec: &mut Decoder<CAP>,
    bytes: &[u8],
) -> Vec<Result<Message, FrameError>> {
    let mut out = Vec::new();
    dec.feed_results(bytes, |r| out.push(r));
    out
}

/// Equality through the encoding (NaN-safe: compares bit patterns).
fn same(a: &Message, b: &Message) -> bool {
    frame(a) == frame(b)
}

#[test]
fn crc_is_crc32_iso_hdlc() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(crc32(b""), 0);
}

#[test]
fn frames_match_the_documented_layout_and_round_trip() {
    let mut dec = FrameDecoder::new();
    for m in all_messages() {
        let f = frame(&m);
        let mut payload = vec![0u8; MAX_FRAME_LEN];
        let p = postcard::to_slice(&m, &mut payload).unwrap();
        assert_eq!(f, reference_frame(VERSION, p), "{m:?}");
        assert!(f.len() <= MAX_FRAME_LEN);
        assert_eq!(f.iter().filter(|b| **b == 0).count(), 1);
        assert_eq!(*f.last().unwrap(), 0);
        let got = decode_all(&mut dec, &f);
        assert_eq!(got, vec![Ok(m)]);
    }
    assert_eq!(dec.stats().ok, all_messages().len() as u32);
    assert_eq!(dec.stats().errors(), 0);
    // The largest message fits the documented bound with room to spare.
    let n = frame(&Message::Checkpoint(big_checkpoint())).len();
    assert!(n > 3000 && n < MAX_FRAME_LEN, "{n}");
}

#[test]
fn encode_reports_a_small_buffer() {
    let m = Message::Sample(sample(5));
    let n = frame(&m).len();
    for len in 0..n {
        let mut buf = vec![0u8; len];
        assert!(encode(&m, &mut buf).is_err(), "len {len}");
    }
}

// The worked examples of docs/wire.md: `wire_doc.rs`.

#[test]
fn any_chunking_gives_the_same_messages() {
    let msgs = all_messages();
    let stream: Vec<u8> = msgs.iter().flat_map(frame).collect();
    let mut expect_stats = None;
    for chunk in 1..=stream.len() / 4 {
        let mut dec = FrameDecoder::new();
        let mut got = Vec::new();
        for c in stream.chunks(chunk) {
            dec.feed(c, |m| got.push(m));
        }
        assert_eq!(got, msgs, "chunk {chunk}");
        assert_eq!(dec.pending(), 0);
        let s = *dec.stats();
        assert_eq!(*expect_stats.get_or_insert(s), s);
    }
    // And a few large/odd chunkings including the whole stream.
    for chunk in [stream.len() - 1, stream.len(), stream.len() + 10] {
        let mut dec = FrameDecoder::new();
        let mut got = Vec::new();
        for c in stream.chunks(chunk) {
            dec.feed(c, |m| got.push(m));
        }
        assert_eq!(got, msgs);
    }
}

#[test]
fn every_single_bit_flip_is_detected_and_resynchronised() {
    let (a, b, c) = (sample(10), sample(11), sample(12));
    let fb = frame(&Message::Sample(b));
    let (fa, fc) = (frame(&Message::Sample(a)), frame(&Message::Sample(c)));
    for byte in 0..fb.len() {
        for bit in 0..8 {
            let mut bad = fb.clone();
            bad[byte] ^= 1 << bit;
            let stream = [fa.clone(), bad, fc.clone()].concat();
            let mut dec = FrameDecoder::new();
            let got = decode_all(&mut dec, &stream);
            let msgs: Vec<Message> = got.iter().filter_map(|r| r.clone().ok()).collect();
            // CRC-32 detects every single-bit error: b never comes out,
            // and nothing else but a and c does.
            assert!(msgs.contains(&Message::Sample(a)), "{byte}.{bit}");
            assert!(
                msgs.iter()
                    .all(|m| *m == Message::Sample(a) || *m == Message::Sample(c)),
                "{byte}.{bit}: {msgs:?}"
            );
            assert!(dec.stats().errors() >= 1, "{byte}.{bit}");
            let last = byte == fb.len() - 1;
            if !last {
                // The delimiter survived: resynchronised, c decoded.
                assert_eq!(msgs.len(), 2, "{byte}.{bit}");
            }
        }
    }
}

/// A frame whose data ends with a full block of 254 non-zero bytes: the
/// encoder closes it with the code `0xFF` and then sends a final `0x01`
/// (docs/wire.md §Frame, 4), byte for byte as the reference encoder, and the
/// decoder reads it. (The `cobs` crate's slice encoder would leave out the
/// `0x01`; the wire's encoder uses its state machine.) Such frames are found
/// by search: `Estimate`s with no zero byte after their `Progress`, of every
/// pair of vector lengths and a few varint lengths.
#[test]
fn a_full_block_at_the_end_of_the_data_is_closed_by_a_final_0x01() {
    let nonzero_progress = Progress {
        last_seq: Some(4321),
        last_t_us: Some(4_321_000_123),
        last_increment: [1.234_567e-3, -2.345_678e-7, 3.456_789e-6],
        clock_candidate: Some((17, 17_000_123)),
        last_nis: 1.234_5,
        accepted: 4321,
        bridged: 3,
        reacquired: 1,
        reacquired_periods: 2,
        clock_steps: 1,
        logged: 4321,
        log_incomplete: Some(SinglePassReason::Reacquired),
        gated: 5,
        since_estimate: 1,
        rejects: RejectCounts {
            non_finite: 1,
            period: 1,
            accel_range: 1,
            increment_range: 1,
            gimbal_range: 1,
            missing_gimbal: 1,
            duplicate: 1,
            out_of_order: 1,
            time_backwards: 1,
            time_mismatch: 1,
            frame_attitude: 1,
            filter: 1,
        },
    };
    let values = |n: usize, scale: f64| -> heapless::Vec<f64, MAX_STATES> {
        (0..n)
            .map(|i| scale * (1.234_567_891_234_5 + 0.111_111_111_111_1 * i as f64))
            .collect()
    };
    let mut dec = FrameDecoder::new();
    let mut found = 0;
    for n_state in 0..=18 {
        for n_sigma in 0..=18 {
            for logged in [7u32, 1_000, 100_000, 20_000_000, u32::MAX] {
                let m = Message::Estimate(Estimate {
                    config: ConfigId::M2Ps,
                    errors: rollcal::models::ErrorModel::Installation,
                    seq: 4321,
                    updates: 4320,
                    state: values(n_state, 1e-4),
                    sigma: values(n_sigma, 1e-6),
                    progress: nonzero_progress,
                    frame_errors: 2,
                    kind: EstimateKind::SinglePass {
                        reason: SinglePassReason::Reacquired,
                        logged,
                    },
                });
                let mut payload = vec![0u8; MAX_FRAME_LEN];
                let p = postcard::to_slice(&m, &mut payload).unwrap();
                let mut raw = vec![VERSION];
                raw.extend_from_slice(p);
                raw.extend_from_slice(&crc32(&raw).to_le_bytes());
                let tail = raw.iter().rev().take_while(|b| **b != 0).count();
                if tail == 0 || tail % 254 != 0 {
                    continue;
                }
                found += 1;
                let f = frame(&m);
                assert_eq!(f, reference_frame(VERSION, p), "{m:?}");
                let n = f.len();
                assert_eq!(f[n - 2..], [0x01, 0x00]);
                assert_eq!(f[n - 2 - 255], 0xFF);
                assert_eq!(decode_all(&mut dec, &f), vec![Ok(m)]);
                // The variant without the final 0x01 decodes too.
                let mut short = f[..n - 2].to_vec();
                short.push(0);
                assert_eq!(decode_all(&mut dec, &short).len(), 1);
            }
        }
    }
    assert!(found >= 3, "{found} frames found");
    assert_eq!(dec.stats().errors(), 0);
    assert_eq!(dec.stats().ok, 2 * found);
}

/// Decoding into a slot (`push_byte_into`, `decode_frame_into`, the
/// firmware's way) gives the messages, errors and counts of decoding by
/// value, and leaves the slot as it was on every rejected frame.
#[test]
fn decoding_into_a_slot_is_decoding_by_value() {
    let good = all_messages();
    let mut stream: Vec<u8> = good.iter().flat_map(frame).collect();
    // Rejected frames of every kind between good ones: a flipped bit, a
    // truncated frame, another version, an oversized frame.
    let mut flipped = frame(&Message::Sample(sample(7)));
    flipped[4] ^= 0x10;
    let truncated = [&frame(&Message::Reset)[..2], &[0u8]].concat();
    stream.extend(flipped);
    stream.extend(frame(&Message::Sample(sample(8))));
    stream.extend(truncated);
    stream.extend(reference_frame(VERSION.wrapping_add(1), &[0]));
    stream.extend(frame(&Message::Finish));
    stream.extend(vec![1u8; MAX_FRAME_LEN + 3]);
    stream.push(0);
    stream.extend(frame(&Message::EstimateRequest));
    let (mut by_value, mut into) = (FrameDecoder::new(), FrameDecoder::new());
    // A stale message in the slot, as a firmware's static slot holds.
    let mut slot = Message::Checkpoint(big_checkpoint());
    let (mut messages, mut errors) = (0, 0);
    for &b in &stream {
        let before = slot.clone();
        match (by_value.push_byte(b), into.push_byte_into(b, &mut slot)) {
            (None, None) => assert!(same(&slot, &before)),
            (Some(Ok(m)), Some(Ok(()))) => {
                assert!(same(&slot, &m), "{m:?}");
                messages += 1;
            }
            (Some(Err(e)), Some(Err(f))) => {
                assert_eq!(e, f);
                assert!(same(&slot, &before), "{e:?}");
                errors += 1;
            }
            (a, b) => panic!("by value {a:?}, into a slot {b:?}"),
        }
    }
    assert_eq!(messages, good.len() + 3);
    assert_eq!(errors, 4);
    assert_eq!(by_value.stats(), into.stats());
    // decode_frame_into of one frame, good and bad.
    for msg in &good {
        let f = frame(msg);
        let body = &f[..f.len() - 1];
        let mut slot = Message::Reset;
        assert_eq!(decode_frame_into(&mut body.to_vec(), &mut slot), Ok(()));
        assert!(same(&slot, msg));
        let mut bad = body.to_vec();
        bad[1] ^= 0x01;
        let before = slot.clone();
        assert_eq!(
            decode_frame_into(&mut bad.clone(), &mut slot).err(),
            decode_frame(&mut bad).err()
        );
        assert!(same(&slot, &before));
    }
}

#[test]
fn truncated_frames_are_counted_and_skipped() {
    let full = frame(&Message::Configure(CalibratorConfig::paper(ConfigId::M1Pa)));
    let next = frame(&Message::Sample(sample(3)));
    let mut stats = DecoderStats::default();
    for cut in 1..full.len() - 1 {
        let mut stream = full[..cut].to_vec();
        stream.push(0);
        stream.extend_from_slice(&next);
        let mut dec = FrameDecoder::new();
        let got = decode_all(&mut dec, &stream);
        assert_eq!(got.len(), 2, "cut {cut}");
        assert!(
            matches!(got[0], Err(FrameError::Truncated | FrameError::Corrupt)),
            "cut {cut}: {:?}",
            got[0]
        );
        assert_eq!(got[1], Ok(Message::Sample(sample(3))));
        stats.truncated += dec.stats().truncated;
        stats.corrupt += dec.stats().corrupt;
    }
    // Short cuts are caught by COBS or the minimum length.
    assert!(stats.truncated > 0 && stats.corrupt > 0, "{stats:?}");
    // A stream that starts mid-frame: the partial frame is skipped.
    let stream = [&next[5..], &next[..]].concat();
    let mut dec = FrameDecoder::new();
    assert_eq!(
        decode_all(&mut dec, &stream).last(),
        Some(&Ok(Message::Sample(sample(3))))
    );
    assert_eq!(dec.stats().errors(), 1);
}

#[test]
fn oversized_frames_are_counted_and_skipped() {
    let big = frame(&Message::Checkpoint(big_checkpoint()));
    let small = frame(&Message::Sample(sample(9)));
    assert!(small.len() <= 96);
    let mut dec = Decoder::<96>::new();
    let got = decode_all(&mut dec, &[big.clone(), small.clone(), big, small].concat());
    assert_eq!(
        got,
        vec![
            Err(FrameError::Oversized),
            Ok(Message::Sample(sample(9))),
            Err(FrameError::Oversized),
            Ok(Message::Sample(sample(9)))
        ]
    );
    assert_eq!(dec.stats().oversized, 2);
    assert_eq!(dec.stats().ok, 2);
    // A capacity that exactly fits the frame's bytes (without delimiter).
    let mut dec = Decoder::<81>::new();
    let small = frame(&Message::Sample(sample(9)));
    assert_eq!(small.len() - 1, 81);
    assert_eq!(decode_all(&mut dec, &small).len(), 1);
}

#[test]
fn wrong_version_and_malformed_frames_are_counted() {
    let m = Message::Sample(sample(4));
    let mut payload = vec![0u8; 256];
    let p = postcard::to_slice(&m, &mut payload).unwrap().to_vec();
    let wrong = reference_frame(VERSION + 1, &p);
    // Unknown enum tag 99, and a valid message followed by a stray byte.
    let unknown = reference_frame(VERSION, &[99, 0, 0]);
    let trailing = reference_frame(VERSION, &[p.clone(), vec![7]].concat());
    let good = reference_frame(VERSION, &p);
    let mut dec = FrameDecoder::new();
    let got = decode_all(&mut dec, &[wrong, unknown, trailing, good].concat());
    assert_eq!(
        got,
        vec![
            Err(FrameError::WrongVersion(VERSION + 1)),
            Err(FrameError::Malformed),
            Err(FrameError::Malformed),
            Ok(m)
        ]
    );
    assert_eq!(dec.stats().wrong_version, 1);
    assert_eq!(dec.stats().malformed, 2);
    // Empty frames (runs of delimiters) are not errors.
    let mut dec = FrameDecoder::new();
    assert!(decode_all(&mut dec, &[0, 0, 0]).is_empty());
    assert_eq!(dec.stats().empty, 3);
    assert_eq!(dec.stats().errors(), 0);
}

#[test]
fn random_bytes_never_panic_and_the_decoder_recovers() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let good = frame(&Message::Sample(sample(8)));
    for round in 0..200 {
        let len = rng.gen_range(0..4000);
        // Mostly random bytes; some rounds with few zeros (long frames).
        let zero_odds = if round % 2 == 0 { 256 } else { 5000 };
        let bytes: Vec<u8> = (0..len)
            .map(|_| {
                if rng.gen_range(0..zero_odds) == 0 {
                    0
                } else {
                    rng.gen_range(1..=255)
                }
            })
            .collect();
        let mut dec = Decoder::<512>::new();
        let mut got = Vec::new();
        for c in bytes.chunks(rng.gen_range(1..64)) {
            dec.feed(c, |m| got.push(m));
        }
        // A delimiter, then a good frame: recovered.
        dec.feed(&[0], |m| got.push(m));
        let before = got.len();
        dec.feed(&good, |m| got.push(m));
        assert_eq!(got.len(), before + 1);
        assert_eq!(got.last(), Some(&Message::Sample(sample(8))));
        let s = dec.stats();
        let frames = bytes.iter().filter(|b| **b == 0).count() as u32 + 2;
        assert_eq!(s.ok + s.errors() + s.empty, frames, "round {round}");
    }
    // Every decode_frame input of a few bytes, exhaustively for length ≤ 2.
    for a in 0..=255u8 {
        for b in 0..=255u8 {
            let _ = decode_frame(&mut [a, b]);
        }
    }
}

fn arb_f32() -> impl Strategy<Value = f32> {
    any::<u32>().prop_map(f32::from_bits)
}

fn arb_f64() -> impl Strategy<Value = f64> {
    any::<u64>().prop_map(f64::from_bits)
}

fn arb_config() -> impl Strategy<Value = ConfigId> {
    (0..ConfigId::ALL.len()).prop_map(|i| ConfigId::ALL[i])
}

fn arb_sample() -> impl Strategy<Value = Sample> {
    (
        any::<u32>(),
        any::<u64>(),
        arb_f32(),
        [arb_f64(), arb_f64(), arb_f64()],
        [arb_f32(), arb_f32(), arb_f32()],
        proptest::option::of([arb_f32(), arb_f32(), arb_f32()]),
        [arb_f32(), arb_f32(), arb_f32(), arb_f32()],
    )
        .prop_map(
            |(seq, t_us, dt, dtheta_cmd, accel_mean, gimbal, c_cn_quat)| Sample {
                seq,
                t_us,
                dt,
                dtheta_cmd,
                accel_mean,
                gimbal,
                c_cn_quat,
            },
        )
}

fn arb_progress() -> impl Strategy<Value = Progress> {
    (
        proptest::option::of(any::<u32>()),
        proptest::option::of(any::<u64>()),
        [arb_f64(), arb_f64(), arb_f64()],
        arb_f64(),
        any::<[u32; 7]>(),
        any::<[u32; 12]>(),
        proptest::option::of(any::<(u32, u64)>()),
    )
        .prop_map(
            |(last_seq, last_t_us, inc, nis, c, r, candidate)| Progress {
                last_seq,
                last_t_us,
                last_increment: inc,
                clock_candidate: candidate,
                last_nis: nis,
                accepted: c[0],
                bridged: c[1],
                reacquired: c[4],
                reacquired_periods: c[5],
                clock_steps: c[6],
                logged: c[0].rotate_left(3),
                log_incomplete: (c[1] % 3 == 0).then_some(SinglePassReason::LogFull),
                gated: c[2],
                since_estimate: c[3],
                rejects: RejectCounts {
                    non_finite: r[0],
                    period: r[1],
                    accel_range: r[2],
                    increment_range: r[3],
                    gimbal_range: r[4],
                    missing_gimbal: r[5],
                    duplicate: r[6],
                    out_of_order: r[7],
                    time_backwards: r[8],
                    time_mismatch: r[9],
                    frame_attitude: r[10],
                    filter: r[11],
                },
            },
        )
}

fn arb_vec<const C: usize>(max: usize) -> impl Strategy<Value = heapless::Vec<f64, C>> {
    proptest::collection::vec(arb_f64(), 0..=max).prop_map(|v| v.into_iter().collect())
}

fn arb_message() -> impl Strategy<Value = Message> {
    prop_oneof![
        arb_sample().prop_map(Message::Sample),
        (
            arb_config(),
            any::<u32>(),
            any::<u32>(),
            arb_vec::<MAX_STATES>(MAX_STATES),
            arb_vec::<MAX_STATES>(MAX_STATES),
            arb_progress(),
            any::<u32>()
        )
            .prop_map(|(config, seq, updates, state, sigma, progress, fe)| {
                Message::Estimate(Estimate {
                    config,
                    errors: if seq % 2 == 0 {
                        rollcal::models::ErrorModel::Installation
                    } else {
                        rollcal::models::ErrorModel::Full
                    },
                    seq,
                    updates,
                    state,
                    sigma,
                    progress,
                    frame_errors: fe,
                    kind: if updates % 2 == 0 {
                        EstimateKind::Running
                    } else {
                        EstimateKind::Final {
                            passes: (seq % 5) as u8,
                            converged: seq % 3 == 0,
                        }
                    },
                })
            }),
        (
            arb_config(),
            arb_vec::<MAX_STATES>(MAX_STATES),
            arb_vec::<MAX_FACTOR>(MAX_FACTOR),
            proptest::option::of(arb_vec::<MAX_STATES>(MAX_STATES)),
            proptest::array::uniform9(arb_f64()),
            any::<u32>(),
            arb_progress()
        )
            .prop_map(
                |(config, state, factor, nominal, c_cn, updates, progress)| {
                    Message::Checkpoint(Checkpoint {
                        config,
                        errors: if updates % 2 == 0 {
                            rollcal::models::ErrorModel::Installation
                        } else {
                            rollcal::models::ErrorModel::Full
                        },
                        state,
                        factor,
                        nominal,
                        c_cn,
                        updates,
                        gated_run: updates.rotate_left(7),
                        gate_open: updates % 2 == 1,
                        progress,
                    })
                }
            ),
        (
            arb_config(),
            arb_f64(),
            any::<u32>(),
            any::<bool>(),
            any::<u8>()
        )
            .prop_map(|(config, x, every, so, it)| {
                let mut c = CalibratorConfig::paper(config);
                c.sigma_accel_g = x;
                c.estimate_every = every;
                c.options = Options {
                    second_order_mean: so,
                    iterations: it,
                    ..Options::default()
                };
                c.limits.max_bridge = every;
                Message::Configure(c)
            }),
        Just(Message::Reset),
        Just(Message::CheckpointRequest),
        Just(Message::EstimateRequest),
        Just(Message::Finish),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// encode → decode is the identity (bit for bit, NaN payloads included),
    /// through a decoder fed in random chunks, with garbage between frames.
    #[test]
    fn round_trip(msgs in proptest::collection::vec(arb_message(), 1..4),
                  chunk in 1usize..300,
                  garbage in proptest::collection::vec(1u8..=255, 0..40)) {
        let mut stream = Vec::new();
        for m in &msgs {
            stream.extend_from_slice(&garbage);
            stream.push(0);
            stream.extend_from_slice(&frame(m));
        }
        let mut dec = FrameDecoder::new();
        let mut got = Vec::new();
        for c in stream.chunks(chunk) {
            dec.feed(c, |m| got.push(m));
        }
        prop_assert_eq!(got.len(), msgs.len());
        for (a, b) in got.iter().zip(&msgs) {
            prop_assert!(same(a, b));
        }
        prop_assert_eq!(dec.stats().ok, msgs.len() as u32);
    }
}
