//! `host-sim observability`: the observability of all seven
//! configurations along a scenario's path, as text tables, the verdict
//! matrix, what the Earth rate changes, and JSON.

use std::path::PathBuf;
use std::time::Instant;

use rollcal::models::ErrorModel;
use rollcal::observability::{COEF_THRESHOLD, PRACTICAL_RATIO, RANK_TOLERANCE};

use super::args::{load_scenario, parse_errors};
use super::Error;
use crate::analysis::floor::Floor;
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
    /// by the instruments' own errors, with the scenario's
    /// `[instruments.prior]` and `[instruments.wander]`; docs/model.md
    /// §Full model); with errors that wander, the floors they leave.
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
    let floors = match args.errors {
        ErrorModel::Full => crate::analysis::floor::scenario_floors(&scenario),
        ErrorModel::Installation => Vec::new(),
    };
    print_floors(&floors, &configs, scenario.timing.duration_s);
    eprintln!("done in {:.2} s", t0.elapsed().as_secs_f64());
    if let Some(path) = &args.json {
        let mut json = report_json(earth_rate, &configs);
        json["floors"] = floors_json(&floors);
        write_json(path, &json)?;
    }
    Ok(())
}

/// The floors as JSON: per term its group, unit (of the `*_printed`
/// values) and the [`Floor`] in internal units.
fn floors_json(floors: &[(&str, &str, Floor)]) -> serde_json::Value {
    floors
        .iter()
        .map(|(g, unit, f)| {
            let k = printed_scale(g);
            serde_json::json!({
                "group": g,
                "unit": unit,
                "floor": f,
                "at_end_printed": f.at_end * k,
                "limit_printed": f.limit * k,
            })
        })
        .collect()
}

/// The factor internal → printed of a floor's group (`dg`: °/h, `ba`: µg).
fn printed_scale(group: &str) -> f64 {
    rollcal::models::Group::from_name(group).map_or(f64::NAN, |g| g.printed_scale().0)
}

/// The floors of the wandering terms beside each configuration's bound on
/// this path (the worst axis): what no path gets below, and what this one
/// reaches.
fn print_floors(floors: &[(&str, &str, Floor)], configs: &[ConfigObs], duration_s: f64) {
    if floors.is_empty() {
        return;
    }
    println!(
        "\nErrors that wander: the floor of their persistent part (the instrument observed \
         directly, docs/observability.md), at this log's {duration_s:.0} s and for any length, \
         beside the bound this path reaches (worst axis):\n"
    );
    let mut head = String::from("| term | floor now | floor, any length | no gain after |");
    let mut rule = String::from("|---|---:|---:|---:|");
    for c in configs {
        head.push_str(&format!(" {} bound |", c.config));
        rule.push_str("---:|");
    }
    println!("{head}\n{rule}");
    for (g, unit, f) in floors {
        let k = printed_scale(g);
        let flat = f
            .flat_after_s
            .map_or_else(|| "— (keeps falling)".to_string(), |t| format!("{t:.0} s"));
        let mut row = format!(
            "| {g} ({unit}) | {:.4} | {:.4} | {flat} |",
            f.at_end * k,
            f.limit * k
        );
        for c in configs {
            let worst = c
                .states
                .iter()
                .filter(|s| s.group.as_str() == *g)
                .map(|s| s.sigma_crlb_rad)
                .fold(f64::NAN, f64::max);
            row.push_str(&format!(" {:.4} |", worst * k));
        }
        println!("{row}");
    }
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
