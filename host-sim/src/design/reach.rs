//! The targets out of reach within the limits, backed by the bound: for
//! each target the designed path misses, the σ it reaches, when the
//! designed pattern repeated past the duration limit reaches it, and which
//! faster rate of the same pattern reaches it within the limit
//! ([`out_of_reach`]).

use super::{Goal, Pattern, Problem};

/// Rates (°/s) tried for a missed target: the designed pattern's angles at
/// these rates, each above the search's limit, up to the scenario file's
/// 10 °/s.
pub const FASTER_RATES_DEG_S: [f64; 6] = [1.25, 2.0, 2.5, 4.0, 5.0, 10.0];

/// One target the designed path misses.
#[derive(Clone, Debug, serde::Serialize)]
pub struct OutOfReach {
    /// State index.
    pub state: usize,
    /// Target σ (internal units).
    pub target: f64,
    /// σ_CRLB reached on the designed path (internal units).
    pub sigma: f64,
    /// The designed pattern repeated past the duration limit: the time (s)
    /// at which the bound first meets the target, if within `horizon_s`.
    pub time_s: Option<f64>,
    /// The horizon searched (s): the tool's limit, or the gimbal limit of the
    /// repeated pattern.
    pub horizon_s: f64,
    /// The slowest of [`FASTER_RATES_DEG_S`] at which the designed pattern
    /// (its angles, every rotation at that rate) meets the target within the
    /// duration limit, and its σ there.
    pub rate: Option<(f64, f64)>,
}

/// The targets of `problem` that `sigma` (the designed path's σ_CRLB)
/// misses, each with what reaches it on the bound: the designed pattern
/// `best` repeated up to `horizon` periods (coarse steps; the time of the
/// first step that meets it), and `best` at each faster rate within
/// `max_periods` (period by period).
pub fn out_of_reach(
    problem: &Problem,
    best: &Pattern,
    sigma: &[f64],
    max_periods: u64,
    max_rate_deg_s: f64,
    horizon: u64,
) -> Vec<OutOfReach> {
    let missed: Vec<(usize, f64)> = problem
        .targets
        .iter()
        .copied()
        .filter(|&(i, t)| sigma.get(i).is_none_or(|s| *s > t))
        .collect();
    if missed.is_empty() {
        return Vec::new();
    }
    let dt = problem.period_s;
    // The designed pattern repeated past the limit, σ after every step.
    let mut p = best.clone();
    p.repeat = true;
    let long = problem.evaluate(&p, Goal::Budget { periods: horizon }, false, true);
    let horizon_s = long.periods as f64 * dt;
    // The same angles at faster rates, within the duration limit.
    let faster: Vec<(f64, Vec<f64>)> = FASTER_RATES_DEG_S
        .iter()
        .filter(|&&r| r > max_rate_deg_s)
        .filter_map(|&r| {
            let mut q = p.clone();
            for rot in &mut q.rotations {
                if rot.angle_deg > 0.0 {
                    rot.rate_deg_s = r;
                }
            }
            if !q.whole(dt) {
                return None;
            }
            let o = problem.evaluate(
                &q,
                Goal::Budget {
                    periods: max_periods,
                },
                true,
                false,
            );
            (o.gimbal_lock.is_none() && !o.sigma_end.is_empty()).then_some((r, o.sigma_end))
        })
        .collect();
    missed
        .into_iter()
        .map(|(i, t)| OutOfReach {
            state: i,
            target: t,
            sigma: sigma.get(i).copied().unwrap_or(f64::INFINITY),
            time_s: long
                .history
                .iter()
                .find(|h| h.1.get(i).is_some_and(|s| *s <= t))
                .map(|h| h.0),
            horizon_s,
            rate: faster
                .iter()
                .find(|(_, s)| s.get(i).is_some_and(|v| *v <= t))
                .map(|(r, s)| (*r, s[i])),
        })
        .collect()
}
