//! One filter period ([`Filter::step`]): [`Filter::predict`] then
//! [`Filter::update`], the filter left as it was on error; and the
//! noise-free step of the posterior Cramér–Rao recursion.

use nalgebra::{RealField, Vector3};

use super::{Error, Filter, Innovation, Observation};
use crate::models::{Model, ATT};

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// One filter period: [`Filter::predict`] then [`Filter::update`].
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
    /// let prior = f.sigma();
    /// for _ in 0..10 {
    ///     let innovation = f.step(&dtheta_c, dt, &obs)?;
    ///     assert!(innovation.nis.is_finite());
    /// }
    /// assert_eq!(f.updates(), 10);
    /// // The tilt about North (ψ_N, state 0) is observed by the accelerometers.
    /// assert!(f.sigma()[0] < prior[0]);
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    pub fn step(
        &mut self,
        dtheta_c: &Vector3<f64>,
        dt: f64,
        obs: &Observation<T>,
    ) -> Result<Innovation<T, Z>, Error> {
        self.step_with(dtheta_c, dt, Some(obs))
    }

    /// One period of the linearised filter fed the noise-free measurement
    /// of its own nominal, `h(x_nom)`, without the caller computing it: the
    /// posterior Cramér–Rao recursion of
    /// [`crate::observability::Observability`] (its covariance update is
    /// [`Filter::step`]'s, which does not depend on the measured values).
    /// [`Error::NoPrediction`] outside the linearised mode (no nominal).
    /// The innovation is not reported (its covariance `S` is not computed)
    /// and the NIS gate does not apply.
    pub(crate) fn step_noise_free(
        &mut self,
        dtheta_c: &Vector3<f64>,
        dt: f64,
    ) -> Result<(), Error> {
        self.step_with(dtheta_c, dt, None).map(|_| ())
    }

    /// [`Filter::step`] with `obs`, or [`Filter::step_noise_free`] for
    /// `None`. Out of line: one filter step is this function
    /// (`firmware/bench.sh` measures its stack).
    #[inline(never)]
    fn step_with(
        &mut self,
        dtheta_c: &Vector3<f64>,
        dt: f64,
        obs: Option<&Observation<T>>,
    ) -> Result<Innovation<T, Z>, Error> {
        if obs.is_none() && self.reference.is_none() {
            return Err(Error::NoPrediction);
        }
        if self.pending.get().is_some() {
            self.settle()?;
            self.pending.clear();
        }
        // `predict` and `update` leave the factor untouched on error (every
        // input of the in-place update is checked before it is touched, and
        // a failure after the scalar updates restores the factor saved
        // before them), so only the state is saved here: the
        // estimate, the computed frame, and the nominal's attitude (`predict`
        // moves only the attitude of the nominal).
        let layout = Self::LAYOUT;
        // The estimate in the working memory, not in this frame.
        self.scratch.x_before = self.x;
        let saved = (
            self.command,
            self.reference.as_ref().map(|r| layout.attitude(r)),
        );
        self.predict(dtheta_c, dt)?;
        let updated = match obs {
            Some(obs) => self.update(obs),
            None => self.update_linearised(None),
        };
        match updated {
            Err(e) if e != Error::Gated => {
                let (command, nominal_att) = saved;
                self.x = self.scratch.x_before;
                self.command = command;
                if let (Some(r), Some(att)) = (self.reference.as_mut(), nominal_att) {
                    r.fixed_rows_mut::<3>(ATT).copy_from(&att);
                }
                self.pending.clear();
                Err(e)
            }
            other => other,
        }
    }
}
