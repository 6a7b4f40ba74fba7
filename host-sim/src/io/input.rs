//! The input of `calibrate`: its format, the settings for a stream without
//! a `Configure` (a platform file, else a scenario, else the paper's), the
//! configuration and error model asked for, and the samples of a CSV log
//! with the `Configure` they are sent after (docs/csv.md).

use std::path::Path;

use rollcal::models::{ConfigId, ErrorModel};
use rollcal::wire::{CalibratorConfig, Sample};

use super::csvlog;
use super::stream::{read_text, Format};
use super::Error;
use crate::sim::scenario::{Platform, Scenario};

/// What `calibrate` reads, and with which settings.
#[derive(Clone, Debug)]
pub struct Input {
    /// The input: a file, `-` for stdin, or a serial device.
    pub path: String,
    /// Frames or CSV.
    pub format: Format,
    /// The platform file's settings, else the scenario's (default: the
    /// paper's).
    pub platform: Platform,
    /// Where `platform` comes from, for the messages.
    pub source: String,
    /// The configuration `--config` or the platform file names.
    pub expected: Option<ConfigId>,
    /// The error model `--errors` or the platform file names.
    pub errors: Option<ErrorModel>,
}

/// The options that choose the input and its settings.
#[derive(Clone, Copy, Debug)]
pub struct InputOptions<'a> {
    /// The input (`--input`).
    pub path: &'a str,
    /// `--format` (default: by the name's extension).
    pub format: Option<Format>,
    /// `--platform`.
    pub platform: Option<&'a Path>,
    /// `--scenario`.
    pub scenario: Option<&'a Path>,
    /// `--config`.
    pub config: Option<ConfigId>,
    /// `--errors`.
    pub errors: Option<ErrorModel>,
}

/// The samples of a CSV log and the `Configure` they are sent after.
#[derive(Clone, Debug)]
pub struct CsvInput {
    /// The samples, in file order.
    pub samples: Vec<Sample>,
    /// The settings the calibrator is configured with.
    pub settings: CalibratorConfig,
    /// The line of each sample in the file (1-based).
    pub lines: Vec<usize>,
    /// Whether the log has the gimbal columns.
    pub has_gimbal: bool,
    /// The note about the columns read past, if any.
    pub ignored_note: Option<String>,
}

impl Input {
    /// The format of the input and the settings without a `Configure`
    /// message: the platform file's, else the scenario's (default: the
    /// paper's). A `--config` that contradicts the platform file is an
    /// error naming both.
    pub fn resolve(o: &InputOptions<'_>) -> Result<Self, Error> {
        let format = o
            .format
            .unwrap_or(if o.path.to_ascii_lowercase().ends_with(".csv") {
                Format::Csv
            } else {
                Format::Frames
            });
        let (platform, source) = match o.platform {
            Some(path) => (
                Platform::from_file(path).map_err(|e| Error::Settings(e.to_string()))?,
                format!("the platform file {}", path.display()),
            ),
            None => {
                let sc = Scenario::load(o.scenario).map_err(|e| Error::Settings(e.to_string()))?;
                let what = o.scenario.map_or_else(
                    || "the paper's scenario".to_string(),
                    |p| format!("the scenario {}", p.display()),
                );
                (Platform::of_scenario(&sc), what)
            }
        };
        let expected = match (o.config, platform.config_id()) {
            (Some(a), Some(b)) if a != b => {
                return Err(Error::Settings(format!(
                    "--config {a} contradicts the configuration {b} of {source}"
                )))
            }
            (a, b) => a.or(b),
        };
        let errors = o.errors.or(platform.error_model());
        Ok(Input {
            path: o.path.to_string(),
            format,
            platform,
            source,
            expected,
            errors,
        })
    }

    /// The samples of a CSV log and the settings to configure the
    /// calibrator with (`fallback`, else the paper's of the configuration).
    pub fn read_csv(&self, fallback: Option<CalibratorConfig>) -> Result<CsvInput, Error> {
        let source = &self.source;
        let Some(id) = self.expected else {
            return Err(Error::Settings(format!(
                "a CSV log has no Configure message: give --config, or --platform FILE with config = \"…\" ({source} names none)"
            )));
        };
        let text = read_text(&self.path)?;
        let mut log =
            csvlog::parse(&text).map_err(|e| Error::Csv(format!("{}: {e}", self.path)))?;
        let settings = fallback.unwrap_or_else(|| CalibratorConfig {
            errors: self.errors.unwrap_or_default(),
            ..CalibratorConfig::paper(id)
        });
        if !log.has_frames {
            csvlog::fill_frames(&mut log.samples, &settings)
                .map_err(|e| Error::Csv(format!("{}: {e}", self.path)))?;
        }
        Ok(CsvInput {
            ignored_note: log.ignored_note(),
            samples: log.samples,
            settings,
            lines: log.lines,
            has_gimbal: log.has_gimbal,
        })
    }
}
