//! What a period gives the filter and what it gives back: the period's
//! measurement ([`Observation`]) and the update's innovation
//! ([`Innovation`]).

use nalgebra::{RealField, SMatrix, SVector, Vector3};

/// The measurement of one period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation<T: RealField + Copy> {
    /// Mean accelerometer output over the period (g, instrument axes).
    pub accel_mean: Vector3<T>,
    /// Gimbal angles `(α, β, γ)` at the end of the period (rad); required by M2.
    pub gimbal: Option<Vector3<T>>,
}

/// Innovation of one update.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Innovation<T: RealField + Copy, const Z: usize> {
    /// `ν = z − h(x̂)`, gimbal components wrapped into (−π, π] (rad; g).
    pub nu: SVector<T, Z>,
    /// Its covariance `S` (including the second-order terms when enabled).
    pub s: SMatrix<T, Z, Z>,
    /// Normalised innovation squared `νᵀ S⁻¹ ν`.
    pub nis: T,
}
