//! The estimator of record: the multi-pass filter over a whole run, with no
//! heap, over a [`SampleLog`] whose storage the caller provides.
//!
//! [`estimate`] runs
//!
//! 1. **pass 1**, the extended filter ([`Filter`], with the cold-start
//!    remedy of [`FilterConfig::options`], by default the second-order
//!    innovation covariance), over every record of the log, from the prior
//!    `x0`, `σ0` at the log's start ([`LogStart`]: the path's start,
//!    `C^c_n = I`, for [`estimate`]; anywhere on the path for
//!    [`estimate_from`]);
//! 2. **back-propagation** ([`back_propagate`]) of the pass's final estimate
//!    to the log's start: the state at the end integrated backwards through every
//!    period with [`Layout::propagate_state`] on [`Period::reversed`]
//!    (parameters are constant; only the attitude moves);
//! 3. **a linearised pass**: a new filter from the same `x0`, `σ0` over the
//!    same log, linearised about the nominal trajectory that starts at the
//!    back-propagated state ([`Filter::set_nominal`]): a Gauss–Newton step
//!    on the whole run, whose covariance is the posterior Cramér–Rao bound
//!    along that trajectory;
//! 4. steps 2–3 again until no final state moves by more than
//!    [`EstimatorOptions::tolerance`] of its σ (angle-wrapped difference)
//!    from the previous pass, at most [`EstimatorOptions::max_passes`]
//!    passes in all (default 4 passes, 0.1 σ).
//!
//! It returns the last pass's filter and a [`PassReport`]. A step that fails
//! (an `Err` from [`Filter::step`] or [`Filter::predict`]) is counted and
//! the pass continues; the filter is then left as it was before the period
//! (except for [`crate::ekf::Error::Gated`], where the prediction stands and
//! only the update is dropped).
//!
//! # Memory
//!
//! No heap and nothing proportional to the run: one filter, three state
//! vectors and the computed frame on the stack. The log is the caller's
//! ([`SliceLog`] over a RAM slice, [`PackedLog`] over a RAM byte slice,
//! `FlashLog` over a NOR flash with feature `flash-log`, or an
//! implementation of [`SampleLog`] of the caller's, see [`log`]).
//!
//! # Walking the computed frame backwards
//!
//! The commanded motion of a period depends on the computed frame `C^c_n`
//! at its start ([`CommandFrame::period`]), so the back-propagation needs
//! `C^c_n` at every period boundary, in reverse order, without storing the
//! periods. The estimator integrates `C^c_n` forward once, during pass 1,
//! over every usable record (a failed step leaves the filter's own frame
//! behind, but the platform still moved), keeps only the end frame, and then
//! walks backwards one period at a time with
//! [`CommandFrame::period_before`], the exact inverse of
//! [`CommandFrame::period`] by a fixed-point iteration (the Earth-rate term
//! contracts it by ≈ 1e-4 per iteration). That costs one extra read of
//! every record per pass and nothing in memory. The same walk from the end
//! of a calibrator's run finds where its log started
//! ([`LogStart::walked_back`]). Each period is inverted to
//! ≤ 4e-16; after the 5400 periods of the paper's path the frame comes back
//! to `C^c_n(0) = I` within 6e-14, and the back-propagated state agrees with
//! one propagated through periods stored on the way forward to ≈ 1e-17 rad
//! (tests in `command.rs` and `tests/it/estimator.rs`). The alternative, re-walking the frame
//! forward from the start with checkpoints, needs either storage for
//! `√n` checkpoints or `O(n²)` recomputation.
//!
//! # Cost
//!
//! Each pass reads every record once forwards; between passes the
//! back-propagation reads them once more backwards: at most
//! `2·max_passes − 1` reads of each record.

#[cfg(feature = "flash-log")]
pub mod flash;
pub mod log;
pub mod packed;
mod start;

#[cfg(feature = "flash-log")]
pub use flash::{FlashLog, FlashLogError, DEFAULT_SEGMENTS, MAX_SLOT};
pub use log::{LogError, LogRecord, SampleLog, SliceLog};
pub use packed::{PackedLayout, PackedLog, MAX_PERIODS};
pub use start::LogStart;

use nalgebra::{RealField, SVector};

use crate::command::{CommandFrame, Period};
use crate::ekf::{self, Filter, FilterConfig, Innovation};
use crate::geometry::wrap_angle;
use crate::models::{Environment, InstallationMatrices, Layout, Model};

/// Default [`EstimatorOptions::max_passes`].
pub const DEFAULT_MAX_PASSES: u8 = 4;
/// Default [`EstimatorOptions::tolerance`] (fraction of σ).
pub const DEFAULT_TOLERANCE: f64 = 0.1;

/// How many passes the estimator runs.
///
/// # Examples
///
/// ```
/// use rollcal::estimator::{EstimatorOptions, DEFAULT_MAX_PASSES};
///
/// // The default: up to 4 passes, stopping once no state moves by 0.1 σ.
/// let default = EstimatorOptions::default();
/// assert_eq!((default.max_passes, default.tolerance), (DEFAULT_MAX_PASSES, 0.1));
/// // Pass 1 alone: the extended filter, as the calibrator runs it live.
/// let pass_1 = EstimatorOptions { max_passes: 1, ..default };
/// assert_eq!(pass_1.max_passes, 1);
/// ```
///
/// The filter options of pass 1 (the cold-start remedy and the NIS gate)
/// are [`FilterConfig::options`] of the configuration given to
/// [`estimate`]; every pass uses that same configuration (in the
/// linearised passes only the NIS gate and the second-order dynamics
/// option still act).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EstimatorOptions {
    /// At most this many passes over the log (0 counts as 1). 1: the
    /// extended filter alone.
    pub max_passes: u8,
    /// The passes stop once no final state moves by `tolerance · σ` or more
    /// from the previous pass's final estimate (σ of the new pass; a
    /// fraction, ≥ 0 and finite; 0 never stops early).
    pub tolerance: f64,
}

impl Default for EstimatorOptions {
    fn default() -> Self {
        Self {
            max_passes: DEFAULT_MAX_PASSES,
            tolerance: DEFAULT_TOLERANCE,
        }
    }
}

/// Why the estimator could not produce an estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EstimatorError {
    /// The log holds no record.
    EmptyLog,
    /// [`Filter::new`] rejected the configuration, `x0` or the prior σ.
    Filter(ekf::Error),
    /// The log did not return record `index` (`index < len()`): a storage
    /// read failed or the record is corrupt.
    Read {
        /// Record index (0-based).
        index: usize,
    },
    /// Back-propagating the state through record `index` failed (gimbal
    /// lock of the Euler attitude, or a non-finite state).
    BackPropagation {
        /// Record index (0-based).
        index: usize,
    },
    /// [`EstimatorOptions::tolerance`] is negative or not finite.
    InvalidTolerance,
}

impl core::fmt::Display for EstimatorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            EstimatorError::EmptyLog => f.write_str("the sample log is empty"),
            EstimatorError::Filter(e) => write!(f, "filter: {e}"),
            EstimatorError::Read { index } => {
                write!(f, "the sample log did not return record {index}")
            }
            EstimatorError::BackPropagation { index } => write!(
                f,
                "back-propagation failed at record {index} (gimbal lock or non-finite state)"
            ),
            EstimatorError::InvalidTolerance => {
                f.write_str("pass tolerance is negative or not finite")
            }
        }
    }
}

impl core::error::Error for EstimatorError {}

impl From<ekf::Error> for EstimatorError {
    fn from(e: ekf::Error) -> Self {
        EstimatorError::Filter(e)
    }
}

/// A step that failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Failure {
    /// Record index (0-based).
    pub index: usize,
    /// What the filter returned.
    pub error: ekf::Error,
}

/// What the estimator did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PassReport {
    /// Passes run (1 … `max_passes`).
    pub passes: u8,
    /// Whether the last pass's final estimate moved by less than the
    /// tolerance from the previous one (always `false` after a single pass).
    pub converged: bool,
    /// Records in the log.
    pub records: usize,
    /// Steps of the last pass that returned an error, NIS-gated ones
    /// included.
    pub failures: u32,
    /// Of those, updates rejected by the NIS gate.
    pub gated: u32,
    /// The first failed step of the last pass.
    pub first_failure: Option<Failure>,
}

/// The outcome of [`estimate`].
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome<T: RealField + Copy, M, const N: usize, const Z: usize> {
    /// The filter at the end of the last pass: its state (rad) and
    /// covariance (rad²) are the estimate at the end of the run.
    pub filter: Filter<T, M, N, Z>,
    /// Passes, convergence and failures.
    pub report: PassReport,
}

/// One processed record, passed to the observer of [`estimate`] after the
/// filter's step.
#[derive(Debug)]
pub struct PassEvent<'a, T: RealField + Copy, M, const N: usize, const Z: usize> {
    /// Pass number, from 1. A new pass starts again at `index` 0, with a
    /// fresh filter.
    pub pass: u8,
    /// Record index (0-based).
    pub index: usize,
    /// The record.
    pub record: &'a LogRecord<T>,
    /// The step's result: the innovation of the update, `None` for a
    /// record without measurement (predicted only), or the filter's error.
    pub result: Result<Option<Innovation<T, Z>>, ekf::Error>,
    /// The filter after the step.
    pub filter: &'a Filter<T, M, N, Z>,
}

/// Tally of one pass.
#[derive(Clone, Copy, Default)]
struct Tally {
    failures: u32,
    gated: u32,
    first: Option<Failure>,
}

impl Tally {
    fn fail(&mut self, index: usize, error: ekf::Error) {
        self.failures = self.failures.saturating_add(1);
        if error == ekf::Error::Gated {
            self.gated = self.gated.saturating_add(1);
        }
        if self.first.is_none() {
            self.first = Some(Failure { index, error });
        }
    }
}

/// The multi-pass estimator of configuration `M` over every record of
/// `log` (see the [module docs](self)).
///
/// `config`: noise, environment and the filter options of every pass;
/// `x0`: initial estimate (rad, the configuration's state order; zeros for
/// a cold start); `sigma0`: prior σ of every state (rad); `passes`: how
/// many passes. `observer` is called after every step of every pass (use
/// `|_| {}` for none); it lets a caller keep a time history or the NIS of
/// the last pass without the library storing anything.
///
/// Errors: [`EstimatorError::EmptyLog`], an invalid tolerance, a prior that
/// [`Filter::new`] rejects, a record the log cannot return, or a failed
/// back-propagation. Never panics. [`estimate_in`] is the same without a
/// filter returned by value (for a small stack).
///
/// # Examples
///
/// The estimator of record of M1-pa over a recorded run of 30 periods of
/// a platform at rest, kept in RAM:
///
/// ```
/// use nalgebra::{SVector, Vector3};
/// use rollcal::ekf::{FilterConfig, Observation};
/// use rollcal::estimator::{estimate, EstimatorOptions, LogRecord, SliceLog};
/// use rollcal::models::{ConfigId, M1Pa};
/// use rollcal::wire::CalibratorConfig;
///
/// let settings = CalibratorConfig::paper(ConfigId::M1Pa);
/// let config = FilterConfig::<f64>::from(&settings);
/// // At rest in the navigation frame: the commanded increment is the Earth
/// // rate's, the accelerometers read 1 g up.
/// let at_rest = LogRecord::measured(
///     1.0,
///     Vector3::from(settings.earth_rate_n),
///     Observation { accel_mean: Vector3::new(0.0, 1.0, 0.0), gimbal: None },
/// );
/// let mut records = [at_rest; 30];
/// let mut log = SliceLog::from_records(&mut records);
/// let x0 = SVector::<f64, 12>::zeros();
/// let sigma0 = SVector::<f64, 12>::repeat(settings.prior_sigma_rad);
/// // (pass, updates in that pass), kept by the observer.
/// let mut last_pass = (0, 0);
/// let outcome = estimate::<f64, M1Pa, 12, 3, _, _>(
///     &config,
///     &x0,
///     &sigma0,
///     &mut log,
///     &EstimatorOptions::default(),
///     |e| {
///         if e.pass != last_pass.0 {
///             last_pass = (e.pass, 0);
///         }
///         if let Ok(Some(_innovation)) = &e.result {
///             last_pass.1 += 1;
///         }
///     },
/// )?;
/// assert_eq!(outcome.report.records, 30);
/// assert!(outcome.report.passes >= 2);
/// assert_eq!(last_pass, (outcome.report.passes, 30));
/// // The run excites little: σ of every state is at most the prior's.
/// assert!(outcome.filter.sigma().iter().all(|s| *s <= settings.prior_sigma_rad));
/// # Ok::<(), rollcal::estimator::EstimatorError>(())
/// ```
pub fn estimate<T, M, const N: usize, const Z: usize, L, F>(
    config: &FilterConfig<T>,
    x0: &SVector<f64, N>,
    sigma0: &SVector<T, N>,
    log: &mut L,
    passes: &EstimatorOptions,
    observer: F,
) -> Result<Outcome<T, M, N, Z>, EstimatorError>
where
    T: RealField + Copy,
    M: Model<N, Z>,
    L: SampleLog<T> + ?Sized,
    F: FnMut(&PassEvent<'_, T, M, N, Z>),
{
    let mut filter = Filter::<T, M, N, Z>::new(*config, *x0, *sigma0)?;
    let report = estimate_in(&mut filter, config, x0, sigma0, log, passes, observer)?;
    Ok(Outcome { filter, report })
}

/// [`estimate`] in the caller's `filter`: every pass restarts it in place
/// ([`Filter::restart`] at `config`, `x0`, `sigma0`; whatever it held
/// before does not matter), and after `Ok` it is the filter at the end of
/// the last pass ([`Outcome::filter`]). A firmware's stack then holds one
/// filter, not the filter, the outcome and a copy of both. On error the
/// filter is left as the failing pass left it.
///
/// The log starts at the path's start ([`LogStart::aligned`]);
/// [`estimate_from`] takes a log that starts elsewhere.
pub fn estimate_in<T, M, const N: usize, const Z: usize, L, F>(
    filter: &mut Filter<T, M, N, Z>,
    config: &FilterConfig<T>,
    x0: &SVector<f64, N>,
    sigma0: &SVector<T, N>,
    log: &mut L,
    passes: &EstimatorOptions,
    observer: F,
) -> Result<PassReport, EstimatorError>
where
    T: RealField + Copy,
    M: Model<N, Z>,
    L: SampleLog<T> + ?Sized,
    F: FnMut(&PassEvent<'_, T, M, N, Z>),
{
    let start = PassStart {
        x0,
        sigma0,
        at: LogStart::aligned(),
    };
    estimate_from(filter, config, &start, log, passes, observer)
}

/// Where every pass of [`estimate_from`] restarts: the prior (estimate
/// `x0`, σ `sigma0`, rad) at the log's start `at`.
#[derive(Clone, Copy, Debug)]
pub struct PassStart<'a, T: RealField + Copy, const N: usize> {
    /// Initial estimate (rad), its attitude states those of the start
    /// ([`LogStart::state`]).
    pub x0: &'a SVector<f64, N>,
    /// Prior σ of every state (rad).
    pub sigma0: &'a SVector<T, N>,
    /// The computed frame at the start of the log's first period.
    pub at: LogStart,
}

/// [`estimate_in`] over a log that starts at `start.at`: every pass
/// restarts the filter at `start.x0`, `start.sigma0` with its computed
/// frame there ([`Filter::start_at`]), and pass 1 integrates the frame
/// from there to the end of the run for the back-propagation. What the
/// calibrator's `Finish` runs ([`crate::calibrator::Calibrator::finish_in`],
/// the start from [`LogStart::walked_back`]).
pub fn estimate_from<T, M, const N: usize, const Z: usize, L, F>(
    filter: &mut Filter<T, M, N, Z>,
    config: &FilterConfig<T>,
    start: &PassStart<'_, T, N>,
    log: &mut L,
    passes: &EstimatorOptions,
    mut observer: F,
) -> Result<PassReport, EstimatorError>
where
    T: RealField + Copy,
    M: Model<N, Z>,
    L: SampleLog<T> + ?Sized,
    F: FnMut(&PassEvent<'_, T, M, N, Z>),
{
    let (x0, sigma0) = (start.x0, start.sigma0);
    let start_frame = start.at.frame(config.env.earth_rate_n);
    let records = log.len();
    if records == 0 {
        return Err(EstimatorError::EmptyLog);
    }
    if !(passes.tolerance.is_finite() && passes.tolerance >= 0.0) {
        return Err(EstimatorError::InvalidTolerance);
    }
    let max = passes.max_passes.max(1);
    let mut nominal: Option<SVector<f64, N>> = None;
    let mut previous: Option<SVector<f64, N>> = None;
    // C^c_n at the end of the run, integrated during pass 1.
    let mut end_frame: Option<CommandFrame<f64>> = None;
    let mut pass: u8 = 1;
    loop {
        filter.restart(*config, *x0, *sigma0)?;
        filter.start_at(&start_frame.c_cn)?;
        filter.set_nominal(nominal);
        let tally = run_pass(filter, log, pass, &mut end_frame, &mut observer)?;
        let converged = converged(filter, previous.as_ref(), passes.tolerance);
        if converged || pass >= max {
            return Ok(PassReport {
                passes: pass,
                converged,
                records,
                failures: tally.failures,
                gated: tally.gated,
                first_failure: tally.first,
            });
        }
        let x = *filter.state();
        let end = end_frame.unwrap_or(start_frame);
        let (x_start, _) = back_propagate_out_of_line(M::LAYOUT, &config.env, &x, &end, log)?;
        nominal = Some(x_start);
        previous = Some(x);
        pass = pass.saturating_add(1);
    }
}

/// One pass of [`estimate_in`] over every record of `log` in `filter`
/// (restarted at the log's start), the computed frame of pass 1
/// integrated from the filter's start into `end_frame` on the way. Out of line, as are the steps between passes: the frame
/// above every filter step of `Finish` is this one's (a record, the
/// step's result), not the passes' bookkeeping (a firmware's stack; the
/// full model's vectors are 0.3 KB each in f64).
#[inline(never)]
fn run_pass<T, M, const N: usize, const Z: usize, L, F>(
    filter: &mut Filter<T, M, N, Z>,
    log: &mut L,
    pass: u8,
    end_frame: &mut Option<CommandFrame<f64>>,
    observer: &mut F,
) -> Result<Tally, EstimatorError>
where
    T: RealField + Copy,
    M: Model<N, Z>,
    L: SampleLog<T> + ?Sized,
    F: FnMut(&PassEvent<'_, T, M, N, Z>),
{
    let mut frame = match end_frame {
        Some(_) => None,
        None => Some(*filter.command_frame()),
    };
    let mut tally = Tally::default();
    for index in 0..log.len() {
        let record = log.get(index).ok_or(EstimatorError::Read { index })?;
        let result = match &record.observation {
            Some(obs) => filter.step(&record.dtheta_cmd, record.dt, obs).map(Some),
            None => filter.predict(&record.dtheta_cmd, record.dt).map(|()| None),
        };
        if let Err(e) = result {
            tally.fail(index, e);
        }
        if let Some(frame) = frame.as_mut().filter(|_| record.has_valid_period()) {
            let p = frame.period(&record.dtheta_cmd, record.dt);
            frame.advance(&p);
        }
        observer(&PassEvent {
            pass,
            index,
            record: &record,
            result,
            filter,
        });
    }
    if let Some(frame) = frame {
        *end_frame = Some(frame);
    }
    Ok(tally)
}

/// Whether no state of `filter` moved by `tolerance` σ or more from
/// `previous`, the last pass's estimate (`false` after pass 1). A state
/// the model holds (σ 0: a term not estimated) has converged when it did
/// not move at all. Out of line (see [`run_pass`]).
#[inline(never)]
fn converged<T, M, const N: usize, const Z: usize>(
    filter: &Filter<T, M, N, Z>,
    previous: Option<&SVector<f64, N>>,
    tolerance: f64,
) -> bool
where
    T: RealField + Copy,
    M: Model<N, Z>,
{
    let x = filter.state();
    let sigma = filter.sigma();
    previous.is_some_and(|prev| {
        x.iter()
            .zip(prev.iter())
            .zip(sigma.iter())
            .all(|((a, b), s)| {
                let moved = wrap_angle(*a - *b).abs();
                moved < tolerance * s.to_subset().unwrap_or(f64::NAN) || moved == 0.0
            })
    })
}

/// [`back_propagate`] out of line (see [`run_pass`]).
#[inline(never)]
fn back_propagate_out_of_line<T, const N: usize, L>(
    layout: Layout,
    env: &Environment<f64>,
    x_end: &SVector<f64, N>,
    frame_end: &CommandFrame<f64>,
    log: &mut L,
) -> Result<(SVector<f64, N>, CommandFrame<f64>), EstimatorError>
where
    T: RealField + Copy,
    L: SampleLog<T> + ?Sized,
{
    back_propagate(layout, env, x_end, frame_end, log)
}

/// The state `x_end` at the end of the run recorded in `log`, integrated
/// backwards through every period of the log to its start, by the model
/// dynamics of `layout` in environment `env` (parameters constant, the
/// attitude integrated with [`Layout::propagate_state`] on
/// [`Period::reversed`]). `frame_end` is the computed frame `C^c_n` at the
/// end of the run. Records whose period is unusable
/// ([`LogRecord::has_valid_period`] false) are skipped, as the filter
/// skips them.
///
/// Returns the state at the start (rad) and the computed frame walked back
/// to the start (for a run that began aligned, `C^c_n ≈ I` to rounding: a
/// check of the walk). No storage: the periods are rebuilt from the end
/// with [`CommandFrame::period_before`].
pub fn back_propagate<T, const N: usize, L>(
    layout: Layout,
    env: &Environment<f64>,
    x_end: &SVector<f64, N>,
    frame_end: &CommandFrame<f64>,
    log: &mut L,
) -> Result<(SVector<f64, N>, CommandFrame<f64>), EstimatorError>
where
    T: RealField + Copy,
    L: SampleLog<T> + ?Sized,
{
    let mut x = *x_end;
    let mut frame = *frame_end;
    // The parameters are constant: their matrices once, in `T` (from the
    // parameters rounded to `T`), with the environment in `T`, as the
    // filter's propagation forms the attitude's increments.
    let matrices = InstallationMatrices::new(layout.installation(x_end).to_precision::<T>());
    let env_t = env.to_precision::<T>();
    for index in (0..log.len()).rev() {
        let record = log.get(index).ok_or(EstimatorError::Read { index })?;
        if !record.has_valid_period() {
            continue;
        }
        let period: Period<f64> = frame.period_before(&record.dtheta_cmd, record.dt);
        x = layout
            .propagate_state_in(
                &env_t,
                &matrices,
                &x,
                &period.reversed().to_precision::<T>(),
            )
            .filter(|v| v.iter().all(|c| c.is_finite()))
            .ok_or(EstimatorError::BackPropagation { index })?;
        frame.retreat(&period);
    }
    Ok((x, frame))
}
