//! The cold-start remedies and their study (`host-sim remedies`): every
//! remedy on M1-pa, M4-pa and M2-ps over seeds and scenarios, scored by the
//! worst |error|/σ over the claimed parameters of each run.

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::Mutex;

use rollcal::ekf::Options;
use rollcal::models::ConfigId;

use crate::analysis::runner::{expected_observable, run_filter, Estimator, Precision};
use crate::analysis::Error;
use crate::output::report::group_of;
use crate::sim::scenario::Scenario;
use crate::sim::truth::{simulate, SimOptions};

/// Cold-start remedies (see the `ekf` module docs and docs/estimator.md,
/// "The cold start").
#[derive(Clone, Copy, Debug, clap::ValueEnum, PartialEq, Eq)]
pub enum Remedy {
    /// Second-order terms in the innovation covariance (the default).
    SecondOrder,
    /// Second-order covariance and second-order mean (Gaussian second-order filter).
    SecondOrderMean,
    /// Plain EKF (inconsistent from a zero start; for comparison).
    Plain,
    /// Iterated EKF: 5 iterations on the first 20 updates.
    Iekf,
    /// Iterated EKF on the first 20 updates plus second-order covariance.
    IekfSecondOrder,
    /// Second-order covariance terms of both the measurement and the dynamics.
    SecondOrderDynamics,
}

impl Remedy {
    /// The filter options of the remedy.
    pub fn options(self) -> Options {
        // Every remedy runs with the default NIS gate, as the default estimator.
        let plain = Options {
            nis_gate: rollcal::ekf::DEFAULT_NIS_GATE,
            ..Options::plain()
        };
        match self {
            Remedy::SecondOrder => Options::default(),
            Remedy::SecondOrderMean => Options {
                second_order_mean: true,
                ..Options::default()
            },
            Remedy::Plain => plain,
            Remedy::SecondOrderDynamics => Options {
                second_order_dynamics: true,
                ..Options::default()
            },
            Remedy::Iekf => Options {
                iterations: 5,
                iterate_updates: 20,
                ..plain
            },
            Remedy::IekfSecondOrder => Options {
                iterations: 5,
                iterate_updates: 20,
                ..Options::default()
            },
        }
    }
}

/// The configurations of the study.
pub const CONFIGS: [ConfigId; 3] = [ConfigId::M1Pa, ConfigId::M4Pa, ConfigId::M2Ps];

/// A run fails above this |error|/σ.
pub const FAIL_RATIO: f64 = 4.0;

/// The estimators compared, with their names in the table.
pub fn estimators() -> Vec<(&'static str, Estimator)> {
    let one = |remedy: Remedy, passes: u8| Estimator {
        options: remedy.options(),
        passes,
        precision: Precision::F64,
    };
    vec![
        ("plain EKF", one(Remedy::Plain, 1)),
        ("IEKF (first 20 updates)", one(Remedy::Iekf, 1)),
        ("2nd-order S", one(Remedy::SecondOrder, 1)),
        ("2nd-order S + mean", one(Remedy::SecondOrderMean, 1)),
        (
            "2nd-order S + dynamics",
            one(Remedy::SecondOrderDynamics, 1),
        ),
        ("IEKF + 2nd-order S", one(Remedy::IekfSecondOrder, 1)),
        (
            "2nd-order S, then linearised passes",
            one(Remedy::SecondOrder, 4),
        ),
    ]
}

/// One run of the study.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// Index of the scenario.
    pub scenario: usize,
    /// Seed of the noise.
    pub seed: u64,
    /// Index of the estimator in [`estimators`].
    pub remedy: usize,
    /// Configuration.
    pub config: ConfigId,
    /// Worst |error|/σ over the claimed parameters (∞ when the run failed).
    pub worst: f64,
}

/// Every estimator of `remedies` on every configuration of [`CONFIGS`],
/// seeds `1..=seeds` of every scenario: one job per (scenario, seed) on
/// every available core (simulate once, run every remedy and
/// configuration); `progress(n)` after each job with the number done.
pub fn study(
    scenarios: &[Scenario],
    seeds: u64,
    remedies: &[(&'static str, Estimator)],
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Vec<Outcome>, Error> {
    let jobs: Vec<(usize, u64)> = (0..scenarios.len())
        .flat_map(|i| (1..=seeds).map(move |s| (i, s)))
        .collect();
    let next = AtomicUsize::new(0);
    let results = Mutex::new(Vec::new());
    let done = AtomicU64::new(0);
    std::thread::scope(|scope| {
        for _ in 0..std::thread::available_parallelism().map_or(2, |n| n.get()) {
            scope.spawn(|| loop {
                let j = next.fetch_add(1, Ordering::Relaxed);
                let Some(&(si, seed)) = jobs.get(j) else {
                    break;
                };
                let sc = &scenarios[si];
                let sim = simulate(
                    sc,
                    SimOptions {
                        seed,
                        noise: true,
                        earth_rate: sc.site.earth_rate,
                    },
                );
                for (ri, (_, est)) in remedies.iter().enumerate() {
                    for id in CONFIGS {
                        let worst =
                            match run_filter(id, sc, &sim, sc.site.earth_rate, *est, None, false) {
                                Ok(r) => r
                                    .states
                                    .iter()
                                    .filter(|s| expected_observable(id, s.name, group_of(s.group)))
                                    .map(|s| s.ratio())
                                    .fold(0.0, f64::max),
                                Err(_) => f64::INFINITY,
                            };
                        results
                            .lock()
                            .map(|mut v| {
                                v.push(Outcome {
                                    scenario: si,
                                    seed,
                                    remedy: ri,
                                    config: id,
                                    worst,
                                })
                            })
                            .ok();
                    }
                }
                let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                progress(n);
            });
        }
    });
    results
        .into_inner()
        .map_err(|e| Error::Poisoned(e.to_string()))
}

/// The tally of one estimator on one configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tally {
    /// Runs.
    pub runs: usize,
    /// Runs above [`FAIL_RATIO`].
    pub failures: usize,
    /// The worst ratio of all runs.
    pub max_ratio: f64,
}

/// The tally of estimator `remedy` on configuration `id` over `outcomes`.
pub fn tally(outcomes: &[Outcome], remedy: usize, id: ConfigId) -> Tally {
    let v: Vec<f64> = outcomes
        .iter()
        .filter(|r| r.remedy == remedy && r.config == id)
        .map(|r| r.worst)
        .collect();
    Tally {
        runs: v.len(),
        failures: v.iter().filter(|w| **w > FAIL_RATIO).count(),
        max_ratio: v.iter().copied().fold(0.0, f64::max),
    }
}
