//! `host-sim checks`: false-alarm and detection rates of `calibrate`'s data
//! checks over seeds ([`crate::analysis::check_rates::rates`]): how often
//! each case is flagged, its likely cause named, its answer within 4σ.

use std::sync::atomic::{AtomicU64, Ordering};

use rollcal::models::ConfigId;

use super::args::load_scenario;
use super::Error;
use crate::analysis::check_rates::{all_cases, rates, Case, Rate, ANSWER_SIGMA};
use crate::analysis::checks::FALSE_ALARM;
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
    /// Only these cases (repeatable, or comma-separated; default: clean,
    /// noise, bias). The stream's defects: clean (the truth is the model),
    /// noise (accelerometer noise 3× the platform's), bias (an unmodelled
    /// accelerometer bias, --bias-ug). A term of the truth the model (the
    /// scenario as the platform file) leaves out, everything else matched:
    /// k2 (10 µg/g² on every accelerometer; sigma_k2_ug_g2 = 0), accel-rw
    /// (a bias random walk of 1 µg/√h; accel_random_walk_ug_rt_h = 0),
    /// warmup (an accelerometer warm-up of 2 µg, τ 1200 s; accel_warmup_ug
    /// = 0), gyro-instability (a Gauss–Markov drift of 0.005 °/h;
    /// gyro_bias_instability_deg_h = 0); creep (an accelerometer bias
    /// creeping linearly by 2 µg over the log: a term no model has). Give
    /// them --errors full and --scenario scenarios/realistic.toml.
    #[arg(long = "case", value_name = "CASE", value_delimiter = ',', value_parser = CASE_KEYS)]
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

/// The `--case` names, in the table's order.
const CASE_KEYS: [&str; 8] = [
    "clean",
    "noise",
    "bias",
    "k2",
    "accel-rw",
    "warmup",
    "gyro-instability",
    "creep",
];

/// The cases run without `--case`.
const DEFAULT_CASES: [&str; 3] = ["clean", "noise", "bias"];

/// `host-sim checks`: false-alarm and detection rates of
/// [`crate::analysis::checks::judge`] over
/// seeds, in process (simulate, defect, estimate, judge, diagnose; no files).
pub fn command(args: &ChecksArgs) -> Result<(), Error> {
    let scenario = load_scenario(args.scenario.as_deref())?;
    let cases: Vec<Case> = all_cases(args.bias_ug)
        .into_iter()
        .filter(|c| {
            if args.cases.is_empty() {
                DEFAULT_CASES.contains(&c.key)
            } else {
                args.cases.iter().any(|k| k == c.key)
            }
        })
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
    print_table(&out, args.bias_ug);
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

/// The rates as a table, then every flagged clean seed and every seed
/// judged consistent with a state beyond 4σ.
fn print_table(out: &[Rate], b: [f64; 3]) {
    let pct =
        |n: usize, of: usize| format!("{n}/{of} {:.1} %", 100.0 * n as f64 / of.max(1) as f64);
    println!(
        "{:<36} {:>5} {:>14} {:>14} {:>14} {:>10}   {:>5} {:>9} {:>5} {:>8}  errors",
        "case",
        "seeds",
        "flagged",
        "cause named",
        "within 4σ",
        "cons. >4σ",
        "nis",
        "whiteness",
        "bias",
        "left_out"
    );
    for r in out {
        let label = if r.key == "bias" {
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
        let named = if r.key == "clean" {
            "-".to_string()
        } else {
            pct(r.named, r.seeds)
        };
        println!(
            "{:<36} {:>5} {:>14} {:>14} {:>14} {:>10}   {:>5} {:>9} {:>5} {:>8}  {}",
            label,
            r.seeds,
            pct(r.flagged, r.seeds),
            named,
            pct(r.within_4_sigma, r.seeds),
            r.consistent_beyond_4_sigma.len(),
            by("nis"),
            by("whiteness"),
            by("bias"),
            by("left_out"),
            r.errors
        );
    }
    println!(
        "(cause named: the warning's likely cause names the case's defect; within 4σ: every state of the answer (the nuisances, attitude, Gauss–Markov parts and warm-ups, apart) within {ANSWER_SIGMA}σ of the persistent truth at the end of the log; cons. >4σ: judged consistent with a state beyond; nis, whiteness, bias, left_out: in how many seeds that check failed)"
    );
    for r in out {
        for (cause, n) in &r.causes {
            println!("{}: {n} × likely cause: {cause}", r.key);
        }
        if r.key == "clean" {
            for (seed, what) in &r.flagged_seeds {
                println!("clean seed {seed} flagged: {what}");
            }
        }
        for (seed, state, ratio, flagged) in &r.beyond_4_sigma {
            let verdict = if *flagged { "flagged" } else { "consistent" };
            println!("{} seed {seed} {verdict}, {state} {ratio:.2}σ off", r.key);
        }
        for (seed, state, ratio, flagged) in &r.nuisance_beyond_4_sigma {
            let verdict = if *flagged { "flagged" } else { "consistent" };
            println!(
                "{} seed {seed} {verdict}, nuisance {state} {ratio:.2}σ off (not the answer)",
                r.key
            );
        }
    }
}
