//! The calibrator's bounds on a file's data-sheet figures
//! (`rollcal::wire::ConfigField::bounds`), checked where the file is read so
//! that a refusal names the file's key in its units, not the `Configure`
//! field the key becomes (issue 43): `[instruments.prior]` and
//! `[instruments.wander]` of a scenario or a platform file.

use rollcal::wire::ConfigField;

use super::{InstrumentPrior, ScenarioError, Wander};

/// A key of the file: the field it becomes, its name and value (printed
/// units) and its unit.
type Key = (ConfigField, &'static str, f64, &'static str);

/// `Ok` when `found` (the first field of the file's `Configure` form the
/// calibrator refuses) is `None`; else the error naming the key of `keys`
/// that became it, with its value and the field's value and bounds.
fn check(
    prefix: &str,
    found: Option<ConfigField>,
    keys: &[Key],
    wire: impl Fn(ConfigField) -> f64,
) -> Result<(), ScenarioError> {
    let Some(field) = found else {
        return Ok(());
    };
    let key = keys.iter().find(|k| k.0 == field);
    let (name, value, unit) = key.map_or(("?", f64::NAN, ""), |k| (k.1, k.2, k.3));
    Err(ScenarioError(format!(
        "{prefix}.{name} = {} {unit} is outside the calibrator's bounds: {field} = {}, not {}",
        short(value),
        short(wire(field)),
        field.bounds()
    )))
}

/// `v` as written in a file where that is short (`100`, `0.003`), else in
/// exponent form to five significant digits at most (`1e8`, `4.8481e-18`).
fn short(v: f64) -> String {
    if v == 0.0 || (1e-3..1e6).contains(&v.abs()) {
        return format!("{v}");
    }
    let e = format!("{v:.4e}");
    match e.split_once('e') {
        Some((m, x)) if m.contains('.') => {
            format!("{}e{x}", m.trim_end_matches('0').trim_end_matches('.'))
        }
        _ => e,
    }
}

impl InstrumentPrior {
    /// The calibrator's bounds on the prior σ ([`ConfigField::bounds`]):
    /// errors name the key (`prefix.sigma_…`).
    pub(super) fn check_bounds(&self, prefix: &str) -> Result<(), ScenarioError> {
        let keys: [Key; 6] = [
            (
                ConfigField::PriorDg,
                "sigma_dg_deg_h",
                self.sigma_dg_deg_h,
                "°/h",
            ),
            (
                ConfigField::PriorDG,
                "sigma_d_g_deg_h_g",
                self.sigma_d_g_deg_h_g,
                "°/h/g",
            ),
            (
                ConfigField::PriorKg,
                "sigma_kg_ppm",
                self.sigma_kg_ppm,
                "ppm",
            ),
            (ConfigField::PriorBa, "sigma_ba_ug", self.sigma_ba_ug, "µg"),
            (
                ConfigField::PriorKa,
                "sigma_ka_ppm",
                self.sigma_ka_ppm,
                "ppm",
            ),
            (
                ConfigField::PriorK2,
                "sigma_k2_ug_g2",
                self.sigma_k2_ug_g2,
                "µg/g²",
            ),
        ];
        let wire = self.to_wire();
        check(prefix, wire.invalid_field(), &keys, |field| {
            let mut c = rollcal::wire::CalibratorConfig::paper(rollcal::models::ConfigId::M1Pa);
            c.instrument_prior = wire;
            field.value(&c)
        })
    }
}

impl Wander {
    /// The calibrator's bounds on the wandering figures
    /// ([`ConfigField::bounds`]): errors name the key (`prefix.…`).
    pub(super) fn check_bounds(&self, prefix: &str) -> Result<(), ScenarioError> {
        let keys: [Key; 9] = [
            (
                ConfigField::GyroMarkovSigma,
                "gyro_bias_instability_deg_h",
                self.gyro_bias_instability_deg_h,
                "°/h",
            ),
            (
                ConfigField::GyroMarkovTau,
                "gyro_correlation_time_s",
                self.gyro_correlation_time_s,
                "s",
            ),
            (
                ConfigField::GyroRandomWalk,
                "gyro_rate_random_walk_deg_h_rt_h",
                self.gyro_rate_random_walk_deg_h_rt_h,
                "°/h/√h",
            ),
            (
                ConfigField::AccelMarkovSigma,
                "accel_bias_instability_ug",
                self.accel_bias_instability_ug,
                "µg",
            ),
            (
                ConfigField::AccelMarkovTau,
                "accel_correlation_time_s",
                self.accel_correlation_time_s,
                "s",
            ),
            (
                ConfigField::AccelRandomWalk,
                "accel_random_walk_ug_rt_h",
                self.accel_random_walk_ug_rt_h,
                "µg/√h",
            ),
            (
                ConfigField::GyroWarmupSigma,
                "gyro_warmup_deg_h",
                self.gyro_warmup_deg_h,
                "°/h",
            ),
            (
                ConfigField::AccelWarmupSigma,
                "accel_warmup_ug",
                self.accel_warmup_ug,
                "µg",
            ),
            (
                ConfigField::WarmupTau,
                "warmup_time_constant_s",
                self.warmup_time_constant_s,
                "s",
            ),
        ];
        let model = self.to_model();
        check(prefix, model.invalid_field(), &keys, |field| {
            let mut c = rollcal::wire::CalibratorConfig::paper(rollcal::models::ConfigId::M1Pa);
            c.wander = model;
            field.value(&c)
        })
    }
}
