//! The accelerometer's specific force in platform axes before the
//! accelerometers' own installation errors, `q = C^p_n f^n` (`R(ψ) C^c_n f^n`
//! in M1, `C(θ) R(λ) f^n` in M2 and M3, `C(θp) f^n` in M4; docs/model.md
//! §Frames, §Configurations), with its first and second derivatives with respect to the attitude
//! and `λ` ([`Platform`]): the part of the Hessian that depends on the
//! configuration's attitude kind.

use nalgebra::{Matrix3, RealField, Vector3};

use crate::geometry::{d2_dcm_times, d_dcm_times, dcm, gimbal_dcm_partials};
use crate::models::{AttitudeKind, Environment, InstallationMatrices, Layout};

/// A 3×3 block of second derivatives of `h`: element `k` is the matrix
/// whose column `l` is `∂²h/∂x_{i+k} ∂x_{j+l}`.
pub(super) type Block<T> = [Matrix3<T>; 3];

/// `q` and its derivatives with respect to the attitude and `λ`.
pub(super) struct Platform<T: RealField + Copy> {
    pub(super) q: Vector3<T>,
    /// `∂q/∂att`, `∂q/∂λ`.
    pub(super) d_att: Matrix3<T>,
    pub(super) d_lam: Matrix3<T>,
    /// Second derivatives (see [`Block`]).
    pub(super) att_att: Block<T>,
    pub(super) att_lam: Block<T>,
    pub(super) lam_lam: Block<T>,
}

fn zero_block<T: RealField + Copy>() -> Block<T> {
    [Matrix3::zeros(); 3]
}

fn map_block<T: RealField + Copy>(b: &Block<T>, f: impl Fn(&Matrix3<T>) -> Matrix3<T>) -> Block<T> {
    let [b0, b1, b2] = b;
    [f(b0), f(b1), f(b2)]
}

impl<T: RealField + Copy> Platform<T> {
    /// `q` and its derivatives for `layout`'s attitude kind. Inlined, each
    /// kind out of line: with the layout a constant (the filter's) only its
    /// kind's code is linked, and the temporaries are not in the frame that
    /// keeps the result under the Hessians (firmware stack).
    #[inline(always)]
    pub(super) fn new(
        layout: &Layout,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
    ) -> Self {
        match layout.attitude {
            AttitudeKind::Misalignment => Self::misalignment(env, att, c_cn),
            AttitudeKind::Attitude => Self::gimbals(env, m, att, None),
            AttitudeKind::Gimbal => Self::gimbals(env, m, att, Some(layout.lam().is_some())),
        }
    }

    /// M1: `q = R(ψ) C^c_n f^n`.
    #[inline(never)]
    fn misalignment(env: &Environment<T>, att: &Vector3<T>, c_cn: &Matrix3<T>) -> Self {
        let w = c_cn * env.gravity_n;
        Self {
            q: dcm(att) * w,
            d_att: d_dcm_times(att, &w),
            d_lam: Matrix3::zeros(),
            att_att: d2_dcm_times(att, &w),
            att_lam: zero_block(),
            lam_lam: zero_block(),
        }
    }

    /// M2–M4: `q = C(θ) u`, `u = R(λ) f^n` when `gimbal` is `Some` (the
    /// gimbal angles are the attitude; `Some(true)`: `λ` is a state), else
    /// `u = f^n`.
    #[inline(never)]
    fn gimbals(
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        gimbal: Option<bool>,
    ) -> Self {
        let g = env.gravity_n;
        let e = gimbal_dcm_partials(att);
        let (u, base) = match gimbal {
            Some(lam) => (m.c_rn * g, lam),
            None => (g, false),
        };
        let [d0, d1, d2] = e.d;
        let [[a00, a01, a02], [_, a11, a12], [_, _, a22]] = e.d2;
        let d_att = Matrix3::from_columns(&[d0 * u, d1 * u, d2 * u]);
        let att_att = [
            Matrix3::from_columns(&[a00 * u, a01 * u, a02 * u]),
            Matrix3::from_columns(&[a01 * u, a11 * u, a12 * u]),
            Matrix3::from_columns(&[a02 * u, a12 * u, a22 * u]),
        ];
        let (d_lam, att_lam, lam_lam) = if base {
            let lam = &m.params.lambda;
            let d1_lam = InstallationMatrices::d_rotation_times(&m.c_rn, &m.jr_lambda, &g);
            (
                e.c * d1_lam,
                [d0 * d1_lam, d1 * d1_lam, d2 * d1_lam],
                map_block(&d2_dcm_times(lam, &g), |b| e.c * b),
            )
        } else {
            (Matrix3::zeros(), zero_block(), zero_block())
        };
        Self {
            q: e.c * u,
            d_att,
            d_lam,
            att_att,
            att_lam,
            lam_lam,
        }
    }
}
