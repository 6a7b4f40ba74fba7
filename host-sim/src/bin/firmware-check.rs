//! Helper of the firmware's QEMU script (`firmware/run-qemu.sh`).
//!
//! - `firmware-check end-frame`: writes one `EstimateRequest` frame to
//!   stdout. Appended to a recorded stream it marks the end of the input for
//!   firmware started with `exit=request` (a UART has no end of file).
//! - `firmware-check compare --firmware OUT --host JSON [--tol RAD]`: decodes
//!   the `Estimate` frames the firmware wrote to its UART, takes the last one
//!   and compares it state by state with `host-sim calibrate --json`'s final
//!   estimates. Prints max |Δ| (rad, arcsec, and in units of the host's σ);
//!   with `--tol`, exits non-zero when a state differs by more than `tol`
//!   rad (or when no estimate was found).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use rollcal::wire::{encode, Estimate, FrameDecoder, Message, MAX_FRAME_LEN};

const ARCSEC: f64 = std::f64::consts::PI / 180.0 / 3600.0;

#[derive(Parser)]
#[command(about = "Helpers of firmware/run-qemu.sh: end-of-stream frame, estimate comparison")]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Write one EstimateRequest frame to stdout.
    EndFrame,
    /// Compare the firmware's last Estimate with host-sim calibrate's JSON.
    Compare {
        /// The firmware's UART output (wire frames).
        #[arg(long)]
        firmware: PathBuf,
        /// `host-sim calibrate --json` output on the same stream.
        #[arg(long)]
        host: PathBuf,
        /// Fail when any state differs by more than this (rad).
        #[arg(long)]
        tol: Option<f64>,
        /// Name printed with the result.
        #[arg(long, default_value = "firmware")]
        label: String,
    },
}

fn end_frame() -> Result<(), String> {
    use std::io::Write;
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = encode(&Message::EstimateRequest, &mut buf).map_err(|e| e.to_string())?;
    std::io::stdout()
        .write_all(buf.get(..n).ok_or("encoder overran its buffer")?)
        .map_err(|e| e.to_string())
}

fn last_estimate(path: &PathBuf) -> Result<(Estimate, usize), String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let mut decoder = FrameDecoder::new();
    let mut last = None;
    let mut count = 0;
    decoder.feed(&bytes, |m| {
        if let Message::Estimate(e) = m {
            count += 1;
            last = Some(e);
        }
    });
    if decoder.stats().errors() > 0 {
        return Err(format!(
            "{}: {} corrupt frames in the firmware's output: {:?}",
            path.display(),
            decoder.stats().errors(),
            decoder.stats()
        ));
    }
    last.map(|e| (e, count))
        .ok_or_else(|| format!("{}: no Estimate frame", path.display()))
}

fn compare(
    firmware: &PathBuf,
    host: &PathBuf,
    tol: Option<f64>,
    label: &str,
) -> Result<bool, String> {
    let (est, count) = last_estimate(firmware)?;
    let text = std::fs::read_to_string(host)
        .map_err(|e| format!("cannot read {}: {e}", host.display()))?;
    let json: serde_json::Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    let config = json["config"].as_str().unwrap_or("?");
    if config != est.config.as_str() {
        return Err(format!(
            "configuration differs: firmware {}, host {config}",
            est.config.as_str()
        ));
    }
    let states = json["states"].as_array().ok_or("host JSON has no states")?;
    if states.len() != est.state.len() {
        return Err(format!(
            "{} states from the firmware, {} from the host",
            est.state.len(),
            states.len()
        ));
    }
    let (mut max_rad, mut max_sigma, mut worst) = (0.0f64, 0.0f64, "");
    for (s, x) in states.iter().zip(est.state.iter()) {
        let name = s["name"].as_str().unwrap_or("?");
        let host_x = s["estimate_rad"]
            .as_f64()
            .ok_or("state without estimate_rad")?;
        let host_sig = s["sigma_rad"].as_f64().ok_or("state without sigma_rad")?;
        // A NaN on either side counts as an infinite difference.
        let d = (x - host_x).abs();
        let d = if d.is_nan() { f64::INFINITY } else { d };
        if d > max_rad || worst.is_empty() {
            max_rad = d;
            worst = name;
        }
        max_sigma = max_sigma.max(d / host_sig);
    }
    let within = tol.map(|t| max_rad <= t);
    println!(
        "{label}: {count} Estimate frames, final seq {} after {} updates; max |Δ| vs host = {max_rad:.3e} rad = {:.3e}″ = {max_sigma:.2e}σ (worst {worst}){}",
        est.seq,
        est.updates,
        max_rad / ARCSEC,
        match (tol, within) {
            (Some(t), Some(true)) => format!(" — PASS (≤ {t:e} rad)"),
            (Some(t), _) => format!(" — FAIL (> {t:e} rad)"),
            _ => String::new(),
        }
    );
    Ok(within.unwrap_or(true))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let r = match cli.command {
        Cmd::EndFrame => end_frame().map(|()| true),
        Cmd::Compare {
            firmware,
            host,
            tol,
            label,
        } => compare(&firmware, &host, tol, &label),
    };
    match r {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("firmware-check: error: {e}");
            ExitCode::FAILURE
        }
    }
}
