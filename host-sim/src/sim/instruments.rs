//! The 36 instrument-error states (docs/model.md §Instrument errors,
//! §Errors that wander): their order, names, printed units and true values,
//! shared by the truth sidecar, the reports and the analysis.
//!
//! Order: `[dg (3), D_g (9, row-major: row = gyro, column = force axis),
//! kg (3), ba (3), ka (3), k2 (3), δ_g (3), δ_a (3), w_g (3), w_a (3)]`.
//! Internal units: rad/s, rad/s per g, dimensionless, g, dimensionless, g
//! per g², rad/s, g, rad/s, g.
//! In the pa configurations the g-sensitive drift is `D_g^pa = D_g R(θaC)`
//! (names `Dgpa_*`); the others are the same numbers in both frames. The
//! true value of a wandering term is the one at the instant it is taken
//! at: `dg + r_g(t)`, `ba + r_a(t)` (the persistent part), `δ_g(t)`,
//! `δ_a(t)` and the warm-up `Δ e^(−t/τ_w)`.

use rollcal::models::{ConfigId, ErrorModel, Group, PlatformFrame, StateInfo};

use crate::sim::scenario::DEG;
use crate::sim::truth::TruthParams;
use crate::sim::wander::WanderTruth;

/// Number of instrument-error states.
pub const INSTRUMENT_STATES: usize = rollcal::wire::INSTRUMENT_STATES;

/// Radians per second in one degree per hour (°/h → rad/s).
pub const DEG_H: f64 = DEG / 3600.0;
/// One part per million (ppm → dimensionless).
pub const PPM: f64 = 1e-6;
/// One micro-g (µg → g).
pub const UG: f64 = 1e-6;

/// The core's states of the full model of `id` after the installation
/// ones: the 36 instrument states, names and groups
/// ([`ConfigId::states_with`], the one table of state names).
fn instrument_infos(id: ConfigId) -> &'static [StateInfo] {
    let all = id.states_with(ErrorModel::Full);
    all.get(id.layout().n()..).unwrap_or(&[])
}

/// The ASCII form of the unit a state of group `group` is written in by
/// the CSV columns and the sidecar: `rad` for the angles (the CSV keeps
/// them in radians), else the printed unit of [`Group::printed_scale`]
/// spelled in ASCII (`°` → `deg`, `µ` → `u`, `²` → `2`): `deg/h`,
/// `deg/h/g`, `ppm`, `ug`. Derived from the group's printed unit, so a new
/// group is named right without a change here.
pub fn ascii_unit(group: Group) -> String {
    if group.unit() == "rad" {
        return "rad".into();
    }
    group
        .printed_scale()
        .1
        .replace('°', "deg")
        .replace('µ', "u")
        .replace('²', "2")
        .replace('³', "3")
        .replace('″', "arcsec")
}

/// The printed value of `v` (internal unit) of a state of group `group`:
/// `v` times the group's factor of [`Group::printed_scale`] (arcseconds for
/// the angles, °/h, °/h/g, ppm, µg, … for the instrument terms). The one
/// conversion of the tables, keyed by the group alone.
pub fn printed_value(group: Group, v: f64) -> f64 {
    v * group.printed_scale().0
}

/// The printed unit of a state of group `group` (`″`, `°/h`, `°/h/g`,
/// `ppm`, `µg`, …; [`Group::printed_scale`]).
pub fn printed_unit(group: Group) -> &'static str {
    group.printed_scale().1
}

/// The 36 names of configuration `id` (`Dgpa_*` in the pa frame).
pub fn instrument_names(id: ConfigId) -> [&'static str; INSTRUMENT_STATES] {
    let infos = instrument_infos(id);
    core::array::from_fn(|i| infos.get(i).map_or("", |s| s.name))
}

/// The internal units of the 36 instrument states, in state order
/// (`rad/s`, `rad/s/g`, `1`, `g`, `1/g`; [`Group::unit`]): the units of
/// the sidecar's `instrument_truth`.
pub fn instrument_units() -> [&'static str; INSTRUMENT_STATES] {
    let infos = instrument_infos(ConfigId::M2Ps);
    core::array::from_fn(|i| infos.get(i).map_or("", |s| s.unit))
}

/// The true instrument states of configuration `id` (internal units, the
/// order above) when the wandering parts are `w` (e.g. the run's end,
/// `Simulation::final_wander`, or [`WanderTruth::zero`]): `D_g` in ps,
/// `D_g^pa = D_g R(θaC)` in pa; `dg + r_g`, `ba + r_a` (the persistent
/// parts, the calibrated values), the Gauss–Markov parts `δ_g`, `δ_a` and
/// the warm-up.
pub fn instrument_truth_state(
    id: ConfigId,
    p: &TruthParams,
    w: &WanderTruth,
) -> [f64; INSTRUMENT_STATES] {
    let d = match id.layout().frame {
        PlatformFrame::Ps => p.d_g,
        PlatformFrame::Pa => p.d_g_pa(),
    };
    let mut x = [0.0; INSTRUMENT_STATES];
    x[..3].copy_from_slice((p.dg + w.r_g).as_slice());
    for r in 0..3 {
        for c in 0..3 {
            x[3 + 3 * r + c] = d[(r, c)];
        }
    }
    x[12..15].copy_from_slice(p.kg.as_slice());
    x[15..18].copy_from_slice((p.ba + w.r_a).as_slice());
    x[18..21].copy_from_slice(p.ka.as_slice());
    x[21..24].copy_from_slice(p.k2.as_slice());
    x[24..27].copy_from_slice(w.delta_g.as_slice());
    x[27..30].copy_from_slice(w.delta_a.as_slice());
    x[30..33].copy_from_slice(w.warmup_g.as_slice());
    x[33..].copy_from_slice(w.warmup_a.as_slice());
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::scenario::ARCSEC;

    #[test]
    fn names_units_and_factors_line_up() {
        assert_eq!(instrument_names(ConfigId::M2Ps)[4], "Dg_xy");
        assert_eq!(instrument_names(ConfigId::M1Pa)[11], "Dgpa_zz");
        assert_eq!(instrument_names(ConfigId::M4Ps)[20], "ka_z");
        assert_eq!(instrument_names(ConfigId::M4Ps)[23], "k2_z");
        assert_eq!(instrument_names(ConfigId::M1Pa)[29], "ba_gm_z");
        assert_eq!(instrument_names(ConfigId::M1Pa)[35], "ba_wu_z");
        let u = instrument_units();
        assert_eq!(
            (u[0], u[3], u[12], u[15], u[18], u[21], u[24], u[27], u[30]),
            ("rad/s", "rad/s/g", "1", "g", "1", "1/g", "rad/s", "g", "rad/s")
        );
        let ascii: Vec<String> = [Group::GyroDrift, Group::GyroGDrift, Group::GyroScale]
            .into_iter()
            .chain([Group::AccelBias, Group::AccelScale, Group::ThetaAT])
            .map(ascii_unit)
            .collect();
        assert_eq!(ascii, ["deg/h", "deg/h/g", "ppm", "ug", "ppm", "rad"]);
        assert!((printed_value(Group::GyroDrift, DEG_H) - 1.0).abs() < 1e-15);
        assert!((printed_value(Group::AccelBias, 30e-6) - 30.0).abs() < 1e-12);
        assert!((printed_value(Group::ThetaGC, ARCSEC) - 1.0).abs() < 1e-15);
    }
}
