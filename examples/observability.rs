//! The observability of a configuration along a path: for M2-ps and M1-pa,
//! two paths generated with the crate's own kinematics
//! ([`CommandFrame`]): a roll about the platform's z axis (the inner
//! gimbal's), and that roll followed by one about its x axis (the outer
//! gimbal's; a roll about y would reach the gimbal lock at 90°), one hour
//! each at 1 °/s, periods of 1 s, the paper's site and noise levels. [`Observability`] accumulates the
//! information matrix and the Cramér–Rao bound; it prints the rank of
//! the information matrix (how many of the states the path observes) and
//! `σ_CRLB` of a few installation errors.
//!
//! `cargo run --release --example observability`

use std::process::ExitCode;

use nalgebra::{SVector, Vector3};
use rollcal::command::CommandFrame;
use rollcal::ekf::{FilterConfig, Options};
use rollcal::geometry::{earth_rate_n, gravity_n, EARTH_RATE};
use rollcal::models::{ConfigId, Environment, M1Pa, M2Ps, Model};
use rollcal::observability::{Observability, RANK_TOLERANCE};

const DEG: f64 = std::f64::consts::PI / 180.0;
const ARCSEC: f64 = DEG / 3600.0;

/// The paper's site (34.25° N) and noise levels.
fn config() -> FilterConfig<f64> {
    let w_ie = earth_rate_n(EARTH_RATE, 34.25 * DEG);
    FilterConfig {
        env: Environment {
            earth_rate_n: w_ie,
            gravity_n: gravity_n(),
        },
        sigma_accel: 1e-6,
        sigma_gyro: 0.1 * ARCSEC,
        sigma_gimbal: 10.0 * ARCSEC,
        options: Options::plain(),
        wander: rollcal::models::Wander::none(),
    }
}

/// The commanded increments (rad, c frame) of 1-s periods rolling at
/// 1 °/s for `seconds` about each platform axis of `axes` in turn.
fn path(axes: &[Vector3<f64>], seconds: u32) -> Vec<Vector3<f64>> {
    let mut frame = CommandFrame::aligned(config().env.earth_rate_n);
    let mut increments = Vec::new();
    for axis in axes {
        let u = axis * DEG;
        for _ in 0..seconds {
            increments.push(frame.increment(&u, 1.0));
            frame.advance(&frame.period_at_rate(&u, 1.0));
        }
    }
    increments
}

/// Rank of the information matrix and σ_CRLB of configuration `M` along
/// `increments`, from a prior σ of 1° on every state.
fn study<M: Model<N, Z>, const N: usize, const Z: usize>(
    id: ConfigId,
    name: &str,
    increments: &[Vector3<f64>],
) -> Result<(), String> {
    let prior = SVector::<f64, N>::repeat(DEG);
    let mut obs = Observability::<f64, M, N, Z>::new(config(), SVector::zeros(), prior)
        .map_err(|e| format!("{id}: {e}"))?;
    for d in increments {
        obs.step(d, 1.0).map_err(|e| format!("{id}: {e}"))?;
    }
    let spectrum = obs
        .analyse(RANK_TOLERANCE)
        .map_err(|e| format!("{id}: {e}"))?;
    let sigma = obs.crlb_sigma();
    let shown: Vec<String> = id
        .states()
        .iter()
        .zip(sigma.iter())
        .skip(3)
        .step_by(3)
        .map(|(info, s)| format!("{} {:.2}\"", info.name, s / ARCSEC))
        .collect();
    println!(
        "{id} {name}: rank {}/{N}, σ_CRLB {}",
        spectrum.rank,
        shown.join(", ")
    );
    Ok(())
}

fn run() -> Result<(), String> {
    let one_axis = path(&[Vector3::z()], 3600);
    let two_axes = path(&[Vector3::z(), Vector3::x()], 3600);
    for (name, increments) in [("about z", &one_axis), ("about z, then x", &two_axes)] {
        study::<M2Ps, 18, 6>(ConfigId::M2Ps, name, increments)?;
        study::<M1Pa, 12, 3>(ConfigId::M1Pa, name, increments)?;
    }
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("observability: {e}");
            ExitCode::FAILURE
        }
    }
}
