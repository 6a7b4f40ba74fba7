//! host-sim: the truth simulator, command-line tool and analyses of rollcal.
//!
//! - [`scenario`]: scenario files (TOML), the paper's scenario built in;
//! - [`truth`]: the truth simulator (physical platform, independent of the
//!   estimator's models);
//! - [`runner`]: runs any configuration's estimator over a simulated run;
//! - [`report`]: tables, JSON and CSV of runs;
//! - [`stream`]: `record` and `calibrate` (wire frames, the calibrator).

pub mod report;
pub mod runner;
pub mod scenario;
pub mod stream;
pub mod truth;
