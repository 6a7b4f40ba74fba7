//! `docs/wire.md` cannot drift from the code: every worked example of the
//! page (a line `frame (NAME): N bytes` or `raw (NAME): N bytes` followed by
//! hex) is the encoder's output for the message built here, the page's hex
//! decodes back to that message, and the sizes the page states are the
//! measured ones.
//!
//! `WIRE_DOC_PRINT=1 cargo test --release -p rollcal --test it wire_doc --
//! --nocapture` prints the examples in the page's format.

use rollcal::estimator::{EstimatorOptions, SliceLog};
use rollcal::models::{ConfigId, ErrorModel};
use rollcal::session::{AnyCalibrator, Reply, Session};
use rollcal::wire::{
    crc32, decode_frame, encode, CalibratorConfig, Checkpoint, Estimate, EstimateKind, Message,
    Progress, Refusal, RefusalReason, RejectCounts, Sample, SinglePassReason, MAX_FRAME_LEN,
    VERSION,
};
use serde::Serialize;

const PAGE: &str = include_str!("../../docs/wire.md");

fn frame(msg: &Message) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let n = encode(msg, &mut buf).unwrap();
    buf.truncate(n);
    buf
}

/// The frame's content before COBS: version, postcard, CRC (little-endian).
fn raw(msg: &Message) -> Vec<u8> {
    let mut raw = vec![VERSION];
    raw.extend_from_slice(&pc(msg));
    let crc = crc32(&raw);
    raw.extend_from_slice(&crc.to_le_bytes());
    raw
}

/// postcard bytes of one value.
fn pc<T: Serialize>(v: &T) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let n = postcard::to_slice(v, &mut buf).unwrap().len();
    buf.truncate(n);
    buf
}

fn sample() -> Sample {
    Sample {
        seq: 1,
        t_us: 1_000_000,
        dt: 1.0,
        dtheta_cmd: [-1.745_329_3e-3, 0.0, 0.0],
        c_cn_quat: [0.999_999_6, -8.726_6e-4, 0.0, 0.0],
        accel_mean: [0.0, 1.0, 0.0],
        gimbal: None,
    }
}

fn sample_gimbal() -> Sample {
    Sample {
        seq: 300,
        t_us: 300_000_000,
        gimbal: Some([0.5, -0.25, 3.0]),
        ..sample()
    }
}

fn running() -> Estimate {
    AnyCalibrator::<f64>::new(CalibratorConfig::paper(ConfigId::M1Pa))
        .unwrap()
        .estimate()
}

fn final_estimate() -> Estimate {
    let mut e = running();
    e.seq = 5400;
    e.updates = 5400;
    e.progress.last_seq = Some(5400);
    e.progress.last_t_us = Some(5_400_000_000);
    e.progress.last_nis = 2.5;
    e.progress.accepted = 5400;
    e.progress.logged = 5400;
    e.kind = EstimateKind::Final {
        passes: 3,
        converged: true,
    };
    e
}

fn single_pass_estimate() -> Estimate {
    let mut e = final_estimate();
    e.progress.log_incomplete = Some(SinglePassReason::LogFull);
    e.progress.logged = 4096;
    e.progress.rejects = RejectCounts {
        duplicate: 2,
        ..RejectCounts::default()
    };
    e.frame_errors = 1;
    e.kind = EstimateKind::SinglePass {
        reason: SinglePassReason::LogFull,
        logged: 4096,
    };
    e
}

/// A fresh M1-pa calibrator's checkpoint, as the page describes it.
fn checkpoint() -> Checkpoint {
    let config = CalibratorConfig::paper(ConfigId::M1Pa);
    let c = AnyCalibrator::<f64>::new(config).unwrap().checkpoint();
    let n = 12;
    assert_eq!((c.state.len(), c.factor.len()), (n, n * (n + 1) / 2));
    assert!(c.state.iter().all(|x| *x == 0.0));
    // The upper triangle row by row: each row starts on the diagonal.
    let diagonal: Vec<usize> = (0..n)
        .map(|r| rollcal::wire::factor_index(n, r, r))
        .collect();
    for (k, d) in c.factor.iter().enumerate() {
        let want = if diagonal.contains(&k) {
            config.prior_sigma_rad.powi(2)
        } else {
            0.0
        };
        assert_eq!(*d, want, "factor[{k}]");
    }
    assert_eq!(c.nominal, None);
    assert_eq!(c.c_cn, [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    assert_eq!((c.updates, c.gated_run, c.gate_open), (0, 0, false));
    assert_eq!(pc(&c.progress), pc(&Progress::default()));
    assert_eq!(pc(&c.progress).len(), 56);
    c
}

/// Every worked example of the page: its name and message.
fn examples() -> Vec<(&'static str, Message)> {
    vec![
        ("Sample", Message::Sample(sample())),
        ("Sample, gimbal", Message::Sample(sample_gimbal())),
        ("Estimate, running", Message::Estimate(running())),
        ("Estimate, final", Message::Estimate(final_estimate())),
        (
            "Estimate, single pass",
            Message::Estimate(single_pass_estimate()),
        ),
        ("Checkpoint", Message::Checkpoint(checkpoint())),
        (
            "Configure",
            Message::Configure(CalibratorConfig::paper(ConfigId::M1Pa)),
        ),
        ("Reset", Message::Reset),
        ("CheckpointRequest", Message::CheckpointRequest),
        ("EstimateRequest", Message::EstimateRequest),
        ("Finish", Message::Finish),
        ("Refused, Configure", refused_configure()),
        ("Refused, restore", refused_restore()),
        ("Refused, field", refused_field()),
    ]
}

/// What a session configured with `CalibratorConfig::paper(M1-pa)` sends
/// back for a `Configure` whose Earth rate is 2e-3 rad/s (above
/// `ekf::MAX_EARTH_RATE`): the session's own refusal, in its wire form.
fn refused_configure() -> Message {
    let mut session = Session::<f64>::new(None, EstimatorOptions::default());
    let mut log = SliceLog::new(&mut []);
    let paper = CalibratorConfig::paper(ConfigId::M1Pa);
    assert_eq!(
        session.handle(&Message::Configure(paper), &mut log),
        Reply::Nothing
    );
    let bad = Message::Configure(CalibratorConfig {
        earth_rate_n: [2e-3, 0.0, 0.0],
        ..paper
    });
    let checkpoint = |s: &Session<f64>| pc(&s.calibrator().unwrap().checkpoint());
    let before = checkpoint(&session);
    let Reply::Error(e) = session.handle(&bad, &mut log) else {
        panic!("the Configure is refused")
    };
    assert_eq!(
        checkpoint(&session),
        before,
        "the session as it was, bit for bit"
    );
    Message::Refused(e.refusal(bad.tag()))
}

/// What the same session sends back for a `Configure` whose `k2` prior is
/// 100 g/g² (the data sheet's 100 µg/g² given as g/g²): the field, named.
fn refused_field() -> Message {
    let mut session = Session::<f64>::new(None, EstimatorOptions::default());
    let mut log = SliceLog::new(&mut []);
    let paper = CalibratorConfig::paper(ConfigId::M1Pa);
    assert_eq!(
        session.handle(&Message::Configure(paper), &mut log),
        Reply::Nothing
    );
    let mut bad = paper;
    bad.instrument_prior.k2 = 100.0;
    let bad = Message::Configure(bad);
    let checkpoint = |s: &Session<f64>| pc(&s.calibrator().unwrap().checkpoint());
    let before = checkpoint(&session);
    let Reply::Error(e) = session.handle(&bad, &mut log) else {
        panic!("the Configure is refused")
    };
    assert_eq!(checkpoint(&session), before, "the session as it was");
    assert_eq!(
        session.calibrator().unwrap().settings().instrument_prior.k2,
        paper.instrument_prior.k2
    );
    Message::Refused(e.refusal(bad.tag()))
}

/// What the same session sends back for the checkpoint of an M2-ps
/// calibrator (a restore of another configuration).
fn refused_restore() -> Message {
    let mut session = Session::<f64>::new(None, EstimatorOptions::default());
    let mut log = SliceLog::new(&mut []);
    let paper = CalibratorConfig::paper(ConfigId::M1Pa);
    assert_eq!(
        session.handle(&Message::Configure(paper), &mut log),
        Reply::Nothing
    );
    let other = AnyCalibrator::<f64>::new(CalibratorConfig::paper(ConfigId::M2Ps)).unwrap();
    let restore = Message::Checkpoint(other.checkpoint());
    let Reply::Error(e) = session.handle(&restore, &mut log) else {
        panic!("the restore is refused")
    };
    Message::Refused(e.refusal(restore.tag()))
}

/// The hex block after the line `KIND (NAME): N bytes` (the page's stated
/// N, and the bytes: on each following line up to the first two spaces, up
/// to a blank line or a fence), or `None` when the page has no such line.
fn block(kind: &str, name: &str) -> Option<(usize, Vec<u8>)> {
    let marker = format!("{kind} ({name}): ");
    let mut lines = PAGE.lines();
    let head = lines.by_ref().find(|l| l.starts_with(&marker))?;
    let stated = head[marker.len()..]
        .strip_suffix(" bytes")
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{kind} ({name}): the line must end with `N bytes`: {head}"));
    let mut bytes = Vec::new();
    for line in lines {
        if line.trim().is_empty() || line.starts_with("```") {
            break;
        }
        let hex = line.split("  ").next().unwrap_or("");
        for tok in hex.split_whitespace() {
            let b = u8::from_str_radix(tok, 16)
                .ok()
                .filter(|_| tok.len() == 2)
                .unwrap_or_else(|| panic!("{kind} ({name}): `{tok}` is not a hex byte: {line}"));
            bytes.push(b);
        }
    }
    Some((stated, bytes))
}

fn hex_lines(bytes: &[u8], per_line: usize) -> String {
    bytes
        .chunks(per_line)
        .map(|c| {
            c.iter()
                .map(|b| format!("{b:02x}"))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn every_worked_example_is_the_encoders_output_and_decodes() {
    let print = std::env::var_os("WIRE_DOC_PRINT").is_some();
    let mut failures = Vec::new();
    for (name, msg) in examples() {
        let want = frame(&msg);
        if print {
            println!(
                "frame ({name}): {} bytes\n{}\n",
                want.len(),
                hex_lines(&want, 24)
            );
            let r = raw(&msg);
            println!("raw ({name}): {} bytes\n{}\n", r.len(), hex_lines(&r, 8));
        }
        match block("frame", name) {
            None => failures.push(format!(
                "docs/wire.md has no `frame ({name}): N bytes` block"
            )),
            Some((stated, got)) => {
                if got != want {
                    failures.push(format!(
                        "frame ({name}): the page's hex is not the encoder's:\n{}",
                        hex_lines(&want, 24)
                    ));
                } else if stated != want.len() {
                    failures.push(format!(
                        "frame ({name}): {} bytes, the page says {stated}",
                        want.len()
                    ));
                }
                // The page's bytes decode to the message: re-encoded
                // bit-identical (a NaN field is not `==` itself).
                let mut f = got.clone();
                f.pop();
                match decode_frame(&mut f) {
                    Ok(back) if frame(&back) == got => {}
                    other => failures.push(format!(
                        "frame ({name}): the page's hex decodes to {other:?}"
                    )),
                }
            }
        }
        // An annotated raw block, where the page has one, is also exact.
        if let Some((stated, got)) = block("raw", name) {
            let want = raw(&msg);
            if got != want || stated != want.len() {
                failures.push(format!(
                    "raw ({name}): the page's annotated bytes ({stated} stated, {} listed) are not the {} raw bytes:\n{}",
                    got.len(),
                    want.len(),
                    hex_lines(&want, 8)
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// An f64 none of whose bytes is zero (a worst case for COBS).
const DENSE: f64 = -1.234_567_890_123_456_7e-3;

fn progress(max: bool) -> Progress {
    if !max {
        return Progress {
            last_nis: 0.0,
            ..Progress::default()
        };
    }
    let m = u32::MAX;
    Progress {
        last_seq: Some(m),
        last_t_us: Some(u64::MAX),
        last_increment: [DENSE; 3],
        clock_candidate: Some((m, u64::MAX)),
        last_nis: DENSE,
        accepted: m,
        bridged: m,
        reacquired: m,
        reacquired_periods: m,
        clock_steps: m,
        logged: m,
        log_incomplete: Some(SinglePassReason::LogUnrepresentable),
        gated: m,
        since_estimate: m,
        rejects: RejectCounts {
            non_finite: m,
            period: m,
            accel_range: m,
            increment_range: m,
            gimbal_range: m,
            missing_gimbal: m,
            duplicate: m,
            out_of_order: m,
            time_backwards: m,
            time_mismatch: m,
            frame_attitude: m,
            filter: m,
        },
    }
}

/// The model of `n` states (18: M2-ps; 39: the full M2-ps).
fn model(n: usize) -> (ConfigId, ErrorModel) {
    let config = ConfigId::M2Ps;
    let errors = if n == 18 {
        ErrorModel::Installation
    } else {
        ErrorModel::Full
    };
    assert_eq!(config.states_with(errors).len(), n);
    (config, errors)
}

fn estimate_of(n: usize, max: bool) -> Message {
    let (config, errors) = model(n);
    let v = if max { DENSE } else { 0.0 };
    Message::Estimate(Estimate {
        config,
        errors,
        seq: if max { u32::MAX } else { 0 },
        updates: if max { u32::MAX } else { 0 },
        state: (0..n).map(|_| v).collect(),
        sigma: (0..n).map(|_| v).collect(),
        progress: progress(max),
        frame_errors: if max { u32::MAX } else { 0 },
        kind: if max {
            EstimateKind::SinglePass {
                reason: SinglePassReason::LogUnrepresentable,
                logged: u32::MAX,
            }
        } else {
            EstimateKind::Running
        },
    })
}

fn checkpoint_of(n: usize, max: bool) -> Message {
    let (config, errors) = model(n);
    let v = if max { DENSE } else { 0.0 };
    Message::Checkpoint(Checkpoint {
        config,
        errors,
        state: (0..n).map(|_| v).collect(),
        factor: (0..n * (n + 1) / 2).map(|_| v).collect(),
        nominal: max.then(|| (0..n).map(|_| v).collect()),
        c_cn: [v; 9],
        updates: if max { u32::MAX } else { 0 },
        gated_run: if max { u32::MAX } else { 0 },
        gate_open: max,
        progress: progress(max),
    })
}

fn sample_of(max: bool) -> Message {
    let v = if max { DENSE as f32 } else { 0.0 };
    Message::Sample(Sample {
        seq: if max { u32::MAX } else { 0 },
        t_us: if max { u64::MAX } else { 0 },
        dt: v,
        dtheta_cmd: [if max { DENSE } else { 0.0 }; 3],
        c_cn_quat: [v; 4],
        accel_mean: [v; 3],
        gimbal: max.then_some([v; 3]),
    })
}

fn configure_of(max: bool) -> Message {
    let mut c = CalibratorConfig::paper(ConfigId::M1Pa);
    if max {
        c.config = ConfigId::M4Ps;
        c.errors = ErrorModel::Full;
        c.estimate_every = u32::MAX;
        c.limits.max_bridge = u32::MAX;
        c.options.iterate_updates = u32::MAX;
        c.options.iterations = u8::MAX;
        // The realistic scenario's wandering errors (no zero byte).
        c.wander = crate::support::realistic_wander();
    } else {
        c.estimate_every = 0;
        c.limits.max_bridge = 0;
    }
    Message::Configure(c)
}

/// The page's table of frame sizes is the measured one: the smallest frame
/// (every varint one byte, every option `None`, every float zero) and the
/// largest (every counter at its maximum, every option `Some`, no float
/// with a zero byte, so that COBS adds a code byte per 254 bytes), and both
/// fit `MAX_FRAME_LEN` (of this build; 54 states need `full-model`).
#[test]
fn the_pages_frame_sizes_are_measured() {
    let rows: Vec<(String, Message, Message)> = vec![
        ("`Sample`".into(), sample_of(false), sample_of(true)),
        (
            "`Estimate`, 18 states".into(),
            estimate_of(18, false),
            estimate_of(18, true),
        ),
        (
            "`Estimate`, 54 states".into(),
            estimate_of(54, false),
            estimate_of(54, true),
        ),
        (
            "`Checkpoint`, 18 states".into(),
            checkpoint_of(18, false),
            checkpoint_of(18, true),
        ),
        (
            "`Checkpoint`, 54 states".into(),
            checkpoint_of(54, false),
            checkpoint_of(54, true),
        ),
        (
            "`Configure`".into(),
            configure_of(false),
            configure_of(true),
        ),
        (
            "`Reset`, `CheckpointRequest`, `EstimateRequest`, `Finish`".into(),
            Message::Reset,
            Message::Finish,
        ),
        (
            "`Refused`".into(),
            Message::Refused(Refusal {
                message: 0,
                reason: RefusalReason::NotConfigured,
            }),
            Message::Refused(Refusal {
                message: u8::MAX,
                reason: RefusalReason::ConfigMismatch {
                    expected: ConfigId::M4Ps,
                    found: ConfigId::M4Ps,
                },
            }),
        ),
    ];
    let mut missing = Vec::new();
    for (name, small, large) in rows {
        let (a, b) = (frame(&small).len(), frame(&large).len());
        assert!(a <= b && b <= MAX_FRAME_LEN, "{name}: {a}..{b}");
        let row = format!("| {name} | {a} | {b} |");
        if std::env::var_os("WIRE_DOC_PRINT").is_some() {
            println!("{row}");
        }
        if !PAGE.contains(&row) {
            missing.push(row);
        }
    }
    assert!(
        missing.is_empty(),
        "docs/wire.md lacks the rows\n{}",
        missing.join("\n")
    );
}

/// The raw bytes of a message field by field, with a label each: the page's
/// annotated `raw` blocks (printed with `WIRE_DOC_PRINT=1`; the check above
/// compares only their bytes).
fn annotated(msg: &Message) -> Vec<(Vec<u8>, String)> {
    let mut out: Vec<(Vec<u8>, String)> = vec![(vec![VERSION], format!("version {VERSION}"))];
    let tag = pc(msg)[0];
    let variant = format!("{msg:?}");
    let variant = variant.split(['(', ' ']).next().unwrap_or("").to_string();
    out.push((vec![tag], format!("Message tag {tag} = {variant}")));
    let mut f = |bytes: Vec<u8>, label: String| out.push((bytes, label));
    let floats = |f: &mut dyn FnMut(Vec<u8>, String), name: &str, v: &[f64]| {
        for (i, x) in v.iter().enumerate() {
            f(pc(x), format!("{name}[{i}] = {x:e}"));
        }
    };
    let progress = |f: &mut dyn FnMut(Vec<u8>, String), p: &Progress| {
        f(
            pc(&p.last_seq),
            format!("progress.last_seq = {:?}", p.last_seq),
        );
        f(
            pc(&p.last_t_us),
            format!("progress.last_t_us = {:?}", p.last_t_us),
        );
        f(
            pc(&p.last_increment),
            format!("progress.last_increment = {:?}", p.last_increment),
        );
        f(
            pc(&p.clock_candidate),
            format!("progress.clock_candidate = {:?}", p.clock_candidate),
        );
        f(
            pc(&p.last_nis),
            format!("progress.last_nis = {:?}", p.last_nis),
        );
        for (name, v) in [
            ("accepted", p.accepted),
            ("bridged", p.bridged),
            ("reacquired", p.reacquired),
            ("reacquired_periods", p.reacquired_periods),
            ("clock_steps", p.clock_steps),
            ("logged", p.logged),
        ] {
            f(pc(&v), format!("progress.{name} = {v}"));
        }
        f(
            pc(&p.log_incomplete),
            format!("progress.log_incomplete = {:?}", p.log_incomplete),
        );
        f(pc(&p.gated), format!("progress.gated = {}", p.gated));
        f(
            pc(&p.since_estimate),
            format!("progress.since_estimate = {}", p.since_estimate),
        );
        let r = &p.rejects;
        let nonzero: Vec<String> = [
            ("duplicate", r.duplicate),
            ("filter", r.filter),
            ("period", r.period),
        ]
        .iter()
        .filter(|(_, v)| *v > 0)
        .map(|(n, v)| format!("{n} = {v}"))
        .collect();
        let others = if nonzero.is_empty() {
            "all 0".to_string()
        } else {
            format!("{}, others 0", nonzero.join(", "))
        };
        f(pc(r), format!("progress.rejects (12 varints): {others}"));
    };
    match msg {
        Message::Refused(r) => {
            f(
                pc(&r.message),
                format!("message = {} (u8: the refused message's tag)", r.message),
            );
            f(pc(&r.reason), format!("reason = {:?}", r.reason));
        }
        Message::Sample(s) => {
            f(pc(&s.seq), format!("seq = {} (varint)", s.seq));
            f(pc(&s.t_us), format!("t_us = {} (varint)", s.t_us));
            f(pc(&s.dt), format!("dt = {:?} (f32)", s.dt));
            for (i, x) in s.dtheta_cmd.iter().enumerate() {
                f(pc(x), format!("dtheta_cmd[{i}] = {x:e} (f64)"));
            }
            for (i, x) in s.c_cn_quat.iter().enumerate() {
                f(pc(x), format!("c_cn_quat[{i}] = {x:e} (f32)"));
            }
            f(
                pc(&s.accel_mean),
                format!("accel_mean = {:?} (3 × f32)", s.accel_mean),
            );
            f(pc(&s.gimbal), format!("gimbal = {:?}", s.gimbal));
        }
        Message::Estimate(e) => {
            f(pc(&e.config), format!("config = {:?}", e.config));
            f(pc(&e.errors), format!("errors = {:?}", e.errors));
            f(pc(&e.seq), format!("seq = {}", e.seq));
            f(pc(&e.updates), format!("updates = {}", e.updates));
            f(
                pc(&(e.state.len() as u32)),
                format!("state: length {}", e.state.len()),
            );
            floats(&mut f, "state", &e.state);
            f(
                pc(&(e.sigma.len() as u32)),
                format!("sigma: length {}", e.sigma.len()),
            );
            floats(&mut f, "sigma", &e.sigma);
            progress(&mut f, &e.progress);
            f(
                pc(&e.frame_errors),
                format!("frame_errors = {}", e.frame_errors),
            );
            f(pc(&e.kind), format!("kind = {:?}", e.kind));
        }
        Message::Configure(c) => {
            f(pc(&c.config), format!("config = {:?}", c.config));
            f(
                pc(&c.sigma_accel_g),
                format!("sigma_accel_g = {:e}", c.sigma_accel_g),
            );
            f(
                pc(&c.sigma_gyro_rad_s),
                format!("sigma_gyro_rad_s = {:e}", c.sigma_gyro_rad_s),
            );
            f(
                pc(&c.sigma_gimbal_rad),
                format!("sigma_gimbal_rad = {:e}", c.sigma_gimbal_rad),
            );
            floats(&mut f, "earth_rate_n", &c.earth_rate_n);
            floats(&mut f, "gravity_n", &c.gravity_n);
            f(
                pc(&c.prior_sigma_rad),
                format!("prior_sigma_rad = {:e}", c.prior_sigma_rad),
            );
            let o = &c.options;
            f(
                pc(&o.second_order_covariance),
                format!(
                    "options.second_order_covariance = {}",
                    o.second_order_covariance
                ),
            );
            f(
                pc(&o.second_order_mean),
                format!("options.second_order_mean = {}", o.second_order_mean),
            );
            f(
                pc(&o.second_order_dynamics),
                format!(
                    "options.second_order_dynamics = {}",
                    o.second_order_dynamics
                ),
            );
            f(
                pc(&o.iterations),
                format!("options.iterations = {} (u8)", o.iterations),
            );
            f(
                pc(&o.iterate_updates),
                format!("options.iterate_updates = {}", o.iterate_updates),
            );
            f(
                pc(&o.nis_gate),
                format!("options.nis_gate = {:?}", o.nis_gate),
            );
            let l = &c.limits;
            f(
                pc(&l.period_s),
                format!("limits.period_s = {:?}", l.period_s),
            );
            f(
                pc(&l.period_tolerance_s),
                format!("limits.period_tolerance_s = {:e}", l.period_tolerance_s),
            );
            f(
                pc(&l.max_accel_g),
                format!("limits.max_accel_g = {:?}", l.max_accel_g),
            );
            f(
                pc(&l.max_increment_rad),
                format!("limits.max_increment_rad = {:?}", l.max_increment_rad),
            );
            f(
                pc(&l.max_gimbal_rad),
                format!("limits.max_gimbal_rad = {:?} (2π)", l.max_gimbal_rad),
            );
            f(
                pc(&l.max_bridge),
                format!("limits.max_bridge = {}", l.max_bridge),
            );
            f(
                pc(&l.frame_tolerance_rad),
                format!("limits.frame_tolerance_rad = {:e}", l.frame_tolerance_rad),
            );
            f(
                pc(&c.estimate_every),
                format!("estimate_every = {}", c.estimate_every),
            );
            f(pc(&c.errors), format!("errors = {:?}", c.errors));
            let p = &c.instrument_prior;
            f(
                pc(&p.dg_rad_s),
                format!("instrument_prior.dg_rad_s = {:e}", p.dg_rad_s),
            );
            f(
                pc(&p.d_g_rad_s_g),
                format!("instrument_prior.d_g_rad_s_g = {:e}", p.d_g_rad_s_g),
            );
            f(pc(&p.kg), format!("instrument_prior.kg = {:e}", p.kg));
            f(pc(&p.ba_g), format!("instrument_prior.ba_g = {:e}", p.ba_g));
            f(pc(&p.ka), format!("instrument_prior.ka = {:e}", p.ka));
            f(pc(&p.k2), format!("instrument_prior.k2 = {:e}", p.k2));
            let w = &c.wander;
            for (name, v) in [
                ("gyro_markov_sigma", w.gyro_markov_sigma),
                ("gyro_markov_tau_s", w.gyro_markov_tau_s),
                ("gyro_random_walk", w.gyro_random_walk),
                ("accel_markov_sigma", w.accel_markov_sigma),
                ("accel_markov_tau_s", w.accel_markov_tau_s),
                ("accel_random_walk", w.accel_random_walk),
                ("gyro_warmup_sigma", w.gyro_warmup_sigma),
                ("accel_warmup_sigma", w.accel_warmup_sigma),
                ("warmup_tau_s", w.warmup_tau_s),
            ] {
                f(pc(&v), format!("wander.{name} = {v:e}"));
            }
        }
        _ => {}
    }
    let r = raw(msg);
    let crc = r[r.len() - 4..].to_vec();
    let c = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
    out.push((
        crc,
        format!(
            "CRC-32 of the {} bytes above = 0x{c:08X}, little-endian",
            r.len() - 4
        ),
    ));
    let joined: Vec<u8> = out.iter().flat_map(|(b, _)| b.clone()).collect();
    assert_eq!(joined, r, "the annotation's fields are the message's bytes");
    out
}

fn print_annotated(name: &str, msg: &Message) {
    println!("raw ({name}): {} bytes", raw(msg).len());
    for (bytes, label) in annotated(msg) {
        for (i, chunk) in bytes.chunks(8).enumerate() {
            let hex = hex_lines(chunk, 8);
            if i == 0 {
                println!("{hex:<24}  {label}");
            } else {
                println!("{hex}");
            }
        }
    }
    println!();
}

#[test]
fn print_annotated_examples() {
    if std::env::var_os("WIRE_DOC_PRINT").is_none() {
        return;
    }
    for (name, msg) in examples() {
        if !matches!(msg, Message::Checkpoint(_)) {
            print_annotated(name, &msg);
        }
    }
}

/// The hex of a value's little-endian bytes (the Python decoder's floats).
fn bits<T: Serialize>(v: &T) -> String {
    pc(v).iter().map(|b| format!("{b:02x}")).collect()
}

fn run_python(args: &[&str]) -> String {
    let root = env!("CARGO_MANIFEST_DIR");
    let out = std::process::Command::new("python3")
        .arg(format!("{root}/tools/wire_decode.py"))
        .args(args)
        .output()
        .expect("python3 runs (tools/wire_decode.py)");
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        out.status.success(),
        "tools/wire_decode.py {args:?} failed:\n{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

/// An independent decoder written from the page alone (`tools/wire_decode.py`)
/// reads the recorded stream (5401 frames) bit-identically to the Rust
/// decoder, and reads every worked example (the replies included) to the
/// fields the Rust side built.
#[test]
fn a_python_decoder_written_from_the_page_reads_the_stream_and_every_example() {
    let root = env!("CARGO_MANIFEST_DIR");
    let samples_path = std::env::temp_dir().join(format!("wire_doc_{}.txt", std::process::id()));
    let samples_arg = samples_path.to_str().unwrap();
    let stream = run_python(&[
        "stream",
        &format!("{root}/tests/data/paper_seed1.bin"),
        "--samples",
        samples_arg,
    ]);
    let got = std::fs::read_to_string(&samples_path).unwrap();
    std::fs::remove_file(&samples_path).ok();
    assert!(
        stream.contains("frames ok=5401 truncated=0 corrupt=0 wrong_version=0 malformed=0 empty=0"),
        "{stream}"
    );
    assert!(
        stream.contains("messages Configure=1 Sample=5400"),
        "{stream}"
    );
    let (_, samples) = crate::support::paper_stream();
    let want: String = samples
        .iter()
        .map(|s| {
            let mut f = vec![s.seq.to_string(), s.t_us.to_string(), bits(&s.dt)];
            f.extend(s.dtheta_cmd.iter().map(bits));
            f.extend(s.c_cn_quat.iter().map(bits));
            f.extend(s.accel_mean.iter().map(bits));
            match s.gimbal {
                Some(g) => f.extend(g.iter().map(bits)),
                None => f.push("none".into()),
            }
            f.join(" ") + "\n"
        })
        .collect();
    assert_eq!(got.lines().count(), 5400);
    for (i, (a, b)) in got.lines().zip(want.lines()).enumerate() {
        assert_eq!(a, b, "sample {i}: Python decoder vs Rust decoder");
    }

    let doc = run_python(&["doc", &format!("{root}/docs/wire.md")]);
    let single_pass = |r: SinglePassReason| format!("{r:?}");
    for (name, msg) in examples() {
        let line = doc
            .lines()
            .find(|l| l.starts_with(&format!("{name}: ")))
            .unwrap_or_else(|| panic!("the Python decoder did not read `{name}`:\n{doc}"));
        let expect: Vec<String> = match &msg {
            Message::Sample(s) => vec![format!("seq={}", s.seq), format!("t_us={}", s.t_us)],
            Message::Estimate(e) => {
                let kind = match e.kind {
                    EstimateKind::Running => "Running".to_string(),
                    EstimateKind::Final { passes, converged } => format!(
                        "Final(passes={passes}, converged={})",
                        if converged { "True" } else { "False" }
                    ),
                    EstimateKind::SinglePass { reason, logged } => {
                        format!(
                            "SinglePass(reason={}, logged={logged})",
                            single_pass(reason)
                        )
                    }
                };
                vec![
                    format!("Estimate config={} errors={:?}", e.config, e.errors),
                    format!("seq={} updates={}", e.seq, e.updates),
                    format!("state.len={} sigma.len={}", e.state.len(), e.sigma.len()),
                    format!("progress.last_nis={}", bits(&e.progress.last_nis)),
                    format!("progress.logged={}", e.progress.logged),
                    format!(
                        "progress.log_incomplete={}",
                        e.progress.log_incomplete.map_or("None".into(), single_pass)
                    ),
                    format!(
                        "progress.rejects.duplicate={}",
                        e.progress.rejects.duplicate
                    ),
                    format!("frame_errors={} kind={kind}", e.frame_errors),
                ]
            }
            Message::Checkpoint(c) => vec![
                format!("factor.len={}", c.factor.len()),
                format!("updates={} gated_run={}", c.updates, c.gated_run),
                format!("progress.accepted={}", c.progress.accepted),
            ],
            Message::Configure(c) => vec![
                format!("Configure config={}", c.config),
                format!("options.nis_gate={}", bits(&c.options.nis_gate)),
                format!("limits.max_bridge={}", c.limits.max_bridge),
                format!("estimate_every={} errors={:?}", c.estimate_every, c.errors),
                format!(
                    "instrument_prior.dg_rad_s={}",
                    bits(&c.instrument_prior.dg_rad_s)
                ),
                format!("instrument_prior.ka={}", bits(&c.instrument_prior.ka)),
                format!("instrument_prior.k2={}", bits(&c.instrument_prior.k2)),
                format!(
                    "wander.accel_random_walk={}",
                    bits(&c.wander.accel_random_walk)
                ),
            ],
            Message::Refused(r) => {
                let reason = match r.reason {
                    RefusalReason::ConfigMismatch { expected, found } => {
                        format!("ConfigMismatch(expected={expected}, found={found})")
                    }
                    other => format!("{other:?}"),
                };
                vec![format!("Refused message={} reason={reason}", r.message)]
            }
            other => vec![format!("{other:?}")],
        };
        for e in expect {
            assert!(
                line.contains(&e),
                "{name}: the Python decoder's line lacks `{e}`:\n{line}"
            );
        }
    }
}

/// The prose of the worked examples: the numbers it quotes are the bytes'.
#[test]
fn the_worked_examples_prose_is_the_bytes() {
    let r = raw(&Message::Checkpoint(checkpoint()));
    let quoted = format!("`raw` ({} bytes)", r.len());
    assert!(
        PAGE.contains(&quoted),
        "docs/wire.md §Checkpoint lacks {quoted}"
    );
    let diag = hex_lines(
        &pc(&CalibratorConfig::paper(ConfigId::M1Pa)
            .prior_sigma_rad
            .powi(2)),
        8,
    );
    assert!(
        PAGE.contains(&format!("`{diag}`")),
        "docs/wire.md §Checkpoint lacks `{diag}`"
    );
    let r = raw(&Message::Estimate(final_estimate()));
    let tail = hex_lines(&r[r.len() - 8..r.len() - 4], 8);
    assert_eq!(tail, "00 01 03 01");
    assert!(PAGE.contains(&format!("ends in `… {tail}`")));
}
