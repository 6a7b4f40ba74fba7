//! The installation parameters of a state vector and the per-period
//! constant matrices of them (docs/model.md §Installation models): `G = R(θgC)(I + L(θgT))`, `A = (I + L(θaT)) R(−θaC)`,
//! `C^r_n = R(λ)`, with the rotations and right Jacobians the model's
//! Jacobians need.

use nalgebra::{Matrix3, RealField, Vector3};

use super::instrument_errors::InstrumentErrors;
use crate::geometry::{dcm, dcm_and_right_jacobian, dcm_deviation, skew};

/// Installation parameters unpacked from a state vector (rad); absent ones
/// are zero. With them the instruments' own errors of a full-model state
/// ([`InstrumentErrors`], all zero for an installation-only layout), which
/// the matrices do not depend on but the model functions read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Installation<T: RealField + Copy> {
    /// Gyro misalignment `θgC` (ps) or `θgC^pa` (pa).
    pub theta_g_c: Vector3<T>,
    /// Gyro non-orthogonality `θgT`.
    pub theta_g_t: Vector3<T>,
    /// Accelerometer misalignment `θaC` (zero in the pa frame).
    pub theta_a_c: Vector3<T>,
    /// Accelerometer non-orthogonality `θaT`.
    pub theta_a_t: Vector3<T>,
    /// Base mounting angles `λ` (zero without a base).
    pub lambda: Vector3<T>,
    /// The instruments' own errors (docs/model.md §Instrument errors; zero for
    /// [`ErrorModel::Installation`](super::ErrorModel::Installation)).
    pub instruments: InstrumentErrors<T>,
}

impl Installation<f64> {
    /// The same parameters in precision `U`, each rounded once.
    pub fn to_precision<U: RealField + Copy>(&self) -> Installation<U> {
        let v = |x: &Vector3<f64>| x.map(nalgebra::convert::<f64, U>);
        Installation {
            theta_g_c: v(&self.theta_g_c),
            theta_g_t: v(&self.theta_g_t),
            theta_a_c: v(&self.theta_a_c),
            theta_a_t: v(&self.theta_a_t),
            lambda: v(&self.lambda),
            instruments: self.instruments.to_precision(),
        }
    }
}

/// The per-period constant matrices of an installation: `G`, `A`, `R(λ)`,
/// and the rotations and right Jacobians of the installation angles that
/// the Jacobians of the model need (so that a period evaluates no
/// trigonometric function of a constant parameter: `∂(R(θ) v)/∂θ =
/// [(R(θ) v)×] J_r(θ)`, [`crate::geometry::d_dcm_times`], is
/// [`InstallationMatrices::d_rotation_times`] on the cached factors, with
/// the same floating-point operations).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstallationMatrices<T: RealField + Copy> {
    /// The unpacked parameters.
    pub params: Installation<T>,
    /// `G = R(θgC)(I + L(θgT))`.
    pub g: Matrix3<T>,
    /// `G − I = (R(θgC) − I)(I + L(θgT)) + L(θgT)`, formed without the
    /// identity ([`crate::geometry::dcm_deviation`]): every entry to its
    /// own relative precision. A filter that computes in single precision
    /// takes the platform rate `G u` as `u + (G − I) u`
    /// ([`Layout::attitude_rate`](super::Layout::attitude_rate)): `G`'s
    /// diagonal, `1 − O(θ²)`, rounded to f32 is off by up to ≈ 7e-8, a
    /// scale factor of the commanded rate that every period repeats.
    pub g_deviation: Matrix3<T>,
    /// `A = (I + L(θaT)) R(−θaC)`.
    pub a: Matrix3<T>,
    /// `C^r_n = R(λ)`.
    pub c_rn: Matrix3<T>,
    /// `R(θgC)`.
    pub r_g_c: Matrix3<T>,
    /// `J_r(θgC)` ([`crate::geometry::right_jacobian`]).
    pub jr_g_c: Matrix3<T>,
    /// `I + L(θgT)`.
    pub unit_g_t: Matrix3<T>,
    /// `R(−θaC)`.
    pub r_a_c: Matrix3<T>,
    /// `J_r(−θaC)`.
    pub jr_a_c: Matrix3<T>,
    /// `I + L(θaT)`.
    pub unit_a_t: Matrix3<T>,
    /// `J_r(λ)`.
    pub jr_lambda: Matrix3<T>,
}

impl<T: RealField + Copy> InstallationMatrices<T> {
    /// The matrices of the installation parameters `params` (rad).
    pub fn new(params: Installation<T>) -> Self {
        let (r_g_c, jr_g_c) = dcm_and_right_jacobian(&params.theta_g_c);
        let lower_g_t = crate::geometry::lower(&params.theta_g_t);
        let unit_g_t = Matrix3::identity() + lower_g_t;
        let (r_a_c, jr_a_c) = dcm_and_right_jacobian(&-params.theta_a_c);
        let unit_a_t = Matrix3::identity() + crate::geometry::lower(&params.theta_a_t);
        let (c_rn, jr_lambda) = dcm_and_right_jacobian(&params.lambda);
        Self {
            // The products of gyro_matrix and accel_matrix, on the same factors.
            g: r_g_c * unit_g_t,
            g_deviation: dcm_deviation(&params.theta_g_c) * unit_g_t + lower_g_t,
            a: unit_a_t * r_a_c,
            c_rn,
            r_g_c,
            jr_g_c,
            unit_g_t,
            r_a_c,
            jr_a_c,
            unit_a_t,
            jr_lambda,
            params,
        }
    }

    /// `A = (I + L(θaT)) R(−θaC)` and `C^r_n = R(λ)` of `params` (rad)
    /// alone, the same values as [`InstallationMatrices::new`]'s: the two
    /// that the single-precision filter needs in f64 (the value of the
    /// mean specific force, [`Layout::mean_accel_output`](super::Layout::mean_accel_output)).
    pub fn accel_and_base(params: &Installation<T>) -> (Matrix3<T>, Matrix3<T>) {
        let unit_a_t = Matrix3::identity() + crate::geometry::lower(&params.theta_a_t);
        (unit_a_t * dcm(&-params.theta_a_c), dcm(&params.lambda))
    }

    /// `∂(R(θ) v)/∂θ = [(R(θ) v)×] J_r(θ)` from `R(θ)` and `J_r(θ)`
    /// ([`crate::geometry::d_dcm_times`] without its trigonometry).
    pub fn d_rotation_times(r: &Matrix3<T>, jr: &Matrix3<T>, v: &Vector3<T>) -> Matrix3<T> {
        skew(&(r * v)) * jr
    }
}

impl InstallationMatrices<f64> {
    /// The same matrices in precision `U` (each element rounded, no
    /// trigonometry recomputed in `U`).
    pub fn to_precision<U: RealField + Copy>(&self) -> InstallationMatrices<U> {
        let m = |x: &Matrix3<f64>| x.map(nalgebra::convert::<f64, U>);
        let v = |x: &Vector3<f64>| x.map(nalgebra::convert::<f64, U>);
        let p = &self.params;
        InstallationMatrices {
            params: Installation {
                theta_g_c: v(&p.theta_g_c),
                theta_g_t: v(&p.theta_g_t),
                theta_a_c: v(&p.theta_a_c),
                theta_a_t: v(&p.theta_a_t),
                lambda: v(&p.lambda),
                instruments: p.instruments.to_precision(),
            },
            g: m(&self.g),
            g_deviation: m(&self.g_deviation),
            a: m(&self.a),
            c_rn: m(&self.c_rn),
            r_g_c: m(&self.r_g_c),
            jr_g_c: m(&self.jr_g_c),
            unit_g_t: m(&self.unit_g_t),
            r_a_c: m(&self.r_a_c),
            jr_a_c: m(&self.jr_a_c),
            unit_a_t: m(&self.unit_a_t),
            jr_lambda: m(&self.jr_lambda),
        }
    }
}
