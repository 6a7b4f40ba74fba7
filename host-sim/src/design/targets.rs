//! The targets of the design: `--target NAME=ARCSEC` ([`parse_target`]),
//! the default target states (the parameter block) and the list of
//! `(state, σ)` the search aims at ([`targets`]).

use rollcal::models::{ConfigId, Group};

use crate::sim::scenario::ARCSEC;

use super::DesignError;

/// A parameter target given on the command line: a state name or a group
/// name, and σ in arcseconds.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetArg {
    /// State or group name.
    pub name: String,
    /// σ (″).
    pub arcsec: f64,
}

/// Parses `NAME=ARCSEC`.
///
/// # Examples
///
/// ```
/// use host_sim::design::parse_target;
///
/// let t = parse_target("thgC=1.5")?;
/// assert_eq!((t.name.as_str(), t.arcsec), ("thgC", 1.5));
/// let e = parse_target("thgC").unwrap_err();
/// assert_eq!(e.to_string(), "target 'thgC': expected NAME=ARCSEC, e.g. thgC=1.5");
/// # Ok::<(), host_sim::design::DesignError>(())
/// ```
pub fn parse_target(s: &str) -> Result<TargetArg, DesignError> {
    let (name, v) = s.split_once('=').ok_or_else(|| {
        DesignError::Target(format!("target '{s}': expected NAME=ARCSEC, e.g. thgC=1.5"))
    })?;
    let arcsec: f64 = v.trim().parse().map_err(|_| {
        DesignError::Target(format!("target '{s}': '{v}' is not a number of arcseconds"))
    })?;
    if !(arcsec.is_finite() && arcsec > 0.0) {
        return Err(DesignError::Target(format!(
            "target '{s}': σ must be > 0 arcseconds"
        )));
    }
    Ok(TargetArg {
        name: name.trim().to_string(),
        arcsec,
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

/// The targets (state index, σ rad): the reference σ times `scale` on the
/// parameter block, then every `--target` (a state or a group name; a
/// group target applies to each of its states), later ones overriding.
pub fn targets(
    id: ConfigId,
    reference_sigma: &[f64],
    scale: f64,
    overrides: &[TargetArg],
) -> Result<Vec<(usize, f64)>, DesignError> {
    let names = id.states();
    let mut t: Vec<(usize, f64)> = default_target_states(id)
        .into_iter()
        .map(|i| (i, reference_sigma[i] * scale))
        .collect();
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
            t.push((i, o.arcsec * ARCSEC));
        }
    }
    t.sort_by_key(|(i, _)| *i);
    Ok(t)
}
