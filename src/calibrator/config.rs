//! The filter's settings from the calibrator's ([`FilterConfig`] from
//! [`CalibratorConfig`]) and the prior every start is made from.

use nalgebra::{RealField, SVector, Vector3};

use super::{to_t, Calibrator, Error};
use crate::ekf::FilterConfig;
use crate::models::{ConfigId, Environment, ErrorModel, Model};
use crate::wire::{CalibratorConfig, MAX_STATES};

/// The filter settings of a calibrator's settings: the environment as it
/// is (f64), the noise levels and the wandering errors in the filter's
/// scalar `T` (the latter for the full model only), the options as they
/// are. What every calibrator runs its filter with.
///
/// # Examples
///
/// ```
/// use rollcal::ekf::FilterConfig;
/// use rollcal::models::ConfigId;
/// use rollcal::wire::CalibratorConfig;
///
/// let settings = CalibratorConfig::paper(ConfigId::M1Pa);
/// let f64_filter = FilterConfig::<f64>::from(&settings);
/// assert_eq!(f64_filter.sigma_accel, 1e-6);
/// assert_eq!(f64_filter.env.gravity_n.y, 1.0);
/// // For an FPU without double precision: the noise levels in f32.
/// let f32_filter = FilterConfig::<f32>::from(&settings);
/// assert_eq!(f32_filter.sigma_accel, 1e-6_f32);
/// ```
impl<T: RealField + Copy> From<&CalibratorConfig> for FilterConfig<T> {
    fn from(s: &CalibratorConfig) -> Self {
        FilterConfig {
            env: Environment {
                earth_rate_n: Vector3::from(s.earth_rate_n),
                gravity_n: Vector3::from(s.gravity_n),
            },
            sigma_accel: to_t(s.sigma_accel_g),
            sigma_gyro: to_t(s.sigma_gyro_rad_s),
            sigma_gimbal: to_t(s.sigma_gimbal_rad),
            options: s.options,
            wander: match s.errors {
                ErrorModel::Installation => crate::models::Wander::none(),
                ErrorModel::Full => s.wander.to_precision(),
            },
        }
    }
}

impl<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>
    Calibrator<T, M, N, Z>
{
    /// `Ok` when `found` and `errors` are this calibrator type's
    /// configuration and error model, and its states fit the messages
    /// ([`MAX_STATES`]: sized for the models the build holds; a larger one
    /// is refused as the session refuses a model the build leaves out).
    pub(super) fn check_config(found: ConfigId, errors: ErrorModel) -> Result<(), Error> {
        if found != M::ID {
            return Err(Error::ConfigMismatch {
                expected: M::ID,
                found,
            });
        }
        if N > MAX_STATES {
            // A model larger than the build's: refused as the session
            // refuses one the build leaves out.
            return Err(Error::not_built(M::ID, M::ERRORS));
        }
        if errors != M::ERRORS {
            return Err(Error::ErrorModelMismatch {
                expected: M::ERRORS,
                found: errors,
            });
        }
        Ok(())
    }

    /// The filter's start of `s`: its settings, the zero estimate and the
    /// prior σ of every state (`prior_sigma_rad` on the installation
    /// states, `instrument_prior` on the instrument errors of the full
    /// model and the stationary σ of `wander` on their Gauss–Markov parts):
    /// what a new calibrator, a reset and every pass of the
    /// estimator of record start from.
    pub(super) fn prior(s: &CalibratorConfig) -> (FilterConfig<T>, SVector<f64, N>, SVector<T, N>) {
        let installation = M::LAYOUT.installation_n();
        let instruments = s.instrument_prior.sigma(&s.wander);
        let sigma0 = SVector::from_fn(|i, _| {
            let sigma = match i.checked_sub(installation) {
                None => s.prior_sigma_rad,
                Some(k) => instruments.get(k).copied().unwrap_or(s.prior_sigma_rad),
            };
            to_t(sigma)
        });
        (FilterConfig::from(s), SVector::zeros(), sigma0)
    }
}
