//! `host-sim observability`: the observability of all seven
//! configurations along a scenario's path, as text tables, the verdict
//! matrix, what the Earth rate changes, and JSON.

use std::path::PathBuf;
use std::time::Instant;

use rollcal::models::ErrorModel;
use rollcal::observability::{COEF_THRESHOLD, PRACTICAL_RATIO, RANK_TOLERANCE};

use super::args::{load_scenario, parse_errors};
use super::Error;
use crate::analysis::observe::{
    analyse_all_with, changes, format_combination, report_json, verdict_matrix_markdown, ConfigObs,
};
use crate::output::report::write_json;
use crate::output::report::UNIT_WIDTH;
use crate::sim::instruments::{printed_unit, printed_value};

/// Arguments of `host-sim observability`.
#[derive(clap::Args)]
pub struct ObservabilityArgs {
    /// Scenario file (TOML); default: the paper's scenario.
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Switch the Earth rate off (the paper's assumption in its proofs).
    #[arg(long)]
    pub no_earth_rate: bool,
    /// Write the analysis as JSON to PATH.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// Error model: `installation` (the paper's states) or `full` (followed
    /// by the instruments' 21 errors, with the scenario's
    /// `[instruments.prior]`; docs/model.md §Full model).
    #[arg(long, default_value = "installation", value_parser = parse_errors)]
    pub errors: ErrorModel,
}

/// `host-sim observability`.
pub fn command(args: &ObservabilityArgs) -> Result<(), Error> {
    let scenario = load_scenario(args.scenario.as_deref())?;
    super::args::note_instrument_prior(&scenario, args.errors);
    let earth_rate = !args.no_earth_rate && scenario.site.earth_rate;
    let t0 = Instant::now();
    let model = match args.errors {
        ErrorModel::Installation => String::new(),
        e => format!(", {} model", e.as_str()),
    };
    eprintln!(
        "analysing 7 configurations along '{}' (Earth rate {}{model})…",
        scenario.name,
        if earth_rate { "on" } else { "off" }
    );
    let configs = analyse_all_with(&scenario, args.errors, earth_rate)?;
    print_report(&configs, earth_rate);
    println!(
        "
Verdicts (x y z per group; yes: observable in practice, weak: σ_CRLB/σ_prior ≥ 0.01, no: in the null space):\n"
    );
    print!("{}", verdict_matrix_markdown(&configs));
    if earth_rate {
        let off = analyse_all_with(&scenario, args.errors, false)?;
        let lines = changes(&off, &configs);
        println!("\nWhat the Earth rate changes (against the paper's Earth-off analysis):");
        if lines.is_empty() {
            println!("  nothing");
        }
        for l in lines {
            println!("  {l}");
        }
    }
    eprintln!("done in {:.2} s", t0.elapsed().as_secs_f64());
    if let Some(path) = &args.json {
        write_json(path, &report_json(earth_rate, &configs))?;
    }
    Ok(())
}

/// Prints the analysis of every configuration as text tables.
fn print_report(configs: &[ConfigObs], earth_rate: bool) {
    println!(
        "Observability along the path, Earth rate {} (rank: eigenvalues of the prior-scaled \
         information matrix above {RANK_TOLERANCE:e}·λmax; null-space coefficients below \
         {COEF_THRESHOLD:e} dropped; observable in practice: σ_CRLB/σ_prior < {PRACTICAL_RATIO})",
        if earth_rate { "on" } else { "off" }
    );
    for c in configs {
        println!(
            "\n{}: {} states, rank {}, null space {}",
            c.config,
            c.n,
            c.rank,
            c.nullity()
        );
        for (i, comb) in c.null_space.iter().enumerate() {
            println!("  unobservable #{}: {}", i + 1, format_combination(comb));
        }
        println!(
            "  {:<10} {:<UNIT_WIDTH$} {:>12} {:>10}  verdict",
            "state", "unit", "σ_CRLB", "σ/σ_prior"
        );
        for s in &c.states {
            println!(
                "  {:<10} {:<UNIT_WIDTH$} {:>12.4} {:>10.2e}  {}",
                s.name,
                printed_unit(s.group),
                printed_value(s.group, s.sigma_crlb_rad),
                s.ratio,
                s.verdict
            );
        }
    }
}
