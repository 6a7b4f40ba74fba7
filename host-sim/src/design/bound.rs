//! The bound evaluation of a candidate: [`Problem::new`] from a scenario,
//! the coarse step of a pattern ([`Problem::step_periods`]) and the
//! posterior Cramér–Rao bound propagated along the pattern's commanded
//! increments ([`Problem::evaluate`]).

use nalgebra::{SVector, Vector3};
use rollcal::command::CommandFrame;
use rollcal::ekf::{FilterConfig, Options};
use rollcal::geometry::euler_angles;
use rollcal::models::{ConfigId, ErrorModel, Model};
use rollcal::observability::Bound;

use crate::analysis::runner::{filter_config, prior_sigma, with_wander};
use crate::sim::instruments::instrument_truth_state;
use crate::sim::scenario::{Scenario, DEG};
use crate::sim::truth::{truth_state, TruthParams};
use crate::sim::wander::WanderTruth;

use super::pattern::gcd;
use super::{
    Goal, Outcome, Pattern, Problem, COARSE_SLACK, DEFAULT_STEP_DEG, FINE_SLACK, MAX_STEP_PERIODS,
};

impl Problem {
    /// The problem of configuration `id` on scenario `s` (its truth, site,
    /// noise, timing, prior), Earth rate as in the scenario, without targets.
    pub fn new(id: ConfigId, s: &Scenario, max_beta_deg: f64) -> Self {
        Self::with_errors(id, ErrorModel::Installation, s, max_beta_deg)
    }

    /// [`Problem::new`] under error model `errors`: with the full model, the
    /// true instrument errors of the scenario follow the installation
    /// states, and the prior is the scenario's `[instruments.prior]` on them
    /// (as [`crate::analysis::runner::SimulatedRun`] sets them for
    /// `host-sim observability`).
    pub fn with_errors(id: ConfigId, errors: ErrorModel, s: &Scenario, max_beta_deg: f64) -> Self {
        let params = TruthParams::from_scenario(s);
        let c_r_n = rollcal::geometry::dcm(&params.lambda);
        let c_ps_n = rollcal::geometry::gimbal_dcm(&params.gimbal0) * c_r_n;
        let at = crate::sim::truth::Instant {
            t: 0.0,
            c_ps_n,
            c_c_n: nalgebra::Matrix3::identity(),
            accel_at_t: Vector3::zeros(),
            gimbal: params.gimbal0,
        };
        let mut truth0 = truth_state(id, &params, &at);
        if errors == ErrorModel::Full {
            truth0.extend(instrument_truth_state(id, &params, &WanderTruth::zero()));
        }
        Self {
            config: id,
            errors,
            cfg: with_wander(
                filter_config(s, s.site.earth_rate, Options::plain()),
                errors,
                &s.instruments.wander,
            ),
            truth0,
            prior: prior_sigma(
                id.layout_with(errors),
                s.prior.sigma_deg * DEG,
                &s.instruments.prior.to_wire(),
                &s.instruments.wander.to_model(),
            ),
            period_s: s.timing.period_s,
            max_beta: max_beta_deg * DEG,
            targets: Vec::new(),
            step_deg: DEFAULT_STEP_DEG,
            coarse_slack: COARSE_SLACK,
            max_step_periods: MAX_STEP_PERIODS,
        }
    }

    /// Periods per coarse step of `p` (1 with `fine`): the largest divisor
    /// of every rotation's and every dwell's period count (and of `extra`)
    /// that keeps a step within `step_deg` of rotation and
    /// [`MAX_STEP_PERIODS`]. A step therefore never straddles the end of a
    /// rotation or of a dwell.
    pub fn step_periods(&self, p: &Pattern, extra: u64, fine: bool) -> u64 {
        if fine {
            return 1;
        }
        let mut g = extra;
        let mut max_rate: f64 = 0.0;
        for r in &p.rotations {
            g = gcd(g, r.periods(self.period_s).unwrap_or(1));
            g = gcd(g, r.dwell_periods(self.period_s).unwrap_or(1));
            if r.angle_deg > 0.0 {
                max_rate = max_rate.max(r.rate_deg_s);
            }
        }
        if max_rate == 0.0 {
            max_rate = 1e-12;
        }
        let cap = ((self.step_deg / (max_rate * self.period_s)).floor() as u64)
            .clamp(1, self.max_step_periods.max(1));
        (1..=cap.min(g.max(1)))
            .rev()
            .find(|d| g.is_multiple_of(*d))
            .unwrap_or(1)
    }

    /// Evaluates pattern `p` towards `goal`; `fine`: one step per period;
    /// `record`: keep σ of every state after every step.
    pub fn evaluate(&self, p: &Pattern, goal: Goal, fine: bool, record: bool) -> Outcome {
        let id = self.config;
        rollcal::with_model!(id, self.errors, |M, N, Z| self
            .evaluate_typed::<M, N, Z>(p, goal, fine, record))
    }

    fn evaluate_typed<M: Model<N, Z>, const N: usize, const Z: usize>(
        &self,
        p: &Pattern,
        goal: Goal,
        fine: bool,
        record: bool,
    ) -> Outcome {
        let (limit, extra) = match goal {
            Goal::Reach { cutoff } => (cutoff, 0),
            Goal::Budget { periods } => (periods, periods),
        };
        let k = self.step_periods(p, extra, fine);
        let cfg = self.coarse_config(k);
        let x0 = SVector::<f64, N>::from_iterator(
            self.truth0.iter().copied().chain(std::iter::repeat(0.0)),
        );
        let prior = SVector::<f64, N>::from_iterator(self.prior.iter().copied());
        let mut out = Outcome {
            k,
            worst_ratio: f64::INFINITY,
            ..Outcome::default()
        };
        // σ only: the bound without Φ(k,0) and J.
        let Ok(mut obs) = Bound::<f64, M, N, Z>::bound_only(cfg, x0, prior) else {
            return out;
        };
        let mut frame = CommandFrame::aligned(self.cfg.env.earth_rate_n);
        let dt1 = self.period_s;
        let mut done = 0u64;
        let ratio_of = |s: &SVector<f64, N>| self.worst_ratio(s.as_slice());
        for piece in p.chunks(limit, dt1, k) {
            let (r, m) = (piece.rotation, piece.periods);
            // A dwell: zero commanded path rate (the increments are the
            // Earth rate alone and the frame stays put), as the truth
            // simulator holds a scenario's `dwell_s`.
            let w = if piece.dwell {
                Vector3::zeros()
            } else {
                Vector3::from(r.axis.unit) * (r.rate_deg_s * DEG)
            };
            let u = frame.c_cn * w;
            let dt = dt1 * m as f64;
            let dtheta = frame.increment(&u, dt);
            if obs.step(&dtheta, dt).is_err() {
                out.gimbal_lock = Some(done);
                break;
            }
            frame.c_cn = frame.after(&u, dt, 1);
            done += m;
            let beta = euler_angles(&frame.c_cn).y;
            if beta.abs() > self.max_beta {
                out.gimbal_lock = Some(done);
                break;
            }
            // σ after every step only where it is read (a history, or a
            // reach time); a budget needs it at the end alone.
            let reach = matches!(goal, Goal::Reach { .. });
            if !record && !reach {
                continue;
            }
            let sigma = obs.crlb_sigma();
            if record {
                out.history.push((
                    done as f64 * dt1,
                    sigma.iter().copied().collect(),
                    piece.index,
                    piece.dwell,
                ));
            }
            let slack = if k > 1 { self.coarse_slack } else { FINE_SLACK };
            if reach && ratio_of(&sigma) <= 1.0 + slack {
                out.reach = Some(done);
                break;
            }
        }
        let sigma = obs.crlb_sigma();
        out.periods = done;
        out.worst_ratio = ratio_of(&sigma);
        out.sigma_end = sigma.iter().copied().collect();
        out
    }

    /// The filter settings of a coarse step of `k` periods: the noise
    /// densities kept (σ of the accelerometer, gyro and gimbal divided by
    /// √k; see the module docs).
    fn coarse_config(&self, k: u64) -> FilterConfig<f64> {
        let scale = (k as f64).sqrt();
        FilterConfig {
            sigma_accel: self.cfg.sigma_accel / scale,
            sigma_gyro: self.cfg.sigma_gyro / scale,
            sigma_gimbal: self.cfg.sigma_gimbal / scale,
            ..self.cfg
        }
    }

    /// max over the targets of σ/target, σ of every state in `sigma` (rad;
    /// a missing state counts as infinite).
    fn worst_ratio(&self, sigma: &[f64]) -> f64 {
        self.targets
            .iter()
            .map(|&(i, t)| sigma.get(i).copied().unwrap_or(f64::INFINITY) / t)
            .fold(0.0, f64::max)
    }
}
