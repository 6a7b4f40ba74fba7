//! The integration kit (`rollcal::device`) on a model of a NOR device
//! (`flash_log::Nor`: a word written once between erases, a power cut
//! after any operation, the cut one landing in part or not at all):
//!
//! - a cut after every write and erase of a run: the device restarted on
//!   what the flash kept resumes by itself (configuration, checkpoint, the
//!   records after it replayed), the host's stream goes on where it was,
//!   and the final answer is bit for bit the uninterrupted run's where the
//!   cut lost no sample, and bit for bit that of an uninterrupted run over
//!   the samples the device kept where it lost some (or within 1e-6σ of it:
//!   the gap is bridged from a replayed record's increment, as the packed
//!   log rounded it);
//! - a flash of another format version, or whose stored `Configure` is
//!   damaged, is recognised and not resumed from;
//! - a region that does not fit is refused and the device given back.

#![cfg(feature = "flash-log")]

use rollcal::device::{Device, DeviceError, Idle, ResumeRefusal};
use rollcal::models::ConfigId;
use rollcal::wire::{decode_frame, encode, EstimateKind, Message, Sample, MAX_FRAME_LEN};

use crate::flash_log::{Cut, Nor};
use crate::support::paper_stream;

/// 4-byte words, 4 KiB sectors, 1-byte reads.
type Dev = Nor<1, 4, 4096>;
/// Sectors of the device: 2 control banks of 4 sectors and 8 of log.
const SECTORS: usize = 16;
const REGION: std::ops::Range<u32> = 0..(SECTORS as u32 * 4096);

/// A final answer: state and σ (rad).
type Answer = (Vec<f64>, Vec<f64>);

/// The frames of the paper stream's `Configure` and first `n` samples.
fn stream(n: usize) -> (Vec<u8>, Vec<Sample>) {
    let (config, samples) = paper_stream();
    let config = rollcal::wire::CalibratorConfig {
        estimate_every: 50,
        ..config
    };
    (frame(&Message::Configure(config)), samples[..n].to_vec())
}

fn frame(m: &Message) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let n = encode(m, &mut buf).unwrap();
    buf.truncate(n);
    buf
}

/// Feeds `bytes`; the last reply.
fn feed(dev: &mut Device<Dev, f64>, bytes: &[u8]) -> Option<Vec<u8>> {
    let mut last = None;
    dev.push_bytes(bytes, |r| last = Some(r.to_vec()));
    last
}

/// The final answer (state and σ, rad) of the device's `Finish`, or `None`
/// when it has none of record.
fn finish(dev: &mut Device<Dev, f64>) -> Option<Answer> {
    let mut reply = feed(dev, &frame(&Message::Finish))?;
    let n = reply.len();
    match decode_frame(&mut reply[..n - 1]).unwrap() {
        Message::Estimate(e) if matches!(e.kind, EstimateKind::Final { .. }) => {
            Some((e.state.to_vec(), e.sigma.to_vec()))
        }
        _ => None,
    }
}

fn dead(dev: &Device<Dev, f64>) -> bool {
    dev.log().is_some_and(|l| l.flash().dead)
}

/// A new device on `flash`, started, checkpointing every 40 samples.
fn boot(flash: Dev) -> (Box<Device<Dev, f64>>, rollcal::device::Resume) {
    let mut dev = Box::new(Device::<Dev, f64>::new());
    dev.set_checkpoint_every(40);
    let resume = dev.start(flash, REGION).map_err(|(_, e)| e).unwrap();
    (dev, resume)
}

/// An uninterrupted run over `config` and `samples` (one `idle` after every
/// frame); its answer and the flash operations it made.
fn uninterrupted(config: &[u8], samples: &[Sample]) -> (Option<Answer>, usize) {
    let (mut dev, resume) = boot(Dev::new(SECTORS));
    assert_eq!(resume.config, None);
    feed(&mut dev, config);
    dev.idle();
    for s in samples {
        feed(&mut dev, &frame(&Message::Sample(*s)));
        dev.idle();
    }
    let ops = dev.log().unwrap().flash().ops;
    (finish(&mut dev), ops)
}

#[test]
fn a_cut_after_every_flash_operation_resumes_to_the_uninterrupted_answer() {
    let (config, samples) = stream(150);
    let (want, ops) = uninterrupted(&config, &samples);
    let want = want.expect("the uninterrupted run answers with the estimator of record");
    let (mut identical, mut lost_runs, mut lost_identical, mut no_config) = (0, 0, 0, 0);
    let mut worst = 0.0f64;
    for cut in [Cut::Nothing, Cut::Half] {
        for at in 0..ops {
            let (mut dev, _) = boot(Dev::new(SECTORS).cut_after(at, cut));
            // The host's stream, up to the cut.
            let mut next = 0;
            feed(&mut dev, &config);
            if !dead(&dev) {
                dev.idle();
            }
            while !dead(&dev) && next < samples.len() {
                feed(&mut dev, &frame(&Message::Sample(samples[next])));
                next += 1;
                if !dead(&dev) {
                    dev.idle();
                }
            }
            assert!(dead(&dev), "the cut after {at} operations happened");
            // The device restarts on what the flash kept; the host goes on.
            let flash = dev.release().unwrap().revive();
            let (mut dev, resume) = boot(flash);
            for s in &samples[next..] {
                feed(&mut dev, &frame(&Message::Sample(*s)));
                dev.idle();
            }
            let got = finish(&mut dev);
            let Some(_) = resume.config else {
                // The cut fell inside the Configure's own record: nothing to
                // resume, the run is the host's to restart.
                assert!(got.is_none(), "cut {at}: no configuration, no answer");
                no_config += 1;
                continue;
            };
            assert_eq!(resume.refused, None, "cut {at} ({cut:?})");
            // The samples the device kept: those up to the resumed one, and
            // those after the cut.
            let resumed = resume.last_seq;
            let kept: Vec<Sample> = samples
                .iter()
                .enumerate()
                .filter(|(i, s)| *i >= next || resumed.is_some_and(|r| s.seq <= r))
                .map(|(_, s)| *s)
                .collect();
            let got = got.unwrap_or_else(|| panic!("cut {at} ({cut:?}): no answer of record"));
            if kept.len() == samples.len() {
                assert_eq!(got, want, "cut {at} ({cut:?}) lost nothing: bit-identical");
                identical += 1;
            } else {
                let (reference, _) = uninterrupted(&config, &kept);
                let reference = reference.expect("the run over the kept samples answers");
                if got == reference {
                    lost_identical += 1;
                }
                // The gap the lost samples leave is bridged from the last
                // increment, which a replayed record holds as the packed
                // log rounded it (2^-40 rad): the answer may move by that.
                let dsigma = got
                    .0
                    .iter()
                    .zip(&reference.0)
                    .zip(&reference.1)
                    .map(|((a, b), s)| (a - b).abs() / s)
                    .fold(0.0f64, f64::max);
                assert!(
                    dsigma <= 1e-6,
                    "cut {at} ({cut:?}), {} samples lost: {dsigma:e} sigma from the run over the kept samples",
                    samples.len() - kept.len()
                );
                worst = worst.max(dsigma);
                lost_runs += 1;
            }
        }
    }
    println!(
        "device: {} bytes in f64, {} in f32 (the session, one frame buffer, one message slot)",
        std::mem::size_of::<Device<Dev, f64>>(),
        std::mem::size_of::<Device<Dev, f32>>()
    );
    println!(
        "device power cuts: {ops} operations x 2 kinds of cut: {identical} resumed bit-identical \
         with nothing lost; {lost_runs} lost samples, of which {lost_identical} bit-identical to \
         the run over the kept samples, the rest within {worst:.1e} sigma of it; {no_config} \
         inside the Configure's record"
    );
    // A cut of a sample's own record loses that sample (150 of the
    // operations); one during `idle` (an erase ahead, a checkpoint) loses
    // nothing once the run's first checkpoint is written.
    assert_eq!(identical + lost_runs + no_config, 2 * ops);
    assert!(identical >= 2 * (ops - samples.len() - 20), "{identical}");
}

/// The frame buffer holds the reply and the flash records between frames:
/// an `idle` while a frame is arriving leaves a due checkpoint for later
/// and the frame whole. Here every `idle` falls inside a frame, so the
/// checkpoints due wait until an `idle` after the last frame; the replies
/// and the final answer are those of a run whose `idle`s come between
/// frames.
#[test]
fn an_idle_inside_a_frame_leaves_the_frame_and_checkpoints_after_it() {
    let (config, samples) = stream(90);
    let run = |inside: bool| {
        let (mut dev, _) = boot(Dev::new(SECTORS));
        feed(&mut dev, &config);
        while dev.idle() != Idle::Nothing {}
        let mut replies = Vec::new();
        for s in &samples {
            let bytes = frame(&Message::Sample(*s));
            let (head, tail) = bytes.split_at(bytes.len() / 2);
            replies.extend(feed(&mut dev, head));
            if inside {
                while dev.idle() != Idle::Nothing {}
                assert_eq!(dev.stats().checkpoints, 0);
            }
            replies.extend(feed(&mut dev, tail));
            if !inside {
                while dev.idle() != Idle::Nothing {}
            }
        }
        let during = dev.stats().checkpoints;
        while dev.idle() != Idle::Nothing {}
        assert_eq!(dev.decoder().stats().errors(), 0);
        let after = dev.stats().checkpoints;
        (replies, (during, after), finish(&mut dev))
    };
    let (between, inside) = (run(false), run(true));
    // 90 samples, a checkpoint after the first and every 40: 3.
    assert_eq!(between.1, (3, 3));
    assert_eq!(inside.1, (0, 1));
    assert!(inside.2.is_some());
    assert_eq!((between.0, between.2), (inside.0, inside.2));
}

#[test]
fn a_flash_of_another_format_a_damaged_or_refused_configure_or_another_runs_log_is_not_resumed_from(
) {
    let (config, samples) = stream(60);
    let (mut dev, _) = boot(Dev::new(SECTORS));
    feed(&mut dev, &config);
    for s in &samples {
        feed(&mut dev, &frame(&Message::Sample(*s)));
        while dev.idle() != Idle::Nothing {}
    }
    assert!(dev.stats().checkpoints >= 2);
    let flash = dev.release().unwrap();

    // As it is: resumed, the records after the last checkpoint replayed.
    let (mut dev, resume) = boot(flash.clone());
    assert_eq!(
        resume.config,
        Some((ConfigId::M2Ps, rollcal::models::ErrorModel::Installation))
    );
    assert_eq!(resume.refused, None);
    assert_eq!(resume.last_seq, Some(samples[59].seq));
    assert_eq!(resume.checkpoint.unwrap() + resume.replayed, 60);
    assert!(finish(&mut dev).is_some());

    // Both banks' headers of another format version.
    let mut other = flash.clone();
    for bank in [0usize, 16384] {
        let h = &mut other.mem[bank..bank + 32];
        if h[..3] == *b"RCL" {
            h[3] += 1;
            let crc = rollcal::wire::crc32(&h[..28]);
            h[28..].copy_from_slice(&crc.to_le_bytes());
        }
    }
    let (mut dev, resume) = boot(other);
    assert_eq!(resume.config, None);
    assert_eq!(resume.refused, Some(ResumeRefusal::Format(2)));
    assert!(dev.session().calibrator().is_none());
    assert!(
        finish(&mut dev).is_none(),
        "a Finish is refused: not configured"
    );

    // The newest record's Configure damaged (one byte of its frame).
    let mut damaged = flash.clone();
    let newest = [0usize, 16384]
        .into_iter()
        .filter(|b| damaged.mem[*b..*b + 3] == *b"RCL")
        .max_by_key(|b| u32::from_le_bytes(damaged.mem[b + 4..b + 8].try_into().unwrap()))
        .unwrap();
    damaged.mem[newest + 32 + 40] ^= 0x10;
    let (_, resume) = boot(damaged);
    assert_eq!(resume.config, None);
    assert!(
        matches!(resume.refused, Some(ResumeRefusal::Frame(_))),
        "{resume:?}"
    );

    // A header rewritten with its CRC: `f` on its eight words.
    let rewrite = |flash: &mut Dev, f: &dyn Fn(&mut [u32; 8])| {
        let h = &mut flash.mem[newest..newest + 32];
        let mut w = [0u32; 8];
        for (w, c) in w.iter_mut().zip(h.chunks_exact(4)) {
            *w = u32::from_le_bytes(c.try_into().unwrap());
        }
        f(&mut w);
        for (c, w) in h.chunks_exact_mut(4).zip(w) {
            c.copy_from_slice(&w.to_le_bytes());
        }
        let crc = rollcal::wire::crc32(&h[..28]);
        h[28..].copy_from_slice(&crc.to_le_bytes());
    };

    // The newest checkpoint names another run's log (the log's epoch is
    // not its): the checkpoint is restored, the log's records are not
    // replayed but emptied, and `Finish` answers single-pass.
    let mut another = flash.clone();
    rewrite(&mut another, &|w| w[4] += 1);
    let (mut dev, resume) = boot(another);
    assert_eq!(resume.refused, Some(ResumeRefusal::LogOfAnotherRun));
    assert!(resume.checkpoint.is_some());
    let kept = rollcal::estimator::SampleLog::<f64>::len(dev.log().unwrap());
    assert_eq!((resume.replayed, kept), (0, 0));
    assert!(dev.session().calibrator().is_some());
    assert!(finish(&mut dev).is_none(), "no answer of record");

    // A stored `Configure` the session refuses (here a negative noise;
    // a model this build does not hold takes the same path): not resumed.
    let (config_msg, _) = paper_stream();
    let refused = frame(&Message::Configure(rollcal::wire::CalibratorConfig {
        sigma_accel_g: -1.0,
        ..config_msg
    }));
    let mut bad = flash.clone();
    let padded = refused.len().div_ceil(4) * 4;
    bad.mem[newest + 32..newest + 32 + padded].fill(0xFF);
    bad.mem[newest + 32..newest + 32 + refused.len()].copy_from_slice(&refused);
    rewrite(&mut bad, &|w| w[2] = refused.len() as u32);
    let (dev, resume) = boot(bad);
    assert_eq!(resume.config, None);
    assert!(
        matches!(
            resume.refused,
            Some(ResumeRefusal::Session(
                rollcal::session::SessionError::Calibrator(
                    rollcal::calibrator::Error::InvalidField(_)
                )
            ))
        ),
        "{resume:?}"
    );
    assert!(dev.session().calibrator().is_none());
}

#[test]
fn a_region_that_does_not_fit_gives_the_device_back() {
    let mut dev = Box::new(Device::<Dev, f64>::new());
    // Not whole sectors.
    let Err((flash, e)) = dev.start(Dev::new(SECTORS), 100..4096 * 16) else {
        panic!("accepted a region that does not start on a sector")
    };
    assert_eq!(e, DeviceError::Region);
    // The control banks alone (8 sectors): no room for the log.
    let Err((flash, e)) = dev.start(flash, 0..8 * 4096) else {
        panic!("accepted a region without room for the log")
    };
    assert_eq!(e, DeviceError::Region);
    assert!(dev.start(flash, REGION).is_ok());
}

/// `examples/device.rs` is a whole firmware integration; what it writes
/// beyond the HAL's UART and flash drivers (between its `glue` marks,
/// blank and comment lines aside) is at most 60 lines, and its docs say
/// how many.
#[test]
fn the_example_glue_is_at_most_60_lines() {
    let text = include_str!("../../examples/device.rs");
    let glue = text
        .split("// glue: begin")
        .nth(1)
        .and_then(|rest| rest.split("// glue: end").next())
        .expect("the example marks its glue");
    let lines = glue
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with("//"))
        .count();
    assert!(lines <= 60, "{lines} lines of glue");
    assert!(
        text.contains(&format!("between the `glue` marks: {lines} lines")),
        "the example's docs give its glue as {lines} lines"
    );
}
