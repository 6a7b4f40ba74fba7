//! The errors of path design ([`DesignError`]); their `Display` is the
//! one-line message `host-sim design` prints.

use std::fmt;

/// Why a design could not be made or checked.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum DesignError {
    /// A limit or option of the request that cannot be searched (a rate
    /// above 10 °/s, |β| at gimbal lock, a duration or budget of no whole
    /// period or beyond what the tool simulates, no axis): the message,
    /// naming the option.
    Limit(String),
    /// An axis (of `--axes` or of the reference path) that is not
    /// understood: the scenario's message.
    Axis(String),
    /// A target that is malformed or names no state or group: the message.
    Target(String),
    /// No path in the search space reaches every target within this many
    /// seconds.
    NoPathReaches {
        /// The duration limit (s).
        within_s: f64,
    },
    /// Every path in the search space hits the gimbal limit within the
    /// budget.
    GimbalLimitEverywhere,
    /// The designed path does not reach the targets period by period.
    NotReachedFine,
    /// The designed path passes the |β| limit in the truth simulator.
    BetaExceeded {
        /// The largest |β| along the path (°).
        beta_deg: f64,
        /// The limit (°).
        limit_deg: f64,
    },
    /// The observability analysis of the designed path failed: its message.
    Observability(String),
    /// The designed scenario is invalid or cannot be written: the message.
    Scenario(String),
    /// The designed scenario's TOML does not read back identically.
    NotIdentical,
    /// The estimator run of the speed measurement failed: its message.
    Estimator(String),
}

impl fmt::Display for DesignError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Limit(m) | Self::Axis(m) | Self::Target(m) => f.write_str(m),
            Self::NoPathReaches { within_s } => write!(
                f,
                "no path in the search space reaches every target within {within_s} s (raise --max-duration-s or --max-rate-deg-s, or loosen the targets)"
            ),
            Self::GimbalLimitEverywhere => f.write_str(
                "every path in the search space hits the gimbal limit within the budget",
            ),
            Self::NotReachedFine => f.write_str(
                "internal: the designed path does not reach the targets period by period",
            ),
            Self::BetaExceeded {
                beta_deg,
                limit_deg,
            } => write!(
                f,
                "internal: the designed path reaches |β| = {beta_deg:.2}° > {limit_deg:.2}°"
            ),
            Self::Observability(m) => write!(f, "observability of the designed path: {m}"),
            Self::Scenario(m) => write!(f, "designed scenario: {m}"),
            Self::NotIdentical => f.write_str("designed scenario: does not read back identically"),
            Self::Estimator(m) => write!(f, "estimator run: {m}"),
        }
    }
}

impl std::error::Error for DesignError {}

impl From<DesignError> for String {
    fn from(e: DesignError) -> Self {
        e.to_string()
    }
}
