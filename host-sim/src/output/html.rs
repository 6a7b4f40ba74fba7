//! `--report DIR` (on `run` and `calibrate`): a self-contained HTML page,
//! `DIR/index.html`, with its PNG figures beside it (no network: no CDN,
//! no external font or script).
//!
//! The page holds a header (configuration, input, passes, precision), the
//! parameter table (estimate, σ, σ_CRLB where known; truth, error and
//! |error|/σ only when a truth exists — without one those columns are
//! absent), the σ(t) convergence figures per parameter group (log scale,
//! filter σ over the σ_CRLB dashes), the error figures when a truth exists
//! ([`crate::output::plots::plot_group_marked`]), the NIS and whitened innovations
//! over time, every figure with the path's segment switches marked, and the
//! consistency checks with the warnings.
//!
//! The page carries a small inline script for the browser check
//! (`tools/check-report.sh`): on `load` it checks that every figure loaded
//! (`complete && naturalWidth > 0`) and that the expected number of figures
//! is present, and sets `<body data-report-check="ok">` (or `"missing:
//! NAME"`); `window.onerror` sets `"script-error: MESSAGE"`. Until the
//! script has run the attribute is `"pending"`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rollcal::models::Group;

use crate::analysis::calibration::Calibration;
use crate::analysis::checks::Check;
use crate::analysis::runner::{RunResult, Verdict};
use crate::output::plots::{self, Curve, Innovations, SigmaSeries};
use crate::sim::instruments::{printed_unit, printed_value};
use crate::sim::segments::switch_times;

/// Everything the report shows.
pub struct Report<'a> {
    /// Page title, e.g. "calibrate M2-ps".
    pub title: String,
    /// Header lines (label, value): configuration, input, passes, precision.
    pub header: Vec<(String, String)>,
    /// The run (final states, history, updates, segments).
    pub result: &'a RunResult,
    /// Final σ_CRLB per state (rad), when known.
    pub crlb: Option<&'a [f64]>,
    /// σ_CRLB per record of the history (rad), when known.
    pub crlb_history: Option<&'a [Vec<f64>]>,
    /// Whether the truth of `result.states` is known.
    pub has_truth: bool,
    /// The true state per record of the history (rad), when known; without
    /// it the error figures use the final truth for the constant parameters
    /// and leave out the (time-varying) attitude.
    pub truth_history: Option<&'a [Vec<f64>]>,
    /// The consistency checks ([`crate::analysis::checks`]).
    pub checks: &'a [Check],
    /// The verdict on the data (`consistent` or `warning: …`).
    pub verdict: &'a str,
    /// The verdict on every state against the truth (one per state of
    /// `result` when `has_truth`; [`state_verdicts`]).
    pub state_verdicts: Vec<Verdict>,
    /// Warnings (failed updates, notes of the run).
    pub warnings: Vec<String>,
}

/// Creates `dir` (and its parents) for a report; refuses an existing file.
pub fn prepare_dir(dir: &Path) -> Result<(), String> {
    if dir.exists() && !dir.is_dir() {
        return Err(format!(
            "--report {}: exists and is not a directory",
            dir.display()
        ));
    }
    std::fs::create_dir_all(dir).map_err(|e| format!("--report {}: {e}", dir.display()))
}

/// Two-sided 99 % band of the mean of `n` NIS values of `dof` degrees of
/// freedom each (Wilson–Hilferty, [`crate::analysis::montecarlo::chi2_quantile`]).
pub fn nis_band(n: usize, dof: usize) -> (f64, f64) {
    let k = (n * dof) as f64;
    let n = n as f64;
    (
        crate::analysis::montecarlo::chi2_quantile(0.005, k) / n,
        crate::analysis::montecarlo::chi2_quantile(0.995, k) / n,
    )
}

/// Degrees of freedom of one update of configuration `id`: the
/// measurement size.
pub fn update_dof(id: rollcal::models::ConfigId) -> usize {
    id.layout().z()
}

fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// A number for the tables: 4 significant digits, `—` when not finite.
fn num(v: f64) -> String {
    if !v.is_finite() {
        return "—".into();
    }
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e6).contains(&a) {
        format!("{v:.3e}")
    } else if a == 0.0 {
        "0".into()
    } else {
        let digits = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{v:.digits$}")
    }
}

/// A value shown beside its σ: with as many decimals as keep the rounding
/// within 0.1σ ([`crate::output::report::decimals`]), at least four
/// significant digits; `—` when not finite.
fn to_sigma(v: f64, sigma: f64) -> String {
    if !v.is_finite() {
        return "—".into();
    }
    let by_size = if v != 0.0 {
        (3 - v.abs().log10().floor() as i32).max(0) as usize
    } else {
        0
    };
    let d = crate::output::report::decimals(sigma, by_size.min(9));
    format!("{v:.d$}")
}

/// The groups of the configuration's states in state order, with the
/// indices of their states.
fn groups(r: &RunResult) -> Vec<(Group, Vec<usize>)> {
    crate::output::groups::in_order(r.states.iter().map(|s| s.info.group))
        .into_iter()
        .map(|g| {
            let idx = (0..r.states.len())
                .filter(|&i| r.states[i].info.group == g)
                .collect();
            (g, idx)
        })
        .collect()
}

fn group_title(g: Group) -> String {
    crate::output::groups::title(g)
}

/// A figure of the page: file name and caption.
struct Figure {
    file: String,
    caption: String,
}

/// Writes the figures into `dir`; returns them in page order (sections:
/// convergence, errors, innovations).
fn write_figures(dir: &Path, rep: &Report<'_>) -> Result<[Vec<Figure>; 3], String> {
    let r = rep.result;
    let switches = switch_times(&r.segments);
    let mut out: [Vec<Figure>; 3] = Default::default();
    if r.history.is_empty() {
        return Ok(out);
    }
    let t: Vec<f64> = r.history.iter().map(|h| h.0).collect();
    let crlb_hist = rep.crlb_history.filter(|c| c.len() == r.history.len());
    out[0] = convergence_figures(dir, r, &t, crlb_hist, &switches)?;
    if rep.has_truth {
        out[1] = error_figures(dir, rep, &t, crlb_hist, &switches)?;
    }
    out[2] = innovations_figure(dir, r, &switches)?;
    Ok(out)
}

/// Filter σ of state `i` per record of the history (its printed unit).
fn sigma_col(r: &RunResult, i: usize) -> Vec<f64> {
    let g = r.states[i].info.group;
    r.history
        .iter()
        .map(|h| printed_value(g, h.2.get(i).copied().unwrap_or(f64::NAN)))
        .collect()
}

/// σ_CRLB of state `i` per record of the history (its printed unit), when
/// known.
fn crlb_col(r: &RunResult, crlb_hist: Option<&[Vec<f64>]>, i: usize) -> Option<Vec<f64>> {
    let g = r.states[i].info.group;
    crlb_hist.map(|c| {
        c.iter()
            .map(|v| printed_value(g, v.get(i).copied().unwrap_or(f64::NAN)))
            .collect()
    })
}

/// The σ(t) figure of every group.
fn convergence_figures(
    dir: &Path,
    r: &RunResult,
    t: &[f64],
    crlb_hist: Option<&[Vec<f64>]>,
    switches: &[f64],
) -> Result<Vec<Figure>, String> {
    let id = r.config;
    let mut out = Vec::new();
    let sigma_col = |i: usize| sigma_col(r, i);
    let crlb_col = |i: usize| crlb_col(r, crlb_hist, i);
    for (g, idx) in groups(r) {
        let sig: Vec<Vec<f64>> = idx.iter().map(|&i| sigma_col(i)).collect();
        let cr: Vec<Option<Vec<f64>>> = idx.iter().map(|&i| crlb_col(i)).collect();
        let series: Vec<SigmaSeries<'_>> = idx
            .iter()
            .zip(&sig)
            .zip(&cr)
            .map(|((&i, s), c)| SigmaSeries {
                label: r.states[i].name,
                unit: printed_unit(g),
                sigma: s,
                crlb: c.as_deref(),
            })
            .collect();
        let file = format!("sigma-{}.png", g.as_str());
        plots::plot_convergence(
            &dir.join(&file),
            &format!("{id}: {} — σ(t)", group_title(g)),
            t,
            &series,
            switches,
        )?;
        out.push(Figure {
            file,
            caption: format!(
                "σ(t) of {} ({}, in {}): filter σ{}, log scale over the whole run; vertical lines: path segment switches.",
                esc(&group_title(g)),
                esc(g.as_str()),
                esc(printed_unit(g)),
                if crlb_hist.is_some() { " over σ_CRLB (dashed)" } else { " (σ_CRLB(t) not known for this input)" }
            ),
        });
    }
    Ok(out)
}

/// The error figure of every group against the truth (the attitude only
/// with a truth history).
fn error_figures(
    dir: &Path,
    rep: &Report<'_>,
    t: &[f64],
    crlb_hist: Option<&[Vec<f64>]>,
    switches: &[f64],
) -> Result<Vec<Figure>, String> {
    let r = rep.result;
    let id = r.config;
    let mut out = Vec::new();
    let sigma_col = |i: usize| sigma_col(r, i);
    let crlb_col = |i: usize| crlb_col(r, crlb_hist, i);
    for (g, idx) in groups(r) {
        let attitude = g == Group::Attitude;
        if attitude && rep.truth_history.is_none() {
            continue;
        }
        let th = rep.truth_history.filter(|h| h.len() == r.history.len());
        if attitude && th.is_none() {
            continue;
        }
        let err: Vec<Vec<f64>> = idx
            .iter()
            .map(|&i| {
                r.history
                    .iter()
                    .enumerate()
                    .map(|(k, h)| {
                        let truth = th
                            .and_then(|th| th.get(k))
                            .and_then(|v| v.get(i).copied())
                            .unwrap_or(r.states[i].truth_rad);
                        let d = h.1.get(i).copied().unwrap_or(f64::NAN) - truth;
                        printed_value(
                            g,
                            if g.unit() == "rad" {
                                rollcal::geometry::wrap_angle(d)
                            } else {
                                d
                            },
                        )
                    })
                    .collect()
            })
            .collect();
        let sig: Vec<Vec<f64>> = idx.iter().map(|&i| sigma_col(i)).collect();
        let nan = vec![f64::NAN; t.len()];
        let cr: Vec<Vec<f64>> = idx
            .iter()
            .map(|&i| crlb_col(i).unwrap_or_else(|| nan.clone()))
            .collect();
        let curves: Vec<Curve<'_>> = idx
            .iter()
            .enumerate()
            .map(|(j, &i)| Curve {
                label: r.states[i].name,
                unit: printed_unit(g),
                error: &err[j],
                sigma: &sig[j],
                crlb: &cr[j],
            })
            .collect();
        let file = format!("error-{}.png", g.as_str());
        plots::plot_group_marked(
            &dir.join(&file),
            &format!("{id}: {} — error, ±3σ filter, ±3σ_CRLB", group_title(g)),
            t,
            &curves,
            switches,
        )?;
        out.push(Figure {
            file,
            caption: format!(
                "Estimation error of {} ({}) against the truth: left |error| and 3σ on a log scale over the whole run, right the signed error in the shaded ±3σ band over the converged part; the ±3σ_CRLB dashes lie under the filter's line{}.",
                esc(&group_title(g)),
                esc(printed_unit(g)),
                if crlb_hist.is_some() { "" } else { " (not known for this input: absent)" }
            ),
        });
    }
    Ok(out)
}

/// The NIS and innovations figure, when there are updates.
fn innovations_figure(dir: &Path, r: &RunResult, switches: &[f64]) -> Result<Vec<Figure>, String> {
    let id = r.config;
    let mut out = Vec::new();
    let u = &r.updates;
    let dof = update_dof(id);
    if !u.is_empty() && dof > 0 {
        let t_u: Vec<f64> = u.iter().map(|u| u.t_s).collect();
        let nis: Vec<f64> = u.iter().map(|u| u.nis).collect();
        let white: Vec<Vec<f64>> = u.iter().map(|u| u.white.clone()).collect();
        let window = u.len().clamp(1, 100);
        let names = crate::analysis::checks::component_names(dof);
        let components: Vec<&str> = names.iter().map(String::as_str).collect();
        let file = "innovations.png".to_string();
        plots::plot_innovations(
            &dir.join(&file),
            &format!("{id}: NIS and whitened innovations of the last pass"),
            &Innovations {
                t_s: &t_u,
                nis: &nis,
                white: &white,
                dof,
                window,
                band: nis_band(window, dof),
                components: &components,
            },
            switches,
        )?;
        out.push(Figure {
            file,
            caption: format!(
                "Top: moving mean of the NIS over {window} updates with its 99 % χ² band (shaded) and the expected value {dof} (dotted). Bottom: the {dof} whitened innovation components ({}; unit variance when the model holds, colours in the legend above the panel) with ±3 dashed. Vertical lines: path segment switches.",
                esc(&names.join(", "))
            ),
        });
    }
    Ok(out)
}

const STYLE: &str = "body{font-family:sans-serif;margin:24px;max-width:1100px;color:#222}\
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ccc}\
table{border-collapse:collapse;font-size:0.9em}td,th{padding:3px 8px;border-bottom:1px solid #e4e4e4;text-align:right}\
th{background:#f2f2f2}td.l,th.l{text-align:left}.fail{color:#b00020;font-weight:bold}.ok{color:#006b3c}\
figure{margin:12px 0}figure img{max-width:100%;border:1px solid #ddd}figcaption{font-size:0.85em;color:#444}\
.warn{background:#fff4e5;border-left:4px solid #e69500;padding:6px 10px;margin:4px 0}\
dl{display:grid;grid-template-columns:max-content auto;gap:2px 16px}dt{font-weight:bold}dd{margin:0}";

/// The page's check script (see the module docs).
const SCRIPT: &str = "window.onerror=function(m){document.body.setAttribute('data-report-check','script-error: '+m);};\
window.addEventListener('load',function(){var b=document.body;\
if((b.getAttribute('data-report-check')||'').indexOf('script-error')===0)return;\
var imgs=document.querySelectorAll('img.figure');var want=parseInt(b.getAttribute('data-expected-figures'),10);\
var bad=[];for(var i=0;i<imgs.length;i++){var im=imgs[i];if(!(im.complete&&im.naturalWidth>0))bad.push(im.getAttribute('src'));}\
if(imgs.length!==want)bad.push('expected '+want+' figures, found '+imgs.length);\
b.setAttribute('data-report-check',bad.length?'missing: '+bad.join(', '):'ok');});";

/// Writes `dir/index.html` and its figures; returns the page's path.
pub fn write_report(dir: &Path, rep: &Report<'_>) -> Result<PathBuf, String> {
    prepare_dir(dir)?;
    let figures = write_figures(dir, rep)?;
    let r = rep.result;
    let n_fig: usize = figures.iter().map(Vec::len).sum();
    let crlb = rep.crlb.filter(|c| c.iter().any(|v| v.is_finite()));
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{t}</title><style>{STYLE}</style><script>{SCRIPT}</script></head>\n<body data-report-check=\"pending\" data-expected-figures=\"{n_fig}\">\n<h1>{t}</h1>\n<dl>",
        t = esc(&rep.title)
    );
    for (k, v) in &rep.header {
        let _ = write!(h, "<dt>{}</dt><dd>{}</dd>", esc(k), esc(v));
    }
    let verdict_class = if rep.verdict.starts_with("consistent") {
        "ok"
    } else {
        "fail"
    };
    let _ = writeln!(
        h,
        "<dt>verdict on the data</dt><dd class=\"{verdict_class}\">{}</dd></dl>",
        esc(rep.verdict)
    );
    // Warnings: the given ones and every failed check with its statistic
    // and band.
    let mut warnings = rep.warnings.clone();
    for c in rep.checks.iter().filter(|c| !c.passed) {
        warnings.push(format!(
            "{} ({}): {} outside [{}, {}]; {}",
            c.name,
            c.scope,
            num(c.statistic),
            num(c.band.0),
            num(c.band.1),
            c.detail
        ));
    }
    if !warnings.is_empty() {
        h.push_str("<h2 id=\"warnings\">Warnings</h2>\n");
        for w in &warnings {
            let _ = writeln!(h, "<div class=\"warn\">{}</div>", esc(w));
        }
    }
    parameter_table(&mut h, rep, crlb);
    figure_sections(&mut h, r, &figures);
    checks_table(&mut h, rep.checks);
    h.push_str("<p><small>Written by host-sim; self-contained (the figures are the PNG files beside this page).</small></p>\n</body></html>\n");
    let page = dir.join("index.html");
    std::fs::write(&page, h).map_err(|e| format!("cannot write {}: {e}", page.display()))?;
    Ok(page)
}

/// The parameter table (`crlb`: the σ_CRLB column, when known): every
/// state in its printed unit (the unit column), each value with the digits
/// that keep its rounding within 0.1σ.
fn parameter_table(h: &mut String, rep: &Report<'_>, crlb: Option<&[f64]>) {
    let r = rep.result;
    h.push_str("<h2 id=\"parameters\">Parameters</h2>\n<p>Final estimate of every state in its unit (angles in arcseconds; the attitude states at the final time), with the digits that keep the rounding within 0.1σ.</p>\n<table><tr><th class=\"l\">state</th><th class=\"l\">group</th><th class=\"l\">unit</th><th>estimate</th><th>σ</th>");
    if crlb.is_some() {
        h.push_str("<th>σ_CRLB</th><th>σ/σ_CRLB</th>");
    }
    if rep.has_truth {
        h.push_str("<th>truth</th><th>error</th><th>|err|/σ</th><th class=\"l\">verdict</th>");
    } else {
        h.push_str("<th>σ/σ_prior</th>");
    }
    h.push_str("</tr>\n");
    for (i, s) in r.states.iter().enumerate() {
        let g = s.info.group;
        let show = |v: f64| printed_value(g, v);
        let sigma = show(s.sigma_rad);
        let _ = write!(
            h,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td>",
            esc(s.name),
            esc(s.group),
            esc(printed_unit(g)),
            to_sigma(show(s.estimate_rad), sigma),
            num(sigma)
        );
        if let Some(c) = crlb {
            let c = c.get(i).copied().unwrap_or(f64::NAN);
            let _ = write!(
                h,
                "<td>{}</td><td>{}</td>",
                num(show(c)),
                num(s.sigma_rad / c)
            );
        }
        if rep.has_truth {
            let v = rep
                .state_verdicts
                .get(i)
                .copied()
                .unwrap_or(Verdict::Failed);
            let class = if matches!(v, Verdict::Failed) {
                " fail"
            } else {
                ""
            };
            let _ = write!(
                h,
                "<td>{}</td><td>{}</td><td>{}</td><td class=\"l{class}\">{}</td>",
                to_sigma(show(s.truth_rad), sigma),
                to_sigma(show(s.error()), sigma),
                num(s.ratio()),
                esc(&v.to_string())
            );
        } else {
            let _ = write!(h, "<td>{}</td>", num(s.sigma_rad / s.prior));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    let _ = writeln!(
        h,
        "<p>{} path segment(s) recovered from the commanded increments; {} pass(es); {} accepted updates in the last pass; {} failed update(s).</p>",
        r.segments.len(),
        r.passes,
        r.updates.len(),
        r.failures.len()
    );
}

/// The figure sections.
fn figure_sections(h: &mut String, r: &RunResult, figures: &[Vec<Figure>; 3]) {
    // Figures.
    let sections = [
        ("convergence", "Convergence σ(t)"),
        ("errors", "Estimation error against the truth"),
        ("innovations", "NIS and innovations over time"),
    ];
    for ((id, title), figs) in sections.iter().zip(figures) {
        if figs.is_empty() {
            if *id == "convergence" && r.history.is_empty() {
                let _ = writeln!(
                    h,
                    "<h2 id=\"{id}\">{title}</h2>\n<p>No time history: the answer is the calibrator's pass 1 (the figures need the final passes).</p>"
                );
            }
            continue;
        }
        let _ = writeln!(h, "<h2 id=\"{id}\">{title}</h2>");
        for f in figs {
            let _ = writeln!(
                h,
                "<figure><img class=\"figure\" src=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>",
                esc(&f.file),
                esc(&f.file),
                f.caption
            );
        }
    }
}

/// The table of the consistency checks.
fn checks_table(h: &mut String, checks: &[Check]) {
    // Consistency checks.
    h.push_str("<h2 id=\"checks\">Consistency checks</h2>\n");
    if checks.is_empty() {
        h.push_str("<p>No check could be computed (no accepted update kept).</p>\n");
    } else {
        h.push_str("<table><tr><th class=\"l\">check</th><th class=\"l\">scope</th><th>statistic</th><th>band</th><th class=\"l\">result</th><th class=\"l\">detail</th></tr>\n");
        for c in checks {
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>[{}, {}]</td><td class=\"l {}\">{}</td><td class=\"l\">{}</td></tr>",
                esc(c.name),
                esc(&c.scope),
                num(c.statistic),
                num(c.band.0),
                num(c.band.1),
                if c.passed { "ok" } else { "fail" },
                if c.passed { "inside" } else { "outside" },
                esc(&c.detail)
            );
        }
        h.push_str("</table>\n");
    }
}

/// The report of `host-sim run`: truth and σ_CRLB(t) along the simulated
/// run; writes `dir/index.html`.
pub fn report_of_run(
    dir: &Path,
    r: &RunResult,
    scenario: &crate::sim::scenario::Scenario,
    sim: &crate::sim::truth::Simulation,
    earth_rate: bool,
    crlb: &[f64],
    header: Vec<(String, String)>,
) -> Result<PathBuf, String> {
    let run = crate::analysis::runner::SimulatedRun::new(r.config, scenario, sim, earth_rate)
        .with_errors(r.errors);
    let crlb_history = run
        .crlb_history()
        .map_err(|e| format!("Cramér–Rao bound: {e}"))?;
    let truth_history = run.truth_history();
    let judgement = crate::analysis::checks::judge(r);
    let verdict = judgement.verdict.to_string();
    let mut warnings = failure_warnings(r);
    warnings.extend(judgement.cause.clone());
    write_report(
        dir,
        &Report {
            title: format!("run {}", r.config),
            header,
            result: r,
            crlb: Some(crlb),
            crlb_history: Some(&crlb_history),
            has_truth: true,
            truth_history: Some(&truth_history),
            checks: &judgement.checks,
            verdict: &verdict,
            state_verdicts: state_verdicts(r),
            warnings,
        },
    )
}

/// The verdict on every state of `r` against its truth, as the tables
/// print it ([`crate::analysis::runner::verdict`]).
pub fn state_verdicts(r: &RunResult) -> Vec<Verdict> {
    r.states
        .iter()
        .map(crate::analysis::verdict::verdict)
        .collect()
}

/// A warning for failed updates, if any.
pub fn failure_warnings(r: &RunResult) -> Vec<String> {
    match r.failures.first() {
        Some((k, e)) => vec![format!(
            "{} update(s) failed; first: period {k} ({e})",
            r.failures.len()
        )],
        None => Vec::new(),
    }
}

/// The report of `host-sim calibrate` of calibration `c`: the truth (the
/// sidecar's final values) when given, σ_CRLB when known (`crlb`,
/// `crlb_history`); the warnings: whether the result is an answer, the
/// rejected samples with their likely cause, the gated share's hint, the
/// refused messages, failed updates, the path near gimbal lock, the data
/// verdict's likely cause, every failed check with its statistic. Writes
/// `dir/index.html`.
pub fn report_of_calibration(
    dir: &Path,
    c: &Calibration,
    crlb: Option<&[f64]>,
    crlb_history: Option<&[Vec<f64>]>,
    header: Vec<(String, String)>,
) -> Result<PathBuf, String> {
    let (r, judgement) = (&c.r, &c.judgement);
    let has_truth = c.sidecar.is_some();
    let verdict = judgement.verdict.to_string();
    let mut warnings: Vec<String> = c
        .not_an_answer
        .iter()
        .map(|w| format!("not an answer: {w}"))
        .collect();
    for f in &c.rejects {
        warnings.push(format!(
            "{} samples rejected for {} (first: {}){}",
            f.count,
            f.reason,
            f.first,
            f.likely_cause
                .as_ref()
                .map_or_else(String::new, |c| format!("; likely cause: {c}"))
        ));
    }
    warnings.extend(c.gated.hint.clone());
    for r in &c.refusals {
        let w = format!(
            "{} refused: {} (the calibrator as it was)",
            crate::analysis::calibration::name_of(r.message),
            r.error
        );
        if !warnings.contains(&w) {
            warnings.push(w);
        }
    }
    warnings.extend(failure_warnings(r));
    if let Some(p) = judgement.path.as_ref().filter(|p| !p.passed) {
        warnings.push(format!("the path nears gimbal lock: {}", p.detail));
    }
    warnings.extend(judgement.cause.clone());
    write_report(
        dir,
        &Report {
            title: format!("calibrate {}", r.config),
            header,
            result: r,
            crlb,
            crlb_history,
            has_truth,
            truth_history: None,
            checks: &judgement.checks,
            verdict: &verdict,
            state_verdicts: if has_truth {
                state_verdicts(r)
            } else {
                Vec::new()
            },
            warnings,
        },
    )
}
