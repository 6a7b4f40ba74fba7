//! [`SimulatedRun`]: one simulated run of one configuration, and the facts
//! every step of `run`, `record --truth`, `observability`, `montecarlo` and
//! `paper` derives from it — the filter settings, the prior, the true
//! states, the log records — in one place instead of re-derived at each
//! step.

use rollcal::ekf::{self, FilterConfig, Options};
use rollcal::estimator::{LogRecord, LogStart};
use rollcal::models::{ConfigId, ErrorModel, Layout};

use super::bound::{bound, bound_history};
use super::config::{filter_config, log_record, prior_sigma, with_wander};
use super::passes::{result, run_passes, Estimator};
use super::results::RunResult;
use crate::sim::instruments::instrument_truth_state;
use crate::sim::scenario::{Scenario, DEG};
use crate::sim::truth::{truth_state, Instant, Simulation};
use crate::sim::wander::WanderTruth;

/// One simulated run (`sim` of `scenario`, Earth rate `earth_rate`) seen
/// by configuration `config`.
///
/// # Examples
///
/// ```
/// use host_sim::analysis::runner::SimulatedRun;
/// use host_sim::sim::scenario::Scenario;
/// use host_sim::sim::truth::{simulate, SimOptions};
/// use rollcal::models::{ConfigId, ErrorModel, Layout};
///
/// let mut scenario = Scenario::paper();
/// scenario.timing.duration_s = 60.0;
/// scenario.path.truncate(1);
/// scenario.path[0].angle_deg = 6.0;
/// let sim = simulate(&scenario, SimOptions { seed: 1, noise: true, earth_rate: true });
/// let run = SimulatedRun::new(ConfigId::M1Pa, &scenario, &sim, true);
/// assert_eq!(run.truth_at_start().len(), ConfigId::M1Pa.layout().n());
/// let crlb = run.crlb().unwrap();
/// assert!(crlb.iter().all(|s| s.is_finite() && *s > 0.0));
/// ```
#[derive(Clone, Copy, Debug)]
pub struct SimulatedRun<'a> {
    /// The configuration.
    pub config: ConfigId,
    /// The scenario simulated.
    pub scenario: &'a Scenario,
    /// The simulated run.
    pub sim: &'a Simulation,
    /// Whether the Earth rate is on (and-ed with the scenario's).
    pub earth_rate: bool,
    /// The error model of the estimator (default: installation only).
    pub errors: ErrorModel,
}

impl<'a> SimulatedRun<'a> {
    /// The run `sim` of `scenario` seen by configuration `config`.
    pub fn new(
        config: ConfigId,
        scenario: &'a Scenario,
        sim: &'a Simulation,
        earth_rate: bool,
    ) -> Self {
        Self {
            config,
            scenario,
            sim,
            earth_rate,
            errors: ErrorModel::Installation,
        }
    }

    /// The same run seen by the model with error model `errors`.
    pub fn with_errors(self, errors: ErrorModel) -> Self {
        Self { errors, ..self }
    }

    /// The layout of the estimator's model.
    pub fn layout(&self) -> Layout {
        self.config.layout_with(self.errors)
    }

    /// The prior σ of the installation states (rad).
    pub fn sigma0(&self) -> f64 {
        self.scenario.prior.sigma_deg * DEG
    }

    /// The prior σ of every state of the model (internal units): the
    /// scenario's `[prior]` on the installation states, its
    /// `[instruments.prior]` on the instrument states of the full model.
    pub fn prior_sigma(&self) -> Vec<f64> {
        prior_sigma(
            self.layout(),
            self.sigma0(),
            &self.scenario.instruments.prior.to_wire(),
            &self.scenario.instruments.wander.to_model(),
        )
    }

    /// The true state at instant `at` (internal units), in the model's
    /// order: the installation states, then the instrument errors with the
    /// wandering parts `w` of that instant (the persistent drift and bias,
    /// the Gauss–Markov parts).
    fn truth_at(&self, at: &Instant, w: &WanderTruth) -> Vec<f64> {
        let mut x = truth_state(self.config, &self.sim.params, at);
        if self.errors == ErrorModel::Full {
            x.extend(instrument_truth_state(self.config, &self.sim.params, w));
        }
        x
    }

    /// The filter settings of the scenario with filter options `options`
    /// (the bound's: [`Options::plain`]).
    pub fn filter_config(&self, options: Options) -> FilterConfig<f64> {
        with_wander(
            filter_config(self.scenario, self.earth_rate, options),
            self.errors,
            &self.scenario.instruments.wander,
        )
    }

    /// The true state at the start of the run (internal units).
    pub fn truth_at_start(&self) -> Vec<f64> {
        self.truth_at(&self.sim.initial, &self.sim.initial_wander)
    }

    /// The true state at the end of the run (internal units): the
    /// wandering terms' calibrated values (their persistent parts then).
    pub fn truth_at_end(&self) -> Vec<f64> {
        match self.sim.samples.last() {
            Some(s) => self.truth_at(&s.truth, &s.wander),
            None => self.truth_at(&self.sim.initial, &self.sim.initial_wander),
        }
    }

    /// The true state at the end of every period (rad).
    pub fn truth_history(&self) -> Vec<Vec<f64>> {
        self.sim
            .samples
            .iter()
            .map(|s| self.truth_at(&s.truth, &s.wander))
            .collect()
    }

    /// The periods as the library's estimator replays them.
    pub fn records(&self) -> Vec<LogRecord<f64>> {
        self.sim.samples.iter().map(log_record).collect()
    }

    /// The estimator `estimator` over the run from `x0` (`None`: the cold
    /// start, zeros), keeping the last pass's time history if asked.
    pub fn run(
        &self,
        estimator: Estimator,
        x0: Option<&[f64]>,
        keep_history: bool,
    ) -> Result<RunResult, ekf::Error> {
        let id = self.config;
        let cfg = self.filter_config(estimator.options);
        let zeros = vec![0.0; self.layout().n()];
        let x0 = x0.unwrap_or(&zeros);
        let sigma0 = self.prior_sigma();
        let p = run_passes(
            id,
            self.errors,
            cfg,
            &sigma0,
            &self.sim.samples,
            estimator,
            x0,
            keep_history,
        )?;
        let truth = self.truth_at_end();
        Ok(result(id, self.errors, &p, &truth, &sigma0))
    }

    /// The posterior Cramér–Rao σ (rad) of every state at the end of the
    /// run ([`bound`] over all its periods from the true initial state).
    pub fn crlb(&self) -> Result<Vec<f64>, ekf::Error> {
        let cfg = self.filter_config(Options::plain());
        let truth0 = self.truth_at_start();
        let records = self.records();
        let sigma0 = self.prior_sigma();
        bound(
            self.config,
            self.errors,
            cfg,
            &truth0,
            &LogStart::aligned(),
            &sigma0,
            &records,
        )
    }

    /// [`Self::crlb`] after every period (for the σ(t) figures).
    pub fn crlb_history(&self) -> Result<Vec<Vec<f64>>, ekf::Error> {
        let cfg = self.filter_config(Options::plain());
        let truth0 = self.truth_at_start();
        let records = self.records();
        let sigma0 = self.prior_sigma();
        bound_history(
            self.config,
            self.errors,
            cfg,
            &truth0,
            &LogStart::aligned(),
            &sigma0,
            &records,
        )
    }
}
