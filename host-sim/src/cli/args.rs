//! Arguments shared by several subcommands: the common options of `run`
//! and `summary`, the cold-start remedies, and the parsers of a
//! configuration and a scenario option.

use std::path::{Path, PathBuf};

use rollcal::models::{ConfigId, ErrorModel};

use super::Error;
use crate::analysis::remedies::Remedy;
use crate::analysis::runner::{Estimator, Precision};
use crate::sim::scenario::{config_message, Scenario};

/// The value parser of every `--config`: a configuration by name, M1-pa,
/// M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps (case-insensitive; core's
/// `FromStr for ConfigId`); the error names the seven
/// ([`config_message`]).
pub fn parse_config(s: &str) -> Result<ConfigId, String> {
    s.parse::<ConfigId>().map_err(|e| config_message(&e, s))
}

/// The scenario of a `--scenario` option (default: the paper's).
pub fn load_scenario(path: Option<&Path>) -> Result<Scenario, Error> {
    Ok(Scenario::load(path)?)
}

/// The options of `run` and `summary`.
#[derive(clap::Args, Clone)]
pub struct CommonArgs {
    /// Scenario file (TOML); default: the paper's scenario (scenarios/paper.toml).
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// RNG seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Switch the Earth rate off (the paper's assumption in its proofs).
    #[arg(long)]
    pub no_earth_rate: bool,
    /// Cold-start remedy of the (first-pass) filter (for comparisons).
    #[arg(long, value_enum, default_value_t = Remedy::SecondOrder)]
    pub remedy: Remedy,
    /// At most this many passes over the data: 1 = extended filter only; each
    /// further pass is linearised about the previous pass's estimate, until
    /// the estimate moves by less than 0.1σ.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(1..=8))]
    pub passes: u8,
    /// Precision of the filter's covariance arithmetic (state, nominal and
    /// residuals are f64 in both).
    #[arg(long, value_enum, default_value_t = Precision::F64)]
    pub precision: Precision,
    /// Error model of the estimator: `installation` (the paper's states) or
    /// `full` (followed by the instruments' drifts, g-sensitive drifts,
    /// scale factors and biases; docs/model.md §Full model).
    #[arg(long, default_value = "installation", value_parser = parse_errors)]
    pub errors: ErrorModel,
}

/// The value parser of every `--errors`: `installation` or `full` (core's
/// `FromStr for ErrorModel`).
pub fn parse_errors(s: &str) -> Result<ErrorModel, String> {
    s.parse::<ErrorModel>()
        .map_err(|_| format!("unknown error model '{s}': expected installation or full"))
}

impl CommonArgs {
    /// The estimator these options ask for.
    pub fn estimator(&self) -> Estimator {
        Estimator {
            options: self.remedy.options(),
            passes: self.passes,
            precision: self.precision,
        }
    }
}

/// Tells on stderr, for the full model, when the scenario gives no
/// `[instruments.prior]` of its own: the run then takes the default
/// priors (an instrument's before any calibration, docs/model.md
/// §The instrumented scenario).
pub fn note_instrument_prior(scenario: &Scenario, errors: ErrorModel) {
    use crate::sim::scenario::InstrumentPrior;
    if errors == ErrorModel::Full && scenario.instruments.prior == InstrumentPrior::default() {
        eprintln!(
            "instrument priors: the defaults of docs/model.md (1 °/h, 1 °/h/g, 2000 ppm, 1000 µg, 1000 ppm, 100 µg/g²); \
             [instruments.prior] of the scenario sets others"
        );
    }
}

/// Warns on stderr when the full model is asked for its first pass alone
/// (`--passes 1`): from a zero start that pass ends biased by several σ on
/// the instrument terms (docs/model.md §Instrument errors), and the later
/// passes of the estimator of record are what remove it.
pub fn warn_full_first_pass(c: &CommonArgs) {
    if c.errors == ErrorModel::Full && c.passes == 1 {
        eprintln!(
            "warning: the full model's first pass alone is biased from a zero start \
             (several σ on ba, ka, k2: 7-13σ on the instrumented scenario); leave --passes at its default for the estimator of record"
        );
    }
}
