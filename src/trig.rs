//! Sine and cosine in the model's precision `T`, for the Jacobians and the
//! covariance terms a single-precision filter evaluates in f32.
//!
//! libm's `sinf`/`cosf` reduce the argument and evaluate their polynomials
//! in f64, which a Cortex-M4F (single-precision FPU) emulates in software.
//! For `T = f32` these functions use an f32-only evaluation instead
//! ([`sin_cos_f32`]); for any other `T` (f64) they are `T::sin`, `T::cos`
//! and `T::sin_cos` unchanged, so every f64 answer stays bit-identical.

use core::any::Any;

use nalgebra::RealField;

/// `4/π`.
const FOUR_OVER_PI: f32 = 1.273_239_5;
/// `π/4` in three parts (Cody–Waite): the first two hold few enough bits
/// that `y · DP1` and `y · DP2` are exact for the octant counts used here.
const DP1: f32 = 0.785_156_25;
const DP2: f32 = 2.418_756_5e-4;
const DP3: f32 = 3.774_895e-8;

/// `sin x` and `cos x` (x in rad) in f32 arithmetic only: the Cody–Waite
/// reduction to `|r| ≤ π/4` and the minimax polynomials of Cephes' `sinf`
/// and `cosf` (S. L. Moshier, *Methods and Programs for Mathematical
/// Functions*, 1989). Error ≤ 2 ulp of 1 for `|x| ≤ 8192` (the filter's
/// angles are within ±π); larger arguments are first reduced modulo the
/// f32 value of 2π (bounded results whose accuracy drops with |x|); NaN or
/// ±∞ give NaN. Never panics.
pub fn sin_cos_f32(x: f32) -> (f32, f32) {
    if !x.is_finite() {
        return (f32::NAN, f32::NAN);
    }
    let mut ax = if x < 0.0 { -x } else { x };
    if ax > 8192.0 {
        // Far outside the filter's range: reduce modulo the f32 value of
        // 2π first (libm's `fmodf` is exact integer arithmetic), so the
        // result stays bounded while its accuracy drops with |x|.
        ax = libm::fmodf(ax, 2.0 * core::f32::consts::PI);
    }
    // The octant, rounded up to even (a saturating conversion: no panic).
    let mut j = (ax * FOUR_OVER_PI) as u32;
    let mut y = j as f32;
    if j & 1 == 1 {
        j = j.wrapping_add(1);
        y += 1.0;
    }
    let r = ((ax - y * DP1) - y * DP2) - y * DP3;
    let z = r * r;
    let ps = ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1) * z * r + r;
    let pc = ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2) * z * z - 0.5 * z + 1.0;
    let (s, c) = match j & 7 {
        0 => (ps, pc),
        2 => (pc, -ps),
        4 => (-ps, -pc),
        _ => (-pc, ps),
    };
    (if x < 0.0 { -s } else { s }, c)
}

/// `x` as an f32 when `T` is f32.
fn as_f32<T: RealField + Copy>(x: &T) -> Option<f32> {
    (x as &dyn Any).downcast_ref::<f32>().copied()
}

/// `v` as a `T` when `T` is f32 (`T::zero()` otherwise; callers only use it
/// when [`as_f32`] succeeded).
fn from_f32<T: RealField + Copy>(v: f32) -> T {
    let mut out = T::zero();
    if let Some(o) = (&mut out as &mut dyn Any).downcast_mut::<f32>() {
        *o = v;
    }
    out
}

/// `(sin x, cos x)` (x in rad), f32-only for `T = f32` ([`sin_cos_f32`]).
pub fn sin_cos<T: RealField + Copy>(x: T) -> (T, T) {
    match as_f32(&x) {
        Some(v) => {
            let (s, c) = sin_cos_f32(v);
            (from_f32(s), from_f32(c))
        }
        None => x.sin_cos(),
    }
}

/// `sin x` (x in rad), f32-only for `T = f32` ([`sin_cos_f32`]).
pub fn sin<T: RealField + Copy>(x: T) -> T {
    match as_f32(&x) {
        Some(v) => from_f32(sin_cos_f32(v).0),
        None => x.sin(),
    }
}

/// `cos x` (x in rad), f32-only for `T = f32` ([`sin_cos_f32`]).
pub fn cos<T: RealField + Copy>(x: T) -> T {
    match as_f32(&x) {
        Some(v) => from_f32(sin_cos_f32(v).1),
        None => x.cos(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One unit in the last place of an f32 near 1.
    const ULP1: f64 = f32::EPSILON as f64;

    #[test]
    fn matches_f64_within_two_ulp_over_the_range() {
        let mut worst = 0.0f64;
        let n = 200_000;
        for k in 0..=n {
            // −8192 … 8192 rad, then a dense grid over ±2π.
            for x in [
                -8192.0 + 16384.0 * f64::from(k) / f64::from(n),
                -7.0 + 14.0 * f64::from(k) / f64::from(n),
            ] {
                let xf = x as f32;
                let (s, c) = sin_cos_f32(xf);
                let xr = f64::from(xf);
                let es = (f64::from(s) - libm::sin(xr)).abs();
                let ec = (f64::from(c) - libm::cos(xr)).abs();
                worst = worst.max(es).max(ec);
            }
        }
        assert!(worst <= 2.0 * ULP1, "worst error {:.3} ulp", worst / ULP1);
    }

    #[test]
    fn signs_quadrants_and_non_finite() {
        let (s, c) = sin_cos_f32(0.0);
        assert_eq!((s, c), (0.0, 1.0));
        let (s, c) = sin_cos_f32(core::f32::consts::FRAC_PI_2);
        assert!((s - 1.0).abs() < 1e-7 && c.abs() < 1e-7);
        let (s, c) = sin_cos_f32(-core::f32::consts::PI);
        assert!(s.abs() < 1e-6 && (c + 1.0).abs() < 1e-7);
        for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let (s, c) = sin_cos_f32(x);
            assert!(s.is_nan() && c.is_nan());
        }
        // Huge arguments: no panic, bounded, and on the unit circle.
        for x in [8192.5f32, -1.0e6, 3.0e38, -3.0e38] {
            let (s, c) = sin_cos_f32(x);
            assert!(
                s.abs() <= 1.0 + 1e-6 && c.abs() <= 1.0 + 1e-6,
                "{x}: {s} {c}"
            );
            assert!((s * s + c * c - 1.0).abs() < 1e-6, "{x}");
        }
    }

    #[test]
    fn f64_is_unchanged() {
        for k in 0..1000 {
            let x = -10.0 + 0.02 * f64::from(k);
            assert_eq!(sin_cos(x), x.sin_cos());
            assert_eq!(sin(x).to_bits(), x.sin().to_bits());
            assert_eq!(cos(x).to_bits(), x.cos().to_bits());
        }
        let (s, c) = sin_cos(0.5f32);
        assert_eq!((s, c), sin_cos_f32(0.5));
    }
}
