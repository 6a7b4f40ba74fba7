//! When an answer is an answer (docs/own-platform.md, "Exit status"): the
//! calibrator accepted enough of the samples it was given, the final passes
//! gave the answer, the data checks ran, and the states the configuration
//! observes are observed. [`reasons`] lists what fails; `calibrate` exits
//! with [`NO_ANSWER_EXIT`] when any does. And the share of updates the NIS
//! gate refused ([`Gated`]), with a hint when it is above what the gate
//! takes of a clean log.

use std::fmt;

use rollcal::models::ConfigId;
use rollcal::observability::expected_observable;

use super::rejects::RejectFinding;
use crate::analysis::checks::DataVerdict;
use crate::analysis::runner::RunResult;
use crate::analysis::statistics::chi2_upper_tail;
use crate::analysis::verdict::PRACTICAL_RATIO;

/// Exit status of `calibrate` when the result is not an answer ([`reasons`]);
/// 0 an answer whose data fit the model, 3 an answer with a data warning
/// ([`crate::analysis::checks::WARNING_EXIT`]), 1 an error, 2 bad
/// arguments.
pub const NO_ANSWER_EXIT: u8 = 4;

/// The largest share of the samples given to the calibrator that it may
/// reject for the result to be an answer: a rejected sample loses only its
/// own period, but more than 1 % of them rejected is a systematic cause
/// (units, order, period, columns), which spoils the samples accepted too.
pub const MAX_REJECTED_SHARE: f64 = 0.01;

/// Why a result is not an answer.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum NotAnAnswer {
    /// More than [`MAX_REJECTED_SHARE`] of the samples were rejected.
    Rejected {
        /// Samples rejected.
        rejected: u32,
        /// Samples given to the calibrator (accepted and rejected).
        received: u32,
        /// The largest reason's key, count and likely cause.
        reason: &'static str,
        /// Its count.
        count: u32,
        /// Its likely cause, when known.
        likely_cause: Option<String>,
    },
    /// The final passes did not give the answer (pass 1 only).
    NotFinal {
        /// Why.
        why: String,
    },
    /// The data checks did not run.
    NotChecked {
        /// Why.
        why: String,
    },
    /// States the configuration observes kept σ near their prior: too few
    /// samples (or a path that does not excite them).
    Unobserved {
        /// The states.
        states: Vec<&'static str>,
        /// Samples accepted.
        accepted: u32,
        /// Whether the bound of the received samples is as wide for every
        /// one of them: the log's path does not observe them (a log that
        /// covers part of the path), rather than the calibrator failing
        /// to learn what the log holds.
        path_limited: bool,
    },
}

impl fmt::Display for NotAnAnswer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NotAnAnswer::Rejected {
                rejected,
                received,
                reason,
                count,
                likely_cause,
            } => {
                write!(
                    f,
                    "{rejected} of {received} samples rejected ({:.1} %; {reason} {count}",
                    100.0 * f64::from(*rejected) / f64::from((*received).max(1))
                )?;
                if let Some(c) = likely_cause {
                    write!(f, ": {c}")?;
                }
                f.write_str(")")
            }
            NotAnAnswer::NotFinal { why } => write!(f, "the final passes did not run ({why})"),
            NotAnAnswer::NotChecked { why } => write!(f, "the data were not checked ({why})"),
            NotAnAnswer::Unobserved {
                states,
                accepted,
                path_limited,
            } => {
                let shown: Vec<&str> = states.iter().take(4).copied().collect();
                write!(
                    f,
                    "{} state(s) the configuration observes kept σ ≥ {PRACTICAL_RATIO} of their prior after {accepted} accepted samples ({}{})",
                    states.len(),
                    shown.join(", "),
                    if states.len() > shown.len() { ", …" } else { "" }
                )?;
                if *path_limited {
                    f.write_str(": the path of this log does not observe them (their bound on the received samples is as wide); a log of the whole path does")?;
                }
                Ok(())
            }
        }
    }
}

/// What the result of a calibration lacks to be an answer (empty: an
/// answer). `final_answer`: the final passes gave the answer; `why_not`:
/// why not (the single-pass reason); `requested_single`: `--passes 1` was
/// asked for, so the final passes and the checks are not required;
/// `bound`: σ_CRLB per state along the received samples (rad or the
/// state's internal unit, as `r.states`' σ), when known.
pub fn reasons(
    r: &RunResult,
    bound: Option<&[f64]>,
    accepted: u32,
    findings: &[RejectFinding],
    final_answer: Option<&str>,
    verdict: &DataVerdict,
    requested_single: bool,
) -> Vec<NotAnAnswer> {
    let mut out = Vec::new();
    let rejected: u32 = findings.iter().map(|f| f.count).sum();
    let received = accepted.saturating_add(rejected);
    if f64::from(rejected) > MAX_REJECTED_SHARE * f64::from(received) {
        if let Some(top) = findings.first() {
            out.push(NotAnAnswer::Rejected {
                rejected,
                received,
                reason: top.reason,
                count: top.count,
                likely_cause: top.likely_cause.clone(),
            });
        }
    }
    if !requested_single {
        if let Some(why) = final_answer {
            out.push(NotAnAnswer::NotFinal { why: why.into() });
        }
        if let DataVerdict::NotChecked { reason } = verdict {
            out.push(NotAnAnswer::NotChecked {
                why: reason.clone(),
            });
        }
    }
    let states = unobserved(r.config, r);
    if !states.is_empty() {
        let path_limited = bound.is_some_and(|b| {
            r.states
                .iter()
                .zip(b)
                .filter(|(s, _)| states.contains(&s.name))
                .all(|(s, &b)| b >= PRACTICAL_RATIO * s.prior)
        });
        out.push(NotAnAnswer::Unobserved {
            states,
            accepted,
            path_limited,
        });
    }
    out
}

/// The states configuration `id` observes (the paper's claims) whose σ
/// stayed at or above [`PRACTICAL_RATIO`] of their prior.
fn unobserved(id: ConfigId, r: &RunResult) -> Vec<&'static str> {
    r.states
        .iter()
        .filter(|s| expected_observable(id, s.name, s.info.group))
        .filter(|s| s.sigma_rad.is_nan() || s.sigma_rad >= PRACTICAL_RATIO * s.prior)
        .map(|s| s.name)
        .collect()
}

/// The updates the NIS gate refused.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Gated {
    /// The gate (0: none).
    pub gate: f64,
    /// Degrees of freedom of an update.
    pub dof: usize,
    /// Refused in pass 1 (the calibrator's running filter).
    pub pass1: u32,
    /// Refused in the last of the final passes, when they ran.
    pub last_pass: Option<u32>,
    /// The measured samples of a pass.
    pub updates: u32,
    /// The share a clean log gates (`P(χ²(dof) > gate)`).
    pub expected_share: f64,
    /// The hint when the last pass (else pass 1) gated more than a clean
    /// log could.
    pub hint: Option<String>,
}

impl Gated {
    /// The gated updates of a calibration: `pass1` and `last_pass` refused
    /// of `updates` measured samples, gate `gate` on `dof` degrees of
    /// freedom. A clean log gates `n·p` on average (`p =
    /// P(χ²(dof) > gate)`); more than `n·p + 4√(n·p) + 2` (a Poisson count
    /// far in its tail) gets the hint.
    pub fn of(gate: f64, dof: usize, pass1: u32, last_pass: Option<u32>, updates: u32) -> Self {
        let p = if gate > 0.0 {
            chi2_upper_tail(gate, dof)
        } else {
            0.0
        };
        let mean = p * f64::from(updates);
        let gated = last_pass.unwrap_or(pass1);
        let hint = (gate > 0.0 && f64::from(gated) > mean + 4.0 * mean.sqrt() + 2.0).then(|| {
            format!(
                "the gate refused {gated} of {updates} updates ({:.1} %); a log the model describes loses {:.1e} of them to a gate of {gate} on {dof} degrees of freedom: outliers, or noise levels below the data's (see the data verdict)",
                100.0 * f64::from(gated) / f64::from(updates.max(1)),
                p
            )
        });
        Gated {
            gate,
            dof,
            pass1,
            last_pass,
            updates,
            expected_share: p,
            hint,
        }
    }
}
