//! The dwell probe: the best single dwell move on a designed pattern,
//! evaluated period by period ([`dwell_probe`]).

use rayon::prelude::*;

use super::{neighbours, Goal, Outcome, Pattern, Problem, Space};

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
            cutoff: (2 * max_periods).min(crate::sim::scenario::MAX_PERIODS),
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
