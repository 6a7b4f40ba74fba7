//! What a period gives the filter and what it gives back: the period's
//! measurement ([`Observation`]) and the update's innovation
//! ([`Innovation`]).

use nalgebra::{RealField, SMatrix, SVector, Vector3};

/// The measurement of one period.
///
/// # Examples
///
/// ```
/// # use nalgebra::{SVector, Vector3};
/// # use rollcal::ekf::{FilterConfig, M1PaFilter, Observation, Options};
/// # use rollcal::geometry::{earth_rate_n, gravity_n, EARTH_RATE};
/// # use rollcal::models::Environment;
/// # let deg = core::f64::consts::PI / 180.0;
/// # let w_ie = earth_rate_n(EARTH_RATE, 34.25 * deg);
/// # let config = FilterConfig::<f64> {
/// #     env: Environment { earth_rate_n: w_ie, gravity_n: gravity_n() },
/// #     sigma_accel: 1e-6,
/// #     sigma_gyro: 0.1 * deg / 3600.0,
/// #     sigma_gimbal: 10.0 * deg / 3600.0,
/// #     options: Options::default(),
/// #     wander: rollcal::models::Wander::none(),
/// # };
/// # let mut f = M1PaFilter::<f64>::new(config, SVector::zeros(), SVector::repeat(deg))?;
/// # // Holding still with the computed frame on n: the commanded increment is
/// # // the Earth rate over the period, the accelerometers read gravity (g).
/// # let (dtheta_c, dt) = (w_ie * 1.0, 1.0);
/// # let obs = Observation { accel_mean: gravity_n::<f64>(), gimbal: None };
/// # use rollcal::ekf::M2PsFilter;
/// // M2 observes the gimbal angles too: an observation without them is refused.
/// let mut m2 = M2PsFilter::<f64>::new(config, SVector::zeros(), SVector::repeat(deg))?;
/// let no_gimbal = Observation { accel_mean: gravity_n::<f64>(), gimbal: None };
/// assert_eq!(m2.step(&dtheta_c, dt, &no_gimbal), Err(rollcal::Error::MissingGimbal));
/// let with_gimbal = Observation { gimbal: Some(Vector3::zeros()), ..no_gimbal };
/// let innovation = m2.step(&dtheta_c, dt, &with_gimbal)?;
/// assert_eq!(innovation.nu.len(), 6); // 3 gimbal angles, then 3 accelerometers
/// // M1 has no gimbal angles in its measurement: they are ignored.
/// f.step(&dtheta_c, dt, &with_gimbal)?;
/// # Ok::<(), rollcal::Error>(())
/// ```
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
