//! The measurement over a period (docs/model.md §Measurement timing): the
//! accelerometers deliver the mean specific force over the period, modelled
//! by Simpson's rule over the three nodes of the period's propagation, with
//! its Jacobian with respect to the state at the end of the period and its
//! sensitivity to the platform-rate noise held over the period
//! ([`Layout::mean_accel`]); and the same mean alone in f64 for the
//! single-precision filter ([`Layout::mean_accel_output`]).

use nalgebra::{Const, Matrix, Matrix3, RealField, SMatrix, StorageMut, Vector3, U3};

use super::error_model::ErrorModel;
use super::installation::InstallationMatrices;
use super::instrument_errors::InstrumentErrors;
use super::layout::{AttitudeKind, Layout, ATT};
use super::propagation::PeriodPropagation;
use super::transition::{apply_transition_of, apply_transition_of_mean};
use super::Environment;
use crate::command::Period;
use crate::geometry::{dcm_deviation, EulerTrig};
use crate::precision::{to_f64, to_t};

impl Layout {
    /// The mean accelerometer output over the period (g) by Simpson's rule
    /// over the three nodes (error ≈ T⁴|h⁽⁴⁾|/2880 < 1e-15 g at 0.1°/s);
    /// its Jacobian with respect to the state at the END of the period,
    /// `∂h̄/∂x_{k+1} = Σ_j w_j H(t_j) Φ(t_j ← t_{k+1})`; and its sensitivity
    /// `D` (g per rad/s) to a platform-rate noise `w` held over the period
    /// *given* `x_{k+1}`: the noise moved the attitude by `B w (t − t_k)`
    /// while the model traces back from an end state that holds all of
    /// `B w T`, so `D = Σ_j w_j H_att(t_j) (t_j − t_{k+1}) B`.
    ///
    /// Returns the output and `D`; the Jacobian is written into `h` (3×N,
    /// e.g. the accelerometer rows of a measurement's Jacobian: no 3×N copy
    /// of it in the caller's frame).
    pub fn mean_accel<T: RealField + Copy, const N: usize, S: StorageMut<T, U3, Const<N>>>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        prop: &PeriodPropagation<T, N>,
        period: &Period<T>,
        h: &mut Matrix<T, U3, Const<N>, S>,
    ) -> (Vector3<T>, Matrix3<T>) {
        let six: T = nalgebra::convert(6.0);
        let four: T = nalgebra::convert(4.0);
        let half: T = nalgebra::convert(0.5);
        let weights = [T::one() / six, four / six, T::one() / six];
        let mut z = Vector3::zeros();
        h.fill(T::zero());
        let mut d = Matrix3::zeros();
        let back = [-period.dt, -period.dt * half, T::zero()];
        // F over [t_j, t_{k+1}]: the midpoint F for the whole period, the mean
        // of the midpoint and end F (centred at 3T/4) for its second half,
        // formed column by column (`apply_transition_of_mean`: no 3×N
        // matrix in this frame).
        let mut hj = SMatrix::<T, 3, N>::zeros();
        for (node, (((att, c_cn), w), tau)) in prop
            .att
            .iter()
            .zip(period.c_cn.iter())
            .zip(weights)
            .zip(back)
            .enumerate()
        {
            let zj = self.accel_output_and_jacobian_into(env, m, att, c_cn, &mut hj);
            z += zj * w;
            if tau != T::zero() {
                d += hj.fixed_columns::<3>(ATT) * prop.noise_map * (w * tau);
                if node == 0 {
                    apply_transition_of(&mut hj, &prop.f_mid, tau);
                } else {
                    apply_transition_of_mean(&mut hj, &prop.f_mid, &prop.f_end, tau);
                }
            }
            // The end node: Φ(t_{k+1} ← t_{k+1}) = I, and no noise
            // accumulated after it. In place (no 3×N temporaries).
            hj *= w;
            *h += &hj;
        }
        (z, d)
    }

    /// The mean accelerometer output over the period (g) alone, in f64, from
    /// the attitude `att` at the period's three nodes (rad,
    /// `PeriodPropagation::att`): the value of [`Layout::mean_accel`]
    /// without its Jacobians, for the filter that computes those in
    /// precision `J` (f32 on an FPU without double precision, where f64 is
    /// emulated). Simpson's rule is applied before `A`: `A Σ w_j R_j f_j`
    /// (one product by `A`, not three; `f_j` is `f^n` in the frame the
    /// attitude rotation acts on; `a` is `A`, `c_rn` is `C^r_n`,
    /// [`InstallationMatrices`]).
    ///
    /// - Misalignment (M1): the first node's `f_0 = C^c_n(t_k) f^n` in f64;
    ///   in `J` the later nodes' turn `(C_j − C_0) f^n` from the frame's
    ///   turn within the period `turn` (read by M1 only)
    ///   ([`PeriodIn::turn`](crate::command::PeriodIn::turn); `ε_J |uT| |f|`,
    ///   1.0e-10 g at the paper's 0.1°/s over 1 s in f32) and the small
    ///   rotation's share `(R(θ_j) − I) f_j`
    ///   ([`crate::geometry::dcm_deviation`]; `ε_J |θ| |f|`, e.g. 6e-11 g
    ///   for 1 mrad in f32).
    /// - Euler angles: the midpoint and end nodes' sines and cosines from
    ///   the first node's, their increments in `J`
    ///   ([`EulerTrig::advanced_in`]; ≤ 7.2e-10 in f32), the rest in f64.
    ///
    /// For the full model ([`ErrorModel::Full`]) the mean is
    /// `ba + (I + K_a) ū + K2 Σ w_j u_j ∘ u_j` with `u_j = A R_j f_j`,
    /// `ū = A Σ w_j R_j f_j` and `instruments`' `ba`, `ka`, `k2` (the
    /// second-order term's mean is the mean of the squares, node by node,
    /// in f64); an installation-only layout ignores `instruments`.
    ///
    /// For `J = f64` it equals `mean_accel`'s value to rounding.
    #[allow(clippy::too_many_arguments)]
    pub fn mean_accel_output<J: RealField + Copy>(
        &self,
        env: &Environment<f64>,
        a: &Matrix3<f64>,
        c_rn: &Matrix3<f64>,
        instruments: &InstrumentErrors<f64>,
        att: &[Vector3<f64>; 3],
        period: &Period<f64>,
        turn: &[Matrix3<J>; 2],
    ) -> Vector3<f64> {
        let weights = [1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0];
        let [att0, att_mid, att1] = att;
        let mut mean = Vector3::zeros();
        // Σ w_j u_j ∘ u_j of the full model (the installation layout never
        // forms it: its arithmetic stays what it was).
        let full = self.errors == ErrorModel::Full;
        let mut mean_sq = Vector3::<f64>::zeros();
        let mut square = |f_j: &Vector3<f64>, w: f64| {
            let u = a * f_j;
            mean_sq += u.component_mul(&u) * w;
        };
        match self.attitude {
            AttitudeKind::Misalignment => {
                // f_j = C_j f^n = f_0 + (C_j − C_0) f^n: f_0 in f64, the
                // later nodes' turn within the period (≤ |uT| |f|) in J.
                let [c0, _, _] = &period.c_cn;
                let f0 = c0 * env.gravity_n;
                let (f0_j, g_j): (Vector3<J>, Vector3<J>) = (to_t(&f0), to_t(&env.gravity_n));
                let [turn_mid, turn_end] = turn;
                let f_turns = [Vector3::zeros(), turn_mid * g_j, turn_end * g_j];
                let mut small = Vector3::<J>::zeros();
                for ((theta, f_turn), w) in att.iter().zip(f_turns).zip(weights) {
                    let node = f_turn + dcm_deviation(&to_t::<J, 3, 1>(theta)) * (f0_j + f_turn);
                    if full {
                        square(&(f0 + to_f64(&node)), w);
                    }
                    let w: J = nalgebra::convert(w);
                    small += node * w;
                }
                mean = f0 + to_f64(&small);
            }
            AttitudeKind::Gimbal | AttitudeKind::Attitude => {
                let f = match self.attitude {
                    AttitudeKind::Gimbal => c_rn * env.gravity_n,
                    _ => env.gravity_n,
                };
                let trig0 = EulerTrig::new(att0);
                let nodes = [
                    trig0,
                    trig0.advanced_in::<J>(att0, &(att_mid - att0)),
                    trig0.advanced_in::<J>(att0, &(att1 - att0)),
                ];
                for (trig, w) in nodes.iter().zip(weights) {
                    let f_j = trig.rotate(&f);
                    if full {
                        square(&f_j, w);
                    }
                    mean += f_j * w;
                }
            }
        }
        let af = a * mean;
        match self.errors {
            ErrorModel::Installation => af,
            ErrorModel::Full => instruments.accel_of_means(&af, &mean_sq),
        }
    }
}
