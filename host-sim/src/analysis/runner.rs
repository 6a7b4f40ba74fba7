//! Runs a configuration's estimator over a simulated (or replayed) run.
//!
//! The estimator itself (the multi-pass filter) is the library's
//! [`rollcal::estimator::estimate`]; this module only puts a run's samples
//! into a [`SliceLog`], dispatches on the configuration and collects the
//! time history, NIS and failures of the last pass for the reports.

use nalgebra::{RealField, SVector};
use rollcal::ekf::{self, Filter, FilterConfig, Observation, Options};
use rollcal::estimator::{self, EstimatorError, EstimatorOptions, LogRecord, SliceLog};
use rollcal::geometry::{wrap_angle, EARTH_RATE};
use rollcal::models::{ConfigId, Environment, Group, Model};
use rollcal::observability::Observability;

use crate::sim::scenario::{Scenario, ARCSEC, DEG};
use crate::sim::segments::{command_segments, CommandSegment};
use crate::sim::truth::{truth_state, PeriodSample, Simulation};

/// Object-safe view of a filter of any configuration and precision
/// (values reported in f64).
pub trait DynFilter: Send {
    /// One period.
    fn step(&mut self, s: &PeriodSample) -> Result<f64, ekf::Error>;
    /// Estimate (rad).
    fn state(&self) -> Vec<f64>;
    /// σ (rad).
    fn sigma(&self) -> Vec<f64>;
    /// Covariance, row-major (rad²).
    fn covariance(&self) -> Vec<f64>;
}

/// A value of precision `T` in f64 (exact for f32).
fn f64_of<T: RealField + Copy>(v: T) -> f64 {
    v.to_subset().unwrap_or(f64::NAN)
}

impl<T: RealField + Copy + Send, M: Model<N, Z> + Send, const N: usize, const Z: usize> DynFilter
    for Filter<T, M, N, Z>
{
    fn step(&mut self, s: &PeriodSample) -> Result<f64, ekf::Error> {
        let obs = observation_t::<T>(s);
        Filter::step(self, &s.dtheta_cmd, s.dt, &obs).map(|i| f64_of(i.nis))
    }
    fn state(&self) -> Vec<f64> {
        Filter::state(self).iter().copied().collect()
    }
    fn sigma(&self) -> Vec<f64> {
        Filter::sigma(self).iter().map(|v| f64_of(*v)).collect()
    }
    fn covariance(&self) -> Vec<f64> {
        Filter::covariance(self)
            .transpose()
            .iter()
            .map(|v| f64_of(*v))
            .collect()
    }
}

/// The precision of the filter's covariance arithmetic (its state, nominal
/// and residuals are f64 in both, see [`rollcal::ekf::Filter`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// Double precision (the host's default).
    #[default]
    F64,
    /// Single precision, as on an FPU without f64 (Cortex-M4F).
    F32,
}

impl Precision {
    /// `"f64"` or `"f32"`.
    pub const fn as_str(self) -> &'static str {
        match self {
            Precision::F64 => "f64",
            Precision::F32 => "f32",
        }
    }
}

/// The measurement of a simulated period in precision `T`.
fn observation_t<T: RealField + Copy>(s: &PeriodSample) -> Observation<T> {
    Observation {
        accel_mean: s.accel_mean.map(nalgebra::convert::<f64, T>),
        gimbal: Some(s.gimbal.map(nalgebra::convert::<f64, T>)),
    }
}

/// The measurement of a simulated period (accelerometer mean, gimbal angles).
fn observation(s: &PeriodSample) -> Observation<f64> {
    Observation {
        accel_mean: s.accel_mean,
        gimbal: Some(s.gimbal),
    }
}

/// A simulated period as the library's estimator replays it.
pub fn log_record(s: &PeriodSample) -> LogRecord<f64> {
    LogRecord::measured(s.dt, s.dtheta_cmd, observation(s))
}

/// Filter settings derived from a scenario.
pub fn filter_config(s: &Scenario, earth_rate: bool, options: Options) -> FilterConfig<f64> {
    filter_config_of(&s.site, &s.noise, earth_rate, options)
}

/// [`filter_config`] of a site and noise levels (a scenario's or a
/// platform file's).
pub fn filter_config_of(
    site: &crate::sim::scenario::Site,
    noise: &crate::sim::scenario::Noise,
    earth_rate: bool,
    options: Options,
) -> FilterConfig<f64> {
    let omega = if site.earth_rate && earth_rate {
        EARTH_RATE
    } else {
        0.0
    };
    let lat = site.latitude_deg * DEG;
    FilterConfig {
        env: Environment {
            earth_rate_n: rollcal::geometry::earth_rate_n(omega, lat),
            gravity_n: rollcal::geometry::gravity_n(),
        },
        sigma_accel: noise.accel_g,
        sigma_gyro: noise.gyro_deg_h * DEG / 3600.0,
        sigma_gimbal: noise.gimbal_arcsec * ARCSEC,
        options,
    }
}

fn initial<const N: usize>(x0: &[f64], sigma0: f64) -> (SVector<f64, N>, SVector<f64, N>) {
    let x = SVector::<f64, N>::from_iterator(x0.iter().copied().chain(std::iter::repeat(0.0)));
    (x, SVector::<f64, N>::repeat(sigma0))
}

/// One state at the end of a run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StateResult {
    /// State name (docs/model.md §State names), e.g. `thgC_x`.
    pub name: &'static str,
    /// Group, e.g. `thgC`.
    pub group: &'static str,
    /// Truth (rad).
    pub truth_rad: f64,
    /// Estimate (rad).
    pub estimate_rad: f64,
    /// Filter σ (rad).
    pub sigma_rad: f64,
}

impl StateResult {
    /// Estimation error (rad); angle-wrapped for the attitude states.
    pub fn error(&self) -> f64 {
        wrap_angle(self.estimate_rad - self.truth_rad)
    }
    /// |error| / σ.
    pub fn ratio(&self) -> f64 {
        self.error().abs() / self.sigma_rad
    }
}

/// One accepted measurement update of the last pass.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Update {
    /// Index of its record in the log (0-based).
    pub index: usize,
    /// Time at the end of its period (s from the start of the log).
    pub t_s: f64,
    /// Normalised innovation squared `νᵀ S⁻¹ ν`.
    pub nis: f64,
    /// The whitened innovation `L⁻¹ ν` with `S = L Lᵀ` (Cholesky):
    /// independent unit-variance components when the model holds, in the
    /// order of the measurement (M2: the gimbal angles α, β, γ, then the
    /// accelerometer x, y, z; the accelerometer alone otherwise); empty
    /// when `S` was not positive definite.
    pub white: Vec<f64>,
}

impl Update {
    /// The update of record `index` at time `t_s` from its innovation.
    pub fn of<T: RealField + Copy, const Z: usize>(
        index: usize,
        t_s: f64,
        i: &ekf::Innovation<T, Z>,
    ) -> Self {
        let nu = i.nu.map(f64_of);
        let s = i.s.map(f64_of);
        let white = s
            .cholesky()
            .and_then(|c| c.l().solve_lower_triangular(&nu))
            .map_or_else(Vec::new, |w| w.iter().copied().collect());
        Self {
            index,
            t_s,
            nis: f64_of(i.nis),
            white,
        }
    }
}

/// A whole run.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// Configuration.
    pub config: ConfigId,
    /// Final states.
    pub states: Vec<StateResult>,
    /// Final covariance, row-major (rad²).
    pub covariance: Vec<f64>,
    /// Time history: (t, estimate, σ) per period.
    pub history: Vec<(f64, Vec<f64>, Vec<f64>)>,
    /// NIS per period.
    pub nis: Vec<f64>,
    /// The accepted updates of the last pass (NIS and whitened innovation).
    pub updates: Vec<Update>,
    /// The path's constant-command segments, from the commanded increments
    /// ([`crate::sim::segments::command_segments`]).
    pub segments: Vec<CommandSegment>,
    /// Prior σ of every state (rad).
    pub prior_sigma_rad: f64,
    /// Passes over the data that were run.
    pub passes: u8,
    /// Updates that failed, with their period index and error.
    pub failures: Vec<(u32, ekf::Error)>,
}

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
    sigma0: f64,
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
/// history), from `x0` with prior σ `sigma0`.
pub fn run_passes(
    id: ConfigId,
    cfg: FilterConfig<f64>,
    sigma0: f64,
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
        Precision::F64 => rollcal::with_config!(id, |M, N, Z| passes_of::<f64, M, N, Z>(
            cfg, sigma0, samples, o, x0, h
        )),
        Precision::F32 => rollcal::with_config!(id, |M, N, Z| passes_of::<f32, M, N, Z>(
            cfg, sigma0, samples, o, x0, h
        )),
    };
    out.map_err(|e| match e {
        EstimatorError::Filter(e) => e,
        EstimatorError::BackPropagation { .. } => ekf::Error::GimbalLock,
        _ => ekf::Error::NoPrediction,
    })
}

/// Runs configuration `id` from `x0` (zeros: cold start) over `sim`.
pub fn run_filter(
    id: ConfigId,
    scenario: &Scenario,
    sim: &Simulation,
    earth_rate: bool,
    estimator: Estimator,
    x0: Option<&[f64]>,
    keep_history: bool,
) -> Result<RunResult, ekf::Error> {
    let cfg = filter_config(scenario, earth_rate, estimator.options);
    let zeros = vec![0.0; id.layout().n()];
    let x0 = x0.unwrap_or(&zeros);
    let sigma0 = scenario.prior.sigma_deg * DEG;
    let p = run_passes(id, cfg, sigma0, &sim.samples, estimator, x0, keep_history)?;
    let last = sim.samples.last().map_or(sim.initial, |s| s.truth);
    let truth = truth_state(id, &sim.params, &last);
    Ok(result(id, &p, &truth, sigma0))
}

/// A [`RunResult`] from the outcome of [`run_passes`] and the true final
/// state `truth` (NaN where unknown).
pub fn result(id: ConfigId, p: &Passes, truth: &[f64], sigma0: f64) -> RunResult {
    let f = &p.filter;
    let (est, sig) = (f.state(), f.sigma());
    let states = id
        .states()
        .iter()
        .enumerate()
        .map(|(i, info)| StateResult {
            name: info.name,
            group: info.group.as_str(),
            truth_rad: truth.get(i).copied().unwrap_or(f64::NAN),
            estimate_rad: est.get(i).copied().unwrap_or(f64::NAN),
            sigma_rad: sig.get(i).copied().unwrap_or(f64::NAN),
        })
        .collect();
    RunResult {
        config: id,
        states,
        covariance: f.covariance(),
        history: p.history.clone(),
        nis: p.nis.clone(),
        updates: p.updates.clone(),
        segments: p.segments.clone(),
        prior_sigma_rad: sigma0,
        passes: p.passes,
        failures: p.failures.clone(),
    }
}

/// Posterior Cramér–Rao bound σ (rad) of every state after the periods
/// `records`, from the true initial state `truth0` (rad; missing trailing
/// states are zero) with prior σ `sigma0` (rad) on every state and the noise
/// levels of `cfg` (its options are ignored): [`Observability`] along the
/// true trajectory, a record without measurement being a period that is
/// only predicted (docs/model.md §Observability, item 3). The one computation of the bound.
pub fn bound(
    id: ConfigId,
    cfg: FilterConfig<f64>,
    truth0: &[f64],
    sigma0: f64,
    records: &[LogRecord<f64>],
) -> Result<Vec<f64>, ekf::Error> {
    fn typed<M: Model<N, Z>, const N: usize, const Z: usize>(
        cfg: FilterConfig<f64>,
        truth0: &[f64],
        sigma0: f64,
        records: &[LogRecord<f64>],
    ) -> Result<Vec<f64>, ekf::Error> {
        let (x, s) = initial::<N>(truth0, sigma0);
        let mut obs = Observability::<f64, M, N, Z>::new(cfg, x, s)?;
        for r in records {
            obs.record(r)?;
        }
        Ok(obs.crlb_sigma().iter().copied().collect())
    }
    rollcal::with_config!(id, |M, N, Z| typed::<M, N, Z>(cfg, truth0, sigma0, records))
}

/// [`bound`] after every record: σ_CRLB (rad) of every state per record
/// (for the σ(t) figures).
pub fn bound_history(
    id: ConfigId,
    cfg: FilterConfig<f64>,
    truth0: &[f64],
    sigma0: f64,
    records: &[LogRecord<f64>],
) -> Result<Vec<Vec<f64>>, ekf::Error> {
    fn typed<M: Model<N, Z>, const N: usize, const Z: usize>(
        cfg: FilterConfig<f64>,
        truth0: &[f64],
        sigma0: f64,
        records: &[LogRecord<f64>],
    ) -> Result<Vec<Vec<f64>>, ekf::Error> {
        let (x, s) = initial::<N>(truth0, sigma0);
        let mut obs = rollcal::observability::Bound::<f64, M, N, Z>::bound_only(cfg, x, s)?;
        let mut out = Vec::with_capacity(records.len());
        for r in records {
            obs.record(r)?;
            out.push(obs.crlb_sigma().iter().copied().collect());
        }
        Ok(out)
    }
    rollcal::with_config!(id, |M, N, Z| typed::<M, N, Z>(cfg, truth0, sigma0, records))
}

/// Posterior Cramér–Rao bound σ (rad) of every state at the end of `sim`
/// ([`bound`] over all its periods, from its true initial state, with the
/// scenario's prior and noise levels).
pub fn crlb_sigma(
    id: ConfigId,
    scenario: &Scenario,
    sim: &Simulation,
    earth_rate: bool,
) -> Result<Vec<f64>, ekf::Error> {
    let cfg = filter_config(scenario, earth_rate, Options::plain());
    let truth0 = truth_state(id, &sim.params, &sim.initial);
    let records: Vec<LogRecord<f64>> = sim.samples.iter().map(log_record).collect();
    bound(id, cfg, &truth0, scenario.prior.sigma_deg * DEG, &records)
}

pub use crate::analysis::verdict::Verdict;

/// The verdict on state `s` of configuration `id` with prior σ `prior` (rad):
/// for a state the configuration observes, `FAILED` beyond 4σ of the truth,
/// `converged` within 4σ once σ is below [`crate::analysis::verdict::PRACTICAL_RATIO`]
/// of the prior, and `not observable` while it is not (a path that does not
/// excite it: the estimate is still the prior's); for the others,
/// `observable in practice` or `not observable` by the same ratio.
pub fn verdict(id: ConfigId, s: &StateResult, group: Group, prior: f64) -> Verdict {
    let practical = s.sigma_rad < crate::analysis::verdict::PRACTICAL_RATIO * prior;
    if expected_observable(id, s.name, group) {
        if s.ratio() > 4.0 {
            Verdict::Failed
        } else if practical {
            Verdict::Converged
        } else {
            Verdict::NotObservable
        }
    } else if practical {
        Verdict::Observable
    } else {
        Verdict::NotObservable
    }
}

/// Whether a state is expected to converge in configuration `id` (docs/model.md
/// §Configurations), used for summaries.
pub fn expected_observable(id: ConfigId, name: &str, group: Group) -> bool {
    use ConfigId::*;
    match group {
        Group::ThetaGT | Group::ThetaAT => true,
        Group::ThetaGC | Group::ThetaAC => matches!(id, M1Pa | M2Ps | M3Pa | M4Pa),
        Group::Lambda => id == M2Ps && (name == "lam_x" || name == "lam_z"),
        Group::Attitude => false,
    }
}
