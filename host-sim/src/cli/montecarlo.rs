//! `host-sim montecarlo`: seeded Monte Carlo runs of one configuration in
//! parallel against the Cramér–Rao bound ([`crate::analysis::montecarlo`]).

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

use rollcal::models::{ConfigId, ErrorModel};

use super::args::{load_scenario, parse_config, parse_errors};
use super::Error;
use crate::analysis::montecarlo::{monte_carlo, Consistency, MonteCarlo};
use crate::analysis::remedies::Remedy;
use crate::analysis::runner::{Estimator, Precision};
use crate::output::progress::Progress;
use crate::output::report::write_json;
use crate::output::report::UNIT_WIDTH;
use crate::sim::instruments::{printed_unit, printed_value};

/// Arguments of `host-sim montecarlo`.
#[derive(clap::Args)]
pub struct MonteCarloArgs {
    /// Configuration: M1-pa, M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps (case-insensitive).
    #[arg(long, value_parser = parse_config)]
    pub config: ConfigId,
    /// Number of runs (seeds 1..=N).
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u64).range(2..=100_000))]
    pub runs: u64,
    /// Scenario file (TOML); default: the paper's scenario.
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Precision of the filter's covariance arithmetic (state, nominal and
    /// residuals are f64 in both).
    #[arg(long, value_enum, default_value_t = Precision::F64)]
    pub precision: Precision,
    /// Error model of the estimator: `installation` or `full` (with the
    /// instruments' own errors; docs/model.md §Full model).
    #[arg(long, default_value = "installation", value_parser = parse_errors)]
    pub errors: ErrorModel,
    /// At most this many passes over the data (default: the estimator of
    /// record's); `--passes 1` judges the running filter, what the
    /// calibrator reports while a run goes on.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=16))]
    pub passes: Option<u8>,
    /// The running filter's cold-start remedy (docs/estimator.md, "The
    /// cold start"; `remedies` compares them): the default is the
    /// estimator of record's.
    #[arg(long, value_enum, default_value_t = Remedy::SecondOrder)]
    pub remedy: Remedy,
    /// Write the statistics as JSON to PATH.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
}

/// `host-sim montecarlo`.
pub fn command(args: &MonteCarloArgs) -> Result<(), Error> {
    let scenario = load_scenario(args.scenario.as_deref())?;
    super::args::note_instrument_prior(&scenario, args.errors);
    let runs = usize::try_from(args.runs).map_err(|e| e.to_string())?;
    eprintln!(
        "{} runs of {} on '{}' with {} threads…",
        runs,
        args.config,
        scenario.name,
        rayon::current_num_threads()
    );
    let progress = Progress::stderr("montecarlo", args.runs, "runs");
    let done = AtomicU64::new(0);
    let mc = monte_carlo(
        args.config,
        args.errors,
        &scenario,
        runs,
        Estimator {
            precision: args.precision,
            passes: args.passes.unwrap_or(Estimator::default().passes),
            options: args.remedy.options(),
        },
        &|n| {
            done.fetch_max(n as u64, Ordering::Relaxed);
            progress.update(n as u64, "");
        },
    );
    progress.finish(done.load(Ordering::Relaxed), "");
    let mc = mc?;
    print_monte_carlo(&mc);
    if let Some(path) = &args.json {
        let v = serde_json::to_value(&mc).map_err(|e| e.to_string())?;
        write_json(path, &v)?;
    }
    Ok(())
}

/// Prints the Monte Carlo table.
fn print_monte_carlo(mc: &MonteCarlo) {
    let errors = match mc.errors {
        ErrorModel::Installation => String::new(),
        e => format!(", {} model", e.as_str()),
    };
    println!(
        "{} Monte Carlo ({}{errors}): {} runs (seeds 1..={}), {:.1} s wall",
        mc.config,
        mc.precision.as_str(),
        mc.runs,
        mc.runs,
        mc.wall_s
    );
    println!(
        "{:<10} {:<UNIT_WIDTH$} {:>11} {:>11} {:>11} {:>11} {:>9}  block",
        "state", "unit", "RMS err", "mean err", "mean σ", "σ_CRLB", "RMS/CRLB"
    );
    for s in &mc.states {
        // Every state in its printed unit, named in the unit column.
        let show = |v: f64| printed_value(s.info.group, v);
        println!(
            "{:<10} {:<UNIT_WIDTH$} {:>11.4} {:>11.4} {:>11.4} {:>11.4} {:>9.3}  {}",
            s.name,
            printed_unit(s.info.group),
            show(s.rms_error_rad),
            show(s.mean_error_rad),
            show(s.mean_sigma_rad),
            show(s.sigma_crlb_rad),
            s.rms_over_crlb,
            if s.in_parameter_block { "yes" } else { "" }
        );
    }
    let show = |name: &str, c: &Consistency| {
        println!(
            "{name}: average {:.3} (dof {} × {} samples), 95 % band [{:.3}, {:.3}]: {}",
            c.mean,
            c.dof,
            c.samples,
            c.lower,
            c.upper,
            if c.inside() { "inside" } else { "OUTSIDE" }
        );
    };
    show("parameter-block NEES", &mc.nees);
    show("NIS (final pass)", &mc.nis);
    println!(
        "worst |error|/σ over the parameter block: {:.2} ({} of seed {}, {} passes)",
        mc.max_normalised_error, mc.worst.1, mc.worst.0, mc.worst.2
    );
}
