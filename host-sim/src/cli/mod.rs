//! The command line of `host-sim`: the clap root, the dispatch to one
//! driver per subcommand, and the one place where an error becomes the
//! one-line message `host-sim: error: …` and an exit status.
//!
//! Each subcommand has its own file holding its arguments and its driver;
//! the drivers (with the table and report writers they call) are the only
//! code of the crate that prints.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

pub mod args;
pub mod calibrate;
pub mod checks;
pub mod design;
pub mod matrices;
pub mod montecarlo;
pub mod observability;
pub mod paper;
pub mod record;
pub mod remedies;
pub mod run;
pub mod summary;

/// The error of a subcommand: any error of the library's layers (or a
/// message), printed by [`main`] as one line, `host-sim: error: …`.
pub type Error = Box<dyn std::error::Error>;

/// A result that is not an answer and has nothing to write (e.g. no sample
/// accepted): printed as `host-sim: error: not an answer: …`, exit status
/// [`crate::analysis::calibration::trust::NO_ANSWER_EXIT`].
#[derive(Debug)]
pub struct NoAnswer(pub String);

impl std::fmt::Display for NoAnswer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "not an answer: {}", self.0)
    }
}

impl std::error::Error for NoAnswer {}

#[derive(Parser)]
#[command(
    name = "host-sim",
    version,
    about = "Truth simulator and estimator runs for rollcal (continuous rolling self-calibration)",
    long_about = "Truth simulator and estimator runs for rollcal.\n\n\
        Without a subcommand, regenerates the whole paper (`paper`): observability tables, \
        all seven estimator runs on the paper's scenario (docs/model.md §The paper's scenario), figures and a summary \
        in ./paper-out/."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Run one configuration's estimator on a scenario and print the final table.
    Run(run::RunArgs),
    /// Run all seven configurations and print one summary line each.
    Summary(args::CommonArgs),
    /// Compare the cold-start remedies over seeds and scenarios (the study
    /// behind the default estimator; see docs/estimator.md, "The cold start").
    Remedies(remedies::RemediesArgs),
    /// Observability of all seven configurations along the scenario's path:
    /// rank, unobservable combinations, Cramér–Rao σ and verdict per state.
    Observability(observability::ObservabilityArgs),
    /// Seeded Monte Carlo runs of one configuration in parallel: RMS error
    /// against the Cramér–Rao bound, parameter-block NEES and NIS.
    Montecarlo(montecarlo::MonteCarloArgs),
    /// Design the rolling path: the shortest sequence of constant-rate
    /// rotations (each optionally followed by a dwell) whose Cramér–Rao σ
    /// reaches every target (default: the reference path's final σ), or the
    /// best within --budget-s; writes it as a scenario file and a σ(t)
    /// figure.
    Design(Box<design::DesignArgs>),
    /// Simulate a scenario and write it as a stream of wire frames
    /// (docs/wire.md) or, with --format csv, as a CSV log (docs/csv.md).
    Record(record::RecordArgs),
    /// Run the calibrator on a frame stream from a file, stdin or a serial
    /// port, or on a CSV log with a platform file (docs/csv.md).
    Calibrate(calibrate::CalibrateArgs),
    /// False-alarm and detection rates of calibrate's data checks (without a
    /// truth) over seeds: a clean stream, accelerometer noise 3×, an
    /// unmodelled accelerometer bias.
    Checks(checks::ChecksArgs),
    /// The whole paper regenerated (the default): observability tables with
    /// the Earth rate on and off, all seven estimator runs, one PNG figure
    /// per configuration and parameter group, summary.md and summary.json.
    Paper(paper::PaperArgs),
}

/// `host-sim`: parses the command line, runs the subcommand (`paper`
/// without one) and turns its outcome into the exit status: 0, 1 with the
/// one-line message `host-sim: error: …` on stderr,
/// [`crate::analysis::checks::WARNING_EXIT`] when `calibrate`'s data checks
/// warn, [`crate::analysis::calibration::trust::NO_ANSWER_EXIT`] when its
/// result is not an answer (2, bad arguments, is clap's).
pub fn main() -> ExitCode {
    // Die quietly on a closed pipe (`host-sim | head`) like other Unix tools,
    // instead of panicking in println!.
    #[cfg(unix)]
    // SAFETY: called first thing in main, before any thread exists; resets a
    // signal disposition to its default.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Run(args)) => run::command(&args),
        Some(Command::Summary(args)) => summary::command(&args),
        Some(Command::Remedies(args)) => remedies::command(&args),
        Some(Command::Observability(args)) => observability::command(&args),
        Some(Command::Montecarlo(args)) => montecarlo::command(&args),
        Some(Command::Paper(args)) => paper::command(&args),
        Some(Command::Design(args)) => design::command(&args).map_err(Error::from),
        Some(Command::Record(args)) => record::command(&args),
        Some(Command::Calibrate(args)) => match calibrate::command(&args) {
            // A data-model warning or a result that is not an answer: their
            // own exit statuses (docs/own-platform.md, "Exit status").
            Ok(status) => return ExitCode::from(status),
            Err(e) => Err(e),
        },
        Some(Command::Checks(args)) => checks::command(&args),
        None => paper::command(&paper::PaperArgs {
            scenario: None,
            seed: 1,
            out: PathBuf::from("paper-out"),
            errors: rollcal::models::ErrorModel::Installation,
        }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("host-sim: error: {e}");
            if e.is::<NoAnswer>() {
                ExitCode::from(crate::analysis::calibration::trust::NO_ANSWER_EXIT)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}
