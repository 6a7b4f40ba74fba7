//! The results of a run: the final states, the accepted updates of the
//! last pass, the whole run.

use nalgebra::RealField;
use rollcal::ekf;
use rollcal::geometry::wrap_angle;
use rollcal::models::{ConfigId, ErrorModel, StateInfo};

use super::filter::f64_of;
use crate::sim::segments::CommandSegment;

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
    /// Prior σ (internal units), for the verdicts; not in the JSON.
    #[serde(skip)]
    pub prior: f64,
    /// The state's name, group and unit: the `*_rad` fields hold a value
    /// in its internal unit (rad for the installation states; rad/s,
    /// rad/s/g, 1 or g for the instrument states of the full model,
    /// [`rollcal::models::StateInfo::printed_scale`]); not in the JSON.
    #[serde(skip)]
    pub info: StateInfo,
}

impl StateResult {
    /// Estimation error (internal unit); angle-wrapped for the angles.
    pub fn error(&self) -> f64 {
        let d = self.estimate_rad - self.truth_rad;
        if self.info.group.is_instrument() {
            d
        } else {
            wrap_angle(d)
        }
    }
    /// |error| / σ (0 for a state the model does not estimate and whose
    /// truth is its zero; infinite where the truth is not zero: the model
    /// lacks a term the data has).
    pub fn ratio(&self) -> f64 {
        let e = self.error().abs();
        if e == 0.0 && self.sigma_rad == 0.0 {
            0.0
        } else {
            e / self.sigma_rad
        }
    }

    /// Whether the model estimates the state (prior σ not zero).
    pub fn estimated(&self) -> bool {
        self.prior != 0.0
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
    /// The innovation `ν` itself (measurement units: rad, g); not in the
    /// JSON.
    #[serde(skip)]
    pub nu: Vec<f64>,
    /// The diagonal of its covariance `S` (squared measurement units); not
    /// in the JSON.
    #[serde(skip)]
    pub s_diag: Vec<f64>,
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
            nu: nu.iter().copied().collect(),
            s_diag: s.diagonal().iter().copied().collect(),
        }
    }
}

/// A whole run.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// Configuration.
    pub config: ConfigId,
    /// Error model (installation only, or with the instruments' errors).
    pub errors: ErrorModel,
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
    /// Prior σ of the installation states (rad; each state's own in
    /// [`StateResult::prior`]).
    pub prior_sigma_rad: f64,
    /// Passes over the data that were run.
    pub passes: u8,
    /// Updates that failed, with their period index and error.
    pub failures: Vec<(u32, ekf::Error)>,
}
