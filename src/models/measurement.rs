//! The accelerometer measurement at one instant and its Jacobian
//! (docs/model.md §Configurations, §Installation models):
//! `Z_a = A C^p_n f^n`, with the platform attitude `C^p_n = R(ψ) C^c_n`
//! (M1), `C^p_r(θA) R(λ)` (M2, M3) or `C^p_r(θp)` (M4). The mean over a
//! period is in `period_mean`.
//!
//! The full model ([`ErrorModel::Full`], docs/model.md §Instrument errors)
//! reads `Z_a = ba + (I + K_a) u + K2 (u ∘ u)`, `u = A C^p_n f^n`; an
//! installation-only layout evaluates exactly the operations it did before
//! the full model existed.

use nalgebra::{Matrix3, RealField, SMatrix, Vector3};

use super::blocks::{scale_rows, set_cols};
use super::error_model::ErrorModel;
use super::installation::InstallationMatrices;
use super::layout::{AttitudeKind, Layout, ATT};
use super::Environment;
use crate::geometry::{d_lower_times, dcm, gimbal_dcm, right_jacobian, skew, EulerTrig};

impl Layout {
    /// The platform attitude `C^p_n` of attitude states `att` (rad), given
    /// the computed frame `c_cn` (used by M1 only) and `C^r_n` (M2/M3).
    pub fn platform_dcm<T: RealField + Copy>(
        &self,
        att: &Vector3<T>,
        c_rn: &Matrix3<T>,
        c_cn: &Matrix3<T>,
    ) -> Matrix3<T> {
        match self.attitude {
            AttitudeKind::Misalignment => dcm(att) * c_cn,
            AttitudeKind::Gimbal => gimbal_dcm(att) * c_rn,
            AttitudeKind::Attitude => gimbal_dcm(att),
        }
    }

    /// The accelerometer output `Z_a = A C^p_n f^n` (g) at one instant;
    /// for the full model `ba + (I + K_a) u + K2 (u ∘ u)`,
    /// `u = A C^p_n f^n`, with the instrument errors of
    /// `m.params.instruments`.
    pub fn accel_output<T: RealField + Copy>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
    ) -> Vector3<T> {
        let af = m.a * (self.platform_dcm(att, &m.c_rn, c_cn) * env.gravity_n);
        self.accel_errors(m, &af)
    }

    /// The accelerometer output of the installed specific force `af`
    /// (`u = A f^p`, g): `af` itself for an installation-only layout,
    /// `ba + (I + K_a) u + K2 (u ∘ u)` for the full model (g).
    pub fn accel_errors<T: RealField + Copy>(
        &self,
        m: &InstallationMatrices<T>,
        af: &Vector3<T>,
    ) -> Vector3<T> {
        match self.errors {
            ErrorModel::Installation => *af,
            ErrorModel::Full => m.params.instruments.accel(af),
        }
    }

    /// `∂Z_a/∂x` (3×N) at one instant.
    pub fn accel_jacobian<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
    ) -> SMatrix<T, 3, N> {
        self.accel_output_and_jacobian(env, m, att, c_cn).1
    }

    /// [`Layout::accel_output`] and [`Layout::accel_jacobian`] together,
    /// on one evaluation of the attitude's rotation (the same values as
    /// the two apart).
    pub fn accel_output_and_jacobian<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
    ) -> (Vector3<T>, SMatrix<T, 3, N>) {
        let mut h = SMatrix::<T, 3, N>::zeros();
        let z = self.accel_output_and_jacobian_into(env, m, att, c_cn, &mut h);
        (z, h)
    }

    /// [`Layout::accel_output_and_jacobian`] with the Jacobian written into
    /// `h` (every entry): no 3×N copy of it where the caller keeps it.
    ///
    /// For the full model the installation columns are multiplied by
    /// `I + K_a + 2 K2 diag(u)` (`u = A f^p`), `∂Z/∂ba = ∂Z/∂δ_a = ∂Z/∂w_a = I`,
    /// `∂Z/∂ka = diag(u)` and `∂Z/∂k2 = diag(u ∘ u)`; the gyro errors'
    /// columns are zero.
    // Out of line: inlined into `mean_accel`'s loop over the nodes, LLVM
    // unrolled the lot into a 1.5 KB frame of spilled addresses (the M4F's
    // linearised M1-pa period went from 42 k to 93 k instructions).
    #[inline(never)]
    pub fn accel_output_and_jacobian_into<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
        h: &mut SMatrix<T, 3, N>,
    ) -> Vector3<T> {
        h.fill(T::zero());
        let g = &env.gravity_n;
        // The attitude's rotation (R(ψ) or C(θ)) and ∂(C^p_n f^n)/∂att.
        let (rot, d_att) = match self.attitude {
            AttitudeKind::Misalignment => {
                let rot = dcm(att);
                (rot, skew(&(rot * (c_cn * g))) * right_jacobian(att))
            }
            AttitudeKind::Gimbal => {
                let trig = EulerTrig::new(att);
                let c = trig.dcm();
                (c, trig.d_dcm_times(&c, &(m.c_rn * g)))
            }
            AttitudeKind::Attitude => {
                let trig = EulerTrig::new(att);
                let c = trig.dcm();
                (c, trig.d_dcm_times(&c, g))
            }
        };
        let c_pn = match self.attitude {
            AttitudeKind::Misalignment => rot * c_cn,
            AttitudeKind::Gimbal => rot * m.c_rn,
            AttitudeKind::Attitude => rot,
        };
        let f_p = c_pn * g;
        set_cols(h, ATT, &(m.a * d_att));
        let f_a = m.r_a_c * f_p;
        if let Some(ic) = self.ac() {
            // ∂(R(−θ) v)/∂θ = −∂(R(φ) v)/∂φ at φ = −θ.
            set_cols(
                h,
                ic,
                &(-(m.unit_a_t
                    * InstallationMatrices::d_rotation_times(&m.r_a_c, &m.jr_a_c, &f_p))),
            );
        }
        set_cols(h, self.at(), &d_lower_times(&f_a));
        if let (Some(il), AttitudeKind::Gimbal) = (self.lam(), self.attitude) {
            let d_lam = m.a
                * rot
                * InstallationMatrices::d_rotation_times(&m.c_rn, &m.jr_lambda, &env.gravity_n);
            set_cols(h, il, &d_lam);
        }
        let af = m.a * f_p;
        if let (Some(n_inst), Some(iba), Some(ika), Some(ik2), Some(iba_gm), Some(iba_wu)) = (
            self.instruments(),
            self.ba(),
            self.ka(),
            self.k2(),
            self.ba_gm(),
            self.ba_wu(),
        ) {
            let e = &m.params.instruments;
            let two: T = nalgebra::convert(2.0);
            let slope = Vector3::repeat(T::one()) + e.ka + e.k2.component_mul(&af) * two;
            scale_rows(h, n_inst, &slope);
            set_cols(h, iba, &Matrix3::identity());
            set_cols(h, ika, &Matrix3::from_diagonal(&af));
            set_cols(h, ik2, &Matrix3::from_diagonal(&af.component_mul(&af)));
            set_cols(h, iba_gm, &Matrix3::identity());
            set_cols(h, iba_wu, &Matrix3::identity());
        }
        self.accel_errors(m, &af)
    }
}
