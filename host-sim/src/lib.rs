//! host-sim: the truth simulator, command-line tool and analyses of rollcal.
//!
//! - [`scenario`]: scenario files (TOML), the paper's scenario built in;
//! - [`truth`]: the truth simulator (physical platform, independent of the
//!   estimator's models);
//! - [`runner`]: runs any configuration's estimator over a simulated run;
//! - [`segments`]: path segments recovered from the commanded increments;
//! - [`report`]: tables, JSON and CSV of runs;
//! - [`checks`]: the data judged against the model without a truth (NIS, whiteness, bias);
//! - [`compensation`]: the calibrated matrices and the compensation of the
//!   raw outputs (`--matrices`);
//! - [`observe`]: the observability analysis of every configuration;
//! - [`design`]: designing the rolling path (the shortest path that reaches
//!   target σ_CRLB, or the best within a budget);
//! - [`montecarlo`]: seeded Monte Carlo runs against the Cramér–Rao bound;
//! - [`paper`]: the whole paper regenerated (tables, runs, figures, summary);
//! - [`stream`]: `record` and `calibrate` (wire frames, the calibrator);
//! - [`html`]: the HTML report (`--report DIR`) with its figures;
//! - [`impair`]: lost frames, clock steps, bit flips and outliers injected
//!   into a recorded stream;
//! - [`plots`]: PNG figures (error, ±3σ band, σ_CRLB against time);
//! - [`verdict`]: the verdict words of every table;
//! - [`progress`]: progress on stderr (a bar on a terminal, lines in a log).

/// The command-line subcommands (arguments and drivers). Temporary inline
/// declaration until `cli/mod.rs` exists.
pub mod cli {
    pub mod design;
}
pub mod checks;
pub mod compensation;
pub mod csvlog;
pub mod design;
pub mod impair;
pub mod montecarlo;
pub mod observe;
pub mod output;
pub mod paper;
pub mod runner;
pub mod scenario;
pub mod segments;
pub mod stream;
pub mod truth;
pub mod verdict;

// The output modules at their former paths.
pub use output::{html, plots, progress, report};
