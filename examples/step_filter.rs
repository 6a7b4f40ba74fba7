//! Steps the M2-ps and M1-pa filters period by period over a recorded
//! stream: the paper's scenario as a platform sends it (5400 periods of
//! 1 s, noise seed 1, `tests/data/paper_seed1.bin`), decoded with the
//! library's own [`FrameDecoder`], and prints the end-of-run estimate of a
//! few states with their σ.
//!
//! `cargo run --release --example step_filter`

use std::process::ExitCode;

use nalgebra::{SVector, Vector3};
use rollcal::ekf::{FilterConfig, M1PaFilter, M2PsFilter, Observation, Options};
use rollcal::models::{ConfigId, Environment};
use rollcal::wire::{CalibratorConfig, FrameDecoder, Message, Sample};

/// The recorded stream: one `Configure`, then one `Sample` per period.
const STREAM: &[u8] = include_bytes!("../tests/data/paper_seed1.bin");

const ARCSEC: f64 = std::f64::consts::PI / 180.0 / 3600.0;

/// The stream's settings and samples.
fn decode(bytes: &[u8]) -> Result<(CalibratorConfig, Vec<Sample>), String> {
    let (mut settings, mut samples) = (None, Vec::new());
    let mut decoder = FrameDecoder::new();
    decoder.feed(bytes, |m| match m {
        Message::Configure(c) => settings = Some(c),
        Message::Sample(s) => samples.push(s),
        _ => {}
    });
    Ok((settings.ok_or("no Configure in the stream")?, samples))
}

/// The filter's settings from the stream's: environment and noise.
fn filter_config(c: &CalibratorConfig) -> FilterConfig<f64> {
    FilterConfig {
        env: Environment {
            earth_rate_n: c.earth_rate_n.into(),
            gravity_n: c.gravity_n.into(),
        },
        sigma_accel: c.sigma_accel_g,
        sigma_gyro: c.sigma_gyro_rad_s,
        sigma_gimbal: c.sigma_gimbal_rad,
        options: Options::default(),
        wander: rollcal::models::Wander::none(),
    }
}

/// A sample's period (s), commanded increment (rad) and measurement.
fn period(s: &Sample) -> (f64, Vector3<f64>, Observation<f64>) {
    let obs = Observation {
        accel_mean: Vector3::from(s.accel_mean).cast(),
        gimbal: s.gimbal.map(|g| Vector3::from(g).cast()),
    };
    (f64::from(s.dt), Vector3::from(s.dtheta_cmd).cast(), obs)
}

/// Prints the first `rows` states of `id` (the installation errors after
/// the attitude) in arcseconds.
fn print_states(id: ConfigId, x: &[f64], sigma: &[f64], rows: std::ops::Range<usize>) {
    for i in rows {
        if let (Some(info), Some(x), Some(s)) = (id.states().get(i), x.get(i), sigma.get(i)) {
            println!(
                "  {:8} {:+9.2} ± {:6.2} arcsec",
                info.name,
                x / ARCSEC,
                s / ARCSEC
            );
        }
    }
}

fn run() -> Result<(), String> {
    let (settings, samples) = decode(STREAM)?;
    let config = filter_config(&settings);
    println!(
        "{} periods of {} s from tests/data/paper_seed1.bin",
        samples.len(),
        samples.first().map_or(0.0, |s| s.dt)
    );

    // M2-ps: gimbal angles measured too (18 states: θA, θgC, θgT, θaC, θaT, λ).
    let prior = SVector::repeat(settings.prior_sigma_rad);
    let mut m2 = M2PsFilter::<f64>::new(config, SVector::zeros(), prior)
        .map_err(|e| format!("M2-ps: {e}"))?;
    // M1-pa: accelerometers only (12 states).
    let prior = SVector::repeat(settings.prior_sigma_rad);
    let mut m1 = M1PaFilter::<f64>::new(config, SVector::zeros(), prior)
        .map_err(|e| format!("M1-pa: {e}"))?;
    let (mut gated2, mut gated1) = (0, 0);
    for s in &samples {
        let (dt, dtheta_c, obs) = period(s);
        // A step that fails (e.g. the NIS gate) leaves the filter as it was.
        gated2 += u32::from(m2.step(&dtheta_c, dt, &obs).is_err());
        gated1 += u32::from(m1.step(&dtheta_c, dt, &obs).is_err());
    }

    println!("M2-ps after {} updates ({gated2} refused):", m2.updates());
    print_states(
        ConfigId::M2Ps,
        m2.state().as_slice(),
        m2.sigma().as_slice(),
        3..9,
    );
    println!("M1-pa after {} updates ({gated1} refused):", m1.updates());
    print_states(
        ConfigId::M1Pa,
        m1.state().as_slice(),
        m1.sigma().as_slice(),
        3..9,
    );
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("step_filter: {e}");
            ExitCode::FAILURE
        }
    }
}
