//! The simulated platform: scenario files, the truth simulator, the
//! impairments of a recorded stream and the path segments of a log.
//!
//! - [`scenario`]: scenario and platform files (TOML), the paper's scenario
//!   built in;
//! - [`truth`]: the truth simulator (physical platform, independent of the
//!   estimator's models);
//! - [`instruments`]: the 30 instrument-error states (order, names, units,
//!   true values);
//! - [`wander`]: the truth of the errors that wander (Gauss–Markov parts,
//!   random walks, warm-up);
//! - [`impair`]: lost frames, clock steps, bit flips and outliers injected
//!   into a recorded stream;
//! - [`segments`]: path segments recovered from the commanded increments.

pub mod impair;
pub mod instruments;
pub mod scenario;
pub mod segments;
pub mod truth;
pub mod wander;
