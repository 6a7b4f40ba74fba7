//! What is evaluated: the [`Goal`] of the search, the fixed [`Problem`]
//! (configuration, truth, noise, targets) and the [`Outcome`] of one
//! evaluation. The evaluation itself is in `bound.rs`.

use rollcal::ekf::FilterConfig;
use rollcal::models::{ConfigId, ErrorModel};

/// What the search aims at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Goal {
    /// The first period at which every target is met, abandoning the
    /// candidate after `cutoff` periods.
    Reach {
        /// Give up after this many periods.
        cutoff: u64,
    },
    /// The worst σ/target after exactly this many periods.
    Budget {
        /// Periods.
        periods: u64,
    },
}

/// The fixed part of every evaluation: configuration, truth, noise, targets.
#[derive(Clone, Debug)]
pub struct Problem {
    /// Configuration.
    pub config: ConfigId,
    /// Error model of the bound: the installation errors, or the full model
    /// (the 21 instrument terms too).
    pub errors: ErrorModel,
    /// Filter settings (noise levels of the scenario, Earth rate).
    pub cfg: FilterConfig<f64>,
    /// True initial state (internal units: rad, then the instrument terms'
    /// rad/s, rad/s/g, 1, g, 1 with the full model).
    pub truth0: Vec<f64>,
    /// Prior σ of every state (internal units; the scenario's `[prior]` and,
    /// with the full model, `[instruments.prior]`).
    pub prior: Vec<f64>,
    /// Filter period (s).
    pub period_s: f64,
    /// Largest |β| (rad) allowed.
    pub max_beta: f64,
    /// `(state index, target σ in rad)` of every target.
    pub targets: Vec<(usize, f64)>,
    /// Largest rotation per coarse step (°).
    pub step_deg: f64,
    /// A coarse step counts a target met at σ ≤ (1 + slack)·target (the
    /// coarse steps' error budget; period by period the test is exact).
    pub coarse_slack: f64,
    /// Largest number of periods per coarse step.
    pub max_step_periods: u64,
}

/// The outcome of one evaluation.
#[derive(Clone, Debug, Default)]
pub struct Outcome {
    /// Periods evaluated.
    pub periods: u64,
    /// Period at which every target was first met (a coarse-step boundary
    /// when `k > 1`).
    pub reach: Option<u64>,
    /// σ_CRLB of every state at the end (rad).
    pub sigma_end: Vec<f64>,
    /// max over the targets of σ/target at the end.
    pub worst_ratio: f64,
    /// The |β| limit was exceeded (at this period) before the end.
    pub gimbal_lock: Option<u64>,
    /// Periods per step used.
    pub k: u64,
    /// Per step, when recorded: (t in s, σ of every state in rad, rotation
    /// index within the pattern, whether the step is the rotation's dwell).
    pub history: Vec<(f64, Vec<f64>, usize, bool)>,
}

impl Outcome {
    /// Feasible and meeting the goal: reached (Reach), or not locked (Budget).
    pub fn feasible(&self, goal: Goal) -> bool {
        match goal {
            Goal::Reach { .. } => self.reach.is_some(),
            Goal::Budget { .. } => self.gimbal_lock.is_none(),
        }
    }

    /// The score to minimise: reach periods, or the worst ratio.
    pub fn score(&self, goal: Goal) -> f64 {
        if !self.feasible(goal) {
            return f64::INFINITY;
        }
        match goal {
            Goal::Reach { .. } => self.reach.map_or(f64::INFINITY, |r| r as f64),
            Goal::Budget { .. } => self.worst_ratio,
        }
    }
}
