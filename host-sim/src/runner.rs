//! Runs a configuration's estimator over a simulated (or replayed) run.

use nalgebra::SVector;
use rollcal::command::CommandFrame;
use rollcal::ekf::{self, Filter, FilterConfig, Observation, Options};
use rollcal::geometry::{wrap_angle, EARTH_RATE};
use rollcal::models::{ConfigId, Environment, Group, Model};

use crate::scenario::{Scenario, ARCSEC, DEG};
use crate::truth::{truth_state, PeriodSample, Simulation};

/// Object-safe view of a filter of any configuration (f64).
pub trait DynFilter: Send {
    /// One period.
    fn step(&mut self, s: &PeriodSample) -> Result<f64, ekf::Error>;
    /// Estimate (rad).
    fn state(&self) -> Vec<f64>;
    /// σ (rad).
    fn sigma(&self) -> Vec<f64>;
    /// Covariance, row-major (rad²).
    fn covariance(&self) -> Vec<f64>;
    /// Switch to the linearised filter about the nominal starting at `x`.
    fn set_nominal(&mut self, x: &[f64]);
    /// The model state propagated backwards over the periods of `samples`
    /// from the current estimate, to the start of the first one.
    fn back_propagate(&self, samples: &[PeriodSample]) -> Option<Vec<f64>>;
}

impl<M: Model<N, Z> + Send, const N: usize, const Z: usize> DynFilter for Filter<f64, M, N, Z> {
    fn step(&mut self, s: &PeriodSample) -> Result<f64, ekf::Error> {
        let obs = Observation {
            accel_mean: s.accel_mean,
            gimbal: Some(s.gimbal),
        };
        Filter::step(self, &s.dtheta_cmd, s.dt, &obs).map(|i| i.nis)
    }
    fn state(&self) -> Vec<f64> {
        Filter::state(self).iter().copied().collect()
    }
    fn sigma(&self) -> Vec<f64> {
        Filter::sigma(self).iter().copied().collect()
    }
    fn covariance(&self) -> Vec<f64> {
        Filter::covariance(self)
            .transpose()
            .iter()
            .copied()
            .collect()
    }
    fn set_nominal(&mut self, x: &[f64]) {
        Filter::set_nominal(self, Some(SVector::from_iterator(x.iter().copied())));
    }
    fn back_propagate(&self, samples: &[PeriodSample]) -> Option<Vec<f64>> {
        let layout = self.layout();
        let env = self.config().env;
        let mut frame = CommandFrame::aligned(env.earth_rate_n);
        let periods: Vec<_> = samples
            .iter()
            .map(|s| {
                let p = frame.period(&s.dtheta_cmd, s.dt);
                frame.advance(&p);
                p
            })
            .collect();
        let mut x = *Filter::state(self);
        for p in periods.iter().rev() {
            x = layout.propagate_state(&env, &x, &p.reversed())?;
        }
        Some(x.iter().copied().collect())
    }
}

/// Filter settings derived from a scenario.
pub fn filter_config(s: &Scenario, earth_rate: bool, options: Options) -> FilterConfig<f64> {
    let omega = if s.site.earth_rate && earth_rate {
        EARTH_RATE
    } else {
        0.0
    };
    let lat = s.site.latitude_deg * DEG;
    FilterConfig {
        env: Environment {
            earth_rate_n: rollcal::geometry::earth_rate_n(omega, lat),
            gravity_n: rollcal::geometry::gravity_n(),
        },
        sigma_accel: s.noise.accel_g,
        sigma_gyro: s.noise.gyro_deg_h * DEG / 3600.0,
        sigma_gimbal: s.noise.gimbal_arcsec * ARCSEC,
        options,
    }
}

fn make<M: Model<N, Z> + Send + 'static, const N: usize, const Z: usize>(
    cfg: FilterConfig<f64>,
    x0: &[f64],
    sigma0: f64,
) -> Result<Box<dyn DynFilter>, ekf::Error> {
    let x = SVector::<f64, N>::from_iterator(x0.iter().copied().chain(std::iter::repeat(0.0)));
    let s = SVector::<f64, N>::repeat(sigma0);
    Ok(Box::new(Filter::<f64, M, N, Z>::new(cfg, x, s)?))
}

/// A filter of configuration `id` with initial estimate `x0` (rad; zeros
/// for a cold start) and prior σ `sigma0` (rad) on every state.
pub fn new_filter(
    id: ConfigId,
    cfg: FilterConfig<f64>,
    x0: &[f64],
    sigma0: f64,
) -> Result<Box<dyn DynFilter>, ekf::Error> {
    use rollcal::models::*;
    match id {
        ConfigId::M1Pa => make::<M1Pa, 12, 3>(cfg, x0, sigma0),
        ConfigId::M1Ps => make::<M1Ps, 15, 3>(cfg, x0, sigma0),
        ConfigId::M2Ps => make::<M2Ps, 18, 6>(cfg, x0, sigma0),
        ConfigId::M3Pa => make::<M3Pa, 15, 3>(cfg, x0, sigma0),
        ConfigId::M3Ps => make::<M3Ps, 18, 3>(cfg, x0, sigma0),
        ConfigId::M4Pa => make::<M4Pa, 12, 3>(cfg, x0, sigma0),
        ConfigId::M4Ps => make::<M4Ps, 15, 3>(cfg, x0, sigma0),
    }
}

/// One state at the end of a run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StateResult {
    /// SPEC name, e.g. `thgC_x`.
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
    /// than [`PASS_TOLERANCE`] of its σ.
    pub passes: u8,
}

/// Passes stop when no final state moves by more than this fraction of its σ.
pub const PASS_TOLERANCE: f64 = 0.1;

impl Default for Estimator {
    fn default() -> Self {
        Self {
            options: Options::default(),
            passes: 4,
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
    /// Failed updates of the last pass.
    pub failures: Vec<(u32, ekf::Error)>,
    /// Passes run.
    pub passes: u8,
}

/// The multi-pass estimator of configuration `id` over `samples` (only
/// their increments, periods, accelerometer means and gimbal angles are
/// used; `truth.t` labels the history), from `x0` with prior σ `sigma0`.
pub fn run_passes(
    id: ConfigId,
    cfg: FilterConfig<f64>,
    sigma0: f64,
    samples: &[PeriodSample],
    estimator: Estimator,
    x0: &[f64],
    keep_history: bool,
) -> Result<Passes, ekf::Error> {
    let mut nominal: Option<Vec<f64>> = None;
    let mut out = None;
    let mut previous: Option<Vec<f64>> = None;
    for pass in 1..=estimator.passes.max(1) {
        let mut f = new_filter(id, cfg, x0, sigma0)?;
        if let Some(xn) = &nominal {
            f.set_nominal(xn);
        }
        let mut history = Vec::new();
        let mut nis = Vec::with_capacity(samples.len());
        let mut failures = Vec::new();
        for s in samples {
            match f.step(s) {
                Ok(v) => nis.push(v),
                Err(e) => failures.push((s.k, e)),
            }
            if keep_history {
                history.push((s.truth.t, f.state(), f.sigma()));
            }
        }
        nominal = f.back_propagate(samples);
        if nominal.is_none() {
            return Err(ekf::Error::GimbalLock);
        }
        let (x, sig) = (f.state(), f.sigma());
        let converged = previous.as_ref().is_some_and(|prev| {
            x.iter()
                .zip(prev)
                .zip(&sig)
                .all(|((a, b), s)| wrap_angle(a - b).abs() < PASS_TOLERANCE * s)
        });
        previous = Some(x);
        out = Some(Passes {
            filter: f,
            history,
            nis,
            failures,
            passes: pass,
        });
        if converged {
            break;
        }
    }
    out.ok_or(ekf::Error::NoPrediction)
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
        prior_sigma_rad: sigma0,
        passes: p.passes,
        failures: p.failures.clone(),
    }
}

/// Posterior Cramér–Rao bound σ (rad) of every state at the end of `sim`:
/// the covariance of the filter linearised along the true trajectory (its
/// nominal starts at the true initial state), with the same prior and
/// process noise (SPEC §5.3).
pub fn crlb_sigma(
    id: ConfigId,
    scenario: &Scenario,
    sim: &Simulation,
    earth_rate: bool,
) -> Result<Vec<f64>, ekf::Error> {
    let cfg = filter_config(scenario, earth_rate, Options::plain());
    let truth0 = truth_state(id, &sim.params, &sim.initial);
    let mut f = new_filter(id, cfg, &truth0, scenario.prior.sigma_deg * DEG)?;
    f.set_nominal(&truth0);
    for s in &sim.samples {
        f.step(s)?;
    }
    Ok(f.sigma())
}

/// What the run says of one state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Claimed observable (SPEC §3) and within 4σ of the truth.
    Converged,
    /// Claimed observable but more than 4σ from the truth.
    Failed,
    /// Not claimed; σ below 1 % of the prior (observable in practice, SPEC §5).
    Observable,
    /// Not claimed; σ at or above 1 % of the prior.
    NotObservable,
}

impl Verdict {
    /// Stable text used in tables and JSON.
    pub const fn as_str(self) -> &'static str {
        match self {
            Verdict::Converged => "converged",
            Verdict::Failed => "FAILED (> 4 sigma)",
            Verdict::Observable => "observable",
            Verdict::NotObservable => "not observable",
        }
    }
}

/// The verdict on state `s` of configuration `id` with prior σ `prior` (rad).
pub fn verdict(id: ConfigId, s: &StateResult, group: Group, prior: f64) -> Verdict {
    if expected_observable(id, s.name, group) {
        if s.ratio() <= 4.0 {
            Verdict::Converged
        } else {
            Verdict::Failed
        }
    } else if s.sigma_rad < 0.01 * prior {
        Verdict::Observable
    } else {
        Verdict::NotObservable
    }
}

/// Whether a state is expected to converge in configuration `id` (SPEC §3,
/// refined verdicts), used for summaries.
pub fn expected_observable(id: ConfigId, name: &str, group: Group) -> bool {
    use ConfigId::*;
    match group {
        Group::ThetaGT | Group::ThetaAT => true,
        Group::ThetaGC | Group::ThetaAC => matches!(id, M1Pa | M2Ps | M3Pa | M4Pa),
        Group::Lambda => id == M2Ps && (name == "lam_x" || name == "lam_z"),
        Group::Attitude => false,
    }
}
