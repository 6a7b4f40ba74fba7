//! Gimbal kinematics: the elementary rotations, the gimbal (Euler) angles'
//! DCM, rate matrix and their derivatives, and the angles of a DCM
//! (docs/model.md §Frames).

use super::*;

/// An elementary rotation and its first two derivatives with respect to
/// its angle: `(R, R′, R″)` with `R = P + cos a · C + sin a · S`.
pub(super) fn elementary<T: RealField + Copy>(
    axis: usize,
    a: T,
) -> (Matrix3<T>, Matrix3<T>, Matrix3<T>) {
    let (s, c) = sin_cos(a);
    let (o, z) = (T::one(), T::zero());
    // (P, C, S) of R1, R2, R3 (see r1, r2, r3).
    let (p, cm, sm) = match axis {
        0 => (
            Matrix3::new(o, z, z, z, z, z, z, z, z),
            Matrix3::new(z, z, z, z, o, z, z, z, o),
            Matrix3::new(z, z, z, z, z, o, z, -o, z),
        ),
        1 => (
            Matrix3::new(z, z, z, z, o, z, z, z, z),
            Matrix3::new(o, z, z, z, z, z, z, z, o),
            Matrix3::new(z, z, -o, z, z, z, o, z, z),
        ),
        _ => (
            Matrix3::new(z, z, z, z, z, z, z, z, o),
            Matrix3::new(o, z, z, z, o, z, z, z, z),
            Matrix3::new(z, o, z, -o, z, z, z, z, z),
        ),
    };
    (p + cm * c + sm * s, sm * c - cm * s, -(cm * c) - sm * s)
}

/// The partial derivatives of the Euler DCM `C(θ) = R3(γ) R2(β) R1(α)`
/// ([`gimbal_dcm`]) with respect to `θ = (α, β, γ)` (rad).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GimbalDcmPartials<T: RealField + Copy> {
    /// `C(θ)`.
    pub c: Matrix3<T>,
    /// `∂C/∂θ_k`.
    pub d: [Matrix3<T>; 3],
    /// `∂²C/∂θ_k ∂θ_l` (symmetric in `k`, `l`).
    pub d2: [[Matrix3<T>; 3]; 3],
}

/// [`GimbalDcmPartials`] of the Euler angles `gimbal_angles` (rad).
pub fn gimbal_dcm_partials<T: RealField + Copy>(
    gimbal_angles: &Vector3<T>,
) -> GimbalDcmPartials<T> {
    let (a, da, dda) = elementary(0, gimbal_angles.x);
    let (b, db, ddb) = elementary(1, gimbal_angles.y);
    let (g, dg, ddg) = elementary(2, gimbal_angles.z);
    let ab = g * db * da;
    let ag = dg * b * da;
    let bg = dg * db * a;
    GimbalDcmPartials {
        c: g * b * a,
        d: [g * b * da, g * db * a, dg * b * a],
        d2: [
            [g * b * dda, ab, ag],
            [ab, g * ddb * a, bg],
            [ag, bg, ddg * b * a],
        ],
    }
}

/// Passive rotation about x by `a` (rad): `[[1,0,0],[0,c,s],[0,−s,c]]`.
pub fn r1<T: RealField + Copy>(a: T) -> Matrix3<T> {
    let (s, c) = sin_cos(a);
    r1_sc(s, c)
}

/// Passive rotation about y by `a` (rad): `[[c,0,−s],[0,1,0],[s,0,c]]`.
pub fn r2<T: RealField + Copy>(a: T) -> Matrix3<T> {
    let (s, c) = sin_cos(a);
    r2_sc(s, c)
}

/// Passive rotation about z by `a` (rad): `[[c,s,0],[−s,c,0],[0,0,1]]`.
pub fn r3<T: RealField + Copy>(a: T) -> Matrix3<T> {
    let (s, c) = sin_cos(a);
    r3_sc(s, c)
}

/// [`r1`] from the sine and cosine of its angle.
pub(super) fn r1_sc<T: RealField + Copy>(s: T, c: T) -> Matrix3<T> {
    let (o, z) = (T::one(), T::zero());
    Matrix3::new(o, z, z, z, c, s, z, -s, c)
}

/// [`r2`] from the sine and cosine of its angle.
pub(super) fn r2_sc<T: RealField + Copy>(s: T, c: T) -> Matrix3<T> {
    let (o, z) = (T::one(), T::zero());
    Matrix3::new(c, z, -s, z, o, z, s, z, c)
}

/// [`r3`] from the sine and cosine of its angle.
pub(super) fn r3_sc<T: RealField + Copy>(s: T, c: T) -> Matrix3<T> {
    let (o, z) = (T::one(), T::zero());
    Matrix3::new(c, s, z, -s, c, z, z, z, o)
}

/// The sines and cosines of the Euler angles `θA = (α, β, γ)` (rad; the
/// gimbal angles of M2/M3, the attitude `θp` of M4), from which every
/// Euler-angle function of one attitude is built: one evaluation of the
/// trigonometry per attitude, however many of [`gimbal_dcm`],
/// [`gimbal_rate_matrix`], [`gimbal_rate_inverse`] and their derivatives a
/// model needs there (each gives the same floating-point result as the
/// free function).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EulerTrig<T: RealField + Copy> {
    /// `(sin α, cos α)`.
    pub alpha: (T, T),
    /// `(sin β, cos β)`.
    pub beta: (T, T),
    /// `(sin γ, cos γ)`.
    pub gamma: (T, T),
}

/// `(sin(a + δ) − sin a, cos(a + δ) − cos a)` from `(sin a, cos a)` by
/// the angle-sum formulas, `sin δ` and `cos δ − 1` from their Taylor series
/// (`|δ| ≤ 0.05` rad, truncation < 1e-17), formed without `sin a`, `cos a`
/// themselves: they keep their relative precision however small `δ` is.
pub(super) fn angle_sum_increments<T: RealField + Copy>(s: T, c: T, d: T) -> (T, T) {
    let d2 = d * d;
    let k = |v: f64| -> T { nalgebra::convert(v) };
    // sin δ = δ(1 − δ²/6 + δ⁴/120 − δ⁶/5040), cos δ − 1 = −δ²/2 + δ⁴/24 − δ⁶/720 + δ⁸/40320;
    // up to |δ| = 4e-3 rad (a period's step on the paper's path) the
    // last terms are below 1e-20 and left out.
    let (sd, cd_1) = if d.abs() <= k(4e-3) {
        (
            d * (T::one() - d2 * (k(1.0 / 6.0) - d2 * k(1.0 / 120.0))),
            -d2 * (k(0.5) - d2 * (k(1.0 / 24.0) - d2 * k(1.0 / 720.0))),
        )
    } else {
        (
            d * (T::one() - d2 * (k(1.0 / 6.0) - d2 * (k(1.0 / 120.0) - d2 * k(1.0 / 5040.0)))),
            -d2 * (k(0.5) - d2 * (k(1.0 / 24.0) - d2 * (k(1.0 / 720.0) - d2 * k(1.0 / 40_320.0)))),
        )
    };
    (s * cd_1 + c * sd, c * cd_1 - s * sd)
}

impl EulerTrig<f64> {
    /// [`EulerTrig::advanced_by`] for a filter that computes in precision
    /// `J` (f32 on an FPU without double precision, where f64 is emulated):
    /// where `|δ| ≤ 4e-3` rad (a period's step on the paper's path) the
    /// increments `sin(a + δ) − sin a`, `cos(a + δ) − cos a` are formed in
    /// `J` and added to the f64 sines and cosines (≤ 3 ε_J |δ|: 7.2e-10 in
    /// f32, the rounding of `sin a`, `cos a`, `sin δ` and the products);
    /// elsewhere, and for `J = f64`, it is `advanced_by`.
    pub fn advanced_in<J: RealField + Copy>(
        &self,
        angles: &Vector3<f64>,
        delta: &Vector3<f64>,
    ) -> Self {
        if TypeId::of::<J>() == TypeId::of::<f64>() || delta.amax() > 4e-3 {
            return self.advanced_by(angles, delta);
        }
        let step = |(s, c): (f64, f64), d: f64| -> (f64, f64) {
            let j = nalgebra::convert::<f64, J>;
            let (ds, dc) = angle_sum_increments(j(s), j(c), j(d));
            (s + scalar_to_f64(ds), c + scalar_to_f64(dc))
        };
        Self {
            alpha: step(self.alpha, delta.x),
            beta: step(self.beta, delta.y),
            gamma: step(self.gamma, delta.z),
        }
    }
}

impl<T: RealField + Copy> EulerTrig<T> {
    /// The trigonometry of the Euler angles `angles = (α, β, γ)` (rad).
    pub fn new(angles: &Vector3<T>) -> Self {
        Self {
            alpha: sin_cos(angles.x),
            beta: sin_cos(angles.y),
            gamma: sin_cos(angles.z),
        }
    }

    /// The trigonometry of `angles + delta` (rad) from this one, the
    /// trigonometry of `angles`: by the angle-sum formulas with `sin δ`,
    /// `cos δ` from their Taylor series where `|δ| ≤ 0.05` rad (truncation
    /// < 1e-17; the result is within a few ulp of [`EulerTrig::new`]), and
    /// by [`EulerTrig::new`]'s sine and cosine elsewhere. A period's nodes
    /// are a few mrad apart, and on an FPU without double precision a
    /// sine-cosine pair in f64 is a library call of many emulated
    /// operations, the series ≈ 15 (on the M4F the f32 filter's linearised
    /// M2-ps period fell by 8 k instructions, BENCHMARKS.md).
    pub fn advanced_by(&self, angles: &Vector3<T>, delta: &Vector3<T>) -> Self {
        let step = |(s, c): (T, T), a: T, d: T| -> (T, T) {
            if d.abs() > nalgebra::convert(0.05) {
                return sin_cos(a + d);
            }
            let (ds, dc) = angle_sum_increments(s, c, d);
            (s + ds, c + dc)
        };
        Self {
            alpha: step(self.alpha, angles.x, delta.x),
            beta: step(self.beta, angles.y, delta.y),
            gamma: step(self.gamma, angles.z, delta.z),
        }
    }

    /// The trigonometry of `β` and `γ` alone (rad), for the functions that
    /// do not depend on `α` (`α` is taken as 0, without evaluating it).
    fn of_beta_gamma(beta: T, gamma: T) -> Self {
        Self {
            alpha: (T::zero(), T::one()),
            beta: sin_cos(beta),
            gamma: sin_cos(gamma),
        }
    }

    /// `C = R3(γ) R2(β) R1(α)` ([`gimbal_dcm`]).
    ///
    /// Written out: the same floating-point values as the product
    /// `r3 · r2 · r1` of the three elementary rotations (its zero terms left
    /// out, its sums in the product's order), without two 3×3 products.
    pub fn dcm(&self) -> Matrix3<T> {
        let (sa, ca) = self.alpha;
        let (sb, cb) = self.beta;
        let (sg, cg) = self.gamma;
        // R3(γ) R2(β): [[cγ cβ, sγ, −cγ sβ], [−sγ cβ, cγ, sγ sβ], [sβ, 0, cβ]].
        let (cg_sb, sg_sb) = (cg * sb, sg * sb);
        Matrix3::new(
            cg * cb,
            sg * ca + cg_sb * sa,
            sg * sa - cg_sb * ca,
            -(sg * cb),
            cg * ca - sg_sb * sa,
            cg * sa + sg_sb * ca,
            sb,
            -(cb * sa),
            cb * ca,
        )
    }

    /// `C v` for `C` = [`EulerTrig::dcm`]: `R3(γ) (R2(β) (R1(α) v))`, the
    /// three elementary rotations applied in turn (18 operations, where
    /// forming `C` and the product take 31; equal to `dcm() * v` to
    /// rounding).
    pub fn rotate(&self, v: &Vector3<T>) -> Vector3<T> {
        let (sa, ca) = self.alpha;
        let (sb, cb) = self.beta;
        let (sg, cg) = self.gamma;
        let (y1, z1) = (ca * v.y + sa * v.z, ca * v.z - sa * v.y);
        let (x2, z2) = (cb * v.x - sb * z1, sb * v.x + cb * z1);
        Vector3::new(cg * x2 + sg * y1, cg * y1 - sg * x2, z2)
    }

    /// `M(β, γ)` ([`gimbal_rate_matrix`]).
    pub fn rate_matrix(&self) -> Matrix3<T> {
        let (sb, cb) = self.beta;
        let (sg, cg) = self.gamma;
        let z = T::zero();
        Matrix3::new(cb * cg, sg, z, -cb * sg, cg, z, sb, z, T::one())
    }

    /// `T(β, γ) = M⁻¹` ([`gimbal_rate_inverse`]); `None` within `1e-9` of
    /// the gimbal lock `β = ±90°`.
    pub fn rate_inverse(&self) -> Option<Matrix3<T>> {
        let (sb, cb) = self.beta;
        if cb.abs() < nalgebra::convert(1e-9) {
            return None;
        }
        let (sg, cg) = self.gamma;
        let z = T::zero();
        Some(Matrix3::new(
            cg / cb,
            -sg / cb,
            z,
            sg,
            cg,
            z,
            -sb * cg / cb,
            sb * sg / cb,
            T::one(),
        ))
    }

    /// `∂(T w)/∂θA` for the rate inverse `t` = [`EulerTrig::rate_inverse`]
    /// ([`d_gimbal_rate_inverse_times`]).
    pub fn d_rate_inverse_times(&self, t: &Matrix3<T>, w: &Vector3<T>) -> Matrix3<T> {
        let (sb, cb) = self.beta;
        let (sg, cg) = self.gamma;
        let z = T::zero();
        let tw = t * w;
        let dm_dbeta = Matrix3::new(-sb * cg, z, z, sb * sg, z, z, cb, z, z);
        let dm_dgamma = Matrix3::new(-cb * sg, cg, z, -cb * cg, -sg, z, z, z, z);
        let col_b = -(t * (dm_dbeta * tw));
        let col_g = -(t * (dm_dgamma * tw));
        Matrix3::from_columns(&[Vector3::zeros(), col_b, col_g])
    }

    /// `∂(C v)/∂θ = [(C v)×] M(β, γ)` for `c` = [`EulerTrig::dcm`]
    /// ([`d_gimbal_dcm_times`]).
    pub fn d_dcm_times(&self, c: &Matrix3<T>, v: &Vector3<T>) -> Matrix3<T> {
        skew(&(c * v)) * self.rate_matrix()
    }
}

/// Gimbal DCM `C^p_r = R3(γ) R2(β) R1(α)` of the gimbal angles
/// `θA = (α, β, γ)` (rad): outer gimbal about base x, middle about y, inner
/// about z. The same Euler sequence parameterises the attitude `θp` of M4.
///
/// # Examples
///
/// ```
/// use nalgebra::Vector3;
/// use rollcal::geometry::{euler_angles, gimbal_dcm, r1, r2, r3};
///
/// // Outer gimbal α about x, middle β about y, inner γ about z.
/// let angles = Vector3::new(10f64, -25.0, 40.0).map(f64::to_radians);
/// let c_pr = gimbal_dcm(&angles);
/// let product = r3(angles.z) * r2(angles.y) * r1(angles.x);
/// assert!((c_pr - product).norm() < 1e-15);
/// // Away from β = ±90° the angles come back from the DCM.
/// assert!((euler_angles(&c_pr) - angles).norm() < 1e-14);
/// ```
pub fn gimbal_dcm<T: RealField + Copy>(gimbal_angles: &Vector3<T>) -> Matrix3<T> {
    EulerTrig::new(gimbal_angles).dcm()
}

/// `M(β, γ)`: the gimbal-rate matrix, `ω^p_rp = M θ̇A`.
pub fn gimbal_rate_matrix<T: RealField + Copy>(beta: T, gamma: T) -> Matrix3<T> {
    EulerTrig::of_beta_gamma(beta, gamma).rate_matrix()
}

/// `T(β, γ) = M⁻¹`: the map from the platform rate to the gimbal-angle rates,
/// `θ̇A = T ω^p_rp`. `None` within `1e-9` of the gimbal lock `β = ±90°`.
///
/// # Examples
///
/// ```
/// use nalgebra::Matrix3;
/// use rollcal::geometry::{gimbal_rate_inverse, gimbal_rate_matrix};
///
/// let (beta, gamma) = (0.4, -1.1);
/// let t = gimbal_rate_inverse(beta, gamma).unwrap();
/// assert!((t * gimbal_rate_matrix(beta, gamma) - Matrix3::identity()).norm() < 1e-14);
/// // At the gimbal lock the gimbal-angle rates are not defined.
/// assert!(gimbal_rate_inverse(core::f64::consts::FRAC_PI_2, gamma).is_none());
/// ```
pub fn gimbal_rate_inverse<T: RealField + Copy>(beta: T, gamma: T) -> Option<Matrix3<T>> {
    EulerTrig::of_beta_gamma(beta, gamma).rate_inverse()
}

/// `∂(T(β, γ) w)/∂θA` for a fixed vector `w` (column α is zero):
/// `∂(T w) = −T (∂M) T w`.
pub fn d_gimbal_rate_inverse_times<T: RealField + Copy>(
    t: &Matrix3<T>,
    beta: T,
    gamma: T,
    w: &Vector3<T>,
) -> Matrix3<T> {
    EulerTrig::of_beta_gamma(beta, gamma).d_rate_inverse_times(t, w)
}

/// `∂(C(θ) v)/∂θ = [(C v)×] M(β, γ)` for the Euler DCM `C = ` [`gimbal_dcm`]`(θ)`.
pub fn d_gimbal_dcm_times<T: RealField + Copy>(
    gimbal_angles: &Vector3<T>,
    v: &Vector3<T>,
) -> Matrix3<T> {
    let trig = EulerTrig::new(gimbal_angles);
    trig.d_dcm_times(&trig.dcm(), v)
}

/// Euler angles `(α, β, γ)` (rad) of `C = R3(γ) R2(β) R1(α)`:
/// `β = asin(C[2][0])`, `α = atan2(−C[2][1], C[2][2])`,
/// `γ = atan2(−C[1][0], C[0][0])`. Exact away from `β = ±90°`.
pub fn euler_angles<T: RealField + Copy>(c: &Matrix3<T>) -> Vector3<T> {
    let beta = c.m31.clamp(-T::one(), T::one()).asin();
    let alpha = (-c.m32).atan2(c.m33);
    let gamma = (-c.m21).atan2(c.m11);
    Vector3::new(alpha, beta, gamma)
}
