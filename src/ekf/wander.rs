//! The errors that wander at the end of a period ([`Filter::wander_jump`];
//! docs/model.md §Errors that wander): after a period's measurement update
//! and attitude time update, the full model's Gauss–Markov states decay by
//! `φ = exp(−T/τ)` and gain the variance `σ² (1 − φ²)`, the warm-up states
//! decay by `exp(−T/τ_w)`, and the drift and bias gain their random walk's
//! `K² T`. The wandering parts are held
//! constant over the period the measurement covers, so this move is
//! independent of the period's measurement and gyro noise: it follows the
//! decorrelated update (`factored`) as a separate time update, with the
//! factor's own O(N) scaling and Agee–Turner rank-one updates
//! ([`Ud::scale_state`](super::factor::Ud::scale_state),
//! [`Ud::add_variance`](super::factor::Ud::add_variance)), cheap because
//! the factor holds the states that gain variance right after the attitude
//! ([`Filter::FACTOR_ORDER`]).

use nalgebra::{RealField, SVector};

use super::factor::Ud;
use super::{Filter, FilterConfig};
use crate::models::{Layout, Model, WanderStep};
use crate::precision::scalar_to_f64;

/// The wandering states of `layout` with what a period does to them:
/// `(first index, φ, q)` for the random walks of the drift and the bias and
/// the Gauss–Markov parts and the warm-up of both (empty for a layout
/// without them).
fn moves<T: RealField + Copy>(layout: &Layout, step: &WanderStep<T>) -> [(Option<usize>, T, T); 6] {
    [
        (layout.dg(), T::one(), step.gyro_walk_q),
        (layout.ba(), T::one(), step.accel_walk_q),
        (layout.dg_gm(), step.gyro_phi, step.gyro_markov_q),
        (layout.ba_gm(), step.accel_phi, step.accel_markov_q),
        (layout.dg_wu(), step.warmup_phi, T::zero()),
        (layout.ba_wu(), step.warmup_phi, T::zero()),
    ]
}

/// Applies one period (`dt`, s) of the wandering errors of `config` to the
/// factor `ud`, whose position `position[i]` holds state `i` (and, with
/// `x`, to the estimate's Gauss–Markov states: their mean decays with
/// `φ`). `work` is the rank-one update's vector. Nothing for a layout
/// without wandering states or [`Wander::none`](crate::models::Wander::none).
pub(super) fn apply<T: RealField + Copy, const N: usize>(
    layout: &Layout,
    config: &FilterConfig<T>,
    dt: f64,
    position: &[usize; N],
    ud: &mut Ud<T, N>,
    x: Option<&mut SVector<f64, N>>,
    work: &mut [T; N],
) {
    if config.wander.is_none() || layout.dg_gm().is_none() {
        return;
    }
    let step = config.wander.step(dt);
    let mut x = x;
    for (first, phi, q) in moves(layout, &step) {
        let Some(first) = first else {
            continue;
        };
        for j in first..first + 3 {
            let k = position.get(j).copied().unwrap_or(j);
            if phi != T::one() {
                ud.scale_state(k, phi);
                if let Some(v) = x.as_deref_mut().and_then(|x| x.get_mut(j)) {
                    *v *= scalar_to_f64(phi);
                }
            }
            // q is finite and not negative (Filter::new checks the wander).
            let _ = ud.add_variance(k, q, work);
        }
    }
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// The end of a period of length `dt` (s) for the errors that wander:
    /// the factor and the estimate's Gauss–Markov states move (see the
    /// [module docs](self)). Cannot fail.
    pub(super) fn wander_jump(&mut self, dt: f64) {
        // Nothing to do (as `apply` finds): skipped before the work vector
        // is cleared; statically for a layout without wandering states.
        if Self::LAYOUT.dg_gm().is_none() || self.config.wander.is_none() {
            return;
        }
        let mut work = [T::zero(); N];
        apply(
            &Self::LAYOUT,
            &self.config,
            dt,
            &Self::POSITION,
            &mut self.ud,
            Some(&mut self.x),
            &mut work,
        );
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
mod tests {
    use nalgebra::{SVector, Vector3};

    use crate::ekf::{Filter, FilterConfig, Options};
    use crate::geometry::{earth_rate_n, gravity_n, EARTH_RATE};
    use crate::models::{Environment, M1PaFull, Model, Wander};

    const N: usize = 48;

    fn config(wander: Wander<f64>) -> FilterConfig<f64> {
        let deg = core::f64::consts::PI / 180.0;
        FilterConfig {
            env: Environment {
                earth_rate_n: earth_rate_n(EARTH_RATE, 34.25 * deg),
                gravity_n: gravity_n(),
            },
            sigma_accel: 1e-6,
            sigma_gyro: 0.1 * deg / 3600.0,
            sigma_gimbal: 10.0 * deg / 3600.0,
            options: Options::default(),
            wander,
        }
    }

    /// Without measurements, the random walks' variance grows by `K² T` a
    /// period and the Gauss–Markov states keep their stationary variance
    /// while their mean decays by `φ` (the factor's scaling and rank-one
    /// updates against the closed forms).
    #[test]
    fn predictions_move_the_wandering_states_as_their_processes() {
        let w = Wander {
            gyro_markov_sigma: 1e-8,
            gyro_markov_tau_s: 600.0,
            gyro_random_walk: 2e-9,
            accel_markov_sigma: 2e-6,
            accel_markov_tau_s: 900.0,
            accel_random_walk: 1e-6 / 60.0,
            gyro_warmup_sigma: 1e-8,
            accel_warmup_sigma: 3e-6,
            warmup_tau_s: 1200.0,
        };
        let layout = <M1PaFull as Model<N, 3>>::LAYOUT;
        let (iba, igm) = (layout.ba().unwrap(), layout.ba_gm().unwrap());
        let mut sigma0 = SVector::<f64, N>::repeat(1e-3);
        for i in 0..3 {
            sigma0[layout.dg_gm().unwrap() + i] = w.gyro_markov_sigma;
            sigma0[igm + i] = w.accel_markov_sigma;
        }
        let mut x0 = SVector::<f64, N>::zeros();
        x0[igm] = 3e-6;
        let mut f = Filter::<f64, M1PaFull, N, 3>::new(config(w), x0, sigma0).unwrap();
        let inc = Vector3::new(1e-3, 0.0, 0.0);
        let periods = 100;
        for _ in 0..periods {
            f.predict(&inc, 1.0).unwrap();
        }
        // The last period's move is applied with the next one's time update
        // (the covariance of a pending period is the predicted state's,
        // whose wandering parts still hold that period's values).
        f.predict(&inc, 1.0).unwrap();
        let moved = f64::from(periods as u32);
        let var = f.covariance();
        let want_ba = 1e-6 + w.accel_random_walk * w.accel_random_walk * moved;
        assert!(
            (var[(iba, iba)] / want_ba - 1.0).abs() < 1e-12,
            "{:e}",
            var[(iba, iba)]
        );
        let s2 = w.accel_markov_sigma * w.accel_markov_sigma;
        assert!((var[(igm, igm)] / s2 - 1.0).abs() < 1e-12);
        let phi = (-1.0f64 / 900.0).exp();
        assert!((f.state()[igm] / (3e-6 * phi.powf(moved)) - 1.0).abs() < 1e-12);
    }
}
