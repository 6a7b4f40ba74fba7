//! What a user reads of a filter between periods: the estimate, its
//! covariance, σ and U-D factor, the settings, the computed frame, the
//! counters; and the nominal of the linearised mode, set and read.

use nalgebra::{RealField, SMatrix, SVector};

use super::{Filter, FilterConfig};
use crate::command::CommandFrame;
use crate::models::{Layout, Model};

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// Switches to a linearised Kalman filter about a nominal trajectory
    /// that starts at `x_nominal` (the state at the current time) and follows
    /// the model's own dynamics; `None` returns to the extended filter.
    ///
    /// Jacobians are then evaluated on the nominal trajectory and the
    /// innovation is `z − h(x_nom) − H (x̂ − x_nom)`. This is each later pass
    /// of the multi-pass estimator (the nominal is the previous pass's estimate
    /// propagated back to the start), and, with the true initial state as
    /// nominal, the Riccati recursion of the posterior Cramér–Rao bound.
    pub fn set_nominal(&mut self, x_nominal: Option<SVector<f64, N>>) {
        self.reference = x_nominal;
    }

    /// The nominal state at the current time, in linearised mode.
    pub fn nominal(&self) -> Option<&SVector<f64, N>> {
        self.reference.as_ref()
    }

    /// The state estimate (rad), in the configuration's state order; held
    /// in double precision whatever `T` (see [`Filter`]).
    pub fn state(&self) -> &SVector<f64, N> {
        &self.x
    }

    /// The state covariance `P = U D Uᵀ` (rad²) of [`Filter::state`].
    pub fn covariance(&self) -> SMatrix<T, N, N> {
        match self.pending.get() {
            Some(_) => self.settled().covariance(),
            None => self.ud.covariance(),
        }
    }

    /// Per-state standard deviations `√P_ii` (rad).
    pub fn sigma(&self) -> SVector<T, N> {
        // With a period pending, those of `settled()`, from its new
        // attitude rows (no copy of the factor).
        let rows = self.pending.get().and_then(|p| {
            self.process_noise(p)
                .and_then(|q| self.ud.predicted_attitude_rows(&p.prop.phi_att, &q))
        });
        let variances = match rows {
            Some(rows) => self.ud.variances_with_rows(&rows),
            None => self.ud.variances(),
        };
        variances.map(|v| v.max(T::zero()).sqrt())
    }

    /// The packed U-D factor of the covariance (rad²; `D` on the diagonal,
    /// `U` strictly above; see the [module documentation](crate::ekf)), as
    /// checkpoints carry it.
    /// Between [`Filter::predict`] and [`Filter::update`] it is the factor at
    /// the start of the pending period.
    pub fn factor(&self) -> &SMatrix<T, N, N> {
        self.ud.packed()
    }

    /// The filter's settings.
    pub fn config(&self) -> &FilterConfig<T> {
        &self.config
    }

    /// The computed frame the filter integrates from the commands.
    pub fn command_frame(&self) -> &CommandFrame<f64> {
        &self.command
    }

    /// Number of updates processed.
    pub fn updates(&self) -> u32 {
        self.updates
    }

    /// The NIS gate's state: consecutive updates it refused just before now
    /// (at most [`MAX_GATED_RUN`](super::MAX_GATED_RUN): the next one is then accepted), and
    /// whether it is held open because the last accepted update was above it.
    pub fn gate_state(&self) -> (u32, bool) {
        (self.gated_run, self.gate_open)
    }

    /// The configuration's layout.
    pub const fn layout(&self) -> Layout {
        Self::LAYOUT
    }
}
