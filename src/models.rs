//! The seven system configurations of docs/model.md §Configurations (paper §1.3).
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
//! All states are radians. The state vector is
//! `[attitude(3), θgC or θgC^pa (3), θgT (3), θaC (3, ps only), θaT (3), λ (3, M2/M3)]`.

use nalgebra::{Const, Matrix, Matrix3, RealField, SMatrix, SVector, StorageMut, Vector3, U3};

use crate::command::Period;
use crate::geometry::{
    d_lower_times, dcm, dcm_and_right_jacobian, dcm_deviation, gimbal_dcm, gimbal_rate_inverse,
    right_jacobian, right_jacobian_inv, skew, wrap_angles, EulerTrig,
};
use crate::precision::{to_f64, to_t};

/// How the attitude block of the state describes the platform attitude.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AttitudeKind {
    /// Misalignment `ψ` (rad) of the platform frame p with respect to the
    /// computed frame c: `C^p_c = R(ψ)` (M1, paper eq. 11).
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
    /// Number of states.
    pub const fn n(&self) -> usize {
        self.at() + 3 + if self.base { 3 } else { 0 }
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

/// The seven configurations of docs/model.md §Configurations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(serde::Serialize, serde::Deserialize)]
pub enum ConfigId {
    /// Misalignment dynamics, accelerometer observations, pa frame (12 states).
    M1Pa,
    /// Misalignment dynamics, accelerometer observations, ps frame (15 states).
    M1Ps,
    /// Gimbal-angle dynamics, gimbal + accelerometer observations, ps (18 states).
    M2Ps,
    /// Gimbal-angle dynamics, accelerometer observations, pa (15 states).
    M3Pa,
    /// Gimbal-angle dynamics, accelerometer observations, ps (18 states).
    M3Ps,
    /// Attitude-angle dynamics, accelerometer observations, pa (12 states).
    M4Pa,
    /// Attitude-angle dynamics, accelerometer observations, ps (15 states).
    M4Ps,
}

/// The one `ConfigId` → configuration-type dispatch: evaluates `body` with
/// `M` the configuration's model type and `N`, `Z` its state and measurement
/// dimensions as `const`s, for the configuration `id` names.
///
/// ```
/// use rollcal::models::{ConfigId, Model};
/// fn states<M: Model<N, Z>, const N: usize, const Z: usize>() -> usize {
///     N
/// }
/// let n = rollcal::with_config!(ConfigId::M2Ps, |M, N, Z| states::<M, N, Z>());
/// assert_eq!(n, 18);
/// ```
#[macro_export]
macro_rules! with_config {
    ($id:expr, |$m:ident, $n:ident, $z:ident| $body:expr) => {
        match $id {
            $crate::models::ConfigId::M1Pa => $crate::with_config!(@arm M1Pa, 12, 3, $m, $n, $z, $body),
            $crate::models::ConfigId::M1Ps => $crate::with_config!(@arm M1Ps, 15, 3, $m, $n, $z, $body),
            $crate::models::ConfigId::M2Ps => $crate::with_config!(@arm M2Ps, 18, 6, $m, $n, $z, $body),
            $crate::models::ConfigId::M3Pa => $crate::with_config!(@arm M3Pa, 15, 3, $m, $n, $z, $body),
            $crate::models::ConfigId::M3Ps => $crate::with_config!(@arm M3Ps, 18, 3, $m, $n, $z, $body),
            $crate::models::ConfigId::M4Pa => $crate::with_config!(@arm M4Pa, 12, 3, $m, $n, $z, $body),
            $crate::models::ConfigId::M4Ps => $crate::with_config!(@arm M4Ps, 15, 3, $m, $n, $z, $body),
        }
    };
    (@arm $ty:ident, $nv:literal, $zv:literal, $m:ident, $n:ident, $z:ident, $body:expr) => {{
        #[allow(non_camel_case_types, dead_code)]
        type $m = $crate::models::$ty;
        #[allow(non_upper_case_globals, dead_code)]
        const $n: usize = $nv;
        #[allow(non_upper_case_globals, dead_code)]
        const $z: usize = $zv;
        $body
    }};
}

// One helper macro per configuration, defined by the cargo feature of *this*
// crate (`#[cfg]` inside an exported macro would test the caller's
// features): it passes its tokens through when the configuration is built,
// and drops them otherwise.
#[cfg(feature = "m1-pa")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m1_pa {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m1-pa"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m1_pa {
    ($($t:tt)*) => {};
}
#[cfg(feature = "m1-ps")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m1_ps {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m1-ps"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m1_ps {
    ($($t:tt)*) => {};
}
#[cfg(feature = "m2-ps")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m2_ps {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m2-ps"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m2_ps {
    ($($t:tt)*) => {};
}
#[cfg(feature = "m3-pa")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m3_pa {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m3-pa"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m3_pa {
    ($($t:tt)*) => {};
}
#[cfg(feature = "m3-ps")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m3_ps {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m3-ps"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m3_ps {
    ($($t:tt)*) => {};
}
#[cfg(feature = "m4-pa")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m4_pa {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m4-pa"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m4_pa {
    ($($t:tt)*) => {};
}
#[cfg(feature = "m4-ps")]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m4_ps {
    ($($t:tt)*) => { $($t)* };
}
#[cfg(not(feature = "m4-ps"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __rollcal_if_m4_ps {
    ($($t:tt)*) => {};
}

#[cfg(not(any(
    feature = "m1-pa",
    feature = "m1-ps",
    feature = "m2-ps",
    feature = "m3-pa",
    feature = "m3-ps",
    feature = "m4-pa",
    feature = "m4-ps"
)))]
compile_error!("rollcal: enable at least one configuration feature (m1-pa, m1-ps, m2-ps, m3-pa, m3-ps, m4-pa, m4-ps; the default `all-configs` enables the seven)");

/// [`with_config!`] over the configurations built into this crate (cargo
/// features `m1-pa` … `m4-ps`; the default `all-configs` has the seven):
/// only their arms are instantiated, and `fallback` is evaluated, with
/// `other` the [`ConfigId`], for a configuration left out. A firmware image
/// built with one configuration feature then holds one configuration's code.
///
/// ```
/// use rollcal::models::{ConfigId, Model};
/// fn states<M: Model<N, Z>, const N: usize, const Z: usize>() -> Option<usize> {
///     Some(N)
/// }
/// let n = rollcal::with_built_config!(ConfigId::M1Pa, |M, N, Z| states::<M, N, Z>(), else |_other| None);
/// assert_eq!(n, Some(12));
/// ```
#[macro_export]
macro_rules! with_built_config {
    ($id:expr, |$m:ident, $n:ident, $z:ident| $body:expr, else |$other:ident| $fallback:expr) => {{
        let id: $crate::models::ConfigId = $id;
        'dispatch: {
            $crate::__rollcal_if_m1_pa! { if id == $crate::models::ConfigId::M1Pa { break 'dispatch $crate::with_config!(@arm M1Pa, 12, 3, $m, $n, $z, $body); } }
            $crate::__rollcal_if_m1_ps! { if id == $crate::models::ConfigId::M1Ps { break 'dispatch $crate::with_config!(@arm M1Ps, 15, 3, $m, $n, $z, $body); } }
            $crate::__rollcal_if_m2_ps! { if id == $crate::models::ConfigId::M2Ps { break 'dispatch $crate::with_config!(@arm M2Ps, 18, 6, $m, $n, $z, $body); } }
            $crate::__rollcal_if_m3_pa! { if id == $crate::models::ConfigId::M3Pa { break 'dispatch $crate::with_config!(@arm M3Pa, 15, 3, $m, $n, $z, $body); } }
            $crate::__rollcal_if_m3_ps! { if id == $crate::models::ConfigId::M3Ps { break 'dispatch $crate::with_config!(@arm M3Ps, 18, 3, $m, $n, $z, $body); } }
            $crate::__rollcal_if_m4_pa! { if id == $crate::models::ConfigId::M4Pa { break 'dispatch $crate::with_config!(@arm M4Pa, 12, 3, $m, $n, $z, $body); } }
            $crate::__rollcal_if_m4_ps! { if id == $crate::models::ConfigId::M4Ps { break 'dispatch $crate::with_config!(@arm M4Ps, 15, 3, $m, $n, $z, $body); } }
            #[allow(unreachable_code)]
            {
                let $other = id;
                $fallback
            }
        }
    }};
}

impl ConfigId {
    /// All seven, in the order of docs/model.md §Configurations.
    pub const ALL: [ConfigId; 7] = [
        ConfigId::M1Pa,
        ConfigId::M1Ps,
        ConfigId::M2Ps,
        ConfigId::M3Pa,
        ConfigId::M3Ps,
        ConfigId::M4Pa,
        ConfigId::M4Ps,
    ];

    /// Whether this build holds the configuration: its cargo feature
    /// (`m1-pa` … `m4-ps`, all seven by default) is on. `Session` refuses a
    /// `Configure` for one that is not, and [`with_built_config!`] takes its
    /// fallback.
    pub const fn is_built(self) -> bool {
        match self {
            ConfigId::M1Pa => cfg!(feature = "m1-pa"),
            ConfigId::M1Ps => cfg!(feature = "m1-ps"),
            ConfigId::M2Ps => cfg!(feature = "m2-ps"),
            ConfigId::M3Pa => cfg!(feature = "m3-pa"),
            ConfigId::M3Ps => cfg!(feature = "m3-ps"),
            ConfigId::M4Pa => cfg!(feature = "m4-pa"),
            ConfigId::M4Ps => cfg!(feature = "m4-ps"),
        }
    }

    /// The first configuration of this build, in the order of docs/model.md
    /// §Configurations (the one a
    /// one-configuration build runs).
    pub const fn first_built() -> ConfigId {
        use ConfigId::*;
        // A build without any configuration does not compile: M4-ps is then
        // the only one left.
        match () {
            () if M1Pa.is_built() => M1Pa,
            () if M1Ps.is_built() => M1Ps,
            () if M2Ps.is_built() => M2Ps,
            () if M3Pa.is_built() => M3Pa,
            () if M3Ps.is_built() => M3Ps,
            () if M4Pa.is_built() => M4Pa,
            () => M4Ps,
        }
    }

    /// The identifier (docs/model.md §Configurations), e.g. `"M2-ps"`.
    pub const fn as_str(self) -> &'static str {
        match self {
            ConfigId::M1Pa => "M1-pa",
            ConfigId::M1Ps => "M1-ps",
            ConfigId::M2Ps => "M2-ps",
            ConfigId::M3Pa => "M3-pa",
            ConfigId::M3Ps => "M3-ps",
            ConfigId::M4Pa => "M4-pa",
            ConfigId::M4Ps => "M4-ps",
        }
    }

    /// Parses an identifier (docs/model.md §Configurations), case-insensitively (`m2-ps` = `M2-ps`).
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|c| c.as_str().eq_ignore_ascii_case(s))
    }

    /// The configuration's composition.
    pub const fn layout(self) -> Layout {
        use AttitudeKind::*;
        use PlatformFrame::*;
        let (attitude, frame, base, gimbal_obs) = match self {
            ConfigId::M1Pa => (Misalignment, Pa, false, false),
            ConfigId::M1Ps => (Misalignment, Ps, false, false),
            ConfigId::M2Ps => (Gimbal, Ps, true, true),
            ConfigId::M3Pa => (Gimbal, Pa, true, false),
            ConfigId::M3Ps => (Gimbal, Ps, true, false),
            ConfigId::M4Pa => (Attitude, Pa, false, false),
            ConfigId::M4Ps => (Attitude, Ps, false, false),
        };
        Layout {
            attitude,
            frame,
            base,
            gimbal_obs,
        }
    }

    /// The names, units and groups of the states, in state order.
    pub fn states(self) -> &'static [StateInfo] {
        match self {
            ConfigId::M1Pa => &M1_PA_STATES,
            ConfigId::M1Ps => &M1_PS_STATES,
            ConfigId::M2Ps => &M2_PS_STATES,
            ConfigId::M3Pa => &M3_PA_STATES,
            ConfigId::M3Ps => &M3_PS_STATES,
            ConfigId::M4Pa => &M4_PA_STATES,
            ConfigId::M4Ps => &M4_PS_STATES,
        }
    }
}

impl core::fmt::Display for ConfigId {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The physical group a state belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Group {
    /// Platform attitude: `ψ`, `θA` or `θp` (time-varying).
    Attitude,
    /// Gyro misalignment `θgC` (ps) or `θgC^pa` (pa).
    ThetaGC,
    /// Gyro non-orthogonality `θgT`.
    ThetaGT,
    /// Accelerometer misalignment `θaC` (ps only).
    ThetaAC,
    /// Accelerometer non-orthogonality `θaT`.
    ThetaAT,
    /// Base mounting angles `λ`.
    Lambda,
}

impl Group {
    /// The stable name used in JSON/CSV output.
    pub const fn as_str(self) -> &'static str {
        match self {
            Group::Attitude => "attitude",
            Group::ThetaGC => "thgC",
            Group::ThetaGT => "thgT",
            Group::ThetaAC => "thaC",
            Group::ThetaAT => "thaT",
            Group::Lambda => "lam",
        }
    }

    /// The group of a stable name (the inverse of [`Group::as_str`]).
    pub fn from_name(name: &str) -> Option<Self> {
        [
            Group::Attitude,
            Group::ThetaGC,
            Group::ThetaGT,
            Group::ThetaAC,
            Group::ThetaAT,
            Group::Lambda,
        ]
        .into_iter()
        .find(|g| g.as_str() == name)
    }
}

/// Name, unit and group of one state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StateInfo {
    /// The ASCII name of the symbol (docs/model.md §State names), e.g. `thgC_x`, `thaT_1`, `lam_z`: a stable
    /// interface of the JSON/CSV outputs.
    pub name: &'static str,
    /// Unit of the state (always `"rad"`).
    pub unit: &'static str,
    /// Physical group.
    pub group: Group,
}

const fn s(name: &'static str, group: Group) -> StateInfo {
    StateInfo {
        name,
        unit: "rad",
        group,
    }
}

macro_rules! states {
    ($($name:literal : $group:ident),* $(,)?) => { [$(s($name, Group::$group)),*] };
}

const M1_PA_STATES: [StateInfo; 12] = states![
    "psi_x": Attitude, "psi_y": Attitude, "psi_z": Attitude,
    "thgCpa_x": ThetaGC, "thgCpa_y": ThetaGC, "thgCpa_z": ThetaGC,
    "thgT_1": ThetaGT, "thgT_2": ThetaGT, "thgT_3": ThetaGT,
    "thaT_1": ThetaAT, "thaT_2": ThetaAT, "thaT_3": ThetaAT,
];
const M1_PS_STATES: [StateInfo; 15] = states![
    "psi_x": Attitude, "psi_y": Attitude, "psi_z": Attitude,
    "thgC_x": ThetaGC, "thgC_y": ThetaGC, "thgC_z": ThetaGC,
    "thgT_1": ThetaGT, "thgT_2": ThetaGT, "thgT_3": ThetaGT,
    "thaC_x": ThetaAC, "thaC_y": ThetaAC, "thaC_z": ThetaAC,
    "thaT_1": ThetaAT, "thaT_2": ThetaAT, "thaT_3": ThetaAT,
];
const M2_PS_STATES: [StateInfo; 18] = states![
    "thA_alpha": Attitude, "thA_beta": Attitude, "thA_gamma": Attitude,
    "thgC_x": ThetaGC, "thgC_y": ThetaGC, "thgC_z": ThetaGC,
    "thgT_1": ThetaGT, "thgT_2": ThetaGT, "thgT_3": ThetaGT,
    "thaC_x": ThetaAC, "thaC_y": ThetaAC, "thaC_z": ThetaAC,
    "thaT_1": ThetaAT, "thaT_2": ThetaAT, "thaT_3": ThetaAT,
    "lam_x": Lambda, "lam_y": Lambda, "lam_z": Lambda,
];
const M3_PA_STATES: [StateInfo; 15] = states![
    "thA_alpha": Attitude, "thA_beta": Attitude, "thA_gamma": Attitude,
    "thgCpa_x": ThetaGC, "thgCpa_y": ThetaGC, "thgCpa_z": ThetaGC,
    "thgT_1": ThetaGT, "thgT_2": ThetaGT, "thgT_3": ThetaGT,
    "thaT_1": ThetaAT, "thaT_2": ThetaAT, "thaT_3": ThetaAT,
    "lam_x": Lambda, "lam_y": Lambda, "lam_z": Lambda,
];
const M3_PS_STATES: [StateInfo; 18] = M2_PS_STATES;
const M4_PA_STATES: [StateInfo; 12] = states![
    "thp_alpha": Attitude, "thp_beta": Attitude, "thp_gamma": Attitude,
    "thgCpa_x": ThetaGC, "thgCpa_y": ThetaGC, "thgCpa_z": ThetaGC,
    "thgT_1": ThetaGT, "thgT_2": ThetaGT, "thgT_3": ThetaGT,
    "thaT_1": ThetaAT, "thaT_2": ThetaAT, "thaT_3": ThetaAT,
];
const M4_PS_STATES: [StateInfo; 15] = states![
    "thp_alpha": Attitude, "thp_beta": Attitude, "thp_gamma": Attitude,
    "thgC_x": ThetaGC, "thgC_y": ThetaGC, "thgC_z": ThetaGC,
    "thgT_1": ThetaGT, "thgT_2": ThetaGT, "thgT_3": ThetaGT,
    "thaC_x": ThetaAC, "thaC_y": ThetaAC, "thaC_z": ThetaAC,
    "thaT_1": ThetaAT, "thaT_2": ThetaAT, "thaT_3": ThetaAT,
];

/// A configuration as a type, with `N` states and `Z` measurement
/// components per period fixed at compile time.
pub trait Model<const N: usize, const Z: usize> {
    /// Which configuration this is.
    const ID: ConfigId;
    /// Its composition (must agree with `ID.layout()`).
    const LAYOUT: Layout = Self::ID.layout();
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

/// The environment every model needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Environment<T: RealField + Copy> {
    /// Earth rate in the navigation frame, `ω^n_ie` (rad/s).
    pub earth_rate_n: Vector3<T>,
    /// Specific force at rest in the navigation frame, `f^n` (g).
    pub gravity_n: Vector3<T>,
}

/// Installation parameters unpacked from a state vector (rad); absent ones
/// are zero.
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
}

fn block3<T: RealField + Copy, const N: usize>(x: &SVector<T, N>, i: usize) -> Vector3<T> {
    Vector3::new(
        x.get(i).copied().unwrap_or_else(T::zero),
        x.get(i + 1).copied().unwrap_or_else(T::zero),
        x.get(i + 2).copied().unwrap_or_else(T::zero),
    )
}

/// The attitude columns of `m` (its first three, [`ATT`]), copied, on the
/// column arrays. Not `fixed_columns(..).clone_owned()` nor column
/// iterators: those go through nalgebra's allocation from an iterator or
/// its view constructors, whose checks are panic paths when the compiler
/// does not inline them (`tools/panic-check.py` found them).
pub(crate) fn attitude_columns<T: RealField + Copy, const R: usize, const N: usize>(
    m: &SMatrix<T, R, N>,
) -> SMatrix<T, R, 3> {
    let mut out = SMatrix::<T, R, 3>::zeros();
    for (dst, src) in out.data.0.iter_mut().zip(m.data.0.iter().skip(ATT)) {
        *dst = *src;
    }
    out
}

/// The attitude rows of `m` (its first three, [`ATT`]), copied (see
/// [`attitude_columns`]).
pub(crate) fn attitude_rows<T: RealField + Copy, const R: usize, const C: usize>(
    m: &SMatrix<T, R, C>,
) -> SMatrix<T, 3, C> {
    let mut out = SMatrix::<T, 3, C>::zeros();
    for (dst, src) in out.data.0.iter_mut().zip(m.data.0.iter()) {
        for (d, s) in dst.iter_mut().zip(src.iter().skip(ATT)) {
            *d = *s;
        }
    }
    out
}

fn put3<T: RealField + Copy, const N: usize>(x: &mut SVector<T, N>, i: usize, v: &Vector3<T>) {
    for (k, val) in v.iter().enumerate() {
        if let Some(dst) = x.get_mut(i + k) {
            *dst = *val;
        }
    }
}

/// Columns `col..col + 3` of `m` := `block` (columns past `N` are dropped).
///
/// On the column arrays of the storage (column-major `[[T; R]; N]`), not a
/// view: `columns_mut(col, 3)` asserts its runtime offset (a panic path
/// into `core::panicking` in the firmware, tools/panic-check.py); the
/// zipped iterators have no bounds check at all.
fn set_cols<T: RealField + Copy, const R: usize, const N: usize>(
    m: &mut SMatrix<T, R, N>,
    col: usize,
    block: &SMatrix<T, R, 3>,
) {
    for (dst, src) in m.data.0.iter_mut().skip(col).zip(block.data.0.iter()) {
        *dst = *src;
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
        let unit_g_t = Matrix3::identity() + crate::geometry::lower(&params.theta_g_t);
        let (r_a_c, jr_a_c) = dcm_and_right_jacobian(&-params.theta_a_c);
        let unit_a_t = Matrix3::identity() + crate::geometry::lower(&params.theta_a_t);
        let (c_rn, jr_lambda) = dcm_and_right_jacobian(&params.lambda);
        Self {
            // The products of gyro_matrix and accel_matrix, on the same factors.
            g: r_g_c * unit_g_t,
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
    /// mean specific force, [`Layout::mean_accel_output`]).
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
            },
            g: m(&self.g),
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

    /// The platform attitude `C^p_n` of attitude states `att` (rad), given
    /// the computed frame `c_cn` (used by M1 only) and `C^r_n` (M2/M3).
    pub fn platform_dcm<T: RealField + Copy>(
        &self,
        att: &Vector3<T>,
        c_rn: &Matrix3<T>,
        c_cn: &Matrix3<T>,
    ) -> Matrix3<T> {
        match self.attitude {
            AttitudeKind::Misalignment => dcm(att) * c_cn,
            AttitudeKind::Gimbal => gimbal_dcm(att) * c_rn,
            AttitudeKind::Attitude => gimbal_dcm(att),
        }
    }

    /// The attitude-state rate (rad/s) at attitude `att` under commanded rate
    /// `omega_c` (docs/model.md §Configurations): M1 `ψ̇ = J_r⁻¹(ψ)(G ωc − R(ψ) ωc)`;
    /// M2/M3 `θ̇A = T(θA)[G ωc − C^p_r R(λ) ω^n_ie]`;
    /// M4 `θ̇p = T(θp)[G ωc − C^p_n ω^n_ie]`. `None` at gimbal lock.
    pub fn attitude_rate<T: RealField + Copy>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        omega_c: &Vector3<T>,
    ) -> Option<Vector3<T>> {
        let w_ip = m.g * omega_c;
        match self.attitude {
            AttitudeKind::Misalignment => {
                Some(right_jacobian_inv(att) * (w_ip - dcm(att) * omega_c))
            }
            AttitudeKind::Gimbal | AttitudeKind::Attitude => {
                let trig = EulerTrig::new(att);
                let t = trig.rate_inverse()?;
                let c_pn = trig.dcm() * m.c_rn;
                Some(t * (w_ip - c_pn * env.earth_rate_n))
            }
        }
    }

    /// `∂(attitude rate)/∂x` (3×N) at state `x`: the rows of the continuous
    /// system matrix `F` that are not zero (parameters are constant).
    pub fn attitude_rate_jacobian<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        omega_c: &Vector3<T>,
    ) -> Option<SMatrix<T, 3, N>> {
        let mut f = SMatrix::<T, 3, N>::zeros();
        self.attitude_rate_jacobian_into(env, m, att, omega_c, &mut f)?;
        Some(f)
    }

    /// [`Layout::attitude_rate_jacobian`] written into `f` (every entry;
    /// `None` at gimbal lock, `f` then unspecified): no 3×N copy of the
    /// result where the caller keeps it.
    pub fn attitude_rate_jacobian_into<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        omega_c: &Vector3<T>,
        f: &mut SMatrix<T, 3, N>,
    ) -> Option<()> {
        f.fill(T::zero());
        // ∂(G ωc)/∂θgC and ∂(G ωc)/∂θgT.
        let d_g_c =
            InstallationMatrices::d_rotation_times(&m.r_g_c, &m.jr_g_c, &(m.unit_g_t * omega_c));
        let d_g_t = m.r_g_c * d_lower_times(omega_c);
        let w_ip = m.g * omega_c;
        match self.attitude {
            AttitudeKind::Misalignment => {
                let jinv = right_jacobian_inv(att);
                let r_wc = dcm(att) * omega_c;
                let w_cp = w_ip - r_wc;
                // ∂(J_r⁻¹(ψ) w)/∂ψ to second order: −½[w×] − (1/12)([(ψ×w)×] + [ψ×][w×]).
                let two: T = nalgebra::convert(2.0);
                let twelve: T = nalgebra::convert(12.0);
                let d_jinv = -skew(&w_cp) / two
                    - (skew(&att.cross(&w_cp)) + skew(att) * skew(&w_cp)) / twelve;
                let d_att = d_jinv - jinv * skew(&r_wc) * right_jacobian(att);
                set_cols(f, ATT, &d_att);
                set_cols(f, GC, &(jinv * d_g_c));
                set_cols(f, GT, &(jinv * d_g_t));
            }
            AttitudeKind::Gimbal | AttitudeKind::Attitude => {
                let trig = EulerTrig::new(att);
                let t = trig.rate_inverse()?;
                let c = trig.dcm();
                let rl_w = m.c_rn * env.earth_rate_n;
                let w = w_ip - c * rl_w;
                let d_att = trig.d_rate_inverse_times(&t, &w) - t * trig.d_dcm_times(&c, &rl_w);
                set_cols(f, ATT, &d_att);
                set_cols(f, GC, &(t * d_g_c));
                set_cols(f, GT, &(t * d_g_t));
                if let Some(il) = self.lam() {
                    let d_lam = -(t
                        * c
                        * InstallationMatrices::d_rotation_times(
                            &m.c_rn,
                            &m.jr_lambda,
                            &env.earth_rate_n,
                        ));
                    set_cols(f, il, &d_lam);
                }
            }
        }
        Some(())
    }

    /// The accelerometer output `Z_a = A C^p_n f^n` (g) at one instant.
    pub fn accel_output<T: RealField + Copy>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
    ) -> Vector3<T> {
        m.a * (self.platform_dcm(att, &m.c_rn, c_cn) * env.gravity_n)
    }

    /// `∂Z_a/∂x` (3×N) at one instant.
    pub fn accel_jacobian<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
    ) -> SMatrix<T, 3, N> {
        self.accel_output_and_jacobian(env, m, att, c_cn).1
    }

    /// [`Layout::accel_output`] and [`Layout::accel_jacobian`] together,
    /// on one evaluation of the attitude's rotation (the same values as
    /// the two apart).
    pub fn accel_output_and_jacobian<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
    ) -> (Vector3<T>, SMatrix<T, 3, N>) {
        let mut h = SMatrix::<T, 3, N>::zeros();
        let z = self.accel_output_and_jacobian_into(env, m, att, c_cn, &mut h);
        (z, h)
    }

    /// [`Layout::accel_output_and_jacobian`] with the Jacobian written into
    /// `h` (every entry): no 3×N copy of it where the caller keeps it.
    // Out of line: inlined into `mean_accel`'s loop over the nodes, LLVM
    // unrolled the lot into a 1.5 KB frame of spilled addresses (the M4F's
    // linearised M1-pa period went from 42 k to 93 k instructions).
    #[inline(never)]
    pub fn accel_output_and_jacobian_into<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
        h: &mut SMatrix<T, 3, N>,
    ) -> Vector3<T> {
        h.fill(T::zero());
        let g = &env.gravity_n;
        // The attitude's rotation (R(ψ) or C(θ)) and ∂(C^p_n f^n)/∂att.
        let (rot, d_att) = match self.attitude {
            AttitudeKind::Misalignment => {
                let rot = dcm(att);
                (rot, skew(&(rot * (c_cn * g))) * right_jacobian(att))
            }
            AttitudeKind::Gimbal => {
                let trig = EulerTrig::new(att);
                let c = trig.dcm();
                (c, trig.d_dcm_times(&c, &(m.c_rn * g)))
            }
            AttitudeKind::Attitude => {
                let trig = EulerTrig::new(att);
                let c = trig.dcm();
                (c, trig.d_dcm_times(&c, g))
            }
        };
        let c_pn = match self.attitude {
            AttitudeKind::Misalignment => rot * c_cn,
            AttitudeKind::Gimbal => rot * m.c_rn,
            AttitudeKind::Attitude => rot,
        };
        let f_p = c_pn * g;
        set_cols(h, ATT, &(m.a * d_att));
        let f_a = m.r_a_c * f_p;
        if let Some(ic) = self.ac() {
            // ∂(R(−θ) v)/∂θ = −∂(R(φ) v)/∂φ at φ = −θ.
            set_cols(
                h,
                ic,
                &(-(m.unit_a_t
                    * InstallationMatrices::d_rotation_times(&m.r_a_c, &m.jr_a_c, &f_p))),
            );
        }
        set_cols(h, self.at(), &d_lower_times(&f_a));
        if let (Some(il), AttitudeKind::Gimbal) = (self.lam(), self.attitude) {
            let d_lam = m.a
                * rot
                * InstallationMatrices::d_rotation_times(&m.c_rn, &m.jr_lambda, &env.gravity_n);
            set_cols(h, il, &d_lam);
        }
        m.a * f_p
    }
}

/// The state trajectory over one period at the nodes `t_k`, `t_k + T/2`,
/// `t_k + T`, and the discrete transition of the attitude block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeriodPropagation<T: RealField + Copy, const N: usize> {
    /// Attitude states at the three nodes (rad).
    pub att: [Vector3<T>; 3],
    /// Rows of `Φ = ∂x_{k+1}/∂x_k` for the attitude block (3×N); the
    /// parameter rows of `Φ` are the identity.
    pub phi_att: SMatrix<T, 3, N>,
    /// `F` rows (3×N) at the midpoint node.
    pub f_mid: SMatrix<T, 3, N>,
    /// `F` rows (3×N) at the end node.
    pub f_end: SMatrix<T, 3, N>,
    /// `B = ∂(attitude rate)/∂(platform rate noise)` at the midpoint (3×3).
    pub noise_map: Matrix3<T>,
}

impl<T: RealField + Copy, const N: usize> PeriodPropagation<T, N> {
    /// All zeros (storage to propagate into, [`Layout::propagate_into`]).
    pub fn zeros() -> Self {
        Self {
            att: [Vector3::zeros(); 3],
            phi_att: SMatrix::zeros(),
            f_mid: SMatrix::zeros(),
            f_end: SMatrix::zeros(),
            noise_map: Matrix3::zeros(),
        }
    }
}

impl Layout {
    /// Propagates the attitude over one period by one RK4 step driven by the
    /// commanded rate at the period's nodes; the midpoint state comes from the
    /// cubic Hermite interpolant (error ≈ T⁴|x⁽⁴⁾|/384 < 1e-14 rad). The
    /// transition rows use the midpoint Jacobian, `Φ = exp(F T)` to second
    /// order. `None` at gimbal lock or on non-finite values.
    pub fn propagate<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att0: &Vector3<T>,
        period: &Period<T>,
    ) -> Option<PeriodPropagation<T, N>> {
        let mut out = PeriodPropagation::zeros();
        self.propagate_into(env, m, att0, period, &mut out)?;
        Some(out)
    }

    /// [`Layout::propagate`] written into `out`. On `None` `out` holds a
    /// partial result.
    pub fn propagate_into<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att0: &Vector3<T>,
        period: &Period<T>,
        out: &mut PeriodPropagation<T, N>,
    ) -> Option<()> {
        let mut att = [Vector3::zeros(); 3];
        self.propagate_into_jacobians_in(env, m, att0, period, &mut att, out)
    }

    /// [`Layout::propagate_into`] with the attitude held in precision `P`
    /// and everything else evaluated in precision `J` on `env_j` and `m_j`
    /// (the environment and installation matrices in `J`): the attitude at
    /// the three nodes into `att` (in `P`), the same rounded to `J` and the
    /// Jacobians into `out`; for `J = P` the conversions are the identity,
    /// which is [`Layout::propagate_into`]. In `J`: the attitude's
    /// increments over the period (the RK4 stages) and the Jacobians (`F` at
    /// the midpoint and the end, the transition rows, the noise map). A
    /// single-precision filter (the filter's pending slot, `P = f64`,
    /// `J = f32`) needs its Jacobians to a few digits only, and the
    /// increments are small: ≈ 1.7e-3 rad per period on the paper's path
    /// (0.1 °/s, 1 s), exact in f32 to ≈ 3e-7 of themselves, ≈ 5e-10 rad,
    /// three orders of magnitude under the paper's gyro noise over a period
    /// (0.1 °/h · 1 s ≈ 4.8e-7 rad). On an FPU without double precision
    /// they would otherwise be emulated f64.
    pub fn propagate_into_jacobians_in<P: RealField + Copy, J: RealField + Copy, const N: usize>(
        &self,
        env_j: &Environment<J>,
        m_j: &InstallationMatrices<J>,
        att0: &Vector3<P>,
        period: &Period<J>,
        att: &mut [Vector3<P>; 3],
        out: &mut PeriodPropagation<J, N>,
    ) -> Option<()> {
        let [_, wm, w1] = &period.omega_c;
        let [_, att_mid, att1] = self.trajectory(env_j, m_j, att0, period)?;
        let (att_mid_j, att1_j) = (vector_in(&att_mid)?, vector_in(&att1)?);
        self.attitude_rate_jacobian_into(env_j, m_j, &att_mid_j, wm, &mut out.f_mid)?;
        self.attitude_rate_jacobian_into(env_j, m_j, &att1_j, w1, &mut out.f_end)?;
        transition_rows_into(&out.f_mid, period.dt, &mut out.phi_att);
        out.noise_map = self.noise_map(&att_mid_j)?;
        out.att = [vector_in(att0)?, att_mid_j, att1_j];
        *att = [*att0, att_mid, att1];
        if att1.iter().all(|v| v.is_finite()) && out.phi_att.iter().all(|v| v.is_finite()) {
            Some(())
        } else {
            None
        }
    }

    /// The attitude at the period's three nodes: one RK4 step driven by the
    /// commanded rate at the nodes, the midpoint from the cubic Hermite
    /// interpolant (see [`Layout::propagate`]); `None` at gimbal lock. The
    /// attitude `att0` is held in precision `P`, its rates, and so its
    /// increments over the period, are evaluated in precision `J` on `env_j`
    /// and `m_j`: the nodes are `att0` plus increments rounded to `J`. For
    /// `J = P` the conversions are the identity; `P = f64`, `J = f32` is
    /// [`Layout::propagate_into_jacobians_in`]'s case (the error it makes).
    fn trajectory<P: RealField + Copy, J: RealField + Copy>(
        &self,
        env_j: &Environment<J>,
        m_j: &InstallationMatrices<J>,
        att0: &Vector3<P>,
        period: &Period<J>,
    ) -> Option<[Vector3<P>; 3]> {
        let to_j = vector_in::<P, J>;
        let to_p = |v: Vector3<J>| vector_in::<J, P>(&v);
        let dt = period.dt;
        let half: J = nalgebra::convert(0.5);
        let two: J = nalgebra::convert(2.0);
        let six: J = nalgebra::convert(6.0);
        let eight: J = nalgebra::convert(8.0);
        let [w0, wm, w1] = &period.omega_c;
        let a0 = to_j(att0)?;
        let k1 = self.attitude_rate(env_j, m_j, &a0, w0)?;
        let k2 = self.attitude_rate(env_j, m_j, &(a0 + k1 * (dt * half)), wm)?;
        let k3 = self.attitude_rate(env_j, m_j, &(a0 + k2 * (dt * half)), wm)?;
        let k4 = self.attitude_rate(env_j, m_j, &(a0 + k3 * dt), w1)?;
        let att1 = att0 + to_p((k1 + (k2 + k3) * two + k4) * (dt / six))?;
        let f1 = self.attitude_rate(env_j, m_j, &to_j(&att1)?, w1)?;
        let att_mid =
            (att0 + att1) * nalgebra::convert::<f64, P>(0.5) + to_p((k1 - f1) * (dt / eight))?;
        Some([*att0, att_mid, att1])
    }

    /// `B = ∂(attitude rate)/∂(platform rate noise)` at attitude `att`
    /// (3×3); `None` at gimbal lock.
    fn noise_map<T: RealField + Copy>(&self, att: &Vector3<T>) -> Option<Matrix3<T>> {
        Some(match self.attitude {
            AttitudeKind::Misalignment => right_jacobian_inv(att),
            AttitudeKind::Gimbal | AttitudeKind::Attitude => gimbal_rate_inverse(att.y, att.z)?,
        })
    }

    /// The mean accelerometer output over the period (g) by Simpson's rule
    /// over the three nodes (error ≈ T⁴|h⁽⁴⁾|/2880 < 1e-15 g at 0.1°/s);
    /// its Jacobian with respect to the state at the END of the period,
    /// `∂h̄/∂x_{k+1} = Σ_j w_j H(t_j) Φ(t_j ← t_{k+1})`; and its sensitivity
    /// `D` (g per rad/s) to a platform-rate noise `w` held over the period
    /// *given* `x_{k+1}`: the noise moved the attitude by `B w (t − t_k)`
    /// while the model traces back from an end state that holds all of
    /// `B w T`, so `D = Σ_j w_j H_att(t_j) (t_j − t_{k+1}) B`.
    ///
    /// Returns the output and `D`; the Jacobian is written into `h` (3×N,
    /// e.g. the accelerometer rows of a measurement's Jacobian: no 3×N copy
    /// of it in the caller's frame).
    pub fn mean_accel<T: RealField + Copy, const N: usize, S: StorageMut<T, U3, Const<N>>>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        prop: &PeriodPropagation<T, N>,
        period: &Period<T>,
        h: &mut Matrix<T, U3, Const<N>, S>,
    ) -> (Vector3<T>, Matrix3<T>) {
        let six: T = nalgebra::convert(6.0);
        let four: T = nalgebra::convert(4.0);
        let half: T = nalgebra::convert(0.5);
        let weights = [T::one() / six, four / six, T::one() / six];
        let mut z = Vector3::zeros();
        h.fill(T::zero());
        let mut d = Matrix3::zeros();
        let back = [-period.dt, -period.dt * half, T::zero()];
        // F over [t_j, t_{k+1}]: the midpoint F for the whole period, the mean
        // of the midpoint and end F (centred at 3T/4) for its second half
        // (by reference: no copies of the 3×N matrices in this frame).
        let f_late = (prop.f_mid + prop.f_end) * half;
        let f_nodes = [&prop.f_mid, &f_late, &prop.f_end];
        let mut hj = SMatrix::<T, 3, N>::zeros();
        for ((((att, c_cn), w), tau), f) in prop
            .att
            .iter()
            .zip(period.c_cn.iter())
            .zip(weights)
            .zip(back)
            .zip(f_nodes.iter())
        {
            let zj = self.accel_output_and_jacobian_into(env, m, att, c_cn, &mut hj);
            z += zj * w;
            if tau != T::zero() {
                d += hj.fixed_columns::<3>(ATT) * prop.noise_map * (w * tau);
                apply_transition_of(&mut hj, f, tau);
            }
            // The end node: Φ(t_{k+1} ← t_{k+1}) = I, and no noise
            // accumulated after it. In place (no 3×N temporaries).
            hj *= w;
            *h += &hj;
        }
        (z, d)
    }
}

impl Layout {
    /// The mean accelerometer output over the period (g) alone, in f64, from
    /// the attitude `att` at the period's three nodes (rad,
    /// `PeriodPropagation::att`): the value of [`Layout::mean_accel`]
    /// without its Jacobians, for the filter that computes those in
    /// precision `J` (f32 on an FPU without double precision, where f64 is
    /// emulated). Simpson's rule is applied before `A`: `A Σ w_j R_j f_j`
    /// (one product by `A`, not three; `f_j` is `f^n` in the frame the
    /// attitude rotation acts on; `a` is `A`, `c_rn` is `C^r_n`,
    /// [`InstallationMatrices`]).
    ///
    /// - Misalignment (M1): the first node's `f_0 = C^c_n(t_k) f^n` in f64;
    ///   in `J` the later nodes' turn `(C_j − C_0) f^n` from the frame's
    ///   turn within the period `turn` (read by M1 only)
    ///   ([`PeriodIn::turn`](crate::command::PeriodIn::turn); `ε_J |uT| |f|`,
    ///   1.0e-10 g at the paper's 0.1°/s over 1 s in f32) and the small
    ///   rotation's share `(R(θ_j) − I) f_j`
    ///   ([`crate::geometry::dcm_deviation`]; `ε_J |θ| |f|`, e.g. 6e-11 g
    ///   for 1 mrad in f32).
    /// - Euler angles: the midpoint and end nodes' sines and cosines from
    ///   the first node's, their increments in `J`
    ///   ([`EulerTrig::advanced_in`]; ≤ 7.2e-10 in f32), the rest in f64.
    ///
    /// For `J = f64` it equals `mean_accel`'s value to rounding.
    pub fn mean_accel_output<J: RealField + Copy>(
        &self,
        env: &Environment<f64>,
        a: &Matrix3<f64>,
        c_rn: &Matrix3<f64>,
        att: &[Vector3<f64>; 3],
        period: &Period<f64>,
        turn: &[Matrix3<J>; 2],
    ) -> Vector3<f64> {
        let weights = [1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0];
        let [att0, att_mid, att1] = att;
        let mut mean = Vector3::zeros();
        match self.attitude {
            AttitudeKind::Misalignment => {
                // f_j = C_j f^n = f_0 + (C_j − C_0) f^n: f_0 in f64, the
                // later nodes' turn within the period (≤ |uT| |f|) in J.
                let [c0, _, _] = &period.c_cn;
                let f0 = c0 * env.gravity_n;
                let (f0_j, g_j): (Vector3<J>, Vector3<J>) = (to_t(&f0), to_t(&env.gravity_n));
                let [turn_mid, turn_end] = turn;
                let f_turns = [Vector3::zeros(), turn_mid * g_j, turn_end * g_j];
                let mut small = Vector3::<J>::zeros();
                for ((theta, f_turn), w) in att.iter().zip(f_turns).zip(weights) {
                    let w: J = nalgebra::convert(w);
                    small +=
                        (f_turn + dcm_deviation(&to_t::<J, 3, 1>(theta)) * (f0_j + f_turn)) * w;
                }
                mean = f0 + to_f64(&small);
            }
            AttitudeKind::Gimbal | AttitudeKind::Attitude => {
                let f = match self.attitude {
                    AttitudeKind::Gimbal => c_rn * env.gravity_n,
                    _ => env.gravity_n,
                };
                let trig0 = EulerTrig::new(att0);
                let nodes = [
                    trig0,
                    trig0.advanced_in::<J>(att0, &(att_mid - att0)),
                    trig0.advanced_in::<J>(att0, &(att1 - att0)),
                ];
                for (trig, w) in nodes.iter().zip(weights) {
                    mean += trig.rotate(&f) * w;
                }
            }
        }
        a * mean
    }
}

impl Layout {
    /// The state at the end of `period` (or at its start, for a
    /// [`Period::reversed`] period) under the model's dynamics; the
    /// parameters are constant. `None` at gimbal lock.
    pub fn propagate_state<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        x: &SVector<T, N>,
        period: &Period<T>,
    ) -> Option<SVector<T, N>> {
        let prop: PeriodPropagation<T, N> =
            self.propagate(env, &self.matrices(x), &self.attitude(x), period)?;
        let [_, _, end] = prop.att;
        let mut out = *x;
        put3(&mut out, ATT, &end);
        Some(out)
    }
}

/// `x` (precision `P`) in precision `J`, through f64: exact between f32 and
/// f64 either way (rounded from f64 to f32). `None` if `x` has no f64 value.
fn scalar_in<P: RealField + Copy, J: RealField + Copy>(x: P) -> Option<J> {
    x.to_subset().map(|v: f64| J::from_subset(&v))
}

/// [`scalar_in`] of each component.
fn vector_in<P: RealField + Copy, J: RealField + Copy>(v: &Vector3<P>) -> Option<Vector3<J>> {
    Some(Vector3::new(
        scalar_in(v.x)?,
        scalar_in(v.y)?,
        scalar_in(v.z)?,
    ))
}

/// Attitude rows of `exp(F τ)` to second order for `F = [[F_a, F_p],[0, 0]]`:
/// `[I + F_a τ + (F_a τ)²/2, (I + F_a τ/2) F_p τ]`.
pub fn transition_rows<T: RealField + Copy, const N: usize>(
    f: &SMatrix<T, 3, N>,
    tau: T,
) -> SMatrix<T, 3, N> {
    let mut phi = SMatrix::zeros();
    transition_rows_into(f, tau, &mut phi);
    phi
}

/// [`transition_rows`] written into `phi` (every entry): no 3×N copy of
/// the result where the caller keeps it.
pub fn transition_rows_into<T: RealField + Copy, const N: usize>(
    f: &SMatrix<T, 3, N>,
    tau: T,
    phi: &mut SMatrix<T, 3, N>,
) {
    let pieces = TransitionPieces::new(f, tau);
    for (j, (col, f_col)) in phi.data.0.iter_mut().zip(f.data.0.iter()).enumerate() {
        *col = pieces.column(j, f_col, tau).into();
    }
}

/// The two matrices of [`transition_rows`] of `F` and `τ`, from which each
/// of its columns follows alone (see [`TransitionPieces::column`]).
struct TransitionPieces<T> {
    /// `F_a τ/2 + (F_a τ)²/6`: a parameter column is `(I + mix) F_j τ`.
    mix: Matrix3<T>,
    /// The attitude block `I + F_a τ + (F_a τ)²/2 + (F_a τ)³/6` (error
    /// ≈ |F τ|⁴/24 < 1e-12).
    aa: Matrix3<T>,
}

impl<T: RealField + Copy> TransitionPieces<T> {
    fn new<const N: usize>(f: &SMatrix<T, 3, N>, tau: T) -> Self {
        let half: T = nalgebra::convert(0.5);
        let sixth: T = nalgebra::convert(1.0 / 6.0);
        let fa = attitude_columns(f) * tau;
        let fa2 = fa * fa;
        Self {
            mix: fa * half + fa2 * sixth,
            aa: Matrix3::identity() + fa + fa2 * half + fa2 * fa * sixth,
        }
    }

    /// Column `j` of the transition rows, `f_col` being column `j` of `F`:
    /// a column of the attitude block, or `F_j τ + mix F_j τ` (the same
    /// operations as the whole-matrix products).
    fn column(&self, j: usize, f_col: &[T; 3], tau: T) -> Vector3<T> {
        match j.checked_sub(ATT) {
            Some(a) if a < 3 => self
                .aa
                .data
                .0
                .get(a)
                .map_or_else(Vector3::zeros, |c| Vector3::from(*c)),
            _ => {
                let ft = Vector3::from(*f_col) * tau;
                ft + self.mix * ft
            }
        }
    }
}

/// `H ← H Φ` with Φ's attitude rows the [`transition_rows`] of `F` and `τ`,
/// each column of Φ formed where it is used ([`apply_transition`] of
/// `transition_rows(f, tau)` without the 3×N Φ; the same operations).
pub fn apply_transition_of<T: RealField + Copy, const R: usize, const N: usize>(
    h: &mut SMatrix<T, R, N>,
    f: &SMatrix<T, 3, N>,
    tau: T,
) {
    let pieces = TransitionPieces::new(f, tau);
    mix_columns(h, f, |j, f_col| pieces.column(j, f_col, tau));
}

/// `H ← H Φ` for a Φ whose parameter rows are the identity: only the
/// attitude columns of `H` mix; `phi_att` are the attitude rows of Φ. In
/// place, one column at a time (no `R×N` temporary).
pub fn apply_transition<T: RealField + Copy, const R: usize, const N: usize>(
    h: &mut SMatrix<T, R, N>,
    phi_att: &SMatrix<T, 3, N>,
) {
    mix_columns(h, phi_att, |_, phi_col| Vector3::from(*phi_col));
}

/// `H ← H Φ` for a Φ whose parameter rows are the identity, column `j` of
/// Φ's attitude rows being `phi_column(j, &source[j])`: the attitude
/// columns become `H_a Φ_aa`, the parameter columns `H_p + H_a Φ_ap`.
fn mix_columns<T: RealField + Copy, const R: usize, const N: usize>(
    h: &mut SMatrix<T, R, N>,
    source: &SMatrix<T, 3, N>,
    phi_column: impl Fn(usize, &[T; 3]) -> Vector3<T>,
) {
    let h_att = attitude_columns(h);
    for (j, (mut col, src)) in h.column_iter_mut().zip(source.data.0.iter()).enumerate() {
        let mixed = h_att * phi_column(j, src);
        if j < ATT + 3 {
            col.copy_from(&mixed);
        } else {
            col += mixed;
        }
    }
}
