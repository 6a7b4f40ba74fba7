//! The filter's settings: the cold-start remedies and the NIS gate
//! ([`Options`], docs/model.md §Estimator), and the noise levels and
//! environment of a filter ([`FilterConfig`]).

use nalgebra::RealField;

use crate::models::{Environment, Wander};

#[cfg(doc)]
use super::Error;

/// Cold-start remedies and gating.
///
/// # Examples
///
/// ```
/// use rollcal::ekf::{Options, DEFAULT_NIS_GATE};
///
/// // The default: the second-order covariance (the cold-start remedy) and
/// // the NIS gate.
/// let o = Options::default();
/// assert!(o.second_order_covariance && !o.second_order_mean);
/// assert_eq!(o.nis_gate, DEFAULT_NIS_GATE);
/// assert!(o.is_built());
/// // A plain EKF, without remedy or gate.
/// let plain = Options::plain();
/// assert!(!plain.second_order_covariance && plain.nis_gate == 0.0);
/// // Research options, e.g. two iterations of the first 100 updates.
/// let iterated = Options { iterations: 2, iterate_updates: 100, ..o };
/// assert_eq!(iterated.is_built(), rollcal::ekf::RESEARCH_OPTIONS);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Options {
    /// Add the second-order terms of the accelerometer measurement to the
    /// innovation covariance (the chosen cold-start remedy).
    pub second_order_covariance: bool,
    /// Add the second-order mean `½ tr(∇²h_a P)` to the predicted measurement.
    pub second_order_mean: bool,
    /// Add the second-order terms of the attitude dynamics to the process noise.
    pub second_order_dynamics: bool,
    /// Iterated-EKF relinearisations per update (0 = plain EKF).
    pub iterations: u8,
    /// Iterate only the first this many updates.
    pub iterate_updates: u32,
    /// Reject an update whose NIS exceeds this value (0 = no gate): the
    /// period is then predicted only. The default, [`DEFAULT_NIS_GATE`],
    /// refuses fewer than 1e-4 of clean updates of any configuration.
    pub nis_gate: f64,
}

/// After this many consecutive gated updates the next one is accepted
/// whatever its NIS. Outliers come alone, while a run of large innovations
/// means the estimate itself is off (pass 1 from a cold start can be
/// overconfident where the path turns onto a new axis, with NIS in the
/// hundreds for tens of periods): gating them all would lock the filter out
/// of its own correction. Once an update above the gate has been accepted,
/// the gate stays open until an update falls below it again, so such a
/// stretch costs at most this many samples.
pub const MAX_GATED_RUN: u32 = 2;

/// The default NIS gate: 30. A clean update's NIS is χ² with `Z` degrees of
/// freedom (3 or 6), which exceeds 30 with probability 1.4e-6 (Z = 3) or
/// 3.9e-5 (Z = 6); a 100σ accelerometer outlier has a NIS near 1e4.
pub const DEFAULT_NIS_GATE: f64 = 30.0;

impl Default for Options {
    fn default() -> Self {
        Self {
            second_order_covariance: true,
            second_order_mean: false,
            second_order_dynamics: false,
            iterations: 0,
            iterate_updates: 0,
            nis_gate: DEFAULT_NIS_GATE,
        }
    }
}

/// Whether this build holds the research options (the cargo feature
/// `research-options`, on by default): the second-order dynamics and the
/// iterated update. Without it their code is left out of the image and a
/// filter that asks for them is refused ([`Error::UnsupportedOption`]).
pub const RESEARCH_OPTIONS: bool = cfg!(feature = "research-options");

impl Options {
    /// Whether this build can run these options ([`RESEARCH_OPTIONS`]):
    /// the defaults, the plain EKF and the second-order mean always; the
    /// second-order dynamics and the iterated update only with the cargo
    /// feature `research-options`.
    pub const fn is_built(&self) -> bool {
        RESEARCH_OPTIONS
            || !(self.second_order_dynamics || (self.iterations > 0 && self.iterate_updates > 0))
    }

    /// A plain EKF (no cold-start remedy), for comparison.
    pub const fn plain() -> Self {
        Self {
            second_order_covariance: false,
            second_order_mean: false,
            second_order_dynamics: false,
            iterations: 0,
            iterate_updates: 0,
            nis_gate: 0.0,
        }
    }
}

/// Noise levels and environment of a filter.
///
/// # Examples
///
/// ```
/// # use nalgebra::{SVector, Vector3};
/// # use rollcal::ekf::{FilterConfig, M1PaFilter, Observation, Options};
/// # use rollcal::geometry::{earth_rate_n, gravity_n, EARTH_RATE};
/// # use rollcal::models::Environment;
/// # let deg = core::f64::consts::PI / 180.0;
/// # let w_ie = earth_rate_n(EARTH_RATE, 34.25 * deg);
/// # let config = FilterConfig::<f64> {
/// #     env: Environment { earth_rate_n: w_ie, gravity_n: gravity_n() },
/// #     sigma_accel: 1e-6,
/// #     sigma_gyro: 0.1 * deg / 3600.0,
/// #     sigma_gimbal: 10.0 * deg / 3600.0,
/// #     options: Options::default(),
/// #     wander: rollcal::models::Wander::none(),
/// # };
/// # let mut f = M1PaFilter::<f64>::new(config, SVector::zeros(), SVector::repeat(deg))?;
/// # // Holding still with the computed frame on n: the commanded increment is
/// # // the Earth rate over the period, the accelerometers read gravity (g).
/// # let (dtheta_c, dt) = (w_ie * 1.0, 1.0);
/// # let obs = Observation { accel_mean: gravity_n::<f64>(), gimbal: None };
/// // The settings in f64, then for a single-precision filter (the covariance
/// // arithmetic in f32; state and nominal stay f64).
/// let f32_config: FilterConfig<f32> = config.to_precision();
/// assert_eq!(f32_config.sigma_accel, 1e-6_f32);
/// assert_eq!(f32_config.env, config.env);
/// let mut g = M1PaFilter::<f32>::new(f32_config, SVector::zeros(), SVector::repeat(deg as f32))?;
/// let obs32 = Observation { accel_mean: gravity_n::<f32>(), gimbal: None };
/// g.step(&dtheta_c, dt, &obs32)?;
/// f.step(&dtheta_c, dt, &obs)?;
/// assert!((g.state() - f.state()).amax() < 1e-6);
/// # Ok::<(), rollcal::Error>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterConfig<T: RealField + Copy> {
    /// Earth rate and gravity, in double precision whatever `T` (they drive
    /// the nominal trajectory, see [`Filter`](super::Filter)).
    pub env: Environment<f64>,
    /// Accelerometer noise of the period mean, 1σ per axis (g).
    pub sigma_accel: T,
    /// Gyro white rate noise, constant over a period, 1σ per axis (rad/s).
    pub sigma_gyro: T,
    /// Gimbal-angle noise, 1σ per angle (rad).
    pub sigma_gimbal: T,
    /// Cold-start remedy and gate.
    pub options: Options,
    /// The instruments' errors that wander (docs/model.md §Errors that
    /// wander): process noise on the full model's drift and bias and the
    /// decay of their Gauss–Markov parts. [`Wander::none`] for constant
    /// errors; a model without those states
    /// ([`ErrorModel::Installation`](crate::models::ErrorModel::Installation))
    /// refuses any other ([`Error::OutOfRange`](super::Error::OutOfRange)),
    /// as every model refuses figures outside their bounds
    /// ([`Wander::invalid_field`]; `NonFiniteInput` for NaN or infinite).
    pub wander: Wander<T>,
}

impl FilterConfig<f64> {
    /// The same settings for a filter of precision `T`: the noise levels
    /// in `T`, the environment (always f64) and the options as they are.
    pub fn to_precision<T: RealField + Copy>(&self) -> FilterConfig<T> {
        FilterConfig {
            env: self.env,
            sigma_accel: nalgebra::convert(self.sigma_accel),
            sigma_gyro: nalgebra::convert(self.sigma_gyro),
            sigma_gimbal: nalgebra::convert(self.sigma_gimbal),
            options: self.options,
            wander: self.wander.to_precision(),
        }
    }
}

/// The largest Earth rate `|ω^n_ie|` a filter accepts (rad/s): 1e-3, about
/// 14 times the Earth's (7.292e-5). Beyond it [`Filter::new`](super::Filter::new)
/// refuses the configuration ([`Error::OutOfRange`](super::Error::OutOfRange)).
pub const MAX_EARTH_RATE: f64 = 1e-3;

/// The range of `|g^n|` a filter accepts (g): 0.5 to 2.
pub const GRAVITY_RANGE: (f64, f64) = (0.5, 2.0);
