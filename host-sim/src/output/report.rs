//! Tables, JSON and CSV of estimator runs (shared by `run`, `calibrate`,
//! `paper`).

use std::path::Path;

use rollcal::models::{ErrorModel, Group};

use crate::analysis::runner::{RunResult, StateResult};
use crate::sim::instruments::printed_value;
use crate::sim::scenario::ARCSEC;

/// The `run` JSON document: configuration, seed, Earth rate, duration and
/// the final states (names and units are an interface: `*_rad`).
pub fn run_json(r: &RunResult, seed: u64, earth_rate: bool, duration_s: f64) -> serde_json::Value {
    let (installation, instruments): (Vec<&StateResult>, Vec<&StateResult>) =
        r.states.iter().partition(|s| !s.info.group.is_instrument());
    let mut json = serde_json::json!({
        "config": r.config.as_str(),
        "seed": seed,
        "earth_rate": earth_rate,
        "duration_s": duration_s,
        "states": installation,
    });
    if r.errors == ErrorModel::Full {
        json["errors"] = r.errors.as_str().into();
        json["instruments"] = instruments.iter().map(|s| instrument_json(s)).collect();
    }
    json
}

/// An instrument state of the full model in its printed unit (°/h, °/h/g,
/// ppm, µg): `name`, `group`, `unit`, `truth`, `estimate`, `sigma`.
fn instrument_json(s: &StateResult) -> serde_json::Value {
    let (k, unit) = s.info.printed_scale();
    serde_json::json!({
        "name": s.name,
        "group": s.group,
        "unit": unit,
        "truth": s.truth_rad * k,
        "estimate": s.estimate_rad * k,
        "sigma": s.sigma_rad * k,
    })
}

/// The CSV column suffix of state `s`: `rad`, or the ASCII form of its
/// printed unit (`deg_h`, `deg_h_g`, `ppm`, `ug`).
fn csv_unit(s: &StateResult) -> String {
    crate::sim::instruments::ascii_unit(s.info.group).replace('/', "_")
}

/// Writes `value` pretty-printed to `path`, with a message naming the path on failure.
pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<(), String> {
    let text = serde_json::to_string_pretty(value).map_err(|e| e.to_string())?;
    std::fs::write(path, text + "\n").map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// Writes the time history (t, then estimate and σ of every state) as CSV.
pub fn write_csv(path: &Path, r: &RunResult) -> std::io::Result<()> {
    use std::io::Write;
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut header = vec!["t_s".to_string()];
    for s in &r.states {
        let unit = csv_unit(s);
        header.push(format!("{}_{unit}", s.name));
        header.push(format!("{}_sigma_{unit}", s.name));
    }
    writeln!(w, "{}", header.join(","))?;
    for (t, x, sig) in &r.history {
        let mut row = vec![format!("{t}")];
        for ((a, b), s) in x.iter().zip(sig).zip(&r.states) {
            let k = if s.info.group.is_instrument() {
                s.info.printed_scale().0
            } else {
                1.0
            };
            row.push(format!("{:e}", a * k));
            row.push(format!("{:e}", b * k));
        }
        writeln!(w, "{}", row.join(","))?;
    }
    w.flush()
}

/// Prints the final table of a run with the Cramér–Rao σ of every state.
pub fn print_table(r: &RunResult, crlb: &[f64]) {
    println!(
        "{:<11} {:>12} {:>12} {:>10} {:>10} {:>8} {:>10} {:>8}  verdict",
        "state", "truth ″", "estimate ″", "error ″", "σ ″", "|err|/σ", "σ_CRLB ″", "σ/σ_CRLB"
    );
    for (s, c) in r.states.iter().zip(crlb) {
        let group = s.info.group;
        let verdict = crate::analysis::runner::verdict(r.config, s, group, s.prior);
        let unit = if s.info.group.is_instrument() {
            format!(" ({})", s.info.printed_scale().1)
        } else {
            String::new()
        };
        println!(
            "{:<11} {:>12.3} {:>12.3} {:>10.4} {:>10.4} {:>8.2} {:>10.4} {:>8.3}  {}{unit}",
            s.name,
            printed_value(s.info.group, s.truth_rad),
            printed_value(s.info.group, s.estimate_rad),
            printed_value(s.info.group, s.error()),
            printed_value(s.info.group, s.sigma_rad),
            s.ratio(),
            printed_value(s.info.group, *c),
            s.sigma_rad / c,
            verdict
        );
    }
    print_failures_and_nis(r);
}

/// Prints the final table of a run without a truth: per state the
/// estimate and σ, the bound σ at the estimate along the received path
/// (`bound`), σ/bound and the observability verdict of that bound
/// (`verdicts`: [`crate::analysis::verdict::Verdict::of_bound`]); never a truth
/// column or `FAILED`. Then the failures and the mean NIS as
/// [`print_table`].
pub fn print_table_no_truth(
    r: &RunResult,
    bound: &[f64],
    verdicts: &[crate::analysis::verdict::Verdict],
) {
    println!(
        "{:<11} {:>12} {:>10} {:>10} {:>8}  verdict (the bound at the estimate, received path)",
        "state", "estimate ″", "σ ″", "bound ″", "σ/bound"
    );
    for ((s, b), v) in r.states.iter().zip(bound).zip(verdicts) {
        println!(
            "{:<11} {:>12.3} {:>10.4} {:>10.4} {:>8.3}  {}",
            s.name,
            s.estimate_rad / ARCSEC,
            s.sigma_rad / ARCSEC,
            b / ARCSEC,
            s.sigma_rad / b,
            v
        );
    }
    print_failures_and_nis(r);
}

fn print_failures_and_nis(r: &RunResult) {
    if !r.failures.is_empty() {
        println!(
            "{} updates failed; first: period {} ({})",
            r.failures.len(),
            r.failures[0].0,
            r.failures[0].1
        );
    }
    let n = r.nis.len().max(1) as f64;
    println!(
        "mean NIS {:.3} over {} updates of the last of {} pass(es)",
        r.nis.iter().sum::<f64>() / n,
        r.nis.len(),
        r.passes
    );
}

/// The group of a state from its group name (attitude when unknown).
pub fn group_of(name: &str) -> Group {
    Group::from_name(name).unwrap_or(Group::Attitude)
}
