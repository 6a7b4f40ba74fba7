//! Monte Carlo runs of one configuration: seeded noise, the estimator of
//! record, and the statistics that compare it with the Cramér–Rao bound
//! (docs/model.md §Estimator: RMS error against σ_CRLB, parameter-block NEES and NIS inside
//! their χ² bands).

use rayon::prelude::*;
use rollcal::ekf;
use rollcal::models::{ConfigId, ErrorModel, Group, StateInfo};

use crate::analysis::observe;
use crate::analysis::runner::{Estimator, RunResult, SimulatedRun};
use crate::analysis::Error;
use crate::sim::scenario::Scenario;
use crate::sim::truth::{simulate, SimOptions};

/// Statistics of one state over the runs.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StateStats {
    /// State name.
    pub name: &'static str,
    /// The unit of the `*_rad` values of an instrument state of the full
    /// model (`rad/s`, `rad/s/g`, `1`, `g`); absent for the angles (rad).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<&'static str>,
    /// Name, group and printed unit of the state; not in the JSON.
    #[serde(skip)]
    pub info: StateInfo,
    /// Root-mean-square final error (rad).
    pub rms_error_rad: f64,
    /// Mean error (rad): a bias shows here.
    pub mean_error_rad: f64,
    /// Mean final filter σ (rad).
    pub mean_sigma_rad: f64,
    /// Posterior Cramér–Rao σ (rad).
    pub sigma_crlb_rad: f64,
    /// RMS error / σ_CRLB.
    pub rms_over_crlb: f64,
    /// Whether the state belongs to the parameter block (installation
    /// errors and λ that the configuration observes).
    pub in_parameter_block: bool,
}

/// A χ² consistency statistic averaged over runs, with its two-sided 95 %
/// band.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Consistency {
    /// Average of the statistic.
    pub mean: f64,
    /// Degrees of freedom of one sample.
    pub dof: usize,
    /// Number of samples averaged.
    pub samples: usize,
    /// Lower end of the 95 % band of the average.
    pub lower: f64,
    /// Upper end of the 95 % band of the average.
    pub upper: f64,
}

impl Consistency {
    /// Whether the average lies in its band.
    pub fn inside(&self) -> bool {
        self.mean >= self.lower && self.mean <= self.upper
    }
}

/// The outcome of a Monte Carlo study.
#[derive(Clone, Debug, serde::Serialize)]
pub struct MonteCarlo {
    /// Configuration.
    #[serde(serialize_with = "observe::ser_config")]
    pub config: ConfigId,
    /// Error model (written only for the full model).
    #[serde(
        skip_serializing_if = "observe::is_installation",
        serialize_with = "observe::ser_errors"
    )]
    pub errors: ErrorModel,
    /// Precision of the filter's covariance arithmetic.
    pub precision: crate::analysis::runner::Precision,
    /// Runs that completed.
    pub runs: usize,
    /// Seeds used (1..=runs).
    pub seeds: Vec<u64>,
    /// Per state.
    pub states: Vec<StateStats>,
    /// Parameter-block NEES, averaged over the runs.
    pub nees: Consistency,
    /// NIS of the final pass, averaged over runs and updates.
    pub nis: Consistency,
    /// Worst |error|/σ_filter over the parameter block and the runs.
    pub max_normalised_error: f64,
    /// Where it occurred: (seed, state name, passes of that run).
    pub worst: (u64, &'static str, u8),
    /// Wall time (s).
    pub wall_s: f64,
}

/// Of the full model's parameter block: a state whose bound is below this
/// fraction of its prior σ, so that the data and not the prior make its
/// estimate (at 0.1 the prior's pull on the estimate is 1 % of the truth).
pub const FULL_BLOCK_RATIO: f64 = 0.1;

// The χ² and normal quantiles: one implementation, in `statistics`.
pub use crate::analysis::statistics::{chi2_quantile, normal_quantile};

/// The 95 % band of the average of `samples` independent χ²(`dof`) values.
pub fn band(mean: f64, dof: usize, samples: usize) -> Consistency {
    let k = (dof * samples) as f64;
    let n = samples.max(1) as f64;
    Consistency {
        mean,
        dof,
        samples,
        lower: chi2_quantile(0.025, k) / n,
        upper: chi2_quantile(0.975, k) / n,
    }
}

/// Whether state `name` of group `group` is in the parameter block of `id`:
/// the installation errors and base angles the configuration observes
/// (docs/model.md §Configurations).
pub fn in_parameter_block(id: ConfigId, name: &str, group: Group) -> bool {
    group != Group::Attitude && crate::analysis::runner::expected_observable(id, name, group)
}

/// Runs `runs` seeded Monte Carlo runs (seeds 1..=runs) of configuration
/// `id` under error model `errors` in parallel; `progress` is called after
/// each run with the number done. The parameter block is
/// [`in_parameter_block`] for the installation model; for the full model,
/// the non-attitude states whose bound is below [`FULL_BLOCK_RATIO`] of
/// their prior.
pub fn monte_carlo(
    id: ConfigId,
    errors: ErrorModel,
    scenario: &Scenario,
    runs: usize,
    estimator: Estimator,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<MonteCarlo, Error> {
    let t0 = std::time::Instant::now();
    let earth_rate = scenario.site.earth_rate;
    // The bound does not depend on the noise: one noise-free trajectory.
    let clean = simulate(
        scenario,
        SimOptions {
            seed: 0,
            noise: false,
            earth_rate,
        },
    );
    crate::sim::truth::check_gimbal_lock(id, &clean)?;
    let clean_run = SimulatedRun::new(id, scenario, &clean, earth_rate).with_errors(errors);
    let (crlb, block) = bound_and_block(&clean_run)?;
    let done = std::sync::atomic::AtomicUsize::new(0);
    let seeds: Vec<u64> = (1..=runs as u64).collect();
    let results: Vec<Result<RunResult, (u64, ekf::Error)>> = seeds
        .par_iter()
        .map(|&seed| {
            let sim = simulate(
                scenario,
                SimOptions {
                    seed,
                    noise: true,
                    earth_rate,
                },
            );
            let r = SimulatedRun::new(id, scenario, &sim, earth_rate)
                .with_errors(errors)
                .run(estimator, None, false)
                .map_err(|e| (seed, e));
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n);
            r
        })
        .collect();
    let mut ok = Vec::new();
    for r in results {
        match r {
            Ok(r) => ok.push(r),
            Err((seed, e)) => return Err(Error::filter(format_args!("{id}: seed {seed}"), e)),
        }
    }
    let n_runs = ok.len().max(1) as f64;
    let states = state_stats(id, errors, &ok, &crlb, &block);
    let (nees_sum, max_ratio, worst) = nees_and_worst(id, &ok, &seeds, &block)?;
    let nees = band(nees_sum / n_runs, block.len(), ok.len());
    let z = id.layout().z();
    let nis_count: usize = ok.iter().map(|r| r.nis.len()).sum();
    let nis_mean = ok.iter().flat_map(|r| r.nis.iter()).sum::<f64>() / nis_count.max(1) as f64;
    let nis = band(nis_mean, z, nis_count);
    Ok(MonteCarlo {
        config: id,
        errors,
        precision: estimator.precision,
        runs: ok.len(),
        seeds,
        states,
        nees,
        nis,
        max_normalised_error: max_ratio,
        worst,
        wall_s: t0.elapsed().as_secs_f64(),
    })
}

/// The bound σ of every state on the noise-free run `run` (its
/// observability analysis, [`observe::analyse_run`]) and the indices of the
/// parameter block ([`monte_carlo`]).
fn bound_and_block(run: &SimulatedRun) -> Result<(Vec<f64>, Vec<usize>), Error> {
    let id = run.config;
    let obs = observe::analyse_run(*run, false)
        .map_err(|e| Error::filter(format_args!("{id}: observability"), e))?;
    let block = obs
        .states
        .iter()
        .enumerate()
        .filter(|(_, s)| match run.errors {
            ErrorModel::Installation => in_parameter_block(id, s.name, s.group),
            _ => !s.group.is_nuisance() && s.ratio < FULL_BLOCK_RATIO,
        })
        .map(|(i, _)| i)
        .collect();
    let crlb = obs.states.iter().map(|s| s.sigma_crlb_rad).collect();
    Ok((crlb, block))
}

/// The statistics of every state over the runs `ok`, against the bound of
/// the analysis `obs`.
fn state_stats(
    id: ConfigId,
    errors: ErrorModel,
    ok: &[RunResult],
    crlb: &[f64],
    block: &[usize],
) -> Vec<StateStats> {
    let n_runs = ok.len().max(1) as f64;
    id.states_with(errors)
        .iter()
        .enumerate()
        .map(|(i, info)| {
            let errs: Vec<f64> = ok.iter().map(|r| r.states[i].error()).collect();
            let rms = (errs.iter().map(|e| e * e).sum::<f64>() / n_runs).sqrt();
            let mean = errs.iter().sum::<f64>() / n_runs;
            let sig = ok.iter().map(|r| r.states[i].sigma_rad).sum::<f64>() / n_runs;
            let crlb = crlb.get(i).copied().unwrap_or(f64::NAN);
            StateStats {
                name: info.name,
                unit: info.group.is_instrument().then_some(info.unit),
                info: *info,
                rms_error_rad: rms,
                mean_error_rad: mean,
                mean_sigma_rad: sig,
                sigma_crlb_rad: crlb,
                rms_over_crlb: rms / crlb,
                in_parameter_block: block.contains(&i),
            }
        })
        .collect()
}

/// The sum over the runs of the parameter block's NEES `e_pᵀ P_pp⁻¹ e_p`,
/// and the worst |error|/σ of the block with where it occurred (seed,
/// state, passes).
#[allow(clippy::type_complexity)]
fn nees_and_worst(
    id: ConfigId,
    ok: &[RunResult],
    seeds: &[u64],
    block: &[usize],
) -> Result<(f64, f64, (u64, &'static str, u8)), Error> {
    let n = ok.first().map_or(0, |r| r.states.len());
    let mut nees_sum = 0.0;
    let mut max_ratio: f64 = 0.0;
    let mut worst = (0, "", 0);
    for (r, &seed) in ok.iter().zip(seeds) {
        let e = nalgebra::DVector::from_iterator(
            block.len(),
            block.iter().map(|&i| r.states[i].error()),
        );
        let p = nalgebra::DMatrix::from_fn(block.len(), block.len(), |a, b| {
            r.covariance[block[a] * n + block[b]]
        });
        let chol = p
            .cholesky()
            .ok_or(Error::NotPositiveDefinite { config: id })?;
        nees_sum += e.dot(&chol.solve(&e));
        for &i in block {
            if r.states[i].ratio() > max_ratio {
                max_ratio = r.states[i].ratio();
                worst = (seed, r.states[i].name, r.passes);
            }
        }
    }
    Ok((nees_sum, max_ratio, worst))
}
