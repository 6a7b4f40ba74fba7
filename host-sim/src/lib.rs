//! host-sim: the truth simulator, command-line tool and analyses of rollcal.
//!
//! The crate is laid out by role:
//!
//! - [`cli`]: the command line (one file per subcommand: its arguments and
//!   its driver); with the table and report writers, the only code that
//!   prints;
//! - [`sim`]: the simulated platform — scenario files, the truth simulator,
//!   impairments of a recorded stream, path segments;
//! - [`analysis`]: what is computed of a run — the estimator runner, the
//!   observability study, Monte Carlo, the data checks, the compensation,
//!   the statistics, the verdicts, the paper;
//! - [`io`]: streams of wire frames, the CSV log, the truth sidecar;
//! - [`design`]: designing the rolling path (the shortest path that reaches
//!   target σ_CRLB, or the best within a budget);
//! - [`output`]: tables, JSON and CSV of runs, the HTML report, PNG
//!   figures, progress on stderr.

pub mod analysis;
pub mod cli;
pub mod design;
pub mod io;
pub mod output;
pub mod sim;
