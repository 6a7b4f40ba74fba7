//! Which instrument errors a model estimates (docs/model.md §Full model,
//! §Instrument errors): the installation errors alone ([`ErrorModel::Installation`],
//! the paper's models and the default of every configuration) or the
//! installation errors followed by the instruments' own errors
//! ([`ErrorModel::Full`]: gyro drift, g-sensitive drift, torquer scale
//! factor, accelerometer bias and scale factor, 21 more states).

use core::fmt;

/// The error model of a configuration: which states follow the attitude.
///
/// # Examples
///
/// ```
/// use rollcal::models::{ErrorModel, ParseErrorModelError};
/// use rollcal::ConfigId;
///
/// assert_eq!(ErrorModel::default(), ErrorModel::Installation);
/// let full: ErrorModel = "full".parse().unwrap();
/// assert_eq!(full, ErrorModel::Full);
/// assert_eq!(full.as_str(), "full");
/// assert_eq!(full.extra_states(), 36);
/// let err: ParseErrorModelError = "bias".parse::<ErrorModel>().unwrap_err();
/// assert_eq!(err.to_string(), "unknown error model (expected installation or full)");
///
/// // M2-ps: 18 installation states, 54 with the instrument errors.
/// assert_eq!(ConfigId::M2Ps.layout().n(), 18);
/// assert_eq!(ConfigId::M2Ps.layout_with(full).n(), 54);
/// ```
// Serialised as its index (postcard: a varint): `Installation` 0, `Full` 1.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ErrorModel {
    /// The installation errors only (the paper's models): the instruments'
    /// own errors are taken as calibrated and compensated.
    #[default]
    Installation,
    /// The installation errors followed by
    /// `[dg (3), D_g (9), kg (3), ba (3), ka (3), k2 (3)]` and the
    /// Gauss–Markov parts and the warm-up of the drift and the bias
    /// `[δ_g (3), δ_a (3), w_g (3), w_a (3)]` (docs/model.md §Instrument
    /// errors, §Errors that wander).
    Full,
}

impl ErrorModel {
    /// Both, in the order of docs/model.md.
    pub const ALL: [ErrorModel; 2] = [ErrorModel::Installation, ErrorModel::Full];

    /// The stable name: `"installation"` or `"full"`; also its
    /// [`Display`](fmt::Display).
    pub const fn as_str(self) -> &'static str {
        match self {
            ErrorModel::Installation => "installation",
            ErrorModel::Full => "full",
        }
    }

    /// The number of states this error model adds after the installation
    /// states: 0 or 36 (24 instrument terms, then 12 nuisances: the
    /// Gauss–Markov parts and the warm-up of the drift and the bias).
    pub const fn extra_states(self) -> usize {
        match self {
            ErrorModel::Installation => 0,
            ErrorModel::Full => 36,
        }
    }

    /// Whether this build holds the error model (cargo features
    /// `installation-model`, `full-model`).
    pub const fn is_built(self) -> bool {
        match self {
            ErrorModel::Installation => cfg!(feature = "installation-model"),
            ErrorModel::Full => cfg!(feature = "full-model"),
        }
    }

    /// The first error model this build holds (the installation model
    /// when it holds both).
    pub const fn first_built() -> ErrorModel {
        if ErrorModel::Installation.is_built() {
            ErrorModel::Installation
        } else {
            ErrorModel::Full
        }
    }

    /// Parses a name, case-insensitively (`"Full"` = `"full"`).
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|e| e.as_str().eq_ignore_ascii_case(s))
    }
}

impl fmt::Display for ErrorModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The error of parsing an [`ErrorModel`] with [`str::parse`]: the text
/// is neither `installation` nor `full` (case-insensitively). Its
/// [`Display`](fmt::Display) is
/// `unknown error model (expected installation or full)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ParseErrorModelError;

impl fmt::Display for ParseErrorModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("unknown error model (expected installation or full)")
    }
}

impl core::error::Error for ParseErrorModelError {}

impl core::str::FromStr for ErrorModel {
    type Err = ParseErrorModelError;

    /// [`ErrorModel::parse`] with an error type.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::parse(s).ok_or(ParseErrorModelError)
    }
}
