//! Drives a [`Session`] from frame bytes, as a firmware does with its
//! UART: the recorded paper stream (`tests/data/paper_seed1.bin`: a
//! `Configure` frame for M2-ps, then 5400 `Sample` frames) followed by a
//! `Finish` frame this example encodes with [`wire::encode`], fed in
//! 64-byte chunks to a [`FrameDecoder`]; every decoded message goes to
//! [`Session::handle`], and every reply is encoded back into a frame. It
//! prints the counts and the final `Estimate`.
//!
//! `cargo run --release --example session_bytes`

use std::process::ExitCode;

use nalgebra::Vector3;
use rollcal::estimator::{EstimatorOptions, LogRecord, SliceLog};
use rollcal::models::Group;
use rollcal::session::{Reply, Session};
use rollcal::wire::{self, EstimateKind, FrameDecoder, Message, MAX_FRAME_LEN};

/// The recorded stream: one `Configure`, then one `Sample` per period.
const STREAM: &[u8] = include_bytes!("../tests/data/paper_seed1.bin");

const ARCSEC: f64 = std::f64::consts::PI / 180.0 / 3600.0;

fn run() -> Result<(), String> {
    // The host's side: the recorded frames, then one more, `Finish`.
    let mut bytes = STREAM.to_vec();
    let mut frame = [0u8; MAX_FRAME_LEN];
    let n = wire::encode(&Message::Finish, &mut frame).map_err(|e| format!("encode: {e:?}"))?;
    bytes.extend_from_slice(frame.get(..n).unwrap_or_default());

    // The calibrator's side: a session (any configuration, the default
    // final passes) and a sample log over a buffer it owns.
    let mut session = Session::<f64>::new(None, EstimatorOptions::default());
    let mut buffer = vec![LogRecord::predicted(1.0, Vector3::zeros()); 5400];
    let mut log = SliceLog::new(&mut buffer);
    let mut decoder = FrameDecoder::new();
    let (mut messages, mut sent_bytes) = (0u32, 0usize);
    let mut last = None;
    for chunk in bytes.chunks(64) {
        decoder.feed(chunk, |msg| {
            messages += 1;
            match session.handle(&msg, &mut log) {
                Reply::Send(reply) => {
                    // What would go back over the wire.
                    sent_bytes += wire::encode(&reply, &mut frame).unwrap_or(0);
                    if let Message::Estimate(e) = reply {
                        last = Some(e);
                    }
                }
                Reply::Nothing => {}
                Reply::Rejected(reason) => println!("sample rejected: {reason:?}"),
                Reply::Error(e) => println!("message refused: {e:?}"),
            }
        });
    }
    println!(
        "{} bytes in, {messages} messages decoded, {} frame errors, {sent_bytes} bytes out",
        bytes.len(),
        decoder.stats().errors()
    );

    let estimate = last.ok_or("no Estimate came back")?;
    match estimate.kind {
        EstimateKind::Final { passes, converged } => println!(
            "final estimate of {} after sample {}: {passes} passes, converged: {converged}",
            estimate.config, estimate.seq
        ),
        other => return Err(format!("the last estimate is not the final one: {other:?}")),
    }
    let states = estimate.config.states();
    for ((info, x), s) in states.iter().zip(&estimate.state).zip(&estimate.sigma) {
        if info.group == Group::Attitude {
            continue;
        }
        println!(
            "  {:8} {:+9.2} ± {:6.2} arcsec",
            info.name,
            x / ARCSEC,
            s / ARCSEC
        );
    }
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("session_bytes: {e}");
            ExitCode::FAILURE
        }
    }
}
