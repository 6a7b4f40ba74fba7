//! Frames, rotations and gimbal kinematics (docs/model.md §Notation, §Frames).
//!
//! Every function here is pure and allocation-free. Angles are radians,
//! direction-cosine matrices (DCMs) follow the convention `C^b_a` = "from
//! frame a to frame b", and rotation vectors follow the paper's passive
//! convention `R(θ) = exp(−[θ×])`, so that `R(θ) ≈ I − [θ×]` to first order.

use core::any::TypeId;

use nalgebra::{Matrix3, RealField, Vector3};

use crate::precision::{scalar_to_f64, to_f64, to_t};
use crate::trig::{cos, sin, sin_cos};

/// `[v×]`: the skew-symmetric matrix with `[v×] w = v × w`.
///
/// # Examples
///
/// ```
/// use nalgebra::Vector3;
/// use rollcal::geometry::skew;
///
/// let (v, w) = (Vector3::new(1.0, 2.0, 3.0), Vector3::new(-0.5, 0.25, 2.0));
/// assert_eq!(skew(&v) * w, v.cross(&w));
/// ```
#[inline]
pub fn skew<T: RealField + Copy>(v: &Vector3<T>) -> Matrix3<T> {
    let z = T::zero();
    Matrix3::new(z, -v.z, v.y, v.z, z, -v.x, -v.y, v.x, z)
}

/// `[v×]²` (= `v vᵀ − |v|² I`), written out: the same floating-point values
/// as `skew(v) * skew(v)` (the product's zero terms left out, its sums in
/// the product's order) without a 3×3 product.
#[inline]
pub fn skew_squared<T: RealField + Copy>(v: &Vector3<T>) -> Matrix3<T> {
    let (x, y, z) = (v.x, v.y, v.z);
    let (xx, yy, zz) = (x * x, y * y, z * z);
    Matrix3::new(
        -zz - yy,
        y * x,
        z * x,
        x * y,
        -zz - xx,
        z * y,
        x * z,
        y * z,
        -yy - xx,
    )
}

/// `L(t)`: the strictly lower-triangular matrix `[[0,0,0],[t1,0,0],[t2,t3,0]]`
/// (the paper's `[θ]` of the non-orthogonality angles `θT`, docs/model.md
/// §Notation).
#[inline]
pub fn lower<T: RealField + Copy>(t: &Vector3<T>) -> Matrix3<T> {
    let z = T::zero();
    Matrix3::new(z, z, z, t.x, z, z, t.y, t.z, z)
}

/// `∂(L(t) v)/∂t`: the Jacobian of `L(t) v` with respect to `t` (exact: `L`
/// is linear in `t`).
#[inline]
pub fn d_lower_times<T: RealField + Copy>(v: &Vector3<T>) -> Matrix3<T> {
    let z = T::zero();
    Matrix3::new(z, z, z, v.x, z, z, z, v.x, v.y)
}

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
struct RotationCoefficients<T> {
    /// `sin x / x`.
    sinc: T,
    /// `(1 − cos x)/x²`.
    cosc: T,
    /// `(x − sin x)/x³`.
    sinc3: T,
}

impl<T: RealField + Copy> RotationCoefficients<T> {
    /// The coefficients of the angle whose square is `angle2` (rad²).
    fn new(angle2: T) -> Self {
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
fn columns<T: RealField + Copy>(m: &Matrix3<T>) -> [Vector3<T>; 3] {
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

/// An elementary rotation and its first two derivatives with respect to
/// its angle: `(R, R′, R″)` with `R = P + cos a · C + sin a · S`.
fn elementary<T: RealField + Copy>(axis: usize, a: T) -> (Matrix3<T>, Matrix3<T>, Matrix3<T>) {
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
fn r1_sc<T: RealField + Copy>(s: T, c: T) -> Matrix3<T> {
    let (o, z) = (T::one(), T::zero());
    Matrix3::new(o, z, z, z, c, s, z, -s, c)
}

/// [`r2`] from the sine and cosine of its angle.
fn r2_sc<T: RealField + Copy>(s: T, c: T) -> Matrix3<T> {
    let (o, z) = (T::one(), T::zero());
    Matrix3::new(c, z, -s, z, o, z, s, z, c)
}

/// [`r3`] from the sine and cosine of its angle.
fn r3_sc<T: RealField + Copy>(s: T, c: T) -> Matrix3<T> {
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
fn angle_sum_increments<T: RealField + Copy>(s: T, c: T, d: T) -> (T, T) {
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

/// Wraps an angle (rad) into `(−π, π]`. Non-finite input is returned as is.
///
/// # Examples
///
/// ```
/// use core::f64::consts::PI;
/// use rollcal::geometry::wrap_angle;
///
/// assert!((wrap_angle(1.5 * PI) + 0.5 * PI).abs() < 1e-15);
/// assert_eq!(wrap_angle(-PI), PI); // (−π, π]: −π becomes π
/// assert_eq!(wrap_angle(0.25), 0.25);
/// ```
pub fn wrap_angle<T: RealField + Copy>(a: T) -> T {
    let pi = T::pi();
    let two_pi = T::two_pi();
    if (a > -pi && a <= pi) || !a.is_finite() {
        return a;
    }
    let mut w = a - two_pi * ((a + pi) / two_pi).floor();
    // Now w ∈ [−π, π); move the closed end to +π.
    if w <= -pi {
        w += two_pi;
    }
    w
}

/// Wraps every component of a vector of angles (rad) into `(−π, π]`.
pub fn wrap_angles<T: RealField + Copy>(a: &Vector3<T>) -> Vector3<T> {
    a.map(wrap_angle)
}

/// The navigation-frame Earth rate `ω^n_ie = Ω [cos φ, sin φ, 0]` (rad/s) in
/// the North–Up–East frame, for latitude `φ` (rad) and Earth rate `Ω`
/// (rad/s; 0 to switch it off).
///
/// # Examples
///
/// ```
/// use rollcal::geometry::{earth_rate_n, EARTH_RATE};
///
/// // At 34.25° N: North and Up components, none East.
/// let phi = 34.25f64.to_radians();
/// let w = earth_rate_n(EARTH_RATE, phi);
/// assert!((w.norm() - EARTH_RATE).abs() < 1e-20);
/// assert!((w.y - EARTH_RATE * phi.sin()).abs() < 1e-20);
/// assert_eq!(w.z, 0.0);
/// ```
pub fn earth_rate_n<T: RealField + Copy>(omega: T, latitude: T) -> Vector3<T> {
    let (s, c) = sin_cos(latitude);
    Vector3::new(omega * c, omega * s, T::zero())
}

/// Earth rotation rate `Ω` (rad/s), WGS-84.
pub const EARTH_RATE: f64 = 7.292115e-5;

/// Specific force at rest in the navigation frame, `f^n = [0, 1, 0]` (g).
pub fn gravity_n<T: RealField + Copy>() -> Vector3<T> {
    Vector3::new(T::zero(), T::one(), T::zero())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Angles (rad) over several turns, both signs, and the exact values
    /// where a sine or cosine term vanishes or a product is exact.
    fn angles() -> impl Iterator<Item = f64> {
        let specials = [
            0.0,
            -0.0,
            1e-9,
            -3e-5,
            0.5,
            -1.0,
            core::f64::consts::FRAC_PI_2,
            3.0,
        ];
        (0..97)
            .map(|i| -7.3 + 0.1517 * f64::from(i) + 1e-3 * f64::from(i % 7))
            .chain(specials)
    }

    /// Equal as numbers, and bit for bit unless both are zeros (the written
    /// out forms leave out the product's `±0` terms, which can flip the
    /// sign of an exact zero and nothing else).
    fn same(a: &Matrix3<f64>, b: &Matrix3<f64>) -> bool {
        a.iter()
            .zip(b.iter())
            .all(|(x, y)| x.to_bits() == y.to_bits() || (*x == 0.0 && *y == 0.0))
    }

    /// The series of the rotation coefficients against their closed forms,
    /// which lose `ε/x²` to cancellation (`1 − cos x`, `x − sin x`, the
    /// inverse Jacobian's `1/x² − …`), from 1e-4 rad to the 0.1 rad
    /// threshold, and continuity there.
    #[test]
    fn rotation_series_agree_with_the_closed_forms() {
        let eps = f64::EPSILON;
        for i in 0..=400 {
            let x = 1e-4 * 10f64.powf(3.0 * f64::from(i) / 400.0) * 0.9999;
            let y = x * x;
            let k = RotationCoefficients::new(y);
            let (s, c) = (x.sin(), x.cos());
            let cancel = 4.0 * eps / y;
            assert!((k.sinc - s / x).abs() <= 4.0 * eps, "sinc at {x}");
            assert!(
                (k.cosc - (1.0 - c) / y).abs() <= 4.0 * eps + cancel,
                "cosc at {x}"
            );
            assert!(
                (k.sinc3 - (x - s) / (y * x)).abs() <= 4.0 * eps + cancel,
                "sinc3 at {x}"
            );
            let theta = Vector3::new(0.6 * x, -0.8 * x, 0.0);
            let jinv = right_jacobian_inv(&theta);
            let closed = 1.0 / y - (1.0 + c) / (2.0 * x * s);
            let from_series = (jinv - Matrix3::identity() - skew(&theta) / 2.0).m11 / (-y * 0.64);
            // m11 of [θ×]² is −(θy² + θz²) = −0.64 y.
            assert!(
                (from_series - closed).abs() <= 8.0 * eps + cancel,
                "J_r⁻¹ at {x}"
            );
        }
        // Either side of the thresholds (1e-8 and 1e-2 rad²).
        for y in [1e-8f64, 1e-2] {
            let (below, above) = (
                RotationCoefficients::new(y * (1.0 - 1e-12)),
                RotationCoefficients::new(y),
            );
            // Rounding, plus the functions' own change over 1e-12 of y.
            let tol = 4.0 * eps + 1e-12 * y;
            assert!((below.sinc - above.sinc).abs() < tol, "sinc at {y}");
            assert!((below.cosc - above.cosc).abs() < tol, "cosc at {y}");
            assert!((below.sinc3 - above.sinc3).abs() < tol, "sinc3 at {y}");
        }
    }

    #[test]
    fn right_jacobian_times_a_vector_is_the_product() {
        for (i, a) in angles().enumerate() {
            let theta = Vector3::new(a, 0.3 - 0.2 * a, 1e-3 * f64::from(i as u8)) * 0.05;
            let v = Vector3::new(7.3e-5, -2.1e-5, 4.4e-5 + 1e-6 * a);
            let d = right_jacobian_times(&theta, &v) - right_jacobian(&theta) * v;
            assert!(
                d.amax() <= 4.0 * f64::EPSILON * v.amax(),
                "at {theta:?}: {d:?}"
            );
        }
    }

    #[test]
    fn advanced_trigonometry_is_within_a_few_ulp_of_the_direct_one() {
        let deltas = [
            0.0, 1e-9, -3.3e-4, 1.7e-3, -8.7e-3, 0.049, -0.05, 0.051, -0.4,
        ];
        for (i, a) in angles().enumerate() {
            let angles = Vector3::new(a, -0.5 * a, 0.3 + a);
            let trig = EulerTrig::new(&angles);
            for (j, &d) in deltas.iter().enumerate() {
                let delta = Vector3::new(d, -d, deltas[(i + j) % deltas.len()]);
                let advanced = trig.advanced_by(&angles, &delta);
                let direct = EulerTrig::new(&(angles + delta));
                for (x, y) in [
                    (advanced.alpha, direct.alpha),
                    (advanced.beta, direct.beta),
                    (advanced.gamma, direct.gamma),
                ] {
                    assert!((x.0 - y.0).abs() <= 4.0 * f64::EPSILON, "sin at {a} + {d}");
                    assert!((x.1 - y.1).abs() <= 4.0 * f64::EPSILON, "cos at {a} + {d}");
                }
            }
        }
    }

    /// The deviations of `R(θ)` and `J_r(θ)` formed without the identity
    /// equal their definitions where those do not cancel, and keep their
    /// relative precision in f32 where they would.
    #[test]
    fn deviations_keep_their_relative_precision() {
        for theta in [
            Vector3::new(0.3, -0.2, 0.5),
            Vector3::new(1.2e-3, -0.7e-3, 0.4e-3),
            Vector3::new(2e-6, 1e-6, -3e-6),
        ] {
            let v = Vector3::new(0.1, 0.9, -0.4);
            let size = theta.norm();
            // In f64 against the definitions (cancellation: ε of 1).
            let deviation = dcm_deviation(&theta);
            assert!((deviation - (dcm(&theta) - Matrix3::identity())).amax() < 4e-16);
            let jv = right_jacobian_deviation_times(&theta, &v);
            assert!((jv - (right_jacobian_times(&theta, &v) - v)).amax() < 4e-16);
            // In f32 against f64, relative to their size (|θ|, |θ|/2).
            let eps = f64::from(f32::EPSILON);
            let t32 = theta.map(|x| x as f32);
            let d32 = dcm_deviation(&t32).map(f64::from);
            assert!((d32 - deviation).amax() / size < 4.0 * eps);
            let jv32 = right_jacobian_deviation_times(&t32, &v.map(|x| x as f32));
            assert!((jv32.map(f64::from) - jv).amax() / (size / 2.0) < 4.0 * eps);
        }
    }

    /// `R(θ) C` with its first-order part in f64 and the rest in f32 is
    /// `dcm(θ) C` to `ε_f32 |θ|²/2` (and in f64 to rounding), where the
    /// whole product in f32 would be `ε_f32` off; its turn `R(θ) C − C` in
    /// f32 is `dcm(θ) C − C` to a few `ε_f32 |θ|`.
    #[test]
    fn rotated_in_keeps_the_first_order_part_in_f64() {
        let c = dcm(&Vector3::new(0.4, -1.1, 2.3));
        let eps = f64::from(f32::EPSILON);
        for theta in [
            Vector3::new(1.7e-3, -2.0e-3, 0.9e-3),
            Vector3::new(2e-6, 1e-6, -3e-6),
            Vector3::new(0.02, 0.05, -0.03),
            Vector3::new(0.3, -0.2, 0.5),
        ] {
            let exact = dcm(&theta) * c;
            let (r64, turn64) = rotated_in::<f64>(&theta, &c);
            assert!((r64 - exact).amax() < 4e-16);
            assert!((turn64 - (exact - c)).amax() < 4e-16);
            let (r32, turn32) = rotated_in::<f32>(&theta, &c);
            let err = (r32 - exact).amax();
            let bound = 4.0 * eps * theta.norm_squared() / 2.0;
            assert!(
                err < bound + 4e-16,
                "θ {theta:?}: {err:e} against {bound:e}"
            );
            let turn_err = (turn32.map(f64::from) - (exact - c)).amax();
            let turn_bound = 2.0 * eps * theta.norm();
            assert!(
                turn_err < turn_bound,
                "θ {theta:?}: turn {turn_err:e} against {turn_bound:e}"
            );
        }
    }

    #[test]
    fn trigonometry_advanced_in_f32_is_within_its_bound() {
        let deltas = [0.0, 1e-9, -3.3e-4, 1.7e-3, -4e-3, 4e-3, -8.7e-3, 0.049];
        let mut worst: f64 = 0.0;
        for (i, a) in angles().enumerate() {
            let angles = Vector3::new(a, -0.5 * a, 0.3 + a);
            let trig = EulerTrig::new(&angles);
            for (j, &d) in deltas.iter().enumerate() {
                let delta = Vector3::new(d, -d, deltas[(i + j) % deltas.len()]);
                let exact = trig.advanced_by(&angles, &delta);
                assert_eq!(trig.advanced_in::<f64>(&angles, &delta), exact);
                let in_f32 = trig.advanced_in::<f32>(&angles, &delta);
                if delta.amax() > 4e-3 {
                    assert_eq!(in_f32, exact, "beyond 4e-3 rad it is advanced_by");
                    continue;
                }
                for (x, y) in [
                    (in_f32.alpha, exact.alpha),
                    (in_f32.beta, exact.beta),
                    (in_f32.gamma, exact.gamma),
                ] {
                    worst = worst.max((x.0 - y.0).abs()).max((x.1 - y.1).abs());
                }
            }
        }
        // 3 ε_f32 |δ| at |δ| = 4e-3 rad.
        assert!(
            worst > 0.0 && worst <= 3.0 * f64::from(f32::EPSILON) / 2.0 * 4e-3,
            "{worst:e}"
        );
    }

    #[test]
    fn written_out_products_equal_the_products_bit_for_bit() {
        let all: [f64; 105] = core::array::from_fn(|i| angles().nth(i).unwrap_or(0.0));
        for (i, &a) in all.iter().enumerate() {
            let b = all[(i * 31 + 7) % all.len()];
            let g = all[(i * 17 + 3) % all.len()];
            let trig = EulerTrig::new(&Vector3::new(a, b, g));
            let product = r3(g) * r2(b) * r1(a);
            assert!(same(&trig.dcm(), &product), "dcm at {a} {b} {g}");
            let v = Vector3::new(a, b, g) * 0.37;
            assert!(
                same(&skew_squared(&v), &(skew(&v) * skew(&v))),
                "skew² at {v:?}"
            );
        }
    }

    #[test]
    fn wrap_edges() {
        let pi = core::f64::consts::PI;
        assert_eq!(wrap_angle(pi), pi);
        assert!((wrap_angle(-pi) - pi).abs() < 1e-15);
        assert!((wrap_angle(3.0 * pi) - pi).abs() < 1e-12);
        assert!((wrap_angle(2.5 * pi) - 0.5 * pi).abs() < 1e-12);
        assert!((wrap_angle(-2.5 * pi) + 0.5 * pi).abs() < 1e-12);
        assert!(wrap_angle(f64::NAN).is_nan());
        assert_eq!(wrap_angle(f64::INFINITY), f64::INFINITY);
    }
}
