//! The calibrator front end: validates [`Sample`]s, runs a configuration's
//! estimator on them (a single pass of the extended filter, exactly pass 1
//! of the host's multi-pass estimator), emits [`Estimate`]s at a chosen
//! cadence, and checkpoints/restores itself through [`Checkpoint`] messages.
//!
//! **Validation.** A sample is rejected, counted by [`RejectReason`], and
//! leaves the filter bit-identical when any used field is NaN/inf, `dt` is
//! not the configured period, a value is out of its plausible range, the
//! configuration needs gimbal angles and there are none, its sequence number
//! repeats or goes backwards, its timestamp does not advance, or the
//! timestamp difference disagrees with the number of elapsed periods.
//!
//! **Lost data loses only itself.** A lost sample loses its period's
//! commanded increment, which the computed frame `C^c_n` (and the model's
//! attitude) must be propagated with. Every [`Sample`] therefore also
//! reports `C^c_n` at the end of its period. Across a gap of `m` missing
//! periods the calibrator searches the commanded motion (at most
//! [`Limits::max_bridge`] periods): the last sample's constant path rate for
//! `j` periods and the new sample's path rate for the others, for every
//! `j` (a rolling path changes rate only at period boundaries, so this is
//! exact for a gap inside one path segment and for one that contains one
//! segment switch). A hypothesis is accepted when it carries `C^c_n` to the
//! reported frame within [`Limits::frame_tolerance_rad`]; the missing periods
//! are then predicted along it without measurement and counted in
//! [`Progress::bridged`]. When no hypothesis fits (a longer gap, or several
//! switches), the motion is not known: the missing periods are predicted
//! along the shortest rotation to the reported frame (at most the last
//! [`MAX_UNKNOWN_GAP_PERIODS`] of them), the computed frame is
//! set from the report, and the attitude states are **re-acquired**
//! ([`crate::ekf::Filter::reacquire_attitude`]: their covariance re-opened to
//! the prior, the parameters' information kept), counted in
//! [`Progress::reacquired`]. Nothing halts the calibrator.
//!
//! **Clock steps.** A sample whose timestamp disagrees with the last
//! accepted one is rejected ([`RejectReason::TimeMismatch`] or
//! [`RejectReason::TimeBackwards`]) and remembered; when the next sample's
//! timestamp agrees with it, the clock stepped: the time is re-anchored
//! there ([`Progress::clock_steps`]) and the rejected period is bridged like
//! any lost one.
//!
//! **Checkpoints.** [`Calibrator::checkpoint`] captures the filter state,
//! the U-D factor of its covariance, nominal, computed frame and update counter, plus the
//! bookkeeping ([`Progress`]); [`Calibrator::restore`] continues from it
//! bit-identically (all values stored as `f64`, which an `f32` value
//! round-trips exactly).

use core::marker::PhantomData;

use nalgebra::{Matrix3, RealField, SVector, Vector3};

use crate::command::CommandFrame;
use crate::ekf::{self, Filter, FilterConfig, Observation, Parts};
use crate::estimator::{self, EstimatorOptions, LogError, LogRecord, PassEvent, SampleLog};
use crate::geometry::{angle_between, dcm_from_quaternion, rotation_vector};
use crate::models::{ConfigId, Environment, Model};
use crate::wire::{
    CalibratorConfig, Checkpoint, Estimate, EstimateKind, Limits, Progress, Sample,
    SinglePassReason,
};

/// Why a sample was rejected. A rejected sample leaves the filter untouched
/// and loses only its own period (bridged with the next accepted sample).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum RejectReason {
    /// A used field is NaN or infinite.
    NonFinite,
    /// `dt` is outside the configured period ± tolerance.
    Period,
    /// A specific-force component exceeds [`Limits::max_accel_g`].
    AccelRange,
    /// A commanded-increment component exceeds [`Limits::max_increment_rad`].
    IncrementRange,
    /// A gimbal angle exceeds [`Limits::max_gimbal_rad`].
    GimbalRange,
    /// The configuration observes gimbal angles and the sample has none.
    MissingGimbal,
    /// Same sequence number as the last accepted sample.
    Duplicate,
    /// Sequence number below the last accepted one.
    OutOfOrder,
    /// Timestamp not after the last accepted one.
    TimeBackwards,
    /// Timestamp difference disagrees with `dt` × elapsed periods.
    TimeMismatch,
    /// The computed-frame quaternion is not a unit quaternion (within
    /// [`Limits::frame_tolerance_rad`]).
    FrameAttitude,
    /// The filter refused the period (its state was restored).
    Filter(ekf::Error),
}

impl core::fmt::Display for RejectReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RejectReason::NonFinite => f.write_str("a field is not finite"),
            RejectReason::Period => f.write_str("period outside the configured tolerance"),
            RejectReason::AccelRange => f.write_str("specific force out of range"),
            RejectReason::IncrementRange => f.write_str("commanded increment out of range"),
            RejectReason::GimbalRange => f.write_str("gimbal angle out of range"),
            RejectReason::MissingGimbal => f.write_str("gimbal angles required but missing"),
            RejectReason::Duplicate => f.write_str("duplicate sequence number"),
            RejectReason::OutOfOrder => f.write_str("sequence number out of order"),
            RejectReason::TimeBackwards => f.write_str("timestamp does not advance"),
            RejectReason::TimeMismatch => f.write_str("timestamp disagrees with the period"),
            RejectReason::FrameAttitude => {
                f.write_str("computed-frame quaternion is not a unit quaternion")
            }
            RejectReason::Filter(e) => write!(f, "filter refused the period: {e}"),
        }
    }
}

impl core::error::Error for RejectReason {}

/// Errors of building or restoring a calibrator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// The settings or checkpoint name another configuration than the type's.
    ConfigMismatch {
        /// The calibrator type's configuration.
        expected: ConfigId,
        /// The configuration found.
        found: ConfigId,
    },
    /// A checkpoint vector has the wrong length for the configuration.
    CheckpointDimension,
    /// The filter refused the settings or the checkpoint's values.
    Filter(ekf::Error),
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Error::ConfigMismatch { expected, found } => write!(
                f,
                "configuration {} given to a {} calibrator",
                found.as_str(),
                expected.as_str()
            ),
            Error::CheckpointDimension => f.write_str("checkpoint dimensions do not match"),
            Error::Filter(e) => write!(f, "filter: {e}"),
        }
    }
}

impl core::error::Error for Error {}

impl From<ekf::Error> for Error {
    fn from(e: ekf::Error) -> Self {
        Error::Filter(e)
    }
}

/// `|d| ≤ tol`, false when either is NaN (a NaN limit rejects).
fn within(d: f64, tol: f64) -> bool {
    d.abs() <= tol
}

fn to_t<T: RealField + Copy>(v: f64) -> T {
    nalgebra::convert(v)
}

fn to_f64<T: RealField + Copy>(v: T) -> f64 {
    v.to_subset().unwrap_or(f64::NAN)
}

fn vec3_f32<T: RealField + Copy>(a: &[f32; 3]) -> Vector3<T> {
    Vector3::new(
        to_t(f64::from(a[0])),
        to_t(f64::from(a[1])),
        to_t(f64::from(a[2])),
    )
}

/// A sample that passed validation.
#[derive(Clone, Copy, Debug)]
struct Validated {
    /// Missing periods before it.
    gap: u32,
    /// Its timestamp re-anchors the time after a clock step.
    reanchored: bool,
}

/// The most periods a gap of unknown motion costs: across a longer gap the
/// motion to the reported frame is predicted over its last
/// `MAX_UNKNOWN_GAP_PERIODS` periods only, and the model's time is not
/// advanced over the earlier part (the parameters are constant; the
/// attitude, whose motion is not known, is re-acquired: its covariance is
/// re-opened to the prior without correlation to the parameters). One
/// sample then never costs more than the configured bridge search
/// ([`Limits::max_bridge`] periods) and this many predictions, where a jump
/// of the sequence number and the time by 2³² periods, which validation
/// accepts, took hours (fuzz/README.md). 7200 is the default
/// [`Limits::max_bridge`] (2 h of 1 s periods); every gap up to it is
/// predicted period by period over its whole length.
pub const MAX_UNKNOWN_GAP_PERIODS: u32 = 7200;

/// The commanded motion across a gap.
#[derive(Clone, Copy, Debug)]
enum Motion {
    /// `old` periods at the last sample's path rate `u_old`, the rest at
    /// the new sample's `u_new` (rad/s, c frame).
    Found {
        old: u32,
        u_old: Vector3<f64>,
        u_new: Vector3<f64>,
    },
    /// Not found: `start` is `C^c_n` at the start of the new sample's
    /// period, from its report.
    Unknown { start: Matrix3<f64> },
}

/// Validates samples and runs configuration `M`'s filter over them (see the
/// module docs). `T` is the filter's scalar (`f64`, or `f32` for FPUs
/// without double precision).
#[derive(Clone, Debug, PartialEq)]
pub struct Calibrator<T: RealField + Copy, M, const N: usize, const Z: usize> {
    filter: Filter<T, M, N, Z>,
    settings: CalibratorConfig,
    progress: Progress,
    frame_errors: u32,
    _model: PhantomData<M>,
}

/// M2-ps calibrator (18 states; needs gimbal angles).
pub type M2PsCalibrator<T> = Calibrator<T, crate::models::M2Ps, 18, 6>;
/// M1-pa calibrator (12 states).
pub type M1PaCalibrator<T> = Calibrator<T, crate::models::M1Pa, 12, 3>;
/// M4-pa calibrator (12 states).
pub type M4PaCalibrator<T> = Calibrator<T, crate::models::M4Pa, 12, 3>;

impl<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>
    Calibrator<T, M, N, Z>
{
    fn filter_config(s: &CalibratorConfig) -> FilterConfig<T> {
        FilterConfig {
            env: Environment {
                earth_rate_n: Vector3::from(s.earth_rate_n),
                gravity_n: Vector3::from(s.gravity_n),
            },
            sigma_accel: to_t(s.sigma_accel_g),
            sigma_gyro: to_t(s.sigma_gyro_rad_s),
            sigma_gimbal: to_t(s.sigma_gimbal_rad),
            options: s.options,
        }
    }

    fn check_config(found: ConfigId) -> Result<(), Error> {
        if found == M::ID {
            Ok(())
        } else {
            Err(Error::ConfigMismatch {
                expected: M::ID,
                found,
            })
        }
    }

    /// The filter's start of `s`: its settings, the zero estimate and the
    /// prior σ (`prior_sigma_rad`) of every state: what a new calibrator, a
    /// reset and every pass of the estimator of record start from.
    fn prior(s: &CalibratorConfig) -> (FilterConfig<T>, SVector<f64, N>, SVector<T, N>) {
        (
            Self::filter_config(s),
            SVector::zeros(),
            SVector::repeat(to_t(s.prior_sigma_rad)),
        )
    }

    /// A calibrator at the prior (zero estimate, σ = `prior_sigma_rad`).
    /// (The session builds its calibrator in place instead:
    /// [`crate::session::AnyCalibrator::build_into`].)
    pub fn new(settings: CalibratorConfig) -> Result<Self, Error> {
        let variance = Self::prior_variance(&settings)?;
        Ok(Self::with_prior_variance(settings, &variance))
    }

    /// What [`Calibrator::new`] checks: the configuration and the prior,
    /// whose variances (rad²) it returns for
    /// [`Calibrator::with_prior_variance`].
    pub(crate) fn prior_variance(settings: &CalibratorConfig) -> Result<SVector<T, N>, Error> {
        Self::check_config(settings.config)?;
        let (config, x0, sigma0) = Self::prior(settings);
        Ok(Filter::<T, M, N, Z>::prior_variance(&config, &x0, &sigma0)?)
    }

    /// [`Calibrator::new`] once [`Calibrator::prior_variance`] has
    /// accepted `settings`: it cannot fail, so the session builds it
    /// straight into its slot.
    #[inline(always)]
    pub(crate) fn with_prior_variance(
        settings: CalibratorConfig,
        variance: &SVector<T, N>,
    ) -> Self {
        let (config, x0, _) = Self::prior(&settings);
        Self {
            filter: Filter::with_prior_variance(config, x0, variance),
            settings,
            progress: Progress::default(),
            frame_errors: 0,
            _model: PhantomData,
        }
    }

    /// Restarts from the prior with the current settings (counters cleared).
    // Not inlined: the session dispatches to seven of these, and their
    // frames must not add up in one caller's frame (firmware stack).
    #[inline(never)]
    pub fn reset(&mut self) -> Result<(), Error> {
        // The filter restarted in place (no filter-sized temporary).
        let (config, x0, sigma0) = Self::prior(&self.settings);
        self.filter.restart(config, x0, sigma0)?;
        self.progress = Progress::default();
        Ok(())
    }

    /// The settings.
    pub fn settings(&self) -> &CalibratorConfig {
        &self.settings
    }

    /// The filter (read-only).
    pub fn filter(&self) -> &Filter<T, M, N, Z> {
        &self.filter
    }

    /// Bookkeeping: last sequence number and time, counters, halted flag.
    pub fn progress(&self) -> &Progress {
        &self.progress
    }

    /// Records the receiver's count of rejected frames, reported in
    /// [`Estimate::frame_errors`].
    pub fn set_frame_errors(&mut self, n: u32) {
        self.frame_errors = n;
    }

    fn validate(&self, s: &Sample) -> Result<Validated, RejectReason> {
        let lim: &Limits = &self.settings.limits;
        let gimbal_obs = M::LAYOUT.gimbal_obs;
        let gimbal = if gimbal_obs { s.gimbal } else { None };
        let values = || {
            s.accel_mean
                .iter()
                .chain(s.c_cn_quat.iter())
                .chain(gimbal.iter().flatten())
                .chain(core::iter::once(&s.dt))
                .map(|v| f64::from(*v))
                .chain(s.dtheta_cmd.iter().copied())
        };
        if !values().all(f64::is_finite) {
            return Err(RejectReason::NonFinite);
        }
        let dt = f64::from(s.dt);
        if !within(dt - lim.period_s, lim.period_tolerance_s) || dt <= 0.0 {
            return Err(RejectReason::Period);
        }
        let over = |a: &[f32; 3], max: f64| a.iter().any(|v| f64::from(*v).abs() > max);
        if over(&s.accel_mean, lim.max_accel_g) {
            return Err(RejectReason::AccelRange);
        }
        if s.dtheta_cmd.iter().any(|v| v.abs() > lim.max_increment_rad) {
            return Err(RejectReason::IncrementRange);
        }
        match gimbal {
            Some(g) if over(&g, lim.max_gimbal_rad) => return Err(RejectReason::GimbalRange),
            None if gimbal_obs => return Err(RejectReason::MissingGimbal),
            _ => {}
        }
        let norm = libm::sqrt(
            s.c_cn_quat
                .iter()
                .map(|v| f64::from(*v) * f64::from(*v))
                .sum::<f64>(),
        );
        if !within(norm - 1.0, lim.frame_tolerance_rad) {
            return Err(RejectReason::FrameAttitude);
        }
        let (Some(last_seq), Some(last_t)) = (self.progress.last_seq, self.progress.last_t_us)
        else {
            return Ok(Validated {
                gap: 0,
                reanchored: false,
            });
        };
        if s.seq == last_seq {
            return Err(RejectReason::Duplicate);
        }
        if s.seq < last_seq {
            return Err(RejectReason::OutOfOrder);
        }
        // The time elapsed since (seq0, t0) agrees with the elapsed periods.
        let agrees = |seq0: u32, t0: u64| {
            s.seq > seq0
                && s.t_us > t0
                && within(
                    (s.t_us - t0) as f64 * 1e-6 - f64::from(s.seq - seq0) * dt,
                    f64::from(s.seq - seq0) * lim.period_tolerance_s,
                )
        };
        let reanchored = if agrees(last_seq, last_t) {
            false
        } else if self
            .progress
            .clock_candidate
            .is_some_and(|(seq0, t0)| agrees(seq0, t0))
        {
            true
        } else if s.t_us <= last_t {
            return Err(RejectReason::TimeBackwards);
        } else {
            return Err(RejectReason::TimeMismatch);
        };
        Ok(Validated {
            gap: s.seq - last_seq - 1,
            reanchored,
        })
    }

    /// The commanded motion across the `gap` missing periods before sample
    /// `s` (see the module docs, "Lost data").
    fn motion_across(&self, s: &Sample, gap: u32) -> Motion {
        let lim = &self.settings.limits;
        let dt = f64::from(s.dt);
        let dtheta = Vector3::from(s.dtheta_cmd);
        let q = s.c_cn_quat.map(f64::from);
        let tol = lim.frame_tolerance_rad;
        let frame = *self.filter.command_frame();
        let er = frame.earth_rate_n;
        // Validated: a unit quaternion within the tolerance.
        let reported = dcm_from_quaternion(&q, tol).unwrap_or(frame.c_cn);
        let at = |c_cn: Matrix3<f64>| CommandFrame {
            c_cn,
            earth_rate_n: er,
        };
        if gap <= lim.max_bridge {
            let last = Vector3::from(self.progress.last_increment);
            let [last_start, _, _] = frame.period_before(&last, dt).c_cn;
            let u_old = at(last_start).path_rate(&last, dt);
            for old in (0..=gap).rev() {
                let c_switch = frame.after(&u_old, dt, old);
                // The new path rate, at the start of the sample's own period:
                // a fixed point, as the start frame enters only through the
                // Earth-rate term (contraction ≈ |ω_ie| T × missing periods
                // at the new rate, < 0.5 up to 7200 periods).
                let mut u_new = at(c_switch).path_rate(&dtheta, dt);
                let mut start = c_switch;
                for _ in 0..8 {
                    let next = at(c_switch).after(&u_new, dt, gap - old);
                    let moved = angle_between(&next, &start);
                    start = next;
                    u_new = at(start).path_rate(&dtheta, dt);
                    if moved < tol * 1e-3 {
                        break;
                    }
                }
                let end = at(start).after(&u_new, dt, 1);
                if angle_between(&end, &reported) <= tol {
                    return Motion::Found { old, u_old, u_new };
                }
            }
        }
        let [start, _, _] = at(reported).period_before(&dtheta, dt).c_cn;
        Motion::Unknown { start }
    }

    /// Predicts the `gap` missing periods along `motion` (and logs them as
    /// predicted periods); re-acquires the attitude when the motion is
    /// unknown.
    fn bridge(
        &mut self,
        gap: u32,
        dt: f64,
        motion: &Motion,
        mut log: Option<&mut (dyn SampleLog<T> + '_)>,
    ) -> Result<Vector3<f64>, ekf::Error> {
        let mut last = Vector3::zeros();
        match motion {
            Motion::Found { old, u_old, u_new } => {
                for i in 0..gap {
                    let u = if i < *old { u_old } else { u_new };
                    let inc = self.filter.command_frame().increment(u, dt);
                    self.filter.predict(&inc, dt)?;
                    self.append(log.as_deref_mut(), &LogRecord::predicted(dt, inc));
                    last = inc;
                }
                Ok(last)
            }
            Motion::Unknown { start } => {
                // At most MAX_UNKNOWN_GAP_PERIODS periods are predicted: the
                // model's time is not advanced over the earlier part of a
                // longer gap (see the constant).
                let predicted = gap.min(MAX_UNKNOWN_GAP_PERIODS);
                if predicted > 0 {
                    let c0 = self.filter.command_frame().c_cn;
                    let periods = f64::from(predicted);
                    let u = rotation_vector(&(start * c0.transpose())) / (dt * periods);
                    for _ in 0..predicted {
                        let inc = self.filter.command_frame().increment(&u, dt);
                        self.filter.predict(&inc, dt)?;
                        last = inc;
                    }
                }
                self.log_broken(SinglePassReason::Reacquired);
                self.filter
                    .reacquire_attitude(start, to_t(self.settings.prior_sigma_rad))?;
                Ok(last)
            }
        }
    }

    /// Marks the log as no longer holding the whole run (the first reason
    /// stays).
    fn log_broken(&mut self, reason: SinglePassReason) {
        if self.progress.log_incomplete.is_none() {
            self.progress.log_incomplete = Some(reason);
        }
    }

    /// Appends `r` to the log, while it still holds the whole run.
    fn append(&mut self, log: Option<&mut (dyn SampleLog<T> + '_)>, r: &LogRecord<T>) {
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

    fn reject(&mut self, r: RejectReason) -> RejectReason {
        let c = &mut self.progress.rejects;
        let slot = match r {
            RejectReason::NonFinite => &mut c.non_finite,
            RejectReason::Period => &mut c.period,
            RejectReason::AccelRange => &mut c.accel_range,
            RejectReason::IncrementRange => &mut c.increment_range,
            RejectReason::GimbalRange => &mut c.gimbal_range,
            RejectReason::MissingGimbal => &mut c.missing_gimbal,
            RejectReason::Duplicate => &mut c.duplicate,
            RejectReason::OutOfOrder => &mut c.out_of_order,
            RejectReason::TimeBackwards => &mut c.time_backwards,
            RejectReason::TimeMismatch => &mut c.time_mismatch,
            RejectReason::FrameAttitude => &mut c.frame_attitude,
            RejectReason::Filter(_) => &mut c.filter,
        };
        *slot = slot.saturating_add(1);
        r
    }

    /// Processes one sample: validates it, bridges the gap before it along
    /// the commanded motion (or re-acquires the attitude), and runs one
    /// filter period. Returns an [`Estimate`] when the cadence
    /// ([`CalibratorConfig::estimate_every`]) says so. On `Err` the sample
    /// was counted by reason and the filter is untouched.
    ///
    /// Without a sample log the final answer ([`Calibrator::finish`]) can
    /// only be pass 1: use [`Calibrator::push_logged`] for the estimator of
    /// record.
    pub fn push(&mut self, s: &Sample) -> Result<Option<Estimate>, RejectReason> {
        self.push_inner(s, None)
    }

    /// [`Calibrator::push`], and the sample (and the periods bridged before
    /// it) appended to `log` for the final passes of
    /// [`Calibrator::finish`]. A rejected sample is not logged.
    ///
    /// The calibrator counts what it logged ([`Progress::logged`]) and
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

    /// Bridges the `gap` periods lost before sample `s` (along the
    /// commanded motion, or re-acquiring the attitude), rolling the filter
    /// back if that fails. Out of line: the filter's copy kept for the
    /// rollback is on the stack only while a gap is bridged, not under
    /// every sample's filter step.
    #[inline(never)]
    fn bridge_gap(
        &mut self,
        s: &Sample,
        gap: u32,
        reanchored: bool,
        log: Option<&mut (dyn SampleLog<T> + '_)>,
    ) -> Result<(), RejectReason> {
        let dt = f64::from(s.dt);
        let motion = self.motion_across(s, gap);
        let saved = self.filter.clone();
        let logged_before = self.progress.logged;
        match self.bridge(gap, dt, &motion, log) {
            Ok(last) => {
                // The bridged periods are consumed whatever the sample's
                // own period does: a refused sample leaves a gap of one
                // period, not one that grows with every refusal.
                let p = &mut self.progress;
                match motion {
                    Motion::Found { .. } => p.bridged = p.bridged.saturating_add(gap),
                    Motion::Unknown { .. } => {
                        p.reacquired = p.reacquired.saturating_add(1);
                        p.reacquired_periods = p.reacquired_periods.saturating_add(gap);
                    }
                }
                if reanchored {
                    p.clock_steps = p.clock_steps.saturating_add(1);
                }
                p.clock_candidate = None;
                let dt_us = libm::round(f64::from(s.dt) * 1e6) as u64;
                p.last_seq = Some(s.seq - 1);
                p.last_t_us = Some(s.t_us.saturating_sub(dt_us));
                p.last_increment = [last.x, last.y, last.z];
            }
            Err(e) => {
                self.filter = saved;
                if self.progress.logged != logged_before {
                    self.log_broken(SinglePassReason::FilterFailed);
                }
                return Err(self.reject(RejectReason::Filter(e)));
            }
        }
        Ok(())
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
        let obs = Observation {
            accel_mean: vec3_f32(&s.accel_mean),
            gimbal: s.gimbal.as_ref().map(vec3_f32),
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
            Err(e) => return Err(self.reject(RejectReason::Filter(e))),
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

    /// The current (running) estimate and health.
    pub fn estimate(&self) -> Estimate {
        self.estimate_of(&self.filter, EstimateKind::Running)
    }

    /// The final answer: the estimator of record ([`crate::estimator`]: pass
    /// 1, back-propagation, linearised passes until no state moves by more
    /// than `passes.tolerance` σ) over `log`, which must hold what
    /// [`Calibrator::push_logged`] appended. When it does not (no log, full,
    /// a re-acquired attitude, a mismatch) the answer is the running
    /// estimate, marked [`EstimateKind::SinglePass`] with the reason. The
    /// calibrator itself is unchanged: more samples may follow. Also returns
    /// the final filter when the passes ran. `observer` sees every step of
    /// every pass ([`PassEvent`]; `|_| {}` when not needed).
    pub fn finish<F: FnMut(&PassEvent<'_, T, M, N, Z>)>(
        &self,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        observer: F,
    ) -> (Estimate, Option<Filter<T, M, N, Z>>) {
        let mut last = None;
        let estimate = self.finish_with(log, passes, observer, |f| last = Some(f.clone()));
        (estimate, last)
    }

    /// [`Calibrator::finish`] without a filter returned by value: `on_final`
    /// sees the final filter when the passes ran (it is not called for a
    /// single-pass answer). The passes run in a copy of the running filter
    /// in this function's frame ([`Calibrator::finish_in`]).
    pub fn finish_with<F, G>(
        &self,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        observer: F,
        on_final: G,
    ) -> Estimate
    where
        F: FnMut(&PassEvent<'_, T, M, N, Z>),
        G: FnOnce(&Filter<T, M, N, Z>),
    {
        let mut filter = self.filter.clone();
        let estimate = self.finish_in(&mut filter, log, passes, observer);
        if matches!(estimate.kind, EstimateKind::Final { .. }) {
            on_final(&filter);
        }
        estimate
    }

    /// [`Calibrator::finish`] in the caller's `filter`: the passes restart
    /// it ([`estimator::estimate_in`]; what it held does not matter), and
    /// after an [`EstimateKind::Final`] answer it is the final filter
    /// (otherwise it is left as it was or as the failing pass left it). A
    /// firmware whose session keeps this filter in static memory
    /// ([`crate::session::AnyFilter`]) has no filter on its stack under the
    /// passes (5.8 KB of f64 filter on the M7).
    // Not inlined: the session dispatches to seven of these, and their
    // frames must not add up in one caller's frame (firmware stack).
    #[inline(never)]
    pub fn finish_in<F>(
        &self,
        filter: &mut Filter<T, M, N, Z>,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        observer: F,
    ) -> Estimate
    where
        F: FnMut(&PassEvent<'_, T, M, N, Z>),
    {
        let logged = self.progress.logged;
        if log.len() > logged as usize && self.progress.log_incomplete.is_none() {
            log.truncate(logged as usize);
        }
        let reason = match self.progress.log_incomplete {
            Some(r) => Some(r),
            None if u32::try_from(log.len()).ok() != Some(logged) => {
                Some(SinglePassReason::LogMismatch)
            }
            None => None,
        };
        if let Some(r) = reason {
            return self.single_pass(r);
        }
        let (config, x0, sigma0) = Self::prior(&self.settings);
        match estimator::estimate_in(filter, &config, &x0, &sigma0, log, passes, observer) {
            Ok(report) => {
                let kind = EstimateKind::Final {
                    passes: report.passes,
                    converged: report.converged,
                };
                self.estimate_of(filter, kind)
            }
            Err(_) => self.single_pass(SinglePassReason::Estimator),
        }
    }

    /// The running estimate as the final answer when the passes cannot
    /// run: [`EstimateKind::SinglePass`] with `reason`.
    pub(crate) fn single_pass(&self, reason: SinglePassReason) -> Estimate {
        let logged = self.progress.logged;
        self.estimate_of(&self.filter, EstimateKind::SinglePass { reason, logged })
    }

    fn estimate_of(&self, filter: &Filter<T, M, N, Z>, kind: EstimateKind) -> Estimate {
        let mut state = heapless::Vec::new();
        let mut sigma = heapless::Vec::new();
        for (x, s) in filter.state().iter().zip(filter.sigma().iter()) {
            // N ≤ MAX_STATES for every configuration: the pushes cannot fail.
            let _ = state.push(*x);
            let _ = sigma.push(to_f64(*s));
        }
        Estimate {
            config: M::ID,
            seq: self.progress.last_seq.unwrap_or(0),
            updates: filter.updates(),
            state,
            sigma,
            progress: self.progress,
            frame_errors: self.frame_errors,
            kind,
        }
    }

    /// A checkpoint from which [`Calibrator::restore`] continues
    /// bit-identically.
    // Not inlined: the session dispatches to seven of these, and their
    // frames must not add up in one caller's frame (firmware stack).
    #[inline(never)]
    pub fn checkpoint(&self) -> Checkpoint {
        let f = &self.filter;
        let collect = |v: &SVector<f64, N>| {
            let mut out = heapless::Vec::new();
            for x in v.iter() {
                let _ = out.push(*x);
            }
            out
        };
        let mut factor = heapless::Vec::new();
        // Row-major: the column-major storage of the transpose.
        for v in f.factor().transpose().iter() {
            let _ = factor.push(to_f64(*v));
        }
        let mut c_cn = [0.0; 9];
        for (o, v) in c_cn
            .iter_mut()
            .zip(f.command_frame().c_cn.transpose().iter())
        {
            *o = *v;
        }
        Checkpoint {
            config: M::ID,
            state: collect(f.state()),
            factor,
            nominal: f.nominal().map(collect),
            c_cn,
            updates: f.updates(),
            gated_run: f.gate_state().0,
            gate_open: f.gate_state().1,
            progress: self.progress,
        }
    }

    /// A calibrator with settings `settings` continuing from checkpoint `cp`.
    // Not inlined: the session dispatches to seven of these, and their
    // frames must not add up in one caller's frame (firmware stack).
    #[inline(never)]
    pub fn restore(settings: CalibratorConfig, cp: &Checkpoint) -> Result<Self, Error> {
        let mut c = Self::new(settings)?;
        c.restore_in_place(settings, cp)?;
        Ok(c)
    }

    /// `*self = Calibrator::restore(settings, cp)?`, in place (the
    /// checkpoint is read where it is: no calibrator-sized or `N×N`
    /// temporary on the stack). On error the calibrator is unchanged.
    pub fn restore_in_place(
        &mut self,
        settings: CalibratorConfig,
        cp: &Checkpoint,
    ) -> Result<(), Error> {
        Self::check_config(settings.config)?;
        Self::check_config(cp.config)?;
        let vector = |v: &[f64]| {
            (v.len() == N)
                .then(|| SVector::<f64, N>::from_iterator(v.iter().copied()))
                .ok_or(Error::CheckpointDimension)
        };
        let x = vector(&cp.state)?;
        if cp.factor.len() != N * N {
            return Err(Error::CheckpointDimension);
        }
        let nominal = match &cp.nominal {
            Some(v) => Some(vector(v)?),
            None => None,
        };
        let c_cn = Matrix3::from_row_iterator(cp.c_cn.iter().copied());
        self.filter.set_parts(
            Self::filter_config(&settings),
            &Parts {
                x: &x,
                factor: &cp.factor,
                c_cn: &c_cn,
                nominal: nominal.as_ref(),
                updates: cp.updates,
                gate_state: (cp.gated_run, cp.gate_open),
            },
        )?;
        self.settings = settings;
        self.progress = cp.progress;
        self.frame_errors = 0;
        Ok(())
    }
}
