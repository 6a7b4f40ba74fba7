//! What a simulated run gives the estimator: its periods as measurements
//! and log records, the filter settings of a scenario or platform file,
//! and the initial state and prior.

use nalgebra::{RealField, SVector};
use rollcal::ekf::{FilterConfig, Observation, Options};
use rollcal::estimator::LogRecord;
use rollcal::geometry::EARTH_RATE;
use rollcal::models::{Environment, ErrorModel, Layout};

use crate::sim::scenario::{Scenario, ARCSEC, DEG};
use crate::sim::truth::PeriodSample;

/// The measurement of a simulated period in precision `T`.
pub(super) fn observation_t<T: RealField + Copy>(s: &PeriodSample) -> Observation<T> {
    Observation {
        accel_mean: s.accel_mean.map(nalgebra::convert::<f64, T>),
        gimbal: Some(s.gimbal.map(nalgebra::convert::<f64, T>)),
    }
}

/// The measurement of a simulated period (accelerometer mean, gimbal angles).
fn observation(s: &PeriodSample) -> Observation<f64> {
    Observation {
        accel_mean: s.accel_mean,
        gimbal: Some(s.gimbal),
    }
}

/// A simulated period as the library's estimator replays it.
pub fn log_record(s: &PeriodSample) -> LogRecord<f64> {
    LogRecord::measured(s.dt, s.dtheta_cmd, observation(s))
}

/// Filter settings derived from a scenario.
pub fn filter_config(s: &Scenario, earth_rate: bool, options: Options) -> FilterConfig<f64> {
    filter_config_of(&s.site, &s.noise, earth_rate, options)
}

/// [`filter_config`] of a site and noise levels (a scenario's or a
/// platform file's).
pub fn filter_config_of(
    site: &crate::sim::scenario::Site,
    noise: &crate::sim::scenario::Noise,
    earth_rate: bool,
    options: Options,
) -> FilterConfig<f64> {
    let omega = if site.earth_rate && earth_rate {
        EARTH_RATE
    } else {
        0.0
    };
    let lat = site.latitude_deg * DEG;
    FilterConfig {
        env: Environment {
            earth_rate_n: rollcal::geometry::earth_rate_n(omega, lat),
            gravity_n: rollcal::geometry::gravity_n(),
        },
        sigma_accel: noise.accel_g,
        sigma_gyro: noise.gyro_deg_h * DEG / 3600.0,
        sigma_gimbal: noise.gimbal_arcsec * ARCSEC,
        options,
    }
}

/// The initial state `x0` (missing trailing states zero) and the prior σ
/// `sigma0` of every state (internal units; a short slice is extended by
/// its last value) as vectors of `N`.
pub(super) fn initial<const N: usize>(
    x0: &[f64],
    sigma0: &[f64],
) -> (SVector<f64, N>, SVector<f64, N>) {
    let x = SVector::<f64, N>::from_iterator(x0.iter().copied().chain(std::iter::repeat(0.0)));
    let last = sigma0.last().copied().unwrap_or(f64::NAN);
    let s = SVector::<f64, N>::from_iterator(sigma0.iter().copied().chain(std::iter::repeat(last)));
    (x, s)
}

/// The prior σ of every state of `layout` (internal units): `angle_rad`
/// (rad) on the installation states, then, for the full model, the
/// instrument priors `instruments` (rad/s, rad/s/g, 1, g, 1; docs/model.md §Instrument errors): the
/// calibrator's prior ([`rollcal::wire::InstrumentPrior::sigma`]).
pub fn prior_sigma(
    layout: Layout,
    angle_rad: f64,
    instruments: &rollcal::wire::InstrumentPrior,
) -> Vec<f64> {
    let mut s = vec![angle_rad; layout.installation_n()];
    if layout.errors == ErrorModel::Full {
        s.extend(instruments.sigma());
    }
    s
}

/// The prior σ of every state of a calibrator's settings (its
/// configuration and error model): [`prior_sigma`] of the `Configure`.
pub fn prior_sigma_of(settings: &rollcal::wire::CalibratorConfig) -> Vec<f64> {
    prior_sigma(
        settings.config.layout_with(settings.errors),
        settings.prior_sigma_rad,
        &settings.instrument_prior,
    )
}
