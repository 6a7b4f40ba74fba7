//! The instruments' own errors of the full model (docs/model.md
//! §Instrument errors, §Full model): [`InstrumentErrors`], unpacked from a state
//! vector by [`Layout::instrument_errors`](super::Layout::instrument_errors),
//! and the two places they act: the gyro input
//! `(I + K_g) ωc + dg + D_g f^p` ([`InstrumentErrors::gyro_input`]) and the
//! accelerometer output `ba + (I + K_a) A f^p`
//! ([`InstrumentErrors::accel`]).

use nalgebra::{Matrix3, RealField, Vector3};

/// The instruments' own errors in the model's platform frame p (ps or pa);
/// all zero for an [`ErrorModel::Installation`](super::ErrorModel) layout.
///
/// # Examples
///
/// ```
/// use nalgebra::{Matrix3, Vector3};
/// use rollcal::models::InstrumentErrors;
///
/// let mut e = InstrumentErrors::<f64>::zeros();
/// e.kg = Vector3::new(1e-4, 0.0, 0.0); // 100 ppm on the x torquer
/// e.dg = Vector3::new(0.0, 1e-7, 0.0); // rad/s
/// e.d_g = Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2e-7, 0.0); // z gyro, f_y
/// let (w, f) = (Vector3::new(1e-3, 0.0, 0.0), Vector3::new(0.0, 1.0, 0.0));
/// let u = e.gyro_input(&w, &f);
/// assert_eq!(u, Vector3::new(1e-3 * (1.0 + 1e-4), 1e-7, 2e-7));
///
/// e.ba = Vector3::new(1e-5, 0.0, 0.0); // g
/// e.ka = Vector3::new(0.0, 2e-4, 0.0);
/// assert_eq!(e.accel(&f), Vector3::new(1e-5, 1.0 + 2e-4, 0.0));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstrumentErrors<T: RealField + Copy> {
    /// Constant gyro drift `dg` (rad/s), per gyro x, y, z.
    pub dg: Vector3<T>,
    /// g-sensitive gyro drift `D_g` (rad/s per g): row = gyro x/y/z,
    /// column = axis of the specific force in the model's platform frame
    /// (`D_g^pa` in the pa frame).
    pub d_g: Matrix3<T>,
    /// Torquer scale-factor errors `kg` (dimensionless), `K_g = diag(kg)`.
    pub kg: Vector3<T>,
    /// Accelerometer bias `ba` (g).
    pub ba: Vector3<T>,
    /// Accelerometer scale-factor errors `ka` (dimensionless),
    /// `K_a = diag(ka)`.
    pub ka: Vector3<T>,
}

impl<T: RealField + Copy> InstrumentErrors<T> {
    /// No instrument errors.
    pub fn zeros() -> Self {
        Self {
            dg: Vector3::zeros(),
            d_g: Matrix3::zeros(),
            kg: Vector3::zeros(),
            ba: Vector3::zeros(),
            ka: Vector3::zeros(),
        }
    }

    /// The rate the gyros deliver for the command `omega_c` (rad/s) under
    /// the specific force `f_p` (g, model's platform frame):
    /// `(I + K_g) ωc + dg + D_g f^p` (rad/s; the platform rate is `G` of
    /// it).
    pub fn gyro_input(&self, omega_c: &Vector3<T>, f_p: &Vector3<T>) -> Vector3<T> {
        omega_c + self.kg.component_mul(omega_c) + self.dg + self.d_g * f_p
    }

    /// What the gyros add to the command `omega_c` (rad/s) under the
    /// specific force `f_p` (g): `K_g ωc + dg + D_g f^p` (rad/s), the
    /// [`InstrumentErrors::gyro_input`] less `ωc`, formed without it (a
    /// single-precision filter's rate keeps the command out of its small
    /// parts, [`Layout::attitude_rate`](super::Layout::attitude_rate)).
    pub fn gyro_error(&self, omega_c: &Vector3<T>, f_p: &Vector3<T>) -> Vector3<T> {
        self.kg.component_mul(omega_c) + self.dg + self.d_g * f_p
    }

    /// The same errors in the pa frame from the ps ones (docs/model.md
    /// §Instrument errors):
    /// `D_g^pa = D_g R(θaC)` (so that `D_g^pa f^pa = D_g f^ps`, with
    /// `f^ps = R(θaC) f^pa`), `dg`, `kg`, `ba`, `ka` unchanged; `theta_a_c`
    /// is the accelerometer misalignment θaC (rad).
    ///
    /// # Examples
    ///
    /// ```
    /// use nalgebra::{Matrix3, Vector3};
    /// use rollcal::geometry::dcm;
    /// use rollcal::models::InstrumentErrors;
    ///
    /// let mut ps = InstrumentErrors::<f64>::zeros();
    /// ps.d_g = Matrix3::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0) * 1e-7;
    /// let theta_a_c = Vector3::new(2e-3, -1e-3, 3e-3);
    /// let pa = ps.in_pa(&theta_a_c);
    /// let f_ps = Vector3::new(0.1, 0.9, -0.2);
    /// let f_pa = dcm(&-theta_a_c) * f_ps; // f^pa = R(−θaC) f^ps
    /// let w = Vector3::new(1e-3, 0.0, 2e-3);
    /// let same = (ps.gyro_input(&w, &f_ps) - pa.gyro_input(&w, &f_pa)).amax();
    /// assert!(same < 1e-20);
    /// ```
    pub fn in_pa(&self, theta_a_c: &Vector3<T>) -> Self {
        Self {
            d_g: self.d_g * crate::geometry::dcm(theta_a_c),
            ..*self
        }
    }

    /// The accelerometer output of the installed specific force `af`
    /// (`A f^p`, g): `ba + (I + K_a) A f^p` (g).
    pub fn accel(&self, af: &Vector3<T>) -> Vector3<T> {
        self.ba + af + self.ka.component_mul(af)
    }
}

impl InstrumentErrors<f64> {
    /// The same errors in precision `U` (each element rounded).
    pub fn to_precision<U: RealField + Copy>(&self) -> InstrumentErrors<U> {
        let v = |x: &Vector3<f64>| x.map(nalgebra::convert::<f64, U>);
        InstrumentErrors {
            dg: v(&self.dg),
            d_g: self.d_g.map(nalgebra::convert::<f64, U>),
            kg: v(&self.kg),
            ba: v(&self.ba),
            ka: v(&self.ka),
        }
    }
}
