//! The calibrator front end: rejects bad samples by reason without touching
//! the filter, takes the start of a log from its first sample wherever on
//! the path it starts, bridges gaps along the commanded motion or
//! re-acquires the attitude, emits estimates at its cadence, and continues
//! bit-identically from a checkpoint taken at any sample. One module per
//! subject; the recorded paper stream's helpers here.

mod bad_input;
mod checkpoint;
mod finish;
mod gaps;
mod session;
mod start;
mod validation;

use crate::support;

use nalgebra::RealField;
use rollcal::calibrator::{Calibrator, M1PaCalibrator, M2PsCalibrator, RejectReason};
use rollcal::ekf::{M1PaFilter, M2PsFilter, Observation, Options};
use rollcal::models::{ConfigId, Model};
use rollcal::wire::{
    encode, CalibratorConfig, Checkpoint, FrameDecoder, Message, Sample, MAX_FRAME_LEN,
};
use support::filter_config;

/// The first `periods` samples of the recorded paper stream (f32 samples,
/// noise seed 1, `tests/it/support`) and its settings.
fn samples(periods: usize) -> (CalibratorConfig, Vec<Sample>) {
    let (sc, mut data) = support::paper_stream();
    data.truncate(periods);
    (sc, data)
}

/// The stream's settings for `id` with an estimate every `every` samples.
fn settings(sc: &CalibratorConfig, id: ConfigId, every: u32) -> CalibratorConfig {
    CalibratorConfig {
        config: id,
        estimate_every: every,
        ..*sc
    }
}

fn bytes(m: &Message) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let n = encode(m, &mut buf).unwrap();
    buf.truncate(n);
    buf
}

/// Through the wire and back, as a device restoring after a reset would.
fn over_the_wire(cp: Checkpoint) -> Checkpoint {
    let mut got = None;
    FrameDecoder::new().feed(&bytes(&Message::Checkpoint(cp)), |m| got = Some(m));
    match got {
        Some(Message::Checkpoint(c)) => c,
        other => panic!("{other:?}"),
    }
}

/// Runs all samples, restarting from a checkpoint (through the wire) at
/// every index in `cuts`; returns the final checkpoint frame, every estimate
/// frame emitted and every push outcome (the f32 filter refuses some
/// early periods; its rejects must repeat exactly too).
type Outcome = (Vec<u8>, Vec<Vec<u8>>, Vec<Result<(), RejectReason>>);

fn run<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>(
    cfg: CalibratorConfig,
    data: &[Sample],
    cuts: &[usize],
) -> Outcome {
    let mut cal = Calibrator::<T, M, N, Z>::new(cfg).unwrap();
    let mut estimates = Vec::new();
    let mut outcomes = Vec::new();
    for (i, s) in data.iter().enumerate() {
        if cuts.contains(&i) {
            let cp = over_the_wire(cal.checkpoint());
            cal = Calibrator::restore(cfg, &cp).unwrap();
        }
        match cal.push(s) {
            Ok(Some(e)) => {
                estimates.push(bytes(&Message::Estimate(e)));
                outcomes.push(Ok(()));
            }
            Ok(None) => outcomes.push(Ok(())),
            Err(r) => outcomes.push(Err(r)),
        }
    }
    (
        bytes(&Message::Checkpoint(cal.checkpoint())),
        estimates,
        outcomes,
    )
}
