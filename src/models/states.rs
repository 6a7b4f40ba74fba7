//! The names, units and groups of the states of each configuration
//! (docs/model.md §State names): [`StateInfo`], [`Group`] and one array
//! per configuration, read through [`ConfigId::states`]. The names are
//! the ASCII forms of the symbols and a stable interface of the JSON and
//! CSV outputs.

use super::{ConfigId, ErrorModel};

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
    /// Constant gyro drift `dg` (rad/s; full model).
    GyroDrift,
    /// g-sensitive gyro drift `D_g` or `D_g^pa` (rad/s per g; full model).
    GyroGDrift,
    /// Torquer (gyro) scale-factor errors `kg` (dimensionless; full model).
    GyroScale,
    /// Accelerometer bias `ba` (g; full model).
    AccelBias,
    /// Accelerometer scale-factor errors `ka` (dimensionless; full model).
    AccelScale,
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
            Group::GyroDrift => "dg",
            Group::GyroGDrift => "Dg",
            Group::GyroScale => "kg",
            Group::AccelBias => "ba",
            Group::AccelScale => "ka",
        }
    }

    /// Every group, installation groups first.
    pub const ALL: [Group; 11] = [
        Group::Attitude,
        Group::ThetaGC,
        Group::ThetaGT,
        Group::ThetaAC,
        Group::ThetaAT,
        Group::Lambda,
        Group::GyroDrift,
        Group::GyroGDrift,
        Group::GyroScale,
        Group::AccelBias,
        Group::AccelScale,
    ];

    /// Whether the group is one of the full model's instrument errors.
    pub const fn is_instrument(self) -> bool {
        matches!(
            self,
            Group::GyroDrift
                | Group::GyroGDrift
                | Group::GyroScale
                | Group::AccelBias
                | Group::AccelScale
        )
    }

    /// The internal unit of the group's states: `"rad"`, `"rad/s"`,
    /// `"rad/s/g"`, `"1"` (dimensionless) or `"g"`.
    pub const fn unit(self) -> &'static str {
        match self {
            Group::Attitude
            | Group::ThetaGC
            | Group::ThetaGT
            | Group::ThetaAC
            | Group::ThetaAT
            | Group::Lambda => "rad",
            Group::GyroDrift => "rad/s",
            Group::GyroGDrift => "rad/s/g",
            Group::GyroScale | Group::AccelScale => "1",
            Group::AccelBias => "g",
        }
    }

    /// The factor from the internal unit to the printed one, and the
    /// printed unit: angles in arcseconds (`″`), `dg` in °/h, `D_g` in
    /// °/h/g, `kg` and `ka` in ppm, `ba` in µg (docs/model.md §State names).
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::Group;
    ///
    /// let (k, unit) = Group::GyroDrift.printed_scale();
    /// assert_eq!(unit, "°/h");
    /// assert!((1f64.to_radians() / 3600.0 * k - 1.0).abs() < 1e-15); // 1 °/h
    /// assert_eq!(Group::AccelBias.printed_scale(), (1e6, "µg"));
    /// ```
    pub const fn printed_scale(self) -> (f64, &'static str) {
        // rad → ″ and rad/s → °/h are the same number: 180·3600/π.
        const RAD_TO_ARCSEC: f64 = 180.0 * 3600.0 / core::f64::consts::PI;
        match self {
            Group::Attitude
            | Group::ThetaGC
            | Group::ThetaGT
            | Group::ThetaAC
            | Group::ThetaAT
            | Group::Lambda => (RAD_TO_ARCSEC, "″"),
            Group::GyroDrift => (RAD_TO_ARCSEC, "°/h"),
            Group::GyroGDrift => (RAD_TO_ARCSEC, "°/h/g"),
            Group::GyroScale | Group::AccelScale => (1e6, "ppm"),
            Group::AccelBias => (1e6, "µg"),
        }
    }

    /// The group of a stable name (the inverse of [`Group::as_str`]).
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::Group;
    ///
    /// assert_eq!(Group::ThetaAT.as_str(), "thaT");
    /// assert_eq!(Group::from_name("lam"), Some(Group::Lambda));
    /// assert_eq!(Group::from_name("bias"), None);
    /// ```
    pub fn from_name(name: &str) -> Option<Self> {
        Group::ALL.into_iter().find(|g| g.as_str() == name)
    }
}

/// Name, unit and group of one state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StateInfo {
    /// The ASCII name of the symbol (docs/model.md §State names), e.g. `thgC_x`, `thaT_1`, `lam_z`: a stable
    /// interface of the JSON/CSV outputs.
    pub name: &'static str,
    /// Unit of the state ([`Group::unit`]): `"rad"` for every
    /// installation state; `"rad/s"`, `"rad/s/g"`, `"1"`, `"g"` for the
    /// full model's instrument errors.
    pub unit: &'static str,
    /// Physical group.
    pub group: Group,
}

impl StateInfo {
    /// The factor from the state's internal unit to its printed one, and
    /// the printed unit ([`Group::printed_scale`]).
    pub const fn printed_scale(&self) -> (f64, &'static str) {
        self.group.printed_scale()
    }
}

const fn s(name: &'static str, group: Group) -> StateInfo {
    StateInfo {
        name,
        unit: group.unit(),
        group,
    }
}

/// `a` followed by `b` (`C = A + B`). Evaluated at compile time only (the
/// `const` arrays below): an index out of range would be a compile error,
/// not a panic path of the firmware.
#[allow(clippy::indexing_slicing)] // i < A, A ≤ i < C = A + B (asserted; const context)
const fn concat<const A: usize, const B: usize, const C: usize>(
    a: [StateInfo; A],
    b: [StateInfo; B],
) -> [StateInfo; C] {
    assert!(A + B == C);
    let mut out = [s("", Group::Attitude); C];
    let mut i = 0;
    while i < A {
        out[i] = a[i];
        i += 1;
    }
    while i < C {
        out[i] = b[i - A];
        i += 1;
    }
    out
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

/// The full model's instrument-error states in the ps frame (docs/model.md
/// §Instrument errors).
const INSTRUMENT_PS: [StateInfo; 21] = states![
    "dg_x": GyroDrift, "dg_y": GyroDrift, "dg_z": GyroDrift,
    "Dg_xx": GyroGDrift, "Dg_xy": GyroGDrift, "Dg_xz": GyroGDrift,
    "Dg_yx": GyroGDrift, "Dg_yy": GyroGDrift, "Dg_yz": GyroGDrift,
    "Dg_zx": GyroGDrift, "Dg_zy": GyroGDrift, "Dg_zz": GyroGDrift,
    "kg_x": GyroScale, "kg_y": GyroScale, "kg_z": GyroScale,
    "ba_x": AccelBias, "ba_y": AccelBias, "ba_z": AccelBias,
    "ka_x": AccelScale, "ka_y": AccelScale, "ka_z": AccelScale,
];
/// The same in the pa frame: `D_g^pa` is named `Dgpa_*` (as `thgCpa_*`).
const INSTRUMENT_PA: [StateInfo; 21] = states![
    "dg_x": GyroDrift, "dg_y": GyroDrift, "dg_z": GyroDrift,
    "Dgpa_xx": GyroGDrift, "Dgpa_xy": GyroGDrift, "Dgpa_xz": GyroGDrift,
    "Dgpa_yx": GyroGDrift, "Dgpa_yy": GyroGDrift, "Dgpa_yz": GyroGDrift,
    "Dgpa_zx": GyroGDrift, "Dgpa_zy": GyroGDrift, "Dgpa_zz": GyroGDrift,
    "kg_x": GyroScale, "kg_y": GyroScale, "kg_z": GyroScale,
    "ba_x": AccelBias, "ba_y": AccelBias, "ba_z": AccelBias,
    "ka_x": AccelScale, "ka_y": AccelScale, "ka_z": AccelScale,
];

const M1_PA_FULL_STATES: [StateInfo; 33] = concat(M1_PA_STATES, INSTRUMENT_PA);
const M1_PS_FULL_STATES: [StateInfo; 36] = concat(M1_PS_STATES, INSTRUMENT_PS);
const M2_PS_FULL_STATES: [StateInfo; 39] = concat(M2_PS_STATES, INSTRUMENT_PS);
const M3_PA_FULL_STATES: [StateInfo; 36] = concat(M3_PA_STATES, INSTRUMENT_PA);
const M3_PS_FULL_STATES: [StateInfo; 39] = concat(M3_PS_STATES, INSTRUMENT_PS);
const M4_PA_FULL_STATES: [StateInfo; 33] = concat(M4_PA_STATES, INSTRUMENT_PA);
const M4_PS_FULL_STATES: [StateInfo; 36] = concat(M4_PS_STATES, INSTRUMENT_PS);

impl ConfigId {
    /// The names, units and groups of the states under error model
    /// `errors`, in state order: [`ConfigId::states`] for
    /// [`ErrorModel::Installation`]; for [`ErrorModel::Full`] the same
    /// followed by `dg_x, dg_y, dg_z, Dg_xx … Dg_zz` (`Dgpa_*` in the pa
    /// frame), `kg_*, ba_*, ka_*`.
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::models::ErrorModel;
    /// use rollcal::{ConfigId, Group};
    ///
    /// let states = ConfigId::M3Pa.states_with(ErrorModel::Full);
    /// assert_eq!(states.len(), 36);
    /// assert_eq!(&states[..15], ConfigId::M3Pa.states());
    /// assert_eq!((states[15].name, states[15].unit), ("dg_x", "rad/s"));
    /// assert_eq!((states[19].name, states[19].group), ("Dgpa_xy", Group::GyroGDrift));
    /// assert_eq!(states[33].printed_scale(), (1e6, "ppm")); // ka_x
    /// ```
    pub fn states_with(self, errors: ErrorModel) -> &'static [StateInfo] {
        match errors {
            ErrorModel::Installation => self.states(),
            ErrorModel::Full => match self {
                ConfigId::M1Pa => &M1_PA_FULL_STATES,
                ConfigId::M1Ps => &M1_PS_FULL_STATES,
                ConfigId::M2Ps => &M2_PS_FULL_STATES,
                ConfigId::M3Pa => &M3_PA_FULL_STATES,
                ConfigId::M3Ps => &M3_PS_FULL_STATES,
                ConfigId::M4Pa => &M4_PA_FULL_STATES,
                ConfigId::M4Ps => &M4_PS_FULL_STATES,
            },
        }
    }

    /// The names, units and groups of the states, in state order.
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::{ConfigId, Group};
    ///
    /// let states = ConfigId::M2Ps.states();
    /// let names: Vec<&str> = states.iter().map(|s| s.name).collect();
    /// assert_eq!(
    ///     names,
    ///     [
    ///         "thA_alpha", "thA_beta", "thA_gamma",
    ///         "thgC_x", "thgC_y", "thgC_z",
    ///         "thgT_1", "thgT_2", "thgT_3",
    ///         "thaC_x", "thaC_y", "thaC_z",
    ///         "thaT_1", "thaT_2", "thaT_3",
    ///         "lam_x", "lam_y", "lam_z",
    ///     ]
    /// );
    /// assert!(states.iter().all(|s| s.unit == "rad"));
    /// assert_eq!(states[15].group, Group::Lambda);
    /// ```
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
