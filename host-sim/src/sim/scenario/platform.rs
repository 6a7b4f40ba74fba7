//! Platform files (TOML): a real platform's site, noise, period, prior and
//! instrument figures, with no truth (docs/csv.md §Platform file); a
//! scenario file is accepted as one.

use std::path::Path;

use rollcal::models::ConfigId;
use serde::{Deserialize, Serialize};

use super::{
    check_noise, check_path, check_prior, check_site, config_message, toml_error, Noise, Prior,
    Scenario, ScenarioError, Segment, Site,
};
use super::{InstrumentPrior, Wander};

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
    /// The instruments' prior (`[instruments.prior]`) and errors that
    /// wander (`[instruments.wander]`), used by the full model. A platform
    /// file carries no instrument values: they are what the calibration
    /// estimates.
    #[serde(default)]
    pub instruments: PlatformInstruments,
}

/// The `[instruments]` table of a platform file: the prior and the
/// errors that wander (the data sheet's figures), no values.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PlatformInstruments {
    /// Prior σ of the instrument terms.
    #[serde(default)]
    pub prior: InstrumentPrior,
    /// The errors that wander, as the model is to carry them.
    #[serde(default, skip_serializing_if = "Wander::is_default")]
    pub wander: Wander,
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
        let mut p: Platform = toml::from_str(text).map_err(err)?;
        if p.timing.period_s.is_finite() && p.timing.period_s > 0.0 {
            p.noise.normalise(p.timing.period_s)?;
        }
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
                wander: s.instruments.wander.clone(),
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
        self.instruments.wander.validate("instruments.wander")?;
        self.instruments.prior.check_wander(
            "instruments.prior",
            &self.instruments.wander,
            "instruments.wander",
        )?;
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
