//! Helper of the firmware's QEMU script (`firmware/run-qemu.sh`).
//!
//! - `firmware-check end-frame`: writes an `EstimateRequest` frame and a
//!   `Finish` frame to stdout. Appended to a recorded stream they end the
//!   input for firmware started with `exit=request` (a UART has no end of
//!   file): the firmware replies with its running estimate (pass 1), then
//!   runs the estimator of record over its sample log and replies with the
//!   final estimate, and exits.
//! - `firmware-check compare --firmware OUT --host JSON [--tol RAD]`: decodes
//!   the `Estimate` frames the firmware wrote to its UART, takes the last one
//!   and compares it state by state with `host-sim calibrate --json`'s final
//!   estimates. Prints max |Δ| (rad, arcsec, and in units of the host's σ);
//!   with `--tol`, exits non-zero when a state differs by more than `tol`
//!   rad (the installation states; a full model's instrument terms, whose
//!   units are not radians, by more than `--tol-instrument-sigma` of the
//!   host's σ), when the last estimate is not the estimator of record's
//!   (`Final`) or (with `--tol`) ran another number of passes than the
//!   host, when the calibrator rejected samples, when `--rc`
//!   (QEMU's exit status) is not 0, or when no estimate was found. With
//!   `--build`, also prints one `summary build=… config=… passes=…
//!   max_dabs_rad=… max_dsigma=… limit=… ok|FAIL` line.
//! - `firmware-check identical --firmware OUT --reference OUT2`: every
//!   `Estimate` of two firmware runs (the running ones and the final one)
//!   must be the same message, every state and σ bit for bit, and the last
//!   one the estimator of record's (a checkpoint → reset → restore run
//!   against the uninterrupted one). Same `--build`/`--rc` summary line.
//!   With `--final-only-running-sigma S` (a device resumed from its flash
//!   log after a reset): the final estimate's state and σ bit for bit, the
//!   running ones within S of their σ.
//! - `firmware-check garble-first-frame --input IN --out OUT`: copies a
//!   stream with one byte of its first frame changed (a frame the decoder
//!   rejects: a lost `Configure`), and checks that the copy has one frame
//!   error more and no `Configure` message left.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use rollcal::models::Group;
use rollcal::wire::{encode, Estimate, EstimateKind, FrameDecoder, Message, MAX_FRAME_LEN};

const ARCSEC: f64 = std::f64::consts::PI / 180.0 / 3600.0;

#[derive(Parser)]
#[command(
    about = "Helpers of firmware/run-qemu.sh: end-of-stream frames, estimate comparison, a garbled stream"
)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

/// How a run is named in the summary line.
#[derive(clap::Args)]
struct RunInfo {
    /// Build name for the summary line (e.g. M7/f64); no summary without it.
    #[arg(long)]
    build: Option<String>,
    /// Configuration label of the summary line (default: the estimate's).
    #[arg(long)]
    config: Option<String>,
    /// QEMU's exit status of the run: not 0 fails the check.
    #[arg(long)]
    rc: Option<i32>,
    /// Wall time of the QEMU run (s), printed in the summary.
    #[arg(long)]
    seconds: Option<u64>,
    /// Text appended to the summary line.
    #[arg(long)]
    note: Option<String>,
}

#[derive(Subcommand)]
enum Cmd {
    /// Write an EstimateRequest and a Finish frame to stdout.
    EndFrame,
    /// Compare the firmware's last Estimate with host-sim calibrate's JSON.
    Compare {
        /// The firmware's UART output (wire frames).
        #[arg(long)]
        firmware: PathBuf,
        /// `host-sim calibrate --json` output on the same stream.
        #[arg(long)]
        host: PathBuf,
        /// Fail when any state differs by more than this (rad), or when the
        /// answer is not the estimator of record's with the host's passes.
        #[arg(long)]
        tol: Option<f64>,
        /// Fail when any state differs by more than this many of the host's
        /// σ, or when the answer is not the estimator of record's with the
        /// host's passes (the check of an f32 build against the host's f64).
        #[arg(long)]
        tol_sigma: Option<f64>,
        /// With `--tol`: fail when an instrument term of the full model
        /// differs by more than this many of the host's σ.
        #[arg(long, default_value_t = 1e-6)]
        tol_instrument_sigma: f64,
        /// Name printed with the result.
        #[arg(long, default_value = "firmware")]
        label: String,
        #[command(flatten)]
        run: RunInfo,
    },
    /// Check that two firmware runs end with bit-identical estimates.
    Identical {
        /// The firmware's UART output (wire frames).
        #[arg(long)]
        firmware: PathBuf,
        /// The reference run's UART output.
        #[arg(long)]
        reference: PathBuf,
        /// What the reference is, for the summary (e.g. uninterrupted).
        #[arg(long, default_value = "reference")]
        against: String,
        /// Only the final estimate's state and σ bit for bit (and its
        /// passes and counts of samples and records); the running ones
        /// within this many σ (a device resumed from its flash log, whose
        /// running filter replayed the packed records).
        #[arg(long)]
        final_only_running_sigma: Option<f64>,
        #[command(flatten)]
        run: RunInfo,
    },
    /// Copy a stream with its first frame garbled.
    GarbleFirstFrame {
        #[arg(long)]
        input: PathBuf,
        #[arg(long)]
        out: PathBuf,
    },
}

fn end_frame() -> Result<(), String> {
    use std::io::Write;
    let mut out = Vec::new();
    for m in [Message::EstimateRequest, Message::Finish] {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = encode(&m, &mut buf).map_err(|e| e.to_string())?;
        out.extend_from_slice(buf.get(..n).ok_or("encoder overran its buffer")?);
    }
    std::io::stdout().write_all(&out).map_err(|e| e.to_string())
}

/// Every `Estimate` frame of a firmware's output, in order.
fn estimates(path: &Path) -> Result<Vec<Estimate>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let mut decoder = FrameDecoder::new();
    let mut all = Vec::new();
    decoder.feed(&bytes, |m| {
        if let Message::Estimate(e) = m {
            all.push(e);
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
    Ok(all)
}

/// The last `Estimate` of a firmware's output and how many there were.
fn last_estimate(path: &Path) -> Result<(Estimate, usize), String> {
    let mut all = estimates(path)?;
    let count = all.len();
    all.pop()
        .map(|e| (e, count))
        .ok_or_else(|| format!("{}: no Estimate frame", path.display()))
}

fn kind_str(kind: &EstimateKind) -> String {
    match kind {
        EstimateKind::Final { passes, .. } => passes.to_string(),
        EstimateKind::SinglePass { reason, .. } => format!("1(single-pass: {reason})"),
        EstimateKind::Running => "running".to_string(),
    }
}

/// Prints the summary line (when `run.build` is set) and returns `ok`.
fn summary(run: &RunInfo, config: &str, fields: &str, ok: bool, why: &[String]) -> bool {
    let rc_ok = run.rc.is_none_or(|rc| rc == 0);
    let ok = ok && rc_ok;
    if let Some(build) = &run.build {
        let mut line = format!(
            "summary build={build} config={} {fields}",
            run.config.as_deref().unwrap_or(config)
        );
        if let Some(rc) = run.rc {
            line += &format!(" exit={rc}");
        }
        if let Some(s) = run.seconds {
            line += &format!(" qemu={s}s");
        }
        // A reported-only run (with a note) is "not-met", never "FAIL".
        line += match (ok, run.note.is_some()) {
            (true, _) => " ok",
            (false, true) => " not-met",
            (false, false) => " FAIL",
        };
        let mut why = why.to_vec();
        if !rc_ok {
            why.push(format!("QEMU exit status {}", run.rc.unwrap_or(0)));
        }
        if !ok && !why.is_empty() {
            line += &format!(" ({})", why.join("; "));
        }
        if let Some(n) = &run.note {
            line += &format!(" {n}");
        }
        println!("{line}");
    }
    ok
}

/// A host state: name, estimate and σ in the firmware's (internal) units,
/// and whether it is an instrument term of the full model.
struct HostState {
    name: String,
    estimate: f64,
    sigma: f64,
    instrument: bool,
}

/// The host JSON's states in state order: the installation states (rad),
/// then the full model's instrument terms, converted from their printed
/// units back to the internal ones.
fn host_states(json: &serde_json::Value) -> Result<Vec<HostState>, String> {
    let mut out = Vec::new();
    for s in json["states"].as_array().ok_or("host JSON has no states")? {
        out.push(HostState {
            name: s["name"].as_str().unwrap_or("?").to_string(),
            estimate: s["estimate_rad"]
                .as_f64()
                .ok_or("state without estimate_rad")?,
            sigma: s["sigma_rad"].as_f64().ok_or("state without sigma_rad")?,
            instrument: false,
        });
    }
    for s in json["instruments"].as_array().into_iter().flatten() {
        let group = s["group"].as_str().unwrap_or("?");
        let (k, _) = Group::from_name(group)
            .ok_or_else(|| format!("instrument term of unknown group {group}"))?
            .printed_scale();
        out.push(HostState {
            name: s["name"].as_str().unwrap_or("?").to_string(),
            estimate: s["estimate"]
                .as_f64()
                .ok_or("instrument without estimate")?
                / k,
            sigma: s["sigma"].as_f64().ok_or("instrument without sigma")? / k,
            instrument: true,
        });
    }
    Ok(out)
}

/// How far the firmware's estimate is from the host's.
struct Differences {
    /// The largest |Δ| over the installation states (rad).
    max_rad: f64,
    /// The largest |Δ|/σ over every state.
    max_sigma: f64,
    /// The largest |Δ|/σ over the instrument terms.
    max_instr: f64,
    /// The installation state of `max_rad`.
    worst: String,
}

/// The differences of the firmware's `state` from the host's `states`:
/// radians for the installation states, the instrument terms in units of
/// their σ (`max_sigma` covers both). A NaN on either side counts as an
/// infinite difference.
fn differences(states: &[HostState], state: &[f64]) -> Differences {
    let (mut max_rad, mut max_sigma, mut max_instr) = (0.0f64, 0.0f64, 0.0f64);
    let mut worst = String::new();
    for (s, x) in states.iter().zip(state.iter()) {
        let d = (x - s.estimate).abs();
        let d = if d.is_nan() { f64::INFINITY } else { d };
        if s.instrument {
            max_instr = max_instr.max(d / s.sigma);
        } else if d > max_rad || worst.is_empty() {
            max_rad = d;
            worst.clone_from(&s.name);
        }
        max_sigma = max_sigma.max(d / s.sigma);
    }
    Differences {
        max_rad,
        max_sigma,
        max_instr,
        worst,
    }
}

fn compare(
    firmware: &Path,
    host: &Path,
    tol: Option<f64>,
    tol_sigma: Option<f64>,
    tol_instrument_sigma: f64,
    label: &str,
    run: &RunInfo,
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
    let states = host_states(&json)?;
    if states.len() != est.state.len() {
        return Err(format!(
            "{} states from the firmware, {} from the host",
            est.state.len(),
            states.len()
        ));
    }
    let Differences {
        max_rad,
        max_sigma,
        max_instr,
        worst,
    } = differences(&states, &est.state);
    let full = states.iter().any(|s| s.instrument);
    let host_passes = json["answer"]["passes"].as_u64();
    let fw_passes = match est.kind {
        EstimateKind::Final { passes, .. } => Some(u64::from(passes)),
        _ => None,
    };
    let mut why = Vec::new();
    if tol.is_some_and(|t| max_rad > t) {
        why.push(format!(
            "max |Δ| {max_rad:.3e} rad > {:e}",
            tol.unwrap_or(0.0)
        ));
    }
    if tol.is_some() && full && max_instr > tol_instrument_sigma {
        why.push(format!(
            "an instrument term {max_instr:.3e}σ > {tol_instrument_sigma:e}σ"
        ));
    }
    if let Some(t) = tol_sigma.filter(|t| max_sigma > *t) {
        why.push(format!("max |Δ| {max_sigma:.3e}σ > {t}σ"));
    }
    let checked = tol.is_some() || tol_sigma.is_some();
    if checked {
        match (fw_passes, host_passes) {
            (None, _) => why.push(format!(
                "the firmware's last estimate is not the estimator of record's ({})",
                kind_str(&est.kind)
            )),
            // The same passes as the host when the comparison is to the
            // last bits (`--tol`, the same arithmetic); an f32 build's
            // passes stop where its own steps fall under the tolerance,
            // which may be a pass before or after f64's (docs/estimator.md,
            // the full model in single precision), and only its answer is
            // held to the host's (`--tol-sigma`).
            (Some(f), Some(h)) if f != h && tol.is_some() => {
                why.push(format!("{f} passes on the firmware, {h} on the host"))
            }
            (Some(_), None) => why.push("the host JSON has no final answer".to_string()),
            _ => {}
        }
    }
    let rejected = est.progress.rejects.total();
    if checked && rejected > 0 {
        why.push(format!("{rejected} samples rejected"));
    }
    let within = why.is_empty();
    println!(
        "{label}: {count} Estimate frames, final seq {} after {} updates, passes {} (host {}); max |Δ| vs host = {max_rad:.3e} rad = {:.3e}″ = {max_sigma:.2e}σ (worst {worst}){}",
        est.seq,
        est.updates,
        kind_str(&est.kind),
        host_passes.map_or("?".to_string(), |p| p.to_string()),
        max_rad / ARCSEC,
        match (checked, within) {
            (true, true) => " — PASS".to_string(),
            (true, false) => format!(" — FAIL ({})", why.join("; ")),
            (false, _) => String::new(),
        }
    );
    let limit = match (tol, tol_sigma) {
        (Some(t), _) => format!("{t:e}"),
        (None, Some(s)) => format!("{s}sigma"),
        (None, None) => "none".to_string(),
    };
    let instruments = if full {
        format!(" max_dsigma_instruments={max_instr:.3e}")
    } else {
        String::new()
    };
    let limit = if full && tol.is_some() {
        format!("{limit},{tol_instrument_sigma:e}sigma")
    } else {
        limit
    };
    let passes = match (fw_passes, host_passes) {
        (Some(f), Some(h)) if f != h => format!("{}(host:{h})", kind_str(&est.kind)),
        _ => kind_str(&est.kind),
    };
    let fields = format!(
        "errors={} passes={passes} max_dabs_rad={max_rad:.3e} max_dsigma={max_sigma:.3e}{instruments} limit={limit}",
        est.errors,
    );
    Ok(summary(run, est.config.as_str(), &fields, within, &why))
}

fn identical(
    firmware: &Path,
    reference: &Path,
    against: &str,
    running_sigma: Option<f64>,
    run: &RunInfo,
) -> Result<bool, String> {
    let all_a = estimates(firmware)?;
    let all_b = estimates(reference)?;
    let (Some(a), Some(b)) = (all_a.last(), all_b.last()) else {
        return Err("no Estimate frame in one of the runs".into());
    };
    let bits = |e: &Estimate| -> Vec<u64> {
        e.state
            .iter()
            .chain(e.sigma.iter())
            .map(|v| v.to_bits())
            .collect()
    };
    let max_rad = a
        .state
        .iter()
        .zip(b.state.iter())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f64, f64::max);
    let same_bits = bits(a) == bits(b);
    let same_message = match running_sigma {
        None => a == b,
        // A resumed device: the final answer's own counts, not the running
        // filter's last innovation.
        Some(_) => {
            (a.seq, a.kind, a.progress.accepted, a.progress.logged)
                == (b.seq, b.kind, b.progress.accepted, b.progress.logged)
        }
    };
    // The running estimates' largest difference, in their own σ.
    let running_dsigma = all_a
        .iter()
        .zip(all_b.iter())
        .flat_map(|(x, y)| {
            x.state
                .iter()
                .zip(y.state.iter())
                .zip(y.sigma.iter())
                .map(|((p, q), s)| (p - q).abs() / s)
        })
        .fold(0.0f64, f64::max);
    // Every estimate (the running ones too), bit for bit.
    let differing = all_a
        .iter()
        .zip(all_b.iter())
        .position(|(x, y)| x != y || bits(x) != bits(y));
    let mut why = Vec::new();
    if all_a.len() != all_b.len() {
        why.push(format!(
            "{} Estimate frames, {} in the {against} run",
            all_a.len(),
            all_b.len()
        ));
    }
    let differing = differing.filter(|_| running_sigma.is_none());
    if let Some(limit) = running_sigma.filter(|l| running_dsigma.is_nan() || running_dsigma > *l) {
        why.push(format!(
            "the running estimates differ by {running_dsigma:.3e} sigma (limit {limit:e})"
        ));
    }
    if let Some(k) = differing {
        why.push(format!(
            "Estimate frame {k} (seq {}) differs from the {against} run's",
            all_a[k].seq
        ));
    }
    if !same_bits {
        why.push(format!("states or σ differ (max |Δ| {max_rad:.3e} rad)"));
    }
    if same_bits && !same_message {
        why.push("the estimates' bookkeeping differs".to_string());
    }
    if !matches!(a.kind, EstimateKind::Final { .. }) {
        why.push(format!(
            "not the estimator of record's ({})",
            kind_str(&a.kind)
        ));
    }
    println!(
        "{}: {} Estimate frames, the last seq {} passes {}; {against}: {}, seq {} passes {}: {}",
        firmware.display(),
        all_a.len(),
        a.seq,
        kind_str(&a.kind),
        all_b.len(),
        b.seq,
        kind_str(&b.kind),
        if why.is_empty() && running_sigma.is_some() {
            format!("final estimate bit-identical, running ones within {running_dsigma:.3e} sigma")
        } else if why.is_empty() {
            "bit-identical".to_string()
        } else {
            why.join("; ")
        }
    );
    let all_same = same_bits && same_message && differing.is_none() && all_a.len() == all_b.len();
    let fields = match running_sigma {
        None => format!(
            "passes={} vs={against} estimates={} max_dabs_rad={max_rad:.3e} bit_identical={}",
            kind_str(&a.kind),
            all_a.len(),
            if all_same { "yes" } else { "no" }
        ),
        Some(_) => format!(
            "passes={} vs={against} estimates={} final_max_dabs_rad={max_rad:.3e} final_bit_identical={} running_max_dsigma={running_dsigma:.3e}",
            kind_str(&a.kind),
            all_a.len(),
            if same_bits && same_message { "yes" } else { "no" }
        ),
    };
    Ok(summary(
        run,
        a.config.as_str(),
        &fields,
        why.is_empty(),
        &why,
    ))
}

/// Frames decoded from `bytes`: (Configure messages, Sample messages, frame errors).
fn census(bytes: &[u8]) -> (usize, usize, u32) {
    let mut d = FrameDecoder::new();
    let (mut configure, mut samples) = (0, 0);
    d.feed(bytes, |m| match m {
        Message::Configure(_) => configure += 1,
        Message::Sample(_) => samples += 1,
        _ => {}
    });
    (configure, samples, d.stats().errors())
}

fn garble_first_frame(input: &Path, out: &Path) -> Result<(), String> {
    let mut bytes =
        std::fs::read(input).map_err(|e| format!("cannot read {}: {e}", input.display()))?;
    let end = bytes
        .iter()
        .position(|&b| b == 0)
        .ok_or("no frame delimiter in the stream")?;
    if end < 2 {
        return Err("the first frame is empty".into());
    }
    // A byte in the middle of the first frame, changed to another non-zero
    // byte (a zero would split the frame instead).
    let at = end / 2;
    let old = bytes[at];
    bytes[at] = if old ^ 0xFF == 0 { 0x7F } else { old ^ 0xFF };
    let (c0, s0, e0) = census(&std::fs::read(input).map_err(|e| e.to_string())?);
    let (c1, s1, e1) = census(&bytes);
    if c0 == 0 || c1 != 0 || s1 != s0 || e1 != e0 + 1 {
        return Err(format!(
            "garbling byte {at} of the first frame: Configure {c0} → {c1}, samples {s0} → {s1}, frame errors {e0} → {e1} (want 1 → 0, unchanged, +1)"
        ));
    }
    std::fs::write(out, &bytes).map_err(|e| format!("cannot write {}: {e}", out.display()))?;
    eprintln!(
        "{}: byte {at} of the first frame (of {} bytes) changed: no Configure left, {s1} samples, {e1} frame error(s)",
        out.display(),
        end + 1
    );
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let (r, run) = match &cli.command {
        Cmd::EndFrame => (end_frame().map(|()| true), None),
        Cmd::Compare {
            firmware,
            host,
            tol,
            tol_sigma,
            tol_instrument_sigma,
            label,
            run,
        } => (
            compare(
                firmware,
                host,
                *tol,
                *tol_sigma,
                *tol_instrument_sigma,
                label,
                run,
            ),
            Some(run),
        ),
        Cmd::Identical {
            firmware,
            reference,
            against,
            final_only_running_sigma,
            run,
        } => (
            identical(firmware, reference, against, *final_only_running_sigma, run),
            Some(run),
        ),
        Cmd::GarbleFirstFrame { input, out } => {
            (garble_first_frame(input, out).map(|()| true), None)
        }
    };
    match r {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("firmware-check: error: {e}");
            if let Some(run) = run {
                summary(run, "?", "no comparison", false, &[e]);
            }
            ExitCode::FAILURE
        }
    }
}
