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
//!
//! [`Sample`]: crate::wire::Sample
//! [`Estimate`]: crate::wire::Estimate
//! [`Checkpoint`]: crate::wire::Checkpoint
//! [`Limits::max_bridge`]: crate::wire::Limits::max_bridge
//! [`Limits::frame_tolerance_rad`]: crate::wire::Limits::frame_tolerance_rad

mod checkpoint;
mod config;
mod error;
mod finish;
mod gaps;
mod push;
mod replay;
mod start;
mod validate;

use core::marker::PhantomData;

use nalgebra::{RealField, SVector, Vector3};

use crate::ekf::{Filter, FilterConfig};
use crate::estimator::LogStart;
use crate::models::Model;
use crate::wire::{CalibratorConfig, Progress};

pub use error::Error;
pub(crate) use finish::Passed;
pub use gaps::MAX_UNKNOWN_GAP_PERIODS;
pub use validate::RejectReason;

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

/// Validates samples and runs configuration `M`'s filter over them (see the
/// module docs). `T` is the filter's scalar (`f64`, or `f32` for FPUs
/// without double precision).
///
/// # Examples
///
/// An M1-pa calibrator fed 30 one-second samples of a platform at rest,
/// each logged for the final passes; a running estimate every 10 samples,
/// then the final answer of the estimator of record.
///
/// ```
/// use nalgebra::Vector3;
/// use rollcal::calibrator::M1PaCalibrator;
/// use rollcal::estimator::{EstimatorOptions, LogRecord, SliceLog};
/// use rollcal::models::ConfigId;
/// use rollcal::wire::{CalibratorConfig, EstimateKind, Sample};
///
/// let settings = CalibratorConfig {
///     estimate_every: 10,
///     ..CalibratorConfig::paper(ConfigId::M1Pa)
/// };
/// let mut cal = M1PaCalibrator::<f64>::new(settings)?;
/// let mut records = [LogRecord::predicted(0.0, Vector3::zeros()); 30];
/// let mut log = SliceLog::new(&mut records);
/// let mut running = Vec::new();
/// for seq in 0..30 {
///     // At rest in the navigation frame: the computed frame stays at
///     // C^c_n = I, the commanded increment is the Earth rate's, the
///     // accelerometers read 1 g up.
///     let sample = Sample {
///         seq,
///         t_us: (u64::from(seq) + 1) * 1_000_000,
///         dt: 1.0,
///         dtheta_cmd: settings.earth_rate_n,
///         c_cn_quat: [1.0, 0.0, 0.0, 0.0],
///         accel_mean: [0.0, 1.0, 0.0],
///         gimbal: None,
///     };
///     if let Some(estimate) = cal.push_logged(&sample, &mut log)? {
///         running.push(estimate.seq);
///     }
/// }
/// assert_eq!(running, [9, 19, 29]);
/// assert_eq!(cal.progress().accepted, 30);
/// let (answer, final_filter) = cal.finish(&mut log, &EstimatorOptions::default(), |_| {});
/// assert!(matches!(answer.kind, EstimateKind::Final { .. }));
/// assert_eq!(answer.state.len(), 12);
/// assert!(final_filter.is_some());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Calibrator<T: RealField + Copy, M, const N: usize, const Z: usize> {
    filter: Filter<T, M, N, Z>,
    settings: CalibratorConfig,
    progress: Progress,
    frame_errors: u32,
    /// Where this run started, as acquired from its first sample (aligned
    /// before it, and after a restore: [`Calibrator::log_start`]).
    start: LogStart,
    _model: PhantomData<M>,
}

/// M2-ps calibrator (18 states; needs gimbal angles).
pub type M2PsCalibrator<T> = Calibrator<T, crate::models::M2Ps, 18, 6>;
/// M1-pa calibrator (12 states).
pub type M1PaCalibrator<T> = Calibrator<T, crate::models::M1Pa, 12, 3>;
/// M4-pa calibrator (12 states).
pub type M4PaCalibrator<T> = Calibrator<T, crate::models::M4Pa, 12, 3>;
/// Full-model M2-ps calibrator (54 states; needs gimbal angles and the
/// `full-model` feature).
pub type M2PsFullCalibrator<T> = Calibrator<T, crate::models::M2PsFull, 54, 6>;
/// Full-model M1-pa calibrator (48 states; needs the `full-model` feature).
pub type M1PaFullCalibrator<T> = Calibrator<T, crate::models::M1PaFull, 48, 3>;
/// Full-model M4-pa calibrator (48 states; needs the `full-model` feature).
pub type M4PaFullCalibrator<T> = Calibrator<T, crate::models::M4PaFull, 48, 3>;

impl<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>
    Calibrator<T, M, N, Z>
{
    /// A calibrator at the prior (zero estimate, σ = `prior_sigma_rad`).
    /// (A value of the calibrator's size: the session builds its
    /// calibrator in place instead,
    /// [`crate::session::AnyCalibrator::build_into`].)
    pub fn new(settings: CalibratorConfig) -> Result<Self, Error> {
        let variance = Self::prior_variance(&settings)?;
        Ok(Self::with_prior_variance(settings, &variance))
    }

    /// What [`Calibrator::new`] checks: the configuration and the prior,
    /// whose variances (rad²) it returns for
    /// [`Calibrator::with_prior_variance`].
    pub(crate) fn prior_variance(settings: &CalibratorConfig) -> Result<SVector<T, N>, Error> {
        Self::check_config(settings.config, settings.errors)?;
        if let Some(field) = settings.invalid_field() {
            return Err(Error::InvalidField(field));
        }
        let (config, x0, sigma0) = Self::prior(settings);
        Ok(Filter::<T, M, N, Z>::prior_variance(&config, &x0, &sigma0)?)
    }

    /// [`Calibrator::new`] once [`Calibrator::prior_variance`] has
    /// accepted `settings`: it cannot fail. (By value: the session builds
    /// its calibrator in place, [`Calibrator::init_in_place`].)
    #[inline(always)]
    fn with_prior_variance(settings: CalibratorConfig, variance: &SVector<T, N>) -> Self {
        let mut c = Self::placeholder(settings);
        c.init_in_place(settings, variance);
        c
    }

    /// A calibrator whose filter is [`Filter::placeholder`]'s zeros: not a
    /// calibrator to run, but the value a slot is filled with before
    /// [`Calibrator::init_in_place`] makes it one (the session's
    /// `Configure`: [`crate::session::AnyCalibrator::build_into`]).
    #[inline(always)]
    pub(crate) fn placeholder(settings: CalibratorConfig) -> Self {
        Self {
            filter: Filter::placeholder(FilterConfig::from(&settings)),
            settings,
            progress: Progress::default(),
            frame_errors: 0,
            start: LogStart::aligned(),
            _model: PhantomData,
        }
    }

    /// Makes this calibrator equal to [`Calibrator::new`]`(settings)`, in
    /// place, whatever it held (no calibrator-sized temporary: the filter
    /// is made from the prior in its own storage,
    /// [`Filter::init_in_place`]). `variance` is what
    /// [`Calibrator::prior_variance`] returned for `settings`, so this
    /// cannot fail. Out of line: the prior's vectors are in its frame, not
    /// in the caller's.
    #[inline(never)]
    pub(crate) fn init_in_place(&mut self, settings: CalibratorConfig, variance: &SVector<T, N>) {
        let (config, x0, _) = Self::prior(&settings);
        self.filter.init_in_place(config, x0, variance);
        self.settings = settings;
        self.progress = Progress::default();
        self.frame_errors = 0;
        self.start = LogStart::aligned();
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
        self.start = LogStart::aligned();
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
    /// [`crate::wire::Estimate::frame_errors`].
    pub fn set_frame_errors(&mut self, n: u32) {
        self.frame_errors = n;
    }
}
