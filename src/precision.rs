//! Conversions between the filter's precision `T` (f32 or f64) and f64,
//! where the single-precision filter hands values between its f64 parts
//! (state, nominal, computed frame, predicted measurement) and its `T`
//! parts (factor, Jacobians, small deviations).

use nalgebra::{RealField, SMatrix};

/// A double-precision matrix in precision `T` (each element rounded).
pub(crate) fn to_t<T: RealField + Copy, const R: usize, const C: usize>(
    m: &SMatrix<f64, R, C>,
) -> SMatrix<T, R, C> {
    m.map(nalgebra::convert::<f64, T>)
}

/// A value of precision `T` in double precision (exact for f32; NaN for a
/// `T` with no f64 value).
pub(crate) fn scalar_to_f64<T: RealField + Copy>(v: T) -> f64 {
    v.to_subset().unwrap_or(f64::NAN)
}

/// A matrix of precision `T` in double precision ([`scalar_to_f64`] of each
/// element).
pub(crate) fn to_f64<T: RealField + Copy, const R: usize, const C: usize>(
    m: &SMatrix<T, R, C>,
) -> SMatrix<f64, R, C> {
    m.map(scalar_to_f64)
}
