//! Designing the rolling path (issue 12): the shortest sequence of
//! constant-rate rotations whose posterior Cramér–Rao bound reaches a target
//! σ on every parameter, or the best worst-case σ/target within a time
//! budget.
//!
//! **The bound.** Every candidate is scored by the one computation of the
//! bound, [`rollcal::observability::Observability`], fed the commanded
//! increments of the candidate path. The increments come from the library's
//! own [`CommandFrame`](rollcal::command::CommandFrame) (`Δθc = uT + T J_r(uT) C^c_n ω^n_ie` at the constant
//! path rate `u`), not from the truth simulator: the bound depends on the
//! commanded motion only, and the truth simulator's RK4 integral of the same
//! motion agrees to rounding (tested). The designed path is finally checked
//! by [`crate::analysis::observe::analyse`] on the simulated run, exactly as
//! `host-sim observability --scenario` computes it.
//!
//! **Coarse steps.** During the search, `k` filter periods are merged into
//! one step of length `kT` with the noise densities kept: the mean of `k`
//! accelerometer means has σ_a/√k, `k` gimbal readings σ_g/√k, and the gyro
//! white rate noise over `kT` has the variance of `k` periods when its σ is
//! divided by √k (the filter's process noise is `(σ_gyro dt)²`). `k` is the
//! largest divisor of every segment's period count that keeps one step
//! within [`DEFAULT_STEP_DEG`] of rotation. The final σ of the designed path
//! is recomputed period by period, and the relative change is reported (it
//! must stay within 1 %).
//!
//! **The search.** Paths start aligned with n and are a *pattern* of up to
//! `P` constant-rate rotations about n-frame axes, repeated until the
//! targets are met (the last rotation cut at a whole period). Stage 1 is
//! exhaustive over the coarse grammar (axes × quarter-turn angles, every
//! segment at the maximum rate) with branch and bound: a candidate is
//! abandoned as soon as its elapsed time passes the best reach time found so
//! far, so within the coarse grammar the result is optimal (to one coarse
//! step). Stage 2 refines the best stage-1 patterns by hill climbing on
//! finer angles (30° steps, which keep the coarse step), slower rates, and, with `--tilted`, axes tilted
//! 45° between two allowed axes. Stage 2b (unless `--no-dwells`) climbs
//! again with dwell moves too: a dwell of 60, 180 or 600 s after a rotation
//! inserted, lengthened, shortened or removed (zero commanded path rate for
//! whole periods, as a scenario's `dwell_s`; the coarse step divides every
//! dwell). The best without and the best with dwells are both polished, so
//! the search with dwells is never worse than without. A candidate whose
//! middle gimbal angle |β| exceeds the limit before it reaches the targets
//! is infeasible.
//!
//! **The floor.** With the full model and errors that wander (a
//! Gauss–Markov drift or bias and a random walk), the persistent part of
//! a drift or a bias cannot be known better than a floor however the
//! platform rolls and for however long ([`crate::analysis::floor`], the
//! floors `host-sim observability --errors full` prints). Each target of
//! such a state carries its floor and the log length past which rolling
//! longer does not help; a target below its floor is out of reach of every
//! path, so it is set apart and reported with its floor, not searched for
//! ([`split_below_floor`]).
//!
//! **The fallback.** When the full model's shortest-path search finds no
//! path, its stage 1 (every candidate run to the duration limit) is scored
//! for the budget search that stands in rather than evaluated again
//! ([`search_reusing`]).
//!
//! The library part lives here, by concern: the axes ([`NamedAxis`]), the
//! paths ([`Pattern`]), the problem and its outcomes ([`Problem`],
//! [`Outcome`]), the bound evaluation (`Problem::evaluate`), the candidate
//! moves and the search ([`search`]), the targets and their floors, the information shares
//! ([`contributions`]), the checks of the designed path and the speed
//! measurement, and one design from start to end ([`run`]). It prints
//! nothing and returns [`DesignError`]; `crate::output::design` prints and
//! writes a [`Run`], and the subcommand (`host-sim design`) is
//! [`crate::cli::design`].

mod axis;
mod bound;
mod candidates;
mod check;
mod error;
mod explain;
mod floors;
mod nominal;
mod pattern;
mod probe;
mod problem;
mod reach;
mod run;
mod search;
mod speed;
mod targets;

#[cfg(test)]
mod tests;

pub use axis::NamedAxis;
pub use candidates::{coarse_patterns, neighbours, polish_neighbours, Space, DWELL_STEPS_S};
pub use check::{
    check_designed, coarse_check, observability_sigma, scenario_toml, scenario_with, Checked,
    CoarseCheck,
};
pub use error::DesignError;
pub use explain::{contributions, target_groups, Contribution};
pub use floors::{floor_of, split_below_floor, state_floors, BelowFloor, StateFloor};
pub use nominal::{nominal_scenario, TRUTH_STEPS_PER_PERIOD};
pub use pattern::{pattern_of, Pattern, Piece, Rotation};
pub use probe::{dwell_probe, DwellProbe};
pub use problem::{Goal, Outcome, Problem};
pub use reach::{out_of_reach, OutOfReach, FASTER_RATES_DEG_S};
pub use run::{run, Note, Observer, Request, Run, Silent, OUT_OF_REACH_HORIZON};
pub use search::{
    best_of, score_all, search, search_reusing, Design, Scored, StageStats, UnreachedStageOne,
};
pub use speed::{measure_speed, Speed};
pub use targets::{
    default_target_states, parse_target, targets, targets_with, InstrumentTargets, TargetArg,
};

/// Largest rotation (°) within one coarse step of the search.
pub const DEFAULT_STEP_DEG: f64 = 10.0;
/// The coarse steps' error budget on σ (relative).
pub const COARSE_SLACK: f64 = 0.01;
/// Period by period, a target counts as met at σ ≤ (1 + this)·target: the
/// library's commanded increments and the truth simulator's agree to this
/// (host-sim/tests/it/design.rs); the written scenario is then checked exactly.
pub const FINE_SLACK: f64 = 1e-4;
/// Largest number of periods merged into one coarse step.
pub const MAX_STEP_PERIODS: u64 = 30;
/// Coarse angles of stage 1 (°).
pub const COARSE_ANGLES: [f64; 4] = [90.0, 180.0, 270.0, 360.0];
/// Candidates re-evaluated period by period at the end of a reach search.
pub const FINAL_CHECKS: usize = 8;
/// Angle step of the refinement (°).
pub const FINE_ANGLE_DEG: f64 = 30.0;
