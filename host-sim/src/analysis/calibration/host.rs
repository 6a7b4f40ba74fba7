//! The host's side of the session: the no_std session
//! ([`rollcal::session::Session`]) with the host's sample log, the NIS and
//! failures of every accepted sample, and the estimator of record's final
//! passes with their covariance.

use nalgebra::RealField;
use rollcal::calibrator::RejectReason;
use rollcal::ekf;
use rollcal::estimator::{
    EstimatorOptions, LogError, LogRecord, LogStart, PackedLayout, PassEvent, SampleLog,
};
use rollcal::models::{ConfigId, ErrorModel, Model};
use rollcal::session::{Covariance, PassObserver, Reply, Session, SessionError};
use rollcal::wire::{CalibratorConfig, Estimate, Message};

use super::rejects::FirstRejects;
use crate::analysis::runner;

/// How the host's sample log keeps a record.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum LogStorage {
    /// Every record as the calibrator logs it.
    #[default]
    Exact,
    /// Each record rounded as a compact log stores it (the firmware's log
    /// in flash, `rollcal::estimator::FlashLog`, and `PackedLog`: 2⁻⁴⁰ rad,
    /// 2⁻²⁷ g, 2π/2²⁴ rad), so that the final passes are the device's to
    /// the last bit.
    Packed,
}

/// The host's sample log: a vector that grows as needed.
pub struct VecLog<T: RealField + Copy = f64> {
    /// The records, as the final passes read them.
    pub records: Vec<LogRecord<T>>,
    /// How a record is kept.
    pub storage: LogStorage,
}

impl<T: RealField + Copy> Default for VecLog<T> {
    fn default() -> Self {
        Self {
            records: Vec::new(),
            storage: LogStorage::default(),
        }
    }
}

impl<T: RealField + Copy> VecLog<T> {
    /// The records in f64 (exact for f32).
    pub fn records_f64(&self) -> Vec<LogRecord<f64>> {
        let f = |v: T| v.to_subset().unwrap_or(f64::NAN);
        self.records
            .iter()
            .map(|r| LogRecord {
                dt: r.dt,
                dtheta_cmd: r.dtheta_cmd,
                observation: r.observation.map(|o| ekf::Observation {
                    accel_mean: o.accel_mean.map(f),
                    gimbal: o.gimbal.map(|g| g.map(f)),
                }),
            })
            .collect()
    }
}

impl<T: RealField + Copy> SampleLog<T> for VecLog<T> {
    /// With [`LogStorage::Packed`], the record as `FlashLog` gives it back
    /// (its period length must be an `f32`, as the wire's are), or refused
    /// as it refuses it.
    fn append(&mut self, r: &LogRecord<T>) -> Result<(), LogError> {
        let r = match self.storage {
            LogStorage::Exact => *r,
            LogStorage::Packed => PackedLayout::AccelGimbal
                .round_trip(r)
                .filter(|_| f64::from(r.dt as f32) == r.dt)
                .ok_or(LogError::Unrepresentable)?,
        };
        self.records.push(r);
        Ok(())
    }
    fn len(&self) -> usize {
        self.records.len()
    }
    fn truncate(&mut self, len: usize) {
        self.records.truncate(len);
    }
    fn get(&mut self, k: usize) -> Option<LogRecord<T>> {
        self.records.get(k).copied()
    }
}

/// The final answer of the session's calibrator.
pub struct Final {
    pub estimate: Estimate,
    /// NIS of every update of the last pass.
    pub nis: Vec<f64>,
    /// The accepted updates of the last pass.
    pub updates: Vec<runner::Update>,
    /// Time history of the last pass: (t, estimate, σ) per record.
    pub history: Vec<(f64, Vec<f64>, Vec<f64>)>,
    /// Covariance of the final filter, row-major (rad²; empty when the
    /// passes did not run).
    pub covariance: Vec<f64>,
    /// Updates of the last pass refused by the NIS gate.
    pub gated: u32,
}

/// A message the session refused (the calibrator left as it was): the
/// message's tag ([`Message::tag`]) and why.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refused {
    /// The refused message's tag.
    pub message: u8,
    /// Why.
    pub error: SessionError,
}

/// Why the host stops reading a stream.
#[derive(Clone, Debug, PartialEq)]
pub enum HostError {
    /// A sample before any `Configure`, and no settings of the host's own.
    NoConfigure,
    /// The stream configures another configuration than the one asked for
    /// (`--config`, the platform file).
    Contradiction(SessionError),
    /// The host's own settings (platform file, scenario) were refused.
    Settings(SessionError),
}

impl std::fmt::Display for HostError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HostError::NoConfigure => f.write_str("the stream has no Configure message: give --config (and --platform FILE for the platform's settings)"),
            HostError::Contradiction(e) => write!(f, "{e}"),
            HostError::Settings(e) => write!(f, "calibrator: {e}"),
        }
    }
}

impl std::error::Error for HostError {}

/// The no_std session (the protocol, once) with the host's log and records
/// for the report.
pub struct Host<T: RealField + Copy> {
    pub session: Session<T>,
    /// Settings for a stream without a `Configure` message (`--platform`
    /// or `--scenario`), when the configuration is known.
    pub fallback: Option<CalibratorConfig>,
    /// The sample log since the last (re)start, for the final passes.
    pub log: VecLog<T>,
    /// NIS of every accepted update since the last (re)start.
    pub nis: Vec<f64>,
    /// Filter failures (sequence number, error).
    pub failures: Vec<(u32, ekf::Error)>,
    /// Where the fallback settings come from, for the note.
    pub fallback_of: String,
    /// Notes for the user (a missing `Configure`, a restart, a refusal),
    /// to print after each [`Host::handle`].
    pub notes: Vec<String>,
    /// The error model every `Configure` is run with (`calibrate
    /// --errors`), whatever it asks for; `None`: the message's.
    pub errors: Option<ErrorModel>,
    /// The protocol version of the last frame of another version seen.
    pub other_version: Option<u8>,
    /// The first rejected sample of each reason since the last (re)start.
    pub first_rejects: FirstRejects,
    /// Every message the session refused.
    pub refusals: Vec<Refused>,
    /// Whether a `Configure` came in the stream.
    pub configure_seen: bool,
    /// Whether a `Finish` was answered after the last sample.
    pub finished: bool,
}

impl<T: RealField + Copy> Host<T> {
    /// A host of a fresh session expecting configuration `expected` (if
    /// known), with the settings `fallback` for a stream without a
    /// `Configure`, taken from `fallback_of`; a `Finish` in the stream runs
    /// at most `passes` passes.
    pub fn new(
        expected: Option<ConfigId>,
        fallback: Option<CalibratorConfig>,
        fallback_of: String,
        passes: u8,
    ) -> Self {
        let passes = EstimatorOptions {
            max_passes: passes,
            ..EstimatorOptions::default()
        };
        Self {
            session: Session::new(expected, passes),
            fallback,
            log: VecLog::default(),
            nis: Vec::new(),
            failures: Vec::new(),
            fallback_of,
            notes: Vec::new(),
            errors: None,
            other_version: None,
            first_rejects: FirstRejects::default(),
            refusals: Vec::new(),
            configure_seen: false,
            finished: false,
        }
    }

    /// Hands message `m` to the session (configuring it with the fallback
    /// settings at a first sample of a stream without a `Configure`),
    /// keeping the NIS and the failures of the accepted samples and the
    /// first rejected sample of each reason; returns what a calibrator sends
    /// back: the session's replies (estimates, checkpoints) and the wire
    /// form of a refusal ([`Message::Refused`]). A refused message leaves
    /// the session as it was and the stream goes on; only a stream the host
    /// cannot run at all stops it ([`HostError`]).
    pub fn handle(&mut self, m: Message) -> Result<Vec<Message>, HostError> {
        let m = match (m, self.errors) {
            (Message::Configure(settings), Some(errors)) => {
                Message::Configure(CalibratorConfig { errors, ..settings })
            }
            (m, _) => m,
        };
        if matches!(m, Message::Sample(_))
            && self.session.calibrator().is_none()
            && !self.configure_seen
        {
            let fallback = self.fallback.ok_or(HostError::NoConfigure)?;
            self.notes.push(format!(
                "note: the stream has no Configure message; using the settings of {}",
                self.fallback_of
            ));
            self.session
                .configure(fallback)
                .map_err(HostError::Settings)?;
        }
        let running = self.session.calibrator().is_some();
        let last = self.session.calibrator().and_then(|c| {
            let p = c.progress();
            p.last_seq.zip(p.last_t_us)
        });
        self.configure_seen |= matches!(m, Message::Configure(_));
        let mut out = Vec::new();
        match self.session.handle(&m, &mut self.log) {
            Reply::Error(e @ SessionError::ConfigMismatch { .. })
                if matches!(m, Message::Configure(_)) =>
            {
                return Err(HostError::Contradiction(e));
            }
            Reply::Error(e) => {
                self.refused(&m, e);
                out.push(Message::Refused(e.refusal(m.tag())));
            }
            Reply::Send(reply) => {
                self.finished |= matches!(m, Message::Finish);
                out.push(reply);
            }
            Reply::Rejected(r) => {
                if let Message::Sample(s) = &m {
                    self.first_rejects.note(&r, s, last);
                    if let RejectReason::Filter(e) = r {
                        self.failures.push((s.seq, e));
                    }
                }
            }
            Reply::Nothing => {
                if matches!(m, Message::Configure(_) | Message::Reset) {
                    if running {
                        self.notes.push(format!(
                            "\nnote: {} mid-stream: restarting the calibrator",
                            tag(&m)
                        ));
                    }
                    self.nis.clear();
                    self.failures.clear();
                    self.first_rejects.first.clear();
                }
            }
        }
        if let Message::Sample(s) = &m {
            self.first_rejects.samples += 1;
            self.finished = false;
            if let Some(cal) = self.session.calibrator() {
                if cal.progress().last_seq == Some(s.seq) && last.map(|l| l.0) != Some(s.seq) {
                    self.nis.push(cal.progress().last_nis);
                }
            }
        }
        Ok(out)
    }

    /// Notes the refusal of `m` (the first of each message and reason
    /// printed, every one counted).
    fn refused(&mut self, m: &Message, error: SessionError) {
        let r = Refused {
            message: m.tag(),
            error,
        };
        if !self.refusals.contains(&r) {
            self.notes.push(format!(
                "note: {} refused ({error}); the calibrator is as it was",
                tag(m)
            ));
        }
        self.refusals.push(r);
    }

    /// Where the log of the session's calibrator started
    /// ([`rollcal::calibrator::Calibrator::log_start`]; the path's start
    /// before it is configured).
    pub fn log_start(&mut self) -> Result<LogStart, crate::analysis::Error> {
        match self.session.calibrator() {
            Some(cal) => {
                cal.log_start(&mut self.log)
                    .map_err(|source| crate::analysis::Error::Estimator {
                        context: "the start of the log".into(),
                        source,
                    })
            }
            None => Ok(LogStart::aligned()),
        }
    }

    /// The estimator of record over the log, at most `passes` passes,
    /// with the last pass's innovations, history and covariance.
    pub fn finish(&mut self, passes: u8) -> Option<Final> {
        let opts = EstimatorOptions {
            max_passes: passes,
            ..EstimatorOptions::default()
        };
        let cal = self.session.calibrator()?;
        let mut last = LastPass::default();
        let mut covariance = Covariance::new();
        let estimate = cal.finish_with_covariance(&mut self.log, &opts, &mut last, &mut covariance);
        let LastPass {
            nis,
            updates,
            history,
            gated,
            ..
        } = last;
        let covariance = covariance.to_vec();
        Some(Final {
            estimate,
            nis,
            updates,
            history,
            covariance,
            gated,
        })
    }
}

/// What [`Host::finish`] keeps of the passes of
/// [`rollcal::session::AnyCalibrator::finish_with_covariance`]: the last
/// pass's NIS, updates and history (time, estimate and σ after every
/// record).
#[derive(Default)]
struct LastPass {
    /// The pass being recorded (number, from 1; 0 before the first).
    pass: u8,
    /// Time at the end of the last record's period (s from the start of
    /// the log).
    t_s: f64,
    /// NIS of every accepted update of the pass.
    nis: Vec<f64>,
    /// Every accepted update of the pass.
    updates: Vec<runner::Update>,
    /// Time (s), estimate (rad) and σ (rad) after every record of the pass.
    history: Vec<(f64, Vec<f64>, Vec<f64>)>,
    /// Updates of the pass refused by the NIS gate.
    gated: u32,
}

impl<T: RealField + Copy> PassObserver<T> for LastPass {
    fn step<M: Model<N, Z>, const N: usize, const Z: usize>(
        &mut self,
        e: &PassEvent<'_, T, M, N, Z>,
    ) {
        let f = |v: &T| v.to_subset().unwrap_or(f64::NAN);
        self.t_s = if e.index == 0 { 0.0 } else { self.t_s } + e.record.dt;
        let t = self.t_s;
        if e.pass != self.pass {
            (self.pass, self.nis, self.updates, self.history, self.gated) =
                (e.pass, Vec::new(), Vec::new(), Vec::new(), 0);
        }
        if matches!(e.result, Err(ekf::Error::Gated)) {
            self.gated += 1;
        }
        if let Ok(Some(i)) = &e.result {
            let u = runner::Update::of(e.index, t, i);
            self.nis.push(u.nis);
            self.updates.push(u);
        }
        self.history.push((
            t,
            e.filter.state().iter().copied().collect(),
            e.filter.sigma().iter().map(f).collect(),
        ));
    }
}

/// The name of a message, for the notes.
pub fn tag(m: &Message) -> &'static str {
    name_of(m.tag())
}

/// The name of the message of tag `tag` ([`Message::tag`]).
pub fn name_of(tag: u8) -> &'static str {
    match tag {
        0 => "Sample",
        1 => "Estimate",
        2 => "Checkpoint (restore)",
        3 => "Configure",
        4 => "Reset",
        5 => "CheckpointRequest",
        6 => "EstimateRequest",
        7 => "Finish",
        8 => "Refused",
        _ => "message",
    }
}
