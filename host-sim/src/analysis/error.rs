//! [`Error`]: why an analysis failed. Its `Display` is the one-line
//! message the command line prints.

use std::fmt;

use rollcal::ekf;
use rollcal::estimator::EstimatorError;

use crate::sim::truth::GimbalLockError;

/// Why an analysis of [`crate::analysis`] failed.
#[derive(Debug)]
pub enum Error {
    /// A filter or a bound failed (`CONTEXT: …`, the context naming the
    /// configuration, the seed or the step).
    Filter {
        /// What was computed.
        context: String,
        /// Why it failed.
        source: ekf::Error,
    },
    /// The estimator of record failed (`CONTEXT: …`).
    Estimator {
        /// What was computed.
        context: String,
        /// Why it failed.
        source: EstimatorError,
    },
    /// The path comes too close to gimbal lock for the configuration.
    GimbalLock(GimbalLockError),
    /// A run's final covariance is not positive definite.
    NotPositiveDefinite {
        /// The configuration.
        config: rollcal::models::ConfigId,
    },
    /// A directory could not be created (`cannot create PATH: …`).
    Create {
        /// The directory.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A file could not be written (`cannot write PATH: …`).
    Write {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A document could not be encoded as JSON.
    Json(serde_json::Error),
    /// A figure could not be drawn: the plotter's message.
    Figure(String),
    /// A worker thread of a study panicked.
    Poisoned(String),
}

impl Error {
    /// A filter failure in `context`.
    pub fn filter(context: impl fmt::Display, source: ekf::Error) -> Self {
        Error::Filter {
            context: context.to_string(),
            source,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Filter { context, source } => write!(f, "{context}: {source}"),
            Error::Estimator { context, source } => write!(f, "{context}: {source}"),
            Error::GimbalLock(e) => write!(f, "{e}"),
            Error::NotPositiveDefinite { config } => {
                write!(f, "{config}: final covariance not positive definite")
            }
            Error::Create { path, source } => write!(f, "cannot create {path}: {source}"),
            Error::Write { path, source } => write!(f, "cannot write {path}: {source}"),
            Error::Json(e) => write!(f, "{e}"),
            Error::Figure(m) | Error::Poisoned(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Filter { source, .. } => Some(source),
            Error::GimbalLock(e) => Some(e),
            Error::Create { source, .. } | Error::Write { source, .. } => Some(source),
            Error::Json(e) => Some(e),
            _ => None,
        }
    }
}

impl From<GimbalLockError> for Error {
    fn from(e: GimbalLockError) -> Self {
        Error::GimbalLock(e)
    }
}
