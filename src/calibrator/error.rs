//! Errors of building or restoring a calibrator ([`Error`]).

use crate::ekf;
use crate::models::{ConfigId, ErrorModel};
use crate::wire::ConfigField;

/// Errors of building or restoring a calibrator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// The settings or checkpoint name another configuration than the type's.
    ConfigMismatch {
        /// The calibrator type's configuration.
        expected: ConfigId,
        /// The configuration found.
        found: ConfigId,
    },
    /// The settings or checkpoint name another error model than the
    /// type's, or the full model in a build without the `full-model`
    /// feature (whose messages cannot carry its states).
    ErrorModelMismatch {
        /// The calibrator's (or the build's) error model.
        expected: ErrorModel,
        /// The error model found.
        found: ErrorModel,
    },
    /// A checkpoint vector has the wrong length for the configuration.
    CheckpointDimension,
    /// A checkpoint's values are not a filter's: its computed frame `C_cn`
    /// is not a rotation (orthonormal within 1e-4, determinant +1).
    CheckpointInvalid,
    /// The filter refused the settings or the checkpoint's values.
    Filter(ekf::Error),
    /// A data-sheet figure of the settings (a noise level, an instrument
    /// prior σ, a wandering error) is not finite, is negative, or is
    /// outside its bounds ([`ConfigField::bounds`]): the field, named
    /// ([`CalibratorConfig::invalid_field`](crate::wire::CalibratorConfig::invalid_field)).
    InvalidField(ConfigField),
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Error::ConfigMismatch { expected, found } => write!(
                f,
                "configuration {} given to a {} calibrator",
                found.as_str(),
                expected.as_str()
            ),
            Error::ErrorModelMismatch { expected, found } => write!(
                f,
                "error model {} given to a calibrator of the {} model",
                found.as_str(),
                expected.as_str()
            ),
            Error::CheckpointDimension => f.write_str("checkpoint dimensions do not match"),
            Error::CheckpointInvalid => f.write_str(
                "checkpoint is not a filter's (factor not upper triangular or frame not a rotation)",
            ),
            Error::Filter(e) => write!(f, "filter: {e}"),
            Error::InvalidField(field) => write!(
                f,
                "{field} is not finite, negative or outside {}",
                field.bounds()
            ),
        }
    }
}

impl core::error::Error for Error {}

impl Error {
    /// Why a calibrator of `config` with `errors` cannot be built here: the
    /// error model is left out of this build (cargo features), or else
    /// the configuration (or a model larger than the build's,
    /// [`crate::wire::MAX_STATES`]). The one refusal the calibrator and the
    /// session's dispatch both give.
    pub(crate) const fn not_built(config: ConfigId, errors: ErrorModel) -> Self {
        if errors.is_built() {
            Error::ConfigMismatch {
                expected: ConfigId::first_built(),
                found: config,
            }
        } else {
            Error::ErrorModelMismatch {
                expected: ErrorModel::first_built(),
                found: errors,
            }
        }
    }
}

impl From<ekf::Error> for Error {
    fn from(e: ekf::Error) -> Self {
        Error::Filter(e)
    }
}
