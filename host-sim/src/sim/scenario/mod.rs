//! Scenario files (TOML): truth parameters, rolling path, noise, timing and
//! prior. The paper's scenario (docs/model.md §The paper's scenario) is the built-in default and is
//! shipped as `scenarios/paper.toml`.

use std::fmt;
use std::path::Path;

use rollcal::models::ParseConfigIdError;
use serde::{Deserialize, Serialize};

mod bounds;
mod platform;
pub use platform::{Platform, PlatformInstruments, PlatformTiming};

/// The paper's scenario, as shipped in `scenarios/paper.toml`.
pub const PAPER_TOML: &str = include_str!("../../../../scenarios/paper.toml");

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
    /// Accelerometer second-order coefficients `k2` (µg/g²): the output
    /// gains `k2_i u_i²`, `u` the specific force along the input axis.
    #[serde(default)]
    pub k2_ug_g2: [f64; 3],
    /// Prior σ of the instrument terms.
    #[serde(default)]
    pub prior: InstrumentPrior,
    /// The errors that wander, in data-sheet units: the truth's and the
    /// model's (docs/model.md §Errors that wander).
    #[serde(default, skip_serializing_if = "Wander::is_default")]
    pub wander: Wander,
    /// The warm-up transient of the drift and the bias (the truth only:
    /// no model carries it).
    #[serde(default, skip_serializing_if = "Warmup::is_default")]
    pub warmup: Warmup,
}

/// The instruments' errors that wander (docs/model.md §Errors that wander),
/// per axis, in data-sheet units (IEEE Std 952 / 1293 terms); every key
/// optional, 0 (or absent) meaning "no such term". In a scenario the
/// bias instabilities and random walks are the truth and the model, the
/// warm-up σ the model's (the truth's warm-up is `[instruments.warmup]`);
/// in a platform file all are the model.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Wander {
    /// Gyro bias instability σ_bg (°/h): the stationary σ of a first-order
    /// Gauss–Markov drift.
    #[serde(default)]
    pub gyro_bias_instability_deg_h: f64,
    /// Its correlation time τ_g (s); needed when the instability is given.
    #[serde(default)]
    pub gyro_correlation_time_s: f64,
    /// Gyro rate random walk K_g (°/h/√h): the drift's σ after t hours is
    /// `K_g √t`.
    #[serde(default)]
    pub gyro_rate_random_walk_deg_h_rt_h: f64,
    /// Accelerometer bias instability σ_ba (µg), Gauss–Markov.
    #[serde(default)]
    pub accel_bias_instability_ug: f64,
    /// Its correlation time τ_a (s).
    #[serde(default)]
    pub accel_correlation_time_s: f64,
    /// Accelerometer acceleration random walk K_a (µg/√h).
    #[serde(default)]
    pub accel_random_walk_ug_rt_h: f64,
    /// Gyro warm-up: the σ of the amplitude `Δ_g` (°/h) of the drift's
    /// transient `Δ_g e^(−t/τ_w)` from the start of the log.
    #[serde(default)]
    pub gyro_warmup_deg_h: f64,
    /// Accelerometer warm-up: the σ of the amplitude `Δ_a` (µg).
    #[serde(default)]
    pub accel_warmup_ug: f64,
    /// The warm-up's time constant τ_w (s); needed when a warm-up is given.
    #[serde(default)]
    pub warmup_time_constant_s: f64,
}

/// The largest bias instability or random walk a file may give: 10 °/h
/// (°/h/√h) for the gyros, 10⁴ µg (µg/√h) for the accelerometers.
pub const MAX_WANDER: (f64, f64) = (10.0, 1e4);

/// The longest correlation or warm-up time a file may give (s): 10⁷
/// (about 116 days).
pub const MAX_TIME_CONSTANT_S: f64 = 1e7;

impl Wander {
    /// Whether the table is absent (every figure zero).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// The model's figures in internal units (rad/s, s, rad/s/√s, g, s,
    /// g/√s): °/h × π/(180·3600); °/h/√h and µg/√h ÷ 60 (√h = 60 √s).
    pub fn to_model(&self) -> rollcal::models::Wander<f64> {
        use crate::sim::instruments::{DEG_H, UG};
        rollcal::models::Wander {
            gyro_markov_sigma: self.gyro_bias_instability_deg_h * DEG_H,
            gyro_markov_tau_s: self.gyro_correlation_time_s,
            gyro_random_walk: self.gyro_rate_random_walk_deg_h_rt_h * DEG_H / 60.0,
            accel_markov_sigma: self.accel_bias_instability_ug * UG,
            accel_markov_tau_s: self.accel_correlation_time_s,
            accel_random_walk: self.accel_random_walk_ug_rt_h * UG / 60.0,
            gyro_warmup_sigma: self.gyro_warmup_deg_h * DEG_H,
            accel_warmup_sigma: self.accel_warmup_ug * UG,
            warmup_tau_s: self.warmup_time_constant_s,
        }
    }

    /// Every figure finite and ≥ 0 and within [`MAX_WANDER`], each
    /// correlation time > 0 and ≤ [`MAX_TIME_CONSTANT_S`] where its
    /// instability is given, and every figure within the calibrator's
    /// bounds (`rollcal::wire::ConfigField::bounds`); errors name the key
    /// (`prefix.…`).
    pub fn validate(&self, prefix: &str) -> Result<(), ScenarioError> {
        let (gyro_max, accel_max) = MAX_WANDER;
        for (name, v, max, unit) in [
            (
                "gyro_bias_instability_deg_h",
                self.gyro_bias_instability_deg_h,
                gyro_max,
                "°/h",
            ),
            (
                "gyro_rate_random_walk_deg_h_rt_h",
                self.gyro_rate_random_walk_deg_h_rt_h,
                gyro_max,
                "°/h/√h",
            ),
            (
                "accel_bias_instability_ug",
                self.accel_bias_instability_ug,
                accel_max,
                "µg",
            ),
            (
                "accel_random_walk_ug_rt_h",
                self.accel_random_walk_ug_rt_h,
                accel_max,
                "µg/√h",
            ),
            ("gyro_warmup_deg_h", self.gyro_warmup_deg_h, gyro_max, "°/h"),
            ("accel_warmup_ug", self.accel_warmup_ug, accel_max, "µg"),
        ] {
            if !(v.is_finite() && (0.0..=max).contains(&v)) {
                return Err(ScenarioError(format!(
                    "{prefix}.{name} = {v} must be finite, ≥ 0 and ≤ {max} {unit}"
                )));
            }
        }
        for (sigma_name, sigma, tau_name, tau) in [
            (
                "gyro_bias_instability_deg_h",
                self.gyro_bias_instability_deg_h,
                "gyro_correlation_time_s",
                self.gyro_correlation_time_s,
            ),
            (
                "accel_bias_instability_ug",
                self.accel_bias_instability_ug,
                "accel_correlation_time_s",
                self.accel_correlation_time_s,
            ),
        ] {
            if !(tau.is_finite() && (0.0..=MAX_TIME_CONSTANT_S).contains(&tau)) {
                return Err(ScenarioError(format!(
                    "{prefix}.{tau_name} = {tau} must be finite, ≥ 0 and ≤ {MAX_TIME_CONSTANT_S} s"
                )));
            }
            if sigma > 0.0 && tau < 1.0 {
                return Err(ScenarioError(format!(
                    "{prefix}.{tau_name} = {tau} s: a bias instability ({prefix}.{sigma_name} = {sigma}) needs its correlation time, at least 1 s"
                )));
            }
        }
        let tau = self.warmup_time_constant_s;
        if !(tau.is_finite() && (0.0..=MAX_TIME_CONSTANT_S).contains(&tau)) {
            return Err(ScenarioError(format!(
                "{prefix}.warmup_time_constant_s = {tau} must be finite, ≥ 0 and ≤ {MAX_TIME_CONSTANT_S} s"
            )));
        }
        if (self.gyro_warmup_deg_h > 0.0 || self.accel_warmup_ug > 0.0) && tau < 1.0 {
            return Err(ScenarioError(format!(
                "{prefix}.warmup_time_constant_s = {tau} s: a warm-up ({prefix}.gyro_warmup_deg_h or accel_warmup_ug) needs its time constant, at least 1 s"
            )));
        }
        self.check_bounds(prefix)
    }
}

/// The warm-up transient of the truth: the drift gains
/// `Δ_g e^(−t/τ_w)` and the bias `Δ_a e^(−t/τ_w)` (deterministic, t from
/// the start of the log). Every key optional (default 0).
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Warmup {
    /// Δ_g per gyro x, y, z (°/h).
    #[serde(default)]
    pub gyro_deg_h: [f64; 3],
    /// Δ_a per accelerometer x, y, z (µg).
    #[serde(default)]
    pub accel_ug: [f64; 3],
    /// τ_w (s), needed when a Δ is not zero.
    #[serde(default)]
    pub time_constant_s: f64,
}

impl Warmup {
    /// Whether the table is absent (no transient).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// Whether there is a transient.
    pub fn is_zero(&self) -> bool {
        self.gyro_deg_h
            .iter()
            .chain(&self.accel_ug)
            .all(|v| *v == 0.0)
    }

    /// Finite values within the drift and bias limits, a time constant
    /// in (0, [`MAX_TIME_CONSTANT_S`]] where a Δ is given; errors name the
    /// key.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        let ok = |v: &[f64; 3], max: f64| v.iter().all(|x| x.is_finite() && x.abs() <= max);
        if !ok(&self.gyro_deg_h, MAX_DRIFT_DEG_H) {
            return Err(ScenarioError(format!(
                "instruments.warmup.gyro_deg_h must be finite and within ±{MAX_DRIFT_DEG_H} °/h"
            )));
        }
        if !ok(&self.accel_ug, MAX_SCALE_PPM_OR_BIAS_UG) {
            return Err(ScenarioError(format!(
                "instruments.warmup.accel_ug must be finite and within ±{MAX_SCALE_PPM_OR_BIAS_UG} µg"
            )));
        }
        let tau = self.time_constant_s;
        if !(tau.is_finite() && (0.0..=MAX_TIME_CONSTANT_S).contains(&tau))
            || (!self.is_zero() && tau <= 0.0)
        {
            return Err(ScenarioError(format!(
                "instruments.warmup.time_constant_s = {tau} must be > 0 and ≤ {MAX_TIME_CONSTANT_S} s when a warm-up is given"
            )));
        }
        Ok(())
    }
}

/// Prior σ of the instrument errors (printed units), one number per kind
/// for every axis; defaults as the instrumented and realistic scenarios'
/// (docs/model.md §Instrument errors).
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
    /// σ of each accelerometer second-order coefficient `k2` (µg/g²);
    /// default 100.
    #[serde(default = "default_sigma_k2")]
    pub sigma_k2_ug_g2: f64,
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
fn default_sigma_k2() -> f64 {
    100.0
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
            k2: self.sigma_k2_ug_g2 * UG,
        }
    }

    /// Every σ finite and ≥ 0 (0: the term is not estimated) and within
    /// the calibrator's bounds (`rollcal::wire::ConfigField::bounds`);
    /// errors name the key (`prefix.sigma_…`).
    pub fn validate(&self, prefix: &str) -> Result<(), ScenarioError> {
        for (name, v) in [
            ("sigma_dg_deg_h", self.sigma_dg_deg_h),
            ("sigma_d_g_deg_h_g", self.sigma_d_g_deg_h_g),
            ("sigma_kg_ppm", self.sigma_kg_ppm),
            ("sigma_ba_ug", self.sigma_ba_ug),
            ("sigma_ka_ppm", self.sigma_ka_ppm),
            ("sigma_k2_ug_g2", self.sigma_k2_ug_g2),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ScenarioError(format!(
                    "{prefix}.{name} = {v} must be finite and ≥ 0 (0: the term is not estimated)"
                )));
            }
        }
        self.check_bounds(prefix)
    }

    /// The prior and the wandering errors agree: a drift or bias that is not
    /// estimated (σ 0) cannot wander (its random walk would have to be
    /// estimated). Errors name both keys.
    pub fn check_wander(
        &self,
        prefix: &str,
        wander: &Wander,
        wander_prefix: &str,
    ) -> Result<(), ScenarioError> {
        for (sigma_name, sigma, walk_name, walk) in [
            (
                "sigma_dg_deg_h",
                self.sigma_dg_deg_h,
                "gyro_rate_random_walk_deg_h_rt_h",
                wander.gyro_rate_random_walk_deg_h_rt_h,
            ),
            (
                "sigma_ba_ug",
                self.sigma_ba_ug,
                "accel_random_walk_ug_rt_h",
                wander.accel_random_walk_ug_rt_h,
            ),
        ] {
            if sigma == 0.0 && walk > 0.0 {
                return Err(ScenarioError(format!(
                    "{prefix}.{sigma_name} = 0 (not estimated) but {wander_prefix}.{walk_name} = {walk}: a term that wanders must be estimated; give it a prior σ, or set its random walk to 0"
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
            sigma_k2_ug_g2: default_sigma_k2(),
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
            && zero(&self.k2_ug_g2)
            && self.wander.is_default()
            && self.warmup.is_zero()
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
        within("k2_ug_g2", &self.k2_ug_g2, max, "µg/g²")?;
        self.prior.validate("instruments.prior")?;
        self.wander.validate("instruments.wander")?;
        self.prior
            .check_wander("instruments.prior", &self.wander, "instruments.wander")?;
        self.warmup.validate()
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

/// Noise levels (1σ). The white noises are given per period (`accel_g`,
/// `gyro_deg_h`) or as a data sheet gives them (`accel_vrw_ug_rt_hz`,
/// `gyro_arw_deg_rt_h`), one of each pair; [`Noise::normalise`] turns the
/// latter into the former for the file's period.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Noise {
    /// Accelerometer noise of one period's mean, per axis (g).
    #[serde(default = "unset")]
    pub accel_g: f64,
    /// Gyro white rate noise, drawn once per period, per axis (°/h).
    #[serde(default = "unset")]
    pub gyro_deg_h: f64,
    /// Gimbal-angle noise per sample (″).
    pub gimbal_arcsec: f64,
    /// Accelerometer velocity random walk N_a (µg/√Hz): one period's mean
    /// has σ = N_a/√T (T in s), instead of `accel_g`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accel_vrw_ug_rt_hz: Option<f64>,
    /// Gyro angle random walk N_g (°/√h): the rate noise of one period has
    /// σ = N_g/√T (T in h, giving °/h), instead of `gyro_deg_h`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gyro_arw_deg_rt_h: Option<f64>,
}

/// The value of a noise key the file did not give.
fn unset() -> f64 {
    f64::NAN
}

impl Noise {
    /// The per-period σ from the data-sheet keys, for the period `period_s`
    /// (s): `accel_g = N_a·1e-6/√T`, `gyro_deg_h = N_g·60/√T` (√h = 60 √s).
    /// Exactly one key of each pair must be given; errors name them.
    pub fn normalise(&mut self, period_s: f64) -> Result<(), ScenarioError> {
        let pairs = [
            (
                "noise.accel_g",
                &mut self.accel_g,
                "noise.accel_vrw_ug_rt_hz",
                self.accel_vrw_ug_rt_hz.take(),
                1e-6,
            ),
            (
                "noise.gyro_deg_h",
                &mut self.gyro_deg_h,
                "noise.gyro_arw_deg_rt_h",
                self.gyro_arw_deg_rt_h.take(),
                60.0,
            ),
        ];
        for (key, per_period, sheet_key, sheet, factor) in pairs {
            match (per_period.is_nan(), sheet) {
                (false, Some(_)) => {
                    return Err(ScenarioError(format!(
                        "give {key} or {sheet_key}, not both"
                    )))
                }
                (true, None) => {
                    return Err(ScenarioError(format!("{key} (or {sheet_key}) is missing")))
                }
                (true, Some(v)) => {
                    if !(v.is_finite() && v >= 0.0) {
                        return Err(ScenarioError(format!(
                            "{sheet_key} = {v} must be finite and ≥ 0"
                        )));
                    }
                    *per_period = v * factor / period_s.sqrt();
                }
                (false, None) => {}
            }
        }
        Ok(())
    }
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
        let mut s: Scenario = toml::from_str(text)
            .map_err(|e| ScenarioError(format!("scenario file: {}", toml_error(text, &e))))?;
        if s.timing.period_s.is_finite() && s.timing.period_s > 0.0 {
            s.noise.normalise(s.timing.period_s)?;
        }
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
