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

mod gimbal;
mod rotation;
#[cfg(test)]
mod tests;

pub use gimbal::*;
pub use rotation::*;

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
