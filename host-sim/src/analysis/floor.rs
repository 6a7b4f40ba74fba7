//! The floor that errors that wander leave (docs/observability.md §Errors
//! that wander): how well the persistent part of a drift or a bias can be
//! known at the end of a log however the platform rolls.
//!
//! No path can observe an instrument's error better than the instrument's
//! own output does when it measures that error directly, period by period,
//! with nothing else unknown: `y_k = p_k + δ_k + v_k`, `p` the persistent
//! part (the constant and its random walk, `p_{k+1} = p_k + w`,
//! `var w = K² T`), `δ` the Gauss–Markov part (`δ_{k+1} = φ δ_k + u`,
//! `φ = e^(−T/τ)`, `var u = σ² (1 − φ²)`), `v` the white noise of one
//! period (the accelerometer noise of a period's mean, or the gyro rate
//! noise). [`floor`] runs the Kalman filter of that two-state model (its
//! covariance alone) over the log's periods: the floor at the log's end,
//! and, run on, its limit. A path does worse: it sees the drift only
//! through the attitude it integrates, the bias through an output that the
//! installation and scale factors also move.
//!
//! With a random walk the floor levels off at a limit (information older
//! than a few `N/K` is forgotten): rolling longer than
//! [`Floor::flat_after_s`] no longer helps. Without one the floor keeps
//! falling (the Gauss–Markov part averages out, `σ² 2τ/t`).

use nalgebra::{Matrix2, Vector2};

/// How much closer than this to its limit the floor must be for rolling
/// longer to be said not to help: 5 %.
pub const FLAT_WITHIN: f64 = 0.05;

/// The longest run [`floor`] computes the limit over (s): 10⁷ s.
pub const LIMIT_HORIZON_S: f64 = 1e7;

/// The floor of one wandering term (internal units: rad/s or g).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Floor {
    /// σ of the persistent part at the end of a log of the given length.
    pub at_end: f64,
    /// Its limit for an arbitrarily long log (the steady state; `at_end`
    /// of [`LIMIT_HORIZON_S`] when there is no random walk).
    pub limit: f64,
    /// The log length from which the floor is within [`FLAT_WITHIN`] of its
    /// limit (s): rolling longer does not help. `None` without a random
    /// walk (the floor keeps falling).
    pub flat_after_s: Option<f64>,
}

/// The figures of one wandering term (internal units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Term {
    /// Prior σ of the persistent part.
    pub prior: f64,
    /// White noise of one period's measurement of the term.
    pub white: f64,
    /// Stationary σ of the Gauss–Markov part (0: none).
    pub markov_sigma: f64,
    /// Its correlation time (s).
    pub markov_tau_s: f64,
    /// Random walk `K` (per √s; 0: none).
    pub random_walk: f64,
}

/// The covariance recursion of the two-state model, period by period.
struct Recursion {
    p: Matrix2<f64>,
    phi: f64,
    q_markov: f64,
    q_walk: f64,
    r: f64,
}

impl Recursion {
    fn new(t: &Term, period_s: f64) -> Self {
        let phi = if t.markov_sigma > 0.0 && t.markov_tau_s > 0.0 {
            (-period_s / t.markov_tau_s).exp()
        } else {
            0.0
        };
        let s2 = t.markov_sigma * t.markov_sigma;
        Self {
            p: Matrix2::new(t.prior * t.prior, 0.0, 0.0, s2),
            phi,
            q_markov: s2 * (1.0 - phi * phi),
            q_walk: t.random_walk * t.random_walk * period_s,
            r: t.white * t.white,
        }
    }

    /// One period: the measurement `y = p + δ + v`, then the move.
    fn step(&mut self) {
        let h = Vector2::new(1.0, 1.0);
        let ph = self.p * h;
        let s = h.dot(&ph) + self.r;
        self.p -= ph * ph.transpose() / s;
        let f = Matrix2::new(1.0, 0.0, 0.0, self.phi);
        self.p = f * self.p * f.transpose() + Matrix2::new(self.q_walk, 0.0, 0.0, self.q_markov);
    }

    fn sigma(&self) -> f64 {
        self.p[(0, 0)].max(0.0).sqrt()
    }
}

/// The floor of `term` for a log of `periods` periods of `period_s` (s):
/// see the [module docs](self).
///
/// # Examples
///
/// A bias observed directly with 1 µg of noise a period and no wander: the
/// floor falls as 1 µg/√n and has no limit.
///
/// ```
/// use host_sim::analysis::floor::{floor, Term};
///
/// let constant = Term { prior: 1e-3, white: 1e-6, markov_sigma: 0.0, markov_tau_s: 0.0, random_walk: 0.0 };
/// let f = floor(&constant, 1.0, 5400);
/// assert!((f.at_end / (1e-6 / 5400f64.sqrt()) - 1.0).abs() < 1e-3);
/// assert_eq!(f.flat_after_s, None);
/// // A random walk of 1 µg/√h levels it off at about √(K N √T) = 0.13 µg.
/// let walk = Term { random_walk: 1e-6 / 60.0, ..constant };
/// let f = floor(&walk, 1.0, 5400);
/// assert!(f.limit > 0.12e-6 && f.limit < 0.14e-6 && f.flat_after_s.is_some());
/// ```
pub fn floor(term: &Term, period_s: f64, periods: usize) -> Floor {
    let mut rec = Recursion::new(term, period_s);
    let mut at_end = rec.sigma();
    let horizon = (LIMIT_HORIZON_S / period_s).ceil() as usize;
    // σ after every period, until the recursion has settled (a relative
    // change below 1e-9 over a period) or the horizon.
    let mut history = Vec::new();
    let mut last = f64::INFINITY;
    for k in 1..=horizon.max(periods) {
        rec.step();
        let s = rec.sigma();
        history.push(s);
        if k == periods {
            at_end = s;
        }
        let settled = (last - s).abs() <= 1e-9 * s;
        last = s;
        if k >= periods && settled && term.random_walk > 0.0 {
            break;
        }
    }
    let limit = history.last().copied().unwrap_or(at_end);
    let flat_after_s = (term.random_walk > 0.0)
        .then(|| {
            history
                .iter()
                .position(|s| *s <= (1.0 + FLAT_WITHIN) * limit)
                .map(|k| (k + 1) as f64 * period_s)
        })
        .flatten();
    Floor {
        at_end,
        limit,
        flat_after_s,
    }
}

/// The floors of a scenario's wandering terms (the drift `dg` and the
/// bias `ba`, the same for the three axes), for a log of the scenario's
/// length: `(state group name, printed unit, floor)`; empty when nothing
/// wanders. The gyro's white noise is the rate noise of a period, the
/// accelerometer's that of a period's mean.
pub fn scenario_floors(
    s: &crate::sim::scenario::Scenario,
) -> Vec<(&'static str, &'static str, Floor)> {
    let w = s.instruments.wander.to_model();
    if w.is_none() {
        return Vec::new();
    }
    let prior = s.instruments.prior.to_wire();
    let (period, periods) = (s.timing.period_s, s.periods());
    let gyro = Term {
        prior: prior.dg_rad_s,
        white: s.noise.gyro_deg_h * crate::sim::instruments::DEG_H,
        markov_sigma: w.gyro_markov_sigma,
        markov_tau_s: w.gyro_markov_tau_s,
        random_walk: w.gyro_random_walk,
    };
    let accel = Term {
        prior: prior.ba_g,
        white: s.noise.accel_g,
        markov_sigma: w.accel_markov_sigma,
        markov_tau_s: w.accel_markov_tau_s,
        random_walk: w.accel_random_walk,
    };
    vec![
        ("dg", "°/h", floor(&gyro, period, periods)),
        ("ba", "µg", floor(&accel, period, periods)),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Gauss–Markov part alone (no random walk): the floor falls slowly,
    /// towards `σ √(2τ/t)` for `t ≫ τ`, and has no flat point.
    #[test]
    fn a_markov_part_averages_out() {
        let t = Term {
            prior: 1e-3,
            white: 1e-6,
            markov_sigma: 2e-6,
            markov_tau_s: 900.0,
            random_walk: 0.0,
        };
        let f = floor(&t, 1.0, 90_000);
        let asymptote = 2e-6 * (2.0 * 900.0 / 90_000.0f64).sqrt();
        assert!((f.at_end / asymptote - 1.0).abs() < 0.1, "{:e}", f.at_end);
        assert!(f.flat_after_s.is_none());
        assert!(f.limit < f.at_end);
    }

    /// The realistic accelerometer (2 µg, 900 s; 1 µg/√h; 1 µg a period):
    /// the floor levels off, and a longer log than its flat point gains
    /// less than 5 %.
    #[test]
    fn the_realistic_bias_levels_off() {
        let t = Term {
            prior: 1e-3,
            white: 1e-6,
            markov_sigma: 2e-6,
            markov_tau_s: 900.0,
            random_walk: 1e-6 / 60.0,
        };
        let f = floor(&t, 1.0, 5400);
        let flat = f.flat_after_s.unwrap();
        let later = floor(&t, 1.0, (2.0 * flat) as usize);
        assert!(later.at_end >= f.limit * (1.0 - 1e-6));
        assert!(later.at_end <= f.limit * (1.0 + FLAT_WITHIN));
        assert!(f.at_end >= f.limit);
    }
}
