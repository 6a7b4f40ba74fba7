//! The estimator of record over a whole logged run: the recorded paper
//! stream (`tests/data/paper_seed1.bin`, 5400 periods of 1 s) logged as
//! [`LogRecord`]s in a [`SliceLog`] over a caller's buffer, then
//! [`estimator::estimate`] runs its passes (forward, back-propagated
//! start, forward again until the estimate moves by less than 0.1 σ) for
//! M2-ps and prints how it went and the installation errors it found.
//!
//! `cargo run --release --example estimate_log`

use std::process::ExitCode;

use nalgebra::{SVector, Vector3};
use rollcal::ekf::{FilterConfig, Observation, Options};
use rollcal::estimator::{self, EstimatorOptions, LogRecord, SampleLog, SliceLog};
use rollcal::models::{ConfigId, Environment, Group, M2Ps};
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

/// A sample as a log record: period (s), commanded increment (rad) and
/// the measurement.
fn record(s: &Sample) -> LogRecord<f64> {
    let observation = Observation {
        accel_mean: Vector3::from(s.accel_mean).cast(),
        gimbal: s.gimbal.map(|g| Vector3::from(g).cast()),
    };
    LogRecord::measured(
        f64::from(s.dt),
        Vector3::from(s.dtheta_cmd).cast(),
        observation,
    )
}

fn run() -> Result<(), String> {
    let (settings, samples) = decode(STREAM)?;
    let config = FilterConfig {
        env: Environment {
            earth_rate_n: settings.earth_rate_n.into(),
            gravity_n: settings.gravity_n.into(),
        },
        sigma_accel: settings.sigma_accel_g,
        sigma_gyro: settings.sigma_gyro_rad_s,
        sigma_gimbal: settings.sigma_gimbal_rad,
        options: Options::default(),
        wander: rollcal::models::Wander::none(),
    };

    // The log: a buffer the caller owns (a firmware's static array), filled
    // as the samples arrive.
    let mut buffer = vec![LogRecord::predicted(1.0, Vector3::zeros()); samples.len()];
    let mut log = SliceLog::new(&mut buffer);
    for s in &samples {
        log.append(&record(s)).map_err(|e| format!("log: {e:?}"))?;
    }
    println!("logged {} periods", log.len());

    let x0 = SVector::<f64, 18>::zeros();
    let sigma0 = SVector::<f64, 18>::repeat(settings.prior_sigma_rad);
    let passes = EstimatorOptions::default();
    // The observer sees every step of every pass: the mean NIS per pass.
    let mut nis = vec![(0.0, 0u32)];
    let outcome = estimator::estimate::<f64, M2Ps, 18, 6, _, _>(
        &config,
        &x0,
        &sigma0,
        &mut log,
        &passes,
        |event| {
            let pass = usize::from(event.pass);
            if nis.len() <= pass {
                nis.resize(pass + 1, (0.0, 0));
            }
            if let (Ok(Some(innovation)), Some(sum)) = (&event.result, nis.get_mut(pass)) {
                *sum = (sum.0 + innovation.nis, sum.1 + 1);
            }
        },
    )
    .map_err(|e| format!("estimate: {e:?}"))?;

    let report = outcome.report;
    println!(
        "{} passes, converged: {}, {} failed steps in the last pass",
        report.passes, report.converged, report.failures
    );
    for (pass, (sum, n)) in nis.iter().enumerate().skip(1) {
        let mean = sum / f64::from((*n).max(1));
        println!("  pass {pass}: mean NIS {mean:.2} over {n} updates (6 measurements each)");
    }
    let (x, sigma) = (outcome.filter.state(), outcome.filter.sigma());
    println!("installation errors of M2-ps (arcsec):");
    for (i, info) in ConfigId::M2Ps.states().iter().enumerate() {
        if info.group == Group::Attitude {
            continue;
        }
        if let (Some(x), Some(s)) = (x.get(i), sigma.get(i)) {
            println!("  {:8} {:+9.2} ± {:6.2}", info.name, x / ARCSEC, s / ARCSEC);
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("estimate_log: {e}");
            ExitCode::FAILURE
        }
    }
}
