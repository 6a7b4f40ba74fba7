//! The errors that wander (docs/model.md §Errors that wander): the
//! instruments' stochastic drift and bias, as the full model carries them
//! ([`Wander`]), and what one period of them does to the state
//! ([`WanderStep`]).
//!
//! Per axis and independent, in internal units (the data sheet's figures
//! converted as docs/model.md §Errors that wander shows):
//! - **bias instability**, a first-order Gauss–Markov process
//!   `δ' = −δ/τ + w` of stationary σ: the states `δ_g` (`dg_gm_*`) and
//!   `δ_a` (`ba_gm_*`), which add to the drift `dg` and the bias `ba`;
//! - **random walk of the bias**, `r' = w`, whose variance grows by `K² t`:
//!   process noise on the states `dg` and `ba` themselves, so that their
//!   estimate at the end of a log is the value to compensate from then on
//!   (`dg + r_g(t_end)`, `ba + r_a(t_end)`);
//! - **warm-up**, `Δ e^(−t/τ_w)` from the start of the log, `Δ` unknown of
//!   σ given: the states `w_g` (`dg_wu_*`) and `w_a` (`ba_wu_*`), which
//!   decay by `e^(−T/τ_w)` a period with no process noise.
//!
//! The filter holds the wandering parts constant over a period and moves
//! them at its end (after the period's measurement update and attitude time
//! update): for a period of length `T` the Gauss–Markov states are
//! multiplied by `φ = exp(−T/τ)` and gain the variance `σ² (1 − φ²)`, the
//! random walks gain `K² T`, the warm-up states are multiplied by
//! `exp(−T/τ_w)`. Over a 1 s period and τ of minutes the
//! difference from the continuous processes is of order `T/τ` of one
//! period's increment, far below the measurement noise.

use nalgebra::RealField;

/// The wandering errors of the full model, per axis (the same for the three
/// gyros and for the three accelerometers), in internal units. All zero
/// ([`Wander::none`]): the errors are constants (the model of
/// docs/model.md §Instrument errors). A zero σ or `K` leaves that part out.
///
/// # Examples
///
/// The realistic scenario's figures (docs/model.md §The realistic
/// scenario) in internal units, and one period of them:
///
/// ```
/// use rollcal::models::Wander;
///
/// let deg_h = 1f64.to_radians() / 3600.0; // 1 °/h in rad/s
/// let w = Wander {
///     gyro_markov_sigma: 0.003 * deg_h,
///     gyro_markov_tau_s: 600.0,
///     gyro_random_walk: 0.002 * deg_h / 60.0, // 0.002 °/h/√h in rad/s/√s
///     accel_markov_sigma: 2e-6,               // 2 µg
///     accel_markov_tau_s: 900.0,
///     accel_random_walk: 1e-6 / 60.0, // 1 µg/√h in g/√s
///     gyro_warmup_sigma: 0.006 * deg_h,
///     accel_warmup_sigma: 4e-6,
///     warmup_tau_s: 1200.0,
/// };
/// assert!(w.is_valid() && !w.is_none());
/// let step = w.step(1.0);
/// assert!((step.accel_phi - (-1.0f64 / 900.0).exp()).abs() < 1e-15);
/// // The stationary variance is kept: σ² φ² + q = σ².
/// let s2 = w.accel_markov_sigma * w.accel_markov_sigma;
/// assert!((s2 * step.accel_phi * step.accel_phi + step.accel_markov_q - s2).abs() < 1e-25);
/// // The random walk's variance grows by K² T.
/// assert_eq!(step.accel_walk_q, w.accel_random_walk * w.accel_random_walk);
/// // The warm-up decays by e^(−T/τ_w), with no noise.
/// assert!((step.warmup_phi - (-1.0f64 / 1200.0).exp()).abs() < 1e-15);
/// assert!(Wander::<f64>::none().is_none());
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Wander<T> {
    /// Gyro bias instability: the stationary σ of the Gauss–Markov part
    /// of each gyro's drift (rad/s); 0: not modelled.
    pub gyro_markov_sigma: T,
    /// Its correlation time τ_g (s); read only when the σ is not zero.
    pub gyro_markov_tau_s: T,
    /// Gyro rate random walk `K_g` (rad/s per √s): each drift's variance
    /// grows by `K_g² t`; 0: the drift is a constant.
    pub gyro_random_walk: T,
    /// Accelerometer bias instability: the stationary σ of the
    /// Gauss–Markov part of each bias (g); 0: not modelled.
    pub accel_markov_sigma: T,
    /// Its correlation time τ_a (s); read only when the σ is not zero.
    pub accel_markov_tau_s: T,
    /// Accelerometer acceleration random walk `K_a` (g per √s): each
    /// bias's variance grows by `K_a² t`; 0: the bias is a constant.
    pub accel_random_walk: T,
    /// Warm-up of each gyro's drift: the σ of its amplitude `Δ_g` (rad/s)
    /// at the start of the log; 0: no warm-up.
    pub gyro_warmup_sigma: T,
    /// Warm-up of each accelerometer's bias: the σ of its amplitude `Δ_a`
    /// (g); 0: no warm-up.
    pub accel_warmup_sigma: T,
    /// The warm-up's time constant τ_w (s); read only when a warm-up σ is
    /// not zero.
    pub warmup_tau_s: T,
}

/// What one period of length `T` does to the wandering states (see
/// [`Wander`]): the Gauss–Markov states are multiplied by `φ` and
/// gain the variance `q`, the random walks gain their `q`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WanderStep<T> {
    /// `exp(−T/τ_g)` (1 when the gyro's instability is not modelled).
    pub gyro_phi: T,
    /// `σ_g² (1 − φ_g²)` ((rad/s)²).
    pub gyro_markov_q: T,
    /// `K_g² T` ((rad/s)²).
    pub gyro_walk_q: T,
    /// `exp(−T/τ_a)` (1 when the accelerometer's instability is not
    /// modelled).
    pub accel_phi: T,
    /// `σ_a² (1 − φ_a²)` (g²).
    pub accel_markov_q: T,
    /// `K_a² T` (g²).
    pub accel_walk_q: T,
    /// `exp(−T/τ_w)` (1 without a warm-up).
    pub warmup_phi: T,
}

/// The largest `T/τ` a period's Gauss–Markov decay is computed for: beyond
/// it the process has forgotten its value (`exp(−20)` = 2e-9) and `φ` is
/// held at `exp(−20)`, so that the filter's factor never divides by an
/// underflowing `φ` (a gap bridged in one long period).
pub const MAX_DECAY_EXPONENT: f64 = 20.0;

impl<T: RealField + Copy> Wander<T> {
    /// No wandering errors: the drift and the bias are constants.
    pub fn none() -> Self {
        Self {
            gyro_markov_sigma: T::zero(),
            gyro_markov_tau_s: T::zero(),
            gyro_random_walk: T::zero(),
            accel_markov_sigma: T::zero(),
            accel_markov_tau_s: T::zero(),
            accel_random_walk: T::zero(),
            gyro_warmup_sigma: T::zero(),
            accel_warmup_sigma: T::zero(),
            warmup_tau_s: T::zero(),
        }
    }

    /// Whether every σ and `K` is zero.
    pub fn is_none(&self) -> bool {
        [
            self.gyro_markov_sigma,
            self.gyro_random_walk,
            self.accel_markov_sigma,
            self.accel_random_walk,
            self.gyro_warmup_sigma,
            self.accel_warmup_sigma,
        ]
        .iter()
        .all(|v| *v == T::zero())
    }

    /// Whether there is a warm-up (a σ of its amplitude not zero).
    pub fn has_warmup(&self) -> bool {
        self.gyro_warmup_sigma != T::zero() || self.accel_warmup_sigma != T::zero()
    }

    /// The nine figures in declaration order.
    pub(crate) fn figures(&self) -> [T; 9] {
        [
            self.gyro_markov_sigma,
            self.gyro_markov_tau_s,
            self.gyro_random_walk,
            self.accel_markov_sigma,
            self.accel_markov_tau_s,
            self.accel_random_walk,
            self.gyro_warmup_sigma,
            self.accel_warmup_sigma,
            self.warmup_tau_s,
        ]
    }

    /// Every figure finite, not negative and within its bounds
    /// ([`crate::wire::ConfigField::bounds`]), and each correlation or
    /// warm-up time within its bounds where its σ is not zero: no
    /// [`Wander::invalid_field`].
    pub fn is_valid(&self) -> bool {
        self.invalid_field().is_none()
    }

    /// One period of length `dt` (s) of the wandering errors.
    pub fn step(&self, dt: f64) -> WanderStep<T> {
        let dt_t: T = nalgebra::convert(dt);
        let markov = |sigma: T, tau: T| -> (T, T) {
            if sigma == T::zero() || tau <= T::zero() || !tau.is_finite() {
                return (T::one(), T::zero());
            }
            let limit: T = nalgebra::convert(MAX_DECAY_EXPONENT);
            let phi = (-(dt_t / tau).min(limit)).exp();
            (phi, sigma * sigma * (T::one() - phi * phi))
        };
        let (gyro_phi, gyro_markov_q) = markov(self.gyro_markov_sigma, self.gyro_markov_tau_s);
        let (accel_phi, accel_markov_q) = markov(self.accel_markov_sigma, self.accel_markov_tau_s);
        // The warm-up: the decay of a Gauss–Markov process without noise.
        let (warmup_phi, _) = if self.has_warmup() {
            markov(T::one(), self.warmup_tau_s)
        } else {
            (T::one(), T::zero())
        };
        WanderStep {
            gyro_phi,
            gyro_markov_q,
            gyro_walk_q: self.gyro_random_walk * self.gyro_random_walk * dt_t,
            accel_phi,
            accel_markov_q,
            accel_walk_q: self.accel_random_walk * self.accel_random_walk * dt_t,
            warmup_phi,
        }
    }
}

impl Wander<f64> {
    /// The same figures in precision `U`, each rounded once.
    pub fn to_precision<U: RealField + Copy>(&self) -> Wander<U> {
        let c = nalgebra::convert::<f64, U>;
        Wander {
            gyro_markov_sigma: c(self.gyro_markov_sigma),
            gyro_markov_tau_s: c(self.gyro_markov_tau_s),
            gyro_random_walk: c(self.gyro_random_walk),
            accel_markov_sigma: c(self.accel_markov_sigma),
            accel_markov_tau_s: c(self.accel_markov_tau_s),
            accel_random_walk: c(self.accel_random_walk),
            gyro_warmup_sigma: c(self.gyro_warmup_sigma),
            accel_warmup_sigma: c(self.accel_warmup_sigma),
            warmup_tau_s: c(self.warmup_tau_s),
        }
    }
}
