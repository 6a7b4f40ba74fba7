//! The seven system configurations of docs/model.md §Configurations.
//!
//! A configuration is composed of four parts:
//! - the **attitude model** ([`AttitudeKind`]): the misalignment `ψ` of the
//!   platform with respect to the computed frame (M1, `C^p_c = R(ψ)`), or the
//!   Euler angles of the platform with respect to the base (`θA`, M2/M3) or
//!   to the navigation frame (`θp`, M4), in the gimbal sequence
//!   `R3(γ) R2(β) R1(α)`;
//! - the **platform frame** ([`PlatformFrame`]): `ps` (cube) or `pa`
//!   (accelerometer axes, where `θaC ≡ 0` and the gyro misalignment is
//!   `θgC^pa`);
//! - the **base** `λ` (M2, M3): `C^r_n = R(λ)`;
//! - the **observation set**: the accelerometer mean over the period, and in
//!   M2 also the gimbal angles at the end of the period.
//!
//! [`Layout`] holds these choices; one generic implementation evaluates the
//! dynamics, the measurement and their Jacobians for any layout, and each
//! configuration is a zero-sized type implementing [`Model`] with its state
//! and measurement dimensions fixed at compile time.
//!
//! The state vector is
//! `[attitude(3), θgC or θgC^pa (3), θgT (3), θaC (3, ps only), θaT (3), λ (3, M2/M3)]`,
//! all radians: the installation states. The **full model** ([`ErrorModel::Full`],
//! docs/model.md §Instrument errors, types `M1PaFull` … `M4PsFull`) appends
//! the instruments' own errors ([`InstrumentErrors`]):
//! `[dg (3, rad/s), D_g (9, rad/s per g, row-major: row = gyro, column =
//! force axis in the model's platform frame), kg (3), ba (3, g), ka (3),
//! k2 (3, g/g²)]` and the Gauss–Markov parts of the drift and the bias
//! `[δ_g (3, rad/s), δ_a (3, g)]` and their warm-up `[w_g (3, rad/s),
//! w_a (3, g)]`, 36 more states (M1-pa 48, M2-ps 54, …). In the model's
//! platform frame p the platform rate is
//! `G [(I + K_g) ωc + dg + δ_g + w_g + D_g f^p]` and the accelerometer
//! output `ba + δ_a + w_a + (I + K_a) u + K2 (u ∘ u)`, `u = A f^p`, with
//! `f^p = C^p_n f^n` from the attitude state.
//!
//! The module by concern:
//! - `config_id`: [`ConfigId`], the seven by name, and [`ParseConfigIdError`];
//! - `error_model`: [`ErrorModel`] (installation only, or full) and
//!   [`ParseErrorModelError`];
//! - `instrument_errors`: [`InstrumentErrors`], the full model's instrument terms;
//! - `dispatch`: [`with_config!`](crate::with_config),
//!   [`with_built_config!`](crate::with_built_config) and
//!   [`with_model!`](crate::with_model), `ConfigId` (and [`ErrorModel`]) → type;
//! - `layout`: [`Layout`], [`AttitudeKind`], [`PlatformFrame`], the state
//!   indices and the unpacking of a state vector;
//! - `states`: the state names ([`StateInfo`], [`Group`]);
//! - `installation`: [`Installation`], [`InstallationMatrices`];
//! - `dynamics`: the attitude rate and its Jacobian;
//! - `measurement`: the accelerometer output at one instant and its Jacobian;
//! - `propagation`: one period's propagation ([`PeriodPropagation`]);
//! - `period_mean`: the mean accelerometer output over a period;
//! - `transition`: the transition rows `Φ` ([`transition_rows`],
//!   [`apply_transition`]);
//! - `wander`: the errors that wander ([`Wander`], [`WanderStep`]).
//!
//! # Examples
//!
//! The state and measurement dimensions of a configuration, as a type and
//! as a value:
//!
//! ```
//! use rollcal::models::{M1Pa, M2Ps, Model};
//! use rollcal::ConfigId;
//!
//! fn dimensions<M: Model<N, Z>, const N: usize, const Z: usize>() -> (usize, usize) {
//!     (N, Z)
//! }
//! assert_eq!(dimensions::<M2Ps, 18, 6>(), (18, 6));
//! assert_eq!(dimensions::<M1Pa, 12, 3>(), (12, 3));
//! assert_eq!(<M2Ps as Model<18, 6>>::ID, ConfigId::M2Ps);
//! let layout = <M2Ps as Model<18, 6>>::LAYOUT;
//! assert_eq!((layout.n(), layout.z()), (18, 6));
//! ```

use nalgebra::{RealField, Vector3};

mod blocks;
mod config_id;
mod dispatch;
mod dynamics;
mod error_model;
mod installation;
mod instrument_errors;
mod layout;
mod measurement;
mod period_mean;
mod propagation;
mod states;
mod transition;
mod wander;

pub(crate) use blocks::attitude_columns;
pub use config_id::{ConfigId, ParseConfigIdError};
pub use error_model::{ErrorModel, ParseErrorModelError};
pub use installation::{Installation, InstallationMatrices};
pub use instrument_errors::InstrumentErrors;
pub use layout::{AttitudeKind, Layout, PlatformFrame, ATT, GC, GT};
pub use propagation::PeriodPropagation;
pub use states::{Group, StateInfo};
pub use transition::{
    apply_transition, apply_transition_of, transition_rows, transition_rows_into,
};
pub use wander::{Wander, WanderStep, MAX_DECAY_EXPONENT};

/// A configuration as a type, with `N` states and `Z` measurement
/// components per period fixed at compile time.
///
/// # Examples
///
/// Code generic over the configuration reads its identifier and
/// composition from the type:
///
/// ```
/// use rollcal::models::{M3Pa, Model};
///
/// fn describe<M: Model<N, Z>, const N: usize, const Z: usize>() -> (&'static str, usize) {
///     assert_eq!(M::ID.states().len(), N);
///     assert_eq!(M::LAYOUT, M::ID.layout());
///     (M::ID.as_str(), Z)
/// }
/// assert_eq!(describe::<M3Pa, 15, 3>(), ("M3-pa", 3));
/// ```
pub trait Model<const N: usize, const Z: usize> {
    /// Which configuration this is.
    const ID: ConfigId;
    /// Which errors its states hold (installation only unless said).
    const ERRORS: ErrorModel = ErrorModel::Installation;
    /// Its composition (must agree with `ID.layout_with(ERRORS)`).
    const LAYOUT: Layout = Self::ID.layout_with(Self::ERRORS);
    /// The names, units and groups of its `N` states
    /// ([`ConfigId::states_with`] of `ID` and `ERRORS`).
    fn states() -> &'static [StateInfo] {
        Self::ID.states_with(Self::ERRORS)
    }
}

macro_rules! config_type {
    ($(#[$doc:meta])* $ty:ident, $id:ident, $n:literal, $z:literal) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        pub struct $ty;
        impl Model<$n, $z> for $ty {
            const ID: ConfigId = ConfigId::$id;
        }
    };
    (full $(#[$doc:meta])* $ty:ident, $id:ident, $n:literal, $z:literal) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        pub struct $ty;
        impl Model<$n, $z> for $ty {
            const ID: ConfigId = ConfigId::$id;
            const ERRORS: ErrorModel = ErrorModel::Full;
        }
    };
}

config_type!(
    /// M1-pa: `ψ, θgC^pa, θgT, θaT` (12 states); accelerometer observations.
    M1Pa, M1Pa, 12, 3);
config_type!(
    /// M1-ps: `ψ, θgC, θgT, θaC, θaT` (15 states); accelerometer observations.
    M1Ps, M1Ps, 15, 3);
config_type!(
    /// M2-ps: `θA, θgC, θgT, θaC, θaT, λ` (18 states); gimbal + accelerometer observations.
    M2Ps, M2Ps, 18, 6);
config_type!(
    /// M3-pa: `θA, θgC^pa, θgT, θaT, λ` (15 states); accelerometer observations.
    M3Pa, M3Pa, 15, 3);
config_type!(
    /// M3-ps: `θA, θgC, θgT, θaC, θaT, λ` (18 states); accelerometer observations.
    M3Ps, M3Ps, 18, 3);
config_type!(
    /// M4-pa: `θp, θgC^pa, θgT, θaT` (12 states); accelerometer observations.
    M4Pa, M4Pa, 12, 3);
config_type!(
    /// M4-ps: `θp, θgC, θgT, θaC, θaT` (15 states); accelerometer observations.
    M4Ps, M4Ps, 15, 3);

config_type!(full
    /// M1-pa full model (docs/model.md §Instrument errors): the 12 states
    /// of [`M1Pa`] followed by `dg, D_g^pa, kg, ba, ka, k2` and the
    /// Gauss–Markov parts `δ_g, δ_a` and warm-up `w_g, w_a` (48 states);
    /// accelerometer observations.
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::models::{ErrorModel, M1PaFull, Model};
    /// use rollcal::ConfigId;
    ///
    /// type M = M1PaFull;
    /// assert_eq!(<M as Model<48, 3>>::ID, ConfigId::M1Pa);
    /// assert_eq!(<M as Model<48, 3>>::ERRORS, ErrorModel::Full);
    /// let layout = <M as Model<48, 3>>::LAYOUT;
    /// assert_eq!((layout.n(), layout.z(), layout.instruments()), (48, 3, Some(12)));
    /// let states = <M as Model<48, 3>>::states();
    /// assert_eq!((states[12].name, states[15].name, states[32].name), ("dg_x", "Dgpa_xx", "ka_z"));
    /// assert_eq!((states[35].name, states[36].name, states[41].name), ("k2_z", "dg_gm_x", "ba_gm_z"));
    /// assert_eq!((states[42].name, states[47].name), ("dg_wu_x", "ba_wu_z"));
    /// ```
    M1PaFull, M1Pa, 48, 3);
config_type!(full
    /// M1-ps full model: [`M1Ps`]'s 15 states and the 36 instrument states (51 states).
    M1PsFull, M1Ps, 51, 3);
config_type!(full
    /// M2-ps full model: [`M2Ps`]'s 18 states and the 36 instrument states (54 states);
    /// gimbal + accelerometer observations.
    M2PsFull, M2Ps, 54, 6);
config_type!(full
    /// M3-pa full model: [`M3Pa`]'s 15 states and the 36 instrument states (51 states).
    M3PaFull, M3Pa, 51, 3);
config_type!(full
    /// M3-ps full model: [`M3Ps`]'s 18 states and the 36 instrument states (54 states).
    M3PsFull, M3Ps, 54, 3);
config_type!(full
    /// M4-pa full model: [`M4Pa`]'s 12 states and the 36 instrument states (48 states).
    M4PaFull, M4Pa, 48, 3);
config_type!(full
    /// M4-ps full model: [`M4Ps`]'s 15 states and the 36 instrument states (51 states).
    M4PsFull, M4Ps, 51, 3);

/// The environment every model needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Environment<T: RealField + Copy> {
    /// Earth rate in the navigation frame, `ω^n_ie` (rad/s).
    pub earth_rate_n: Vector3<T>,
    /// Specific force at rest in the navigation frame, `f^n` (g).
    pub gravity_n: Vector3<T>,
}

impl Environment<f64> {
    /// The same environment in precision `U`, each value rounded once.
    pub fn to_precision<U: RealField + Copy>(&self) -> Environment<U> {
        Environment {
            earth_rate_n: self.earth_rate_n.map(nalgebra::convert::<f64, U>),
            gravity_n: self.gravity_n.map(nalgebra::convert::<f64, U>),
        }
    }
}
