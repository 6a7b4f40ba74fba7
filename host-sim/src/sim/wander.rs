//! The truth of the errors that wander (docs/model.md §Errors that
//! wander): per axis, independent, the Gauss–Markov parts `δ' = −δ/τ + w`
//! of the drift and the bias (started in their stationary distribution),
//! their random walks `r' = w` (started at zero) and the deterministic
//! warm-up `Δ e^(−t/τ_w)`, advanced at the truth step by the exact
//! discretisation of each process:
//! `δ ← e^(−h/τ) δ + σ √(1 − e^(−2h/τ)) n`, `r ← r + K √h n`,
//! `n ~ N(0, 1)`. Their random numbers come from their own stream of the
//! run's seed, so that the noise of a scenario without them is unchanged.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rollcal::models::Wander;

use crate::sim::truth::TruthParams;

/// The wandering parts of the drift and the bias at one instant (rad/s,
/// g); all zero without them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WanderTruth {
    /// Random walk of the gyro drift `r_g` (rad/s).
    pub r_g: Vector3<f64>,
    /// Gauss–Markov part of the gyro drift `δ_g` (rad/s).
    pub delta_g: Vector3<f64>,
    /// Random walk of the accelerometer bias `r_a` (g).
    pub r_a: Vector3<f64>,
    /// Gauss–Markov part of the accelerometer bias `δ_a` (g).
    pub delta_a: Vector3<f64>,
    /// Warm-up of the drift `Δ_g e^(−t/τ_w)` (rad/s).
    pub warmup_g: Vector3<f64>,
    /// Warm-up of the bias `Δ_a e^(−t/τ_w)` (g).
    pub warmup_a: Vector3<f64>,
}

impl WanderTruth {
    /// No wandering part.
    pub fn zero() -> Self {
        Self::default()
    }

    /// The whole wandering drift `δ_g + r_g + warm-up` (rad/s).
    pub fn drift(&self) -> Vector3<f64> {
        self.delta_g + self.r_g + self.warmup_g
    }

    /// The whole wandering bias `δ_a + r_a + warm-up` (g).
    pub fn bias(&self) -> Vector3<f64> {
        self.delta_a + self.r_a + self.warmup_a
    }
}

/// The processes of one run, advanced at the truth step.
pub struct WanderProcess {
    figures: Wander<f64>,
    warmup: (Vector3<f64>, Vector3<f64>, f64),
    state: WanderTruth,
    rng: ChaCha8Rng,
    noise: bool,
}

impl WanderProcess {
    /// The processes of `params`, their random numbers from stream 1 of
    /// `seed`; without `noise` (the golden, noise-free run) the
    /// Gauss–Markov parts start at zero and nothing is drawn: only the
    /// warm-up moves.
    pub fn new(params: &TruthParams, seed: u64, noise: bool) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(1);
        let figures = params.wander;
        let mut p = Self {
            figures,
            warmup: params.warmup,
            state: WanderTruth::zero(),
            rng,
            noise,
        };
        if noise {
            // The stationary distribution.
            p.state.delta_g = p.gauss3() * figures.gyro_markov_sigma;
            p.state.delta_a = p.gauss3() * figures.accel_markov_sigma;
        }
        p
    }

    fn gauss3(&mut self) -> Vector3<f64> {
        let mut n = || -> f64 { StandardNormal.sample(&mut self.rng) };
        Vector3::new(n(), n(), n())
    }

    /// Advances every process by `h` (s).
    pub fn advance(&mut self, h: f64) {
        if !self.noise {
            return;
        }
        let f = self.figures;
        let markov = |sigma: f64, tau: f64| -> Option<(f64, f64)> {
            (sigma > 0.0 && tau > 0.0).then(|| {
                let phi = (-h / tau).exp();
                (phi, sigma * (1.0 - phi * phi).sqrt())
            })
        };
        if let Some((phi, q)) = markov(f.gyro_markov_sigma, f.gyro_markov_tau_s) {
            let n = self.gauss3();
            self.state.delta_g = self.state.delta_g * phi + n * q;
        }
        if let Some((phi, q)) = markov(f.accel_markov_sigma, f.accel_markov_tau_s) {
            let n = self.gauss3();
            self.state.delta_a = self.state.delta_a * phi + n * q;
        }
        if f.gyro_random_walk > 0.0 {
            let n = self.gauss3();
            self.state.r_g += n * (f.gyro_random_walk * h.sqrt());
        }
        if f.accel_random_walk > 0.0 {
            let n = self.gauss3();
            self.state.r_a += n * (f.accel_random_walk * h.sqrt());
        }
    }

    /// The state at time `t` (s; the warm-up is a function of time, the
    /// stochastic parts are where [`WanderProcess::advance`] left them).
    pub fn truth(&self, t: f64) -> WanderTruth {
        let (dg, ba, tau) = self.warmup;
        let k = if tau > 0.0 { (-t / tau).exp() } else { 0.0 };
        WanderTruth {
            warmup_g: dg * k,
            warmup_a: ba * k,
            ..self.state
        }
    }

    /// The whole wandering drift at time `t` (rad/s).
    pub fn drift(&self, t: f64) -> Vector3<f64> {
        self.truth(t).drift()
    }

    /// The whole wandering bias at time `t` (g).
    pub fn bias(&self, t: f64) -> Vector3<f64> {
        self.truth(t).bias()
    }
}
