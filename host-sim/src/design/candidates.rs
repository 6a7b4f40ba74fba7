//! The candidates of the search: its [`Space`] (axes, rates, limits,
//! dwell steps), every stage-1 pattern of the coarse grammar
//! ([`coarse_patterns`]) and the moves of the refinement ([`neighbours`])
//! and of the polish ([`polish_neighbours`]).

use super::pattern::round_angle;
use super::{NamedAxis, Pattern, Rotation, COARSE_ANGLES, FINE_ANGLE_DEG};

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
