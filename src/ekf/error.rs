//! The filter's errors ([`Error`]): what a step, a construction or a
//! restore refuses, and why.

/// Errors of the estimator. A refusal on the wire carries one
/// (`wire::RefusalReason::Filter`): its postcard index is the variant's
/// declaration index (docs/wire.md §Refused), so variants are only ever
/// appended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// An input (increment, period, measurement, option) is NaN or infinite.
    NonFiniteInput,
    /// The period is not strictly positive.
    InvalidPeriod,
    /// The configuration observes gimbal angles but none were given.
    MissingGimbal,
    /// The Euler-angle attitude reached gimbal lock (`β = ±90°`).
    GimbalLock,
    /// The innovation covariance `S` is not positive definite.
    InnovationNotPositiveDefinite,
    /// The state covariance `P` lost positive definiteness.
    CovarianceNotPositiveDefinite,
    /// The propagated or updated state is not finite.
    NonFiniteState,
    /// The innovation failed the NIS gate; the state was left untouched.
    Gated,
    /// `update` was called without a preceding `predict`.
    NoPrediction,
    /// The environment is not one the filter's arithmetic is bounded for:
    /// an Earth rate above [`MAX_EARTH_RATE`](super::MAX_EARTH_RATE)
    /// (rad/s), or a gravity outside [`GRAVITY_RANGE`](super::GRAVITY_RANGE)
    /// (g); or a noise level whose square is not a normal number of the
    /// filter's precision (it would underflow or overflow in the update);
    /// or a wandering error outside its bounds
    /// ([`Wander::invalid_field`](crate::models::Wander::invalid_field)).
    OutOfRange,
    /// The options ask for a branch this build leaves out: the second-order
    /// dynamics or the iterated update without the cargo feature
    /// `research-options` (a lean firmware image; [`Options::is_built`](super::Options::is_built)).
    UnsupportedOption,
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Error::NonFiniteInput => "input is not finite",
            Error::InvalidPeriod => "period is not strictly positive",
            Error::MissingGimbal => "configuration observes gimbal angles but none were given",
            Error::GimbalLock => "attitude reached gimbal lock (beta = +-90 deg)",
            Error::InnovationNotPositiveDefinite => {
                "innovation covariance is not positive definite"
            }
            Error::CovarianceNotPositiveDefinite => "state covariance is not positive definite",
            Error::NonFiniteState => "state is not finite",
            Error::Gated => "innovation rejected by the NIS gate",
            Error::NoPrediction => "update without a preceding predict",
            Error::OutOfRange => {
                "environment or noise level out of range (Earth rate above 1e-3 rad/s, gravity outside 0.5..2 g, a noise variance not a normal number, or a wandering error outside its bounds)"
            }
            Error::UnsupportedOption => {
                "option not in this build (second-order dynamics or iterated update: cargo feature research-options)"
            }
        })
    }
}

impl core::error::Error for Error {}
