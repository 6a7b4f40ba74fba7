//! The update of one period ([`Filter::update`]): the observation checked
//! and laid out as the measurement vector, then the update variant of the
//! filter's mode: the extended filter's (pass 1, with the cold-start
//! remedies; [`extended`], [`iterated`]) or the linearised filter's about
//! its nominal ([`linearised`]). Every variant ends in the factored update
//! ([`Filter::factored`](super::Filter::factored)).

mod extended;
mod iterated;
mod linearised;

use nalgebra::{RealField, SVector};

use super::{all_finite, Error, Filter, Innovation, Observation};
use crate::models::Model;
use crate::precision::to_f64;

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// Processes the measurement of the period that [`Filter::predict`] just
    /// propagated over.
    ///
    /// On error the state and the covariance are left untouched: the
    /// factor is updated in place, and an update that fails after Bierman's
    /// scalar updates began ([`Error::CovarianceNotPositiveDefinite`], or
    /// [`Error::NonFiniteState`] for a non-finite result) returns it to
    /// the copy saved before them in the filter's working memory.
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
    /// // An update needs the period predicted first.
    /// assert_eq!(f.update(&obs).unwrap_err(), rollcal::Error::NoPrediction);
    /// let before = f.sigma();
    /// f.predict(&dtheta_c, dt)?;
    /// let innovation = f.update(&obs)?;
    /// assert!(innovation.nis >= 0.0 && innovation.s[(0, 0)] > 0.0);
    /// assert!(f.sigma()[0] < before[0]);
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    pub fn update(&mut self, obs: &Observation<T>) -> Result<Innovation<T, Z>, Error> {
        let layout = Self::LAYOUT;
        if self.pending.get().is_none() {
            return Err(Error::NoPrediction);
        }
        let gimbal = match (layout.gimbal_obs, obs.gimbal) {
            (true, None) => return Err(Error::MissingGimbal),
            (true, Some(g)) => Some(g),
            (false, _) => None,
        };
        if !all_finite(
            obs.accel_mean
                .iter()
                .chain(gimbal.iter().flat_map(|g| g.iter()))
                .copied(),
        ) {
            return Err(Error::NonFiniteInput);
        }
        let mut z = SVector::<f64, Z>::zeros();
        if let Some(g) = gimbal {
            z.fixed_rows_mut::<3>(0).copy_from(&to_f64(&g));
        }
        z.fixed_rows_mut::<3>(Self::ACCEL_ROW)
            .copy_from(&to_f64(&obs.accel_mean));
        if self.reference.is_some() {
            self.update_linearised(Some(&z))
        } else {
            self.update_extended(&z)
        }
    }
}
