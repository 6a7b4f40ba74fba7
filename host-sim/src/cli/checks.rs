//! `host-sim checks`: false-alarm and detection rates of `calibrate`'s data
//! checks over seeds ([`crate::analysis::checks::rates`]), and the printed
//! table of one judgement.

use std::sync::atomic::{AtomicU64, Ordering};

use rollcal::models::ConfigId;

use super::args::load_scenario;
use super::Error;
use crate::analysis::checks::{cases, rates, Case, FALSE_ALARM};
use crate::output::progress::Progress;
use crate::output::report::write_json;

/// `--config` of `checks`: core's `FromStr for ConfigId`, with the short
/// message this subcommand has always given.
fn parse_config_short(s: &str) -> Result<ConfigId, String> {
    s.parse::<ConfigId>()
        .map_err(|_| format!("unknown configuration '{s}'"))
}

/// Arguments of `host-sim checks`.
#[derive(clap::Args, Clone, Debug)]
pub struct ChecksArgs {
    /// Configuration: M1-pa, M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps.
    #[arg(long, value_parser = parse_config_short)]
    pub config: rollcal::models::ConfigId,
    /// Error model of the estimator: `installation` (the paper's) or
    /// `full` (the instruments' own errors too).
    #[arg(long, default_value = "installation", value_parser = super::args::parse_errors)]
    pub errors: rollcal::models::ErrorModel,
    /// Seeds 1..=N of every case.
    #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    pub seeds: u64,
    /// Scenario file (TOML); default: the paper's scenario.
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<std::path::PathBuf>,
    /// The unmodelled bias of the bias case (µg per axis, instrument frame).
    #[arg(long, value_name = "X,Y,Z", default_value = "10,10,10", value_parser = parse_bias, allow_hyphen_values = true)]
    pub bias_ug: [f64; 3],
    /// Only these cases (repeatable): clean, noise, bias (default: all three).
    #[arg(long = "case", value_name = "CASE", value_parser = ["clean", "noise", "bias"])]
    pub cases: Vec<String>,
    /// Also write the rates as JSON to PATH.
    #[arg(long, value_name = "PATH")]
    pub json: Option<std::path::PathBuf>,
}

fn parse_bias(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{s}' is not X,Y,Z"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([*x, *y, *z]),
        _ => Err(format!("'{s}' is not X,Y,Z (three finite numbers)")),
    }
}

/// `host-sim checks`: false-alarm and detection rates of
/// [`crate::analysis::checks::judge`] over
/// seeds, in process (simulate, defect, estimate, judge; no files).
pub fn command(args: &ChecksArgs) -> Result<(), Error> {
    let scenario = load_scenario(args.scenario.as_deref())?;
    let keys = ["clean", "noise", "bias"];
    let cases: Vec<Case> = cases(args.bias_ug)
        .into_iter()
        .zip(keys)
        .filter(|(_, k)| args.cases.is_empty() || args.cases.iter().any(|c| c == k))
        .map(|(c, _)| c)
        .collect();
    let total = args.seeds * cases.len() as u64;
    eprintln!(
        "{} runs of {} on '{}' ({} cases × {} seeds) with {} threads…",
        total,
        args.config,
        scenario.name,
        cases.len(),
        args.seeds,
        rayon::current_num_threads()
    );
    let progress = Progress::stderr("checks", total, "runs");
    let done = AtomicU64::new(0);
    super::args::note_instrument_prior(&scenario, args.errors);
    let out = rates(
        args.config,
        args.errors,
        &scenario,
        args.seeds,
        &cases,
        &|| {
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress.update(n, "");
        },
    );
    progress.finish(done.load(Ordering::Relaxed), "");
    let b = args.bias_ug;
    println!(
        "{}{} on '{}', seeds 1..={}; the estimator told the scenario's noise; judgement at a stated false-alarm rate of {FALSE_ALARM}",
        args.config,
        match args.errors {
            rollcal::models::ErrorModel::Full => " (full model)",
            _ => "",
        },
        scenario.name,
        args.seeds
    );
    println!(
        "{:<28} {:>8} {:>14}   {:>5} {:>9} {:>5}  errors",
        "case", "seeds", "flagged", "nis", "whiteness", "bias"
    );
    for r in &out {
        let label = if r.case == "accel bias" {
            format!("accel bias ({}, {}, {}) µg", b[0], b[1], b[2])
        } else {
            r.case.clone()
        };
        let by = |n: &str| {
            r.by_check
                .iter()
                .find(|(k, _)| *k == n)
                .map_or(0, |(_, v)| *v)
        };
        println!(
            "{:<28} {:>8} {:>14}   {:>5} {:>9} {:>5}  {}",
            label,
            r.seeds,
            format!(
                "{}/{} {:.1} %",
                r.flagged,
                r.seeds,
                100.0 * r.flagged as f64 / r.seeds.max(1) as f64
            ),
            by("nis"),
            by("whiteness"),
            by("bias"),
            r.errors
        );
    }
    println!("(nis, whiteness, bias: in how many seeds that check failed)");
    if let Some(clean) = out.iter().find(|r| r.case == "clean") {
        for (seed, what) in &clean.flagged_seeds {
            println!("clean seed {seed} flagged: {what}");
        }
    }
    if let Some(path) = &args.json {
        let v = serde_json::json!({
            "config": args.config.as_str(),
            "errors": args.errors.as_str(),
            "scenario": scenario.name,
            "seeds": args.seeds,
            "false_alarm": FALSE_ALARM,
            "bias_ug": args.bias_ug,
            "rates": out,
        });
        write_json(path, &v)?;
    }
    if out.iter().any(|r| r.errors > 0) {
        return Err("some runs failed (see the errors column)".into());
    }
    Ok(())
}
