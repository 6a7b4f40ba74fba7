//! `host-sim record`: a simulated scenario written as a stream of wire
//! frames (docs/wire.md) or a CSV log (docs/csv.md), impaired as asked,
//! with its truth sidecar.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;

use rollcal::models::ConfigId;
use rollcal::wire::{Message, Sample};

use super::args::{load_scenario, parse_config};
use super::Error;
use crate::analysis::calibration::calibrator_config;
use crate::io::csvlog;
use crate::io::sidecar::truth_json;
use crate::io::stream::{push_frame, refuse_terminal, to_sample, Format};
use crate::output::report::write_json;
use crate::sim::impair::{Applied, Impairments};
use crate::sim::truth::{check_gimbal_lock, simulate, SimOptions};

/// Arguments of `host-sim record`.
#[derive(clap::Args, Clone, Debug)]
pub struct RecordArgs {
    /// Configuration named in the stream's `Configure` message (and of the
    /// truth sidecar): M1-pa, M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps.
    #[arg(long, value_parser = parse_config)]
    pub config: ConfigId,
    /// Scenario file (TOML); default: the paper's scenario.
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// RNG seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Switch the Earth rate off.
    #[arg(long)]
    pub no_earth_rate: bool,
    /// Output file, or `-` for stdout.
    #[arg(long, value_name = "FILE|-", default_value = "-")]
    pub out: String,
    /// Also write the truth (final true states, Cramér–Rao σ) as JSON to PATH.
    #[arg(long, value_name = "PATH")]
    pub truth: Option<PathBuf>,
    /// With --truth: also every state at the end of every period (the
    /// history of the errors that wander), `history_rad` and
    /// `instrument_history` in the sidecar.
    #[arg(long, requires = "truth")]
    pub truth_history: bool,
    /// Estimate cadence written into the `Configure` message (samples;
    /// default 60). Frames only: a CSV log has no `Configure`.
    #[arg(long)]
    pub estimate_every: Option<u32>,
    /// The error model the stream's `Configure` asks the calibrator for
    /// (`installation`, the default, or `full`; `calibrate --errors`
    /// overrides it). Frames only: a CSV log has no `Configure` (its error
    /// model is the platform file's `errors` or `calibrate --errors`).
    #[arg(long, value_parser = super::args::parse_errors)]
    pub errors: Option<rollcal::models::ErrorModel>,
    /// Impairments of the link and the platform (lost frames, clock steps,
    /// bit flips, outliers), applied after the simulation.
    #[command(flatten)]
    pub impair: Impairments,
    /// Output format: wire frames (docs/wire.md), or a CSV log
    /// (docs/csv.md; no `Configure`: calibrate it with --platform).
    #[arg(long, value_enum, default_value_t = Format::Frames)]
    pub format: Format,
}

/// `host-sim record`.
pub fn command(args: &RecordArgs) -> Result<(), Error> {
    let csv = args.format == Format::Csv;
    if csv && args.impair.bit_flips > 0.0 {
        return Err("--bit-flips impairs the frame bytes: not with --format csv".into());
    }
    // What only the frames' Configure carries: refused, not ignored.
    if let (true, Some(e)) = (csv, args.errors) {
        return Err(format!(
            "--errors {}: a CSV log has no Configure to carry it (give errors = \"{}\" in the platform file, or calibrate --errors {}): not with --format csv",
            e.as_str(),
            e.as_str(),
            e.as_str()
        )
        .into());
    }
    if csv && args.estimate_every.is_some() {
        return Err(
            "--estimate-every: a CSV log has no Configure to carry it: not with --format csv"
                .into(),
        );
    }
    if !csv {
        refuse_terminal(&args.out, std::io::stdout().is_terminal())?;
    }
    // `--accel-bias-ug` adds to the scenario's accelerometer bias: the truth
    // simulator applies it, and the sidecar records the sum.
    let sc = args
        .impair
        .accel
        .biased(&load_scenario(args.scenario.as_deref())?);
    // The scenario's `ba` plus `--accel-bias-ug` within the model's limits.
    sc.instruments
        .validate()
        .map_err(|e| format!("with --accel-bias-ug: {}", e.0))?;
    let earth_rate = !args.no_earth_rate && sc.site.earth_rate;
    eprintln!(
        "recording '{}' ({} periods, seed {}) for {}…",
        sc.name,
        sc.periods(),
        args.seed,
        args.config
    );
    let sim = simulate(
        &sc,
        SimOptions {
            seed: args.seed,
            noise: true,
            earth_rate,
        },
    );
    check_gimbal_lock(args.config, &sim)?;
    let mut settings = calibrator_config(
        &sc,
        args.config,
        args.errors.unwrap_or_default(),
        earth_rate,
    );
    settings.estimate_every = args.estimate_every.unwrap_or(60);
    let mut samples: Vec<Sample> = sim.samples.iter().map(to_sample).collect();
    let mut applied = Applied::default();
    let imp = &args.impair;
    imp.apply_to_samples(
        &mut samples,
        settings.sigma_accel_g,
        args.seed,
        &mut applied,
    );
    let mut bytes = Vec::with_capacity(samples.len() * 80);
    if csv {
        bytes = csvlog::write(&samples).into_bytes();
    } else {
        push_frame(&mut bytes, &Message::Configure(settings))?;
        for s in &samples {
            push_frame(&mut bytes, &Message::Sample(*s))?;
        }
        imp.apply_to_bytes(&mut bytes, args.seed, &mut applied);
    }
    if imp.any() {
        eprintln!(
            "impaired: {} sample frames dropped, {} outliers, {} timestamps shifted, {} bits flipped",
            applied.dropped, applied.outliers, applied.shifted, applied.bit_flips
        );
    }
    if args.out == "-" {
        let mut out = std::io::stdout().lock();
        out.write_all(&bytes)
            .and_then(|()| out.flush())
            .map_err(|e| format!("cannot write to stdout: {e}"))?;
    } else {
        std::fs::write(&args.out, &bytes).map_err(|e| format!("cannot write {}: {e}", args.out))?;
    }
    if csv {
        eprintln!("{} lines, {} bytes", samples.len() + 1, bytes.len());
    } else {
        eprintln!("{} frames, {} bytes", samples.len() + 1, bytes.len());
    }
    if let Some(path) = &args.truth {
        let json = truth_json(
            args.config,
            &sc,
            &sim,
            args.seed,
            earth_rate,
            args.truth_history,
        )?;
        write_json(path, &json)?;
    }
    Ok(())
}
