//! The host's side of the session: the no_std session
//! ([`rollcal::session::Session`]) with the host's sample log, the NIS and
//! failures of every accepted sample, and the estimator of record's final
//! passes with their covariance.

use nalgebra::RealField;
use rollcal::calibrator::RejectReason;
use rollcal::ekf;
use rollcal::estimator::{
    EstimatorOptions, LogError, LogRecord, PackedLayout, PassEvent, SampleLog,
};
use rollcal::models::{ConfigId, ErrorModel, Model};
use rollcal::session::{Covariance, PassObserver, Reply, Session};
use rollcal::wire::{CalibratorConfig, Estimate, Message};

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
}

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
    /// Notes for the user (a missing `Configure`, a restart), to print
    /// after each [`Host::handle`].
    pub notes: Vec<String>,
    /// The error model every `Configure` is run with (`calibrate
    /// --errors`), whatever it asks for; `None`: the message's.
    pub errors: Option<ErrorModel>,
    /// The protocol version of the last frame of another version seen.
    pub other_version: Option<u8>,
}

impl<T: RealField + Copy> Host<T> {
    /// A host of a fresh session expecting configuration `expected` (if
    /// known), with the settings `fallback` for a stream without a
    /// `Configure`, taken from `fallback_of`.
    pub fn new(
        expected: Option<ConfigId>,
        fallback: Option<CalibratorConfig>,
        fallback_of: String,
    ) -> Self {
        Self {
            session: Session::new(expected, EstimatorOptions::default()),
            fallback,
            log: VecLog::default(),
            nis: Vec::new(),
            failures: Vec::new(),
            fallback_of,
            notes: Vec::new(),
            errors: None,
            other_version: None,
        }
    }

    /// Hands message `m` to the session (configuring it with the fallback
    /// settings at a first sample without a `Configure`), keeping the NIS
    /// and the failures of the accepted samples.
    pub fn handle(&mut self, m: Message) -> Result<(), String> {
        let m = match (m, self.errors) {
            (Message::Configure(settings), Some(errors)) => {
                Message::Configure(CalibratorConfig { errors, ..settings })
            }
            (m, _) => m,
        };
        match &m {
            Message::Sample(_) if self.session.calibrator().is_none() => {
                let Some(fallback) = self.fallback else {
                    return Err("the stream has no Configure message: give --config (and --platform FILE for the platform's settings)".into());
                };
                self.notes.push(format!(
                    "note: the stream has no Configure message; using the settings of {}",
                    self.fallback_of
                ));
                self.session
                    .configure(fallback)
                    .map_err(|e| format!("calibrator: {e}"))?;
            }
            Message::Configure(_) | Message::Reset => {
                if self.session.calibrator().is_some() {
                    self.notes.push(format!(
                        "\nnote: {} mid-stream: restarting the calibrator",
                        tag(&m)
                    ));
                }
                self.nis.clear();
                self.failures.clear();
            }
            _ => {}
        }
        match self.session.handle(&m, &mut self.log) {
            Reply::Error(e) => return Err(format!("{e}")),
            Reply::Rejected(RejectReason::Filter(e)) => {
                if let Message::Sample(s) = &m {
                    self.failures.push((s.seq, e));
                }
            }
            Reply::Nothing | Reply::Send(_) | Reply::Rejected(_) => {
                if let (Message::Sample(s), Some(cal)) = (&m, self.session.calibrator()) {
                    if cal.progress().last_seq == Some(s.seq) {
                        self.nis.push(cal.progress().last_nis);
                    }
                }
            }
        }
        Ok(())
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
            ..
        } = last;
        let covariance = covariance.to_vec();
        Some(Final {
            estimate,
            nis,
            updates,
            history,
            covariance,
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
            (self.pass, self.nis, self.updates, self.history) =
                (e.pass, Vec::new(), Vec::new(), Vec::new());
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

fn tag(m: &Message) -> &'static str {
    match m {
        Message::Configure(_) => "Configure",
        Message::Reset => "Reset",
        _ => "message",
    }
}
