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
    /// innovation is `z − h(x_nom) − H (x̂ − x_nom)`. The full model's
    /// Gauss–Markov and warm-up states of the nominal are set to zero
    /// (their mean decays to zero). This is each later pass
    /// of the multi-pass estimator (the nominal is the previous pass's estimate
    /// propagated back to the start), and, with the true initial state as
    /// nominal, the Riccati recursion of the posterior Cramér–Rao bound.
    ///
    /// # Examples
    ///
    /// ```
    /// # use nalgebra::{SVector, Vector3};
    /// # use rollcal::ekf::{FilterConfig, M1PaFilter, Observation, Options};
    /// # use rollcal::geometry::{earth_rate_n, gravity_n, EARTH_RATE};
    /// # use rollcal::models::Environment;
    /// # let deg = core::f64::consts::PI / 180.0;
    /// # let w_ie = earth_rate_n(EARTH_RATE, 34.25 * deg);
    /// # let config = FilterConfig::<f64> {
    /// #     env: Environment { earth_rate_n: w_ie, gravity_n: gravity_n() },
    /// #     sigma_accel: 1e-6,
    /// #     sigma_gyro: 0.1 * deg / 3600.0,
    /// #     sigma_gimbal: 10.0 * deg / 3600.0,
    /// #     options: Options::default(),
    /// #     wander: rollcal::models::Wander::none(),
    /// # };
    /// # let mut f = M1PaFilter::<f64>::new(config, SVector::zeros(), SVector::repeat(deg))?;
    /// # // Holding still with the computed frame on n: the commanded increment is
    /// # // the Earth rate over the period, the accelerometers read gravity (g).
    /// # let (dtheta_c, dt) = (w_ie * 1.0, 1.0);
    /// # let obs = Observation { accel_mean: gravity_n::<f64>(), gimbal: None };
    /// f.step(&dtheta_c, dt, &obs)?;
    /// // Linearised about the estimate from here on.
    /// f.set_nominal(Some(*f.state()));
    /// assert!(f.nominal().is_some());
    /// f.step(&dtheta_c, dt, &obs)?;
    /// f.set_nominal(None); // back to the extended filter
    /// assert!(f.nominal().is_none());
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    pub fn set_nominal(&mut self, x_nominal: Option<SVector<f64, N>>) {
        self.reference = x_nominal.map(|mut x| {
            // The full model's Gauss–Markov parts and warm-up enter the model
            // linearly and decay towards zero: the nominal holds them at zero, the one
            // value the decay leaves in place, so that the linearised filter
            // moves its offsets from it exactly as the model moves the state
            // (docs/model.md §Errors that wander).
            for i in [
                Self::LAYOUT.dg_gm(),
                Self::LAYOUT.ba_gm(),
                Self::LAYOUT.dg_wu(),
                Self::LAYOUT.ba_wu(),
            ]
            .into_iter()
            .flatten()
            .flat_map(|i| i..i + 3)
            {
                if let Some(v) = x.get_mut(i) {
                    *v = 0.0;
                }
            }
            x
        });
    }

    /// The nominal state at the current time, in linearised mode.
    pub fn nominal(&self) -> Option<&SVector<f64, N>> {
        self.reference.as_ref()
    }

    /// The state estimate (rad), in the configuration's state order; held
    /// in double precision whatever `T` (see [`Filter`]).
    ///
    /// # Examples
    ///
    /// ```
    /// # use nalgebra::{SVector, Vector3};
    /// # use rollcal::ekf::{FilterConfig, M1PaFilter, Observation, Options};
    /// # use rollcal::geometry::{earth_rate_n, gravity_n, EARTH_RATE};
    /// # use rollcal::models::Environment;
    /// # let deg = core::f64::consts::PI / 180.0;
    /// # let w_ie = earth_rate_n(EARTH_RATE, 34.25 * deg);
    /// # let config = FilterConfig::<f64> {
    /// #     env: Environment { earth_rate_n: w_ie, gravity_n: gravity_n() },
    /// #     sigma_accel: 1e-6,
    /// #     sigma_gyro: 0.1 * deg / 3600.0,
    /// #     sigma_gimbal: 10.0 * deg / 3600.0,
    /// #     options: Options::default(),
    /// #     wander: rollcal::models::Wander::none(),
    /// # };
    /// # let mut f = M1PaFilter::<f64>::new(config, SVector::zeros(), SVector::repeat(deg))?;
    /// # // Holding still with the computed frame on n: the commanded increment is
    /// # // the Earth rate over the period, the accelerometers read gravity (g).
    /// # let (dtheta_c, dt) = (w_ie * 1.0, 1.0);
    /// # let obs = Observation { accel_mean: gravity_n::<f64>(), gimbal: None };
    /// f.step(&dtheta_c, dt, &obs)?;
    /// // 12 states of M1-pa, in the order of `ConfigId::M1Pa.states()`.
    /// let names = rollcal::ConfigId::M1Pa.states();
    /// assert_eq!(f.state().len(), names.len());
    /// assert!(f.state().iter().all(|v| v.is_finite()));
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    pub fn state(&self) -> &SVector<f64, N> {
        &self.x
    }

    /// The state covariance `P = U D Uᵀ` (rad²) of [`Filter::state`].
    pub fn covariance(&self) -> SMatrix<T, N, N> {
        Self::covariance_to_state_order(match self.pending.get() {
            Some(_) => self.settled().covariance(),
            None => self.ud.covariance(),
        })
    }

    /// Per-state standard deviations `√P_ii` (rad).
    ///
    /// # Examples
    ///
    /// ```
    /// # use nalgebra::{SVector, Vector3};
    /// # use rollcal::ekf::{FilterConfig, M1PaFilter, Observation, Options};
    /// # use rollcal::geometry::{earth_rate_n, gravity_n, EARTH_RATE};
    /// # use rollcal::models::Environment;
    /// # let deg = core::f64::consts::PI / 180.0;
    /// # let w_ie = earth_rate_n(EARTH_RATE, 34.25 * deg);
    /// # let config = FilterConfig::<f64> {
    /// #     env: Environment { earth_rate_n: w_ie, gravity_n: gravity_n() },
    /// #     sigma_accel: 1e-6,
    /// #     sigma_gyro: 0.1 * deg / 3600.0,
    /// #     sigma_gimbal: 10.0 * deg / 3600.0,
    /// #     options: Options::default(),
    /// #     wander: rollcal::models::Wander::none(),
    /// # };
    /// # let mut f = M1PaFilter::<f64>::new(config, SVector::zeros(), SVector::repeat(deg))?;
    /// # // Holding still with the computed frame on n: the commanded increment is
    /// # // the Earth rate over the period, the accelerometers read gravity (g).
    /// # let (dtheta_c, dt) = (w_ie * 1.0, 1.0);
    /// # let obs = Observation { accel_mean: gravity_n::<f64>(), gimbal: None };
    /// f.step(&dtheta_c, dt, &obs)?;
    /// // σ is the square root of the covariance's diagonal.
    /// let (sigma, p) = (f.sigma(), f.covariance());
    /// for i in 0..12 {
    ///     assert!((sigma[i] * sigma[i] - p[(i, i)]).abs() <= 1e-12 * p[(i, i)]);
    /// }
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    pub fn sigma(&self) -> SVector<T, N> {
        // With a period pending, those of `settled()`, from its new
        // attitude rows (no copy of the factor).
        let rows = self.pending.get().and_then(|p| {
            self.process_noise(p)
                .and_then(|q| self.ud.predicted_attitude_rows(&p.prop.phi_att, &q))
        });
        let mut variances = match rows {
            Some(rows) => self.ud.variances_with_rows(&rows),
            None => self.ud.variances(),
        };
        Self::vector_to_state_order(&mut variances);
        variances.map(|v| v.max(T::zero()).sqrt())
    }

    /// The packed U-D factor of the covariance (rad²; `D` on the diagonal,
    /// `U` strictly above; see the [module documentation](crate::ekf)), as
    /// checkpoints carry it, its rows and columns in the factor's order
    /// ([`Filter::FACTOR_ORDER`]: the state vector's for the installation
    /// model).
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
