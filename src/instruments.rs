//! Instrument installation models (docs/model.md §Installation models;
//! paper eqs. 6, 10, 11).
//!
//! Angles are radians. `θgC`, `θaC` are the axis-rotation (misalignment)
//! angles of the gyro and accelerometer triads, `θgT`, `θaT` their
//! non-orthogonality angles (the entries of `L(t)`, numbered 1..3).

use nalgebra::{Matrix3, RealField, Vector3};

use crate::geometry::{dcm, lower, rotation_vector};

/// Gyro installation matrix `G = R(θgC) (I + L(θgT))` (paper eqs. 6, 11):
/// the platform rate is `ω^p_ip = G ωc` when the gyros follow the commanded
/// rate `ωc`. In the pa frame pass `θgC^pa` for `theta_g_c`.
pub fn gyro_matrix<T: RealField + Copy>(
    theta_g_c: &Vector3<T>,
    theta_g_t: &Vector3<T>,
) -> Matrix3<T> {
    dcm(theta_g_c) * (Matrix3::identity() + lower(theta_g_t))
}

/// Accelerometer installation matrix in the ps frame,
/// `A = (I + L(θaT)) R(−θaC)`: the output is `Z_a = A f^ps` (g).
/// In the pa frame `θaC = 0` by definition and `A = I + L(θaT)`.
pub fn accel_matrix<T: RealField + Copy>(
    theta_a_c: &Vector3<T>,
    theta_a_t: &Vector3<T>,
) -> Matrix3<T> {
    (Matrix3::identity() + lower(theta_a_t)) * dcm(&(-theta_a_c))
}

/// The pa-frame gyro misalignment `θgC^pa` (rad) of the ps-frame angles,
/// exactly: `R(θgC^pa) = R(−θaC) R(θgC)` (paper eq. 10 is its first-order
/// form `θgC^pa ≈ θgC − θaC`).
pub fn theta_g_c_pa<T: RealField + Copy>(
    theta_g_c: &Vector3<T>,
    theta_a_c: &Vector3<T>,
) -> Vector3<T> {
    rotation_vector(&(dcm(&(-theta_a_c)) * dcm(theta_g_c)))
}
