//! The search: candidates scored in parallel with branch and bound
//! ([`score_all`]), stage 1 exhaustive over the coarse grammar, the hill
//! climbing of stages 2 and 2b, the period-by-period finalists and the
//! polish ([`search`]), and its result types ([`Scored`], [`StageStats`],
//! [`Design`]).

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

use rayon::prelude::*;

use super::{
    coarse_patterns, neighbours, polish_neighbours, DesignError, Goal, Outcome, Pattern, Problem,
    Space, FINAL_CHECKS,
};

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

/// Candidates scored between two reads of the shared bound (see
/// [`score_all`]): a fixed number, not one per thread, so that the answer
/// is the same on every machine.
const BOUND_CHUNK: usize = 32;

/// Scores `patterns` in parallel (rayon). For `Goal::Reach` the candidates
/// share the best reach time found so far and stop there (branch and
/// bound: a candidate still short of its targets at that time cannot win).
/// The bound is read at the start of each chunk of `BOUND_CHUNK` (32)
/// candidates and lowered after it, so which candidates are cut short does
/// not depend on the scheduling (a bound read while other threads run
/// would make the pool of candidates, and so the design, vary from run to
/// run). Ties go to the earlier candidate. `progress(done)` is called after
/// every candidate.
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
    let mut scored: Vec<Scored> = Vec::with_capacity(patterns.len());
    for chunk in patterns.chunks(BOUND_CHUNK) {
        let g = match goal {
            Goal::Reach { .. } => Goal::Reach {
                cutoff: incumbent.load(Ordering::Relaxed),
            },
            b => b,
        };
        let part: Vec<Scored> = chunk
            .par_iter()
            .map(|pattern| {
                let outcome = problem.evaluate(pattern, g, false, false);
                periods.fetch_add(outcome.periods, Ordering::Relaxed);
                progress(done.fetch_add(1, Ordering::Relaxed) + 1);
                let score = outcome.score(goal);
                Scored {
                    pattern: pattern.clone(),
                    outcome,
                    score,
                }
            })
            .collect();
        for r in part.iter().filter_map(|s| s.outcome.reach) {
            incumbent.fetch_min(r, Ordering::Relaxed);
        }
        scored.extend(part);
    }
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

/// Stage 1 of a shortest-path search that found no path: every candidate
/// of the coarse grammar evaluated to the cutoff (or its gimbal limit),
/// kept for the budget search over the same limit that stands in
/// ([`search_reusing`]), which would evaluate them again to the same end.
#[derive(Clone, Debug)]
pub struct UnreachedStageOne {
    /// The search space's patterns, scored (every one, in order).
    scored: Vec<Scored>,
    /// The stage's statistics.
    stats: StageStats,
    /// What the outcomes depend on besides the pattern: the cutoff
    /// (periods), the problem's largest coarse step (°, periods).
    key: (u64, f64, u64),
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
) -> Result<Design, DesignError> {
    search_reusing(problem, space, goal, &mut None, progress)
}

/// [`search`], keeping stage 1 of a shortest-path search that finds no
/// path in `unreached`, and, for a budget of the same periods as that
/// search's cutoff on the same coarse steps, scoring those candidates'
/// outcomes for the budget instead of evaluating them again. No candidate
/// of such a stage 1 met the targets, so each ran to the cutoff or to its
/// gimbal limit, exactly as the budget runs it when its coarse step is the
/// same (a candidate whose step the budget's length changes is evaluated
/// again): the result is the budget search's own.
pub fn search_reusing(
    problem: &Problem,
    space: &Space,
    goal: Goal,
    unreached: &mut Option<UnreachedStageOne>,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Design, DesignError> {
    let cutoff = match goal {
        Goal::Reach { cutoff } => cutoff,
        Goal::Budget { periods } => periods,
    };
    let key = (cutoff, problem.step_deg, problem.max_step_periods);
    let incumbent = AtomicU64::new(cutoff);
    let kept = match (goal, unreached.take()) {
        (Goal::Budget { .. }, Some(u)) if u.key == key => Some(u),
        _ => None,
    };
    let (all, s1) = match kept {
        Some(u) => rescored(problem, goal, u),
        None => stage_one_scored(problem, space, goal, &incumbent, progress),
    };
    if matches!(goal, Goal::Reach { .. }) && all.iter().all(|s| s.outcome.reach.is_none()) {
        *unreached = Some(UnreachedStageOne {
            scored: all.clone(),
            stats: s1.clone(),
            key,
        });
    }
    let (starts, pool) = stage_one_starts(space, all);
    let mut stages = vec![s1];
    let climbed = climb_stages(
        problem,
        space,
        goal,
        &incumbent,
        starts,
        pool,
        &mut stages,
        progress,
    );
    // The candidates to polish, without and with dwells. Reach: the coarse
    // reach times are within the coarse steps' slack, so the best few of
    // each are re-evaluated period by period and the exact fastest wins
    // (ties: the better coarse score, then the earlier candidate).
    let mut finalists: Vec<(Scored, Option<Outcome>)> = Vec::new();
    if let Goal::Reach { .. } = goal {
        let (f, st) = reach_finalists(problem, cutoff, [climbed.pool, climbed.pool_b]);
        finalists = f;
        stages.push(st);
    } else {
        for b in [climbed.best_a, climbed.best_b].into_iter().flatten() {
            if !finalists.iter().any(|f| f.0.pattern == b.pattern) {
                finalists.push((b, None));
            }
        }
    }
    let chosen = polish_finalists(problem, goal, cutoff, finalists, &mut stages, progress);
    let (best, searched, outcome) = chosen.ok_or(match goal {
        Goal::Reach { .. } => DesignError::NoPathReaches {
            within_s: cutoff as f64 * problem.period_s,
        },
        Goal::Budget { .. } => DesignError::GimbalLimitEverywhere,
    })?;
    let fine = matches!(goal, Goal::Reach { .. }).then_some(outcome);
    Ok(Design {
        best,
        stages,
        fine,
        searched,
    })
}

/// Stage 1: every pattern of the coarse grammar scored with branch and
/// bound. Returns every candidate scored, in order, and the stage's
/// statistics.
fn stage_one_scored(
    problem: &Problem,
    space: &Space,
    goal: Goal,
    incumbent: &AtomicU64,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> (Vec<Scored>, StageStats) {
    let patterns = coarse_patterns(space, problem.period_s);
    let total = patterns.len();
    score_all(
        problem,
        patterns,
        goal,
        incumbent,
        "stage 1: exhaustive over the coarse grammar",
        &|n| progress("stage 1", n, total),
    )
}

/// Stage 1 of a budget from the kept stage 1 of a shortest-path search
/// that found no path ([`search_reusing`]): each outcome scored for the
/// budget, evaluated again where the budget's length changes its coarse
/// step. The statistics are the kept stage's (its candidates, periods and
/// wall time: they were evaluated once), the re-evaluated ones added.
fn rescored(problem: &Problem, goal: Goal, u: UnreachedStageOne) -> (Vec<Scored>, StageStats) {
    let extra = match goal {
        Goal::Budget { periods } => periods,
        Goal::Reach { .. } => 0,
    };
    let t0 = std::time::Instant::now();
    let mut stats = u.stats;
    let again = AtomicU64::new(0);
    let scored: Vec<Scored> = u
        .scored
        .into_par_iter()
        .map(|s| {
            let outcome = if problem.step_periods(&s.pattern, extra, false) == s.outcome.k {
                s.outcome
            } else {
                let o = problem.evaluate(&s.pattern, goal, false, false);
                again.fetch_add(o.periods, Ordering::Relaxed);
                o
            };
            let score = outcome.score(goal);
            Scored {
                pattern: s.pattern,
                outcome,
                score,
            }
        })
        .collect();
    stats.name = "stage 1: exhaustive over the coarse grammar (the shortest-path search's candidates, scored for the budget)".into();
    stats.periods += again.load(Ordering::Relaxed);
    stats.wall_s += t0.elapsed().as_secs_f64();
    stats.pruned = 0;
    stats.infeasible = scored
        .iter()
        .filter(|s| s.outcome.gimbal_lock.is_some())
        .count();
    stats.best_score = scored.iter().map(|s| s.score).fold(f64::INFINITY, f64::min);
    (scored, stats)
}

/// The hill-climbing starts of stage 1's scored candidates (the best
/// distinct `refine_starts` patterns) and the pool of the best
/// [`FINAL_CHECKS`].
fn stage_one_starts(space: &Space, mut scored: Vec<Scored>) -> (Vec<Scored>, Vec<Scored>) {
    scored.retain(|s| s.score.is_finite());
    scored.sort_by(|a, b| a.score.total_cmp(&b.score));
    let starts: Vec<Scored> = scored.iter().take(space.refine_starts).cloned().collect();
    let pool: Vec<Scored> = scored.into_iter().take(FINAL_CHECKS).collect();
    (starts, pool)
}

/// What the hill climbing of stages 2 and 2b leaves: the finite candidates
/// of each (`pool`: stage 1 and 2, `pool_b`: stage 2b) and the best of each.
struct Climbed {
    pool: Vec<Scored>,
    pool_b: Vec<Scored>,
    best_a: Option<Scored>,
    best_b: Option<Scored>,
}

/// Stage 2 (without dwells) from the stage-1 `starts`, then, with dwell
/// steps, stage 2b from the starts and the stage-2 optima; their
/// statistics are appended to `stages`.
#[allow(clippy::too_many_arguments)]
fn climb_stages(
    problem: &Problem,
    space: &Space,
    goal: Goal,
    incumbent: &AtomicU64,
    starts: Vec<Scored>,
    mut pool: Vec<Scored>,
    stages: &mut Vec<StageStats>,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Climbed {
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
        incumbent,
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
            incumbent,
            from,
            &mut seen_b,
            &mut pool_b,
            "stage 2b: hill climbing with dwells (from the stage-1 starts and the stage-2 optima)",
            &|d, t| progress("stage 2b", d, t),
        );
        stages.push(st);
        best_b = b;
    }
    Climbed {
        pool,
        pool_b,
        best_a,
        best_b,
    }
}

/// Reach: the best [`FINAL_CHECKS`] of each pool re-evaluated period by
/// period; the exact fastest of each is a finalist. Returns the finalists
/// and the stage's statistics.
fn reach_finalists(
    problem: &Problem,
    cutoff: u64,
    pools: [Vec<Scored>; 2],
) -> (Vec<(Scored, Option<Outcome>)>, StageStats) {
    let mut finalists: Vec<(Scored, Option<Outcome>)> = Vec::new();
    let t0 = std::time::Instant::now();
    let mut n = 0;
    for mut p in pools {
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
    let st = StageStats {
        name: "final: the best candidates period by period".into(),
        candidates: n,
        pruned: 0,
        infeasible: 0,
        periods: 0,
        wall_s: t0.elapsed().as_secs_f64(),
        best_score: best_reach.map_or(f64::INFINITY, |r| r as f64),
    };
    (finalists, st)
}

/// Polish: finer angles around each finalist, every candidate period by
/// period (exact: no coarse-step error), hill climbing; the best wins
/// (ties: the one without dwells). Returns (the polished best with its
/// search outcome, the finalist it came from, its period-by-period
/// outcome); the polish's statistics are appended to `stages`.
fn polish_finalists(
    problem: &Problem,
    goal: Goal,
    cutoff: u64,
    finalists: Vec<(Scored, Option<Outcome>)>,
    stages: &mut Vec<StageStats>,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Option<(Scored, Scored, Outcome)> {
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
    chosen
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
