//! The filter between two periods as a checkpoint saves it ([`Parts`]), and
//! the filter rebuilt from them ([`Filter::from_parts`],
//! [`Filter::set_parts`]), bit-identically.

use nalgebra::{Matrix3, RealField, SMatrix, SVector};

use super::{all_finite, env_t, Error, Filter, FilterConfig};
use crate::command::CommandFrame;
use crate::models::Model;
use crate::precision::scalar_to_f64;
use crate::wire::factor_len;

/// The parts of a filter between two periods, as a checkpoint saves them
/// ([`Filter::set_parts`], [`Filter::from_parts`]).
#[derive(Clone, Copy, Debug)]
pub struct Parts<'a, const N: usize> {
    /// State (rad; the configuration's state order).
    pub x: &'a SVector<f64, N>,
    /// The packed U-D factor of the covariance (rad², [`Filter::factor`]),
    /// its upper triangle (diagonal included, the zeros below left out) row
    /// by row in f64 (rounded to `T`): `N (N + 1) / 2` values
    /// ([`crate::wire::factor_len`]), row `r` holding columns `r..N`.
    pub factor: &'a [f64],
    /// The computed frame `C^c_n` at the start of the next period.
    pub c_cn: &'a Matrix3<f64>,
    /// The nominal of the linearised mode (rad), `None` for the extended
    /// filter.
    pub nominal: Option<&'a SVector<f64, N>>,
    /// Updates applied so far.
    pub updates: u32,
    /// The NIS gate's state ([`Filter::gate_state`]).
    pub gate_state: (u32, bool),
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// Rebuilds a filter between two periods from its parts, as saved by a
    /// checkpoint ([`crate::calibrator::Calibrator::checkpoint`]): state `x`
    /// (rad), the packed U-D factor of its covariance ([`Filter::factor`],
    /// rad², used as given, so a restored filter continues
    /// bit-identically), computed frame `c_cn` (`C^c_n`), nominal
    /// of the linearised mode, the update counter and the state of the NIS
    /// gate ([`Filter::gate_state`]). The Earth rate of the computed frame is
    /// the one of `config`.
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
    /// for _ in 0..3 {
    ///     f.step(&dtheta_c, dt, &obs)?;
    /// }
    /// // A checkpoint's parts, and the filter rebuilt from them.
    /// let mut g = M1PaFilter::from_parts(
    ///     *f.config(),
    ///     *f.state(),
    ///     *f.factor(),
    ///     f.command_frame().c_cn,
    ///     f.nominal().copied(),
    ///     f.updates(),
    ///     f.gate_state(),
    /// )?;
    /// assert_eq!(g, f);
    /// // It continues bit-identically.
    /// assert_eq!(g.step(&dtheta_c, dt, &obs)?, f.step(&dtheta_c, dt, &obs)?);
    /// assert_eq!(g.state(), f.state());
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    pub fn from_parts(
        config: FilterConfig<T>,
        x: SVector<f64, N>,
        factor: SMatrix<T, N, N>,
        c_cn: Matrix3<f64>,
        nominal: Option<SVector<f64, N>>,
        updates: u32,
        gate_state: (u32, bool),
    ) -> Result<Self, Error> {
        let mut f = Self::new(config, SVector::zeros(), SVector::repeat(T::one()))?;
        let parts = Parts {
            x: &x,
            // Not read: the factor is `factor`'s entries (below).
            factor: &[],
            c_cn: &c_cn,
            nominal: nominal.as_ref(),
            updates,
            gate_state,
        };
        // Exact: every T of the filter is an f64.
        f.set_parts_with(config, &parts, &|r, c| {
            factor.get((r, c)).copied().map(scalar_to_f64)
        })?;
        Ok(f)
    }

    /// [`Filter::from_parts`] in place, with the factor as its upper
    /// triangle row by row in f64 ([`Parts::factor`]: a checkpoint's
    /// layout, read where it is: no `N×N` temporary). Every part is checked
    /// before the filter is touched: on error it is unchanged
    /// ([`Error::NonFiniteInput`] also for a factor that has not
    /// `N (N + 1) / 2` entries).
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
    /// // The factor in a checkpoint's layout: its upper triangle row by row,
    /// // in f64.
    /// let n = f.state().len();
    /// let rows: Vec<f64> = (0..n).flat_map(|r| (r..n).map(move |c| (r, c)))
    ///     .map(|(r, c)| f.factor()[(r, c)])
    ///     .collect();
    /// let parts = rollcal::ekf::Parts {
    ///     x: f.state(),
    ///     factor: &rows,
    ///     c_cn: &f.command_frame().c_cn,
    ///     nominal: f.nominal(),
    ///     updates: f.updates(),
    ///     gate_state: f.gate_state(),
    /// };
    /// let mut g = M1PaFilter::new(config, SVector::zeros(), SVector::repeat(deg))?;
    /// g.set_parts(config, &parts)?;
    /// assert_eq!(g, f);
    /// // A factor of the wrong size is refused, the filter left as it was.
    /// let short = rollcal::ekf::Parts { factor: &rows[..10], ..parts };
    /// assert_eq!(g.set_parts(config, &short), Err(rollcal::Error::NonFiniteInput));
    /// assert_eq!(g, f);
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    pub fn set_parts(
        &mut self,
        config: FilterConfig<T>,
        parts: &Parts<'_, N>,
    ) -> Result<(), Error> {
        let upper = parts.factor;
        // A factor of another length has no entry (refused as non-finite).
        let whole = upper.len() == factor_len(N);
        self.set_parts_with(config, parts, &|r, c| {
            whole
                .then(|| upper.get(crate::wire::factor_index(N, r, c)).copied())
                .flatten()
        })
    }

    /// [`Filter::set_parts`] with the factor's upper triangle given by
    /// `factor_at(r, c)` (`c ≥ r`; f64) instead of [`Parts::factor`].
    fn set_parts_with(
        &mut self,
        config: FilterConfig<T>,
        parts: &Parts<'_, N>,
        factor_at: &dyn Fn(usize, usize) -> Option<f64>,
    ) -> Result<(), Error> {
        Self::prior_variance(&config, &SVector::zeros(), &SVector::repeat(T::one()))?;
        let nominal_values = parts.nominal.iter().flat_map(|v| v.iter().copied());
        if !all_finite(
            parts
                .x
                .iter()
                .chain(parts.c_cn.iter())
                .copied()
                .chain(nominal_values),
        )
            // Finite in T, not only in f64 (an f32 overflow is non-finite).
            || !(0..N).all(|r| {
                (r..N).all(|c| {
                    factor_at(r, c).is_some_and(|v| nalgebra::convert::<f64, T>(v).is_finite())
                })
            })
        {
            return Err(Error::NonFiniteInput);
        }
        if !self.ud.set_upper_with(factor_at, Self::HELD_FROM) {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        self.x = *parts.x;
        self.command = CommandFrame::aligned(config.env.earth_rate_n);
        self.command.c_cn = *parts.c_cn;
        self.env_t = env_t(&config.env);
        self.config = config;
        self.pending.clear();
        self.reference = parts.nominal.copied();
        self.updates = parts.updates;
        (self.gated_run, self.gate_open) = parts.gate_state;
        self.matrices
            .fill(Self::LAYOUT.installation(&SVector::<f64, N>::zeros()));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::wire::factor_index;

    #[test]
    fn factor_index_walks_the_triangle_row_by_row() {
        let n = 5;
        let mut want = 0;
        for r in 0..n {
            for c in r..n {
                assert_eq!(factor_index(n, r, c), want);
                want += 1;
            }
        }
        assert_eq!(want, crate::wire::factor_len(n));
    }
}
