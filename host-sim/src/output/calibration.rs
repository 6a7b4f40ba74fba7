//! What `calibrate` writes of a [`Calibration`]: the table (against the
//! truth, or with the bound at the estimate and its verdict, never FAILED:
//! docs/own-platform.md, "Judging a calibration without a truth"), the data
//! checks and the stream's counters; the JSON of `--json`; the header of
//! the HTML report. Rendering only: the numbers come computed
//! ([`crate::analysis::calibration`]).

use std::io::Write;

use rollcal::wire::EstimateKind;

use crate::analysis::calibration::rejects::RejectFinding;
use crate::analysis::calibration::trust::Gated;
use crate::analysis::calibration::{name_of, Calibration, Refused};
use crate::io::stream::{frames_json, reject_json, Format};
use crate::output::report::{run_json, write_judgement, write_table, write_table_no_truth};

/// How the input was read, for the outputs.
#[derive(Clone, Copy, Debug)]
pub struct Source<'a> {
    /// The input as given (`--input`).
    pub input: &'a str,
    /// Frames or CSV.
    pub format: Format,
    /// The precision of the calibrator's arithmetic (`f64`, `f32`).
    pub precision: &'a str,
    /// The truth sidecar's path, when given.
    pub truth: Option<&'a std::path::Path>,
    /// The reply frames sent (`--replies`), when asked for.
    pub replies: Option<u64>,
}

/// Writes the table, the data checks and the stream's counters.
pub fn write_results(
    out: &mut dyn Write,
    c: &Calibration,
    src: &Source<'_>,
) -> std::io::Result<()> {
    let (r, p) = (&c.r, &c.est.progress);
    match (&c.at_estimate, &c.sidecar) {
        (Some((b, v)), _) => write_table_no_truth(out, r, Some((b, v)))?,
        (None, None) => write_table_no_truth(out, r, None)?,
        (None, Some(_)) => write_table(out, r, &c.crlb)?,
    }
    write_judgement(out, &c.judgement)?;
    let rj = reject_json(&p.rejects);
    let frames = if src.format == Format::Csv {
        "CSV log".to_string()
    } else {
        format!(
            "{} frames ok, {} rejected {}",
            c.stats.ok,
            c.stats.errors(),
            frames_json(&c.stats)
        )
    };
    writeln!(
        out,
        "stream: {frames}; samples: {} accepted, {} bridged, {} rejected {}",
        p.accepted,
        p.bridged,
        p.rejects.total(),
        rj
    )?;
    if p.reacquired > 0 || p.clock_steps > 0 {
        writeln!(
            out,
            "lost data: {} gap(s) with unknown motion re-acquired the attitude ({} periods), {} clock step(s) re-anchored",
            p.reacquired, p.reacquired_periods, p.clock_steps
        )?;
    }
    write_findings(out, &c.rejects)?;
    write_gated(out, &c.gated)?;
    write_refusals(out, &c.refusals)?;
    if let Some(n) = src.replies {
        writeln!(out, "replies: {n} frames sent")?;
    }
    if c.not_an_answer.is_empty() {
        writeln!(out, "answer: an answer (enough samples accepted, the final passes and the data checks run, every state the configuration observes observed)")?;
    } else {
        for why in &c.not_an_answer {
            writeln!(out, "answer: NOT an answer: {why}")?;
        }
    }
    Ok(())
}

/// The rejected samples by reason: count, the first one, the likely cause.
pub fn write_findings(out: &mut dyn Write, findings: &[RejectFinding]) -> std::io::Result<()> {
    for f in findings {
        write!(
            out,
            "rejected: {:<15} {:>6}  first: {}",
            f.reason, f.count, f.first
        )?;
        match &f.likely_cause {
            Some(c) => writeln!(out, "; likely cause: {c}")?,
            None => writeln!(out)?,
        }
    }
    Ok(())
}

/// The gated updates and their share, with the hint when above a clean
/// log's.
fn write_gated(out: &mut dyn Write, g: &Gated) -> std::io::Result<()> {
    if g.gate <= 0.0 {
        return writeln!(out, "gated: no NIS gate");
    }
    let share = |n: u32| 100.0 * f64::from(n) / f64::from(g.updates.max(1));
    write!(
        out,
        "gated (NIS > {}): pass 1 {} of {} updates ({:.2} %)",
        g.gate,
        g.pass1,
        g.updates,
        share(g.pass1)
    )?;
    if let Some(n) = g.last_pass {
        write!(out, ", last pass {n} ({:.2} %)", share(n))?;
    }
    writeln!(out)?;
    if let Some(h) = &g.hint {
        writeln!(out, "  hint: {h}")?;
    }
    Ok(())
}

/// The messages the session refused (the calibrator left as it was).
fn write_refusals(out: &mut dyn Write, refusals: &[Refused]) -> std::io::Result<()> {
    let mut seen: Vec<(u8, String)> = Vec::new();
    for r in refusals {
        let key = (r.message, r.error.to_string());
        if seen.contains(&key) {
            continue;
        }
        let n = refusals
            .iter()
            .filter(|x| x.message == r.message && x.error.to_string() == key.1)
            .count();
        writeln!(
            out,
            "refused: {} ×{n}: {} (the calibrator as it was; wire: Refused)",
            name_of(r.message),
            key.1
        )?;
        seen.push(key);
    }
    Ok(())
}

/// The JSON of `--json`: `run`'s, with the passes, precision, bound,
/// answer, checks, pass 1 and the stream's counters.
pub fn json(c: &Calibration, src: &Source<'_>) -> serde_json::Value {
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
    json["precision"] = src.precision.into();
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
    if let Some((b, v)) = &c.at_estimate {
        json["bound_at_estimate_sigma_rad"] = serde_json::json!(b);
        json["observability"] = serde_json::json!(v);
    }
    let judgement = &c.judgement;
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
    json["answer"]["usable"] = c.not_an_answer.is_empty().into();
    json["answer"]["not_an_answer"] = serde_json::json!(c.not_an_answer);
    json["rejected"] = serde_json::json!(c.rejects);
    json["gated"] = serde_json::json!(c.gated);
    json["refused"] = c
        .refusals
        .iter()
        .map(|r| serde_json::json!({"message": name_of(r.message), "reason": r.error.to_string()}))
        .collect();
    json["stream"] = serde_json::json!({
        "format": if src.format == Format::Csv { "csv" } else { "frames" },
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

/// The header lines of the HTML report: configuration, input, passes,
/// precision, samples, truth.
pub fn report_header(c: &Calibration, src: &Source<'_>) -> Vec<(String, String)> {
    let (r, p) = (&c.r, &c.est.progress);
    vec![
        ("configuration".into(), c.id.to_string()),
        (
            "input".into(),
            format!(
                "{} ({})",
                src.input,
                if src.format == Format::Csv {
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
        ("precision".into(), src.precision.into()),
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
            src.truth.map_or_else(
                || "none (no truth columns, no error figures)".into(),
                |t| t.display().to_string(),
            ),
        ),
        (
            "answer".into(),
            match c.not_an_answer.first() {
                None => "an answer (exit status 0, or 3 with a data warning)".into(),
                Some(why) => format!("NOT an answer (exit status 4): {why}"),
            },
        ),
    ]
}
