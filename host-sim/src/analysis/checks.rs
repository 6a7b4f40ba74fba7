//! Judging a calibration without a truth: does the data fit the model?
//!
//! The estimator's last pass (a filter linearised about the previous pass's
//! estimate, [`rollcal::estimator`]) produces, for every accepted update, the
//! normalised innovation squared (NIS) and the whitened innovation `L⁻¹ν`
//! ([`crate::analysis::runner::Update`]). When the model (the platform file's noise
//! levels, the configuration's instrument model) holds, the whitened
//! components are independent, zero-mean and of unit variance. [`judge`]
//! tests that:
//!
//! - **`nis`**: the mean NIS over `n` updates of `z` components, `n·NIS̄ ~
//!   χ²(n·z)`, against its two-sided band, over the whole log and per path
//!   segment (a wrong noise level);
//! - **`whiteness`**: the lag-1 autocorrelation `r₁ = Σ wₖwₖ₊₁ / Σ wₖ²` of
//!   every whitened component over the whole log, `≈ N(0, 1/n)`, against
//!   `±z/√n` (correlated noise, an unmodelled slow error);
//! - **`bias`**: the mean of every whitened component per path segment,
//!   `≈ N(0, 1/n_seg)`, against `±z/√n_seg` (an unmodelled constant error:
//!   the estimator absorbs what it can of it into the installation angles,
//!   but not the same way on every segment);
//! - **`left_out`** (full model, when the platform file leaves a term with
//!   a fixed signature out): the Wald statistic `x̂ᵀP⁻¹x̂ ~ χ²(d)` of the
//!   term estimated in one more run ([`Wald`],
//!   [`crate::analysis::calibration::left_out`]), one-sided (a term the
//!   data have and the model lacks).
//!
//! Every check is at the same significance `α / m` (two-sided but
//! `left_out`), `m` the number of checks made (Bonferroni), so the whole
//! judgement of a clean log raises a false alarm with probability at most
//! [`FALSE_ALARM`]. The thresholds are here and nowhere else.

use std::fmt;

use crate::analysis::runner::{RunResult, Update};

/// The false-alarm probability of the whole judgement (all checks
/// together) on data that fit the model.
pub const FALSE_ALARM: f64 = 0.01;

/// A segment with fewer accepted updates than this is not checked on its
/// own (its updates still count in the overall checks).
pub const MIN_SEGMENT_UPDATES: usize = 30;

/// Exit status of `calibrate` when the data do not fit the model (a
/// [`DataVerdict::Warning`]); 0 is `consistent`, 1 an error, 2 bad
/// arguments.
pub const WARNING_EXIT: u8 = 3;

/// One check of the data against the model.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Check {
    /// `"nis"`, `"whiteness"`, `"bias"` or `"left_out"` (and the path's
    /// `"gimbal_lock"`).
    pub name: &'static str,
    /// Where: `"overall"` or `"segment 2 (t 1800–2700 s)"`, with the
    /// component for whiteness and bias, e.g. `"overall, accel y"`.
    pub scope: String,
    /// The statistic: mean NIS, lag-1 autocorrelation or mean whitened
    /// innovation.
    pub statistic: f64,
    /// The acceptance band `(lower, upper)` of the statistic.
    pub band: (f64, f64),
    /// Whether the statistic is inside the band.
    pub passed: bool,
    /// A short explanation (the number of updates, the distribution).
    pub detail: String,
}

/// The verdict on the data.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case", tag = "verdict")]
pub enum DataVerdict {
    /// Every check passed.
    Consistent,
    /// At least one check failed: the failed checks, worst first (by
    /// how far outside its band, in band half-widths).
    Warning {
        /// The failed checks.
        failed: Vec<Check>,
    },
    /// The checks could not be made (no accepted update of a final pass,
    /// e.g. `--passes 1`): the reason.
    NotChecked {
        /// Why.
        reason: String,
    },
}

impl DataVerdict {
    /// Whether the verdict is a warning.
    pub fn is_warning(&self) -> bool {
        matches!(self, DataVerdict::Warning { .. })
    }
    /// The JSON word: `consistent`, `warning` or `not_checked`.
    pub fn word(&self) -> &'static str {
        match self {
            DataVerdict::Consistent => "consistent",
            DataVerdict::Warning { .. } => "warning",
            DataVerdict::NotChecked { .. } => "not_checked",
        }
    }
}

impl fmt::Display for DataVerdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DataVerdict::Consistent => f.write_str("consistent"),
            DataVerdict::NotChecked { reason } => write!(f, "not checked: {reason}"),
            DataVerdict::Warning { failed } => {
                f.write_str("warning:")?;
                for (i, c) in failed.iter().take(3).enumerate() {
                    let sep = if i == 0 { " " } else { "; " };
                    write!(
                        f,
                        "{sep}{} {} ({:.4} outside [{:.4}, {:.4}])",
                        c.name, c.scope, c.statistic, c.band.0, c.band.1
                    )?;
                }
                if failed.len() > 3 {
                    write!(f, "; and {} more", failed.len() - 3)?;
                }
                Ok(())
            }
        }
    }
}

/// All checks and the verdict.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Judgement {
    /// Every statistical check made, in order: NIS, whiteness, bias.
    pub checks: Vec<Check>,
    /// The path's distance from gimbal lock ([`gimbal_lock_check`]), for
    /// a configuration that measures the gimbal angles: a condition of the
    /// model, not a statistic (it has no false-alarm rate and is not one of
    /// the `checks`). A failed one makes the verdict a warning.
    pub path: Option<Check>,
    /// The verdict.
    pub verdict: DataVerdict,
    /// The significance of each check (`FALSE_ALARM / checks.len()`).
    pub alpha_each: f64,
    /// The likely cause of a warning, when the data say more than "the
    /// model does not fit" ([`likely_cause`]).
    pub cause: Option<String>,
}

/// What the installation model's warning most likely means: a NIS or bias
/// check failed, the signature of an unmodelled constant error of the
/// accelerometer outputs (bias, scale factor) or of the platform's drift
/// (gyro drift, g-sensitive drift), which the installation model takes as
/// calibrated (docs/model.md §Instrument errors). `None` for the full model,
/// or when neither check failed.
pub fn likely_cause(errors: rollcal::models::ErrorModel, verdict: &DataVerdict) -> Option<String> {
    let DataVerdict::Warning { failed } = verdict else {
        return None;
    };
    let signature = failed.iter().any(|c| c.name == "nis" || c.name == "bias");
    (errors == rollcal::models::ErrorModel::Installation && signature).then(|| {
        "likely cause: the instruments' own errors (accelerometer bias or scale factor, \
         gyro drift), which the installation model takes as calibrated: calibrate again \
         with --errors full"
            .to_string()
    })
}

impl Judgement {
    /// The JSON of the judgement: `{"false_alarm", "alpha_each", "checks",
    /// "path", "data_verdict": {"verdict", "failed"|"reason"}}` (`path`
    /// null without gimbal angles).
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "false_alarm": FALSE_ALARM,
            "alpha_each": self.alpha_each,
            "checks": self.checks,
            "path": self.path,
            "data_verdict": self.verdict,
            "likely_cause": self.cause,
        })
    }

    /// This judgement with the path's check `path` ([`gimbal_lock_check`]);
    /// a failed one is put first among the verdict's failed checks (a
    /// verdict that was `consistent` or `not_checked` becomes a warning).
    pub fn with_path(mut self, path: Option<Check>) -> Self {
        if let Some(c) = path.as_ref().filter(|c| !c.passed) {
            match &mut self.verdict {
                DataVerdict::Warning { failed } => failed.insert(0, c.clone()),
                v => {
                    *v = DataVerdict::Warning {
                        failed: vec![c.clone()],
                    }
                }
            }
        }
        self.path = path;
        self
    }
}

/// How close a recorded path came to gimbal lock: the largest angle of the
/// middle gimbal from upright, `acos |cos β|` (°; `|β|` for `|β| ≤ 90°`),
/// over the gimbal angles of `records` (M2 measures them at the end of each
/// period; `calibrate` passes the calibrator's log, the whole run unless
/// the log is incomplete, without the periods predicted only), against [`crate::sim::truth::MAX_GIMBAL_BETA_DEG`], the limit the
/// simulator holds its paths to. Near lock the outer and inner angles'
/// sensitivity to the attitude grows as `1/cos β` and the linearised model
/// breaks down (docs/estimator.md, "Fast rolls"). `None` for a configuration `id` that
/// does not measure the gimbal angles (its model holds through lock; M1's
/// samples carry them all the same) or when no record carries them.
pub fn gimbal_lock_check(
    id: rollcal::models::ConfigId,
    records: &[rollcal::LogRecord<f64>],
) -> Option<Check> {
    if !id.layout().gimbal_obs {
        return None;
    }
    let limit = crate::sim::truth::MAX_GIMBAL_BETA_DEG;
    let (worst, at) = records
        .iter()
        .enumerate()
        .filter_map(|(k, r)| Some((r.observation?.gimbal?.y, k)))
        .map(|(beta, k)| (beta.cos().abs().min(1.0).acos().to_degrees(), k))
        .fold(None, |w: Option<(f64, usize)>, b| match w {
            // NaN angles are refused by the calibrator before the log.
            Some(w) if b.0 <= w.0 => Some(w),
            _ => Some(b),
        })?;
    Some(check(
        "gimbal_lock",
        "path".into(),
        worst,
        (0.0, limit),
        format!(
            "largest |β| of the middle gimbal {worst:.2}° (record {}, t = {:.0} s into the log); gimbal lock at 90°, the model is kept to ≤ {limit}°",
            at + 1,
            records.iter().take(at + 1).map(|r| r.dt).sum::<f64>()
        ),
    ))
}

// The χ² and normal quantiles: one implementation, in `statistics`.
pub use crate::analysis::statistics::{chi2_quantile, normal_quantile};

/// The names of the whitened components of a measurement of `z`
/// components (M2: gimbal α, β, γ then accelerometer x, y, z).
pub fn component_names(z: usize) -> Vec<String> {
    match z {
        3 => ["accel x", "accel y", "accel z"].map(String::from).to_vec(),
        6 => [
            "gimbal alpha",
            "gimbal beta",
            "gimbal gamma",
            "accel x",
            "accel y",
            "accel z",
        ]
        .map(String::from)
        .to_vec(),
        _ => (1..=z).map(|i| format!("component {i}")).collect(),
    }
}

/// A group of updates to check: a scope and the updates.
struct Group<'a> {
    scope: String,
    updates: Vec<&'a Update>,
}

/// The checks of the last pass's updates of `r` and the verdict
/// (see the [module docs](self)).
pub fn judge(r: &RunResult) -> Judgement {
    judge_with(r, &[])
}

/// [`judge`] with the tests `left_out` of the terms the model leaves out
/// (each one more of the `m` checks).
pub fn judge_with(r: &RunResult, left_out: &[Wald]) -> Judgement {
    let mut j = judge_updates_with(&r.updates, &r.segments, left_out);
    j.cause = likely_cause(r.errors, &j.verdict);
    j
}

/// The Wald test of a term the model leaves out
/// ([`crate::analysis::calibration::left_out`]): its statistic `x̂ᵀP⁻¹x̂`,
/// `χ²(dof)` at most when the data have no such term. Its band, `[0,
/// χ²₁₋α(dof)]` at the judgement's `α`, is set by [`judge_updates_with`].
#[derive(Clone, Debug, PartialEq)]
pub struct Wald {
    /// The term and the platform file's key, e.g. `"k2
    /// (instruments.prior.sigma_k2_ug_g2 = 0)"`.
    pub scope: String,
    /// `x̂ᵀP⁻¹x̂`.
    pub statistic: f64,
    /// Its degrees of freedom: the term's number of states.
    pub dof: usize,
    /// The estimate with its σ, and the distribution.
    pub detail: String,
}

/// [`judge`] of updates and segments.
pub fn judge_updates(
    updates: &[Update],
    segments: &[crate::sim::segments::CommandSegment],
) -> Judgement {
    judge_updates_with(updates, segments, &[])
}

/// [`judge_updates`] with the tests `left_out` of the terms the model
/// leaves out: `m` counts them too, each one-sided (`left_out`: the
/// statistic above `χ²₁₋α(dof)` fails).
pub fn judge_updates_with(
    updates: &[Update],
    segments: &[crate::sim::segments::CommandSegment],
    left_out: &[Wald],
) -> Judgement {
    let z = updates.iter().map(|u| u.white.len()).max().unwrap_or(0);
    let ups: Vec<&Update> = updates.iter().filter(|u| u.white.len() == z).collect();
    if z == 0 || ups.len() < 2 {
        let reason = if ups.is_empty() {
            "no innovations of a final pass: the checks need the final passes (not run with --passes 1, or when the log is not the whole run)".to_string()
        } else {
            format!(
                "{} update(s) in the final pass: too few to check",
                ups.len()
            )
        };
        return Judgement {
            checks: Vec::new(),
            path: None,
            verdict: DataVerdict::NotChecked { reason },
            alpha_each: f64::NAN,
            cause: None,
        };
    }
    let names = component_names(z);
    let groups = groups(&ups, segments);
    // m checks: NIS per group, whiteness per component overall, bias per
    // component per segment group.
    let segs = groups.len() - 1;
    let m = groups.len() + z + z * segs + left_out.len();
    let alpha = FALSE_ALARM / m as f64;
    let zq = normal_quantile(1.0 - alpha / 2.0);
    let mut checks = Vec::with_capacity(m);
    nis_checks(&groups, z, alpha, &mut checks);
    whiteness_checks(&groups[0].updates, &names, zq, &mut checks);
    bias_checks(&groups, &names, zq, &mut checks);
    for w in left_out {
        checks.push(check(
            "left_out",
            w.scope.clone(),
            w.statistic,
            (0.0, chi2_quantile(1.0 - alpha, w.dof as f64)),
            w.detail.clone(),
        ));
    }
    let mut failed: Vec<Check> = checks.iter().filter(|c| !c.passed).cloned().collect();
    failed.sort_by(|a, b| excess(b).total_cmp(&excess(a)));
    let verdict = if failed.is_empty() {
        DataVerdict::Consistent
    } else {
        DataVerdict::Warning { failed }
    };
    Judgement {
        checks,
        path: None,
        verdict,
        alpha_each: alpha,
        cause: None,
    }
}

/// The overall group of the updates `ups`, then one per path segment of at
/// least [`MIN_SEGMENT_UPDATES`] updates (when the path has several).
fn groups<'a>(
    ups: &[&'a Update],
    segments: &[crate::sim::segments::CommandSegment],
) -> Vec<Group<'a>> {
    let mut groups = vec![Group {
        scope: "overall".into(),
        updates: ups.to_vec(),
    }];
    if segments.len() > 1 {
        for (i, s) in segments.iter().enumerate() {
            let u: Vec<&Update> = ups
                .iter()
                .copied()
                .filter(|u| (s.first..s.end).contains(&u.index))
                .collect();
            if u.len() >= MIN_SEGMENT_UPDATES {
                groups.push(Group {
                    scope: format!("segment {} (t {:.0}–{:.0} s)", i + 1, s.t0_s, s.t1_s),
                    updates: u,
                });
            }
        }
    }
    groups
}

/// The mean-NIS check of every group, at significance `alpha`.
fn nis_checks(groups: &[Group<'_>], z: usize, alpha: f64, checks: &mut Vec<Check>) {
    for g in groups {
        let n = g.updates.len() as f64;
        let dof = n * z as f64;
        let mean = g.updates.iter().map(|u| u.nis).sum::<f64>() / n;
        let band = (
            chi2_quantile(alpha / 2.0, dof) / n,
            chi2_quantile(1.0 - alpha / 2.0, dof) / n,
        );
        checks.push(check(
            "nis",
            g.scope.clone(),
            mean,
            band,
            format!(
                "{} updates, n·NIS̄ ~ χ²({dof:.0}), expected {z}",
                g.updates.len()
            ),
        ));
    }
}

/// The lag-1 autocorrelation check of every whitened component over the
/// whole log (`overall`), at the two-sided quantile `zq`.
fn whiteness_checks(overall: &[&Update], names: &[String], zq: f64, checks: &mut Vec<Check>) {
    for (c, name) in names.iter().enumerate() {
        let w: Vec<f64> = overall.iter().map(|u| u.white[c]).collect();
        let num: f64 = w.windows(2).map(|p| p[0] * p[1]).sum();
        let den: f64 = w.iter().map(|v| v * v).sum();
        let r1 = if den > 0.0 { num / den } else { f64::NAN };
        let h = zq / (w.len() as f64).sqrt();
        checks.push(check(
            "whiteness",
            format!("overall, {name}"),
            r1,
            (-h, h),
            format!("lag-1 autocorrelation of {} updates, ≈ N(0, 1/n)", w.len()),
        ));
    }
}

/// The mean of every whitened component per segment group, at the
/// two-sided quantile `zq`.
fn bias_checks(groups: &[Group<'_>], names: &[String], zq: f64, checks: &mut Vec<Check>) {
    for g in groups.iter().skip(1) {
        let n = g.updates.len() as f64;
        for (c, name) in names.iter().enumerate() {
            let mean = g.updates.iter().map(|u| u.white[c]).sum::<f64>() / n;
            let h = zq / n.sqrt();
            checks.push(check(
                "bias",
                format!("{}, {name}", g.scope),
                mean,
                (-h, h),
                format!(
                    "mean whitened innovation of {} updates, ≈ N(0, 1/n)",
                    g.updates.len()
                ),
            ));
        }
    }
}

/// How far from its band's middle a check's statistic is, in band
/// half-widths (1: on the edge; NaN: infinitely far).
pub fn excess(c: &Check) -> f64 {
    let half = 0.5 * (c.band.1 - c.band.0);
    let mid = 0.5 * (c.band.1 + c.band.0);
    let e = (c.statistic - mid).abs() / half;
    if e.is_nan() {
        f64::INFINITY
    } else {
        e
    }
}

fn check(
    name: &'static str,
    scope: String,
    statistic: f64,
    band: (f64, f64),
    detail: String,
) -> Check {
    Check {
        name,
        scope,
        statistic,
        band,
        passed: statistic >= band.0 && statistic <= band.1,
        detail,
    }
}

// The cases of `host-sim checks` and their rates: one module of their own.
pub use crate::analysis::check_rates::{cases, judge_simulated, rates, Case, Rate};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::segments::CommandSegment;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    #[test]
    fn quantiles_match_tables() {
        for (p, q) in [
            (0.975, 1.959_963_984_540_054),
            (0.995, 2.575_829_303_548_901),
            (0.5, 0.0),
            (1e-4, -3.719_016_485_455_68),
            (1.0 - 1e-6, 4.753_424_308_822_899),
        ] {
            assert!(
                (normal_quantile(p) - q).abs() < 1e-8 * q.abs().max(1.0),
                "{p}: {}",
                normal_quantile(p)
            );
        }
        assert!(normal_quantile(0.0).is_nan() && normal_quantile(1.0).is_nan());
        // χ² tables: (p, k, quantile).
        for (p, k, q, tol) in [
            (0.975, 10.0, 20.483, 0.002),
            (0.025, 10.0, 3.247, 0.01),
            (0.95, 100.0, 124.342, 0.001),
            (0.05, 100.0, 77.929, 0.001),
            (0.999, 1000.0, 1143.917, 0.001),
        ] {
            let got = chi2_quantile(p, k);
            assert!(((got - q) / q).abs() < tol, "χ²({k}) at {p}: {got} vs {q}");
        }
    }

    fn updates(n: usize, z: usize, seed: u64, f: impl Fn(usize, &mut [f64])) -> Vec<Update> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|k| {
                let mut w: Vec<f64> = (0..z).map(|_| StandardNormal.sample(&mut rng)).collect();
                f(k, &mut w);
                Update {
                    index: k,
                    t_s: k as f64 + 1.0,
                    nis: w.iter().map(|v| v * v).sum(),
                    nu: w.clone(),
                    s_diag: vec![1.0; z],
                    white: w,
                }
            })
            .collect()
    }

    fn segs(n: usize, parts: usize) -> Vec<CommandSegment> {
        (0..parts)
            .map(|i| CommandSegment {
                first: i * n / parts,
                end: (i + 1) * n / parts,
                t0_s: (i * n / parts) as f64,
                t1_s: ((i + 1) * n / parts) as f64,
                rate_rad_s: [0.0; 3],
            })
            .collect()
    }

    #[test]
    fn white_noise_is_consistent_at_the_stated_rate() {
        let s = segs(3000, 6);
        let flagged = (0..200)
            .filter(|seed| {
                judge_updates(&updates(3000, 6, *seed, |_, _| {}), &s)
                    .verdict
                    .is_warning()
            })
            .count();
        // ≤ 1 % expected (Bonferroni is conservative); 6 of 200 would be
        // p ≈ 0.02 at 1 %.
        assert!(flagged <= 6, "{flagged} of 200 clean logs flagged");
        let j = judge_updates(&updates(3000, 6, 1, |_, _| {}), &s);
        assert_eq!(j.checks.len(), 7 + 6 + 36);
        assert!((j.alpha_each - FALSE_ALARM / 49.0).abs() < 1e-15);
    }

    #[test]
    fn wrong_noise_correlation_and_bias_are_named() {
        let s = segs(3000, 6);
        let j = judge_updates(
            &updates(3000, 6, 1, |_, w| w[4] *= 1.5), // accel y noise 1.5×
            &s,
        );
        let DataVerdict::Warning { failed } = &j.verdict else {
            panic!("{:?}", j.verdict)
        };
        assert_eq!(failed[0].name, "nis");
        assert!(j.verdict.to_string().starts_with("warning: nis "));
        // A bias of 0.3σ on accel z in segment 3 only.
        let j = judge_updates(
            &updates(3000, 6, 2, |k, w| {
                if (1000..1500).contains(&k) {
                    w[5] += 0.3;
                }
            }),
            &s,
        );
        let DataVerdict::Warning { failed } = &j.verdict else {
            panic!("{:?}", j.verdict)
        };
        assert_eq!(failed[0].name, "bias");
        assert_eq!(failed[0].scope, "segment 3 (t 1000–1500 s), accel z");
        // AR(1) noise, ρ = 0.3, unit variance, on gimbal alpha.
        let mut prev = 0.0;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let ar: Vec<f64> = (0..3000)
            .map(|_| {
                let e: f64 = StandardNormal.sample(&mut rng);
                prev = 0.3 * prev + (1.0f64 - 0.09).sqrt() * e;
                prev
            })
            .collect();
        let j = judge_updates(&updates(3000, 6, 3, |k, w| w[0] = ar[k]), &s);
        let DataVerdict::Warning { failed } = &j.verdict else {
            panic!("{:?}", j.verdict)
        };
        assert_eq!(
            (failed[0].name, failed[0].scope.as_str()),
            ("whiteness", "overall, gimbal alpha")
        );
    }

    #[test]
    fn no_updates_is_not_checked_and_prints() {
        let j = judge_updates(&[], &[]);
        assert!(matches!(j.verdict, DataVerdict::NotChecked { .. }));
        assert!(j.verdict.to_string().contains("final passes"));
        assert_eq!(DataVerdict::Consistent.to_string(), "consistent");
        let v = j.json();
        assert_eq!(v["data_verdict"]["verdict"], "not_checked");
    }
}
