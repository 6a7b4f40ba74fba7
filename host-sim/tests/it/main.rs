//! host-sim's integration tests, one test binary with one module per
//! subject (one binary links once: a fresh clone compiles and links it in
//! a fraction of the time one binary per file takes). Most drive the
//! `host-sim` binary (`CARGO_BIN_EXE_host-sim`, `support::host_sim`).
//!
//! Run one subject with a filter on the module path, e.g.
//! `cargo test --release -p host-sim --test it checks::`.

mod support;

mod calibrate_full;
mod checks;
mod cli;
mod cli_defects;
mod cli_paper;
mod compensation;
mod compensation_full;
mod consistency;
mod convergence;
mod csv_log;
mod design;
mod design_answer;
mod dwell;
mod f32;
mod firmware_check;
mod full_model;
mod golden;
mod ground_station;
mod innovations;
mod instruments;
mod left_out;
mod mid_path;
mod mistakes;
mod observability;
mod packed_log;
mod plots;
mod report;
mod robustness;
mod serial;
mod tables;
mod wander;
