//! The prediction of one period ([`Filter::predict`]): the state propagated
//! by one RK4 step over the commanded motion (docs/model.md §Configurations,
//! §Measurement timing), the period kept pending for its covariance time update;
//! and the optional second-order terms of the attitude dynamics
//! ([`Options::second_order_dynamics`](super::Options::second_order_dynamics)).

use nalgebra::{Matrix3, RealField, SMatrix, SVector, Vector3};

use super::options::RESEARCH_OPTIONS;
use super::{all_finite, Error, Filter};
use crate::command::Period;
use crate::models::{Model, ATT};
use crate::precision::{to_f64, to_t};

/// `(½ tr(∇²g_a P), ½ tr(∇²g_a P ∇²g_b P))` of a 3-vector function `g`
/// whose Jacobian is `jac`, by central differences of `jac` along the
/// error-state directions `j` with `relevant(j)`. Used for the attitude
/// dynamics (`Options::second_order_dynamics`, off by default), and as the
/// reference the analytic accelerometer Hessian is tested against.
pub(crate) fn hessian_terms<T: RealField + Copy, const N: usize>(
    x: &SVector<T, N>,
    p: &SMatrix<T, N, N>,
    relevant: impl Fn(usize) -> bool,
    jac: impl Fn(&SVector<T, N>) -> Option<SMatrix<T, 3, N>>,
) -> Option<(Vector3<T>, Matrix3<T>)> {
    let delta: T = nalgebra::convert(1e-5);
    let two: T = nalgebra::convert(2.0);
    let half: T = nalgebra::convert(0.5);
    let mut hess = [SMatrix::<T, N, N>::zeros(); 3];
    for j in (0..N).filter(|&j| relevant(j)) {
        let mut e = SVector::<T, N>::zeros();
        if let Some(v) = e.get_mut(j) {
            *v = delta;
        }
        let d = (jac(&(x + e))? - jac(&(x - e))?) / (two * delta);
        for (a, hs) in hess.iter_mut().enumerate() {
            if let (Some(mut col), Some(row)) = (hs.column_iter_mut().nth(j), d.row_iter().nth(a)) {
                col.copy_from(&row.transpose());
            }
        }
    }
    let mut mean = Vector3::zeros();
    let mut cov = Matrix3::zeros();
    let mut hp = [SMatrix::<T, N, N>::zeros(); 3];
    for (a, hs) in hess.iter_mut().enumerate() {
        *hs = (*hs + hs.transpose()) * half;
        if let (Some(dst), Some(m)) = (hp.get_mut(a), mean.get_mut(a)) {
            *dst = *hs * p;
            *m = dst.trace() * half;
        }
    }
    for a in 0..3 {
        for b in a..3 {
            if let (Some(ha), Some(hb)) = (hp.get(a), hp.get(b)) {
                // tr(A B) = Σ_ij A_ij B_ji
                let t = ha.component_mul(&hb.transpose()).sum() * half;
                if let Some(v) = cov.get_mut((a, b)) {
                    *v = t;
                }
                if let Some(v) = cov.get_mut((b, a)) {
                    *v = t;
                }
            }
        }
    }
    Some((mean, cov))
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// Propagates the state over one period of length `dt` (s) with
    /// commanded angle increment `dtheta_c` (rad, c frame). The covariance's
    /// time update is applied by the [`Filter::update`] that follows (with
    /// the measurement, whose noise it shares), or by the next `predict`.
    ///
    /// On error the filter is left as it was, except that a period
    /// predicted before without its update gets its time update (as the
    /// next `predict` or `step` would apply it): the period is propagated
    /// straight into the filter's pending slot, which that period held.
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
    /// f.predict(&dtheta_c, dt)?;
    /// // The covariance's time update waits for the update (or the next predict).
    /// assert_eq!(f.updates(), 0);
    /// f.update(&obs)?;
    /// assert_eq!(f.updates(), 1);
    /// // A period must be strictly positive.
    /// assert_eq!(f.predict(&dtheta_c, 0.0), Err(rollcal::Error::InvalidPeriod));
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    pub fn predict(&mut self, dtheta_c: &Vector3<f64>, dt: f64) -> Result<(), Error> {
        if !all_finite(dtheta_c.iter().copied().chain([dt])) {
            return Err(Error::NonFiniteInput);
        }
        if dt <= 0.0 {
            return Err(Error::InvalidPeriod);
        }
        // A period predicted without a measurement: its time update (in
        // place, untouched on error) frees the slot.
        self.settle()?;
        self.pending.clear();
        let layout = Self::LAYOUT;
        // The linearisation point: the estimate (EKF) or the nominal (by
        // reference: no copy of the state).
        let x_lin = self.reference.as_ref().unwrap_or(&self.x);
        self.matrices.refresh(&layout, x_lin);
        let slot = &mut self.pending.value;
        self.command
            .period_in_into::<T>(dtheta_c, dt, &mut slot.period, &mut slot.period_t);
        let att0 = layout.attitude(x_lin);
        // The attitude in f64, its increments over the period and the
        // Jacobians in T (see `Filter`).
        layout
            .propagate_into_jacobians_in(
                &self.env_t,
                &self.matrices.m,
                &att0,
                &slot.period_t.period,
                &mut slot.att,
                &mut slot.prop,
            )
            .ok_or(Error::GimbalLock)?;
        // Φ's attitude rows as the factor reads them (its order).
        Self::columns_to_factor_order(&mut slot.prop.phi_att);
        let new = &self.pending.value;
        let q_extra = if RESEARCH_OPTIONS && self.config.options.second_order_dynamics {
            self.second_order_dynamics(&new.period, &new.att)?
        } else {
            Matrix3::<T>::zeros()
        };
        if !all_finite(q_extra.iter().copied()) || !all_finite(new.prop.noise_map.iter().copied()) {
            return Err(Error::NonFiniteState);
        }
        let [_, _, att1] = new.att;
        let x_new = match &self.reference {
            // x̂_{k+1} = x_nom,k+1 ⊞ Φ (x̂_k ⊟ x_nom,k): the parameters
            // x_nom + δ, the attitude att_{k+1} + Φ_att δ (formed in δ's
            // place).
            Some(x_nom) => {
                let mut x = layout.difference(&self.x, x_nom);
                let d_att = Self::attitude_term(&new.prop.phi_att, &x);
                for (i, (v, nom)) in x.iter_mut().zip(x_nom.iter()).enumerate() {
                    if i >= ATT + 3 {
                        *v += *nom;
                    }
                }
                x.fixed_rows_mut::<3>(ATT).copy_from(&(att1 + d_att));
                x
            }
            // The estimate with the attitude at the period's end.
            None => {
                let mut x = self.x;
                x.fixed_rows_mut::<3>(ATT).copy_from(&att1);
                x
            }
        };
        if !all_finite(x_new.iter().copied()) {
            return Err(Error::NonFiniteState);
        }
        if let Some(x_nom) = self.reference.as_mut() {
            x_nom.fixed_rows_mut::<3>(ATT).copy_from(&att1);
        }
        self.x = x_new;
        self.command.advance(&self.pending.value.period);
        self.pending.value.q_extra = q_extra;
        self.pending.valid = true;
        Ok(())
    }

    /// The second-order process noise of the attitude over `period`
    /// (rad²; [`Options::second_order_dynamics`]): the linearisation error
    /// of the period map `x_{k+1} ≈ x_k + f(x_mid) T`, from central
    /// differences of the attitude-rate Jacobian. Out of line: its N×N
    /// temporaries stay out of [`Filter::predict`]'s frame.
    #[inline(never)]
    fn second_order_dynamics(
        &self,
        period: &Period<f64>,
        att: &[Vector3<f64>; 3],
    ) -> Result<Matrix3<T>, Error> {
        let layout = Self::LAYOUT;
        let env = &self.config.env;
        let [_, wm, _] = period.omega_c;
        let [_, cm, _] = period.c_cn;
        let [_, att_mid, _] = *att;
        let mut x_mid = self.x;
        x_mid.fixed_rows_mut::<3>(ATT).copy_from(&att_mid);
        // The states the rate depends on: attitude, θgC, θgT, λ and, in the
        // full model, the gyro errors dg, D_g, kg (15 states from dg).
        let relevant = |j: usize| {
            j < 9
                || layout.lam().is_some_and(|i| (i..i + 3).contains(&j))
                || layout.dg().is_some_and(|i| (i..i + 15).contains(&j))
        };
        let p_now = to_f64(&Self::covariance_to_state_order(
            self.propagated_factor()?.covariance(),
        ));
        let (_, q2) = hessian_terms(&x_mid, &p_now, relevant, |xp| {
            layout.attitude_rate_jacobian(env, &layout.matrices(xp), &layout.attitude(xp), &wm, &cm)
        })
        .ok_or(Error::GimbalLock)?;
        Ok(to_t(&(q2 * (period.dt * period.dt))))
    }
}
