//! What is computed of a run: the estimator runner, the observability
//! study, Monte Carlo, the data checks, the compensation, the statistics
//! and the verdicts.
//!
//! - [`runner`]: runs any configuration's estimator over a simulated run;
//! - [`observe`]: the observability analysis of every configuration;
//! - [`montecarlo`]: seeded Monte Carlo runs against the Cramér–Rao bound;
//! - [`calibration`]: the calibrator run on a stream (`calibrate`'s session);
//! - [`checks`]: the data judged against the model without a truth (NIS,
//!   whiteness, bias);
//! - [`check_rates`]: the cases of `host-sim checks` (a defect of the
//!   stream, a term the model leaves out) and their rates over seeds;
//! - [`compensation`]: the calibrated matrices and the compensation of the
//!   raw outputs (`--matrices`);
//! - [`statistics`]: the normal and χ² quantiles;
//! - [`verdict`]: the verdict words of every table;
//! - [`Error`]: why an analysis failed;
//! - [`paper`]: the whole paper regenerated (tables, runs, figures, summary);
//! - [`remedies`]: the cold-start remedies and their study.

pub mod calibration;
pub mod check_rates;
pub mod checks;
pub mod compensation;
mod error;
pub mod floor;
pub mod montecarlo;
pub mod observe;
pub mod paper;
pub mod remedies;
pub mod runner;
pub mod statistics;
pub mod verdict;

pub use error::Error;
