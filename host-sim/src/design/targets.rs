//! The targets of the design: `--target NAME=VALUE` ([`parse_target`]),
//! the default target states (the parameter block), the default targets of
//! the instrument terms of the full model ([`InstrumentTargets`]) and the
//! list of `(state, σ)` the search aims at ([`targets`]).

use rollcal::models::{ConfigId, ErrorModel, Group};

use crate::sim::scenario::ARCSEC;

use super::DesignError;

/// A parameter target given on the command line: a state name or a group
/// name, and σ in the state's printed unit (arcseconds for the angles; °/h,
/// °/h/g, ppm, µg for the instrument terms of the full model).
#[derive(Clone, Debug, PartialEq)]
pub struct TargetArg {
    /// State or group name.
    pub name: String,
    /// σ in the printed unit (″ for the angles).
    pub value: f64,
}

/// The default targets of the instrument terms of the full model, in their
/// printed units: the accuracy PSINS reaches (issue 31).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstrumentTargets {
    /// Gyro drift `dg` (°/h).
    pub dg_deg_h: f64,
    /// g-sensitive drift `D_g` (°/h/g).
    pub d_g_deg_h_g: f64,
    /// Gyro scale factor `kg` (ppm).
    pub kg_ppm: f64,
    /// Accelerometer bias `ba` (µg).
    pub ba_ug: f64,
    /// Accelerometer scale factor `ka` (ppm).
    pub ka_ppm: f64,
}

impl InstrumentTargets {
    /// PSINS's reached accuracy: dg 0.005 °/h, D_g 0.005 °/h/g, kg 1 ppm,
    /// ba 1 µg, ka 1 ppm.
    pub const PSINS: Self = Self {
        dg_deg_h: 0.005,
        d_g_deg_h_g: 0.005,
        kg_ppm: 1.0,
        ba_ug: 1.0,
        ka_ppm: 1.0,
    };

    /// The target of an instrument group (printed unit); `None` for an angle.
    pub fn of(&self, g: Group) -> Option<f64> {
        match g {
            Group::GyroDrift => Some(self.dg_deg_h),
            Group::GyroGDrift => Some(self.d_g_deg_h_g),
            Group::GyroScale => Some(self.kg_ppm),
            Group::AccelBias => Some(self.ba_ug),
            Group::AccelScale => Some(self.ka_ppm),
            _ => None,
        }
    }
}

/// `value` in the printed unit of a state of group `g` → internal unit (the
/// inverse of [`crate::sim::instruments::printed_value`]).
fn internal_value(g: Group, value: f64) -> f64 {
    if g.is_instrument() {
        value / g.printed_scale().0
    } else {
        value * ARCSEC
    }
}

/// Parses `NAME=VALUE` (σ in the state's printed unit: ″ for the angles).
///
/// # Examples
///
/// ```
/// use host_sim::design::parse_target;
///
/// let t = parse_target("thgC=1.5")?;
/// assert_eq!((t.name.as_str(), t.value), ("thgC", 1.5));
/// let e = parse_target("thgC").unwrap_err();
/// assert_eq!(e.to_string(), "target 'thgC': expected NAME=ARCSEC, e.g. thgC=1.5");
/// # Ok::<(), host_sim::design::DesignError>(())
/// ```
pub fn parse_target(s: &str) -> Result<TargetArg, DesignError> {
    let (name, v) = s.split_once('=').ok_or_else(|| {
        DesignError::Target(format!("target '{s}': expected NAME=ARCSEC, e.g. thgC=1.5"))
    })?;
    let value: f64 = v.trim().parse().map_err(|_| {
        DesignError::Target(format!("target '{s}': '{v}' is not a number of arcseconds (or of the instrument term's °/h, °/h/g, ppm, µg)"))
    })?;
    if !(value.is_finite() && value > 0.0) {
        return Err(DesignError::Target(format!("target '{s}': σ must be > 0")));
    }
    Ok(TargetArg {
        name: name.trim().to_string(),
        value,
    })
}

/// The states of `id` a target applies to by default: the parameter block
/// (the installation errors and λ the configuration observes).
pub fn default_target_states(id: ConfigId) -> Vec<usize> {
    id.states()
        .iter()
        .enumerate()
        .filter(|(_, s)| crate::analysis::montecarlo::in_parameter_block(id, s.name, s.group))
        .map(|(i, _)| i)
        .collect()
}

/// The targets (state index, σ in internal units) of `id` under the
/// installation model: the reference σ times `scale` on the parameter
/// block, then every `--target` (a state or a group name; a group target
/// applies to each of its states), later ones overriding.
pub fn targets(
    id: ConfigId,
    reference_sigma: &[f64],
    scale: f64,
    overrides: &[TargetArg],
) -> Result<Vec<(usize, f64)>, DesignError> {
    targets_with(
        id,
        ErrorModel::Installation,
        reference_sigma,
        &InstrumentTargets::PSINS,
        scale,
        overrides,
    )
}

/// [`targets`] under error model `errors`: with the full model, the 21
/// instrument terms follow with the targets of `instruments` (printed
/// units) times `scale`. `reference_sigma` covers the installation states
/// at least (the full model's state order starts with them).
pub fn targets_with(
    id: ConfigId,
    errors: ErrorModel,
    reference_sigma: &[f64],
    instruments: &InstrumentTargets,
    scale: f64,
    overrides: &[TargetArg],
) -> Result<Vec<(usize, f64)>, DesignError> {
    let names = id.states_with(errors);
    let mut t: Vec<(usize, f64)> = default_target_states(id)
        .into_iter()
        .map(|i| (i, reference_sigma[i] * scale))
        .collect();
    if errors == ErrorModel::Full {
        for (i, s) in names.iter().enumerate() {
            if let Some(v) = instruments.of(s.group) {
                t.push((i, internal_value(s.group, v * scale)));
            }
        }
    }
    for o in overrides {
        let hits: Vec<usize> = names
            .iter()
            .enumerate()
            .filter(|(_, s)| s.name == o.name || s.group.as_str() == o.name)
            .map(|(i, _)| i)
            .collect();
        if hits.is_empty() {
            let list: Vec<&str> = names.iter().map(|s| s.name).collect();
            return Err(DesignError::Target(format!(
                "target '{}': {id} has no such state or group (states: {})",
                o.name,
                list.join(", ")
            )));
        }
        for i in hits {
            if names[i].group == Group::Attitude {
                return Err(DesignError::Target(format!(
                    "target '{}': attitude states vary with time and take no target",
                    o.name
                )));
            }
            t.retain(|(j, _)| *j != i);
            t.push((i, internal_value(names[i].group, o.value)));
        }
    }
    t.sort_by_key(|(i, _)| *i);
    Ok(t)
}
