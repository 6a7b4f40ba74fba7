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
//! The driver goes in steps: the settings of the input
//! ([`crate::io::input`]), the stream read into the session (`feed`), the
//! answer of the session ([`Calibration`], everything the outputs need,
//! computed once), then the printed results, the JSON and the HTML report
//! ([`crate::output::calibration`]).

use std::path::PathBuf;
use std::time::{Duration, Instant as Clock};

use std::io::Write;

use nalgebra::RealField;
use rollcal::models::{ConfigId, ErrorModel};
use rollcal::session::Request;
use rollcal::wire::{FrameDecoder, FrameError, Message};

use super::args::parse_config;
use super::{Error, NoAnswer};
use crate::analysis::calibration::rejects::SampleSource;
use crate::analysis::calibration::trust::NO_ANSWER_EXIT;
use crate::analysis::calibration::{
    platform_config, Calibration, CalibrationError, Context, Host, LogStorage,
};
use crate::analysis::checks::WARNING_EXIT;
use crate::analysis::runner::Precision;
use crate::io::input::{CsvInput, Input, InputOptions};
use crate::io::replies::{ReplySink, ReplyTarget};
use crate::io::sidecar::read_sidecar;
use crate::io::stream::{is_device, read_input, write_device, Format};
use crate::output::calibration::{json, report_header, write_findings, write_results, Source};
use crate::output::progress::Progress;
use crate::output::report::write_json;

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
    /// Send the calibrator's replies as wire frames (docs/wire.md): the
    /// periodic Estimates, the answer to every request (EstimateRequest,
    /// CheckpointRequest, Finish) and the refusals (Refused), and at the
    /// end of the input the answer to a Finish unless one was answered: to
    /// a file, to standard output (`-`; the tables then go to standard
    /// error) or back on the serial device of --input (`serial`).
    #[arg(long, value_name = "PATH|-|serial", value_parser = crate::io::replies::parse_target)]
    pub replies: Option<ReplyTarget>,
}

/// `host-sim calibrate`, returning its exit status: 0 an answer whose data
/// fit the model, [`WARNING_EXIT`] an answer with a data warning,
/// [`NO_ANSWER_EXIT`] a result that is not an answer (the reasons printed;
/// the outputs still written); errors are 1 ([`super::main`]).
pub fn command(args: &CalibrateArgs) -> Result<u8, Error> {
    check_options(args)?;
    match args.precision {
        Precision::F64 => calibrate_in::<f64>(args),
        Precision::F32 => calibrate_in::<f32>(args),
    }
}

/// Refuses, before any input is read, an option combination that cannot
/// be served: replies back on a serial device that is not the input, binary
/// replies into a terminal, a report directory that is a file, an output
/// whose directory does not exist.
fn check_options(args: &CalibrateArgs) -> Result<(), Error> {
    use std::io::IsTerminal;
    match &args.replies {
        Some(ReplyTarget::Serial) if !is_device(&args.input) => {
            return Err(format!(
                "--replies serial writes back on the serial device of --input, and {} is not one",
                args.input
            )
            .into())
        }
        Some(ReplyTarget::Stdout) if std::io::stdout().is_terminal() => {
            return Err(
                "--replies - writes binary frames: redirect or pipe stdout, or give --replies FILE"
                    .into(),
            )
        }
        _ => {}
    }
    if let Some(dir) = args.report.as_ref().filter(|d| d.exists() && !d.is_dir()) {
        return Err(format!("--report {}: exists and is not a directory", dir.display()).into());
    }
    let files = [
        ("--json", args.json.as_deref()),
        ("--matrices", args.matrices.matrices.as_deref()),
        ("--matrices-txt", args.matrices.matrices_txt.as_deref()),
        ("--report", args.report.as_deref()),
        (
            "--replies",
            match &args.replies {
                Some(ReplyTarget::File(p)) => Some(p.as_path()),
                _ => None,
            },
        ),
    ];
    for (opt, path) in files {
        let Some(path) = path else { continue };
        let parent = path.parent().filter(|p| !p.as_os_str().is_empty());
        if let Some(dir) = parent.filter(|d| !d.is_dir()) {
            return Err(format!(
                "{opt} {}: the directory {} does not exist",
                path.display(),
                dir.display()
            )
            .into());
        }
    }
    Ok(())
}

/// `host-sim calibrate` with the calibrator's covariance arithmetic in `T`:
/// the session opened, the input read into it, its answer, then what is
/// printed and written, and the exit status.
fn calibrate_in<T: RealField + Copy>(args: &CalibrateArgs) -> Result<u8, Error> {
    let t0 = Clock::now();
    let (input, mut host, csv) = open::<T>(args)?;
    let mut replies = ReplySink::open(args.replies.as_ref())?;
    let mut decoder = FrameDecoder::new();
    let lines = csv.as_ref().map(|c| (c.lines.clone(), c.has_gimbal));
    feed(args, &input, &mut host, &mut decoder, &mut replies, csv)?;
    let ctx = Context {
        passes: args.passes,
        source: SampleSource {
            lines: lines.as_ref().map(|l| l.0.as_slice()),
            has_gimbal: lines.as_ref().map(|l| l.1),
        },
        latitude_deg: Some(input.platform.site.latitude_deg),
    };
    let mut out = console(args);
    let c = answer(args, &mut host, &decoder, &ctx, &mut out)?;
    // The answer to a Finish, unless the stream's last one was answered.
    if args.replies.is_some() && !host.finished {
        let back = replies.send(&host.handle(Request::Finish.message())?)?;
        if !back.is_empty() {
            write_device(&args.input, args.baud, &back)?;
        }
    }
    let src = Source {
        input: &args.input,
        format: input.format,
        precision: args.precision.as_str(),
        truth: args.truth.as_deref(),
        replies: args.replies.as_ref().map(|_| replies.frames),
    };
    write_results(&mut out, &c, &src)?;
    eprintln!("done in {:.2} s", t0.elapsed().as_secs_f64());
    write_outputs(args, &c, &src, &mut out)?;
    Ok(exit_status(&c))
}

/// The input and its settings, the host's session for them, and the
/// samples of a CSV log (read whole).
fn open<T: RealField + Copy>(
    args: &CalibrateArgs,
) -> Result<(Input, Host<T>, Option<CsvInput>), Error> {
    let input = Input::resolve(&InputOptions {
        path: &args.input,
        format: args.format,
        platform: args.platform.as_deref(),
        scenario: args.scenario.as_deref(),
        config: args.config,
        errors: args.errors,
    })?;
    let fallback = input.expected.map(|id| {
        platform_config(
            &input.platform,
            id,
            input.errors.unwrap_or_default(),
            input.platform.site.earth_rate,
        )
    });
    let mut host = Host::<T>::new(input.expected, fallback, input.source.clone(), args.passes);
    host.errors = args.errors;
    host.log.storage = args.log;
    let runs = input.expected.map_or_else(
        || "the stream's configuration".to_string(),
        |id| id.to_string(),
    );
    eprintln!("calibrating {runs} from {}…", args.input);
    let csv = if input.format == Format::Csv {
        let csv = input.read_csv(host.fallback)?;
        if let Some(note) = &csv.ignored_note {
            eprintln!("{note}");
        }
        eprintln!("settings of {}", input.source);
        Some(csv)
    } else {
        None
    };
    Ok((input, host, csv))
}

/// The session's answer after the stream (the truth sidecar read now:
/// `record --truth T | calibrate --truth T` works); with no sample
/// accepted, the rejected samples by reason printed and [`NoAnswer`].
fn answer<T: RealField + Copy>(
    args: &CalibrateArgs,
    host: &mut Host<T>,
    decoder: &FrameDecoder,
    ctx: &Context<'_>,
    out: &mut dyn Write,
) -> Result<Calibration, Error> {
    let stats = *decoder.stats();
    let id = host.configured(&stats)?;
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
    match Calibration::of(host, stats, sidecar, ctx) {
        Ok(c) => {
            for note in &c.notes {
                eprintln!("{note}");
            }
            Ok(c)
        }
        Err(e @ CalibrationError::NoneAccepted { .. }) => {
            if let CalibrationError::NoneAccepted { findings, .. } = &e {
                write_findings(out, findings)?;
            }
            Err(NoAnswer(e.to_string()).into())
        }
        Err(e) => Err(e.into()),
    }
}

/// The exit status of calibration `c`: [`NO_ANSWER_EXIT`] (its first
/// reason printed as the one-line error, with a data warning's likely
/// cause), else [`WARNING_EXIT`] on a data warning, else 0.
fn exit_status(c: &Calibration) -> u8 {
    let warning = c.judgement.verdict.is_warning();
    let Some(first) = c.not_an_answer.first() else {
        return if warning { WARNING_EXIT } else { 0 };
    };
    let more = match c.not_an_answer.len() - 1 {
        0 => String::new(),
        n => format!(" (and {n} more reason(s), the `answer:` lines above)"),
    };
    let data = match (&c.judgement.cause, warning) {
        (Some(cause), true) => format!(
            "; the data warning's likely cause: {}",
            cause.trim_start_matches("likely cause: ")
        ),
        _ => String::new(),
    };
    eprintln!("host-sim: error: not an answer: {first}{more}{data}");
    NO_ANSWER_EXIT
}

/// Where the tables go: standard output, or standard error when the
/// replies take standard output.
fn console(args: &CalibrateArgs) -> Box<dyn Write> {
    if args.replies == Some(ReplyTarget::Stdout) {
        Box::new(std::io::stderr())
    } else {
        Box::new(std::io::stdout())
    }
}

/// Writes every output asked for (`--json`, `--matrices`, `--report`), each
/// whatever became of the others; the first failure is returned after all
/// were tried, every one printed. A report directory that could not be
/// written is not left behind empty.
fn write_outputs(
    args: &CalibrateArgs,
    c: &Calibration,
    src: &Source<'_>,
    out: &mut dyn Write,
) -> Result<(), Error> {
    let mut failed: Vec<String> = Vec::new();
    if let Some(path) = &args.json {
        if let Err(e) = write_json(path, &json(c, src)) {
            failed.push(e);
        }
    }
    if let Err(e) = args.matrices.write_to(&c.r, out) {
        failed.push(e.to_string());
    }
    if let Some(dir) = &args.report {
        match report(c, src, dir) {
            Ok(page) => eprintln!("report: {}", page.display()),
            Err(e) => failed.push(e.to_string()),
        }
    }
    for e in failed.iter().skip(1) {
        eprintln!("host-sim: error: {e}");
    }
    match failed.into_iter().next() {
        Some(e) => Err(e.into()),
        None => Ok(()),
    }
}

/// The HTML report of `--report DIR`: the directory is created here, and
/// removed again when it stayed empty because the report failed.
fn report(c: &Calibration, src: &Source<'_>, dir: &std::path::Path) -> Result<PathBuf, Error> {
    let existed = dir.exists();
    let result = (|| -> Result<PathBuf, Error> {
        let crlb_history = c.crlb_history()?;
        let crlb = c.sidecar.as_ref().map(|_| c.crlb.as_slice());
        Ok(crate::output::html::report_of_calibration(
            dir,
            c,
            crlb,
            crlb_history.as_deref(),
            report_header(c, src),
        )?)
    })();
    if result.is_err() && !existed {
        let _ = std::fs::remove_dir(dir);
    }
    result
}

/// [`Host::handle`], then its notes printed; the replies sent.
fn handle<T: RealField + Copy>(
    host: &mut Host<T>,
    replies: &mut ReplySink,
    m: Message,
) -> Result<Vec<u8>, String> {
    let result = host.handle(m);
    for note in host.notes.drain(..) {
        eprintln!("{note}");
    }
    let msgs = result.map_err(|e| e.to_string())?;
    replies.send(&msgs).map_err(|e| e.to_string())
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
/// samples (`csv`), else the frames of the input, with the progress line;
/// the replies sent as they come.
fn feed<T: RealField + Copy>(
    args: &CalibrateArgs,
    input: &Input,
    host: &mut Host<T>,
    decoder: &mut FrameDecoder,
    replies: &mut ReplySink,
    csv: Option<CsvInput>,
) -> Result<(), Error> {
    // The expected number of samples: the log's, else the platform's
    // (scenario's) periods.
    let total = csv
        .as_ref()
        .map_or(input.platform.periods(), |c| c.samples.len()) as u64;
    let progress = Progress::stderr("calibrate", total, "samples accepted");
    let idle = Duration::from_secs_f64(args.idle_timeout.max(0.1));
    let csv_read = csv.is_some();
    let read = match csv {
        // Driven exactly as a frame stream: the Configure, then the samples.
        Some(csv) => {
            let mut result = handle(host, replies, Message::Configure(csv.settings)).map(|_| ());
            for (k, s) in csv.samples.into_iter().enumerate() {
                if result.is_err() {
                    break;
                }
                result = handle(host, replies, Message::Sample(s)).map(|_| ());
                if k % 256 == 0 {
                    let (accepted, text) = detail(host, decoder);
                    progress.update(accepted, &text);
                }
            }
            result
        }
        None => read_input(&args.input, args.baud, idle, |bytes| {
            let mut result = Ok(Vec::new());
            decoder.feed_results(bytes, |r| match r {
                Ok(m) => {
                    if let Ok(back) = &mut result {
                        match handle(host, replies, m) {
                            Ok(b) => back.extend(b),
                            Err(e) => result = Err(e),
                        }
                    }
                }
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
