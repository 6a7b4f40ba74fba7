//! Instrument installation models (docs/model.md §Installation models).
//!
//! Angles are radians. `θgC`, `θaC` are the axis-rotation (misalignment)
//! angles of the gyro and accelerometer triads, `θgT`, `θaT` their
//! non-orthogonality angles (the entries of `L(t)`, numbered 1..3).

use nalgebra::{Matrix3, RealField, Vector3};

use crate::geometry::{dcm, lower, rotation_vector};

/// Gyro installation matrix `G = R(θgC) (I + L(θgT))` (docs/model.md
/// §Installation models):
/// the platform rate is `ω^p_ip = G ωc` when the gyros follow the commanded
/// rate `ωc`. In the pa frame pass `θgC^pa` for `theta_g_c`.
///
/// # Examples
///
/// ```
/// use nalgebra::{Matrix3, Vector3};
/// use rollcal::geometry::{lower, skew};
/// use rollcal::instruments::gyro_matrix;
///
/// // Perfectly installed gyros: G = I.
/// let zero = Vector3::<f64>::zeros();
/// assert_eq!(gyro_matrix(&zero, &zero), Matrix3::identity());
/// // Small errors (20″): G ≈ I − [θgC×] + L(θgT) to first order.
/// let arcsec = 1f64.to_radians() / 3600.0;
/// let theta_g_c = Vector3::new(20.0, -10.0, 5.0) * arcsec;
/// let theta_g_t = Vector3::new(3.0, 8.0, -4.0) * arcsec;
/// let first_order = Matrix3::identity() - skew(&theta_g_c) + lower(&theta_g_t);
/// assert!((gyro_matrix(&theta_g_c, &theta_g_t) - first_order).norm() < 1e-8);
/// ```
pub fn gyro_matrix<T: RealField + Copy>(
    theta_g_c: &Vector3<T>,
    theta_g_t: &Vector3<T>,
) -> Matrix3<T> {
    dcm(theta_g_c) * (Matrix3::identity() + lower(theta_g_t))
}

/// Accelerometer installation matrix in the ps frame,
/// `A = (I + L(θaT)) R(−θaC)`: the output is `Z_a = A f^ps` (g).
/// In the pa frame `θaC = 0` by definition and `A = I + L(θaT)`.
///
/// # Examples
///
/// ```
/// use nalgebra::{Matrix3, Vector3};
/// use rollcal::geometry::lower;
/// use rollcal::instruments::accel_matrix;
///
/// let arcsec = 1f64.to_radians() / 3600.0;
/// let theta_a_t = Vector3::new(12.0, -6.0, 9.0) * arcsec;
/// // pa frame: θaC = 0 and A = I + L(θaT); a platform level in 1 g reads
/// // Z_a = A f^ps, the cross-coupling of the non-orthogonality angles.
/// let a = accel_matrix(&Vector3::zeros(), &theta_a_t);
/// assert_eq!(a, Matrix3::identity() + lower(&theta_a_t));
/// let z_a = a * Vector3::new(0.0, 1.0, 0.0);
/// assert!((z_a - Vector3::new(0.0, 1.0, theta_a_t.z)).norm() < 1e-18);
/// ```
pub fn accel_matrix<T: RealField + Copy>(
    theta_a_c: &Vector3<T>,
    theta_a_t: &Vector3<T>,
) -> Matrix3<T> {
    (Matrix3::identity() + lower(theta_a_t)) * dcm(&(-theta_a_c))
}

/// The pa-frame gyro misalignment `θgC^pa` (rad) of the ps-frame angles,
/// exactly: `R(θgC^pa) = R(−θaC) R(θgC)` (the paper's `θgC^pa ≈ θgC − θaC`
/// is its first-order form, docs/model.md §Installation models).
///
/// # Examples
///
/// ```
/// use nalgebra::Vector3;
/// use rollcal::instruments::theta_g_c_pa;
///
/// let arcsec = 1f64.to_radians() / 3600.0;
/// let theta_g_c = Vector3::new(30.0, 0.0, -15.0) * arcsec;
/// let theta_a_c = Vector3::new(10.0, 5.0, 0.0) * arcsec;
/// // The paper's θgC^pa ≈ θgC − θaC is its first-order form.
/// let exact = theta_g_c_pa(&theta_g_c, &theta_a_c);
/// assert!((exact - (theta_g_c - theta_a_c)).norm() < 1e-3 * arcsec);
/// ```
pub fn theta_g_c_pa<T: RealField + Copy>(
    theta_g_c: &Vector3<T>,
    theta_a_c: &Vector3<T>,
) -> Vector3<T> {
    rotation_vector(&(dcm(&(-theta_a_c)) * dcm(theta_g_c)))
}
