//! Designing the rolling path (issue 12): the shortest sequence of
//! constant-rate rotations whose posterior Cramér–Rao bound reaches a target
//! σ on every parameter, or the best worst-case σ/target within a time
//! budget.
//!
//! **The bound.** Every candidate is scored by the one computation of the
//! bound, [`rollcal::observability::Observability`], fed the commanded
//! increments of the candidate path. The increments come from the library's
//! own [`CommandFrame`] (`Δθc = uT + T J_r(uT) C^c_n ω^n_ie` at the constant
//! path rate `u`), not from the truth simulator: the bound depends on the
//! commanded motion only, and the truth simulator's RK4 integral of the same
//! motion agrees to rounding (tested). The designed path is finally checked
//! by [`crate::observe::analyse`] on the simulated run, exactly as
//! `host-sim observability --scenario` computes it.
//!
//! **Coarse steps.** During the search, `k` filter periods are merged into
//! one step of length `kT` with the noise densities kept: the mean of `k`
//! accelerometer means has σ_a/√k, `k` gimbal readings σ_g/√k, and the gyro
//! white rate noise over `kT` has the variance of `k` periods when its σ is
//! divided by √k (the filter's process noise is `(σ_gyro dt)²`). `k` is the
//! largest divisor of every segment's period count that keeps one step
//! within [`DEFAULT_STEP_DEG`] of rotation. The final σ of the designed path
//! is recomputed period by period, and the relative change is reported (it
//! must stay within 1 %).
//!
//! **The search.** Paths start aligned with n and are a *pattern* of up to
//! `P` constant-rate rotations about n-frame axes, repeated until the
//! targets are met (the last rotation cut at a whole period). Stage 1 is
//! exhaustive over the coarse grammar (axes × quarter-turn angles, every
//! segment at the maximum rate) with branch and bound: a candidate is
//! abandoned as soon as its elapsed time passes the best reach time found so
//! far, so within the coarse grammar the result is optimal (to one coarse
//! step). Stage 2 refines the best stage-1 patterns by hill climbing on
//! finer angles (30° steps, which keep the coarse step), slower rates, and, with `--tilted`, axes tilted
//! 45° between two allowed axes. Stage 2b (unless `--no-dwells`) climbs
//! again with dwell moves too: a dwell of 60, 180 or 600 s after a rotation
//! inserted, lengthened, shortened or removed (zero commanded path rate for
//! whole periods, as a scenario's `dwell_s`; the coarse step divides every
//! dwell). The best without and the best with dwells are both polished, so
//! the search with dwells is never worse than without. A candidate whose
//! middle gimbal angle |β| exceeds the limit before it reaches the targets
//! is infeasible.

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

use nalgebra::{SVector, Vector3};
use rayon::prelude::*;
use rollcal::command::CommandFrame;
use rollcal::ekf::{FilterConfig, Options};
use rollcal::geometry::euler_angles;
use rollcal::models::{ConfigId, Group, Model};
use rollcal::observability::Bound;

use crate::runner::filter_config;
use crate::scenario::{Axis, Scenario, Segment, ARCSEC, DEG};
use crate::truth::{truth_state, TruthParams};

/// Largest rotation (°) within one coarse step of the search.
pub const DEFAULT_STEP_DEG: f64 = 10.0;
/// The coarse steps' error budget on σ (relative).
pub const COARSE_SLACK: f64 = 0.01;
/// Period by period, a target counts as met at σ ≤ (1 + this)·target: the
/// library's commanded increments and the truth simulator's agree to this
/// (tests/design.rs); the written scenario is then checked exactly.
pub const FINE_SLACK: f64 = 1e-4;
/// Largest number of periods merged into one coarse step.
pub const MAX_STEP_PERIODS: u64 = 30;
/// Coarse angles of stage 1 (°).
pub const COARSE_ANGLES: [f64; 4] = [90.0, 180.0, 270.0, 360.0];
/// Candidates re-evaluated period by period at the end of a reach search.
pub const FINAL_CHECKS: usize = 8;
/// Angle step of the refinement (°).
pub const FINE_ANGLE_DEG: f64 = 30.0;

/// One n-frame rotation axis with its name.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct NamedAxis {
    /// `north`, `up`, … or `north+up` for a tilted axis.
    pub name: String,
    /// Unit vector in n (North, Up, East).
    pub unit: [f64; 3],
}

impl NamedAxis {
    /// One of the six named n-frame directions.
    pub fn named(name: &str) -> Result<Self, String> {
        let unit = Axis::Named(name.to_string())
            .unit()
            .map_err(|e| e.to_string())?;
        Ok(Self {
            name: name.to_ascii_lowercase(),
            unit,
        })
    }

    /// The axis half-way between two perpendicular axes.
    pub fn tilted(a: &NamedAxis, b: &NamedAxis) -> Self {
        let s = std::f64::consts::FRAC_1_SQRT_2;
        Self {
            name: format!("{}+{}", a.name, b.name),
            unit: [
                (a.unit[0] + b.unit[0]) * s,
                (a.unit[1] + b.unit[1]) * s,
                (a.unit[2] + b.unit[2]) * s,
            ],
        }
    }

    fn dot(&self, o: &NamedAxis) -> f64 {
        self.unit[0] * o.unit[0] + self.unit[1] * o.unit[1] + self.unit[2] * o.unit[2]
    }

    /// The scenario-file form: the name for the six directions, else the
    /// vector.
    pub fn to_axis(&self) -> Axis {
        if self.name.contains('+') {
            Axis::Vector(self.unit)
        } else {
            Axis::Named(self.name.clone())
        }
    }
}

/// One constant-rate rotation of a path, then an optional dwell.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Rotation {
    /// The axis.
    pub axis: NamedAxis,
    /// Angle (°); 0 only with a dwell (a pure dwell, e.g. in a reference
    /// path).
    pub angle_deg: f64,
    /// Rate (°/s).
    pub rate_deg_s: f64,
    /// Hold still this long after the rotation (s, whole periods): zero
    /// commanded path rate, as `dwell_s` of a scenario segment.
    #[serde(skip_serializing_if = "is_zero")]
    pub dwell_s: f64,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// `x / period_s` if it is a whole number ≥ 0.
fn whole_periods(x: f64, period_s: f64) -> Option<u64> {
    let d = x / period_s;
    let r = d.round();
    (d.is_finite() && (d - r).abs() <= 1e-6 && r >= 0.0).then_some(r as u64)
}

impl Rotation {
    /// A rotation without a dwell.
    pub fn new(axis: NamedAxis, angle_deg: f64, rate_deg_s: f64) -> Self {
        Self {
            axis,
            angle_deg,
            rate_deg_s,
            dwell_s: 0.0,
        }
    }

    /// Whole periods of length `period_s` the rotation lasts (without the
    /// dwell), if whole and at least one (zero for a pure dwell).
    pub fn periods(&self, period_s: f64) -> Option<u64> {
        let r = whole_periods(self.angle_deg / self.rate_deg_s, period_s)?;
        let dwell = self.dwell_periods(period_s)?;
        (r >= 1 || (r == 0 && dwell >= 1)).then_some(r)
    }

    /// Whole periods of the dwell after the rotation, if whole.
    pub fn dwell_periods(&self, period_s: f64) -> Option<u64> {
        whole_periods(self.dwell_s, period_s)
    }

    /// Whole periods of the rotation and its dwell, if both are whole.
    pub fn total_periods(&self, period_s: f64) -> Option<u64> {
        Some(self.periods(period_s)? + self.dwell_periods(period_s)?)
    }
}

/// A piece of a path: `periods` periods of rotation `index` of the pattern,
/// rotating or (`dwell`) holding still after it.
#[derive(Clone, Copy, Debug)]
pub struct Piece<'a> {
    /// Index of the rotation in the pattern.
    pub index: usize,
    /// The rotation.
    pub rotation: &'a Rotation,
    /// Its dwell (zero path rate), not its rotation.
    pub dwell: bool,
    /// Whole periods.
    pub periods: u64,
}

/// A candidate: a pattern of rotations repeated until the path ends.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Pattern {
    /// The rotations of one cycle.
    pub rotations: Vec<Rotation>,
    /// Whether the cycle repeats (false: the path is the rotations once,
    /// then the platform holds still).
    pub repeat: bool,
}

impl Pattern {
    /// Short text, e.g. `(south 180° @0.1°/s, east 90° @0.1°/s + dwell 60 s) repeated`.
    pub fn describe(&self) -> String {
        let parts: Vec<String> = self
            .rotations
            .iter()
            .map(|r| {
                let mut t = format!("{} {}° @{}°/s", r.axis.name, r.angle_deg, r.rate_deg_s);
                if r.dwell_s > 0.0 {
                    t.push_str(&format!(" + dwell {} s", r.dwell_s));
                }
                t
            })
            .collect();
        format!(
            "({}){}",
            parts.join(", "),
            if self.repeat { " repeated" } else { "" }
        )
    }

    /// Whether any rotation has a dwell.
    pub fn has_dwell(&self) -> bool {
        self.rotations.iter().any(|r| r.dwell_s > 0.0)
    }

    /// Every rotation and dwell is a whole number of periods.
    pub fn whole(&self, period_s: f64) -> bool {
        self.rotations
            .iter()
            .all(|r| r.total_periods(period_s).is_some())
    }

    /// The path's segments over its first `periods` periods (the last one
    /// cut at a whole period, within its rotation or its dwell), as
    /// scenario segments.
    pub fn segments(&self, periods: u64, period_s: f64) -> Vec<Segment> {
        let mut out: Vec<Segment> = Vec::new();
        // The previous piece: (rotation index, dwell).
        let mut last: Option<(usize, bool)> = None;
        for piece in self.chunks(periods, period_s, u64::MAX) {
            let r = piece.rotation;
            let span = period_s * piece.periods as f64;
            if piece.dwell {
                // After its own rotation: that segment's dwell; else (a pure
                // dwell) a segment of its own.
                match (last, out.last_mut()) {
                    (Some((i, _)), Some(seg)) if i == piece.index => {
                        seg.dwell_s = round_angle(seg.dwell_s + span);
                    }
                    _ => out.push(Segment {
                        axis: r.axis.to_axis(),
                        angle_deg: 0.0,
                        rate_deg_s: r.rate_deg_s,
                        dwell_s: round_angle(span),
                    }),
                }
                last = Some((piece.index, true));
                continue;
            }
            let angle = r.rate_deg_s * span;
            // A single repeated rotation (without dwells) is one continuous
            // segment.
            if let (Some((i, false)), Some(seg)) = (last, out.last_mut()) {
                let prev = &self.rotations[i];
                if prev.axis == r.axis && prev.rate_deg_s == r.rate_deg_s && seg.dwell_s == 0.0 {
                    seg.angle_deg = round_angle(seg.angle_deg + angle);
                    last = Some((piece.index, false));
                    continue;
                }
            }
            out.push(Segment {
                axis: r.axis.to_axis(),
                angle_deg: round_angle(angle),
                rate_deg_s: r.rate_deg_s,
                dwell_s: 0.0,
            });
            last = Some((piece.index, false));
        }
        out
    }

    /// Pieces of at most `k` periods covering the first `periods` periods:
    /// every rotation, then its dwell.
    pub fn chunks(&self, periods: u64, period_s: f64, k: u64) -> Vec<Piece<'_>> {
        let mut out = Vec::new();
        let mut left = periods;
        if self.rotations.is_empty() {
            return out;
        }
        'cycle: loop {
            for (i, r) in self.rotations.iter().enumerate() {
                let (Some(rot), Some(dwell)) = (r.periods(period_s), r.dwell_periods(period_s))
                else {
                    return out;
                };
                for (mut n, is_dwell) in [(rot, false), (dwell, true)] {
                    while n > 0 && left > 0 {
                        let m = n.min(k).min(left);
                        out.push(Piece {
                            index: i,
                            rotation: r,
                            dwell: is_dwell,
                            periods: m,
                        });
                        n -= m;
                        left -= m;
                    }
                }
                if left == 0 {
                    break 'cycle;
                }
            }
            if !self.repeat {
                break;
            }
        }
        out
    }

    /// Periods of one cycle, dwells included.
    pub fn cycle_periods(&self, period_s: f64) -> Option<u64> {
        self.rotations
            .iter()
            .map(|r| r.total_periods(period_s))
            .sum()
    }
}

fn round_angle(a: f64) -> f64 {
    (a * 1e9).round() / 1e9
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// What the search aims at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Goal {
    /// The first period at which every target is met, abandoning the
    /// candidate after `cutoff` periods.
    Reach {
        /// Give up after this many periods.
        cutoff: u64,
    },
    /// The worst σ/target after exactly this many periods.
    Budget {
        /// Periods.
        periods: u64,
    },
}

/// The fixed part of every evaluation: configuration, truth, noise, targets.
#[derive(Clone, Debug)]
pub struct Problem {
    /// Configuration.
    pub config: ConfigId,
    /// Filter settings (noise levels of the scenario, Earth rate).
    pub cfg: FilterConfig<f64>,
    /// True initial state (rad).
    pub truth0: Vec<f64>,
    /// Prior σ (rad).
    pub sigma0: f64,
    /// Filter period (s).
    pub period_s: f64,
    /// Largest |β| (rad) allowed.
    pub max_beta: f64,
    /// `(state index, target σ in rad)` of every target.
    pub targets: Vec<(usize, f64)>,
    /// Largest rotation per coarse step (°).
    pub step_deg: f64,
    /// A coarse step counts a target met at σ ≤ (1 + slack)·target (the
    /// coarse steps' error budget; period by period the test is exact).
    pub coarse_slack: f64,
    /// Largest number of periods per coarse step.
    pub max_step_periods: u64,
}

/// The outcome of one evaluation.
#[derive(Clone, Debug, Default)]
pub struct Outcome {
    /// Periods evaluated.
    pub periods: u64,
    /// Period at which every target was first met (a coarse-step boundary
    /// when `k > 1`).
    pub reach: Option<u64>,
    /// σ_CRLB of every state at the end (rad).
    pub sigma_end: Vec<f64>,
    /// max over the targets of σ/target at the end.
    pub worst_ratio: f64,
    /// The |β| limit was exceeded (at this period) before the end.
    pub gimbal_lock: Option<u64>,
    /// Periods per step used.
    pub k: u64,
    /// Per step, when recorded: (t in s, σ of every state in rad, rotation
    /// index within the pattern, whether the step is the rotation's dwell).
    pub history: Vec<(f64, Vec<f64>, usize, bool)>,
}

impl Outcome {
    /// Feasible and meeting the goal: reached (Reach), or not locked (Budget).
    pub fn feasible(&self, goal: Goal) -> bool {
        match goal {
            Goal::Reach { .. } => self.reach.is_some(),
            Goal::Budget { .. } => self.gimbal_lock.is_none(),
        }
    }

    /// The score to minimise: reach periods, or the worst ratio.
    pub fn score(&self, goal: Goal) -> f64 {
        if !self.feasible(goal) {
            return f64::INFINITY;
        }
        match goal {
            Goal::Reach { .. } => self.reach.map_or(f64::INFINITY, |r| r as f64),
            Goal::Budget { .. } => self.worst_ratio,
        }
    }
}

impl Problem {
    /// The problem of configuration `id` on scenario `s` (its truth, site,
    /// noise, timing, prior), Earth rate as in the scenario, without targets.
    pub fn new(id: ConfigId, s: &Scenario, max_beta_deg: f64) -> Self {
        let params = TruthParams::from_scenario(s);
        let c_r_n = rollcal::geometry::dcm(&params.lambda);
        let c_ps_n = rollcal::geometry::gimbal_dcm(&params.gimbal0) * c_r_n;
        let at = crate::truth::Instant {
            t: 0.0,
            c_ps_n,
            c_c_n: nalgebra::Matrix3::identity(),
            accel_at_t: Vector3::zeros(),
            gimbal: params.gimbal0,
        };
        Self {
            config: id,
            cfg: filter_config(s, s.site.earth_rate, Options::plain()),
            truth0: truth_state(id, &params, &at),
            sigma0: s.prior.sigma_deg * DEG,
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
        rollcal::with_config!(id, |M, N, Z| self
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
        let scale = (k as f64).sqrt();
        let cfg = FilterConfig {
            sigma_accel: self.cfg.sigma_accel / scale,
            sigma_gyro: self.cfg.sigma_gyro / scale,
            sigma_gimbal: self.cfg.sigma_gimbal / scale,
            ..self.cfg
        };
        let x0 = SVector::<f64, N>::from_iterator(
            self.truth0.iter().copied().chain(std::iter::repeat(0.0)),
        );
        let prior = SVector::<f64, N>::repeat(self.sigma0);
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
        let ratio_of = |s: &SVector<f64, N>| {
            self.targets
                .iter()
                .map(|&(i, t)| s.get(i).copied().unwrap_or(f64::INFINITY) / t)
                .fold(0.0, f64::max)
        };
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
}

/// The search space and its limits.
#[derive(Clone, Debug)]
pub struct Space {
    /// Allowed axes.
    pub axes: Vec<NamedAxis>,
    /// Also try axes tilted 45° between two perpendicular allowed axes in
    /// the refinement.
    pub tilted: bool,
    /// Maximum rate (°/s).
    pub max_rate_deg_s: f64,
    /// Maximum duration (s).
    pub max_duration_s: f64,
    /// Longest pattern (rotations per cycle).
    pub max_rotations: usize,
    /// Hill-climbing starts of the refinement (best stage-1 patterns).
    pub refine_starts: usize,
    /// Dwell moves of the refinement (s): after each rotation a dwell is
    /// inserted, lengthened or shortened by each of these, or removed;
    /// empty: no dwells (`--no-dwells`).
    pub dwell_steps: Vec<f64>,
}

/// The refinement's dwell moves (s): insert, lengthen or shorten a dwell
/// after a rotation by each of these, or remove it.
pub const DWELL_STEPS_S: [f64; 3] = [60.0, 180.0, 600.0];

/// One evaluated candidate.
#[derive(Clone, Debug)]
pub struct Scored {
    /// The pattern.
    pub pattern: Pattern,
    /// Its coarse outcome.
    pub outcome: Outcome,
    /// Its score (lower is better).
    pub score: f64,
}

/// Statistics of one search stage.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StageStats {
    /// Stage name.
    pub name: String,
    /// Candidates evaluated.
    pub candidates: usize,
    /// Of which pruned by the bound on the best reach time so far.
    pub pruned: usize,
    /// Of which infeasible (gimbal limit).
    pub infeasible: usize,
    /// Periods propagated (all candidates).
    pub periods: u64,
    /// Wall time (s).
    pub wall_s: f64,
    /// Best score after the stage.
    pub best_score: f64,
}

impl StageStats {
    /// Candidates per minute.
    pub fn per_minute(&self) -> f64 {
        self.candidates as f64 / self.wall_s.max(1e-9) * 60.0
    }
}

/// Every stage-1 pattern: 1..=P rotations about the allowed axes by the
/// coarse angles at the maximum rate, no two consecutive rotations (in the
/// cycle) about the same axis, whole periods only.
pub fn coarse_patterns(space: &Space, period_s: f64) -> Vec<Pattern> {
    let rate = space.max_rate_deg_s;
    let mut out = Vec::new();
    for len in 1..=space.max_rotations {
        let angles: &[f64] = if len == 1 {
            &COARSE_ANGLES[..1]
        } else {
            &COARSE_ANGLES
        };
        let choices: Vec<(usize, f64)> = (0..space.axes.len())
            .flat_map(|a| angles.iter().map(move |&g| (a, g)))
            .collect();
        let mut idx = vec![0usize; len];
        loop {
            let seq: Vec<(usize, f64)> = idx.iter().map(|&i| choices[i]).collect();
            let ok = (0..len).all(|i| len == 1 || seq[i].0 != seq[(i + 1) % len].0);
            if ok {
                let p = Pattern {
                    rotations: seq
                        .iter()
                        .map(|&(a, g)| Rotation::new(space.axes[a].clone(), g, rate))
                        .collect(),
                    repeat: true,
                };
                if p.whole(period_s) {
                    out.push(p);
                }
            }
            // Next index tuple.
            let mut pos = 0;
            loop {
                if pos == len {
                    break;
                }
                idx[pos] += 1;
                if idx[pos] < choices.len() {
                    break;
                }
                idx[pos] = 0;
                pos += 1;
            }
            if pos == len {
                break;
            }
        }
    }
    out
}

/// The neighbours of a pattern in the refinement: each rotation's angle
/// ±30°, ±60°, ±90°; its rate at ¾ and ½ of the maximum (or back to the
/// maximum); with `tilted`, its axis tilted 45° towards each perpendicular
/// allowed axis; the dwell after it (`space.dwell_steps`) inserted,
/// lengthened or shortened by each step, or removed; whole periods only
/// (a dwell that is not a whole number of periods is never proposed).
pub fn neighbours(p: &Pattern, space: &Space, period_s: f64) -> Vec<Pattern> {
    let mut out = Vec::new();
    let max = space.max_rate_deg_s;
    let mut push = |q: Pattern| {
        if q.whole(period_s) && !out.contains(&q) {
            out.push(q);
        }
    };
    for i in 0..p.rotations.len() {
        for d in [-90.0, -60.0, -FINE_ANGLE_DEG, FINE_ANGLE_DEG, 60.0, 90.0] {
            let mut q = p.clone();
            let a = q.rotations[i].angle_deg + d;
            if (FINE_ANGLE_DEG - 1e-9..=720.0).contains(&a) {
                q.rotations[i].angle_deg = a;
                push(q);
            }
        }
        for f in [1.0, 0.75, 0.5] {
            let rate = max * f;
            if (rate - p.rotations[i].rate_deg_s).abs() > 1e-12 {
                let mut q = p.clone();
                q.rotations[i].rate_deg_s = rate;
                push(q);
            }
        }
        if !space.dwell_steps.is_empty() {
            let d = p.rotations[i].dwell_s;
            let mut dwells: Vec<f64> = Vec::new();
            for &step in &space.dwell_steps {
                dwells.push(d + step);
                if d - step > 0.0 {
                    dwells.push(d - step);
                }
            }
            if d > 0.0 {
                dwells.push(0.0);
            }
            for w in dwells {
                let mut q = p.clone();
                q.rotations[i].dwell_s = round_angle(w);
                push(q);
            }
        }
        if space.tilted {
            let base = &p.rotations[i].axis;
            if !base.name.contains('+') {
                for b in &space.axes {
                    if base.dot(b).abs() < 1e-9 {
                        let mut q = p.clone();
                        q.rotations[i].axis = NamedAxis::tilted(base, b);
                        push(q);
                    }
                }
            }
        }
    }
    out
}

/// The neighbours of the polish stage: each rotation's angle ±15° and ±5°
/// (at least 5°), whole periods only.
pub fn polish_neighbours(p: &Pattern, period_s: f64) -> Vec<Pattern> {
    let mut out = Vec::new();
    for i in 0..p.rotations.len() {
        for d in [-15.0, -5.0, 5.0, 15.0] {
            let mut q = p.clone();
            let a = q.rotations[i].angle_deg + d;
            if a >= 5.0 - 1e-9 {
                q.rotations[i].angle_deg = a;
                if q.whole(period_s) && !out.contains(&q) {
                    out.push(q);
                }
            }
        }
    }
    out
}

/// Scores `patterns` in parallel (rayon). For `Goal::Reach` the candidates
/// share the best reach time found so far and stop there (branch and
/// bound: a candidate still short of its targets at that time cannot win).
/// Ties go to the earlier candidate, so the result does not depend on the
/// scheduling. `progress(done)` is called after every candidate.
pub fn score_all(
    problem: &Problem,
    patterns: Vec<Pattern>,
    goal: Goal,
    incumbent: &AtomicU64,
    name: &str,
    progress: &(dyn Fn(usize) + Sync),
) -> (Vec<Scored>, StageStats) {
    let t0 = std::time::Instant::now();
    let done = AtomicUsize::new(0);
    let periods = AtomicU64::new(0);
    let scored: Vec<Scored> = patterns
        .into_par_iter()
        .map(|pattern| {
            let g = match goal {
                Goal::Reach { .. } => Goal::Reach {
                    cutoff: incumbent.load(Ordering::Relaxed),
                },
                b => b,
            };
            let outcome = problem.evaluate(&pattern, g, false, false);
            if let Some(r) = outcome.reach {
                incumbent.fetch_min(r, Ordering::Relaxed);
            }
            periods.fetch_add(outcome.periods, Ordering::Relaxed);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            let score = outcome.score(goal);
            Scored {
                pattern,
                outcome,
                score,
            }
        })
        .collect();
    let infeasible = scored
        .iter()
        .filter(|s| s.outcome.gimbal_lock.is_some() && !s.outcome.feasible(goal))
        .count();
    let pruned = scored
        .iter()
        .filter(|s| {
            matches!(goal, Goal::Reach { .. })
                && s.outcome.reach.is_none()
                && s.outcome.gimbal_lock.is_none()
        })
        .count();
    let best = scored.iter().map(|s| s.score).fold(f64::INFINITY, f64::min);
    let stats = StageStats {
        name: name.to_string(),
        candidates: scored.len(),
        pruned,
        infeasible,
        periods: periods.load(Ordering::Relaxed),
        wall_s: t0.elapsed().as_secs_f64(),
        best_score: best,
    };
    (scored, stats)
}

/// The best of `scored` (lowest score, then earliest).
pub fn best_of(scored: &[Scored]) -> Option<&Scored> {
    scored
        .iter()
        .filter(|s| s.score.is_finite())
        .min_by(|a, b| a.score.total_cmp(&b.score))
}

/// The result of a search.
#[derive(Clone, Debug)]
pub struct Design {
    /// The best pattern.
    pub best: Scored,
    /// Per stage.
    pub stages: Vec<StageStats>,
    /// Reach: the best pattern's outcome period by period.
    pub fine: Option<Outcome>,
    /// The best pattern before the polish (on the coarse grammar's step)
    /// and its coarse outcome.
    pub searched: Scored,
}

/// Searches `space` towards `goal`: stage 1 exhaustive over the coarse
/// grammar with branch and bound, stage 2 hill climbing from the best
/// `refine_starts` stage-1 patterns, stage 2b (with `space.dwell_steps`)
/// hill climbing with the dwell moves too from the stage-2 optima; the best
/// without and the best with dwells are polished and the better wins.
/// `progress(stage, done, total)`.
pub fn search(
    problem: &Problem,
    space: &Space,
    goal: Goal,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Design, String> {
    let cutoff = match goal {
        Goal::Reach { cutoff } => cutoff,
        Goal::Budget { periods } => periods,
    };
    let incumbent = AtomicU64::new(cutoff);
    let patterns = coarse_patterns(space, problem.period_s);
    let total = patterns.len();
    let (mut scored, s1) = score_all(
        problem,
        patterns,
        goal,
        &incumbent,
        "stage 1: exhaustive over the coarse grammar",
        &|n| progress("stage 1", n, total),
    );
    let mut stages = vec![s1];
    // Hill-climbing starts: the best distinct stage-1 patterns.
    scored.retain(|s| s.score.is_finite());
    scored.sort_by(|a, b| a.score.total_cmp(&b.score));
    let starts: Vec<Scored> = scored.iter().take(space.refine_starts).cloned().collect();
    let mut pool: Vec<Scored> = scored.into_iter().take(FINAL_CHECKS).collect();
    let mut seen: Vec<Pattern> = starts.iter().map(|s| s.pattern.clone()).collect();
    // Stage 2 without dwells, then (stage 2b) the dwell moves from its
    // optima: the search with dwells finds everything the search without
    // them finds, and its result is never worse.
    let no_dwells = Space {
        dwell_steps: Vec::new(),
        ..space.clone()
    };
    let (optima, best_a, st) = climb(
        problem,
        &no_dwells,
        goal,
        &incumbent,
        starts.clone(),
        &mut seen,
        &mut pool,
        "stage 2: hill climbing (angles, rates, tilted axes)",
        &|d, t| progress("stage 2", d, t),
    );
    stages.push(st);
    let mut pool_b: Vec<Scored> = Vec::new();
    let mut best_b = None;
    if !space.dwell_steps.is_empty() {
        // From the stage-1 starts (every move at once, which can lead to
        // another optimum than stage 2's) and from the stage-2 optima (the
        // dwell moves on top of them); its own list of seen patterns.
        let mut from = starts;
        for o in optima {
            if !from.iter().any(|s| s.pattern == o.pattern) {
                from.push(o);
            }
        }
        let mut seen_b: Vec<Pattern> = from.iter().map(|s| s.pattern.clone()).collect();
        let (_, b, st) = climb(
            problem,
            space,
            goal,
            &incumbent,
            from,
            &mut seen_b,
            &mut pool_b,
            "stage 2b: hill climbing with dwells (from the stage-1 starts and the stage-2 optima)",
            &|d, t| progress("stage 2b", d, t),
        );
        stages.push(st);
        best_b = b;
    }
    // The candidates to polish, without and with dwells. Reach: the coarse
    // reach times are within the coarse steps' slack, so the best few of
    // each are re-evaluated period by period and the exact fastest wins
    // (ties: the better coarse score, then the earlier candidate).
    let mut finalists: Vec<(Scored, Option<Outcome>)> = Vec::new();
    if let Goal::Reach { .. } = goal {
        let t0 = std::time::Instant::now();
        let mut n = 0;
        for mut p in [pool, pool_b] {
            p.sort_by(|a, b| a.score.total_cmp(&b.score));
            p.dedup_by(|a, b| a.pattern == b.pattern);
            p.truncate(FINAL_CHECKS);
            let checked: Vec<(Scored, Outcome)> = p
                .into_par_iter()
                .map(|s| {
                    let o = problem.evaluate(&s.pattern, Goal::Reach { cutoff }, true, false);
                    (s, o)
                })
                .collect();
            n += checked.len();
            if let Some((s, o)) = checked
                .into_iter()
                .filter(|(_, o)| o.reach.is_some())
                .min_by_key(|(_, o)| o.reach)
            {
                if !finalists.iter().any(|f| f.0.pattern == s.pattern) {
                    finalists.push((s, Some(o)));
                }
            }
        }
        let best_reach = finalists
            .iter()
            .filter_map(|f| f.1.as_ref().and_then(|o| o.reach))
            .min();
        stages.push(StageStats {
            name: "final: the best candidates period by period".into(),
            candidates: n,
            pruned: 0,
            infeasible: 0,
            periods: 0,
            wall_s: t0.elapsed().as_secs_f64(),
            best_score: best_reach.map_or(f64::INFINITY, |r| r as f64),
        });
    } else {
        for b in [best_a, best_b].into_iter().flatten() {
            if !finalists.iter().any(|f| f.0.pattern == b.pattern) {
                finalists.push((b, None));
            }
        }
    }
    // Polish: finer angles around each finalist, every candidate period by
    // period (exact: no coarse-step error), hill climbing; the best wins
    // (ties: the one without dwells).
    let mut st = StageStats {
        name: "polish: ±15°, ±5° angles, period by period".into(),
        candidates: 0,
        pruned: 0,
        infeasible: 0,
        periods: 0,
        wall_s: 0.0,
        best_score: f64::INFINITY,
    };
    let t0 = std::time::Instant::now();
    let mut chosen: Option<(Scored, Scored, Outcome)> = None;
    for (searched, fine0) in finalists {
        let (pattern, outcome) = polish(problem, goal, cutoff, &searched, fine0, &mut st, progress);
        let score = outcome.score(goal);
        if chosen.as_ref().is_none_or(|c| score < c.2.score(goal)) {
            let best = Scored {
                pattern,
                outcome: searched.outcome.clone(),
                score: searched.score,
            };
            chosen = Some((best, searched, outcome));
        }
    }
    st.wall_s = t0.elapsed().as_secs_f64();
    st.best_score = chosen.as_ref().map_or(f64::INFINITY, |c| c.2.score(goal));
    if chosen.is_some() {
        stages.push(st);
    }
    let (best, searched, outcome) = chosen.ok_or_else(|| match goal {
        Goal::Reach { .. } => format!(
            "no path in the search space reaches every target within {} s (raise --max-duration-s or --max-rate-deg-s, or loosen the targets)",
            cutoff as f64 * problem.period_s
        ),
        Goal::Budget { .. } => "every path in the search space hits the gimbal limit within the budget".to_string(),
    })?;
    let fine = matches!(goal, Goal::Reach { .. }).then_some(outcome);
    Ok(Design {
        best,
        stages,
        fine,
        searched,
    })
}

/// Hill climbing from each of `starts` over the neighbours in `space`
/// (best neighbour first, at most 20 rounds), skipping `seen` patterns; the
/// finite candidates go to `pool`. Returns each start's local optimum, the
/// best of them, and the stage's statistics.
#[allow(clippy::too_many_arguments)]
fn climb(
    problem: &Problem,
    space: &Space,
    goal: Goal,
    incumbent: &AtomicU64,
    starts: Vec<Scored>,
    seen: &mut Vec<Pattern>,
    pool: &mut Vec<Scored>,
    name: &str,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> (Vec<Scored>, Option<Scored>, StageStats) {
    let mut best: Option<Scored> = starts.first().cloned();
    let mut stats = StageStats {
        name: name.into(),
        candidates: 0,
        pruned: 0,
        infeasible: 0,
        periods: 0,
        wall_s: 0.0,
        best_score: best.as_ref().map_or(f64::INFINITY, |b| b.score),
    };
    let t0 = std::time::Instant::now();
    let mut optima = Vec::new();
    for start in starts {
        let mut current = start;
        for _round in 0..20 {
            let cands: Vec<Pattern> = neighbours(&current.pattern, space, problem.period_s)
                .into_iter()
                .filter(|q| !seen.contains(q))
                .collect();
            if cands.is_empty() {
                break;
            }
            seen.extend(cands.iter().cloned());
            let n = cands.len();
            let done0 = stats.candidates;
            let (sc, st) = score_all(problem, cands, goal, incumbent, "", &|i| {
                progress(done0 + i, done0 + n)
            });
            stats.candidates += st.candidates;
            stats.pruned += st.pruned;
            stats.infeasible += st.infeasible;
            stats.periods += st.periods;
            pool.extend(sc.iter().filter(|s| s.score.is_finite()).cloned());
            match best_of(&sc) {
                Some(b) if b.score < current.score => current = b.clone(),
                _ => break,
            }
        }
        if best.as_ref().is_none_or(|b| current.score < b.score) {
            best = Some(current.clone());
        }
        if !optima.iter().any(|o: &Scored| o.pattern == current.pattern) {
            optima.push(current);
        }
    }
    stats.wall_s = t0.elapsed().as_secs_f64();
    stats.best_score = best.as_ref().map_or(f64::INFINITY, |b| b.score);
    (optima, best, stats)
}

/// The polish of one finalist: ±15°, ±5° angle moves, every candidate
/// period by period, hill climbing (at most 12 rounds). `fine0`: the
/// finalist's period-by-period outcome, if known.
fn polish(
    problem: &Problem,
    goal: Goal,
    cutoff: u64,
    start: &Scored,
    fine0: Option<Outcome>,
    st: &mut StageStats,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> (Pattern, Outcome) {
    let mut pattern = start.pattern.clone();
    let mut current = fine0.unwrap_or_else(|| problem.evaluate(&pattern, goal, true, false));
    let mut cur_score = current.score(goal);
    let mut seen = vec![pattern.clone()];
    for _round in 0..12 {
        let cands: Vec<Pattern> = polish_neighbours(&pattern, problem.period_s)
            .into_iter()
            .filter(|q| !seen.contains(q))
            .collect();
        if cands.is_empty() {
            break;
        }
        seen.extend(cands.iter().cloned());
        let g = match goal {
            Goal::Reach { .. } => Goal::Reach {
                cutoff: current.reach.unwrap_or(cutoff),
            },
            other => other,
        };
        let n0 = st.candidates;
        let total = n0 + cands.len();
        let done = AtomicUsize::new(0);
        let res: Vec<(Pattern, Outcome)> = cands
            .into_par_iter()
            .map(|q| {
                let o = problem.evaluate(&q, g, true, false);
                progress(
                    "polish",
                    n0 + done.fetch_add(1, Ordering::Relaxed) + 1,
                    total,
                );
                (q, o)
            })
            .collect();
        st.candidates = total;
        st.periods += res.iter().map(|r| r.1.periods).sum::<u64>();
        let winner = res
            .into_iter()
            .filter(|r| r.1.score(goal).is_finite())
            .min_by(|a, b| a.1.score(goal).total_cmp(&b.1.score(goal)));
        match winner {
            Some((q, o)) if o.score(goal) < cur_score => {
                cur_score = o.score(goal);
                pattern = q;
                current = o;
            }
            _ => break,
        }
    }
    (pattern, current)
}

/// The reference path (e.g. the paper's) as a non-repeating pattern, its
/// dwells included; the scenario's time after the path's end (the platform
/// holds still) is a dwell after the last segment.
pub fn pattern_of(s: &Scenario) -> Result<Pattern, String> {
    let mut rotations = s
        .path
        .iter()
        .map(|seg| {
            let unit = seg.axis.unit().map_err(|e| e.to_string())?;
            let name = match &seg.axis {
                Axis::Named(n) => n.to_ascii_lowercase(),
                Axis::Vector(v) => format!("[{}, {}, {}]", v[0], v[1], v[2]),
            };
            Ok(Rotation {
                axis: NamedAxis { name, unit },
                angle_deg: seg.angle_deg,
                rate_deg_s: seg.rate_deg_s,
                dwell_s: seg.dwell_s,
            })
        })
        .collect::<Result<Vec<_>, String>>()?;
    let path_s: f64 = s.path.iter().map(Segment::duration_s).sum();
    let rest = round_angle(s.timing.duration_s - path_s);
    if let Some(last) = rotations.last_mut() {
        if rest > 0.0 {
            last.dwell_s = round_angle(last.dwell_s + rest);
        }
    }
    Ok(Pattern {
        rotations,
        repeat: false,
    })
}

/// A parameter target given on the command line: a state name or a group
/// name, and σ in arcseconds.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetArg {
    /// State or group name.
    pub name: String,
    /// σ (″).
    pub arcsec: f64,
}

/// Parses `NAME=ARCSEC`.
pub fn parse_target(s: &str) -> Result<TargetArg, String> {
    let (name, v) = s
        .split_once('=')
        .ok_or_else(|| format!("target '{s}': expected NAME=ARCSEC, e.g. thgC=1.5"))?;
    let arcsec: f64 = v
        .trim()
        .parse()
        .map_err(|_| format!("target '{s}': '{v}' is not a number of arcseconds"))?;
    if !(arcsec.is_finite() && arcsec > 0.0) {
        return Err(format!("target '{s}': σ must be > 0 arcseconds"));
    }
    Ok(TargetArg {
        name: name.trim().to_string(),
        arcsec,
    })
}

/// The states of `id` a target applies to by default: the parameter block
/// (the installation errors and λ the configuration observes).
pub fn default_target_states(id: ConfigId) -> Vec<usize> {
    id.states()
        .iter()
        .enumerate()
        .filter(|(_, s)| crate::montecarlo::in_parameter_block(id, s.name, s.group))
        .map(|(i, _)| i)
        .collect()
}

/// The targets (state index, σ rad): the reference σ times `scale` on the
/// parameter block, then every `--target` (a state or a group name; a
/// group target applies to each of its states), later ones overriding.
pub fn targets(
    id: ConfigId,
    reference_sigma: &[f64],
    scale: f64,
    overrides: &[TargetArg],
) -> Result<Vec<(usize, f64)>, String> {
    let names = id.states();
    let mut t: Vec<(usize, f64)> = default_target_states(id)
        .into_iter()
        .map(|i| (i, reference_sigma[i] * scale))
        .collect();
    for o in overrides {
        let hits: Vec<usize> = names
            .iter()
            .enumerate()
            .filter(|(_, s)| s.name == o.name || s.group.as_str() == o.name)
            .map(|(i, _)| i)
            .collect();
        if hits.is_empty() {
            let list: Vec<&str> = names.iter().map(|s| s.name).collect();
            return Err(format!(
                "target '{}': {id} has no such state or group (states: {})",
                o.name,
                list.join(", ")
            ));
        }
        for i in hits {
            if names[i].group == Group::Attitude {
                return Err(format!(
                    "target '{}': attitude states vary with time and take no target",
                    o.name
                ));
            }
            t.retain(|(j, _)| *j != i);
            t.push((i, o.arcsec * ARCSEC));
        }
    }
    t.sort_by_key(|(i, _)| *i);
    Ok(t)
}

/// Information shares: per rotation of the path (in order), per state
/// group, the share of the group's information gain `Σ 1/σ²(end) −
/// 1/σ²(start)` (σ_CRLB, marginal) that the rotation contributed.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Contribution {
    /// The rotation.
    pub rotation: String,
    /// Start and end (s).
    pub t0_s: f64,
    /// End (s).
    pub t1_s: f64,
    /// `(group, share)`.
    pub shares: Vec<(&'static str, f64)>,
}

/// The groups of the targets of `problem`, in state order.
pub fn target_groups(problem: &Problem) -> Vec<Group> {
    let names = problem.config.states();
    let mut g: Vec<Group> = Vec::new();
    for &(i, _) in &problem.targets {
        if !g.contains(&names[i].group) {
            g.push(names[i].group);
        }
    }
    g
}

/// Per contiguous rotation of a recorded outcome, the information shares.
pub fn contributions(problem: &Problem, p: &Pattern, o: &Outcome) -> Vec<Contribution> {
    let names = problem.config.states();
    let groups = target_groups(problem);
    let info = |s: &[f64], g: Group| -> f64 {
        problem
            .targets
            .iter()
            .filter(|(i, _)| names[*i].group == g)
            .map(|(i, _)| 1.0 / (s[*i] * s[*i]))
            .sum()
    };
    let prior: Vec<f64> = vec![problem.sigma0; names.len()];
    let last = o.history.last().map_or(&prior, |h| &h.1);
    let total: Vec<f64> = groups
        .iter()
        .map(|&g| info(last, g) - info(&prior, g))
        .collect();
    let mut out = Vec::new();
    let mut start_sigma = prior.clone();
    let mut t0 = 0.0;
    let mut i = 0;
    while i < o.history.len() {
        let (idx, dwell) = (o.history[i].2, o.history[i].3);
        let mut j = i;
        while j + 1 < o.history.len() && o.history[j + 1].2 == idx && o.history[j + 1].3 == dwell {
            j += 1;
        }
        let (t1, ref end, _, _) = o.history[j];
        let r = &p.rotations[idx];
        let shares = groups
            .iter()
            .zip(&total)
            .map(|(&g, &tot)| (g.as_str(), (info(end, g) - info(&start_sigma, g)) / tot))
            .collect();
        out.push(Contribution {
            rotation: if dwell {
                format!("dwell (after {})", r.axis.name)
            } else {
                format!("{} @{}°/s", r.axis.name, r.rate_deg_s)
            },
            t0_s: t0,
            t1_s: t1,
            shares,
        });
        start_sigma = end.clone();
        t0 = t1;
        i = j + 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn space() -> Space {
        Space {
            axes: ["north", "up", "east"]
                .iter()
                .map(|n| NamedAxis::named(n).unwrap())
                .collect(),
            tilted: true,
            max_rate_deg_s: 0.1,
            max_duration_s: 5400.0,
            max_rotations: 2,
            refine_starts: 1,
            dwell_steps: DWELL_STEPS_S.to_vec(),
        }
    }

    #[test]
    fn patterns_are_whole_periods_and_distinct() {
        let p = coarse_patterns(&space(), 1.0);
        // 3 single rotations, then 3·2 ordered axis pairs × 4 × 4 angles.
        assert_eq!(p.len(), 3 + 6 * 16);
        for (i, a) in p.iter().enumerate() {
            assert!(a.rotations.iter().all(|r| r.periods(1.0).is_some()));
            assert!(!p[i + 1..].contains(a));
        }
        let n = neighbours(&p[5], &space(), 1.0);
        assert!(!n.is_empty());
        assert!(n.iter().all(|q| q != &p[5]));
    }

    #[test]
    fn chunks_cover_the_periods_and_cut_the_last_rotation() {
        let s = space();
        let p = Pattern {
            rotations: vec![
                Rotation::new(s.axes[0].clone(), 90.0, 0.1),
                Rotation::new(s.axes[2].clone(), 45.0, 0.05),
            ],
            repeat: true,
        };
        assert_eq!(p.cycle_periods(1.0), Some(1800));
        let segs = p.segments(2000, 1.0);
        assert_eq!(segs.len(), 3);
        assert!((segs[2].angle_deg - 20.0).abs() < 1e-9);
        let total: u64 = p.chunks(2000, 1.0, 7).iter().map(|c| c.periods).sum();
        assert_eq!(total, 2000);
        assert!(p.chunks(2000, 1.0, 7).iter().all(|c| c.periods <= 7));
    }

    /// North 90° at 1°/s, dwell 60 s, east 180° at 1°/s, dwell 180 s.
    fn with_dwells() -> Pattern {
        let s = space();
        let mut a = Rotation::new(s.axes[0].clone(), 90.0, 1.0);
        a.dwell_s = 60.0;
        let mut b = Rotation::new(s.axes[2].clone(), 180.0, 1.0);
        b.dwell_s = 180.0;
        Pattern {
            rotations: vec![a, b],
            repeat: true,
        }
    }

    #[test]
    fn a_dwell_is_whole_periods_and_divides_the_coarse_step() {
        let p = with_dwells();
        assert_eq!(p.cycle_periods(1.0), Some(90 + 60 + 180 + 180));
        let problem = Problem::new(ConfigId::M1Pa, &Scenario::paper(), 60.0);
        // gcd(90, 60, 180, 180) = 30, within 10° at 1°/s: 10.
        let k = problem.step_periods(&p, 0, false);
        assert_eq!(k, 10);
        for (n, r) in [(90, false), (60, true), (180, false), (180, true)] {
            assert_eq!(n % k, 0, "{n} periods, dwell {r}");
        }
        // Every coarse piece is k whole periods (the last one cut at the
        // requested end), rotations and dwells alike, and the dwells are
        // exactly where they belong.
        let pieces = p.chunks(1234, 1.0, k);
        assert_eq!(pieces.iter().map(|c| c.periods).sum::<u64>(), 1234);
        let (last, body) = pieces.split_last().unwrap();
        assert!(body.iter().all(|c| c.periods == k));
        assert_eq!(last.periods, 1234 % k);
        let dwell: u64 = pieces.iter().filter(|c| c.dwell).map(|c| c.periods).sum();
        // Two whole cycles (1020 s, 480 s of dwell), then 90 + 60 + 64.
        assert_eq!(dwell, 2 * 240 + 60);
        // A budget that is not a multiple of the dwells' divisor shrinks k.
        assert_eq!(problem.step_periods(&p, 1234, false), 2);
        // The segments carry the dwells; the last rotation is cut.
        let segs = p.segments(1234, 1.0);
        let ds: Vec<(f64, f64)> = segs.iter().map(|g| (g.angle_deg, g.dwell_s)).collect();
        assert_eq!(
            ds,
            [
                (90.0, 60.0),
                (180.0, 180.0),
                (90.0, 60.0),
                (180.0, 180.0),
                (90.0, 60.0),
                (64.0, 0.0)
            ]
        );
        // Cut within a dwell: the dwell is cut at a whole period.
        let segs = p.segments(90 + 30, 1.0);
        assert_eq!(segs.len(), 1);
        assert_eq!((segs[0].angle_deg, segs[0].dwell_s), (90.0, 30.0));
    }

    #[test]
    fn dwell_moves_are_proposed_in_whole_periods_only() {
        let s = space();
        let p = Pattern {
            rotations: vec![Rotation::new(s.axes[0].clone(), 90.0, 0.1)],
            repeat: true,
        };
        // The dwells of the neighbours that differ from `base` in the dwell
        // alone.
        let dwells = |q: &[Pattern], base: &Pattern| -> Vec<f64> {
            let b = &base.rotations[0];
            let mut d: Vec<f64> = q
                .iter()
                .map(|x| &x.rotations[0])
                .filter(|r| {
                    r.axis == b.axis && r.angle_deg == b.angle_deg && r.rate_deg_s == b.rate_deg_s
                })
                .map(|r| r.dwell_s)
                .collect();
            d.sort_by(f64::total_cmp);
            d
        };
        // Insert 60, 180, 600 s.
        assert_eq!(dwells(&neighbours(&p, &s, 1.0), &p), [60.0, 180.0, 600.0]);
        // Lengthen, shorten, remove.
        let mut q = p.clone();
        q.rotations[0].dwell_s = 180.0;
        let n = neighbours(&q, &s, 1.0);
        assert_eq!(dwells(&n, &q), [0.0, 120.0, 240.0, 360.0, 780.0]);
        // With 40 s periods (90° at 0.1°/s = 900 s = 22.5 periods is not
        // whole; 120° is 30 periods): 60 and 180 s are not whole periods
        // and are never proposed, 600 s (15 periods) is.
        let mut r = p.clone();
        r.rotations[0].angle_deg = 120.0;
        assert_eq!(dwells(&neighbours(&r, &s, 40.0), &r), [600.0]);
        // No dwell moves without dwell steps (--no-dwells).
        let mut none = space();
        none.dwell_steps.clear();
        assert!(dwells(&neighbours(&p, &none, 1.0), &p).is_empty());
        // A dwell that is not whole periods makes the pattern unusable.
        let mut bad = p.clone();
        bad.rotations[0].dwell_s = 0.5;
        assert!(!bad.whole(1.0));
        assert!(bad.chunks(100, 1.0, 1).is_empty());
    }

    #[test]
    fn targets_parse_and_override() {
        assert!(parse_target("thgC=1.5").is_ok());
        assert!(parse_target("thgC").is_err());
        assert!(parse_target("thgC=-1").is_err());
        assert!(parse_target("thgC=x").is_err());
        let id = ConfigId::M2Ps;
        let sigma = vec![1e-5; id.layout().n()];
        let t = targets(id, &sigma, 1.0, &[]).unwrap();
        assert_eq!(t.len(), 14);
        let t = targets(
            id,
            &sigma,
            1.0,
            &[TargetArg {
                name: "lam_y".into(),
                arcsec: 30.0,
            }],
        )
        .unwrap();
        assert_eq!(t.len(), 15);
        assert!(targets(
            id,
            &sigma,
            1.0,
            &[TargetArg {
                name: "nope".into(),
                arcsec: 1.0
            }]
        )
        .is_err());
    }
}

// ---------------------------------------------------------------------------
// The `host-sim design` subcommand.
// ---------------------------------------------------------------------------

use std::path::PathBuf;

/// Arguments of `host-sim design`.
#[derive(clap::Args, Clone, Debug)]
pub struct DesignArgs {
    /// Configuration: M1-pa, M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps (case-insensitive).
    #[arg(long, value_parser = parse_config_id)]
    pub config: ConfigId,
    /// Scenario file (TOML): site, noise, truth, timing, prior, and the
    /// reference path the targets default to; default: the paper's scenario.
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// A target σ, NAME=ARCSEC, NAME a state (thgC_x) or a group (thgC);
    /// repeatable. Default: the reference path's final σ_CRLB on every
    /// parameter the configuration observes (the parameter block).
    #[arg(long = "target", value_name = "NAME=ARCSEC", value_parser = parse_target)]
    pub targets: Vec<TargetArg>,
    /// Multiply the default targets by this factor (e.g. 2: half the accuracy).
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive)]
    pub target_scale: f64,
    /// Maximum rotation rate (°/s). At the paper's 0.1 °/s no path of the
    /// search space beats the paper's (see README).
    #[arg(long, value_name = "DEG_S", default_value_t = 1.0, value_parser = parse_positive)]
    pub max_rate_deg_s: f64,
    /// Maximum duration (s); default: the reference scenario's duration.
    #[arg(long, value_name = "S", value_parser = parse_positive)]
    pub max_duration_s: Option<f64>,
    /// Largest middle gimbal angle |β| (°) along the path (gimbal lock at 90°).
    #[arg(long, default_value_t = 60.0, value_parser = parse_positive)]
    pub max_beta_deg: f64,
    /// Allowed rotation axes (n-frame directions), comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "north,south,up,down,east,west"
    )]
    pub axes: Vec<String>,
    /// Also try axes tilted 45° between two perpendicular allowed axes (refinement).
    #[arg(long)]
    pub tilted: bool,
    /// Longest repeated pattern (rotations per cycle) of the exhaustive stage.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..=4))]
    pub max_rotations: u8,
    /// Hill-climbing starts of the refinement (the best exhaustive patterns).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(1..=32))]
    pub refine_starts: u8,
    /// Do not search dwells. By default a second hill climbing (stage 2b)
    /// also inserts, lengthens, shortens or removes a dwell of 60, 180 or
    /// 600 s after each rotation (zero commanded rate for whole periods);
    /// the better of the searches without and with dwells wins, and it
    /// costs 1–22 % more search time (README, "Dwells").
    #[arg(long)]
    pub no_dwells: bool,
    /// Instead of the shortest path to the targets: the path with the best
    /// worst-case σ/target within this duration (s).
    #[arg(long, value_name = "S", value_parser = parse_positive)]
    pub budget_s: Option<f64>,
    /// Largest rotation (°) of one coarse step of the search.
    #[arg(long, default_value_t = DEFAULT_STEP_DEG, value_parser = parse_positive)]
    pub step_deg: f64,
    // (The help as an attribute: `<config>` in a doc comment is read by
    // rustdoc as an HTML tag.)
    #[arg(
        long,
        value_name = "FILE",
        help = "Write the designed path as a scenario file (accepted by run, \
                observability and montecarlo); default: designed-<config>.toml"
    )]
    pub out: Option<PathBuf>,
    #[arg(
        long,
        value_name = "FILE",
        help = "σ(t) figure of every target parameter, designed against reference \
                path (PNG); default: designed-<config>.png"
    )]
    pub figure: Option<PathBuf>,
    /// Write the result (targets, path, σ, search statistics) as JSON.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// Write σ(t) of every target state, designed and reference, as CSV.
    #[arg(long, value_name = "PATH")]
    pub csv: Option<PathBuf>,
    /// Print which rotations excite each parameter group (information shares).
    #[arg(long)]
    pub explain: bool,
    /// Also time one bound evaluation against one estimator run of the
    /// designed path (the speed ratio).
    #[arg(long)]
    pub measure_speed: bool,
}

fn parse_config_id(s: &str) -> Result<ConfigId, String> {
    ConfigId::parse(s).ok_or_else(|| {
        let ids: Vec<&str> = ConfigId::ALL.iter().map(|c| c.as_str()).collect();
        format!(
            "unknown configuration '{s}' (expected one of {})",
            ids.join(", ")
        )
    })
}

fn parse_positive(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}' must be a positive number")),
    }
}

/// σ of every target of `problem` after the bound of `scenario`'s
/// simulated run (`host-sim observability --scenario` exactly).
fn observability_sigma(problem: &Problem, s: &Scenario) -> Result<Vec<f64>, String> {
    let sim = crate::truth::simulate(
        s,
        crate::truth::SimOptions {
            seed: 0,
            noise: false,
            earth_rate: s.site.earth_rate,
        },
    );
    let max_beta = sim
        .samples
        .iter()
        .map(|x| x.truth.gimbal.y.abs())
        .fold(0.0, f64::max);
    if max_beta > problem.max_beta {
        return Err(format!(
            "internal: the designed path reaches |β| = {:.2}° > {:.2}°",
            max_beta / DEG,
            problem.max_beta / DEG
        ));
    }
    let obs = crate::observe::analyse(problem.config, s, &sim, s.site.earth_rate, false)
        .map_err(|e| format!("observability of the designed path: {e}"))?;
    Ok(obs.states.iter().map(|x| x.sigma_crlb_rad).collect())
}

fn scenario_with(
    base: &Scenario,
    name: &str,
    path: Vec<Segment>,
    periods: u64,
) -> Result<Scenario, String> {
    let mut s = base.clone();
    s.name = name.to_string();
    s.path = path;
    s.timing.duration_s = periods as f64 * base.timing.period_s;
    s.validate()
        .map_err(|e| format!("designed scenario: {e}"))?;
    Ok(s)
}

/// The TOML text of a designed scenario, with a header saying how it was made.
pub fn scenario_toml(s: &Scenario, header: &str) -> Result<String, String> {
    let body = toml::to_string(s).map_err(|e| format!("designed scenario: {e}"))?;
    let text = format!("{header}{body}");
    // It must read back as the same scenario.
    let back = Scenario::from_toml(&text).map_err(|e| format!("designed scenario: {e}"))?;
    if &back != s {
        return Err("designed scenario: does not read back identically".into());
    }
    Ok(text)
}

/// Runs `host-sim design`.
pub fn command(args: &DesignArgs) -> Result<(), String> {
    let t_all = std::time::Instant::now();
    let base = match &args.scenario {
        Some(p) => Scenario::from_file(p).map_err(|e| e.to_string())?,
        None => Scenario::paper(),
    };
    let id = args.config;
    let period_s = base.timing.period_s;
    let reference = pattern_of(&base)?;
    let ref_periods = base.periods() as u64;
    let max_rate = args.max_rate_deg_s;
    if max_rate > 10.0 {
        return Err("--max-rate-deg-s must be ≤ 10 °/s (the scenario file's limit)".into());
    }
    if args.max_beta_deg >= 89.0 {
        return Err("--max-beta-deg must be below 89° (gimbal lock at 90°)".into());
    }
    let max_duration = args.max_duration_s.unwrap_or(base.timing.duration_s);
    let max_periods = (max_duration / period_s).floor() as u64;
    if max_periods == 0 {
        return Err("--max-duration-s is shorter than one period".into());
    }
    let limit = crate::scenario::MAX_PERIODS;
    if max_periods > limit {
        return Err(format!(
            "--max-duration-s {max_duration} is {max_periods} periods, more than the {limit} this tool simulates"
        ));
    }
    let mut axes = Vec::new();
    for a in &args.axes {
        let ax = NamedAxis::named(a.trim())?;
        if !axes.contains(&ax) {
            axes.push(ax);
        }
    }
    if axes.is_empty() {
        return Err("--axes: give at least one axis".into());
    }
    let mut problem = Problem::new(id, &base, args.max_beta_deg);
    problem.step_deg = args.step_deg;

    // The reference path, period by period: the default targets.
    let ref_out = problem.evaluate(
        &reference,
        Goal::Budget {
            periods: ref_periods,
        },
        true,
        true,
    );
    if ref_out.sigma_end.is_empty() {
        return Err(format!("{id}: the bound cannot start on this scenario"));
    }
    // The default targets: the reference scenario's σ_CRLB exactly as
    // `host-sim observability --scenario` computes it.
    let ref_sigma = {
        let mut p = problem.clone();
        p.max_beta = f64::INFINITY;
        observability_sigma(&p, &base)?
    };
    problem.targets = targets(id, &ref_sigma, args.target_scale, &args.targets)?;
    let names = id.states();

    let goal = match args.budget_s {
        Some(b) => {
            let p = (b / period_s).round() as u64;
            if p == 0 || ((b / period_s) - p as f64).abs() > 1e-9 {
                return Err(format!(
                    "--budget-s {b} must be a whole number of {period_s} s periods"
                ));
            }
            if p > limit {
                return Err(format!(
                    "--budget-s {b} is {p} periods, more than the {limit} this tool simulates"
                ));
            }
            Goal::Budget { periods: p }
        }
        None => Goal::Reach {
            cutoff: max_periods,
        },
    };
    let space = Space {
        axes,
        tilted: args.tilted,
        max_rate_deg_s: max_rate,
        max_duration_s: max_duration,
        max_rotations: usize::from(args.max_rotations),
        refine_starts: usize::from(args.refine_starts),
        dwell_steps: if args.no_dwells {
            Vec::new()
        } else {
            DWELL_STEPS_S.to_vec()
        },
    };
    eprintln!(
        "design: {id} on '{}': {} targets, max rate {max_rate} °/s, {} s at most, |β| ≤ {}°, axes {}{}, {}; {} threads",
        base.name,
        problem.targets.len(),
        max_duration,
        args.max_beta_deg,
        space.axes.iter().map(|a| a.name.as_str()).collect::<Vec<_>>().join(","),
        if space.tilted { " (+ tilted)" } else { "" },
        if space.dwell_steps.is_empty() { "no dwells" } else { "dwells" },
        rayon::current_num_threads()
    );
    let (design, mut periods, coarse_periods, coarse, coarse_change) = loop {
        let progress = crate::progress::Progress::stderr("design", 1, "candidates");
        let last = std::sync::Mutex::new(0u64);
        let design = search(&problem, &space, goal, &|st, d, t| {
            if let Ok(mut l) = last.lock() {
                *l = d as u64;
            }
            progress.stage(st, d as u64, t as u64, "")
        });
        if let Ok(l) = last.lock() {
            progress.finish(*l, "");
        }
        let design = design?;
        let best = &design.best.pattern;

        // The designed path, period by period.
        let (periods, coarse_periods) = match goal {
            Goal::Reach { .. } => {
                let r = design.fine.as_ref().and_then(|f| f.reach).ok_or_else(|| {
                    "internal: the designed path does not reach the targets period by period"
                        .to_string()
                })?;
                let c = problem.evaluate(
                    best,
                    Goal::Reach {
                        cutoff: max_periods,
                    },
                    false,
                    false,
                );
                (r, c.reach.unwrap_or(c.periods))
            }
            Goal::Budget { periods } => (periods, periods),
        };
        // Coarse steps against period by period at the coarse end.
        let coarse = problem.evaluate(
            best,
            Goal::Budget {
                periods: coarse_periods,
            },
            false,
            false,
        );
        let fine_at = problem.evaluate(
            best,
            Goal::Budget {
                periods: coarse_periods,
            },
            true,
            false,
        );
        let coarse_change = problem
            .targets
            .iter()
            .map(|&(i, _)| (coarse.sigma_end[i] / fine_at.sigma_end[i] - 1.0).abs())
            .fold(0.0, f64::max);
        // The coarse steps must leave σ within 1 % (the result is then
        // recomputed period by period anyway): otherwise search again with
        // steps half as long.
        if coarse_change <= 0.01 || problem.max_step_periods <= 1 {
            break (design, periods, coarse_periods, coarse, coarse_change);
        }
        problem.max_step_periods = (coarse.k / 2).max(1);
        problem.step_deg /= 2.0;
        eprintln!(
            "design: coarse steps of {} periods moved σ by {:.2} % (> 1 %): searching again with at most {} periods per step",
            coarse.k,
            100.0 * coarse_change,
            problem.max_step_periods
        );
    };
    let best = &design.best.pattern;

    // Check with `host-sim observability`'s computation; one more period at
    // a time in the rare case rounding of the truth simulator's increments
    // leaves a target a hair short.
    let name = format!("designed-{}", id.as_str());
    let mut designed;
    let mut check;
    let mut tries = 0;
    loop {
        designed = scenario_with(&base, &name, best.segments(periods, period_s), periods)?;
        check = observability_sigma(&problem, &designed)?;
        let met = problem.targets.iter().all(|&(i, t)| check[i] <= t);
        if met || matches!(goal, Goal::Budget { .. }) || tries >= 10 || periods >= max_periods {
            break;
        }
        periods += 1;
        tries += 1;
    }
    let met = problem.targets.iter().all(|&(i, t)| check[i] <= t);
    let fine_rec = problem.evaluate(best, Goal::Budget { periods }, true, true);
    let probe = if space.dwell_steps.is_empty() {
        None
    } else {
        dwell_probe(&problem, best, goal, max_periods, &space.dwell_steps)
    };

    // Report.
    let t_design = periods as f64 * period_s;
    let t_ref = ref_periods as f64 * period_s;
    println!(
        "Designed rolling path for {id} on '{}' (Earth rate {}, latitude {}°), limits: rate ≤ {max_rate} °/s, duration ≤ {max_duration} s, |β| ≤ {}°",
        base.name,
        if base.site.earth_rate { "on" } else { "off" },
        base.site.latitude_deg,
        args.max_beta_deg
    );
    match goal {
        Goal::Reach { .. } => {
            println!(
                "\nShortest path to every target: {t_design} s ({:.1} % of the reference path's {t_ref} s){}",
                100.0 * t_design / t_ref,
                if met { "" } else { "  — WARNING: the observability check misses a target" }
            );
            if periods >= ref_periods {
                println!("  No path of the search space reaches the targets sooner than the reference path.");
            }
        }
        Goal::Budget { periods: b } => println!(
            "\nBest worst-case σ/target within {} s: {:.3} (the reference path in its {t_ref} s: {:.3})",
            b as f64 * period_s,
            problem
                .targets
                .iter()
                .map(|&(i, t)| check[i] / t)
                .fold(0.0, f64::max),
            problem
                .targets
                .iter()
                .map(|&(i, t)| ref_sigma[i] / t)
                .fold(0.0, f64::max)
        ),
    }
    println!("  pattern: {}", best.describe());
    println!("  path ({} segments):", designed.path.len());
    for (i, s) in designed.path.iter().enumerate() {
        let ax = match &s.axis {
            Axis::Named(n) => n.clone(),
            Axis::Vector(v) => format!("[{:.4}, {:.4}, {:.4}]", v[0], v[1], v[2]),
        };
        let dwell = if s.dwell_s > 0.0 {
            format!(", then dwell {} s", s.dwell_s)
        } else {
            String::new()
        };
        println!(
            "    {:>2}. {:<24} {:>8.2}° at {} °/s ({} s){dwell}",
            i + 1,
            ax,
            s.angle_deg,
            s.rate_deg_s,
            (s.angle_deg / s.rate_deg_s).round()
        );
    }
    println!(
        "\n  {:<10} {:>12} {:>14} {:>14} {:>8}",
        "state", "target ″", "reference ″", "designed ″", "σ/target"
    );
    for &(i, t) in &problem.targets {
        println!(
            "  {:<10} {:>12.4} {:>14.4} {:>14.4} {:>8.3}",
            names[i].name,
            t / ARCSEC,
            ref_sigma[i] / ARCSEC,
            check[i] / ARCSEC,
            check[i] / t
        );
    }
    println!("  (designed σ: `host-sim observability --scenario` of the written scenario)");
    println!("\nSearch:");
    for s in &design.stages {
        println!(
            "  {}: {} candidates ({} stopped at the best time so far, {} past the gimbal limit), {} periods, {:.2} s: {:.0} candidates/min",
            s.name,
            s.candidates,
            s.pruned,
            s.infeasible,
            s.periods,
            s.wall_s,
            s.per_minute()
        );
    }
    println!(
        "  coarse steps: {} periods per step on the designed path; σ at {} s by coarse steps vs period by period: max change {:.3} % (must be ≤ 1 %)",
        coarse.k,
        coarse_periods as f64 * period_s,
        100.0 * coarse_change
    );
    if let Goal::Reach { .. } = goal {
        println!(
            "  optimality: exact over the exhaustive grammar (patterns of ≤ {} rotations about {} axes by 90°·n at {max_rate} °/s, repeated) to one coarse step; the refinement only improves on it (local optimum over 30° angles, ¾ and ½ rates{}{})",
            space.max_rotations,
            space.axes.len(),
            if space.tilted { ", tilted axes" } else { "" },
            if space.dwell_steps.is_empty() { "" } else { ", dwells of ±60, ±180, ±600 s" }
        );
    }

    if let Some(pr) = &probe {
        let what = match goal {
            Goal::Reach { .. } => "reaches every target in",
            Goal::Budget { .. } => "worst σ/target",
        };
        let unit = if matches!(goal, Goal::Reach { .. }) {
            " s"
        } else {
            ""
        };
        println!(
            "  dwells: the best single dwell move on the designed pattern, {}: {what} {}{unit} against {}{unit} without it ({:+.2} %), period by period",
            pr.pattern.describe(),
            pr.score,
            pr.base,
            100.0 * (pr.score / pr.base - 1.0)
        );
    }

    if args.explain {
        print_explain(&problem, best, &fine_rec, &reference, &ref_out);
    }

    let mut speed = serde_json::Value::Null;
    if args.measure_speed {
        // On the search's own candidate (before the polish): what every
        // candidate of the search costs.
        let p = &design.searched.pattern;
        let n = design.searched.outcome.periods.max(1);
        let sc = scenario_with(&base, "speed", p.segments(n, period_s), n)?;
        speed = measure_speed(&problem, p, n, &sc)?;
    }

    // Files.
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{name}.toml")));
    let header = format!(
        "# Designed by `host-sim design --config {id}` (rollcal): {}\n# reaches {} in {t_design} s (reference path: {t_ref} s); check with\n#   host-sim observability --scenario {}\n",
        best.describe(),
        match goal {
            Goal::Reach { .. } => "every target".to_string(),
            Goal::Budget { .. } => "the best worst-case σ/target of the budget".to_string(),
        },
        out.display()
    );
    std::fs::write(&out, scenario_toml(&designed, &header)?)
        .map_err(|e| format!("cannot write {}: {e}", out.display()))?;
    println!("\nWrote the designed scenario to {}", out.display());
    let fig = args
        .figure
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{name}.png")));
    let series: Vec<crate::plots::SigmaCurve> = problem
        .targets
        .iter()
        .map(|&(i, t)| crate::plots::SigmaCurve {
            label: names[i].name,
            target: t / ARCSEC,
            a: fine_rec
                .history
                .iter()
                .map(|h| (h.0, h.1[i] / ARCSEC))
                .collect(),
            b: ref_out
                .history
                .iter()
                .map(|h| (h.0, h.1[i] / ARCSEC))
                .collect(),
        })
        .collect();
    crate::plots::plot_sigma_comparison(
        &fig,
        &format!("{id}: σ_CRLB(t), designed path ({t_design} s) vs reference path ({t_ref} s)"),
        "designed",
        "reference",
        &series,
    )?;
    println!("Wrote the σ(t) figure to {}", fig.display());
    if let Some(p) = &args.csv {
        write_sigma_csv(p, &problem, &fine_rec, &ref_out)?;
    }
    if let Some(p) = &args.json {
        let json = serde_json::json!({
            "config": id.as_str(),
            "scenario": base.name,
            "goal": match goal { Goal::Reach{..} => "shortest".to_string(), Goal::Budget{periods} => format!("budget {} s", periods as f64 * period_s) },
            "limits": {"max_rate_deg_s": max_rate, "max_duration_s": max_duration, "max_beta_deg": args.max_beta_deg,
                "axes": space.axes.iter().map(|a| a.name.clone()).collect::<Vec<_>>(), "tilted": space.tilted,
                "dwell_steps_s": space.dwell_steps},
            "pattern": best,
            "duration_s": t_design,
            "reference_duration_s": t_ref,
            "all_targets_met": met,
            "targets": problem.targets.iter().map(|&(i, t)| serde_json::json!({
                "state": names[i].name, "target_rad": t, "reference_sigma_rad": ref_sigma[i],
                "designed_sigma_rad": check[i]})).collect::<Vec<_>>(),
            "path": designed.path,
            "stages": design.stages,
            "coarse_step_periods": coarse.k,
            "coarse_step_max_change": coarse_change,
            "speed": speed,
            "dwell_probe": probe.as_ref().map(|p| serde_json::json!({
                "pattern": p.pattern, "score": p.score, "without": p.base})),
            "wall_s": t_all.elapsed().as_secs_f64(),
        });
        crate::report::write_json(p, &json)?;
    }
    eprintln!("design: done in {:.1} s", t_all.elapsed().as_secs_f64());
    if matches!(goal, Goal::Reach { .. }) && !met {
        return Err("the designed path misses a target in the observability check".into());
    }
    Ok(())
}

/// The best single dwell move on a designed pattern, period by period.
#[derive(Clone, Debug)]
pub struct DwellProbe {
    /// The pattern with the move.
    pub pattern: Pattern,
    /// Its score: reach time (s) or worst σ/target.
    pub score: f64,
    /// The designed pattern's score, alike.
    pub base: f64,
}

/// Every dwell move of the refinement (a dwell of each step inserted,
/// lengthened, shortened or removed after each rotation) applied to `best`,
/// evaluated period by period without pruning (a reach up to twice the
/// duration limit): how much the best of them gains or loses against
/// `best` (reach time in s, or worst σ/target).
pub fn dwell_probe(
    problem: &Problem,
    best: &Pattern,
    goal: Goal,
    max_periods: u64,
    steps: &[f64],
) -> Option<DwellProbe> {
    let space = Space {
        axes: Vec::new(),
        tilted: false,
        max_rate_deg_s: 0.0,
        max_duration_s: 0.0,
        max_rotations: 0,
        refine_starts: 0,
        dwell_steps: steps.to_vec(),
    };
    // Past the duration limit too (up to twice it): how much later a dwell
    // reaches the targets, not only that it misses the limit.
    let g = match goal {
        Goal::Reach { .. } => Goal::Reach {
            cutoff: (2 * max_periods).min(crate::scenario::MAX_PERIODS),
        },
        b => b,
    };
    let value = |o: &Outcome| match g {
        Goal::Reach { .. } => o.score(g) * problem.period_s,
        Goal::Budget { .. } => o.score(g),
    };
    // Only the dwell moves: the same axes, angles and rates.
    let moves: Vec<Pattern> = neighbours(best, &space, problem.period_s)
        .into_iter()
        .filter(|q| {
            q.rotations.iter().zip(&best.rotations).all(|(a, b)| {
                a.axis == b.axis && a.angle_deg == b.angle_deg && a.rate_deg_s == b.rate_deg_s
            })
        })
        .collect();
    let base_o = problem.evaluate(best, g, true, false);
    let base = value(&base_o);
    // A dwell past the end of the evaluated path changes nothing: skipped.
    let n = base_o.periods;
    let same = best.segments(n, problem.period_s);
    moves
        .into_iter()
        .filter(|q| q.segments(n, problem.period_s) != same)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|q| {
            let score = value(&problem.evaluate(&q, g, true, false));
            DwellProbe {
                pattern: q,
                score,
                base,
            }
        })
        .collect::<Vec<_>>()
        .into_iter()
        .min_by(|a, b| a.score.total_cmp(&b.score))
}

fn write_sigma_csv(
    path: &std::path::Path,
    problem: &Problem,
    a: &Outcome,
    b: &Outcome,
) -> Result<(), String> {
    use std::fmt::Write;
    let names = problem.config.states();
    let mut text = String::from("path,t_s");
    for &(i, _) in &problem.targets {
        let _ = write!(text, ",{}_sigma_rad", names[i].name);
    }
    text.push('\n');
    for (label, o) in [("designed", a), ("reference", b)] {
        for h in &o.history {
            let _ = write!(text, "{label},{}", h.0);
            for &(i, _) in &problem.targets {
                let _ = write!(text, ",{:e}", h.1[i]);
            }
            text.push('\n');
        }
    }
    std::fs::write(path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

fn print_explain(
    problem: &Problem,
    best: &Pattern,
    fine: &Outcome,
    reference: &Pattern,
    ref_out: &Outcome,
) {
    let groups = target_groups(problem);
    for (label, p, o) in [("designed", best, fine), ("reference", reference, ref_out)] {
        println!(
            "\nWhich rotations excite which parameters, {label} path: share of each group's information gain Σ(1/σ²_end − 1/σ²_start) (σ_CRLB, marginal) per rotation"
        );
        print!("  {:<28} {:>13}", "rotation", "t [s]");
        for g in &groups {
            print!(" {:>7}", g.as_str());
        }
        println!();
        let c = contributions(problem, p, o);
        for r in &c {
            print!("  {:<28} {:>6.0}–{:<6.0}", r.rotation, r.t0_s, r.t1_s);
            for (_, s) in &r.shares {
                print!(" {:>6.1}%", 100.0 * s);
            }
            println!();
        }
        // By axis.
        let mut axes: Vec<String> = Vec::new();
        for r in &c {
            let a = r.rotation.split(' ').next().unwrap_or("").to_string();
            if !axes.contains(&a) {
                axes.push(a);
            }
        }
        println!("  by axis (share of the information; in brackets, per second relative to the whole path's average: > 1 excites the group more than the average second):");
        let total_t = c.last().map_or(1.0, |r| r.t1_s).max(1e-9);
        for a in &axes {
            let t: f64 = c
                .iter()
                .filter(|r| r.rotation.split(' ').next() == Some(a.as_str()))
                .map(|r| r.t1_s - r.t0_s)
                .sum();
            let tf = t / total_t;
            print!("  {:<28} {:>13}", a, format!("{:.0} % of t", 100.0 * tf));
            for (gi, _) in groups.iter().enumerate() {
                let s: f64 = c
                    .iter()
                    .filter(|r| r.rotation.split(' ').next() == Some(a.as_str()))
                    .map(|r| r.shares[gi].1)
                    .sum();
                print!(" {:>5.1}% ({:.2})", 100.0 * s, s / tf.max(1e-9));
            }
            println!();
        }
    }
}

/// Times one coarse bound evaluation of the designed path (mean of 20)
/// against one run of the estimator of record on it (mean of 3; simulation
/// excluded), and the full evaluations per minute on every thread.
fn measure_speed(
    problem: &Problem,
    best: &Pattern,
    periods: u64,
    designed: &Scenario,
) -> Result<serde_json::Value, String> {
    let goal = Goal::Budget { periods };
    let reps = 20;
    let t0 = std::time::Instant::now();
    let mut k = 0;
    for _ in 0..reps {
        k = problem.evaluate(best, goal, false, false).k;
    }
    let bound_s = t0.elapsed().as_secs_f64() / f64::from(reps);
    let t0 = std::time::Instant::now();
    for _ in 0..5 {
        problem.evaluate(best, goal, true, false);
    }
    let fine_s = t0.elapsed().as_secs_f64() / 5.0;
    let t0 = std::time::Instant::now();
    let sim = crate::truth::simulate(
        designed,
        crate::truth::SimOptions {
            seed: 1,
            noise: true,
            earth_rate: designed.site.earth_rate,
        },
    );
    let sim_s = t0.elapsed().as_secs_f64();
    // The mean of 3 runs: one run alone scatters by ± 30 % on a shared
    // machine.
    let est_reps = 3;
    let t0 = std::time::Instant::now();
    let mut passes = 0;
    for _ in 0..est_reps {
        passes = crate::runner::run_filter(
            problem.config,
            designed,
            &sim,
            designed.site.earth_rate,
            crate::runner::Estimator::default(),
            None,
            false,
        )
        .map_err(|e| format!("estimator run: {e}"))?
        .passes;
    }
    let est_s = t0.elapsed().as_secs_f64() / f64::from(est_reps);
    // Full (unpruned) evaluations per minute on every thread.
    let n = 4 * rayon::current_num_threads();
    let t0 = std::time::Instant::now();
    (0..n).into_par_iter().for_each(|_| {
        problem.evaluate(best, goal, false, false);
    });
    let par_s = t0.elapsed().as_secs_f64();
    let per_min = n as f64 / par_s * 60.0;
    println!(
        "\nSpeed on the search's best candidate {} ({} s): one bound evaluation {:.2} ms ({} periods per step; period by period {:.2} ms); one estimator run ({} passes) {:.1} ms, {:.0}× the bound; with the simulation of its data ({:.1} ms, as in a Monte Carlo run) {:.1} ms, {:.0}× the bound; {:.0} full candidate evaluations per minute on {} threads",
        best.describe(),
        periods as f64 * problem.period_s,
        bound_s * 1e3,
        k,
        fine_s * 1e3,
        passes,
        est_s * 1e3,
        est_s / bound_s,
        sim_s * 1e3,
        (sim_s + est_s) * 1e3,
        (sim_s + est_s) / bound_s,
        per_min,
        rayon::current_num_threads()
    );
    Ok(serde_json::json!({
        "bound_eval_s": bound_s, "bound_eval_fine_s": fine_s, "step_periods": k,
        "estimator_run_s": est_s, "estimator_passes": passes, "ratio": est_s / bound_s,
        "simulation_s": sim_s, "ratio_with_simulation": (sim_s + est_s) / bound_s,
        "full_evaluations_per_minute": per_min, "threads": rayon::current_num_threads()}))
}
