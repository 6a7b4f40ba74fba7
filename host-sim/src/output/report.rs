//! Tables, JSON and CSV of estimator runs (shared by `run`, `calibrate`,
//! `paper`).

use std::io::Write;
use std::path::Path;

use rollcal::models::{ErrorModel, Group};

use crate::analysis::checks::{Judgement, FALSE_ALARM};
use crate::analysis::runner::{RunResult, StateResult};
use crate::sim::instruments::{printed_unit, printed_value};

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

/// The decimals of a value printed beside its σ (`sigma`, printed unit):
/// at least `min`, and enough that the rounding stays within 0.1σ (half
/// the last digit ≤ 0.1σ: `10^-d ≤ 0.2σ`; at most 9).
pub fn decimals(sigma: f64, min: usize) -> usize {
    if sigma.is_finite() && sigma > 0.0 {
        ((-(0.2 * sigma).log10()).ceil().max(0.0) as usize).clamp(min, 9)
    } else {
        min
    }
}

/// Width of the unit column of the tables (`″`, `°/h`, `°/h/g`, `ppm`,
/// `µg`, …: characters, not bytes).
pub const UNIT_WIDTH: usize = 6;

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
            // Angles in rad (the `_rad` columns), the others in their printed unit.
            let k = if s.info.group.unit() == "rad" {
                1.0
            } else {
                s.info.printed_scale().0
            };
            row.push(format!("{:e}", a * k));
            row.push(format!("{:e}", b * k));
        }
        writeln!(w, "{}", row.join(","))?;
    }
    w.flush()
}

/// Prints the final table of a run with the Cramér–Rao σ of every state
/// ([`write_table`] to stdout).
pub fn print_table(r: &RunResult, crlb: &[f64]) {
    let _ = write_table(&mut std::io::stdout().lock(), r, crlb);
}

/// Writes the final table of a run with the Cramér–Rao σ of every state,
/// each in its printed unit (the `unit` column; [`printed_value`]), and
/// the verdict against the truth ([`crate::analysis::verdict::verdict`]).
pub fn write_table(out: &mut dyn Write, r: &RunResult, crlb: &[f64]) -> std::io::Result<()> {
    writeln!(
        out,
        "{:<11} {:<UNIT_WIDTH$} {:>12} {:>12} {:>10} {:>10} {:>8} {:>10} {:>8}  verdict",
        "state", "unit", "truth", "estimate", "error", "σ", "|err|/σ", "σ_CRLB", "σ/σ_CRLB"
    )?;
    for (s, c) in r.states.iter().zip(crlb) {
        let g = s.info.group;
        let (d3, d4) = {
            let sigma = printed_value(g, s.sigma_rad);
            (decimals(sigma, 3), decimals(sigma, 4))
        };
        writeln!(
            out,
            "{:<11} {:<UNIT_WIDTH$} {:>12.d3$} {:>12.d3$} {:>10.d4$} {:>10.4} {:>8.2} {:>10.4} {:>8.3}  {}",
            s.name,
            printed_unit(g),
            printed_value(g, s.truth_rad),
            printed_value(g, s.estimate_rad),
            printed_value(g, s.error()),
            printed_value(g, s.sigma_rad),
            s.ratio(),
            printed_value(g, *c),
            s.sigma_rad / c,
            crate::analysis::verdict::verdict(s)
        )?;
    }
    write_failures_and_nis(out, r)
}

/// Writes the final table of a run without a truth: per state, in its
/// printed unit, the estimate and σ, the bound σ at the estimate along the
/// received path (`bound`), σ/bound and the observability verdict of that
/// bound (`verdicts`: [`crate::analysis::verdict::Verdict::of_bound`]);
/// never a truth column or `FAILED`. Then the failures and the mean NIS as
/// [`write_table`].
pub fn write_table_no_truth(
    out: &mut dyn Write,
    r: &RunResult,
    bound: Option<(&[f64], &[crate::analysis::verdict::Verdict])>,
) -> std::io::Result<()> {
    writeln!(
        out,
        "{:<11} {:<UNIT_WIDTH$} {:>12} {:>10} {:>10} {:>8}  verdict (the bound at the estimate, received path)",
        "state", "unit", "estimate", "σ", "bound", "σ/bound"
    )?;
    for (i, s) in r.states.iter().enumerate() {
        let b = bound
            .and_then(|(b, _)| b.get(i))
            .copied()
            .unwrap_or(f64::NAN);
        let v = bound.and_then(|(_, v)| v.get(i)).map_or_else(
            || "— (no bound at the estimate)".to_string(),
            ToString::to_string,
        );
        let g = s.info.group;
        let d3 = decimals(printed_value(g, s.sigma_rad), 3);
        writeln!(
            out,
            "{:<11} {:<UNIT_WIDTH$} {:>12.d3$} {:>10.4} {:>10.4} {:>8.3}  {}",
            s.name,
            printed_unit(g),
            printed_value(g, s.estimate_rad),
            printed_value(g, s.sigma_rad),
            printed_value(g, b),
            s.sigma_rad / b,
            v
        )?;
    }
    write_failures_and_nis(out, r)
}

fn write_failures_and_nis(out: &mut dyn Write, r: &RunResult) -> std::io::Result<()> {
    if let Some((k, e)) = r.failures.first() {
        writeln!(
            out,
            "{} updates failed; first: period {k} ({e})",
            r.failures.len(),
        )?;
    }
    let n = r.nis.len().max(1) as f64;
    writeln!(
        out,
        "mean NIS {:.3} over {} updates of the last of {} pass(es)",
        r.nis.iter().sum::<f64>() / n,
        r.nis.len(),
        r.passes
    )
}

/// Writes the data checks of a judgement (every NIS and whiteness check,
/// the failed bias checks and the passed ones as one line), the path's
/// check, the verdict and its likely cause.
pub fn write_judgement(out: &mut dyn Write, j: &Judgement) -> std::io::Result<()> {
    if !j.checks.is_empty() {
        writeln!(
            out,
            "data against the model ({} checks, each at α = {:.1e}: a clean log is flagged with probability ≤ {}):",
            j.checks.len(),
            j.alpha_each,
            FALSE_ALARM
        )?;
        writeln!(
            out,
            "  {:<10} {:<42} {:>10} {:>22}  result",
            "check", "scope", "statistic", "band"
        )?;
        let mut passed_bias = 0;
        for c in &j.checks {
            if c.name == "bias" && c.passed {
                passed_bias += 1;
                continue;
            }
            writeln!(
                out,
                "  {:<10} {:<42} {:>10.4} {:>22}  {}",
                c.name,
                c.scope,
                c.statistic,
                format!("[{:.4}, {:.4}]", c.band.0, c.band.1),
                if c.passed { "pass" } else { "FAIL" }
            )?;
        }
        if passed_bias > 0 {
            writeln!(
                out,
                "  bias       {passed_bias} segment × component checks passed"
            )?;
        }
    }
    if let Some(c) = &j.path {
        writeln!(
            out,
            "path: {} ({}): {}",
            c.name,
            c.detail,
            if c.passed { "pass" } else { "FAIL" }
        )?;
    }
    writeln!(out, "data verdict: {}", j.verdict)?;
    if let Some(cause) = &j.cause {
        writeln!(out, "{cause}")?;
    }
    Ok(())
}

/// The group of a state from its group name (attitude when unknown).
pub fn group_of(name: &str) -> Group {
    Group::from_name(name).unwrap_or(Group::Attitude)
}
