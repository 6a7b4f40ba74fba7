//! The speed of the bound against the estimator: one bound evaluation of a
//! designed path timed against one estimator run on it
//! (`host-sim design --measure-speed`).

use rayon::prelude::*;

use crate::sim::scenario::Scenario;

use super::{DesignError, Goal, Pattern, Problem};

/// Timings of [`measure_speed`].
#[derive(Clone, Copy, Debug)]
pub struct Speed {
    /// One coarse bound evaluation (s, mean of 20).
    pub bound_eval_s: f64,
    /// One period-by-period bound evaluation (s, mean of 5).
    pub bound_eval_fine_s: f64,
    /// Periods per coarse step.
    pub step_periods: u64,
    /// One estimator run (s, mean of 3; simulation excluded).
    pub estimator_run_s: f64,
    /// Passes of the estimator run.
    pub estimator_passes: u8,
    /// The simulation of the run's data (s).
    pub simulation_s: f64,
    /// Full (unpruned) evaluations per minute on every thread.
    pub full_evaluations_per_minute: f64,
    /// Threads.
    pub threads: usize,
}

/// Times one coarse bound evaluation of the designed path (mean of 20)
/// against one run of the estimator of record on it (mean of 3; simulation
/// excluded), and the full evaluations per minute on every thread.
pub fn measure_speed(
    problem: &Problem,
    best: &Pattern,
    periods: u64,
    designed: &Scenario,
) -> Result<Speed, DesignError> {
    let goal = Goal::Budget { periods };
    let reps = 20;
    let t0 = std::time::Instant::now();
    let mut k = 0;
    for _ in 0..reps {
        k = problem.evaluate(best, goal, false, false).k;
    }
    let bound_s = t0.elapsed().as_secs_f64() / f64::from(reps);
    let t0 = std::time::Instant::now();
    for _ in 0..5 {
        problem.evaluate(best, goal, true, false);
    }
    let fine_s = t0.elapsed().as_secs_f64() / 5.0;
    let t0 = std::time::Instant::now();
    let sim = crate::sim::truth::simulate(
        designed,
        crate::sim::truth::SimOptions {
            seed: 1,
            noise: true,
            earth_rate: designed.site.earth_rate,
        },
    );
    let sim_s = t0.elapsed().as_secs_f64();
    // The mean of 3 runs: one run alone scatters by ± 30 % on a shared
    // machine.
    let est_reps = 3;
    let t0 = std::time::Instant::now();
    let mut passes = 0;
    for _ in 0..est_reps {
        // The estimator of the problem's error model.
        passes = crate::analysis::runner::SimulatedRun::new(
            problem.config,
            designed,
            &sim,
            designed.site.earth_rate,
        )
        .with_errors(problem.errors)
        .run(crate::analysis::runner::Estimator::default(), None, false)
        .map_err(|e| DesignError::Estimator(e.to_string()))?
        .passes;
    }
    let est_s = t0.elapsed().as_secs_f64() / f64::from(est_reps);
    // Full (unpruned) evaluations per minute on every thread.
    let n = 4 * rayon::current_num_threads();
    let t0 = std::time::Instant::now();
    (0..n).into_par_iter().for_each(|_| {
        problem.evaluate(best, goal, false, false);
    });
    let par_s = t0.elapsed().as_secs_f64();
    let per_min = n as f64 / par_s * 60.0;
    Ok(Speed {
        bound_eval_s: bound_s,
        bound_eval_fine_s: fine_s,
        step_periods: k,
        estimator_run_s: est_s,
        estimator_passes: passes,
        simulation_s: sim_s,
        full_evaluations_per_minute: per_min,
        threads: rayon::current_num_threads(),
    })
}
