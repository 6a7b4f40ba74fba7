//! The calibrator run on a stream, as `calibrate` drives it:
//!
//! - `host`: the no_std session ([`rollcal::session::Session`]) with the
//!   host's sample log, the NIS and failures of every accepted sample, the
//!   estimator of record's final passes with their covariance;
//! - `answer`: what the session answered after the stream, as a
//!   [`Calibration`] (everything the outputs need, computed once);
//! - `bound`: the bound at the estimate without a truth;
//! - [`rejects`]: why samples were rejected, and the likely cause;
//! - [`trust`]: when the result is an answer, and the gated updates;
//! - [`diagnose`]: the likely cause of a data warning;
//! - [`left_out`]: the terms the platform file leaves out, tested;
//! - here: the calibrator settings of a scenario or platform file.

mod answer;
mod bound;
pub mod diagnose;
mod host;
pub mod left_out;
pub mod rejects;
pub mod trust;

use rollcal::ekf::Options;
use rollcal::estimator::LogRecord;
use rollcal::models::{ConfigId, ErrorModel};
use rollcal::wire::CalibratorConfig;

use crate::analysis::checks::{self, Judgement, Wald};
use crate::analysis::runner::{self, RunResult};
use crate::sim::scenario::{Platform, Scenario, DEG};

pub use answer::{Calibration, CalibrationError, Context};
pub use bound::{bound_at_estimate, state_at_start, truth_at_start, CalibratorView};
pub use host::{name_of, Final, Host, HostError, LogStorage, Refused, VecLog};

/// Calibrator settings equal to `runner::filter_config` of the scenario
/// (so that the stream's filter is `run`'s filter), for error model
/// `errors` with the scenario's instrument prior.
pub fn calibrator_config(
    sc: &Scenario,
    id: ConfigId,
    errors: ErrorModel,
    earth_rate: bool,
) -> CalibratorConfig {
    platform_config(&Platform::of_scenario(sc), id, errors, earth_rate)
}

/// Calibrator settings of a platform file (the `Configure` message a
/// platform with these settings would send), for error model `errors`,
/// with the platform's instrument prior and errors that wander whichever
/// the model (the installation model does not use them).
pub fn platform_config(
    p: &Platform,
    id: ConfigId,
    errors: ErrorModel,
    earth_rate: bool,
) -> CalibratorConfig {
    let f = runner::filter_config_of(&p.site, &p.noise, earth_rate, Options::default());
    let mut c = CalibratorConfig::paper(id);
    c.sigma_accel_g = f.sigma_accel;
    c.sigma_gyro_rad_s = f.sigma_gyro;
    c.sigma_gimbal_rad = f.sigma_gimbal;
    c.earth_rate_n = f.env.earth_rate_n.into();
    c.gravity_n = f.env.gravity_n.into();
    c.prior_sigma_rad = p.prior.sigma_deg * DEG;
    c.limits.period_s = p.timing.period_s;
    c.errors = errors;
    c.instrument_prior = p.instruments.prior.to_wire();
    // The platform's figures travel whatever the model: the installation
    // model ignores them, as it ignores the instrument prior, and a
    // stream `calibrate --errors full` reads keeps them.
    c.wander = p.instruments.wander.to_model();
    c
}

/// The data of a calibration judged against the model as `calibrate`
/// judges them: the checks of the last pass's innovations (`r`), the test
/// of every term the platform file leaves out ([`left_out::test`], one
/// more run of the estimator over `records` when there is one), the path's
/// distance from gimbal lock, and a warning's likely cause
/// ([`diagnose::likely_cause`]; `latitude_deg`: the platform's).
pub fn judge(
    settings: &CalibratorConfig,
    r: &RunResult,
    records: &[LogRecord<f64>],
    latitude_deg: Option<f64>,
) -> Judgement {
    let left = left_out::test(settings, records);
    let walds: Vec<Wald> = left
        .iter()
        .flat_map(|l| l.findings.iter().map(|f| f.wald.clone()))
        .collect();
    let mut j = checks::judge_with(r, &walds)
        .with_path(checks::gimbal_lock_check(settings.config, records));
    if j.verdict.is_warning() {
        j.cause = diagnose::likely_cause(
            settings,
            records,
            &r.updates,
            &j,
            latitude_deg,
            left.as_ref(),
        );
    }
    j
}
