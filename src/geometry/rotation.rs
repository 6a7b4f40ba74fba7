//! Rotations: the DCM of a rotation vector and its inverse, quaternions,
//! the right Jacobian and the derivatives of the DCM (docs/model.md
//! §Notation), the small-angle parts a single-precision filter forms
//! without the large quantity they are added to.

use super::*;

/// `R(θ) = exp(−[θ×])` (Rodrigues): the DCM of a frame rotated by the
/// rotation vector `θ` (rad) with respect to the reference frame.
///
/// # Examples
///
/// ```
/// use nalgebra::Vector3;
/// use rollcal::geometry::{dcm, r3};
///
/// // A rotation of 30° about z is the passive elementary rotation R3(30°):
/// // the z axis stays, the x axis of the reference frame has the
/// // coordinates (cos 30°, −sin 30°, 0) in the rotated frame.
/// let a = 30f64.to_radians();
/// let c = dcm(&(Vector3::z() * a));
/// assert!((c - r3(a)).norm() < 1e-15);
/// assert!((c * Vector3::x() - Vector3::new(a.cos(), -a.sin(), 0.0)).norm() < 1e-15);
/// // To first order R(θ) = I − [θ×].
/// let small = Vector3::new(1e-6, -2e-6, 3e-6);
/// let first_order = nalgebra::Matrix3::identity() - rollcal::geometry::skew(&small);
/// assert!((dcm(&small) - first_order).norm() < 1e-11);
/// ```
pub fn dcm<T: RealField + Copy>(theta: &Vector3<T>) -> Matrix3<T> {
    RotationCoefficients::new(theta.norm_squared()).dcm(theta)
}

/// [`dcm`] and [`right_jacobian`] of one rotation vector `θ` (rad) on one
/// evaluation of their coefficients (`sin x / x`, `(1 − cos x)/x²`,
/// `(x − sin x)/x³` of `x = |θ|`; the same values as the two functions
/// apart).
pub fn dcm_and_right_jacobian<T: RealField + Copy>(theta: &Vector3<T>) -> (Matrix3<T>, Matrix3<T>) {
    let k = RotationCoefficients::new(theta.norm_squared());
    (k.dcm(theta), k.right_jacobian(theta))
}

/// The coefficients of the rotation functions of a rotation vector of
/// angle `x = |θ|` (rad): `sin x / x`, `(1 − cos x)/x²` and
/// `(x − sin x)/x³`, which [`dcm`] (`I − a[θ×] + b[θ×]²` with the first two)
/// and [`right_jacobian`] (with the last two) share.
///
/// Below `x² = 1e-8` from two terms of their Taylor series (truncation
/// < 1e-18); below `x² = 1e-2` (0.1 rad: the installation angles, a
/// period's commanded increment, M1's misalignment) from five, by Horner
/// (truncation < 3e-18, and no cancellation: `1 − cos x` and `x − sin x`
/// of x = 1.7e-3 rad lose 1e-10 of their value to it; and where f64 is
/// emulated, `sin` and `cos` are library calls of many emulated operations,
/// the series 15); above, from `sin x` and `cos x`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct RotationCoefficients<T> {
    /// `sin x / x`.
    pub(super) sinc: T,
    /// `(1 − cos x)/x²`.
    pub(super) cosc: T,
    /// `(x − sin x)/x³`.
    pub(super) sinc3: T,
}

impl<T: RealField + Copy> RotationCoefficients<T> {
    /// The coefficients of the angle whose square is `angle2` (rad²).
    pub(super) fn new(angle2: T) -> Self {
        let c = |v: f64| -> T { nalgebra::convert(v) };
        let y = angle2;
        if y < c(1e-8) {
            Self {
                sinc: T::one() - y / c(6.0),
                cosc: T::one() / c(2.0) - y / c(24.0),
                sinc3: T::one() / c(6.0) - y / c(120.0),
            }
        } else if y < c(1e-2) {
            // Σ (−y)ⁿ / (2n+1)!, Σ (−y)ⁿ / (2n+2)!, Σ (−y)ⁿ / (2n+3)!, n = 0..4.
            let horner =
                |k: [f64; 5]| c(k[0]) - y * (c(k[1]) - y * (c(k[2]) - y * (c(k[3]) - y * c(k[4]))));
            Self {
                sinc: horner([1.0, 1.0 / 6.0, 1.0 / 120.0, 1.0 / 5040.0, 1.0 / 362_880.0]),
                cosc: horner([
                    0.5,
                    1.0 / 24.0,
                    1.0 / 720.0,
                    1.0 / 40_320.0,
                    1.0 / 3_628_800.0,
                ]),
                sinc3: horner([
                    1.0 / 6.0,
                    1.0 / 120.0,
                    1.0 / 5040.0,
                    1.0 / 362_880.0,
                    1.0 / 39_916_800.0,
                ]),
            }
        } else {
            let x = y.sqrt();
            let (s, co) = (sin(x), cos(x));
            Self {
                sinc: s / x,
                cosc: (T::one() - co) / y,
                sinc3: (x - s) / (y * x),
            }
        }
    }

    /// [`dcm`] of `theta` (whose coefficients these are).
    fn dcm(&self, theta: &Vector3<T>) -> Matrix3<T> {
        Matrix3::identity() - skew(theta) * self.sinc + skew_squared(theta) * self.cosc
    }

    /// [`right_jacobian`] of `theta` (whose coefficients these are).
    fn right_jacobian(&self, theta: &Vector3<T>) -> Matrix3<T> {
        Matrix3::identity() - skew(theta) * self.cosc + skew_squared(theta) * self.sinc3
    }

    /// [`dcm_deviation`] of `theta` (whose coefficients these are).
    fn dcm_deviation(&self, theta: &Vector3<T>) -> Matrix3<T> {
        skew_squared(theta) * self.cosc - skew(theta) * self.sinc
    }
}

/// `R(θ) − I = −a[θ×] + b[θ×]²` ([`dcm`] less the identity; `a = sin x / x`,
/// `b = (1 − cos x)/x²`, `x = |θ|`, θ in rad) formed without the identity,
/// so that every entry keeps its relative precision however small `θ`
/// is: `dcm(θ) − I` cancels on the diagonal (in f32, `1 − 1.4e-6` keeps
/// two digits). The single-precision filter forms a period's rotation
/// increments this way ([`crate::command::CommandFrame::period_in`]).
pub fn dcm_deviation<T: RealField + Copy>(theta: &Vector3<T>) -> Matrix3<T> {
    RotationCoefficients::new(theta.norm_squared()).dcm_deviation(theta)
}

/// `R(θ) c = c − a [θ×] c + b [θ×]² c` (`a = sin x / x`, `b = (1 − cos x)/x²`,
/// `x = |θ|`, θ in rad) for a filter that computes in precision `J` (f32
/// on an FPU without double precision, where f64 is emulated): the
/// first-order part `c − θ × c` (column by column) in f64, the rest,
/// `(1 − a) [θ×] c + b [θ×]² c` (≈ `x²/2 |c|`), in `J`, with
/// `1 − a = x² (x − sin x)/x³` formed without cancellation. Its error is
/// `ε_J x²/2 |c|` beside f64's rounding (in f32 1e-13 at the paper's
/// 0.1°/s over 1 s, `x = 1.75e-3`; 2e-13 at `x = 2.8e-3`), where `dcm(θ) * c` in emulated f64 costs
/// about 80 operations more. For `J = f64` it equals `dcm(θ) * c` to
/// rounding.
///
/// Also returns the turn `R(θ) c − c` in `J`, from the same two parts (the
/// first-order one rounded to `J` once): to `ε_J x |c|` (1e-10 at 0.1°/s
/// over 1 s in f32), which `R(θ) c − c` in `J` would lose to cancellation.
pub fn rotated_in<J: RealField + Copy>(
    theta: &Vector3<f64>,
    c: &Matrix3<f64>,
) -> (Matrix3<f64>, Matrix3<J>) {
    let first = columns(c).map(|c_j| theta.cross(&c_j));
    let theta_j: Vector3<J> = to_t(theta);
    let y = theta_j.norm_squared();
    let k = RotationCoefficients::new(y);
    let one_minus_a = y * k.sinc3;
    let first_j: [Vector3<J>; 3] = first.map(|f| to_t(&f));
    let rest_j = first_j.map(|f_j| f_j * one_minus_a + theta_j.cross(&f_j) * k.cosc);
    let [f0, f1, f2] = first;
    let [r0, r1, r2] = rest_j;
    let [g0, g1, g2] = first_j;
    let rest = Matrix3::from_columns(&[to_f64(&r0), to_f64(&r1), to_f64(&r2)]);
    let turn = Matrix3::from_columns(&[r0 - g0, r1 - g1, r2 - g2]);
    (c - Matrix3::from_columns(&[f0, f1, f2]) + rest, turn)
}

/// The columns of `m`.
pub(super) fn columns<T: RealField + Copy>(m: &Matrix3<T>) -> [Vector3<T>; 3] {
    [
        Vector3::new(m.m11, m.m21, m.m31),
        Vector3::new(m.m12, m.m22, m.m32),
        Vector3::new(m.m13, m.m23, m.m33),
    ]
}

/// `J_r(θ) v − v = −a (θ × v) + b (θ × (θ × v))` ([`right_jacobian_times`]
/// less `v`; `a = (1 − cos x)/x²`, `b = (x − sin x)/x³`, `x = |θ|`, θ in
/// rad), formed without `v`: it keeps its relative precision however small
/// it is beside `v`.
pub fn right_jacobian_deviation_times<T: RealField + Copy>(
    theta: &Vector3<T>,
    v: &Vector3<T>,
) -> Vector3<T> {
    let k = RotationCoefficients::new(theta.norm_squared());
    let tv = theta.cross(v);
    theta.cross(&tv) * k.sinc3 - tv * k.cosc
}

/// The inverse of [`dcm`]: the rotation vector `θ` (rad) with `R(θ) = c`,
/// `|θ| ≤ π`. `c` must be a proper rotation matrix.
///
/// # Examples
///
/// ```
/// use nalgebra::Vector3;
/// use rollcal::geometry::{dcm, rotation_vector};
///
/// let theta = Vector3::new(0.3, -1.2, 0.7); // rad, |θ| < π
/// assert!((rotation_vector(&dcm(&theta)) - theta).norm() < 1e-14);
/// ```
pub fn rotation_vector<T: RealField + Copy>(c: &Matrix3<T>) -> Vector3<T> {
    let two: T = nalgebra::convert(2.0);
    // R(θ) = exp(−[θ×]) ⇒ the antisymmetric part of c is −sin|θ| [θ̂×].
    let w = Vector3::new(c.m23 - c.m32, c.m31 - c.m13, c.m12 - c.m21) / two;
    let cos = ((c.m11 + c.m22 + c.m33 - T::one()) / two).clamp(-T::one(), T::one());
    let sin = w.norm();
    let angle = sin.atan2(cos);
    if sin < nalgebra::convert(1e-6) && cos > T::zero() {
        // θ ≈ w (1 + |w|²/6): series of angle/sin(angle).
        let six: T = nalgebra::convert(6.0);
        return w * (T::one() + sin * sin / six);
    }
    if sin < nalgebra::convert(1e-6) {
        // Near π: use the symmetric part, c + cᵀ = 2 I cos + 2(1−cos) θ̂θ̂ᵀ.
        let s = (c + c.transpose()) / two;
        let one_minus_cos = T::one() - cos;
        let diag = Vector3::new(s.m11 - cos, s.m22 - cos, s.m33 - cos) / one_minus_cos;
        let mut axis = if diag.x >= diag.y && diag.x >= diag.z {
            Vector3::new(diag.x, s.m12 / one_minus_cos, s.m13 / one_minus_cos)
        } else if diag.y >= diag.z {
            Vector3::new(s.m21 / one_minus_cos, diag.y, s.m23 / one_minus_cos)
        } else {
            Vector3::new(s.m31 / one_minus_cos, s.m32 / one_minus_cos, diag.z)
        };
        let n = axis.norm();
        if n > T::zero() {
            axis /= n;
        }
        // The sign is fixed by the (small) antisymmetric part where it exists.
        if axis.dot(&w) < T::zero() {
            axis = -axis;
        }
        return axis * angle;
    }
    w * (angle / sin)
}

/// The unit quaternion `[w, x, y, z]` of the DCM `c`: with `θ` the rotation
/// vector of `c` ([`rotation_vector`], `c = R(θ)`), `q = [cos(|θ|/2),
/// sin(|θ|/2) θ/|θ|]`. The wire carries the computed frame `C^c_n` this
/// way (`docs/wire.md`).
///
/// # Examples
///
/// ```
/// use nalgebra::Vector3;
/// use rollcal::geometry::{dcm, dcm_from_quaternion, quaternion_from_dcm};
///
/// let c = dcm(&Vector3::new(0.1, 0.2, -0.3));
/// let q = quaternion_from_dcm(&c);
/// let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
/// assert!((norm - 1.0).abs() < 1e-15);
/// let back = dcm_from_quaternion(&q, 1e-6).unwrap();
/// assert!((back - c).norm() < 1e-15);
/// // A quaternion far from unit length is refused.
/// assert!(dcm_from_quaternion(&[2.0, 0.0, 0.0, 0.0], 1e-6).is_none());
/// ```
pub fn quaternion_from_dcm<T: RealField + Copy>(c: &Matrix3<T>) -> [T; 4] {
    let theta = rotation_vector(c);
    let half: T = nalgebra::convert(0.5);
    let angle = theta.norm();
    // sin(|θ|/2)/|θ|, with its series below 1e-4 rad (error < 1e-18).
    let k = if angle < nalgebra::convert(1e-4) {
        let forty_eight: T = nalgebra::convert(48.0);
        half - angle * angle / forty_eight
    } else {
        sin(angle * half) / angle
    };
    [cos(angle * half), theta.x * k, theta.y * k, theta.z * k]
}

/// The DCM `R(θ)` of the quaternion `q = [w, x, y, z]` (see
/// [`quaternion_from_dcm`]): `I − 2w[v×] + 2[v×]²` of `q/|q|`. `None` when
/// `q` is not finite or `| |q| − 1 |` exceeds `tolerance`.
pub fn dcm_from_quaternion<T: RealField + Copy>(q: &[T; 4], tolerance: T) -> Option<Matrix3<T>> {
    let [w, x, y, z] = *q;
    let norm = (w * w + x * x + y * y + z * z).sqrt();
    if !norm.is_finite() || (norm - T::one()).abs() > tolerance {
        return None;
    }
    let (w, v) = (w / norm, Vector3::new(x, y, z) / norm);
    let k = skew(&v);
    let two: T = nalgebra::convert(2.0);
    Some(Matrix3::identity() - k * (two * w) + skew_squared(&v) * two)
}

/// The angle (rad, in `[0, π]`) of the rotation from the DCM `b` to the DCM
/// `a`: `|θ|` of `R(θ) = a bᵀ`.
pub fn angle_between<T: RealField + Copy>(a: &Matrix3<T>, b: &Matrix3<T>) -> T {
    rotation_vector(&(a * b.transpose())).norm()
}

/// Right Jacobian of the rotation vector, `J_r(θ)`, for the convention
/// `R(θ) = exp(−[θ×])`: `R(θ + δ) ≈ (I − [(J_r(θ) δ)×]) R(θ)`.
pub fn right_jacobian<T: RealField + Copy>(theta: &Vector3<T>) -> Matrix3<T> {
    RotationCoefficients::new(theta.norm_squared()).right_jacobian(theta)
}

/// `J_r(θ) v` ([`right_jacobian`] times a vector `v`) without forming the
/// matrix: `v − a (θ × v) + b (θ × (θ × v))` with `a = (1 − cos x)/x²`,
/// `b = (x − sin x)/x³`, `x = |θ|` (equal to `right_jacobian(θ) * v` to
/// rounding).
pub fn right_jacobian_times<T: RealField + Copy>(theta: &Vector3<T>, v: &Vector3<T>) -> Vector3<T> {
    let k = RotationCoefficients::new(theta.norm_squared());
    let tv = theta.cross(v);
    v - tv * k.cosc + theta.cross(&tv) * k.sinc3
}

/// Inverse of [`right_jacobian`]: `J_r⁻¹(θ)`, the map from the angular rate
/// to the rotation-vector rate, `θ̇ = J_r⁻¹(θ) ω` (docs/model.md §Configurations, M1 dynamics).
pub fn right_jacobian_inv<T: RealField + Copy>(theta: &Vector3<T>) -> Matrix3<T> {
    let angle2 = theta.norm_squared();
    let k = skew(theta);
    let two: T = nalgebra::convert(2.0);
    let c = if angle2 < nalgebra::convert(1e-8) {
        let twelve: T = nalgebra::convert(12.0);
        let seven_twenty: T = nalgebra::convert(720.0);
        T::one() / twelve + angle2 / seven_twenty
    } else if angle2 < nalgebra::convert(1e-2) {
        // (1 − (x/2) cot(x/2))/x² = 1/12 + y/720 + y²/30240 + y³/1209600
        // + y⁴/47900160 + …, y = x² (truncation < 1e-19 below 0.1 rad; see
        // RotationCoefficients for why not sin and cos).
        let k = |v: f64| -> T { nalgebra::convert(v) };
        let y = angle2;
        k(1.0 / 12.0)
            + y * (k(1.0 / 720.0)
                + y * (k(1.0 / 30_240.0) + y * (k(1.0 / 1_209_600.0) + y * k(1.0 / 47_900_160.0))))
    } else {
        let angle = angle2.sqrt();
        T::one() / angle2 - (T::one() + cos(angle)) / (two * angle * sin(angle))
    };
    Matrix3::identity() + k / two + skew_squared(theta) * c
}

/// `∂(R(θ) v)/∂θ = [(R(θ) v)×] J_r(θ)`: Jacobian of a vector rotated by
/// [`dcm`] with respect to the rotation vector.
pub fn d_dcm_times<T: RealField + Copy>(theta: &Vector3<T>, v: &Vector3<T>) -> Matrix3<T> {
    skew(&(dcm(theta) * v)) * right_jacobian(theta)
}

/// `∂J_r(θ)/∂θ_k`, `k = 1, 2, 3` (exact; [`right_jacobian`]): with
/// `J_r = I − a K + b K²`, `K = [θ×]`, `x = |θ|`, `a = (1 − cos x)/x²`,
/// `b = (x − sin x)/x³`,
/// `∂J_r/∂θ_k = −(a′/x) θ_k K − a E_k + (b′/x) θ_k K² + b (E_k K + K E_k)`,
/// `E_k = [e_k×]`. `a′/x` and `b′/x` lose `1/x⁴` of their digits to
/// cancellation, so below `x = 0.1` rad they come from their series
/// (truncation < 3e-12 relative).
pub fn d_right_jacobian<T: RealField + Copy>(theta: &Vector3<T>) -> [Matrix3<T>; 3] {
    let x2 = theta.norm_squared();
    let k = skew(theta);
    let k2 = skew_squared(theta);
    let c = |v: f64| -> T { nalgebra::convert(v) };
    let (a, b, da, db) = if x2 < c(1e-2) {
        let x4 = x2 * x2;
        let x6 = x4 * x2;
        (
            c(0.5) - x2 / c(24.0) + x4 / c(720.0) - x6 / c(40_320.0),
            c(1.0 / 6.0) - x2 / c(120.0) + x4 / c(5040.0) - x6 / c(362_880.0),
            c(-1.0 / 12.0) + x2 / c(180.0) - x4 / c(6720.0),
            c(-1.0 / 60.0) + x2 / c(1260.0) - x4 / c(60_480.0),
        )
    } else {
        let x = x2.sqrt();
        let (s, co) = sin_cos(x);
        let x3 = x2 * x;
        let x4 = x2 * x2;
        let one_c = T::one() - co;
        let x_s = x - s;
        (
            one_c / x2,
            x_s / x3,
            s / x3 - c(2.0) * one_c / x4,
            one_c / x4 - c(3.0) * x_s / (x4 * x),
        )
    };
    let part = |tk: T, e: Vector3<T>| {
        let ek = skew(&e);
        -(k * (da * tk)) - ek * a + k2 * (db * tk) + (ek * k + k * ek) * b
    };
    [
        part(theta.x, Vector3::x()),
        part(theta.y, Vector3::y()),
        part(theta.z, Vector3::z()),
    ]
}

/// The second derivatives of a vector rotated by [`dcm`]: element `k` is
/// the 3×3 matrix whose column `l` is `∂²(R(θ) v)/∂θ_k ∂θ_l`, i.e.
/// `∂/∂θ_k` of [`d_dcm_times`] `= [(R v)×] J_r(θ)`:
/// `[(∂(R v)/∂θ_k)×] J_r + [(R v)×] ∂J_r/∂θ_k`.
pub fn d2_dcm_times<T: RealField + Copy>(theta: &Vector3<T>, v: &Vector3<T>) -> [Matrix3<T>; 3] {
    let rv = dcm(theta) * v;
    let jr = right_jacobian(theta);
    let srv = skew(&rv);
    let [c0, c1, c2] = (srv * jr).data.0;
    let [j0, j1, j2] = d_right_jacobian(theta);
    [
        skew(&c0.into()) * jr + srv * j0,
        skew(&c1.into()) * jr + srv * j1,
        skew(&c2.into()) * jr + srv * j2,
    ]
}
