//! The names, units and groups of the states of each configuration
//! (docs/model.md §State names): [`StateInfo`], [`Group`] and one array
//! per configuration, read through [`ConfigId::states`]. The names are
//! the ASCII forms of the symbols and a stable interface of the JSON and
//! CSV outputs.

use super::ConfigId;

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

impl ConfigId {
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
