//! Making a filter: [`Filter::new`] from the configuration and the prior,
//! and [`Filter::restart`] in place, with the checks of their inputs.

use core::marker::PhantomData;

use nalgebra::{RealField, SVector};

use super::cache::MatricesCache;
use super::factor::Ud;
use super::options::{GRAVITY_RANGE, MAX_EARTH_RATE};
use super::pending::PendingSlot;
use super::scratch::Scratch;
use super::{all_finite, env_t, Error, Filter, FilterConfig};
use crate::command::CommandFrame;
use crate::models::Model;

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// A filter with initial estimate `x0` (rad; the full model's
    /// instrument terms in their internal units) and prior standard
    /// deviations `sigma0` (the same units), the computed frame aligned
    /// with n. An instrument state's σ may be zero: the model does not
    /// estimate it (its variance stays zero and its estimate `x0`).
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
    /// // An M1-pa filter from its configuration and prior: zero initial estimate,
    /// // 1° on each of its 12 states.
    /// let f = M1PaFilter::<f64>::new(config, SVector::zeros(), SVector::repeat(deg))?;
    /// assert_eq!(f.state().len(), 12);
    /// assert_eq!(f.sigma(), SVector::<f64, 12>::repeat(deg));
    /// assert_eq!(f.updates(), 0);
    /// // A prior σ that is not strictly positive is refused (only the full
    /// // model's instrument terms may have a zero σ: not estimated).
    /// assert_eq!(
    ///     M1PaFilter::<f64>::new(config, SVector::zeros(), SVector::zeros()).unwrap_err(),
    ///     rollcal::Error::CovarianceNotPositiveDefinite
    /// );
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    // Not inlined: a caller that holds its filter in its own frame (the
    // firmware's synthetic run) then holds one `Result`, not the
    // constructor's temporaries too.
    #[inline(never)]
    pub fn new(
        config: FilterConfig<T>,
        x0: SVector<f64, N>,
        sigma0: SVector<T, N>,
    ) -> Result<Self, Error> {
        let variance = Self::prior_variance(&config, &x0, &sigma0)?;
        Ok(Self::with_prior_variance(config, x0, &variance))
    }

    /// [`Filter::new`] built in `slot` (whatever it held), and returned
    /// there: a filter in the slot is re-initialised in place, an empty
    /// slot first receives a placeholder of zeros (`Filter::placeholder`), written
    /// straight into it. A firmware that keeps its filter in static memory
    /// has no filter-sized value on its stack (59 KB for the full M2-ps
    /// model in f64, more than a Cortex-M's whole stack budget of 16 KB;
    /// built by value, this function's frame was 29.7 KB on the M7; now
    /// the largest frame of the path, the placeholder's, is 3.4 KB:
    /// `python3 tools/stack-usage.py ELF 'new_in|place_in'` on
    /// `firmware/run-qemu.sh`'s M7 image). On error `slot` is unchanged.
    ///
    /// # Examples
    ///
    /// ```
    /// # use nalgebra::SVector;
    /// # use rollcal::ekf::{FilterConfig, M2PsFullFilter, Options};
    /// # use rollcal::geometry::{earth_rate_n, gravity_n, EARTH_RATE};
    /// # use rollcal::models::Environment;
    /// # let deg = core::f64::consts::PI / 180.0;
    /// # let config = FilterConfig::<f64> {
    /// #     env: Environment { earth_rate_n: earth_rate_n(EARTH_RATE, 34.25 * deg), gravity_n: gravity_n() },
    /// #     sigma_accel: 1e-6,
    /// #     sigma_gyro: 0.1 * deg / 3600.0,
    /// #     sigma_gimbal: 10.0 * deg / 3600.0,
    /// #     options: Options::default(),
    /// #     wander: rollcal::models::Wander::none(),
    /// # };
    /// // In a firmware: `static mut SLOT: Option<M2PsFullFilter<f64>> = None;`
    /// let mut slot: Option<M2PsFullFilter<f64>> = None;
    /// let f = M2PsFullFilter::new_in(&mut slot, config, SVector::zeros(), SVector::repeat(1e-3))?;
    /// assert_eq!(f.state().len(), 54);
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    // Not inlined: its frame holds the prior's checks, not a filter.
    #[inline(never)]
    pub fn new_in(
        slot: &mut Option<Self>,
        config: FilterConfig<T>,
        x0: SVector<f64, N>,
        sigma0: SVector<T, N>,
    ) -> Result<&mut Self, Error> {
        let variance = Self::prior_variance(&config, &x0, &sigma0)?;
        if slot.is_none() {
            Self::place_in(slot, config);
        }
        match slot {
            Some(f) => {
                f.init_in_place(config, x0, &variance);
                Ok(f)
            }
            // Not reached: `place_in` has just filled the slot.
            None => Err(Error::NonFiniteInput),
        }
    }

    /// Puts [`Filter::placeholder`] into `slot`, in a frame of its own:
    /// the caller then makes it a filter in place
    /// ([`Filter::init_in_place`]).
    #[inline(never)]
    fn place_in(slot: &mut Option<Self>, config: FilterConfig<T>) {
        *slot = Some(Self::placeholder(config));
    }

    /// A filter whose storage is all zeros but for `config` and the
    /// computed frame: not a filter to run, but the value a slot is
    /// filled with before [`Filter::init_in_place`] makes it one. Its
    /// large parts (the factor, the saved factor, the pending period) are
    /// constant zeros, which the compiler writes straight into the slot
    /// (a memset of the destination, not a filter-sized temporary on the
    /// stack copied into it, as a factor built from the prior's
    /// variances was: 23 KB for the full M2-ps model in f64).
    #[inline(always)]
    pub(crate) fn placeholder(config: FilterConfig<T>) -> Self {
        Self {
            x: SVector::zeros(),
            ud: Ud::zeros(),
            command: CommandFrame::aligned(config.env.earth_rate_n),
            config,
            pending: PendingSlot::empty(),
            reference: None,
            updates: 0,
            gated_run: 0,
            gate_open: false,
            matrices: MatricesCache::new(Self::LAYOUT.installation(&SVector::<f64, N>::zeros())),
            env_t: env_t(&config.env),
            scratch: Scratch::zeros(),
            _model: PhantomData,
        }
    }

    /// Makes this filter the one [`Filter::new`] builds at `x0` with the
    /// prior variances `variance`, in place, whatever it held (its working memory, not
    /// state, is left as it was: [`Scratch`]). `variance` is what
    /// [`Filter::prior_variance`] returned for `config`, `x0`: finite and
    /// not negative, so this cannot fail.
    pub(crate) fn init_in_place(
        &mut self,
        config: FilterConfig<T>,
        x0: SVector<f64, N>,
        variance: &SVector<T, N>,
    ) {
        // `variance` passed `prior_variance`'s checks: accepted.
        let _accepted = self.ud.set_diagonal(variance, &Self::FACTOR_ORDER);
        self.x = x0;
        self.command = CommandFrame::aligned(config.env.earth_rate_n);
        self.env_t = env_t(&config.env);
        self.config = config;
        self.pending.clear();
        self.reference = None;
        self.updates = 0;
        self.gated_run = 0;
        self.gate_open = false;
        self.matrices.fill(Self::LAYOUT.installation(&x0));
    }

    /// [`Filter::new`] from the prior variances `variance` that
    /// [`Filter::prior_variance`] returned for `config`, `x0`: it cannot
    /// fail, so a caller can build the filter straight into its place (the
    /// session's calibrator slot) instead of out of a `Result`.
    #[inline(always)]
    pub(crate) fn with_prior_variance(
        config: FilterConfig<T>,
        x0: SVector<f64, N>,
        variance: &SVector<T, N>,
    ) -> Self {
        let mut f = Self::placeholder(config);
        f.init_in_place(config, x0, variance);
        f
    }

    /// Makes this filter equal to `Filter::new(config, x0, sigma0)`, in
    /// place (no filter-sized temporary: the estimator's passes restart one
    /// filter, [`crate::estimator::estimate_in`]). On error the filter is
    /// unchanged.
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
    /// f.step(&dtheta_c, dt, &obs)?;
    /// // Back to the prior, in place: the same filter as a new one.
    /// f.restart(config, SVector::zeros(), SVector::repeat(deg))?;
    /// assert_eq!(f, M1PaFilter::new(config, SVector::zeros(), SVector::repeat(deg))?);
    /// # Ok::<(), rollcal::Error>(())
    /// ```
    // Not inlined: once per pass, and its code once per configuration.
    #[inline(never)]
    pub fn restart(
        &mut self,
        config: FilterConfig<T>,
        x0: SVector<f64, N>,
        sigma0: SVector<T, N>,
    ) -> Result<(), Error> {
        let variance = Self::prior_variance(&config, &x0, &sigma0)?;
        self.init_in_place(config, x0, &variance);
        Ok(())
    }

    /// The prior variances `σ0²` (rad²) of [`Filter::new`] after its
    /// checks of the inputs.
    pub(crate) fn prior_variance(
        config: &FilterConfig<T>,
        x0: &SVector<f64, N>,
        sigma0: &SVector<T, N>,
    ) -> Result<SVector<T, N>, Error> {
        #[allow(clippy::let_unit_value)]
        let () = Self::SIZES_AGREE;
        let inputs = [config.sigma_accel, config.sigma_gyro, config.sigma_gimbal];
        if !all_finite(sigma0.iter().copied().chain(inputs))
            || !all_finite(x0.iter().copied())
            || !all_finite(
                config
                    .env
                    .earth_rate_n
                    .iter()
                    .chain(config.env.gravity_n.iter())
                    .copied(),
            )
            || !config.options.nis_gate.is_finite()
        {
            return Err(Error::NonFiniteInput);
        }
        if !config.options.is_built() {
            return Err(Error::UnsupportedOption);
        }
        // An instrument state may have a zero prior σ: the model does not
        // estimate it (its variance stays zero, its estimate at x0).
        let first_instrument = Self::LAYOUT.instruments().unwrap_or(N);
        let may_be_zero = |i: usize| i >= first_instrument;
        if sigma0
            .iter()
            .enumerate()
            .any(|(i, s)| *s < T::zero() || (*s == T::zero() && !may_be_zero(i)))
            || config.sigma_accel <= T::zero()
        {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        // A finite prior σ whose variance overflows (σ > 1.3e154 in f64,
        // 1.8e19 in f32) would give an infinite covariance, from which no
        // checkpoint of the filter could be restored (`from_parts`).
        let variance = sigma0.component_mul(sigma0);
        // (Also one that underflows to zero: only a zero σ gives a zero
        // variance.)
        if !all_finite(variance.iter().copied())
            || variance
                .iter()
                .zip(sigma0.iter())
                .any(|(v, s)| *v <= T::zero() && *s != T::zero())
        {
            return Err(Error::NonFiniteInput);
        }
        // The errors that wander: figures within their bounds
        // (`Wander::invalid_field`; so every σ's variance is a normal number
        // and every τ in use at least 1e-3 s), and states to carry them.
        let wander = &config.wander;
        if !wander.is_valid() {
            return Err(if all_finite(wander.figures()) {
                Error::OutOfRange
            } else {
                Error::NonFiniteInput
            });
        }
        if !wander.is_none() && Self::LAYOUT.dg_gm().is_none() {
            return Err(Error::OutOfRange);
        }
        if Self::LAYOUT.gimbal_obs && config.sigma_gimbal <= T::zero() {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        // Bounds that keep the update's arithmetic in range: with an Earth
        // rate of 4e71 rad/s (found by the session fuzz target) the
        // factored update overflowed after its scalar updates had been
        // applied, leaving a refused period's covariance changed.
        let env = &config.env;
        let gravity = env.gravity_n.norm();
        if env.earth_rate_n.norm() > MAX_EARTH_RATE
            || !(GRAVITY_RANGE.0..=GRAVITY_RANGE.1).contains(&gravity)
        {
            return Err(Error::OutOfRange);
        }
        // A noise level whose variance is subnormal, zero or infinite in T
        // (σ_gyro may be zero: no process noise).
        let min_normal = if core::mem::size_of::<T>() <= 4 {
            f64::from(f32::MIN_POSITIVE)
        } else {
            f64::MIN_POSITIVE
        };
        let normal = |s: T| {
            let v = s * s;
            v.is_finite() && v >= nalgebra::convert(min_normal)
        };
        let gimbal_ok = !Self::LAYOUT.gimbal_obs || normal(config.sigma_gimbal);
        let zero_or_normal = |s: T| s == T::zero() || normal(s);
        let gyro_ok = zero_or_normal(config.sigma_gyro);
        if !normal(config.sigma_accel) || !gyro_ok || !gimbal_ok {
            return Err(Error::OutOfRange);
        }
        Ok(variance)
    }
}
