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
//! **Gaps.** A missing sample loses its period's commanded increment, which
//! the computed frame `C^c_n` (and the model's attitude) must be propagated
//! with. The calibrator therefore bridges a gap only when it cannot be
//! wrong by more than the Earth-rate drift of the increment: at most
//! [`Limits::max_bridge`] missing periods, and the commanded increments of
//! the samples on both sides agree within [`Limits::bridge_tolerance_rad`]
//! (the platform stayed on one constant-rate path segment). The missing
//! periods are then predicted, without measurement, with the mean of the two
//! increments (the increment drifts by ≈ 1e-7 rad per period at 0.1°/s, so
//! the mean is off by a second-order amount), and counted in
//! [`Progress::bridged`]. Any other gap (e.g. across a path-segment switch,
//! where guessing the increment would turn `C^c_n` by up to 0.1° per missing
//! period) is rejected as [`RejectReason::Gap`] and **halts** the
//! calibrator: every further sample is rejected as [`RejectReason::Halted`]
//! until [`Calibrator::reset`] or a restore from a checkpoint taken before
//! the gap. The estimate reached so far stays available. A rejected sample
//! (e.g. NaN) also leaves a gap of one period, bridged by the same rule.
//!
//! **Checkpoints.** [`Calibrator::checkpoint`] captures the filter state,
//! covariance, nominal, computed frame and update counter, plus the
//! bookkeeping ([`Progress`]); [`Calibrator::restore`] continues from it
//! bit-identically (all values stored as `f64`, which an `f32` value
//! round-trips exactly).

use core::marker::PhantomData;

use nalgebra::{Matrix3, RealField, SMatrix, SVector, Vector3};

use crate::ekf::{self, Filter, FilterConfig, Observation};
use crate::models::{ConfigId, Environment, Model};
use crate::wire::{CalibratorConfig, Checkpoint, Estimate, Limits, Progress, Sample};

/// Why a sample was rejected. A rejected sample leaves the filter untouched.
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
    /// A sequence gap that cannot be bridged; the calibrator is now halted.
    Gap,
    /// The calibrator is halted by an earlier unbridgeable gap.
    Halted,
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
            RejectReason::Gap => f.write_str("sequence gap cannot be bridged; calibrator halted"),
            RejectReason::Halted => f.write_str("calibrator halted by an earlier gap"),
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

fn vec3<T: RealField + Copy>(a: [f64; 3]) -> Vector3<T> {
    Vector3::new(to_t(a[0]), to_t(a[1]), to_t(a[2]))
}

fn vec3_f32<T: RealField + Copy>(a: &[f32; 3]) -> Vector3<T> {
    Vector3::new(
        to_t(f64::from(a[0])),
        to_t(f64::from(a[1])),
        to_t(f64::from(a[2])),
    )
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
                earth_rate_n: vec3(s.earth_rate_n),
                gravity_n: vec3(s.gravity_n),
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

    fn fresh_filter(s: &CalibratorConfig) -> Result<Filter<T, M, N, Z>, Error> {
        Ok(Filter::new(
            Self::filter_config(s),
            SVector::zeros(),
            SVector::repeat(to_t(s.prior_sigma_rad)),
        )?)
    }

    /// A calibrator at the prior (zero estimate, σ = `prior_sigma_rad`).
    pub fn new(settings: CalibratorConfig) -> Result<Self, Error> {
        Self::check_config(settings.config)?;
        Ok(Self {
            filter: Self::fresh_filter(&settings)?,
            settings,
            progress: Progress::default(),
            frame_errors: 0,
            _model: PhantomData,
        })
    }

    /// Restarts from the prior with the current settings (counters cleared).
    pub fn reset(&mut self) -> Result<(), Error> {
        self.filter = Self::fresh_filter(&self.settings)?;
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

    /// Whether an unbridgeable gap halted the calibrator.
    pub fn halted(&self) -> bool {
        self.progress.halted
    }

    /// Records the receiver's count of rejected frames, reported in
    /// [`Estimate::frame_errors`].
    pub fn set_frame_errors(&mut self, n: u32) {
        self.frame_errors = n;
    }

    fn validate(&self, s: &Sample) -> Result<u32, RejectReason> {
        let lim: &Limits = &self.settings.limits;
        let gimbal_obs = M::LAYOUT.gimbal_obs;
        let gimbal = if gimbal_obs { s.gimbal } else { None };
        let values = || {
            s.dtheta_cmd
                .iter()
                .chain(s.accel_mean.iter())
                .chain(gimbal.iter().flatten())
                .chain(core::iter::once(&s.dt))
                .map(|v| f64::from(*v))
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
        if over(&s.dtheta_cmd, lim.max_increment_rad) {
            return Err(RejectReason::IncrementRange);
        }
        match gimbal {
            Some(g) if over(&g, lim.max_gimbal_rad) => return Err(RejectReason::GimbalRange),
            None if gimbal_obs => return Err(RejectReason::MissingGimbal),
            _ => {}
        }
        let (Some(last_seq), Some(last_t)) = (self.progress.last_seq, self.progress.last_t_us)
        else {
            return Ok(0);
        };
        if s.seq == last_seq {
            return Err(RejectReason::Duplicate);
        }
        if s.seq < last_seq {
            return Err(RejectReason::OutOfOrder);
        }
        if s.t_us <= last_t {
            return Err(RejectReason::TimeBackwards);
        }
        let periods = f64::from(s.seq - last_seq);
        let elapsed = (s.t_us - last_t) as f64 * 1e-6;
        if !within(elapsed - periods * dt, periods * lim.period_tolerance_s) {
            return Err(RejectReason::TimeMismatch);
        }
        let gap = s.seq - last_seq - 1;
        if gap > 0 {
            let last = self.progress.last_increment;
            let agree = s
                .dtheta_cmd
                .iter()
                .zip(last)
                .all(|(a, b)| (f64::from(*a) - b).abs() <= lim.bridge_tolerance_rad);
            if gap > lim.max_bridge || !agree {
                return Err(RejectReason::Gap);
            }
        }
        Ok(gap)
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
            RejectReason::Gap => &mut c.gap,
            RejectReason::Halted => &mut c.halted,
            RejectReason::Filter(_) => &mut c.filter,
        };
        *slot = slot.saturating_add(1);
        if r == RejectReason::Gap {
            self.progress.halted = true;
        }
        r
    }

    /// Processes one sample: validates it, bridges a short gap before it if
    /// allowed, and runs one filter period. Returns an [`Estimate`] when the
    /// cadence ([`CalibratorConfig::estimate_every`]) says so. On `Err` the
    /// sample was counted by reason and the filter is untouched.
    pub fn push(&mut self, s: &Sample) -> Result<Option<Estimate>, RejectReason> {
        if self.progress.halted {
            return Err(self.reject(RejectReason::Halted));
        }
        let gap = match self.validate(s) {
            Ok(g) => g,
            Err(r) => return Err(self.reject(r)),
        };
        let dt: T = to_t(f64::from(s.dt));
        let dtheta: Vector3<T> = vec3_f32(&s.dtheta_cmd);
        let obs = Observation {
            accel_mean: vec3_f32(&s.accel_mean),
            gimbal: s.gimbal.as_ref().map(vec3_f32),
        };
        let saved = (gap > 0).then(|| self.filter.clone());
        let result = (|| {
            if gap > 0 {
                let half: T = to_t(0.5);
                let mean = (dtheta + vec3::<T>(self.progress.last_increment)) * half;
                for _ in 0..gap {
                    self.filter.predict(&mean, dt)?;
                }
            }
            self.filter.step(&dtheta, dt, &obs)
        })();
        let nis = match result {
            Ok(innovation) => Some(to_f64(innovation.nis)),
            Err(ekf::Error::Gated) => None,
            Err(e) => {
                if let Some(f) = saved {
                    self.filter = f;
                }
                return Err(self.reject(RejectReason::Filter(e)));
            }
        };
        let p = &mut self.progress;
        match nis {
            Some(v) => p.last_nis = v,
            None => p.gated = p.gated.saturating_add(1),
        }
        p.last_seq = Some(s.seq);
        p.last_t_us = Some(s.t_us);
        p.last_increment = s.dtheta_cmd.map(f64::from);
        p.accepted = p.accepted.saturating_add(1);
        p.bridged = p.bridged.saturating_add(gap);
        p.since_estimate = p.since_estimate.saturating_add(1);
        let every = self.settings.estimate_every;
        if every > 0 && p.since_estimate >= every {
            p.since_estimate = 0;
            return Ok(Some(self.estimate()));
        }
        Ok(None)
    }

    /// The current estimate and health.
    pub fn estimate(&self) -> Estimate {
        let mut state = heapless::Vec::new();
        let mut sigma = heapless::Vec::new();
        for (x, s) in self.filter.state().iter().zip(self.filter.sigma().iter()) {
            // N ≤ MAX_STATES for every configuration: the pushes cannot fail.
            let _ = state.push(to_f64(*x));
            let _ = sigma.push(to_f64(*s));
        }
        Estimate {
            config: M::ID,
            seq: self.progress.last_seq.unwrap_or(0),
            updates: self.filter.updates(),
            state,
            sigma,
            progress: self.progress,
            frame_errors: self.frame_errors,
        }
    }

    /// A checkpoint from which [`Calibrator::restore`] continues
    /// bit-identically.
    pub fn checkpoint(&self) -> Checkpoint {
        let f = &self.filter;
        let collect = |v: &SVector<T, N>| {
            let mut out = heapless::Vec::new();
            for x in v.iter() {
                let _ = out.push(to_f64(*x));
            }
            out
        };
        let mut covariance = heapless::Vec::new();
        // Row-major: the column-major storage of Pᵀ.
        for v in f.covariance().transpose().iter() {
            let _ = covariance.push(to_f64(*v));
        }
        let mut c_cn = [0.0; 9];
        for (o, v) in c_cn
            .iter_mut()
            .zip(f.command_frame().c_cn.transpose().iter())
        {
            *o = to_f64(*v);
        }
        Checkpoint {
            config: M::ID,
            state: collect(f.state()),
            covariance,
            nominal: f.nominal().map(collect),
            c_cn,
            updates: f.updates(),
            progress: self.progress,
        }
    }

    /// A calibrator with settings `settings` continuing from checkpoint `cp`.
    pub fn restore(settings: CalibratorConfig, cp: &Checkpoint) -> Result<Self, Error> {
        Self::check_config(settings.config)?;
        Self::check_config(cp.config)?;
        let vector = |v: &[f64]| {
            (v.len() == N)
                .then(|| SVector::<T, N>::from_iterator(v.iter().map(|x| to_t::<T>(*x))))
                .ok_or(Error::CheckpointDimension)
        };
        let x = vector(&cp.state)?;
        if cp.covariance.len() != N * N {
            return Err(Error::CheckpointDimension);
        }
        let p = SMatrix::<T, N, N>::from_row_iterator(cp.covariance.iter().map(|v| to_t::<T>(*v)));
        let nominal = match &cp.nominal {
            Some(v) => Some(vector(v)?),
            None => None,
        };
        let c_cn = Matrix3::from_row_iterator(cp.c_cn.iter().map(|v| to_t::<T>(*v)));
        let filter = Filter::from_parts(
            Self::filter_config(&settings),
            x,
            p,
            c_cn,
            nominal,
            cp.updates,
        )?;
        Ok(Self {
            filter,
            settings,
            progress: cp.progress,
            frame_errors: 0,
            _model: PhantomData,
        })
    }
}
