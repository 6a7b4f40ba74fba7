//! What the session answered after the stream, as a [`Calibration`]: the
//! final passes (unless `--passes 1`), the truth sidecar's values and the
//! bound of the samples received, the result as a run's.

use std::fmt;

use nalgebra::RealField;
use rollcal::ekf::FilterConfig;
use rollcal::estimator::{LogRecord, LogStart};
use rollcal::models::{ConfigId, ErrorModel};
use rollcal::wire::{CalibratorConfig, DecoderStats, Estimate, EstimateKind, VERSION};

use super::bound::{bound_at_estimate, state_at_start, truth_at_start, CalibratorView};
use super::host::{Final, Host, Refused};
use super::rejects::{findings, RejectFinding, SampleSource};
use super::trust::{self, Gated, NotAnAnswer};
use crate::analysis::checks::Judgement;
use crate::analysis::runner::{self, Passes, RunResult};
use crate::analysis::verdict::Verdict;
use crate::io::sidecar::Sidecar;

/// What a calibration gave: everything the printed table, the JSON, the
/// matrices and the report need, computed once.
pub struct Calibration {
    /// The configuration of the stream.
    pub id: ConfigId,
    /// The calibrator's settings.
    pub settings: CalibratorConfig,
    /// The calibrator's running estimate (pass 1).
    pub est: Estimate,
    /// The decoder's counters.
    pub stats: DecoderStats,
    /// The truth sidecar, when given.
    pub sidecar: Option<Sidecar>,
    /// Where the log started on the path.
    pub start: LogStart,
    /// The true state at the log's start (with a sidecar and a complete
    /// log).
    pub truth_start: Option<Vec<f64>>,
    /// The bound of the samples received (with a sidecar and a complete log).
    pub received_bound: Option<Vec<f64>>,
    /// σ_CRLB per state: the bound of the samples received, else the full
    /// run's from the sidecar, else NaN.
    pub crlb: Vec<f64>,
    /// The estimator of record's final passes (None with `--passes 1`).
    pub fin: Option<Final>,
    /// Whether the final passes are the answer (else pass 1).
    pub final_answer: bool,
    /// The result as a run's.
    pub r: RunResult,
    /// The calibrator's log in f64 (after the final passes).
    pub records: Vec<LogRecord<f64>>,
    /// The session's restarts (`Configure` after the first, `Reset`).
    pub restarts: u32,
    /// Messages the session ignored.
    pub ignored: u32,
    /// Without a truth: the bound at the estimate along the received path
    /// and its verdict per state ([`bound_at_estimate`]).
    pub at_estimate: Option<(Vec<f64>, Vec<Verdict>)>,
    /// The data judged against the model ([`crate::analysis::checks::judge`]) with the
    /// path's distance from gimbal lock.
    pub judgement: Judgement,
    /// Notes for the user (how the bound was taken, an incomplete answer).
    pub notes: Vec<String>,
    /// The rejected samples by reason, largest first.
    pub rejects: Vec<RejectFinding>,
    /// The updates the NIS gate refused.
    pub gated: Gated,
    /// What the result lacks to be an answer (empty: an answer).
    pub not_an_answer: Vec<NotAnAnswer>,
    /// The messages the session refused.
    pub refusals: Vec<Refused>,
}

/// What [`Calibration::of`] needs besides the session.
#[derive(Clone, Copy, Debug, Default)]
pub struct Context<'a> {
    /// At most this many passes (1: the calibrator's pass 1, asked for).
    pub passes: u8,
    /// Where the samples came from (CSV lines), for naming a sample.
    pub source: SampleSource<'a>,
    /// The platform's latitude (°), for the likely cause of a warning.
    pub latitude_deg: Option<f64>,
}

/// Why the session gave no calibration to report.
#[derive(Debug)]
pub enum CalibrationError {
    /// Every frame was of another protocol version.
    OtherVersion {
        /// The version of the frames.
        version: u8,
        /// How many frames of it.
        frames: u32,
    },
    /// No `Configure` and no sample reached the session.
    NoSamples {
        /// Frames decoded.
        ok: u32,
        /// Frames rejected.
        rejected: u32,
    },
    /// The calibrator accepted no sample: why each was rejected.
    NoneAccepted {
        /// Samples rejected.
        rejected: u32,
        /// Frames rejected.
        bad_frames: u32,
        /// The rejected samples by reason, largest first.
        findings: Vec<RejectFinding>,
    },
    /// The stream's `Configure` was refused, and no calibrator ran.
    ConfigureRefused(String),
    /// The bound of the received samples could not be computed.
    Bound(String),
    /// The bound at the estimate could not be computed.
    Analysis(crate::analysis::Error),
}

impl fmt::Display for CalibrationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CalibrationError::OtherVersion { version, frames } => write!(
                f,
                "the stream is of protocol version {version} ({frames} frames), this host-sim reads version {VERSION}: record it again with this version"
            ),
            CalibrationError::NoSamples { ok, rejected } => write!(
                f,
                "no samples in the stream ({ok} frames decoded, {rejected} rejected)"
            ),
            CalibrationError::NoneAccepted {
                rejected,
                bad_frames,
                findings,
            } => {
                write!(
                    f,
                    "no sample accepted ({rejected} rejected, {bad_frames} bad frames"
                )?;
                if let Some(top) = findings.first() {
                    write!(f, "; {} {}", top.reason, top.count)?;
                    if let Some(c) = &top.likely_cause {
                        write!(f, ": {c}")?;
                    }
                }
                f.write_str(")")
            }
            CalibrationError::ConfigureRefused(e) => write!(
                f,
                "the stream's Configure was refused ({e}): no calibrator ran"
            ),
            CalibrationError::Bound(e) => write!(f, "Cramér–Rao bound of the received samples: {e}"),
            CalibrationError::Analysis(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for CalibrationError {}

impl<T: RealField + Copy> Host<T> {
    /// The configuration of the session's calibrator, or why there is
    /// none (`stats`: the decoder's counters).
    pub fn configured(&self, stats: &DecoderStats) -> Result<ConfigId, CalibrationError> {
        if let (None, Some(v)) = (self.session.calibrator(), self.other_version) {
            return Err(CalibrationError::OtherVersion {
                version: v,
                frames: stats.wrong_version,
            });
        }
        if let (None, Some(r)) = (
            self.session.calibrator(),
            self.refusals.iter().find(|r| r.message == 3),
        ) {
            return Err(CalibrationError::ConfigureRefused(r.error.to_string()));
        }
        self.session
            .calibrator()
            .map(|c| c.settings().config)
            .ok_or(CalibrationError::NoSamples {
                ok: stats.ok,
                rejected: stats.errors(),
            })
    }
}

impl Calibration {
    /// The answer of the session in `host` after the stream: the final
    /// passes (at most `passes`; none for 1), with the decoder's counters
    /// `stats` and the truth `sidecar`.
    pub fn of<T: RealField + Copy>(
        host: &mut Host<T>,
        stats: DecoderStats,
        sidecar: Option<Sidecar>,
        ctx: &Context<'_>,
    ) -> Result<Self, CalibrationError> {
        let passes = ctx.passes;
        let id = host.configured(&stats)?;
        let (settings, est, running_covariance, rejects) = running(host, &stats, ctx)?;
        let layout = id.layout_with(settings.errors);
        let nan = vec![f64::NAN; layout.n()];
        let (start, truth_start, received_bound) =
            received(&settings, sidecar.as_ref(), &est, host)?;
        // The sidecar's bound is the installation model's: not the full model's.
        let crlb = received_bound
            .as_ref()
            .or(sidecar
                .as_ref()
                .map(|s| &s.crlb)
                .filter(|_| settings.errors == ErrorModel::Installation))
            .unwrap_or(&nan)
            .clone();
        // The final answer: the calibrator's own estimator of record over its
        // log (pass 1 alone with --passes 1, or when the log is incomplete).
        let fin = if passes > 1 {
            host.finish(passes)
        } else {
            None
        };
        let truth = sidecar
            .as_ref()
            .map_or_else(|| nan.clone(), |s| log_end_truth(s, &settings, &est));
        let sigma0 = runner::prior_sigma_of(&settings);
        let r = result(
            &settings,
            host,
            &est,
            fin.as_ref(),
            running_covariance,
            &truth,
            &sigma0,
        );
        let final_answer = fin
            .as_ref()
            .is_some_and(|f| matches!(f.estimate.kind, EstimateKind::Final { .. }));
        let mut notes = Vec::new();
        let single = single_pass(fin.as_ref(), &mut notes);
        let records = host.log.records_f64();
        // Without a truth, the bound at the estimate; an estimate the bound
        // cannot be linearised at (data far from the model) is noted, and
        // the checks still judge the data.
        let at_estimate = match &sidecar {
            None => match at_estimate(&settings, &start, &est, &r, &records, &mut notes) {
                Ok(b) => Some(b),
                Err(e) => {
                    notes.push(format!("note: no bound at the estimate ({e})"));
                    None
                }
            },
            Some(_) => None,
        };
        let judgement = super::judge(&settings, &r, &records, ctx.latitude_deg);
        let measured = records.iter().filter(|r| r.observation.is_some()).count();
        let gated = Gated::of(
            settings.options.nis_gate,
            layout.z(),
            est.progress.gated,
            fin.as_ref().filter(|_| final_answer).map(|f| f.gated),
            u32::try_from(measured).unwrap_or(u32::MAX),
        );
        let bound = received_bound
            .as_deref()
            .or(at_estimate.as_ref().map(|(b, _)| b.as_slice()));
        let not_an_answer = trust::reasons(
            &r,
            bound,
            est.progress.accepted,
            &rejects,
            single.as_deref(),
            &judgement.verdict,
            passes == 1,
        );
        Ok(Calibration {
            id,
            settings,
            est,
            stats,
            sidecar,
            start,
            truth_start,
            received_bound,
            crlb,
            fin,
            final_answer,
            r,
            records,
            restarts: host.session.stats().restarts,
            ignored: host.session.stats().ignored,
            at_estimate,
            judgement,
            notes,
            rejects,
            gated,
            not_an_answer,
            refusals: host.refusals.clone(),
        })
    }
}

/// The session's calibrator after the stream: its settings, its running
/// estimate (pass 1), the running filter's covariance (the answer when the
/// final passes do not run) and the rejected samples by reason; with no
/// sample accepted, [`CalibrationError::NoneAccepted`].
#[allow(clippy::type_complexity)]
fn running<T: RealField + Copy>(
    host: &mut Host<T>,
    stats: &DecoderStats,
    ctx: &Context<'_>,
) -> Result<(CalibratorConfig, Estimate, Vec<f64>, Vec<RejectFinding>), CalibrationError> {
    let Some(cal) = host.session.calibrator_mut() else {
        return Err(CalibrationError::NoSamples {
            ok: stats.ok,
            rejected: stats.errors(),
        });
    };
    cal.set_frame_errors(stats.errors());
    let settings = *cal.settings();
    let est = cal.estimate();
    let layout = settings.config.layout_with(settings.errors);
    let covariance =
        crate::analysis::compensation::covariance_of_packed_ud(&layout, &cal.checkpoint().factor);
    let rejects = findings(
        &est.progress.rejects,
        &host.first_rejects,
        &settings,
        ctx.source,
    );
    if est.progress.accepted == 0 {
        return Err(CalibrationError::NoneAccepted {
            rejected: est.progress.rejects.total(),
            bad_frames: stats.errors(),
            findings: rejects,
        });
    }
    Ok((settings, est, covariance, rejects))
}

/// Why the final passes are not the answer (`None` when they are), noted
/// for the user when the calibrator says why.
fn single_pass(fin: Option<&Final>, notes: &mut Vec<String>) -> Option<String> {
    match fin.map(|f| f.estimate.kind) {
        Some(EstimateKind::SinglePass { reason, .. }) => {
            notes.push(format!(
                "note: {reason}: the final answer is the calibrator's pass 1"
            ));
            Some(reason.to_string())
        }
        Some(_) => None,
        None => Some("--passes 1".to_string()),
    }
}

/// The bound at the estimate and its verdicts, for a calibration without
/// a truth (docs/own-platform.md, "Judging a calibration without a
/// truth"), from the log's start `start`. A log that is not the whole run
/// (re-acquired attitude, full log) has no start of the final passes: the
/// bound along the logged records from the cold start (the prior estimate
/// at the log's start, as pass 1), said so in `notes`.
fn at_estimate(
    settings: &CalibratorConfig,
    start: &LogStart,
    est: &Estimate,
    r: &RunResult,
    records: &[LogRecord<f64>],
    notes: &mut Vec<String>,
) -> Result<(Vec<f64>, Vec<Verdict>), CalibrationError> {
    let p = &est.progress;
    let x_start = if p.log_incomplete.is_some() {
        notes.push(format!(
            "note: the log is not the whole run: the bound is taken from the cold start along the {} logged samples only (of {} accepted)",
            records.len(),
            p.accepted
        ));
        None
    } else {
        let end: Vec<f64> = r.states.iter().map(|s| s.estimate_rad).collect();
        Some(state_at_start(settings, start, &end, records).map_err(CalibrationError::Analysis)?)
    };
    bound_at_estimate(settings, start, x_start.as_deref(), records)
        .map_err(CalibrationError::Analysis)
}

impl Calibration {
    /// σ_CRLB(t) for the report: the bound of the received samples along
    /// the log, when it was computed (a truth sidecar with the initial
    /// state and a complete log).
    pub fn crlb_history(&self) -> Result<Option<Vec<Vec<f64>>>, CalibrationError> {
        let errors = self.settings.errors;
        match self.truth_start.as_ref() {
            Some(t0) if self.received_bound.is_some() => runner::bound_history(
                self.id,
                errors,
                FilterConfig::<f64>::from(&self.settings),
                t0,
                &self.start,
                &runner::prior_sigma_of(&self.settings),
                &self.records,
            )
            .map(Some)
            .map_err(|e| CalibrationError::Bound(e.to_string())),
            _ => Ok(None),
        }
    }
}

/// Where the log started on the path, the true state there (with a
/// sidecar and a complete log) and the bound of the samples actually
/// received: the bound over the same log (the bridged periods predicted
/// only) from that true state; `None` without one (no sidecar, or a log
/// that is not the whole run: then the full run's bound of the sidecar is
/// the one shown).
#[allow(clippy::type_complexity)]
fn received<T: RealField + Copy>(
    settings: &CalibratorConfig,
    sidecar: Option<&Sidecar>,
    est: &Estimate,
    host: &mut Host<T>,
) -> Result<(LogStart, Option<Vec<f64>>, Option<Vec<f64>>), CalibrationError> {
    let start = host.log_start().map_err(CalibrationError::Analysis)?;
    let records = host.log.records_f64();
    let truth_start = match (sidecar, est.progress.log_incomplete) {
        (Some(s), None) => truth_at_start(
            settings,
            &start,
            (
                s.truth0_of(settings.errors),
                &log_end_truth(s, settings, est),
            ),
            &records,
        )
        .map_err(CalibrationError::Analysis)?,
        _ => None,
    };
    let sigma0 = runner::prior_sigma_of(settings);
    let bound = truth_start
        .as_deref()
        .map(|t0| {
            runner::bound(
                settings.config,
                settings.errors,
                FilterConfig::<f64>::from(settings),
                t0,
                &start,
                &sigma0,
                &records,
            )
            .map_err(|e| CalibrationError::Bound(e.to_string()))
        })
        .transpose()?;
    Ok((start, truth_start, bound))
}

/// The true state at the end of the log (its last sample's period, by its
/// sequence number: a recording numbers its periods from 1): the sidecar's
/// final state, or, for a log that lost its last samples, the state at
/// that period ([`Sidecar::truth_at_period`]: the attitude moved since).
fn log_end_truth(s: &Sidecar, settings: &CalibratorConfig, est: &Estimate) -> Vec<f64> {
    est.progress
        .last_seq
        .and_then(|k| s.truth_at_period(settings.errors, k))
        .unwrap_or_else(|| s.truth_of(settings.errors))
}

/// The answer as a run's result: the final passes' estimate, σ,
/// covariance, innovations and history when they are the answer, else
/// pass 1's (with the running filter's covariance).
fn result<T: RealField + Copy>(
    settings: &CalibratorConfig,
    host: &Host<T>,
    est: &Estimate,
    fin: Option<&Final>,
    running_covariance: Vec<f64>,
    truth: &[f64],
    sigma0: &[f64],
) -> RunResult {
    // The last pass of the estimator of record (None: pass 1 is the answer,
    // whose innovations and history were not kept).
    let final_pass = fin.filter(|f| matches!(f.estimate.kind, EstimateKind::Final { .. }));
    let (state, sigma, nis, passes) = match final_pass {
        Some(Final { estimate, nis, .. }) => {
            let passes = match estimate.kind {
                EstimateKind::Final { passes, .. } => passes,
                _ => 1,
            };
            (&estimate.state, &estimate.sigma, nis.clone(), passes)
        }
        None => (&est.state, &est.sigma, host.nis.clone(), 1),
    };
    // Failures of the last pass are counted in the estimate's report,
    // not listed; the table shows the pass-1 failures.
    runner::result(
        settings.config,
        settings.errors,
        &Passes {
            filter: Box::new(CalibratorView {
                state: state.to_vec(),
                sigma: sigma.to_vec(),
                covariance: match final_pass {
                    Some(f) => f.covariance.clone(),
                    None => running_covariance,
                },
            }),
            history: final_pass.map(|f| f.history.clone()).unwrap_or_default(),
            nis,
            updates: final_pass.map(|f| f.updates.clone()).unwrap_or_default(),
            segments: crate::sim::segments::command_segments(
                host.log.records.iter().map(|r| (r.dt, r.dtheta_cmd.into())),
            ),
            failures: host.failures.clone(),
            passes,
        },
        truth,
        sigma0,
    )
}
