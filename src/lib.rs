//! # rollcal
//!
//! Continuous-rolling self-calibration of the instrument installation errors
//! of a three-axis gimballed inertial platform: while the platform rolls in
//! the 1 g field, an extended Kalman filter estimates the axis rotations
//! (`θgC`, `θaC`) and non-orthogonalities (`θgT`, `θaT`) of the gyros and
//! accelerometers and the base mounting angles `λ` from the accelerometer
//! outputs (and, in M2, the gimbal angles).
//!
//! `#![no_std]`, no heap, no panics on any input; every configuration is a
//! type with its dimensions fixed at compile time. Generic over the scalar
//! (`f64` reference; `f32` for FPUs without double precision).
//!
//! Conventions (docs/model.md §Notation, §Frames): radians inside, specific force in g, navigation
//! frame North–Up–East, `C^b_a` maps frame-a coordinates to frame b, and
//! `R(θ) = exp(−[θ×])`. See [`geometry`] for the frames.
//!
//! Modules, in the order of docs/model.md:
//! - [`geometry`]: rotations, gimbal kinematics (§Notation, §Frames);
//! - [`instruments`]: installation models `G`, `A` (§Installation models);
//! - [`command`]: the computed frame and the commanded rate;
//! - [`models`]: the seven configurations (§Configurations);
//! - [`ekf`]: the filter (docs/model.md §Estimator), with its U-D factored
//!   covariance and the analytic Hessian of the accelerometer model (the
//!   filter's second-order terms) as private modules;
//! - [`estimator`]: the estimator of record, the multi-pass filter over a
//!   whole run kept in a caller-provided [`estimator::SampleLog`];
//! - [`observability`]: information matrix, null space and Cramér–Rao
//!   bound along a path (docs/model.md §Observability);
//! - [`wire`]: the serial protocol (docs/wire.md): messages, frames, decoder;
//! - [`calibrator`]: the front end that validates samples, bridges lost data
//!   along the commanded motion (or re-acquires the attitude), runs pass 1,
//!   logs the run, answers `Finish` with the estimator of record, emits
//!   estimates and checkpoints.
//!
//! - [`session`]: the protocol once: message → effect and reply, driven by
//!   the firmware and by `host-sim calibrate`.
//!
//! [`with_config!`] is the one `ConfigId` → configuration-type dispatch.
#![no_std]
#![deny(missing_docs, unsafe_code)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing
    )
)]

pub mod calibrator;
pub mod command;
#[cfg(feature = "flash-log")]
pub mod device;
pub mod ekf;
pub mod estimator;
pub mod geometry;
pub mod instruments;
pub mod models;
pub mod observability;
mod precision;
pub mod session;
mod trig;
pub mod wire;

/// The README's Rust examples, compiled and run as doc-tests
/// (`cargo test --doc`); not part of the API.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

/// docs/wire.md's Rust example, compiled and run as a doc-test; not part
/// of the API.
#[cfg(doctest)]
#[doc = include_str!("../docs/wire.md")]
pub struct WireDoctests;

pub use calibrator::{Calibrator, M1PaCalibrator, M2PsCalibrator, M4PaCalibrator, RejectReason};
pub use ekf::{Error, Filter, FilterConfig, Innovation, Observation, Options};
pub use estimator::{EstimatorOptions, LogRecord, SampleLog, SliceLog};
pub use models::{ConfigId, Environment, Group, Layout, Model, ParseConfigIdError, StateInfo};
pub use wire::{CalibratorConfig, Checkpoint, Decoder, Estimate, FrameDecoder, Message, Sample};
