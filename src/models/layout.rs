//! The composition of a configuration and where its states sit in the
//! state vector (docs/model.md §Configurations): the attitude
//! model ([`AttitudeKind`]), the platform frame ([`PlatformFrame`]), the
//! [`Layout`] that combines them with the base and the observation set, the
//! fixed indices [`ATT`], [`GC`], [`GT`], and the unpacking of a state
//! vector into its attitude and installation parameters.
//!
//! The state vector is
//! `[attitude(3), θgC or θgC^pa (3), θgT (3), θaC (3, ps only), θaT (3), λ (3, M2/M3)]`,
//! followed for the full model ([`ErrorModel::Full`]) by the instruments'
//! own errors `[dg (3), D_g (9, row-major), kg (3), ba (3), ka (3), k2 (3),
//! δ_g (3), δ_a (3), w_g (3), w_a (3)]` ([`Layout::instruments`],
//! [`Layout::instrument_errors`]); `δ_g`, `δ_a` are the Gauss–Markov
//! parts of the drift and the bias and `w_g`, `w_a` their warm-up, which
//! add to `dg` and `ba`.

use nalgebra::{RealField, SVector, Vector3};

use super::blocks::{block3, put3};
use super::error_model::ErrorModel;
use super::installation::{Installation, InstallationMatrices};
use super::instrument_errors::InstrumentErrors;
use crate::geometry::wrap_angles;

/// How the attitude block of the state describes the platform attitude.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AttitudeKind {
    /// Misalignment `ψ` (rad) of the platform frame p with respect to the
    /// computed frame c: `C^p_c = R(ψ)` (M1, docs/model.md §Frames).
    Misalignment,
    /// Gimbal angles `θA = (α, β, γ)` (rad): `C^p_r = R3(γ)R2(β)R1(α)`,
    /// `C^p_n = C^p_r R(λ)` (M2, M3).
    Gimbal,
    /// Attitude angles `θp = (α, β, γ)` (rad) of p with respect to n in the
    /// gimbal sequence: `C^p_n = R3(γ)R2(β)R1(α)` (M4).
    Attitude,
}

/// Which platform frame the filter estimates in (docs/model.md §Frames).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PlatformFrame {
    /// Frame defined by the platform cube; all 12 instrument angles.
    Ps,
    /// Frame defined by the accelerometer axes; `θaC ≡ 0`, 9 angles.
    Pa,
}

/// The composition of a configuration.
///
/// # Examples
///
/// Where the states of M1-pa sit, and a state vector unpacked:
///
/// ```
/// use nalgebra::{SVector, Vector3};
/// use rollcal::models::{ATT, GC, GT};
/// use rollcal::ConfigId;
///
/// let layout = ConfigId::M1Pa.layout();
/// assert_eq!((ATT, GC, GT, layout.at()), (0, 3, 6, 9));
/// assert_eq!((layout.ac(), layout.lam()), (None, None)); // pa frame, no base
///
/// let mut x = SVector::<f64, 12>::zeros();
/// x[layout.at()] = 1e-3; // θaT_1 (rad)
/// let p = layout.installation(&x);
/// assert_eq!(p.theta_a_t, Vector3::new(1e-3, 0.0, 0.0));
/// assert_eq!(p.theta_a_c, Vector3::zeros()); // θaC ≡ 0 in pa
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Layout {
    /// Attitude model.
    pub attitude: AttitudeKind,
    /// Platform frame.
    pub frame: PlatformFrame,
    /// Whether the base mounting angles `λ` are states.
    pub base: bool,
    /// Whether the gimbal angles are observed (M2).
    pub gimbal_obs: bool,
    /// Which errors the states hold after the attitude: the installation
    /// errors alone, or followed by the instruments' own (docs/model.md
    /// §Instrument errors).
    pub errors: ErrorModel,
}

/// Index of the first attitude state.
pub const ATT: usize = 0;
/// Index of the first gyro misalignment state (`θgC` or `θgC^pa`).
pub const GC: usize = 3;
/// Index of the first gyro non-orthogonality state `θgT`.
pub const GT: usize = 6;

impl Layout {
    /// Index of the first `θaC` state (ps frame only).
    pub const fn ac(&self) -> Option<usize> {
        match self.frame {
            PlatformFrame::Ps => Some(9),
            PlatformFrame::Pa => None,
        }
    }
    /// Index of the first `θaT` state.
    pub const fn at(&self) -> usize {
        match self.frame {
            PlatformFrame::Ps => 12,
            PlatformFrame::Pa => 9,
        }
    }
    /// Index of the first `λ` state (M2, M3 only).
    pub const fn lam(&self) -> Option<usize> {
        if self.base {
            Some(self.at() + 3)
        } else {
            None
        }
    }
    /// Number of states: the installation states
    /// ([`Layout::installation_n`]) and, for [`ErrorModel::Full`], 36 more.
    pub const fn n(&self) -> usize {
        self.installation_n() + self.errors.extra_states()
    }
    /// Number of installation states (attitude, instrument angles, `λ`):
    /// [`Layout::n`] of the installation-only layout.
    pub const fn installation_n(&self) -> usize {
        self.at() + 3 + if self.base { 3 } else { 0 }
    }
    /// The same composition with the error model `errors`.
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::models::ErrorModel;
    /// use rollcal::ConfigId;
    ///
    /// let full = ConfigId::M1Pa.layout().with_errors(ErrorModel::Full);
    /// assert_eq!(full, ConfigId::M1Pa.layout_with(ErrorModel::Full));
    /// assert_eq!((full.n(), full.instruments()), (48, Some(12)));
    /// assert_eq!(
    ///     (full.dg(), full.d_g(), full.kg(), full.ba(), full.ka()),
    ///     (Some(12), Some(15), Some(24), Some(27), Some(30))
    /// );
    /// assert_eq!((full.k2(), full.dg_gm(), full.ba_gm()), (Some(33), Some(36), Some(39)));
    /// assert_eq!((full.dg_wu(), full.ba_wu()), (Some(42), Some(45)));
    /// assert_eq!(ConfigId::M1Pa.layout().instruments(), None);
    /// ```
    pub const fn with_errors(self, errors: ErrorModel) -> Layout {
        Layout { errors, ..self }
    }
    /// Index of the first instrument-error state (the number of
    /// installation states), [`ErrorModel::Full`] only.
    pub const fn instruments(&self) -> Option<usize> {
        match self.errors {
            ErrorModel::Installation => None,
            ErrorModel::Full => Some(self.installation_n()),
        }
    }
    /// The index `offset` states after the first instrument-error state.
    const fn instrument_index(&self, offset: usize) -> Option<usize> {
        match self.instruments() {
            Some(i) => Some(i + offset),
            None => None,
        }
    }
    /// Index of the first constant gyro drift state `dg_x` (rad/s).
    pub const fn dg(&self) -> Option<usize> {
        self.instrument_index(0)
    }
    /// Index of the first g-sensitive drift state `Dg_xx` (`Dgpa_xx` in
    /// pa; rad/s per g; nine, row-major: row = gyro, column = force axis).
    pub const fn d_g(&self) -> Option<usize> {
        self.instrument_index(3)
    }
    /// Index of the first torquer scale-factor state `kg_x` (dimensionless).
    pub const fn kg(&self) -> Option<usize> {
        self.instrument_index(12)
    }
    /// Index of the first accelerometer bias state `ba_x` (g).
    pub const fn ba(&self) -> Option<usize> {
        self.instrument_index(15)
    }
    /// Index of the first accelerometer scale-factor state `ka_x`
    /// (dimensionless).
    pub const fn ka(&self) -> Option<usize> {
        self.instrument_index(18)
    }
    /// Index of the first accelerometer second-order state `k2_x` (g per
    /// g²).
    pub const fn k2(&self) -> Option<usize> {
        self.instrument_index(21)
    }
    /// Index of the first Gauss–Markov gyro drift state `dg_gm_x` (rad/s).
    pub const fn dg_gm(&self) -> Option<usize> {
        self.instrument_index(24)
    }
    /// Index of the first Gauss–Markov accelerometer bias state `ba_gm_x`
    /// (g).
    pub const fn ba_gm(&self) -> Option<usize> {
        self.instrument_index(27)
    }
    /// Index of the first warm-up gyro drift state `dg_wu_x` (rad/s).
    pub const fn dg_wu(&self) -> Option<usize> {
        self.instrument_index(30)
    }
    /// Index of the first warm-up accelerometer bias state `ba_wu_x` (g).
    pub const fn ba_wu(&self) -> Option<usize> {
        self.instrument_index(33)
    }
    /// Number of measurement components per period.
    pub const fn z(&self) -> usize {
        if self.gimbal_obs {
            6
        } else {
            3
        }
    }
}

impl Layout {
    /// `x − y` with the Euler attitude angles (θA, θp) wrapped into (−π, π].
    pub fn difference<T: RealField + Copy, const N: usize>(
        &self,
        x: &SVector<T, N>,
        y: &SVector<T, N>,
    ) -> SVector<T, N> {
        let mut d = x - y;
        if self.attitude != AttitudeKind::Misalignment {
            let wrapped = wrap_angles(&block3(&d, ATT));
            put3(&mut d, ATT, &wrapped);
        }
        d
    }

    /// Unpacks the installation parameters of a state vector.
    pub fn installation<T: RealField + Copy, const N: usize>(
        &self,
        x: &SVector<T, N>,
    ) -> Installation<T> {
        Installation {
            theta_g_c: block3(x, GC),
            theta_g_t: block3(x, GT),
            theta_a_c: self.ac().map_or_else(Vector3::zeros, |i| block3(x, i)),
            theta_a_t: block3(x, self.at()),
            lambda: self.lam().map_or_else(Vector3::zeros, |i| block3(x, i)),
            instruments: self.instrument_errors(x),
        }
    }

    /// Unpacks the instruments' own errors of a state vector (all zero for
    /// an [`ErrorModel::Installation`] layout), as they act: the drift
    /// `dg + δ_g + w_g` and the bias `ba + δ_a + w_a` include their
    /// Gauss–Markov parts and warm-up
    /// ([`Layout::persistent_instrument_errors`] leaves them out).
    ///
    /// # Examples
    ///
    /// ```
    /// use nalgebra::{SVector, Vector3};
    /// use rollcal::models::ErrorModel;
    /// use rollcal::ConfigId;
    ///
    /// let layout = ConfigId::M2Ps.layout_with(ErrorModel::Full);
    /// let mut x = SVector::<f64, 54>::zeros();
    /// x[layout.ba().unwrap() + 1] = 2e-5; // ba_y (g)
    /// x[layout.ba_gm().unwrap() + 1] = 1e-6; // its Gauss–Markov part (g)
    /// x[layout.d_g().unwrap() + 5] = 1e-7; // Dg_yz (rad/s per g)
    /// x[layout.k2().unwrap()] = 1.5e-5; // k2_x (g/g²)
    /// let e = layout.instrument_errors(&x);
    /// assert_eq!(e.ba, Vector3::new(0.0, 2e-5 + 1e-6, 0.0));
    /// assert_eq!(layout.persistent_instrument_errors(&x).ba, Vector3::new(0.0, 2e-5, 0.0));
    /// assert_eq!(e.d_g[(1, 2)], 1e-7);
    /// assert_eq!(e.k2.x, 1.5e-5);
    /// ```
    pub fn instrument_errors<T: RealField + Copy, const N: usize>(
        &self,
        x: &SVector<T, N>,
    ) -> InstrumentErrors<T> {
        let mut e = self.persistent_instrument_errors(x);
        if let (Some(ig), Some(ia), Some(wg), Some(wa)) =
            (self.dg_gm(), self.ba_gm(), self.dg_wu(), self.ba_wu())
        {
            e.dg += block3(x, ig) + block3(x, wg);
            e.ba += block3(x, ia) + block3(x, wa);
        }
        e
    }

    /// The instruments' own errors of a state vector without the
    /// Gauss–Markov parts and the warm-up of the drift and the bias: the values to
    /// compensate from the state's time on (the calibrated values,
    /// docs/model.md §Errors that wander).
    pub fn persistent_instrument_errors<T: RealField + Copy, const N: usize>(
        &self,
        x: &SVector<T, N>,
    ) -> InstrumentErrors<T> {
        match self.instruments() {
            None => InstrumentErrors::zeros(),
            Some(i) => {
                let (r0, r1, r2) = (block3(x, i + 3), block3(x, i + 6), block3(x, i + 9));
                InstrumentErrors {
                    dg: block3(x, i),
                    d_g: nalgebra::Matrix3::from_rows(&[
                        r0.transpose(),
                        r1.transpose(),
                        r2.transpose(),
                    ]),
                    kg: block3(x, i + 12),
                    ba: block3(x, i + 15),
                    ka: block3(x, i + 18),
                    k2: block3(x, i + 21),
                }
            }
        }
    }

    /// The attitude block of a state vector.
    pub fn attitude<T: RealField + Copy, const N: usize>(&self, x: &SVector<T, N>) -> Vector3<T> {
        block3(x, ATT)
    }

    /// The installation matrices of a state vector.
    pub fn matrices<T: RealField + Copy, const N: usize>(
        &self,
        x: &SVector<T, N>,
    ) -> InstallationMatrices<T> {
        InstallationMatrices::new(self.installation(x))
    }
}
