//! Inputs and outputs of recorded runs: streams of wire frames, the CSV log
//! and the truth sidecar.
//!
//! - [`stream`]: a scenario as wire frames, the calibrator's host session,
//!   reading a file, stdin or a serial port;
//! - [`csvlog`]: the CSV log (docs/csv.md);
//! - [`input`]: what `calibrate` reads and with which settings;
//! - [`replies`]: where `calibrate --replies` sends the calibrator's replies;
//! - [`Error`]: why an input or output failed;
//! - [`sidecar`]: the truth sidecar of a recorded stream.

pub mod csvlog;
mod error;
pub mod input;
pub mod replies;
pub mod sidecar;
pub mod stream;

pub use error::Error;
