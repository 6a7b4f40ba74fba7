//! The 21 instrument-error states (docs/model.md §Instrument errors):
//! their order, names, printed units and true values, shared by the
//! truth sidecar, the reports and (when the full model lands) the analysis.
//!
//! Order: `[dg (3), D_g (9, row-major: row = gyro, column = force axis),
//! kg (3), ba (3), ka (3)]`. Internal units: rad/s, rad/s per g,
//! dimensionless, g, dimensionless. In the pa configurations the
//! g-sensitive drift is `D_g^pa = D_g R(θaC)` (names `Dgpa_*`); `dg`, `kg`,
//! `ba`, `ka` are the same numbers in both frames.

use rollcal::models::{ConfigId, ErrorModel, Group, PlatformFrame, StateInfo};

use crate::sim::scenario::{ARCSEC, DEG};
use crate::sim::truth::TruthParams;

/// Number of instrument-error states.
pub const INSTRUMENT_STATES: usize = 21;

/// Radians per second in one degree per hour (°/h → rad/s).
pub const DEG_H: f64 = DEG / 3600.0;
/// One part per million (ppm → dimensionless).
pub const PPM: f64 = 1e-6;
/// One micro-g (µg → g).
pub const UG: f64 = 1e-6;

/// The core's states of the full model of `id` after the installation
/// ones: the 21 instrument states, names and groups
/// ([`ConfigId::states_with`], the one table of state names).
fn instrument_infos(id: ConfigId) -> &'static [StateInfo] {
    let all = id.states_with(ErrorModel::Full);
    all.get(id.layout().n()..).unwrap_or(&[])
}

/// The ASCII form of the printed unit of an instrument group, as the
/// sidecar and the CSV columns write it (`deg_h`-style names use
/// [`ascii_unit`] with `/` turned into `_`): `deg/h`, `deg/h/g`, `ppm`,
/// `ug`; `rad` for the angles.
pub fn ascii_unit(group: Group) -> &'static str {
    match group {
        Group::GyroDrift => "deg/h",
        Group::GyroGDrift => "deg/h/g",
        Group::AccelBias => "ug",
        Group::GyroScale | Group::AccelScale => "ppm",
        _ => "rad",
    }
}

/// The printed value of `v` (internal unit) of a state of group `group`:
/// arcseconds for the angles (`v / ARCSEC`, as every table has always
/// printed them), the unit of [`Group::printed_scale`] (°/h, °/h/g, ppm,
/// µg) for the instrument states. The one conversion of the tables.
pub fn printed_value(group: Group, v: f64) -> f64 {
    if group.is_instrument() {
        v * group.printed_scale().0
    } else {
        v / ARCSEC
    }
}

/// The printed unit of instrument state `i` (`deg/h`, `deg/h/g`, `ppm`,
/// `ug`, `ppm`).
pub fn printed_unit(i: usize) -> &'static str {
    instrument_infos(ConfigId::M2Ps)
        .get(i)
        .map_or("", |s| ascii_unit(s.group))
}

/// The factor internal → printed of instrument state `i` (multiply an
/// internal value by it: rad/s → °/h, rad/s/g → °/h/g, 1 → ppm, g → µg;
/// core's [`Group::printed_scale`]).
pub fn printed_factor(i: usize) -> f64 {
    instrument_infos(ConfigId::M2Ps)
        .get(i)
        .map_or(f64::NAN, |s| s.group.printed_scale().0)
}

/// The 21 names of configuration `id` (`Dgpa_*` in the pa frame).
pub fn instrument_names(id: ConfigId) -> [&'static str; INSTRUMENT_STATES] {
    let infos = instrument_infos(id);
    core::array::from_fn(|i| infos.get(i).map_or("", |s| s.name))
}

/// The 21 printed units, in state order.
pub fn instrument_units() -> [&'static str; INSTRUMENT_STATES] {
    core::array::from_fn(printed_unit)
}

/// The true instrument states of configuration `id` (internal units, the
/// order above): `D_g` in ps, `D_g^pa = D_g R(θaC)` in pa.
pub fn instrument_truth_state(id: ConfigId, p: &TruthParams) -> [f64; INSTRUMENT_STATES] {
    let d = match id.layout().frame {
        PlatformFrame::Ps => p.d_g,
        PlatformFrame::Pa => p.d_g_pa(),
    };
    let mut x = [0.0; INSTRUMENT_STATES];
    x[..3].copy_from_slice(p.dg.as_slice());
    for r in 0..3 {
        for c in 0..3 {
            x[3 + 3 * r + c] = d[(r, c)];
        }
    }
    x[12..15].copy_from_slice(p.kg.as_slice());
    x[15..18].copy_from_slice(p.ba.as_slice());
    x[18..].copy_from_slice(p.ka.as_slice());
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_units_and_factors_line_up() {
        assert_eq!(instrument_names(ConfigId::M2Ps)[4], "Dg_xy");
        assert_eq!(instrument_names(ConfigId::M1Pa)[11], "Dgpa_zz");
        assert_eq!(instrument_names(ConfigId::M4Ps)[20], "ka_z");
        let u = instrument_units();
        assert_eq!(
            (u[0], u[3], u[12], u[15], u[18]),
            ("deg/h", "deg/h/g", "ppm", "ug", "ppm")
        );
        assert!((printed_factor(0) * DEG_H - 1.0).abs() < 1e-15);
        assert!((printed_factor(16) * 30e-6 - 30.0).abs() < 1e-12);
    }
}
