//! The discrete propagation over one filter period (docs/model.md
//! §Measurement timing): one RK4 step of the attitude dynamics driven by
//! the commanded rate at the period's three nodes `t_k − T`, `t_k − T/2`,
//! `t_k`, the midpoint from the cubic Hermite interpolant, the transition
//! rows `Φ = exp(F T)` to second order and the noise map `B`
//! ([`PeriodPropagation`]); the state at the end of a period.

use core::any::TypeId;

use nalgebra::{Matrix3, RealField, SMatrix, SVector, Vector3};

use super::blocks::put3;
use super::installation::InstallationMatrices;
use super::layout::{AttitudeKind, Layout, ATT};
use super::transition::transition_rows_into;
use super::Environment;
use crate::command::Period;
use crate::geometry::{gimbal_rate_inverse, right_jacobian_inv};

/// The state trajectory over one period at the nodes `t_k`, `t_k + T/2`,
/// `t_k + T`, and the discrete transition of the attitude block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeriodPropagation<T: RealField + Copy, const N: usize> {
    /// Attitude states at the three nodes (rad).
    pub att: [Vector3<T>; 3],
    /// Rows of `Φ = ∂x_{k+1}/∂x_k` for the attitude block (3×N); the
    /// parameter rows of `Φ` are the identity.
    pub phi_att: SMatrix<T, 3, N>,
    /// `F` rows (3×N) at the midpoint node.
    pub f_mid: SMatrix<T, 3, N>,
    /// `F` rows (3×N) at the end node.
    pub f_end: SMatrix<T, 3, N>,
    /// `B = ∂(attitude rate)/∂(platform rate noise)` at the midpoint (3×3).
    pub noise_map: Matrix3<T>,
}

impl<T: RealField + Copy, const N: usize> PeriodPropagation<T, N> {
    /// All zeros (storage to propagate into, [`Layout::propagate_into`]).
    pub fn zeros() -> Self {
        Self {
            att: [Vector3::zeros(); 3],
            phi_att: SMatrix::zeros(),
            f_mid: SMatrix::zeros(),
            f_end: SMatrix::zeros(),
            noise_map: Matrix3::zeros(),
        }
    }
}

impl Layout {
    /// Propagates the attitude over one period by one RK4 step driven by the
    /// commanded rate at the period's nodes; the midpoint state comes from the
    /// cubic Hermite interpolant (error ≈ T⁴|x⁽⁴⁾|/384 < 1e-14 rad). The
    /// transition rows use the midpoint Jacobian, `Φ = exp(F T)` to second
    /// order. `None` at gimbal lock or on non-finite values.
    pub fn propagate<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att0: &Vector3<T>,
        period: &Period<T>,
    ) -> Option<PeriodPropagation<T, N>> {
        let mut out = PeriodPropagation::zeros();
        self.propagate_into(env, m, att0, period, &mut out)?;
        Some(out)
    }

    /// [`Layout::propagate`] written into `out`. On `None` `out` holds a
    /// partial result.
    pub fn propagate_into<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att0: &Vector3<T>,
        period: &Period<T>,
        out: &mut PeriodPropagation<T, N>,
    ) -> Option<()> {
        let mut att = [Vector3::zeros(); 3];
        self.propagate_into_jacobians_in(env, m, att0, period, &mut att, out)
    }

    /// [`Layout::propagate_into`] with the attitude held in precision `P`
    /// and everything else evaluated in precision `J` on `env_j` and `m_j`
    /// (the environment and installation matrices in `J`): the attitude at
    /// the three nodes into `att` (in `P`), the same rounded to `J` and the
    /// Jacobians into `out`; for `J = P` the conversions are the identity,
    /// which is [`Layout::propagate_into`]. In `J`: the attitude's
    /// increments over the period (the RK4 stages) and the Jacobians (`F` at
    /// the midpoint and the end, the transition rows, the noise map). A
    /// single-precision filter (the filter's pending slot, `P = f64`,
    /// `J = f32`) needs its Jacobians to a few digits only, and the
    /// increments are small: ≈ 1.7e-3 rad per period on the paper's path
    /// (0.1 °/s, 1 s), exact in f32 to ≈ 3e-7 of themselves, ≈ 5e-10 rad,
    /// three orders of magnitude under the paper's gyro noise over a period
    /// (0.1 °/h · 1 s ≈ 4.8e-7 rad). On an FPU without double precision
    /// they would otherwise be emulated f64. What `J` must not do is round
    /// the commanded rotation the same way in every period: a relative
    /// error of the commanded rate that repeats is a torquer scale factor
    /// (the full model's `kg`; f32's 2⁻²⁴ ≈ 0.06 ppm is 0.1σ on a roll at
    /// 1 °/s). So, for `J` other than f64, the rates' small parts are formed
    /// without the command ([`Layout::attitude_rate`]: `G`'s rounded
    /// diagonal) and the RK4 sum is divided by 6 (1/6 rounded to f32 is
    /// 3e-8 of itself too large).
    pub fn propagate_into_jacobians_in<P: RealField + Copy, J: RealField + Copy, const N: usize>(
        &self,
        env_j: &Environment<J>,
        m_j: &InstallationMatrices<J>,
        att0: &Vector3<P>,
        period: &Period<J>,
        att: &mut [Vector3<P>; 3],
        out: &mut PeriodPropagation<J, N>,
    ) -> Option<()> {
        let [_, wm, w1] = &period.omega_c;
        let [_, cm, c1] = &period.c_cn;
        let [_, att_mid, att1] = self.trajectory(env_j, m_j, att0, period)?;
        let (att_mid_j, att1_j) = (vector_in(&att_mid)?, vector_in(&att1)?);
        self.attitude_rate_jacobian_into(env_j, m_j, &att_mid_j, wm, cm, &mut out.f_mid)?;
        self.attitude_rate_jacobian_into(env_j, m_j, &att1_j, w1, c1, &mut out.f_end)?;
        transition_rows_into(&out.f_mid, period.dt, &mut out.phi_att);
        out.noise_map = self.noise_map(&att_mid_j)?;
        out.att = [vector_in(att0)?, att_mid_j, att1_j];
        *att = [*att0, att_mid, att1];
        if att1.iter().all(|v| v.is_finite()) && out.phi_att.iter().all(|v| v.is_finite()) {
            Some(())
        } else {
            None
        }
    }

    /// The attitude at the period's three nodes: one RK4 step driven by the
    /// commanded rate at the nodes, the midpoint from the cubic Hermite
    /// interpolant (see [`Layout::propagate`]); `None` at gimbal lock. The
    /// attitude `att0` is held in precision `P`, its rates, and so its
    /// increments over the period, are evaluated in precision `J` on `env_j`
    /// and `m_j`: the nodes are `att0` plus increments rounded to `J`. For
    /// `J = P` the conversions are the identity; `P = f64`, `J = f32` is
    /// [`Layout::propagate_into_jacobians_in`]'s case (the error it makes).
    fn trajectory<P: RealField + Copy, J: RealField + Copy>(
        &self,
        env_j: &Environment<J>,
        m_j: &InstallationMatrices<J>,
        att0: &Vector3<P>,
        period: &Period<J>,
    ) -> Option<[Vector3<P>; 3]> {
        let to_j = vector_in::<P, J>;
        let to_p = |v: Vector3<J>| vector_in::<J, P>(&v);
        let dt = period.dt;
        let eight: J = nalgebra::convert(8.0);
        let [_, _, w1] = &period.omega_c;
        let [_, _, c1] = &period.c_cn;
        let (att1, k1) = self.rk4_end(env_j, m_j, att0, period)?;
        let f1 = self.attitude_rate(env_j, m_j, &to_j(&att1)?, w1, c1)?;
        let att_mid =
            (att0 + att1) * nalgebra::convert::<f64, P>(0.5) + to_p((k1 - f1) * (dt / eight))?;
        Some([*att0, att_mid, att1])
    }

    /// The attitude at the end of `period` by one RK4 step from `att0`,
    /// and the rate at its start (`k1`): [`Layout::trajectory`]'s end node.
    fn rk4_end<P: RealField + Copy, J: RealField + Copy>(
        &self,
        env_j: &Environment<J>,
        m_j: &InstallationMatrices<J>,
        att0: &Vector3<P>,
        period: &Period<J>,
    ) -> Option<(Vector3<P>, Vector3<J>)> {
        let to_j = vector_in::<P, J>;
        let to_p = |v: Vector3<J>| vector_in::<J, P>(&v);
        let dt = period.dt;
        let half: J = nalgebra::convert(0.5);
        let two: J = nalgebra::convert(2.0);
        let six: J = nalgebra::convert(6.0);
        let [w0, wm, w1] = &period.omega_c;
        // C^c_n at the nodes: read by the full model's M1 only (f^p of
        // the g-sensitive drift).
        let [c0, cm, c1] = &period.c_cn;
        let a0 = to_j(att0)?;
        let k1 = self.attitude_rate(env_j, m_j, &a0, w0, c0)?;
        let k2 = self.attitude_rate(env_j, m_j, &(a0 + k1 * (dt * half)), wm, cm)?;
        let k3 = self.attitude_rate(env_j, m_j, &(a0 + k2 * (dt * half)), wm, cm)?;
        let k4 = self.attitude_rate(env_j, m_j, &(a0 + k3 * dt), w1, c1)?;
        let sum = k1 + (k2 + k3) * two + k4;
        // In f64 the weight T/6 as ever; in f32 its rounding (1/6 is off by
        // 3e-8 of itself) would be a scale factor of the commanded rotation
        // that every period repeats, so the sum is divided by 6 (each
        // increment rounded once, period by period differently).
        let increment = if TypeId::of::<J>() == TypeId::of::<f64>() {
            sum * (dt / six)
        } else {
            sum * dt / six
        };
        Some((att0 + to_p(increment)?, k1))
    }

    /// `B = ∂(attitude rate)/∂(platform rate noise)` at attitude `att`
    /// (3×3); `None` at gimbal lock.
    fn noise_map<T: RealField + Copy>(&self, att: &Vector3<T>) -> Option<Matrix3<T>> {
        Some(match self.attitude {
            AttitudeKind::Misalignment => right_jacobian_inv(att),
            AttitudeKind::Gimbal | AttitudeKind::Attitude => gimbal_rate_inverse(att.y, att.z)?,
        })
    }

    /// The state at the end of `period` (or at its start, for a
    /// [`Period::reversed`] period) under the model's dynamics; the
    /// parameters are constant. `None` at gimbal lock.
    pub fn propagate_state<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        x: &SVector<T, N>,
        period: &Period<T>,
    ) -> Option<SVector<T, N>> {
        self.propagate_state_with(env, &self.matrices(x), x, period)
    }

    /// [`Layout::propagate_state`] with the installation matrices of `x`'s
    /// parameters given (`m = self.matrices(x)`, the same bits): a caller
    /// that integrates many periods with the same parameters forms them
    /// once. Only the attitude is integrated (the RK4 step of
    /// [`Layout::propagate`], without the Jacobians, the midpoint node or
    /// the noise map, which a state alone does not need). `None` at gimbal
    /// lock or for a non-finite attitude.
    pub fn propagate_state_with<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        x: &SVector<T, N>,
        period: &Period<T>,
    ) -> Option<SVector<T, N>> {
        let (end, _) = self.rk4_end(env, m, &self.attitude(x), period)?;
        if !end.iter().all(|v| v.is_finite()) {
            return None;
        }
        let mut out = *x;
        put3(&mut out, ATT, &end);
        Some(out)
    }

    /// [`Layout::propagate_state_with`] of an f64 state whose attitude's
    /// increments over the period are evaluated in precision `J`, on the
    /// environment `env_j`, matrices `m_j` and period `period_j` in `J`
    /// (the attitude itself stays f64; as the filter propagates it,
    /// [`Layout::propagate_into_jacobians_in`]). For `J = f64` the same
    /// bits as [`Layout::propagate_state_with`]; for `J = f32` the
    /// estimator's back-propagation on an FPU without f64 (the Cortex-M4F,
    /// where each period of it in emulated f64 cost more than a filter
    /// step: 0.3 M instructions, 4.9 G of the full M2-ps model's `Finish`).
    pub fn propagate_state_in<J: RealField + Copy, const N: usize>(
        &self,
        env_j: &Environment<J>,
        m_j: &InstallationMatrices<J>,
        x: &SVector<f64, N>,
        period_j: &Period<J>,
    ) -> Option<SVector<f64, N>> {
        let (end, _) = self.rk4_end(env_j, m_j, &self.attitude(x), period_j)?;
        if !end.iter().all(|v| v.is_finite()) {
            return None;
        }
        let mut out = *x;
        put3(&mut out, ATT, &end);
        Some(out)
    }
}

/// `x` (precision `P`) in precision `J`, through f64: exact between f32 and
/// f64 either way (rounded from f64 to f32). `None` if `x` has no f64 value.
fn scalar_in<P: RealField + Copy, J: RealField + Copy>(x: P) -> Option<J> {
    x.to_subset().map(|v: f64| J::from_subset(&v))
}

/// [`scalar_in`] of each component.
fn vector_in<P: RealField + Copy, J: RealField + Copy>(v: &Vector3<P>) -> Option<Vector3<J>> {
    Some(Vector3::new(
        scalar_in(v.x)?,
        scalar_in(v.y)?,
        scalar_in(v.z)?,
    ))
}
