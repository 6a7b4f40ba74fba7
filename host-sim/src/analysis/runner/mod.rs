//! Runs a configuration's estimator over a simulated (or replayed) run.
//!
//! The estimator itself (the multi-pass filter) is the library's
//! [`rollcal::estimator::estimate`]; this module only puts a run's samples
//! into a [`rollcal::estimator::SliceLog`], dispatches on the configuration and collects the
//! time history, NIS and failures of the last pass for the reports.
//!
//! - `filter`: the object-safe view of a filter ([`DynFilter`]) and the
//!   [`Precision`] of its covariance arithmetic;
//! - `config`: a simulated period as a measurement and a log record, the
//!   filter settings of a scenario;
//! - `results`: [`StateResult`], [`Update`], [`RunResult`];
//! - `passes`: the estimator of record over a run ([`run_passes`],
//!   [`run_filter`]);
//! - `bound`: the Cramér–Rao bound ([`bound`], [`bound_history`],
//!   [`crlb_sigma`]);
//! - `context`: [`SimulatedRun`], the facts of one simulated run of one
//!   configuration, derived once.

mod bound;
mod config;
mod context;
mod filter;
mod passes;
mod results;

pub use bound::{bound, bound_history, crlb_sigma};
pub use config::{
    filter_config, filter_config_of, log_record, prior_sigma, prior_sigma_of, with_wander,
};
pub use context::SimulatedRun;
pub use filter::{DynFilter, Precision};
pub use passes::{result, run_filter, run_passes, segments_of_samples, Estimator, Passes};
pub use results::{RunResult, StateResult, Update};

pub use crate::analysis::verdict::{expected_observable, verdict, Verdict};
