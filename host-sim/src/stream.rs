//! `record` and `calibrate`: a scenario as a stream of wire frames
//! (`docs/wire.md`), and the calibrator run on such a stream from a file,
//! stdin or a serial port.
//!
//! `record` writes a `Configure` message (the scenario's noise levels,
//! Earth rate, prior) and then one `Sample` per period, with f32 fields as
//! the firmware would send them. The stream carries no truth; `--truth PATH`
//! writes it to a JSON sidecar (true final states and Cramér–Rao σ of the
//! recorded configuration) that `calibrate --truth PATH` reads to fill the
//! truth and σ_CRLB columns. Without it, `calibrate` prints the estimate,
//! σ and the bound at the estimate with its observability verdict, and
//! judges the data against the model ([`crate::checks`]).
//!
//! `record --format csv` writes the same samples as a CSV log
//! ([`crate::csvlog`], docs/csv.md), without the `Configure`; `calibrate`
//! reads such a log with the settings of a platform file (`--platform`),
//! sending the calibrator the `Configure` of those settings and then the
//! samples, as a frame stream would.
//!
//! `calibrate` decodes the stream, validates and processes every sample
//! with the no_std [`rollcal::calibrator::Calibrator`] (f64) — pass 1,
//! exactly what the firmware computes — and then, like `run`, runs the
//! further linearised passes over the accepted samples (`--passes 1` gives
//! the firmware's answer). The table and JSON are those of `run`, plus a
//! `stream` object (frame and sample counters) and `pass1` (the
//! calibrator's final estimate and σ, full f64 precision).

use std::io::{IsTerminal, Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant as Clock};

use nalgebra::{RealField, Vector3};
use rollcal::calibrator::{Calibrator, RejectReason};
use rollcal::ekf::{self, FilterConfig, Options};
use rollcal::estimator::{EstimatorOptions, LogError, LogRecord, SampleLog};
use rollcal::models::{ConfigId, Environment, Model};
use rollcal::session::{AnyCalibrator, Reply, Session};
use rollcal::wire::{
    encode, CalibratorConfig, DecoderStats, Estimate, EstimateKind, FrameDecoder, Message, Sample,
    MAX_FRAME_LEN,
};

use crate::checks::{self, DataVerdict};
use crate::progress::Progress;
use crate::report::{print_table, print_table_no_truth, run_json, write_json};
use crate::runner::{self, Passes, RunResult};
use crate::scenario::{Platform, Scenario, DEG};
use crate::segments;
use crate::truth::{simulate, truth_state, PeriodSample, SimOptions};
use crate::verdict::Verdict;
use rollcal::observability::Observability;

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
    /// Estimate cadence written into the `Configure` message (samples).
    #[arg(long, default_value_t = 60)]
    pub estimate_every: u32,
    /// Impairments of the link and the platform (lost frames, clock steps,
    /// bit flips, outliers), applied after the simulation.
    #[command(flatten)]
    pub impair: crate::impair::Impairments,
    /// Output format: wire frames (docs/wire.md), or a CSV log
    /// (docs/csv.md; no `Configure`: calibrate it with --platform).
    #[arg(long, value_enum, default_value_t = Format::Frames)]
    pub format: Format,
}

/// Format of a recorded log.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// Binary wire frames (docs/wire.md).
    Frames,
    /// CSV, one line per period (docs/csv.md).
    Csv,
}

/// Arguments of `host-sim calibrate`.
#[derive(clap::Args, Clone, Debug)]
pub struct CalibrateArgs {
    /// Configuration to run: must agree with the stream's `Configure`
    /// message and the platform file's `config` (default: theirs).
    #[arg(long, value_parser = parse_config)]
    pub config: Option<ConfigId>,
    /// Input: a file, `-` for stdin, or a serial device (e.g. /dev/ttyUSB0,
    /// or a pseudo-terminal such as /dev/pts/3; a device is read until it
    /// has been idle for --idle-timeout).
    #[arg(long, value_name = "FILE|-|SERIAL_DEVICE", default_value = "-")]
    pub input: String,
    /// Input format (default: `csv` for a name ending in `.csv`, else frames).
    #[arg(long, value_enum)]
    pub format: Option<Format>,
    /// Platform file (TOML, docs/csv.md): configuration, site, noise,
    /// period, prior; the settings of a CSV log or of a stream without a
    /// `Configure` message.
    #[arg(long, value_name = "FILE", conflicts_with = "scenario")]
    pub platform: Option<PathBuf>,
    /// Baud rate of a serial device.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// A serial stream ends after this many seconds without a byte.
    #[arg(long, default_value_t = 5.0)]
    pub idle_timeout: f64,
    /// Settings used when the stream has no `Configure` message (default:
    /// the paper's scenario).
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Truth sidecar written by `record --truth`.
    #[arg(long, value_name = "PATH")]
    pub truth: Option<PathBuf>,
    /// At most this many passes: 1 = the calibrator alone (the firmware's
    /// answer); more = further linearised passes as in `run`.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(1..=8))]
    pub passes: u8,
    /// Precision of the calibrator's covariance arithmetic (f32: as the
    /// Cortex-M4F firmware; state, nominal and residuals are f64 in both).
    #[arg(long, value_enum, default_value_t = runner::Precision::F64)]
    pub precision: runner::Precision,
    /// Write the final states as JSON (as `run --json`) to PATH.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// `--matrices`, `--matrices-txt`: the result as matrices to apply.
    #[command(flatten)]
    pub matrices: crate::compensation::MatricesArgs,
    /// Write an HTML report to DIR/index.html (created if missing), with its
    /// PNG figures beside it: parameter table, σ(t), error (with --truth),
    /// NIS and innovation figures with the segment switches, consistency
    /// checks. The figures need the final passes (none with --passes 1).
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
}

fn parse_config(s: &str) -> Result<ConfigId, String> {
    ConfigId::parse(s).ok_or_else(|| {
        let ids: Vec<&str> = ConfigId::ALL.iter().map(|c| c.as_str()).collect();
        format!(
            "unknown configuration '{s}' (expected one of {})",
            ids.join(", ")
        )
    })
}

/// Calibrator settings equal to `runner::filter_config` of the scenario
/// (so that the stream's filter is `run`'s filter).
pub fn calibrator_config(sc: &Scenario, id: ConfigId, earth_rate: bool) -> CalibratorConfig {
    platform_config(&Platform::of_scenario(sc), id, earth_rate)
}

/// Calibrator settings of a platform file (the `Configure` message a
/// platform with these settings would send).
pub fn platform_config(p: &Platform, id: ConfigId, earth_rate: bool) -> CalibratorConfig {
    let f = runner::filter_config_of(&p.site, &p.noise, earth_rate, Options::default());
    let mut c = CalibratorConfig::paper(id);
    c.sigma_accel_g = f.sigma_accel;
    c.sigma_gyro_rad_s = f.sigma_gyro;
    c.sigma_gimbal_rad = f.sigma_gimbal;
    c.earth_rate_n = f.env.earth_rate_n.into();
    c.gravity_n = f.env.gravity_n.into();
    c.prior_sigma_rad = p.prior.sigma_deg * DEG;
    c.limits.period_s = p.timing.period_s;
    c
}

/// The filter settings of a calibrator configuration (f64).
pub fn filter_config(c: &CalibratorConfig) -> FilterConfig<f64> {
    FilterConfig {
        env: Environment {
            earth_rate_n: c.earth_rate_n.into(),
            gravity_n: c.gravity_n.into(),
        },
        sigma_accel: c.sigma_accel_g,
        sigma_gyro: c.sigma_gyro_rad_s,
        sigma_gimbal: c.sigma_gimbal_rad,
        options: c.options,
    }
}

/// A simulated period as the platform would send it (f32 fields but the
/// commanded increment, f64; the timestamp is the end of the period in µs).
pub fn to_sample(s: &PeriodSample) -> Sample {
    let f = |v: &Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
    Sample {
        seq: s.k,
        t_us: (s.truth.t * 1e6).round() as u64,
        dt: s.dt as f32,
        dtheta_cmd: s.dtheta_cmd.into(),
        accel_mean: f(&s.accel_mean),
        gimbal: Some(f(&s.gimbal)),
        c_cn_quat: rollcal::geometry::quaternion_from_dcm(&s.truth.c_c_n).map(|v| v as f32),
    }
}

/// `record` writes binary frames: to stdout (`out` = `-`) only when stdout
/// is not a terminal (`stdout_is_terminal`).
pub fn refuse_terminal(out: &str, stdout_is_terminal: bool) -> Result<(), String> {
    if out == "-" && stdout_is_terminal {
        return Err(
            "record writes binary frames: give --out FILE, or redirect or pipe stdout (e.g. | host-sim calibrate --input -)"
                .into(),
        );
    }
    Ok(())
}

/// Appends the frame of `m` to `out`.
pub fn push_frame(out: &mut Vec<u8>, m: &Message) -> Result<(), String> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = encode(m, &mut buf).map_err(|e| e.to_string())?;
    out.extend_from_slice(buf.get(..n).unwrap_or_default());
    Ok(())
}

fn load_scenario(path: Option<&Path>) -> Result<Scenario, String> {
    match path {
        Some(p) => Scenario::from_file(p).map_err(|e| e.to_string()),
        None => Ok(Scenario::paper()),
    }
}

/// `host-sim record`.
pub fn record(args: &RecordArgs) -> Result<(), String> {
    let csv = args.format == Format::Csv;
    if csv && args.impair.bit_flips > 0.0 {
        return Err("--bit-flips impairs the frame bytes: not with --format csv".into());
    }
    if !csv {
        refuse_terminal(&args.out, std::io::stdout().is_terminal())?;
    }
    let sc = load_scenario(args.scenario.as_deref())?;
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
    crate::truth::check_gimbal_lock(args.config, &sim)?;
    let mut settings = calibrator_config(&sc, args.config, earth_rate);
    settings.estimate_every = args.estimate_every;
    let mut samples: Vec<Sample> = sim.samples.iter().map(to_sample).collect();
    let mut applied = crate::impair::Applied::default();
    let imp = &args.impair;
    imp.apply_to_samples(
        &mut samples,
        settings.sigma_accel_g,
        args.seed,
        &mut applied,
    );
    let mut bytes = Vec::with_capacity(samples.len() * 80);
    if csv {
        bytes = crate::csvlog::write(&samples).into_bytes();
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
        let last = sim.samples.last().map_or(sim.initial, |s| s.truth);
        let truth = truth_state(args.config, &sim.params, &last);
        let truth0 = truth_state(args.config, &sim.params, &sim.initial);
        let crlb = runner::crlb_sigma(args.config, &sc, &sim, earth_rate)
            .map_err(|e| format!("Cramér–Rao bound: {e}"))?;
        let json = serde_json::json!({
            "config": args.config.as_str(),
            "scenario": sc.name,
            "seed": args.seed,
            "earth_rate": earth_rate,
            "duration_s": sc.timing.duration_s,
            "names": args.config.states().iter().map(|s| s.name).collect::<Vec<_>>(),
            "truth_rad": truth,
            "truth0_rad": truth0,
            "crlb_sigma_rad": crlb,
        });
        write_json(path, &json)?;
    }
    Ok(())
}

/// The host's sample log: a vector that grows as needed.
pub struct VecLog<T: RealField + Copy = f64>(pub Vec<LogRecord<T>>);

impl<T: RealField + Copy> Default for VecLog<T> {
    fn default() -> Self {
        Self(Vec::new())
    }
}

impl<T: RealField + Copy> VecLog<T> {
    /// The records in f64 (exact for f32).
    pub fn records_f64(&self) -> Vec<LogRecord<f64>> {
        let f = |v: T| v.to_subset().unwrap_or(f64::NAN);
        self.0
            .iter()
            .map(|r| LogRecord {
                dt: r.dt,
                dtheta_cmd: r.dtheta_cmd,
                observation: r.observation.map(|o| ekf::Observation {
                    accel_mean: o.accel_mean.map(f),
                    gimbal: o.gimbal.map(|g| g.map(f)),
                }),
            })
            .collect()
    }
}

impl<T: RealField + Copy> SampleLog<T> for VecLog<T> {
    fn append(&mut self, r: &LogRecord<T>) -> Result<(), LogError> {
        self.0.push(*r);
        Ok(())
    }
    fn len(&self) -> usize {
        self.0.len()
    }
    fn truncate(&mut self, len: usize) {
        self.0.truncate(len);
    }
    fn get(&mut self, k: usize) -> Option<LogRecord<T>> {
        self.0.get(k).copied()
    }
}

/// The final answer of the session's calibrator.
struct Final {
    estimate: Estimate,
    /// NIS of every update of the last pass.
    nis: Vec<f64>,
    /// The accepted updates of the last pass.
    updates: Vec<runner::Update>,
    /// Time history of the last pass: (t, estimate, σ) per record.
    history: Vec<(f64, Vec<f64>, Vec<f64>)>,
    /// Covariance of the final filter, row-major (rad²; empty when the
    /// passes did not run).
    covariance: Vec<f64>,
}

/// The no_std session (the protocol, once) with the host's log and records
/// for the report.
struct Host<T: RealField + Copy> {
    session: Session<T>,
    /// Settings for a stream without a `Configure` message (`--platform`
    /// or `--scenario`), when the configuration is known.
    fallback: Option<CalibratorConfig>,
    /// The sample log since the last (re)start, for the final passes.
    log: VecLog<T>,
    /// NIS of every accepted update since the last (re)start.
    nis: Vec<f64>,
    /// Filter failures (sequence number, error).
    failures: Vec<(u32, ekf::Error)>,
    /// Where the fallback settings come from, for the note.
    fallback_of: String,
}

impl<T: RealField + Copy> Host<T> {
    fn handle(&mut self, m: Message) -> Result<(), String> {
        match &m {
            Message::Sample(_) if self.session.calibrator().is_none() => {
                let Some(fallback) = self.fallback else {
                    return Err("the stream has no Configure message: give --config (and --platform FILE for the platform's settings)".into());
                };
                eprintln!(
                    "note: the stream has no Configure message; using the settings of {}",
                    self.fallback_of
                );
                self.session
                    .configure(fallback)
                    .map_err(|e| format!("calibrator: {e}"))?;
            }
            Message::Configure(_) | Message::Reset => {
                if self.session.calibrator().is_some() {
                    eprintln!("\nnote: {} mid-stream: restarting the calibrator", tag(&m));
                }
                self.nis.clear();
                self.failures.clear();
            }
            _ => {}
        }
        match self.session.handle(&m, &mut self.log) {
            Reply::Error(e) => return Err(format!("{e}")),
            Reply::Rejected(RejectReason::Filter(e)) => {
                if let Message::Sample(s) = &m {
                    self.failures.push((s.seq, e));
                }
            }
            Reply::Nothing | Reply::Send(_) | Reply::Rejected(_) => {
                if let (Message::Sample(s), Some(cal)) = (&m, self.session.calibrator()) {
                    if cal.progress().last_seq == Some(s.seq) {
                        self.nis.push(cal.progress().last_nis);
                    }
                }
            }
        }
        Ok(())
    }

    fn finish(&mut self, passes: u8) -> Option<Final> {
        let opts = EstimatorOptions {
            max_passes: passes,
            ..EstimatorOptions::default()
        };
        let cal = self.session.calibrator()?;
        let (mut nis, mut updates, mut history, mut pass) = (Vec::new(), Vec::new(), Vec::new(), 0);
        let (estimate, covariance) = finish_with_covariance(cal, &mut self.log, &opts, &mut |ev| {
            if ev.pass != pass {
                (pass, nis, updates, history) = (ev.pass, Vec::new(), Vec::new(), Vec::new());
            }
            if let Some(u) = ev.update {
                nis.push(u.nis);
                updates.push(u);
            }
            history.push((ev.t_s, ev.state, ev.sigma));
        });
        Some(Final {
            estimate,
            nis,
            updates,
            history,
            covariance,
        })
    }
}

/// One record of a pass of [`finish_with_covariance`].
struct FinishEvent {
    /// Pass number, from 1.
    pass: u8,
    /// Time at the end of the record's period (s from the start of the log).
    t_s: f64,
    /// The accepted update of the record, if any.
    update: Option<runner::Update>,
    /// Estimate after the record (rad).
    state: Vec<f64>,
    /// σ after the record (rad).
    sigma: Vec<f64>,
}

/// [`AnyCalibrator::finish`], also returning the final filter's covariance
/// (row-major, rad²; empty when the passes did not run).
fn finish_with_covariance<T: RealField + Copy>(
    cal: &AnyCalibrator<T>,
    log: &mut (dyn SampleLog<T> + '_),
    passes: &EstimatorOptions,
    on_record: &mut dyn FnMut(FinishEvent),
) -> (Estimate, Vec<f64>) {
    fn one<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>(
        c: &Calibrator<T, M, N, Z>,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        on_record: &mut dyn FnMut(FinishEvent),
    ) -> (Estimate, Vec<f64>) {
        let f = |v: &T| v.to_subset().unwrap_or(f64::NAN);
        let mut t = 0.0;
        let (estimate, filter) = c.finish(log, passes, |e| {
            t = if e.index == 0 { 0.0 } else { t } + e.record.dt;
            on_record(FinishEvent {
                pass: e.pass,
                t_s: t,
                update: match &e.result {
                    Ok(Some(i)) => Some(runner::Update::of(e.index, t, i)),
                    _ => None,
                },
                state: e.filter.state().iter().copied().collect(),
                sigma: e.filter.sigma().iter().map(f).collect(),
            })
        });
        let covariance = filter.map_or_else(Vec::new, |f| {
            f.covariance()
                .transpose()
                .iter()
                .map(|v| v.to_subset().unwrap_or(f64::NAN))
                .collect()
        });
        (estimate, covariance)
    }
    match cal {
        AnyCalibrator::M1Pa(c) => one(c, log, passes, on_record),
        AnyCalibrator::M1Ps(c) => one(c, log, passes, on_record),
        AnyCalibrator::M2Ps(c) => one(c, log, passes, on_record),
        AnyCalibrator::M3Pa(c) => one(c, log, passes, on_record),
        AnyCalibrator::M3Ps(c) => one(c, log, passes, on_record),
        AnyCalibrator::M4Pa(c) => one(c, log, passes, on_record),
        AnyCalibrator::M4Ps(c) => one(c, log, passes, on_record),
    }
}

fn tag(m: &Message) -> &'static str {
    match m {
        Message::Configure(_) => "Configure",
        Message::Reset => "Reset",
        _ => "message",
    }
}

/// Reads an input until its end (or, for a serial port, until it has been
/// idle for `idle`), feeding `on_bytes`.
fn read_input(
    input: &str,
    baud: u32,
    idle: Duration,
    mut on_bytes: impl FnMut(&[u8]) -> Result<(), String>,
) -> Result<(), String> {
    let mut buf = vec![0u8; 4096];
    let mut drain = |r: &mut dyn Read, serial: bool| -> Result<(), String> {
        let mut last = Clock::now();
        loop {
            match r.read(&mut buf) {
                Ok(0) if !serial => return Ok(()),
                Ok(n) => {
                    if n > 0 {
                        last = Clock::now();
                    }
                    on_bytes(buf.get(..n).unwrap_or_default())?;
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) if serial && e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => return Err(format!("cannot read {input}: {e}")),
            }
            if serial && last.elapsed() > idle {
                eprintln!("\nno data for {:.1} s: end of stream", idle.as_secs_f64());
                return Ok(());
            }
        }
    };
    if input == "-" {
        return drain(&mut std::io::stdin().lock(), false);
    }
    let meta = std::fs::metadata(input).map_err(|e| format!("cannot open {input}: {e}"))?;
    #[cfg(unix)]
    let is_device = {
        use std::os::unix::fs::FileTypeExt;
        meta.file_type().is_char_device()
    };
    #[cfg(not(unix))]
    let is_device = !meta.is_file();
    if is_device {
        let mut port = serialport::new(input, baud)
            .timeout(Duration::from_millis(100))
            .open()
            .map_err(|e| format!("cannot open serial device {input} at {baud} Bd: {e}"))?;
        drain(&mut port, true)
    } else {
        let mut f = std::fs::File::open(input).map_err(|e| format!("cannot open {input}: {e}"))?;
        drain(&mut f, false)
    }
}

/// The whole of a text input (a file or `-` for stdin).
fn read_text(input: &str) -> Result<String, String> {
    if input == "-" {
        let mut text = String::new();
        std::io::stdin()
            .lock()
            .read_to_string(&mut text)
            .map_err(|e| format!("cannot read stdin: {e}"))?;
        return Ok(text);
    }
    std::fs::read_to_string(input).map_err(|e| format!("cannot open {input}: {e}"))
}

/// The truth sidecar written by `record --truth`.
struct Sidecar {
    truth: Vec<f64>,
    /// True initial state (rad), for the bound of the samples received.
    truth0: Option<Vec<f64>>,
    crlb: Vec<f64>,
    seed: Option<u64>,
    duration_s: Option<f64>,
}

fn read_sidecar(path: &Path, id: ConfigId) -> Result<Sidecar, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let v: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| format!("{} is not a truth sidecar: {e}", path.display()))?;
    if v["config"].as_str() != Some(id.as_str()) {
        return Err(format!(
            "{} holds the truth of {}, not {id}",
            path.display(),
            v["config"]
        ));
    }
    let floats = |key: &str| -> Result<Vec<f64>, String> {
        v[key]
            .as_array()
            .map(|a| a.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)).collect())
            .ok_or_else(|| format!("{}: no '{key}' array", path.display()))
    };
    Ok(Sidecar {
        truth: floats("truth_rad")?,
        truth0: floats("truth0_rad").ok(),
        crlb: floats("crlb_sigma_rad")?,
        seed: v["seed"].as_u64(),
        duration_s: v["duration_s"].as_f64(),
    })
}

fn reject_json(c: &rollcal::wire::RejectCounts) -> serde_json::Value {
    serde_json::to_value(c).unwrap_or_default()
}

fn frames_json(s: &DecoderStats) -> serde_json::Value {
    serde_json::to_value(s).unwrap_or_default()
}

/// `host-sim calibrate`.
pub fn calibrate(args: &CalibrateArgs) -> Result<(), String> {
    calibrate_judged(args).map(|_| ())
}

/// `host-sim calibrate`, returning the verdict of the data checks
/// ([`crate::checks::judge`]; `main` exits with
/// [`crate::checks::WARNING_EXIT`] on a warning).
pub fn calibrate_judged(args: &CalibrateArgs) -> Result<DataVerdict, String> {
    match args.precision {
        runner::Precision::F64 => calibrate_in::<f64>(args),
        runner::Precision::F32 => calibrate_in::<f32>(args),
    }
}

/// The bound σ (rad) of every state at the estimate along the received
/// path, and the observability verdict of each, for `calibrate` without a
/// truth. The initial state is the estimator of record's own start of the
/// log: the final estimate `x_end` integrated back through every record
/// ([`rollcal::estimator::back_propagate`], what the next linearised pass
/// would start from); the bound is [`runner::bound`]'s recursion
/// ([`Observability`]) from it; the null space is that of the information
/// matrix along the same records linearised at zero state (as
/// `observability`), the verdict [`Verdict::of_bound`].
/// With `x_end` `None` the bound starts at `x_start` instead.
fn bound_at_estimate(
    id: ConfigId,
    cfg: FilterConfig<f64>,
    x_end: Option<&[f64]>,
    x_start: &[f64],
    sigma0: f64,
    records: &[LogRecord<f64>],
) -> Result<(Vec<f64>, Vec<Verdict>), String> {
    fn typed<M: Model<N, Z>, const N: usize, const Z: usize>(
        id: ConfigId,
        cfg: FilterConfig<f64>,
        x_end: Option<&[f64]>,
        x_start: &[f64],
        sigma0: f64,
        records: &[LogRecord<f64>],
    ) -> Result<(Vec<f64>, Vec<Verdict>), String> {
        use rollcal::observability::{COEF_THRESHOLD, RANK_TOLERANCE};
        let vector = |v: &[f64]| {
            nalgebra::SVector::<f64, N>::from_iterator(
                v.iter().copied().chain(std::iter::repeat(0.0)),
            )
        };
        let x0 = match x_end {
            None => vector(x_start),
            Some(x_end) => {
                let mut frame = rollcal::command::CommandFrame::aligned(cfg.env.earth_rate_n);
                for r in records.iter().filter(|r| r.has_valid_period()) {
                    let p = frame.period(&r.dtheta_cmd, r.dt);
                    frame.advance(&p);
                }
                let mut storage = records.to_vec();
                let mut log = rollcal::estimator::SliceLog::from_records(&mut storage);
                rollcal::estimator::back_propagate::<f64, N, _>(
                    id.layout(),
                    &cfg.env,
                    &vector(x_end),
                    &frame,
                    &mut log,
                )
                .map_err(|e| format!("the start of the log: {e}"))?
                .0
            }
        };
        let prior = nalgebra::SVector::<f64, N>::repeat(sigma0);
        let e = |e: ekf::Error| format!("the bound at the estimate: {e}");
        let mut at = Observability::<f64, M, N, Z>::new(cfg, x0, prior).map_err(e)?;
        let mut zero = Observability::<f64, M, N, Z>::new(cfg, nalgebra::SVector::zeros(), prior)
            .map_err(e)?;
        for r in records {
            at.record(r).map_err(e)?;
            zero.record(r).map_err(e)?;
        }
        let part = zero.analyse(RANK_TOLERANCE).map_err(e)?.participation();
        let ratio = at.ratio();
        let verdicts = (0..N)
            .map(|i| Verdict::of_bound(part[i] > COEF_THRESHOLD, ratio[i]))
            .collect();
        Ok((at.crlb_sigma().iter().copied().collect(), verdicts))
    }
    rollcal::with_config!(id, |M, N, Z| typed::<M, N, Z>(
        id, cfg, x_end, x_start, sigma0, records
    ))
}

/// `host-sim calibrate` with the calibrator's covariance arithmetic in `T`.
fn calibrate_in<T: RealField + Copy>(args: &CalibrateArgs) -> Result<DataVerdict, String> {
    let t0 = Clock::now();
    if let Some(dir) = &args.report {
        crate::html::prepare_dir(dir)?;
    }
    let format = args
        .format
        .unwrap_or(if args.input.to_ascii_lowercase().ends_with(".csv") {
            Format::Csv
        } else {
            Format::Frames
        });
    // The settings without a Configure message: the platform file's, else
    // the scenario's (default: the paper's).
    let (platform, source) = match &args.platform {
        Some(path) => (
            Platform::from_file(path).map_err(|e| e.to_string())?,
            format!("the platform file {}", path.display()),
        ),
        None => {
            let sc = load_scenario(args.scenario.as_deref())?;
            let what = args.scenario.as_ref().map_or_else(
                || "the paper's scenario".to_string(),
                |p| format!("the scenario {}", p.display()),
            );
            (Platform::of_scenario(&sc), what)
        }
    };
    let expected = match (args.config, platform.config_id()) {
        (Some(a), Some(b)) if a != b => {
            return Err(format!(
                "--config {a} contradicts the configuration {b} of {source}"
            ))
        }
        (a, b) => a.or(b),
    };
    let mut host = Host::<T> {
        session: Session::new(expected, EstimatorOptions::default()),
        fallback: expected.map(|id| platform_config(&platform, id, platform.site.earth_rate)),
        log: VecLog::default(),
        nis: Vec::new(),
        failures: Vec::new(),
        fallback_of: source.clone(),
    };
    let mut decoder = FrameDecoder::new();
    let runs = expected.map_or_else(
        || "the stream's configuration".to_string(),
        |id| id.to_string(),
    );
    eprintln!("calibrating {runs} from {}…", args.input);
    // The expected number of samples: the platform's (scenario's) periods.
    let mut total = platform.periods() as u64;
    let csv = if format == Format::Csv {
        let Some(id) = expected else {
            return Err(format!(
                "a CSV log has no Configure message: give --config, or --platform FILE with config = \"…\" ({source} names none)"
            ));
        };
        let text = read_text(&args.input)?;
        let mut log = crate::csvlog::parse(&text).map_err(|e| format!("{}: {e}", args.input))?;
        let settings = host.fallback.unwrap_or_else(|| CalibratorConfig::paper(id));
        if !log.has_frames {
            crate::csvlog::fill_frames(&mut log.samples, settings.earth_rate_n)
                .map_err(|e| format!("{}: {e}", args.input))?;
        }
        total = log.samples.len() as u64;
        eprintln!("settings of {source}");
        Some((log.samples, settings))
    } else {
        None
    };
    let progress = Progress::stderr("calibrate", total, "samples accepted");
    let detail = |host: &Host<T>, decoder: &FrameDecoder| {
        let p = host.session.calibrator().map(|c| *c.progress());
        let accepted = p.map_or(0, |p| u64::from(p.accepted));
        let rejected = p.map_or(0, |p| p.rejects.total());
        (
            accepted,
            format!(
                "{rejected} rejected, {} bad frames",
                decoder.stats().errors()
            ),
        )
    };
    let idle = Duration::from_secs_f64(args.idle_timeout.max(0.1));
    let csv_read = csv.is_some();
    let read = match csv {
        // Driven exactly as a frame stream: the Configure, then the samples.
        Some((samples, settings)) => {
            let mut result = host.handle(Message::Configure(settings));
            for (k, s) in samples.into_iter().enumerate() {
                if result.is_err() {
                    break;
                }
                result = host.handle(Message::Sample(s));
                if k % 256 == 0 {
                    let (accepted, text) = detail(&host, &decoder);
                    progress.update(accepted, &text);
                }
            }
            result
        }
        None => read_input(&args.input, args.baud, idle, |bytes| {
            let mut result = Ok(());
            decoder.feed(bytes, |m| {
                if result.is_ok() {
                    result = host.handle(m);
                }
            });
            let (accepted, text) = detail(&host, &decoder);
            progress.update(accepted, &text);
            result
        }),
    };
    let (accepted, text) = detail(&host, &decoder);
    // The summary line unless the input never gave a frame (e.g. a file
    // that does not open): then the error alone says what happened.
    let stats = decoder.stats();
    if read.is_ok() || csv_read || stats.ok > 0 || stats.errors() > 0 || stats.empty > 0 {
        progress.finish(accepted, &text);
    }
    read.map_err(|e| {
        if e.starts_with("the stream configures") {
            match (args.config, &args.platform) {
                (Some(_), _) => format!("{e} (--config)"),
                (None, Some(_)) => format!("{e} ({source})"),
                _ => e,
            }
        } else {
            e
        }
    })?;
    let stats = *decoder.stats();
    let Some(id) = host.session.calibrator().map(|c| c.settings().config) else {
        return Err(format!(
            "no samples in the stream ({} frames decoded, {} rejected)",
            stats.ok,
            stats.errors()
        ));
    };
    // Read after the stream: `record --truth T | calibrate --truth T` works.
    let sidecar = args
        .truth
        .as_deref()
        .map(|p| read_sidecar(p, id))
        .transpose()?;
    if decoder.pending() > 0 {
        eprintln!(
            "note: {} bytes of an unfinished frame at the end of the stream",
            decoder.pending()
        );
    }
    let Some(cal) = host.session.calibrator_mut() else {
        return Err(format!(
            "no samples in the stream ({} frames decoded, {} rejected)",
            stats.ok,
            stats.errors()
        ));
    };
    cal.set_frame_errors(stats.errors());
    let settings = *cal.settings();
    let est = cal.estimate();
    // The running filter's covariance (the answer when the passes do not run).
    let running_covariance =
        crate::compensation::covariance_of_packed_ud(id.layout().n(), &cal.checkpoint().factor);
    let p = est.progress;
    if p.accepted == 0 {
        return Err(format!(
            "no sample accepted ({} rejected, {} bad frames)",
            p.rejects.total(),
            stats.errors()
        ));
    }
    let sigma0 = settings.prior_sigma_rad;
    let nan = vec![f64::NAN; id.layout().n()];
    let truth = sidecar.as_ref().map_or(&nan, |s| &s.truth);
    // The bound of the samples actually received: the bound over the same
    // log (the bridged periods predicted only);
    // the full run's bound when the log is not the whole run.
    let received_bound = match (
        sidecar.as_ref().and_then(|s| s.truth0.as_ref()),
        p.log_incomplete,
    ) {
        (Some(t0), None) => Some(
            runner::bound(
                settings.config,
                filter_config(&settings),
                t0,
                sigma0,
                &host.log.records_f64(),
            )
            .map_err(|e| format!("Cramér–Rao bound of the received samples: {e}"))?,
        ),
        _ => None,
    };
    let crlb = received_bound
        .as_ref()
        .or(sidecar.as_ref().map(|s| &s.crlb))
        .unwrap_or(&nan);
    // The final answer: the calibrator's own estimator of record over its
    // log (pass 1 alone with --passes 1, or when the log is incomplete).
    let fin = if args.passes > 1 {
        host.finish(args.passes)
    } else {
        None
    };
    if let Some(EstimateKind::SinglePass { reason, .. }) = fin.as_ref().map(|f| f.estimate.kind) {
        eprintln!("note: {reason}: the final answer is the calibrator's pass 1");
    }
    let (state, sigma, nis, failures, passes) = match &fin {
        Some(Final { estimate, nis, .. })
            if matches!(estimate.kind, EstimateKind::Final { .. }) =>
        {
            let passes = match estimate.kind {
                EstimateKind::Final { passes, .. } => passes,
                _ => 1,
            };
            // Failures of the last pass are counted in the estimate's report,
            // not listed; the table shows the pass-1 failures.
            (
                &estimate.state,
                &estimate.sigma,
                nis.clone(),
                host.failures.clone(),
                passes,
            )
        }
        _ => (
            &est.state,
            &est.sigma,
            host.nis.clone(),
            host.failures.clone(),
            1,
        ),
    };
    // The last pass of the estimator of record (None: pass 1 is the answer,
    // whose innovations and history were not kept).
    let final_pass = fin
        .as_ref()
        .filter(|f| matches!(f.estimate.kind, EstimateKind::Final { .. }));
    let r: RunResult = runner::result(
        id,
        &Passes {
            filter: Box::new(CalibratorView {
                state: state.to_vec(),
                sigma: sigma.to_vec(),
                covariance: match &fin {
                    Some(f) if matches!(f.estimate.kind, EstimateKind::Final { .. }) => {
                        f.covariance.clone()
                    }
                    _ => running_covariance,
                },
            }),
            history: final_pass.map(|f| f.history.clone()).unwrap_or_default(),
            nis,
            updates: final_pass.map(|f| f.updates.clone()).unwrap_or_default(),
            segments: segments::command_segments(
                host.log.0.iter().map(|r| (r.dt, r.dtheta_cmd.into())),
            ),
            failures,
            passes,
        },
        truth,
        sigma0,
    );
    // Without a truth: the bound at the estimate and its verdict, never
    // FAILED (README "Judging a calibration without a truth").
    let at_estimate = if sidecar.is_none() {
        let records = host.log.records_f64();
        // A log that is not the whole run (re-acquired attitude, full log)
        // has no known start: the bound along the logged records from the
        // cold start (zero state, as pass 1), said so.
        let zeros = vec![0.0; id.layout().n()];
        let end = if p.log_incomplete.is_some() {
            eprintln!(
                "note: the log is not the whole run: the bound is taken from the cold start along the {} logged samples only (of {} accepted)",
                records.len(),
                p.accepted
            );
            None
        } else {
            Some(state.as_slice())
        };
        let (b, v) =
            bound_at_estimate(id, filter_config(&settings), end, &zeros, sigma0, &records)?;
        print_table_no_truth(&r, &b, &v);
        Some((b, v))
    } else {
        print_table(&r, crlb);
        None
    };
    let judgement =
        checks::judge(&r).with_path(checks::gimbal_lock_check(id, &host.log.records_f64()));
    checks::print(&judgement);
    let rj = reject_json(&p.rejects);
    let frames = if format == Format::Csv {
        "CSV log".to_string()
    } else {
        format!(
            "{} frames ok, {} rejected {}",
            stats.ok,
            stats.errors(),
            frames_json(&stats)
        )
    };
    println!(
        "stream: {frames}; samples: {} accepted, {} bridged, {} rejected {}",
        p.accepted,
        p.bridged,
        p.rejects.total(),
        rj
    );
    if p.reacquired > 0 || p.clock_steps > 0 {
        println!(
            "lost data: {} gap(s) with unknown motion re-acquired the attitude ({} periods), {} clock step(s) re-anchored",
            p.reacquired, p.reacquired_periods, p.clock_steps
        );
    }
    eprintln!("done in {:.2} s", t0.elapsed().as_secs_f64());
    if let Some(path) = &args.json {
        let earth_rate = settings.earth_rate_n.iter().any(|v| *v != 0.0);
        let duration = sidecar
            .as_ref()
            .and_then(|s| s.duration_s)
            .unwrap_or(p.accepted as f64 * settings.limits.period_s);
        let mut json = run_json(
            &r,
            sidecar.as_ref().and_then(|s| s.seed).unwrap_or(0),
            earth_rate,
            duration,
        );
        if sidecar.as_ref().and_then(|s| s.seed).is_none() {
            json["seed"] = serde_json::Value::Null;
        }
        json["passes"] = r.passes.into();
        json["precision"] = args.precision.as_str().into();
        json["crlb_sigma_rad"] = serde_json::json!(crlb);
        json["crlb_of"] = if received_bound.is_some() {
            "received samples"
        } else if sidecar.is_some() {
            "full run"
        } else {
            "none"
        }
        .into();
        json["answer"] = match fin.as_ref().map(|f| f.estimate.kind) {
            Some(EstimateKind::Final { passes, converged }) => {
                serde_json::json!({"kind": "final", "passes": passes, "converged": converged})
            }
            Some(EstimateKind::SinglePass { reason, logged }) => serde_json::json!({
                "kind": "single_pass", "reason": reason.to_string(), "logged": logged
            }),
            _ => serde_json::json!({"kind": "single_pass", "reason": "--passes 1"}),
        };
        if let Some((b, v)) = &at_estimate {
            json["bound_at_estimate_sigma_rad"] = serde_json::json!(b);
            json["observability"] = serde_json::json!(v);
        }
        let j = judgement.json();
        json["checks"] = j["checks"].clone();
        json["path_check"] = j["path"].clone();
        json["data_verdict"] = j["data_verdict"].clone();
        json["data_false_alarm"] = j["false_alarm"].clone();
        json["pass1"] = serde_json::json!({
            "seq": est.seq,
            "updates": est.updates,
            "estimate_rad": est.state.to_vec(),
            "sigma_rad": est.sigma.to_vec(),
        });
        json["stream"] = serde_json::json!({
            "format": if format == Format::Csv { "csv" } else { "frames" },
            "frames": frames_json(&stats),
            "accepted": p.accepted,
            "bridged": p.bridged,
            "gated": p.gated,
            "rejects": rj,
            "reacquired": p.reacquired,
            "reacquired_periods": p.reacquired_periods,
            "clock_steps": p.clock_steps,
            "restarts": host.session.stats().restarts,
            "other_messages": host.session.stats().ignored,
        });
        write_json(path, &json)?;
    }
    args.matrices.write(&r)?;
    if let Some(dir) = &args.report {
        // σ_CRLB(t): the bound of the received samples, when computed.
        let crlb_history = match sidecar.as_ref().and_then(|s| s.truth0.as_ref()) {
            Some(t0) if received_bound.is_some() => Some(
                runner::bound_history(
                    id,
                    filter_config(&settings),
                    t0,
                    sigma0,
                    &host.log.records_f64(),
                )
                .map_err(|e| format!("Cramér–Rao bound of the received samples: {e}"))?,
            ),
            _ => None,
        };
        let header = vec![
            ("configuration".into(), id.to_string()),
            (
                "input".into(),
                format!(
                    "{} ({})",
                    args.input,
                    if format == Format::Csv {
                        "CSV log"
                    } else {
                        "frames"
                    }
                ),
            ),
            (
                "passes".into(),
                format!(
                    "{} (answer: {})",
                    r.passes,
                    if final_pass.is_some() {
                        "final"
                    } else {
                        "pass 1"
                    }
                ),
            ),
            ("precision".into(), args.precision.as_str().into()),
            (
                "samples".into(),
                format!(
                    "{} accepted, {} bridged, {} rejected, {} gated",
                    p.accepted,
                    p.bridged,
                    p.rejects.total(),
                    p.gated
                ),
            ),
            (
                "truth".into(),
                args.truth.as_ref().map_or_else(
                    || "none (no truth columns, no error figures)".into(),
                    |t| t.display().to_string(),
                ),
            ),
        ];
        let crlb = sidecar.as_ref().map(|_| crlb.as_slice());
        let page = crate::html::report_of_calibration(
            dir,
            &r,
            crlb,
            crlb_history.as_deref(),
            sidecar.is_some(),
            &judgement,
            header,
        )?;
        eprintln!("report: {}", page.display());
    }
    Ok(judgement.verdict)
}

/// The calibrator's final values as a [`runner::DynFilter`], for the report.
struct CalibratorView {
    state: Vec<f64>,
    sigma: Vec<f64>,
    covariance: Vec<f64>,
}

impl runner::DynFilter for CalibratorView {
    fn step(&mut self, _: &PeriodSample) -> Result<f64, ekf::Error> {
        Err(ekf::Error::NoPrediction)
    }
    fn state(&self) -> Vec<f64> {
        self.state.clone()
    }
    fn sigma(&self) -> Vec<f64> {
        self.sigma.clone()
    }
    fn covariance(&self) -> Vec<f64> {
        self.covariance.clone()
    }
}
