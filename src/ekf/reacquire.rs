//! The attitude acquired: at the start of a log that does not start at the
//! path's start ([`Filter::start_at`]: the computed frame set before the
//! first period), and re-acquired after a gap across which the commanded
//! motion is not known ([`Filter::reacquire_attitude`]: the computed frame
//! set, the attitude's covariance re-opened, the parameters' information
//! kept).

use nalgebra::{Matrix3, RealField};

use super::{all_finite, Error, Filter};
use crate::models::{Model, ATT};

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// Re-acquires the attitude after a gap across which the commanded
    /// motion is not known: the computed frame is set to `c_cn` (`C^c_n` at
    /// the start of the next period), and the attitude states' covariance
    /// is re-opened to `sigma` (rad) on each of them with no correlation to
    /// the parameters, whose covariance (their information) is kept. The
    /// attitude estimate is left as it is (the caller predicts it across the
    /// gap). In linearised mode the nominal's attitude follows the estimate,
    /// so the nominal stays a trajectory of the model.
    ///
    /// # Errors
    /// [`Error::NonFiniteInput`] or [`Error::CovarianceNotPositiveDefinite`]
    /// for a non-finite frame or a `sigma` that is not strictly positive; the
    /// filter is then left untouched.
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
    /// for _ in 0..5 {
    ///     f.step(&dtheta_c, dt, &obs)?;
    /// }
    /// let params = f.sigma().fixed_rows::<9>(3).into_owned();
    /// // After a gap: the computed frame as re-acquired, the attitude re-opened to 1°.
    /// f.reacquire_attitude(&nalgebra::Matrix3::identity(), deg)?;
    /// let sigma = f.sigma();
    /// assert!((sigma[0] - deg).abs() < 1e-12 && (sigma[2] - deg).abs() < 1e-12);
    /// assert_eq!(sigma.fixed_rows::<9>(3).into_owned(), params); // the parameters' information is kept
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    pub fn reacquire_attitude(&mut self, c_cn: &Matrix3<f64>, sigma: T) -> Result<(), Error> {
        if !all_finite(c_cn.iter().copied()) || !sigma.is_finite() {
            return Err(Error::NonFiniteInput);
        }
        if sigma <= T::zero() {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        // The pending time update moves only the attitude block, which this
        // replaces: it needs no applying.
        self.ud.reset_attitude(sigma * sigma);
        self.command.c_cn = *c_cn;
        if let Some(nominal) = self.reference.as_mut() {
            let att = Self::LAYOUT.attitude(&self.x);
            nominal.fixed_rows_mut::<3>(ATT).copy_from(&att);
        }
        self.pending.clear();
        Ok(())
    }

    /// Sets the computed frame `C^c_n` at the start of the next period to
    /// `c_cn`, nothing else: for a filter whose log does not start at the
    /// path's start (where `C^c_n = I`, [`Filter::new`]), called after
    /// [`Filter::new`] or [`Filter::restart`] and before the first period,
    /// with the attitude of the initial estimate given for that frame
    /// ([`crate::estimator::LogStart`]).
    ///
    /// # Errors
    /// [`Error::NonFiniteInput`] for a non-finite frame; the filter is then
    /// left untouched.
    ///
    /// # Examples
    ///
    /// ```
    /// # use nalgebra::SVector;
    /// # use rollcal::ekf::{FilterConfig, M1PaFilter, Options};
    /// # use rollcal::geometry::{earth_rate_n, gravity_n, r2, EARTH_RATE};
    /// # use rollcal::models::Environment;
    /// # let deg = core::f64::consts::PI / 180.0;
    /// # let config = FilterConfig::<f64> {
    /// #     env: Environment { earth_rate_n: earth_rate_n(EARTH_RATE, 34.25 * deg), gravity_n: gravity_n() },
    /// #     sigma_accel: 1e-6,
    /// #     sigma_gyro: 0.1 * deg / 3600.0,
    /// #     sigma_gimbal: 10.0 * deg / 3600.0,
    /// #     options: Options::default(),
    /// #     wander: rollcal::models::Wander::none(),
    /// # };
    /// let mut f = M1PaFilter::<f64>::new(config, SVector::zeros(), SVector::repeat(deg))?;
    /// // A log that starts half a turn about Up into the path.
    /// f.start_at(&r2(180.0 * deg))?;
    /// assert_eq!(f.command_frame().c_cn, r2(180.0 * deg));
    /// assert!(f.start_at(&(r2(0.0) * f64::NAN)).is_err());
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    pub fn start_at(&mut self, c_cn: &Matrix3<f64>) -> Result<(), Error> {
        if !all_finite(c_cn.iter().copied()) {
            return Err(Error::NonFiniteInput);
        }
        self.command.c_cn = *c_cn;
        Ok(())
    }
}
