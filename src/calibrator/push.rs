//! Pass 1: one sample at a time through the filter ([`Calibrator::push`],
//! [`Calibrator::push_logged`]), and the bookkeeping of the sample log the
//! final passes run over.

use nalgebra::{RealField, Vector3};

use super::{to_f64, vec3_f32, Calibrator, RejectReason};
use crate::ekf::{self, Observation};
use crate::estimator::{LogError, LogRecord, SampleLog};
use crate::models::Model;
use crate::wire::{Estimate, Sample, SinglePassReason};

impl<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>
    Calibrator<T, M, N, Z>
{
    /// Processes one sample: validates it, takes the start of the log from
    /// it when it is the run's first (a log may start anywhere on the path,
    /// [`Calibrator::log_start`]), bridges the gap before it along the
    /// commanded motion (or re-acquires the attitude), and runs one filter
    /// period. Returns an [`Estimate`] when the cadence
    /// ([`CalibratorConfig::estimate_every`](crate::wire::CalibratorConfig::estimate_every)) says so. On `Err` the sample
    /// was counted by reason and the filter is untouched.
    ///
    /// Without a sample log the final answer ([`Calibrator::finish`]) can
    /// only be pass 1: use [`Calibrator::push_logged`] for the estimator of
    /// record.
    ///
    /// # Examples
    ///
    /// A sample repeated is rejected, counted, and leaves the filter as it
    /// was:
    ///
    /// ```
    /// use rollcal::calibrator::{M4PaCalibrator, RejectReason};
    /// use rollcal::models::ConfigId;
    /// use rollcal::wire::{CalibratorConfig, Sample};
    ///
    /// let settings = CalibratorConfig::paper(ConfigId::M4Pa);
    /// let mut cal = M4PaCalibrator::<f64>::new(settings)?;
    /// let sample = Sample {
    ///     seq: 7,
    ///     t_us: 8_000_000,
    ///     dt: 1.0,
    ///     dtheta_cmd: settings.earth_rate_n,
    ///     c_cn_quat: [1.0, 0.0, 0.0, 0.0],
    ///     accel_mean: [0.0, 1.0, 0.0],
    ///     gimbal: None,
    /// };
    /// assert_eq!(cal.push(&sample), Ok(None));
    /// let filter = cal.filter().clone();
    /// assert_eq!(cal.push(&sample), Err(RejectReason::Duplicate));
    /// assert_eq!(cal.filter(), &filter);
    /// assert_eq!(cal.progress().rejects.duplicate, 1);
    /// # Ok::<(), rollcal::calibrator::Error>(())
    /// ```
    pub fn push(&mut self, s: &Sample) -> Result<Option<Estimate>, RejectReason> {
        self.push_inner(s, None)
    }

    /// [`Calibrator::push`], and the sample (and the periods bridged before
    /// it) appended to `log` for the final passes of
    /// [`Calibrator::finish`]. A rejected sample is not logged.
    ///
    /// The calibrator counts what it logged ([`Progress::logged`](crate::wire::Progress::logged)) and
    /// treats the log's first that many records as its own: a longer log
    /// (after a reset, a new configuration, or a restore from a checkpoint
    /// taken earlier) is truncated to them, so a log that survives a device
    /// reset (FRAM) continues a restored calibration; a shorter one cannot
    /// hold the run and makes the final answer pass 1 only
    /// ([`SinglePassReason::LogMismatch`]).
    // Not inlined: the session dispatches to seven of these, and their
    // frames must not add up in one caller's frame (firmware stack).
    #[inline(never)]
    pub fn push_logged(
        &mut self,
        s: &Sample,
        log: &mut (dyn SampleLog<T> + '_),
    ) -> Result<Option<Estimate>, RejectReason> {
        self.sync_log(log);
        self.push_inner(s, Some(log))
    }

    /// Takes `log` back to the records this calibrator logged (see
    /// [`Calibrator::push_logged`]).
    fn sync_log(&mut self, log: &mut (dyn SampleLog<T> + '_)) {
        if self.progress.log_incomplete.is_some() {
            return;
        }
        let logged = self.progress.logged as usize;
        match log.len() {
            n if n > logged => log.truncate(logged),
            n if n < logged => self.log_broken(SinglePassReason::LogMismatch),
            _ => {}
        }
    }

    fn push_inner(
        &mut self,
        s: &Sample,
        mut log: Option<&mut (dyn SampleLog<T> + '_)>,
    ) -> Result<Option<Estimate>, RejectReason> {
        let checked = match self.validate(s) {
            Ok(v) => v,
            Err(r) => {
                if matches!(r, RejectReason::TimeMismatch | RejectReason::TimeBackwards) {
                    self.progress.clock_candidate = Some((s.seq, s.t_us));
                }
                return Err(self.reject(r));
            }
        };
        let gap = checked.gap;
        let dt = f64::from(s.dt);
        let dtheta = Vector3::from(s.dtheta_cmd);
        // The gimbal angles of a configuration that does not measure them
        // are dropped here, not carried into the log: its filter ignores
        // them, and a compact log of that configuration
        // (`PackedLayout::Accel`) has no room for them.
        let obs = Observation {
            accel_mean: vec3_f32(&s.accel_mean),
            gimbal: s
                .gimbal
                .as_ref()
                .filter(|_| M::LAYOUT.gimbal_obs)
                .map(vec3_f32),
        };
        // A run's first sample: the log may start anywhere on the path.
        let acquired = match self.progress.last_seq {
            None => self
                .acquire_start(s)
                .map_err(|e| self.reject(RejectReason::Filter(e)))?,
            Some(_) => false,
        };
        if gap > 0 {
            self.bridge_gap(s, gap, checked.reanchored, log.as_deref_mut())?;
        } else if checked.reanchored {
            self.progress.clock_steps = self.progress.clock_steps.saturating_add(1);
        }
        // The filter leaves itself as it was when the step fails.
        let nis = match self.filter.step(&dtheta, dt, &obs) {
            Ok(innovation) => Some(to_f64(innovation.nis)),
            Err(ekf::Error::Gated) => None,
            Err(e) => {
                if acquired {
                    self.unacquire();
                }
                return Err(self.reject(RejectReason::Filter(e)));
            }
        };
        self.append(log, &LogRecord::measured(dt, dtheta, obs));
        let p = &mut self.progress;
        match nis {
            Some(v) => p.last_nis = v,
            None => p.gated = p.gated.saturating_add(1),
        }
        p.clock_candidate = None;
        p.last_seq = Some(s.seq);
        p.last_t_us = Some(s.t_us);
        p.last_increment = s.dtheta_cmd;
        p.accepted = p.accepted.saturating_add(1);
        p.since_estimate = p.since_estimate.saturating_add(1);
        let every = self.settings.estimate_every;
        if every > 0 && p.since_estimate >= every {
            p.since_estimate = 0;
            return Ok(Some(self.estimate()));
        }
        Ok(None)
    }

    /// Marks the log as no longer holding the whole run (the first reason
    /// stays).
    pub(super) fn log_broken(&mut self, reason: SinglePassReason) {
        if self.progress.log_incomplete.is_none() {
            self.progress.log_incomplete = Some(reason);
        }
    }

    /// Appends `r` to the log, while it still holds the whole run.
    pub(super) fn append(&mut self, log: Option<&mut (dyn SampleLog<T> + '_)>, r: &LogRecord<T>) {
        let Some(log) = log else {
            self.log_broken(SinglePassReason::NoLog);
            return;
        };
        if self.progress.log_incomplete.is_some() {
            return;
        }
        match log.append(r) {
            Ok(()) => self.progress.logged = self.progress.logged.saturating_add(1),
            Err(LogError::Full) => self.log_broken(SinglePassReason::LogFull),
            Err(LogError::Unrepresentable) => self.log_broken(SinglePassReason::LogUnrepresentable),
            Err(_) => self.log_broken(SinglePassReason::LogStorage),
        }
    }
}
