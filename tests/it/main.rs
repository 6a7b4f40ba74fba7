//! The library's integration tests, one test binary with one module per
//! subject (one binary links once: a fresh clone compiles and links it in
//! a fraction of the time one binary per file takes). The library alone,
//! no host-sim: data come from `tests/data/` through the library's own
//! decoder (`support`).
//!
//! Run one subject with a filter on the module path, e.g.
//! `cargo test --release -p rollcal --test it wire::`.

mod support;

mod calibrator;
mod configs;
mod device;
mod estimator;
mod f32;
mod filter_api;
mod flash_log;
mod full_model;
mod fuzz_seeds;
mod geometry;
mod jacobians;
mod observability;
mod shared_evaluations;
mod wire;
mod wire_doc;
