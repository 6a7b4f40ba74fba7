//! `host-sim calibrate`: the calibrator run on a frame stream from a file,
//! stdin or a serial port, or on a CSV log with a platform file; its table
//! (against the truth sidecar, or with the bound at the estimate), the data
//! checks, the stream counters, and the JSON, matrices and report asked
//! for.
//!
//! `record` writes a `Configure` message (the scenario's noise levels,
//! Earth rate, prior) and then one `Sample` per period, with f32 fields as
//! the firmware would send them. The stream carries no truth; `--truth PATH`
//! writes it to a JSON sidecar (true final states and Cramér–Rao σ of the
//! recorded configuration) that `calibrate --truth PATH` reads to fill the
//! truth and σ_CRLB columns. Without it, `calibrate` prints the estimate,
//! σ and the bound at the estimate with its observability verdict, and
//! judges the data against the model ([`crate::analysis::checks`]).
//!
//! `record --format csv` writes the same samples as a CSV log
//! ([`crate::io::csvlog`], docs/csv.md), without the `Configure`; `calibrate`
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
//!
//! The driver goes in steps, each a function: the settings of the input
//! (`input`), the stream read into the session (`feed`), the answer of
//! the session (`answer`: a `Calibration`, everything the outputs need),
//! the printed results (`print_results`), the JSON (`json_of`) and the
//! HTML report (`report`).

use std::path::PathBuf;
use std::time::{Duration, Instant as Clock};

use nalgebra::RealField;
use rollcal::ekf::FilterConfig;
use rollcal::estimator::{LogRecord, LogStart};
use rollcal::models::{ConfigId, ErrorModel};
use rollcal::wire::{
    CalibratorConfig, DecoderStats, Estimate, EstimateKind, FrameDecoder, FrameError, Message,
    Sample, VERSION,
};

use super::args::{load_scenario, parse_config};
use super::checks::print_judgement;
use super::Error;
use crate::analysis::calibration::{
    bound_at_estimate, platform_config, state_at_start, truth_at_start, CalibratorView, Final,
    Host, LogStorage,
};
use crate::analysis::checks::{self, DataVerdict, Judgement};
use crate::analysis::runner::{self, Passes, Precision, RunResult};
use crate::analysis::verdict::Verdict;
use crate::io::sidecar::{read_sidecar, Sidecar};
use crate::io::stream::{frames_json, read_input, read_text, reject_json, Format};
use crate::output::progress::Progress;
use crate::output::report::{print_table, print_table_no_truth, run_json, write_json};
use crate::sim::scenario::Platform;

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
    /// Error model: `installation` (the paper's) or `full` (the
    /// instruments' own errors too, docs/model.md §Full model); overrides
    /// the stream's `Configure` (default: the stream's, else the platform
    /// file's `errors`, else installation).
    #[arg(long, value_parser = super::args::parse_errors)]
    pub errors: Option<ErrorModel>,
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
    #[arg(long, value_enum, default_value_t = Precision::F64)]
    pub precision: Precision,
    /// How the sample log of the final passes keeps a record: `exact`, or
    /// `packed`, rounded as the firmware's log in flash stores it (docs/estimator.md
    /// §The sample log): the final answer is then the firmware's to the
    /// last bit (firmware/run-qemu.sh compares with it).
    #[arg(long, value_enum, default_value_t = LogStorage::Exact)]
    pub log: LogStorage,
    /// Write the final states as JSON (as `run --json`) to PATH.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// `--matrices`, `--matrices-txt`: the result as matrices to apply.
    #[command(flatten)]
    pub matrices: super::matrices::MatricesArgs,
    /// Write an HTML report to DIR/index.html (created if missing), with its
    /// PNG figures beside it: parameter table, σ(t), error (with --truth),
    /// NIS and innovation figures with the segment switches, consistency
    /// checks. The figures need the final passes (none with --passes 1).
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
}

/// `host-sim calibrate`, returning the verdict of the data checks
/// ([`crate::analysis::checks::judge`]; [`super::main`] exits with
/// [`crate::analysis::checks::WARNING_EXIT`] on a warning).
pub fn command(args: &CalibrateArgs) -> Result<DataVerdict, Error> {
    match args.precision {
        Precision::F64 => calibrate_in::<f64>(args),
        Precision::F32 => calibrate_in::<f32>(args),
    }
}

/// `host-sim calibrate` with the calibrator's covariance arithmetic in `T`.
fn calibrate_in<T: RealField + Copy>(args: &CalibrateArgs) -> Result<DataVerdict, Error> {
    let t0 = Clock::now();
    if let Some(dir) = &args.report {
        crate::output::html::prepare_dir(dir)?;
    }
    let input = input(args)?;
    let mut host = Host::<T>::new(
        input.expected,
        input.expected.map(|id| {
            platform_config(
                &input.platform,
                id,
                input.errors.unwrap_or_default(),
                input.platform.site.earth_rate,
            )
        }),
        input.source.clone(),
    );
    host.errors = args.errors;
    host.log.storage = args.log;
    let mut decoder = FrameDecoder::new();
    let runs = input.expected.map_or_else(
        || "the stream's configuration".to_string(),
        |id| id.to_string(),
    );
    eprintln!("calibrating {runs} from {}…", args.input);
    // The expected number of samples: the platform's (scenario's) periods.
    let mut total = input.platform.periods() as u64;
    let csv = if input.format == Format::Csv {
        let (samples, settings) = read_csv(args, &input, host.fallback)?;
        total = samples.len() as u64;
        eprintln!("settings of {}", input.source);
        Some((samples, settings))
    } else {
        None
    };
    feed(args, &input, &mut host, &mut decoder, csv, total)?;
    let c = answer(args, &input, &mut host, &decoder)?;
    let (judgement, at_estimate) = print_results(&c)?;
    eprintln!("done in {:.2} s", t0.elapsed().as_secs_f64());
    if let Some(path) = &args.json {
        write_json(path, &json_of(args, &c, &judgement, at_estimate.as_ref()))?;
    }
    args.matrices.write(&c.r)?;
    if let Some(dir) = &args.report {
        report(args, &c, &judgement, dir)?;
    }
    Ok(judgement.verdict)
}

/// The input's format and the settings for a stream without a `Configure`.
struct Input {
    /// Frames or CSV.
    format: Format,
    /// The platform file's settings, else the scenario's (default: the
    /// paper's).
    platform: Platform,
    /// Where `platform` comes from, for the messages.
    source: String,
    /// The configuration `--config` or the platform file names.
    expected: Option<ConfigId>,
    /// The error model `--errors` or the platform file names.
    errors: Option<ErrorModel>,
}

/// The format of the input and the settings without a Configure message:
/// the platform file's, else the scenario's (default: the paper's).
fn input(args: &CalibrateArgs) -> Result<Input, Error> {
    let format = args
        .format
        .unwrap_or(if args.input.to_ascii_lowercase().ends_with(".csv") {
            Format::Csv
        } else {
            Format::Frames
        });
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
            return Err(
                format!("--config {a} contradicts the configuration {b} of {source}").into(),
            )
        }
        (a, b) => a.or(b),
    };
    let errors = args.errors.or(platform.error_model());
    Ok(Input {
        format,
        platform,
        source,
        expected,
        errors,
    })
}

/// The samples of a CSV log and the settings to configure the calibrator
/// with (the fallback settings, else the paper's of the configuration).
fn read_csv(
    args: &CalibrateArgs,
    input: &Input,
    fallback: Option<CalibratorConfig>,
) -> Result<(Vec<Sample>, CalibratorConfig), Error> {
    let source = &input.source;
    let Some(id) = input.expected else {
        return Err(format!(
            "a CSV log has no Configure message: give --config, or --platform FILE with config = \"…\" ({source} names none)"
        ).into());
    };
    let text = read_text(&args.input)?;
    let mut log = crate::io::csvlog::parse(&text).map_err(|e| format!("{}: {e}", args.input))?;
    if let Some(note) = log.ignored_note() {
        eprintln!("{note}");
    }
    let settings = fallback.unwrap_or_else(|| CalibratorConfig {
        errors: input.errors.unwrap_or_default(),
        ..CalibratorConfig::paper(id)
    });
    if !log.has_frames {
        crate::io::csvlog::fill_frames(&mut log.samples, &settings)
            .map_err(|e| format!("{}: {e}", args.input))?;
    }
    Ok((log.samples, settings))
}

/// [`Host::handle`], then its notes printed.
fn handle<T: RealField + Copy>(host: &mut Host<T>, m: Message) -> Result<(), String> {
    let result = host.handle(m);
    for note in host.notes.drain(..) {
        eprintln!("{note}");
    }
    result
}

/// Accepted samples and the progress text of the session.
fn detail<T: RealField + Copy>(host: &Host<T>, decoder: &FrameDecoder) -> (u64, String) {
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
}

/// Reads the input into the session: the CSV log's `Configure` and
/// samples (`csv`), else the frames of the input, with the progress line
/// (`total` samples expected).
fn feed<T: RealField + Copy>(
    args: &CalibrateArgs,
    input: &Input,
    host: &mut Host<T>,
    decoder: &mut FrameDecoder,
    csv: Option<(Vec<Sample>, CalibratorConfig)>,
    total: u64,
) -> Result<(), Error> {
    let progress = Progress::stderr("calibrate", total, "samples accepted");
    let idle = Duration::from_secs_f64(args.idle_timeout.max(0.1));
    let csv_read = csv.is_some();
    let read = match csv {
        // Driven exactly as a frame stream: the Configure, then the samples.
        Some((samples, settings)) => {
            let mut result = handle(host, Message::Configure(settings));
            for (k, s) in samples.into_iter().enumerate() {
                if result.is_err() {
                    break;
                }
                result = handle(host, Message::Sample(s));
                if k % 256 == 0 {
                    let (accepted, text) = detail(host, decoder);
                    progress.update(accepted, &text);
                }
            }
            result
        }
        None => read_input(&args.input, args.baud, idle, |bytes| {
            let mut result = Ok(());
            decoder.feed_results(bytes, |r| match r {
                Ok(m) if result.is_ok() => result = handle(host, m),
                Err(FrameError::WrongVersion(v)) => host.other_version = Some(v),
                _ => {}
            });
            let (accepted, text) = detail(host, decoder);
            progress.update(accepted, &text);
            result
        })
        .map(|idle| {
            if let Some(idle) = idle {
                eprintln!("\nno data for {:.1} s: end of stream", idle.as_secs_f64());
            }
        })
        .map_err(|e| e.to_string()),
    };
    let (accepted, text) = detail(host, decoder);
    // The summary line unless the input never gave a frame (e.g. a file
    // that does not open): then the error alone says what happened.
    let stats = decoder.stats();
    if read.is_ok() || csv_read || stats.ok > 0 || stats.errors() > 0 || stats.empty > 0 {
        progress.finish(accepted, &text);
    }
    let source = &input.source;
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
        .into()
    })
}

/// What a calibration gave: everything the printed table, the JSON, the
/// matrices and the report need, computed once.
struct Calibration {
    /// The configuration of the stream.
    id: ConfigId,
    /// The calibrator's settings.
    settings: CalibratorConfig,
    /// The calibrator's running estimate (pass 1).
    est: Estimate,
    /// The decoder's counters.
    stats: DecoderStats,
    /// Frames or CSV.
    format: Format,
    /// The truth sidecar, when given.
    sidecar: Option<Sidecar>,
    /// Where the log started on the path.
    start: LogStart,
    /// The true state at the log's start (with a sidecar and a complete
    /// log).
    truth_start: Option<Vec<f64>>,
    /// The bound of the samples received (with a sidecar and a complete log).
    received_bound: Option<Vec<f64>>,
    /// σ_CRLB per state: the bound of the samples received, else the full
    /// run's from the sidecar, else NaN.
    crlb: Vec<f64>,
    /// The estimator of record's final passes (None with `--passes 1`).
    fin: Option<Final>,
    /// Whether the final passes are the answer (else pass 1).
    final_answer: bool,
    /// The result as a run's.
    r: RunResult,
    /// The calibrator's log in f64 (after the final passes).
    records: Vec<LogRecord<f64>>,
    /// The session's restarts and messages ignored.
    restarts: u32,
    /// Messages the session ignored.
    ignored: u32,
}

/// The answer of the session after the stream: the final passes (unless
/// `--passes 1`), the truth sidecar and the bound of the samples received,
/// as a [`Calibration`].
fn answer<T: RealField + Copy>(
    args: &CalibrateArgs,
    input: &Input,
    host: &mut Host<T>,
    decoder: &FrameDecoder,
) -> Result<Calibration, Error> {
    let stats = *decoder.stats();
    if let (None, Some(v)) = (host.session.calibrator(), host.other_version) {
        return Err(format!(
            "the stream is of protocol version {v} ({} frames), this host-sim reads version {VERSION}: record it again with this version",
            stats.wrong_version
        )
        .into());
    }
    let Some(id) = host.session.calibrator().map(|c| c.settings().config) else {
        return Err(format!(
            "no samples in the stream ({} frames decoded, {} rejected)",
            stats.ok,
            stats.errors()
        )
        .into());
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
        )
        .into());
    };
    cal.set_frame_errors(stats.errors());
    let settings = *cal.settings();
    let layout = id.layout_with(settings.errors);
    if settings.errors == ErrorModel::Full && args.report.is_some() {
        return Err("--report is not available with --errors full yet".into());
    }
    let est = cal.estimate();
    // The running filter's covariance (the answer when the passes do not run).
    let running_covariance = crate::analysis::compensation::covariance_of_packed_ud(
        layout.n(),
        &cal.checkpoint().factor,
    );
    let p = est.progress;
    if p.accepted == 0 {
        return Err(format!(
            "no sample accepted ({} rejected, {} bad frames)",
            p.rejects.total(),
            stats.errors()
        )
        .into());
    }
    let sigma0 = runner::prior_sigma_of(&settings);
    let nan = vec![f64::NAN; layout.n()];
    let (start, truth_start, received_bound) = received(&settings, sidecar.as_ref(), &est, host)?;
    // The sidecar's bound is the installation model's: not the full model's.
    let crlb = received_bound
        .as_ref()
        .or(sidecar
            .as_ref()
            .map(|s| &s.crlb)
            .filter(|_| settings.errors == ErrorModel::Installation))
        .unwrap_or(&nan)
        .clone();
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
    let truth = sidecar
        .as_ref()
        .map_or_else(|| nan.clone(), |s| s.truth_of(settings.errors));
    let r = result(
        &settings,
        host,
        &est,
        fin.as_ref(),
        running_covariance,
        &truth,
        &sigma0,
    );
    let final_answer = fin
        .as_ref()
        .is_some_and(|f| matches!(f.estimate.kind, EstimateKind::Final { .. }));
    Ok(Calibration {
        id,
        settings,
        est,
        stats,
        format: input.format,
        sidecar,
        start,
        truth_start,
        received_bound,
        crlb,
        fin,
        final_answer,
        r,
        records: host.log.records_f64(),
        restarts: host.session.stats().restarts,
        ignored: host.session.stats().ignored,
    })
}

/// Where the log started on the path, the true state there (with a
/// sidecar and a complete log) and the bound of the samples actually
/// received: the bound over the same log (the bridged periods predicted
/// only) from that true state; `None` without one (no sidecar, or a log
/// that is not the whole run: then the full run's bound of the sidecar is
/// the one shown).
#[allow(clippy::type_complexity)]
fn received<T: RealField + Copy>(
    settings: &CalibratorConfig,
    sidecar: Option<&Sidecar>,
    est: &Estimate,
    host: &mut Host<T>,
) -> Result<(LogStart, Option<Vec<f64>>, Option<Vec<f64>>), Error> {
    let start = host.log_start()?;
    let records = host.log.records_f64();
    let truth_start = match (sidecar, est.progress.log_incomplete) {
        (Some(s), None) => truth_at_start(
            settings,
            &start,
            (s.truth0_of(settings.errors), &s.truth_of(settings.errors)),
            &records,
        )?,
        _ => None,
    };
    let sigma0 = runner::prior_sigma_of(settings);
    let bound = truth_start
        .as_deref()
        .map(|t0| {
            runner::bound(
                settings.config,
                settings.errors,
                FilterConfig::<f64>::from(settings),
                t0,
                &start,
                &sigma0,
                &records,
            )
            .map_err(|e| format!("Cramér–Rao bound of the received samples: {e}"))
        })
        .transpose()?;
    Ok((start, truth_start, bound))
}

/// The answer as a run's result: the final passes' estimate, σ,
/// covariance, innovations and history when they are the answer, else
/// pass 1's (with the running filter's covariance).
fn result<T: RealField + Copy>(
    settings: &CalibratorConfig,
    host: &Host<T>,
    est: &Estimate,
    fin: Option<&Final>,
    running_covariance: Vec<f64>,
    truth: &[f64],
    sigma0: &[f64],
) -> RunResult {
    let (state, sigma, nis, failures, passes) = match fin {
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
    let final_pass = fin.filter(|f| matches!(f.estimate.kind, EstimateKind::Final { .. }));
    runner::result(
        settings.config,
        settings.errors,
        &Passes {
            filter: Box::new(CalibratorView {
                state: state.to_vec(),
                sigma: sigma.to_vec(),
                covariance: match final_pass {
                    Some(f) => f.covariance.clone(),
                    None => running_covariance,
                },
            }),
            history: final_pass.map(|f| f.history.clone()).unwrap_or_default(),
            nis,
            updates: final_pass.map(|f| f.updates.clone()).unwrap_or_default(),
            segments: crate::sim::segments::command_segments(
                host.log.records.iter().map(|r| (r.dt, r.dtheta_cmd.into())),
            ),
            failures,
            passes,
        },
        truth,
        sigma0,
    )
}

/// Prints the table (against the truth, or with the bound at the estimate
/// and its verdict, never FAILED: docs/own-platform.md, "Judging a
/// calibration without a truth"), the data checks and the stream's counters; returns the
/// judgement and, without a truth, the bound at the estimate and its
/// verdicts.
#[allow(clippy::type_complexity)]
fn print_results(c: &Calibration) -> Result<(Judgement, Option<(Vec<f64>, Vec<Verdict>)>), Error> {
    let (id, r, p) = (c.id, &c.r, &c.est.progress);
    let at_estimate = if c.sidecar.is_none() {
        let records = &c.records;
        // A log that is not the whole run (re-acquired attitude, full log)
        // has no start of the final passes: the bound along the logged
        // records from the cold start (the prior estimate at the log's
        // start, as pass 1), said so.
        let x_start = if p.log_incomplete.is_some() {
            eprintln!(
                "note: the log is not the whole run: the bound is taken from the cold start along the {} logged samples only (of {} accepted)",
                records.len(),
                p.accepted
            );
            None
        } else {
            let end: Vec<f64> = r.states.iter().map(|s| s.estimate_rad).collect();
            Some(state_at_start(&c.settings, &c.start, &end, records)?)
        };
        let (b, v) = bound_at_estimate(&c.settings, &c.start, x_start.as_deref(), records)?;
        print_table_no_truth(r, &b, &v);
        Some((b, v))
    } else {
        print_table(r, &c.crlb);
        None
    };
    let judgement = checks::judge(r).with_path(checks::gimbal_lock_check(id, &c.records));
    print_judgement(&judgement);
    let rj = reject_json(&p.rejects);
    let frames = if c.format == Format::Csv {
        "CSV log".to_string()
    } else {
        format!(
            "{} frames ok, {} rejected {}",
            c.stats.ok,
            c.stats.errors(),
            frames_json(&c.stats)
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
    Ok((judgement, at_estimate))
}

/// The JSON of `--json`: `run`'s, with the passes, precision, bound,
/// answer, checks, pass 1 and the stream's counters.
fn json_of(
    args: &CalibrateArgs,
    c: &Calibration,
    judgement: &Judgement,
    at_estimate: Option<&(Vec<f64>, Vec<Verdict>)>,
) -> serde_json::Value {
    let (r, p, est, sidecar) = (&c.r, &c.est.progress, &c.est, &c.sidecar);
    let earth_rate = c.settings.earth_rate_n.iter().any(|v| *v != 0.0);
    let duration = sidecar
        .as_ref()
        .and_then(|s| s.duration_s)
        .unwrap_or(p.accepted as f64 * c.settings.limits.period_s);
    let mut json = run_json(
        r,
        sidecar.as_ref().and_then(|s| s.seed).unwrap_or(0),
        earth_rate,
        duration,
    );
    if sidecar.as_ref().and_then(|s| s.seed).is_none() {
        json["seed"] = serde_json::Value::Null;
    }
    json["passes"] = r.passes.into();
    json["precision"] = args.precision.as_str().into();
    json["crlb_sigma_rad"] = serde_json::json!(c.crlb);
    json["crlb_of"] = if c.received_bound.is_some() {
        "received samples"
    } else if sidecar.is_some() {
        "full run"
    } else {
        "none"
    }
    .into();
    json["answer"] = match c.fin.as_ref().map(|f| f.estimate.kind) {
        Some(EstimateKind::Final { passes, converged }) => {
            serde_json::json!({"kind": "final", "passes": passes, "converged": converged})
        }
        Some(EstimateKind::SinglePass { reason, logged }) => serde_json::json!({
            "kind": "single_pass", "reason": reason.to_string(), "logged": logged
        }),
        _ => serde_json::json!({"kind": "single_pass", "reason": "--passes 1"}),
    };
    if let Some((b, v)) = at_estimate {
        json["bound_at_estimate_sigma_rad"] = serde_json::json!(b);
        json["observability"] = serde_json::json!(v);
    }
    let j = judgement.json();
    json["checks"] = j["checks"].clone();
    json["path_check"] = j["path"].clone();
    json["data_verdict"] = j["data_verdict"].clone();
    json["data_false_alarm"] = j["false_alarm"].clone();
    if judgement.cause.is_some() {
        json["data_likely_cause"] = j["likely_cause"].clone();
    }
    json["pass1"] = serde_json::json!({
        "seq": est.seq,
        "updates": est.updates,
        "estimate_rad": est.state.to_vec(),
        "sigma_rad": est.sigma.to_vec(),
    });
    json["stream"] = serde_json::json!({
        "format": if c.format == Format::Csv { "csv" } else { "frames" },
        "frames": frames_json(&c.stats),
        "accepted": p.accepted,
        "bridged": p.bridged,
        "gated": p.gated,
        "rejects": reject_json(&p.rejects),
        "reacquired": p.reacquired,
        "reacquired_periods": p.reacquired_periods,
        "clock_steps": p.clock_steps,
        "restarts": c.restarts,
        "other_messages": c.ignored,
    });
    json
}

/// The HTML report of `--report DIR`.
fn report(
    args: &CalibrateArgs,
    c: &Calibration,
    judgement: &Judgement,
    dir: &std::path::Path,
) -> Result<(), Error> {
    let (id, r, p) = (c.id, &c.r, &c.est.progress);
    // σ_CRLB(t): the bound of the received samples, when computed.
    let crlb_history = match c.truth_start.as_ref() {
        Some(t0) if c.received_bound.is_some() => Some(
            runner::bound_history(
                id,
                ErrorModel::Installation,
                FilterConfig::<f64>::from(&c.settings),
                t0,
                &c.start,
                &[c.settings.prior_sigma_rad],
                &c.records,
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
                if c.format == Format::Csv {
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
                if c.final_answer { "final" } else { "pass 1" }
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
    let crlb = c.sidecar.as_ref().map(|_| c.crlb.as_slice());
    let page = crate::output::html::report_of_calibration(
        dir,
        r,
        crlb,
        crlb_history.as_deref(),
        c.sidecar.is_some(),
        judgement,
        header,
    )?;
    eprintln!("report: {}", page.display());
    Ok(())
}
