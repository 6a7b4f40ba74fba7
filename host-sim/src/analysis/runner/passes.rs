//! The estimator of record over a run's periods
//! ([`rollcal::estimator::estimate`]), dispatched on the configuration and
//! the precision, keeping the last pass's history, NIS, updates and
//! failures.

use nalgebra::RealField;
use rollcal::ekf::{self, FilterConfig, Options};
use rollcal::estimator::{self, EstimatorError, EstimatorOptions, LogRecord, SliceLog};
use rollcal::models::{ConfigId, ErrorModel, Model};

use super::config::{initial, observation_t};
use super::context::SimulatedRun;
use super::filter::{f64_of, DynFilter, Precision};
use super::results::{RunResult, StateResult, Update};
use crate::sim::scenario::Scenario;
use crate::sim::segments::{command_segments, CommandSegment};
use crate::sim::truth::{PeriodSample, Simulation};

/// How the estimator processes a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimator {
    /// Filter options (cold-start remedy of the first pass).
    pub options: Options,
    /// At most this many passes over the data. 1: the extended filter alone.
    /// Each further pass is a filter linearised about the previous pass's
    /// final estimate propagated back to the start (a Gauss–Newton step on
    /// the whole run); the passes stop once the final estimate moves by less
    /// than [`estimator::DEFAULT_TOLERANCE`] of its σ
    /// ([`rollcal::estimator`]).
    pub passes: u8,
    /// Precision of the covariance arithmetic.
    pub precision: Precision,
}

impl Default for Estimator {
    fn default() -> Self {
        Self {
            options: Options::default(),
            passes: estimator::DEFAULT_MAX_PASSES,
            precision: Precision::F64,
        }
    }
}

/// The outcome of [`run_passes`]: the last pass's filter and records.
pub struct Passes {
    /// The filter after the last pass.
    pub filter: Box<dyn DynFilter>,
    /// Time history of the last pass (when kept).
    pub history: Vec<(f64, Vec<f64>, Vec<f64>)>,
    /// NIS per period of the last pass.
    pub nis: Vec<f64>,
    /// The accepted updates of the last pass.
    pub updates: Vec<Update>,
    /// The constant-command segments of the log.
    pub segments: Vec<CommandSegment>,
    /// Failed updates of the last pass.
    pub failures: Vec<(u32, ekf::Error)>,
    /// Passes run.
    pub passes: u8,
}

/// What the observer keeps of the last pass.
#[derive(Default)]
struct LastPass {
    pass: u8,
    history: Vec<(f64, Vec<f64>, Vec<f64>)>,
    nis: Vec<f64>,
    updates: Vec<Update>,
    failures: Vec<(u32, ekf::Error)>,
}

#[allow(clippy::too_many_arguments)]
fn passes_of<
    T: RealField + Copy + Send,
    M: Model<N, Z> + Send + 'static,
    const N: usize,
    const Z: usize,
>(
    cfg: FilterConfig<f64>,
    sigma0: &[f64],
    samples: &[PeriodSample],
    options: &EstimatorOptions,
    x0: &[f64],
    keep_history: bool,
) -> Result<Passes, EstimatorError> {
    let mut storage: Vec<LogRecord<T>> = samples
        .iter()
        .map(|s| LogRecord::measured(s.dt, s.dtheta_cmd, observation_t::<T>(s)))
        .collect();
    let mut log = SliceLog::from_records(&mut storage);
    let (x, s64) = initial::<N>(x0, sigma0);
    let s = s64.map(nalgebra::convert::<f64, T>);
    let cfg = cfg.to_precision::<T>();
    let mut last = LastPass::default();
    let out = estimator::estimate::<T, M, N, Z, _, _>(&cfg, &x, &s, &mut log, options, |ev| {
        if ev.pass != last.pass {
            last = LastPass {
                pass: ev.pass,
                nis: Vec::with_capacity(samples.len()),
                ..LastPass::default()
            };
        }
        let sample = samples.get(ev.index);

        match ev.result {
            Ok(Some(i)) => {
                last.nis.push(f64_of(i.nis));
                let t = sample.map_or(f64::NAN, |s| s.truth.t);
                last.updates.push(Update::of(ev.index, t, &i));
            }
            Ok(None) => {}
            Err(e) => last.failures.push((sample.map_or(0, |s| s.k), e)),
        }
        if keep_history {
            let t = sample.map_or(f64::NAN, |s| s.truth.t);
            last.history
                .push((t, DynFilter::state(ev.filter), DynFilter::sigma(ev.filter)));
        }
    })?;
    Ok(Passes {
        filter: Box::new(out.filter),
        history: last.history,
        nis: last.nis,
        updates: last.updates,
        segments: segments_of_samples(samples),
        failures: last.failures,
        passes: out.report.passes,
    })
}

/// The constant-command segments of simulated periods.
pub fn segments_of_samples(samples: &[PeriodSample]) -> Vec<CommandSegment> {
    command_segments(samples.iter().map(|s| (s.dt, s.dtheta_cmd.into())))
}

/// The multi-pass estimator ([`rollcal::estimator::estimate`]) of
/// configuration `id` over `samples` (only their increments, periods,
/// accelerometer means and gimbal angles are used; `truth.t` labels the
/// history), from `x0` with prior σ `sigma0` of every state (internal
/// units), configuration `id` under error model `errors`.
#[allow(clippy::too_many_arguments)]
pub fn run_passes(
    id: ConfigId,
    errors: ErrorModel,
    cfg: FilterConfig<f64>,
    sigma0: &[f64],
    samples: &[PeriodSample],
    estimator: Estimator,
    x0: &[f64],
    keep_history: bool,
) -> Result<Passes, ekf::Error> {
    let options = EstimatorOptions {
        max_passes: estimator.passes,
        ..EstimatorOptions::default()
    };
    let (o, h) = (&options, keep_history);
    let out = match estimator.precision {
        Precision::F64 => rollcal::with_model!(id, errors, |M, N, Z| passes_of::<f64, M, N, Z>(
            cfg, sigma0, samples, o, x0, h
        )),
        Precision::F32 => rollcal::with_model!(id, errors, |M, N, Z| passes_of::<f32, M, N, Z>(
            cfg, sigma0, samples, o, x0, h
        )),
    };
    out.map_err(|e| match e {
        EstimatorError::Filter(e) => e,
        EstimatorError::BackPropagation { .. } => ekf::Error::GimbalLock,
        _ => ekf::Error::NoPrediction,
    })
}

/// Runs configuration `id` from `x0` (zeros: cold start) over `sim`
/// ([`SimulatedRun::run`]).
pub fn run_filter(
    id: ConfigId,
    scenario: &Scenario,
    sim: &Simulation,
    earth_rate: bool,
    estimator: Estimator,
    x0: Option<&[f64]>,
    keep_history: bool,
) -> Result<RunResult, ekf::Error> {
    SimulatedRun::new(id, scenario, sim, earth_rate).run(estimator, x0, keep_history)
}

/// A [`RunResult`] from the outcome of [`run_passes`] (configuration `id`
/// under error model `errors`), the true final state `truth` (NaN where
/// unknown) and the prior σ of every state `sigma0` (internal units; a
/// short slice is extended by its last value, as the initial prior is).
pub fn result(
    id: ConfigId,
    errors: ErrorModel,
    p: &Passes,
    truth: &[f64],
    sigma0: &[f64],
) -> RunResult {
    let f = &p.filter;
    let (est, sig) = (f.state(), f.sigma());
    let at = |v: &[f64], i: usize| v.get(i).copied().unwrap_or(f64::NAN);
    let states = id
        .states_with(errors)
        .iter()
        .enumerate()
        .map(|(i, info)| StateResult {
            name: info.name,
            group: info.group.as_str(),
            truth_rad: at(truth, i),
            estimate_rad: at(&est, i),
            sigma_rad: at(&sig, i),
            prior: sigma0.get(i).or(sigma0.last()).copied().unwrap_or(f64::NAN),
            info: *info,
        })
        .collect();
    RunResult {
        config: id,
        errors,
        states,
        covariance: f.covariance(),
        history: p.history.clone(),
        nis: p.nis.clone(),
        updates: p.updates.clone(),
        segments: p.segments.clone(),
        prior_sigma_rad: sigma0.first().copied().unwrap_or(f64::NAN),
        passes: p.passes,
        failures: p.failures.clone(),
    }
}
