//! Scenario files (TOML): truth parameters, rolling path, noise, timing and
//! prior. The paper's scenario (docs/model.md §The paper's scenario) is the built-in default and is
//! shipped as `scenarios/paper.toml`.

use std::fmt;
use std::path::Path;

use rollcal::models::{ConfigId, ParseConfigIdError};
use serde::{Deserialize, Serialize};

/// The paper's scenario, as shipped in `scenarios/paper.toml`.
pub const PAPER_TOML: &str = include_str!("../../../scenarios/paper.toml");

/// Degrees → radians.
pub const DEG: f64 = std::f64::consts::PI / 180.0;
/// Arcseconds → radians.
pub const ARCSEC: f64 = DEG / 3600.0;

/// Most filter periods a scenario may have (≈ 11.6 days at 1 s): the
/// simulator and the runs keep every period in memory.
pub const MAX_PERIODS: u64 = 1_000_000;

/// Most truth integration steps a scenario may have.
pub const MAX_TRUTH_STEPS: u64 = 1_000_000_000;

/// A complete simulation scenario. Angles in the file are degrees unless the
/// field name says otherwise.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Free-text name.
    pub name: String,
    /// True installation errors and initial attitude.
    pub truth: Truth,
    /// Site and Earth rate.
    pub site: Site,
    /// The rolling path, in order.
    pub path: Vec<Segment>,
    /// Noise levels.
    pub noise: Noise,
    /// Timing.
    pub timing: Timing,
    /// Filter prior.
    pub prior: Prior,
    /// The instruments' own errors and their prior (docs/model.md
    /// §Instrument errors). Optional: absent means all zero with the
    /// default prior, and an all-default table is not written back.
    #[serde(default, skip_serializing_if = "Instruments::is_default")]
    pub instruments: Instruments,
}

/// The instruments' own errors (docs/model.md §Instrument errors), in the
/// file's printed units, ps frame: gyro drift and scale factor,
/// accelerometer bias and scale factor. Every key is optional (default 0).
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Instruments {
    /// Constant gyro drift `dg` per gyro x, y, z (°/h).
    #[serde(default)]
    pub dg_deg_h: [f64; 3],
    /// g-sensitive gyro drift `D_g` (°/h per g), row-major: row = gyro
    /// x/y/z, column = axis of the specific force in the ps frame.
    #[serde(default)]
    pub d_g_deg_h_g: [[f64; 3]; 3],
    /// Gyro (torquer) scale-factor errors `kg` (ppm).
    #[serde(default)]
    pub kg_ppm: [f64; 3],
    /// Accelerometer bias `ba` (µg), in the accelerometers' output axes.
    #[serde(default)]
    pub ba_ug: [f64; 3],
    /// Accelerometer scale-factor errors `ka` (ppm).
    #[serde(default)]
    pub ka_ppm: [f64; 3],
    /// Prior σ of the 21 instrument states.
    #[serde(default)]
    pub prior: InstrumentPrior,
}

/// Prior σ of the instrument errors (printed units), one number per kind
/// for every axis; defaults as the instrumented scenario's (docs/model.md
/// §The instrumented scenario).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct InstrumentPrior {
    /// σ of each constant drift `dg` (°/h); default 1.
    #[serde(default = "default_sigma_dg")]
    pub sigma_dg_deg_h: f64,
    /// σ of each g-sensitive drift entry of `D_g` (°/h/g); default 1.
    #[serde(default = "default_sigma_d_g")]
    pub sigma_d_g_deg_h_g: f64,
    /// σ of each gyro scale factor `kg` (ppm); default 2000.
    #[serde(default = "default_sigma_kg")]
    pub sigma_kg_ppm: f64,
    /// σ of each accelerometer bias `ba` (µg); default 1000.
    #[serde(default = "default_sigma_ba")]
    pub sigma_ba_ug: f64,
    /// σ of each accelerometer scale factor `ka` (ppm); default 1000.
    #[serde(default = "default_sigma_ka")]
    pub sigma_ka_ppm: f64,
}

fn default_sigma_dg() -> f64 {
    1.0
}
fn default_sigma_d_g() -> f64 {
    1.0
}
fn default_sigma_kg() -> f64 {
    2000.0
}
fn default_sigma_ba() -> f64 {
    1000.0
}
fn default_sigma_ka() -> f64 {
    1000.0
}

impl InstrumentPrior {
    /// The prior as a `Configure` message carries it (internal units).
    pub fn to_wire(&self) -> rollcal::wire::InstrumentPrior {
        use crate::sim::instruments::{DEG_H, PPM, UG};
        rollcal::wire::InstrumentPrior {
            dg_rad_s: self.sigma_dg_deg_h * DEG_H,
            d_g_rad_s_g: self.sigma_d_g_deg_h_g * DEG_H,
            kg: self.sigma_kg_ppm * PPM,
            ba_g: self.sigma_ba_ug * UG,
            ka: self.sigma_ka_ppm * PPM,
        }
    }

    /// Every σ finite and > 0; errors name the key (`prefix.sigma_…`).
    pub fn validate(&self, prefix: &str) -> Result<(), ScenarioError> {
        for (name, v) in [
            ("sigma_dg_deg_h", self.sigma_dg_deg_h),
            ("sigma_d_g_deg_h_g", self.sigma_d_g_deg_h_g),
            ("sigma_kg_ppm", self.sigma_kg_ppm),
            ("sigma_ba_ug", self.sigma_ba_ug),
            ("sigma_ka_ppm", self.sigma_ka_ppm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(ScenarioError(format!(
                    "{prefix}.{name} must be finite and > 0"
                )));
            }
        }
        Ok(())
    }
}

impl Default for InstrumentPrior {
    fn default() -> Self {
        Self {
            sigma_dg_deg_h: default_sigma_dg(),
            sigma_d_g_deg_h_g: default_sigma_d_g(),
            sigma_kg_ppm: default_sigma_kg(),
            sigma_ba_ug: default_sigma_ba(),
            sigma_ka_ppm: default_sigma_ka(),
        }
    }
}

/// Largest |dg| and |D_g| entry a scenario may have (°/h, °/h/g).
pub const MAX_DRIFT_DEG_H: f64 = 10.0;
/// Largest |kg|, |ka| (ppm) and |ba| (µg) a scenario may have.
pub const MAX_SCALE_PPM_OR_BIAS_UG: f64 = 1e4;

impl Instruments {
    /// Whether every error is zero (the priors do not count): the truth
    /// simulator then runs the installation-only model, bit for bit.
    pub fn is_zero(&self) -> bool {
        let zero = |v: &[f64]| v.iter().all(|x| *x == 0.0);
        zero(&self.dg_deg_h)
            && self.d_g_deg_h_g.iter().all(|r| zero(r))
            && zero(&self.kg_ppm)
            && zero(&self.ba_ug)
            && zero(&self.ka_ppm)
    }

    /// Whether the table is what an absent `[instruments]` means (zero
    /// errors, default priors).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// Checks every value (finite, within the limits) and every prior
    /// (> 0); errors name the key.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        let within = |name: &str, v: &[f64], max: f64, unit: &str| {
            if v.iter().all(|x| x.is_finite() && x.abs() <= max) {
                Ok(())
            } else {
                Err(ScenarioError(format!(
                    "instruments.{name} must be finite and within ±{max} {unit}"
                )))
            }
        };
        within("dg_deg_h", &self.dg_deg_h, MAX_DRIFT_DEG_H, "°/h")?;
        for (i, row) in self.d_g_deg_h_g.iter().enumerate() {
            within(&format!("d_g_deg_h_g[{i}]"), row, MAX_DRIFT_DEG_H, "°/h/g")?;
        }
        let max = MAX_SCALE_PPM_OR_BIAS_UG;
        within("kg_ppm", &self.kg_ppm, max, "ppm")?;
        within("ba_ug", &self.ba_ug, max, "µg")?;
        within("ka_ppm", &self.ka_ppm, max, "ppm")?;
        self.prior.validate("instruments.prior")
    }
}

/// True installation errors (degrees), in the ps frame.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Truth {
    /// Accelerometer non-orthogonality θaT (°).
    pub theta_a_t_deg: [f64; 3],
    /// Accelerometer misalignment θaC (°).
    pub theta_a_c_deg: [f64; 3],
    /// Gyro non-orthogonality θgT (°).
    pub theta_g_t_deg: [f64; 3],
    /// Gyro misalignment θgC in the ps frame (°).
    pub theta_g_c_deg: [f64; 3],
    /// Base mounting angles λ (°).
    pub lambda_deg: [f64; 3],
    /// Initial gimbal angles θA(0) = (α, β, γ) (°).
    pub gimbal0_deg: [f64; 3],
}

/// Site.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Site {
    /// Latitude φ (°).
    pub latitude_deg: f64,
    /// Whether the Earth rotates (`--no-earth-rate` overrides to false).
    pub earth_rate: bool,
}

/// One rolling segment: rotation about a navigation-frame axis.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Segment {
    /// `north`, `south`, `up`, `down`, `east`, `west`, or `[x, y, z]` in n
    /// (North–Up–East) components (normalised).
    pub axis: Axis,
    /// Rotation angle (°, right-handed about the axis).
    pub angle_deg: f64,
    /// Rotation rate (°/s, > 0).
    pub rate_deg_s: f64,
    /// Hold still for this long after the rotation (s, ≥ 0, a whole number
    /// of periods): zero commanded path rate. Optional, default 0; a
    /// segment with `angle_deg = 0` and `dwell_s > 0` is a pure dwell.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub dwell_s: f64,
}

/// `skip_serializing_if` for an optional dwell: absent when zero, so paths
/// without dwells serialise as before.
pub(crate) fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

impl Segment {
    /// Time spent rotating (s).
    pub fn rotation_s(&self) -> f64 {
        self.angle_deg / self.rate_deg_s
    }

    /// The segment's whole duration, rotation then dwell (s).
    pub fn duration_s(&self) -> f64 {
        self.rotation_s() + self.dwell_s
    }
}

/// A rotation axis.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum Axis {
    /// A named direction.
    Named(String),
    /// Components in n.
    Vector([f64; 3]),
}

/// Noise levels (1σ).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Noise {
    /// Accelerometer noise of one period's mean, per axis (g).
    pub accel_g: f64,
    /// Gyro white rate noise, drawn once per period, per axis (°/h).
    pub gyro_deg_h: f64,
    /// Gimbal-angle noise per sample (″).
    pub gimbal_arcsec: f64,
}

/// Timing.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Timing {
    /// Filter period T (s).
    pub period_s: f64,
    /// Truth RK4 step (s); `period_s / truth_step_s` must be an even integer.
    pub truth_step_s: f64,
    /// Total duration (s), at least the path's; the platform holds still
    /// after the path ends.
    pub duration_s: f64,
}

/// Filter prior.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Prior {
    /// Prior σ of every installation angle, attitude and gimbal state (°).
    pub sigma_deg: f64,
}

/// A scenario that cannot be used, and why.
#[derive(Debug)]
pub struct ScenarioError(pub String);

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ScenarioError {}

impl Axis {
    /// The unit vector in n.
    pub fn unit(&self) -> Result<[f64; 3], ScenarioError> {
        let v = match self {
            Axis::Named(s) => match s.to_ascii_lowercase().as_str() {
                "north" => [1.0, 0.0, 0.0],
                "south" => [-1.0, 0.0, 0.0],
                "up" => [0.0, 1.0, 0.0],
                "down" => [0.0, -1.0, 0.0],
                "east" => [0.0, 0.0, 1.0],
                "west" => [0.0, 0.0, -1.0],
                other => {
                    return Err(ScenarioError(format!(
                    "unknown axis '{other}' (use north, south, up, down, east, west or [x, y, z])"
                )))
                }
            },
            Axis::Vector(v) => *v,
        };
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if !(n.is_finite() && n > 1e-12) {
            return Err(ScenarioError(
                "a path axis vector must be finite and non-zero".into(),
            ));
        }
        Ok([v[0] / n, v[1] / n, v[2] / n])
    }
}

impl Scenario {
    /// The paper's scenario (docs/model.md §The paper's scenario).
    pub fn paper() -> Self {
        // The shipped file is validated by a test; fall back never happens.
        Self::from_toml(PAPER_TOML)
            .unwrap_or_else(|e| panic!("built-in paper scenario is invalid: {e}"))
    }

    /// Parses and validates a scenario.
    pub fn from_toml(text: &str) -> Result<Self, ScenarioError> {
        let s: Scenario = toml::from_str(text)
            .map_err(|e| ScenarioError(format!("scenario file: {}", toml_error(text, &e))))?;
        s.validate()?;
        Ok(s)
    }

    /// Reads, parses and validates a scenario file.
    pub fn from_file(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| ScenarioError(format!("cannot read scenario {}: {e}", path.display())))?;
        Self::from_toml(&text).map_err(|e| ScenarioError(format!("{}: {}", path.display(), e.0)))
    }

    /// The scenario of a `--scenario FILE` option: the file's, else the
    /// paper's (the one loader of every subcommand).
    pub fn load(path: Option<&Path>) -> Result<Self, ScenarioError> {
        match path {
            Some(p) => Self::from_file(p),
            None => Ok(Self::paper()),
        }
    }

    /// Number of filter periods.
    pub fn periods(&self) -> usize {
        (self.timing.duration_s / self.timing.period_s).round() as usize
    }

    /// Truth substeps per period.
    pub fn substeps(&self) -> usize {
        (self.timing.period_s / self.timing.truth_step_s).round() as usize
    }

    /// Checks every field; errors say which and why.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        let err = |m: String| Err(ScenarioError(m));
        let t = &self.truth;
        for (name, v) in [
            ("theta_a_t_deg", t.theta_a_t_deg),
            ("theta_a_c_deg", t.theta_a_c_deg),
            ("theta_g_t_deg", t.theta_g_t_deg),
            ("theta_g_c_deg", t.theta_g_c_deg),
            ("lambda_deg", t.lambda_deg),
        ] {
            if v.iter().any(|x| !x.is_finite() || x.abs() > 5.0) {
                return err(format!("truth.{name} must be finite and within ±5° (installation errors are small angles)"));
            }
        }
        if t.gimbal0_deg.iter().any(|x| !x.is_finite()) || t.gimbal0_deg[1].abs() > 80.0 {
            return err(
                "truth.gimbal0_deg must be finite with |β| ≤ 80° (gimbal lock at ±90°)".into(),
            );
        }
        check_site(&self.site)?;
        let tm = &self.timing;
        if !(tm.period_s.is_finite() && tm.period_s > 0.0) {
            return err("timing.period_s must be > 0".into());
        }
        if !(tm.truth_step_s.is_finite() && tm.truth_step_s > 0.0 && tm.truth_step_s <= tm.period_s)
        {
            return err("timing.truth_step_s must be > 0 and ≤ period_s".into());
        }
        let ratio = tm.period_s / tm.truth_step_s;
        if (ratio - ratio.round()).abs() > 1e-9 || !(ratio.round() as u64).is_multiple_of(2) {
            return err(format!(
                "timing.period_s / truth_step_s = {ratio} must be an even integer (Simpson's rule)"
            ));
        }
        if !(tm.duration_s.is_finite() && tm.duration_s >= tm.period_s) {
            return err("timing.duration_s must be ≥ period_s".into());
        }
        let k = tm.duration_s / tm.period_s;
        if (k - k.round()).abs() > 1e-9 {
            return err("timing.duration_s must be a whole number of periods".into());
        }
        // Resource limits, before anything is allocated: the simulator keeps
        // every period (≈ 0.3 kB each, more with a time history) and
        // integrates every truth step.
        if k.round() > MAX_PERIODS as f64 {
            return err(format!(
                "timing.duration_s / period_s = {:.0} periods, more than the {MAX_PERIODS} this tool simulates (every period is kept in memory)",
                k.round()
            ));
        }
        let steps = k.round() * ratio.round();
        if steps > MAX_TRUTH_STEPS as f64 {
            return err(format!(
                "timing: {steps:.0} truth steps (duration_s / truth_step_s), more than the {MAX_TRUTH_STEPS} this tool integrates; lengthen truth_step_s"
            ));
        }
        if self.path.is_empty() {
            return err("path must have at least one segment".into());
        }
        check_path(&self.path, tm.period_s)?;
        let path_s: f64 = self.path.iter().map(Segment::duration_s).sum();
        if path_s > tm.duration_s + 1e-6 * tm.period_s {
            return err(format!(
                "the path lasts {path_s} s but timing.duration_s is {} s: the path would be cut (lengthen duration_s to at least {path_s}, or shorten the path)",
                tm.duration_s
            ));
        }
        check_noise(&self.noise)?;
        check_prior(&self.prior)?;
        self.instruments.validate()
    }
}

/// A TOML error on one line: `line N: message`.
fn toml_error(text: &str, e: &toml::de::Error) -> String {
    let msg = e.message().trim().replace('\n', "; ");
    match e.span() {
        Some(span) => {
            let line = text
                .get(..span.start)
                .map_or(0, |t| t.matches('\n').count())
                + 1;
            format!("line {line}: {msg}")
        }
        None => msg,
    }
}

fn check_site(site: &Site) -> Result<(), ScenarioError> {
    if !site.latitude_deg.is_finite() || site.latitude_deg.abs() > 90.0 {
        return Err(ScenarioError(
            "site.latitude_deg must be within ±90°".into(),
        ));
    }
    Ok(())
}

fn check_path(path: &[Segment], period_s: f64) -> Result<(), ScenarioError> {
    let err = |m: String| Err(ScenarioError(m));
    for (i, seg) in path.iter().enumerate() {
        seg.axis
            .unit()
            .map_err(|e| ScenarioError(format!("path[{i}]: {e}")))?;
        if !(seg.rate_deg_s.is_finite() && seg.rate_deg_s > 0.0 && seg.rate_deg_s <= 10.0) {
            return err(format!("path[{i}].rate_deg_s must be in (0, 10] °/s"));
        }
        if !(seg.dwell_s.is_finite() && seg.dwell_s >= 0.0) {
            return err(format!("path[{i}].dwell_s must be finite and ≥ 0 s"));
        }
        let pure_dwell = seg.angle_deg == 0.0 && seg.dwell_s > 0.0;
        if !(seg.angle_deg.is_finite() && (seg.angle_deg > 0.0 || pure_dwell)) {
            return err(format!(
                "path[{i}].angle_deg must be > 0 (or 0 with dwell_s > 0, a pure dwell)"
            ));
        }
        let w = seg.dwell_s / period_s;
        if (w - w.round()).abs() > 1e-6 {
            return err(format!(
                "path[{i}].dwell_s = {} s is not a whole number of {} s periods",
                seg.dwell_s, period_s
            ));
        }
        let d = seg.angle_deg / seg.rate_deg_s / period_s;
        if (d - d.round()).abs() > 1e-6 {
            return err(format!(
                "path[{i}] lasts {} s, not a whole number of {} s periods: the filter assumes a constant path rate over each period",
                seg.angle_deg / seg.rate_deg_s,
                period_s
            ));
        }
    }
    Ok(())
}

fn check_noise(n: &Noise) -> Result<(), ScenarioError> {
    let err = |m: &str| Err(ScenarioError(m.into()));
    if !(n.accel_g.is_finite() && n.accel_g > 0.0) {
        return err("noise.accel_g must be > 0");
    }
    if !(n.gyro_deg_h.is_finite() && n.gyro_deg_h >= 0.0) {
        return err("noise.gyro_deg_h must be ≥ 0");
    }
    if !(n.gimbal_arcsec.is_finite() && n.gimbal_arcsec > 0.0) {
        return err("noise.gimbal_arcsec must be > 0");
    }
    Ok(())
}

fn check_prior(p: &Prior) -> Result<(), ScenarioError> {
    if !(p.sigma_deg.is_finite() && p.sigma_deg > 0.0) {
        return Err(ScenarioError("prior.sigma_deg must be > 0".into()));
    }
    Ok(())
}

/// The message of a text `s` that names no configuration: core's
/// [`ParseConfigIdError`] (`unknown configuration '…' (expected one of
/// M1-pa, …)`) with the whole text, where core keeps at most
/// [`ParseConfigIdError::INPUT_CAPACITY`] bytes of it.
pub fn config_message(e: &ParseConfigIdError, s: &str) -> String {
    // The text is the first thing the message quotes (after a prefix that
    // cannot hold a cut text, which ends with `…`).
    e.to_string().replacen(e.input(), s, 1)
}

/// A platform file (TOML): what the calibrator needs to know of a real
/// platform — configuration, site, noise levels, period, prior and
/// optionally the nominal rolling path (for reporting) — and no truth.
/// The tables are those of a scenario file; a scenario file is also
/// accepted as a platform file (its truth is then ignored).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Platform {
    /// Free-text name.
    #[serde(default)]
    pub name: String,
    /// Configuration (M1-pa, M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps;
    /// case-insensitive). Optional: `calibrate --config` may give it.
    #[serde(default)]
    pub config: Option<String>,
    /// Site and Earth rate.
    pub site: Site,
    /// Noise levels.
    pub noise: Noise,
    /// Timing.
    pub timing: PlatformTiming,
    /// Filter prior.
    pub prior: Prior,
    /// The nominal rolling path (optional; for reporting only).
    #[serde(default)]
    pub path: Vec<Segment>,
    /// The error model to calibrate (`installation`, the default, or
    /// `full`: the instruments' own errors too); `calibrate --errors`
    /// overrides it.
    #[serde(default)]
    pub errors: Option<String>,
    /// The instruments' prior (`[instruments.prior]`, used by the full
    /// model; default docs/model.md §The instrumented scenario's). A platform file carries no instrument
    /// values: they are what the calibration estimates.
    #[serde(default)]
    pub instruments: PlatformInstruments,
}

/// The `[instruments]` table of a platform file: the prior alone.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PlatformInstruments {
    /// Prior σ of the 21 instrument states.
    #[serde(default)]
    pub prior: InstrumentPrior,
}

/// Timing of a platform.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PlatformTiming {
    /// Filter period T (s).
    pub period_s: f64,
    /// Expected duration of a log (s), for the progress line (optional).
    #[serde(default)]
    pub duration_s: Option<f64>,
}

impl Platform {
    /// Parses and validates a platform file; a scenario file (one with a
    /// `[truth]` table) is read as a scenario and its truth ignored.
    pub fn from_toml(text: &str) -> Result<Self, ScenarioError> {
        let err =
            |e: toml::de::Error| ScenarioError(format!("platform file: {}", toml_error(text, &e)));
        let value: toml::Table = toml::from_str(text).map_err(err)?;
        if value.contains_key("truth") {
            return Scenario::from_toml(text).map(|s| Self::of_scenario(&s));
        }
        let p: Platform = toml::from_str(text).map_err(err)?;
        p.validate()?;
        Ok(p)
    }

    /// Reads, parses and validates a platform file.
    pub fn from_file(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|e| {
            ScenarioError(format!("cannot read platform file {}: {e}", path.display()))
        })?;
        Self::from_toml(&text).map_err(|e| ScenarioError(format!("{}: {}", path.display(), e.0)))
    }

    /// The platform part of a scenario (no configuration).
    pub fn of_scenario(s: &Scenario) -> Self {
        Self {
            name: s.name.clone(),
            config: None,
            site: s.site.clone(),
            noise: s.noise.clone(),
            timing: PlatformTiming {
                period_s: s.timing.period_s,
                duration_s: Some(s.timing.duration_s),
            },
            prior: s.prior.clone(),
            path: s.path.clone(),
            errors: None,
            instruments: PlatformInstruments {
                prior: s.instruments.prior.clone(),
            },
        }
    }

    /// The error model the file names (`errors`), if any.
    pub fn error_model(&self) -> Option<rollcal::models::ErrorModel> {
        self.errors
            .as_deref()
            .and_then(rollcal::models::ErrorModel::parse)
    }

    /// The configuration the file names, if any.
    pub fn config_id(&self) -> Option<rollcal::models::ConfigId> {
        self.config
            .as_deref()
            .and_then(rollcal::models::ConfigId::parse)
    }

    /// Expected number of periods of a log (`timing.duration_s`, else the
    /// path's length), 0 when unknown.
    pub fn periods(&self) -> usize {
        let path_s: f64 = self.path.iter().map(Segment::duration_s).sum();
        (self.timing.duration_s.unwrap_or(path_s) / self.timing.period_s).round() as usize
    }

    /// Checks every field; errors say which and why.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        if let Some(c) = &self.config {
            c.parse::<ConfigId>()
                .map_err(|e| ScenarioError(format!("config: {}", config_message(&e, c))))?;
        }
        if let Some(e) = &self.errors {
            e.parse::<rollcal::models::ErrorModel>()
                .map_err(|err| ScenarioError(format!("errors: '{e}': {err}")))?;
        }
        self.instruments.prior.validate("instruments.prior")?;
        check_site(&self.site)?;
        let tm = &self.timing;
        if !(tm.period_s.is_finite() && tm.period_s > 0.0) {
            return Err(ScenarioError("timing.period_s must be > 0".into()));
        }
        if let Some(d) = tm.duration_s {
            if !(d.is_finite() && d >= tm.period_s) {
                return Err(ScenarioError("timing.duration_s must be ≥ period_s".into()));
            }
        }
        check_path(&self.path, tm.period_s)?;
        check_noise(&self.noise)?;
        check_prior(&self.prior)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_file_parses() {
        let s = Scenario::paper();
        assert_eq!(s.periods(), 5400);
        assert_eq!(s.substeps(), 100);
    }

    #[test]
    fn bad_fields_are_reported() {
        let bad = PAPER_TOML.replace("period_s = 1.0", "period_s = -1.0");
        let e = Scenario::from_toml(&bad).unwrap_err();
        assert!(e.0.contains("period_s"), "{e}");
        let bad = PAPER_TOML.replace("rate_deg_s = 0.1", "rate_deg_s = 0.07");
        assert!(Scenario::from_toml(&bad)
            .unwrap_err()
            .0
            .contains("whole number"));
        assert!(Scenario::from_toml("name = 3").is_err());
    }
}
