//! Test and bench data from the library's own API: the recorded paper
//! stream `tests/data/paper_seed1.bin` (see `tests/data/GOLDEN-README.md`)
//! decoded with [`rollcal::wire::FrameDecoder`].
//!
//! The stream was written by the truth simulator,
//! `cargo run --release -p host-sim -- record --config M2-ps --seed 1 --out tests/data/paper_seed1.bin`:
//! the paper's scenario (5400 periods of 1 s, Earth rate on, noise seed 1),
//! a `Configure` message with the scenario's settings and then one `Sample`
//! per period with f32 fields, as a platform sends them (gimbal angles
//! included, so the samples serve every configuration).

#![allow(dead_code)]

use nalgebra::Vector3;
use rollcal::ekf::{FilterConfig, Observation, Options};
use rollcal::estimator::LogRecord;
use rollcal::models::{ConfigId, Environment};
use rollcal::wire::{CalibratorConfig, FrameDecoder, Message, Sample};

/// The recorded stream's frames.
pub const PAPER_STREAM: &[u8] = include_bytes!("../../data/paper_seed1.bin");

/// The stream's `Configure` settings and its samples, in order.
pub fn paper_stream() -> (CalibratorConfig, Vec<Sample>) {
    let mut config = None;
    let mut samples = Vec::with_capacity(5400);
    let mut dec = FrameDecoder::new();
    dec.feed(PAPER_STREAM, |m| match m {
        Message::Configure(c) => config = Some(c),
        Message::Sample(s) => samples.push(s),
        other => panic!("unexpected message in the recorded stream: {other:?}"),
    });
    assert_eq!(
        dec.stats().errors(),
        0,
        "the recorded stream decodes cleanly"
    );
    assert_eq!(samples.len(), 5400);
    (config.expect("the stream starts with Configure"), samples)
}

/// The stream's settings for configuration `id`, with estimates every
/// `every` samples (0: none).
pub fn settings(id: ConfigId, every: u32) -> CalibratorConfig {
    CalibratorConfig {
        config: id,
        estimate_every: every,
        ..paper_stream().0
    }
}

/// The realistic scenario's errors that wander (docs/model.md §The
/// realistic scenario), in internal units (rad/s, s, g).
pub fn realistic_wander() -> rollcal::models::Wander<f64> {
    let deg_h = 1f64.to_radians() / 3600.0;
    rollcal::models::Wander {
        gyro_markov_sigma: 0.003 * deg_h,
        gyro_markov_tau_s: 600.0,
        gyro_random_walk: 0.002 * deg_h / 60.0,
        accel_markov_sigma: 2e-6,
        accel_markov_tau_s: 900.0,
        accel_random_walk: 1e-6 / 60.0,
        gyro_warmup_sigma: 0.005 * deg_h,
        accel_warmup_sigma: 3e-6,
        warmup_tau_s: 1200.0,
    }
}

/// The filter settings of `c` (f64) with filter options `options`.
pub fn filter_config(c: &CalibratorConfig, options: Options) -> FilterConfig<f64> {
    FilterConfig {
        env: Environment {
            earth_rate_n: c.earth_rate_n.into(),
            gravity_n: c.gravity_n.into(),
        },
        sigma_accel: c.sigma_accel_g,
        sigma_gyro: c.sigma_gyro_rad_s,
        sigma_gimbal: c.sigma_gimbal_rad,
        options,
        wander: rollcal::models::Wander::none(),
    }
}

/// A sample's period length (s) and commanded increment (rad, c frame) in f64.
pub fn period(s: &Sample) -> (f64, Vector3<f64>) {
    (f64::from(s.dt), Vector3::from(s.dtheta_cmd).cast())
}

/// A sample's measurement in f64.
pub fn observation(s: &Sample) -> Observation<f64> {
    Observation {
        accel_mean: Vector3::from(s.accel_mean).cast(),
        gimbal: s.gimbal.map(|g| Vector3::from(g).cast()),
    }
}

/// A sample as a log record (f64).
pub fn log_record(s: &Sample) -> LogRecord<f64> {
    let (dt, d) = period(s);
    LogRecord::measured(dt, d, observation(s))
}

/// Reference COBS encoder, written from the textbook definition (not the
/// crate's streaming one): blocks of ≤ 254 non-zero bytes, each prefixed by
/// its length + 1.
pub fn cobs_reference(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8];
    let mut code_idx = 0;
    let mut code = 1u8;
    for &b in data {
        if b == 0 {
            out[code_idx] = code;
            code_idx = out.len();
            out.push(0);
            code = 1;
        } else {
            out.push(b);
            code += 1;
            if code == 0xFF {
                out[code_idx] = code;
                code_idx = out.len();
                out.push(0);
                code = 1;
            }
        }
    }
    out[code_idx] = code;
    out
}
