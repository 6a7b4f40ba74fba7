//! One design from start to end ([`run`]): the limits and targets of a
//! [`Request`] (those below the floor the wandering errors leave set
//! apart), the reference path's bound, the search (repeated with
//! shorter coarse steps until they hold, and for the full model the budget
//! search when no path reaches every target), the check of the written
//! scenario, the dwell probe and the targets out of reach. It prints
//! nothing: progress and notes go to an [`Observer`], the result is a
//! [`Run`] for `output::design` to print and write.

use std::fmt;

use rollcal::models::{ConfigId, ErrorModel};

use super::{
    check_designed, coarse_check, dwell_probe, measure_speed, observability_sigma, out_of_reach,
    pattern_of, scenario_with, search_reusing, split_below_floor, state_floors, targets_with,
    BelowFloor, Checked, CoarseCheck, Design, DesignError, DwellProbe, Goal, InstrumentTargets,
    NamedAxis, OutOfReach, Outcome, Pattern, Problem, Space, Speed, StateFloor, TargetArg,
    UnreachedStageOne, DWELL_STEPS_S,
};
use crate::sim::scenario::{Scenario, MAX_PERIODS};

/// How far past the duration limit (× the limit) the designed pattern is
/// repeated to tell when a target out of reach is met.
pub const OUT_OF_REACH_HORIZON: u64 = 10;

/// What a design is asked: the options of `host-sim design`, parsed.
#[derive(Clone, Debug, PartialEq)]
pub struct Request {
    /// Configuration.
    pub config: ConfigId,
    /// Error model of the bound.
    pub errors: ErrorModel,
    /// `--target NAME=VALUE` overrides.
    pub targets: Vec<TargetArg>,
    /// Factor on the default targets.
    pub target_scale: f64,
    /// Largest rotation rate (°/s).
    pub max_rate_deg_s: f64,
    /// Largest duration (s); the reference path's when `None`.
    pub max_duration_s: Option<f64>,
    /// Largest middle gimbal angle |β| (°).
    pub max_beta_deg: f64,
    /// Allowed rotation axes (names).
    pub axes: Vec<String>,
    /// Also axes tilted 45° between two allowed ones.
    pub tilted: bool,
    /// Longest pattern of the exhaustive stage.
    pub max_rotations: u8,
    /// Hill-climbing starts of the refinement.
    pub refine_starts: u8,
    /// Whether dwells are searched.
    pub dwells: bool,
    /// The best path within this duration (s) instead of the shortest.
    pub budget_s: Option<f64>,
    /// Largest rotation of one coarse step (°).
    pub step_deg: f64,
}

/// What a design reports while it runs: the search's progress and notes.
pub trait Observer: Sync {
    /// A search starts (there may be more than one).
    fn search_started(&self) {}
    /// Stage `stage` of the search has done `done` of `total` candidates.
    fn stage(&self, _stage: &str, _done: usize, _total: usize) {}
    /// The search started last has ended.
    fn search_finished(&self) {}
    /// Something the user should know of the run.
    fn note(&self, _note: &Note) {}
}

/// An observer that keeps nothing.
pub struct Silent;

impl Observer for Silent {}

/// A note of a running design ([`Observer::note`]); its `Display` is the
/// line `host-sim design` prints on stderr.
#[derive(Clone, Debug, PartialEq)]
pub enum Note {
    /// The search starts: what is searched, within which limits.
    Searching {
        /// Configuration.
        config: ConfigId,
        /// Whether the bound is the full model's.
        full: bool,
        /// The reference scenario's name.
        scenario: String,
        /// Number of targets searched for.
        targets: usize,
        /// Number of targets below their floor (not searched for).
        below_floor: usize,
        /// Largest rate (°/s).
        max_rate: f64,
        /// Largest duration (s).
        max_duration: f64,
        /// Largest |β| (°).
        max_beta_deg: f64,
        /// The axes' names.
        axes: Vec<String>,
        /// Tilted axes too.
        tilted: bool,
        /// Dwells searched.
        dwells: bool,
        /// Worker threads.
        threads: usize,
    },
    /// The coarse steps moved σ by more than 1 %: searching again with
    /// shorter ones.
    Refining {
        /// Periods per coarse step of the last search.
        periods_per_step: u64,
        /// The relative change they made.
        change: f64,
        /// Periods per step of the next search.
        next: u64,
    },
    /// No path reaches every target: the budget search instead.
    Fallback {
        /// The duration limit (s).
        within_s: f64,
    },
}

impl fmt::Display for Note {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Note::Searching {
                config,
                full,
                scenario,
                targets,
                below_floor,
                max_rate,
                max_duration,
                max_beta_deg,
                axes,
                tilted,
                dwells,
                threads,
            } => write!(
                f,
                "design: {config}{} on '{scenario}': {targets} targets{}, max rate {max_rate} °/s, {max_duration} s at most, |β| ≤ {max_beta_deg}°, axes {}{}, {}; {threads} threads",
                if *full { " (full model)" } else { "" },
                if *below_floor > 0 {
                    format!(" ({below_floor} more below the floor the wandering errors leave: not searched for)")
                } else {
                    String::new()
                },
                axes.join(","),
                if *tilted { " (+ tilted)" } else { "" },
                if *dwells { "dwells" } else { "no dwells" },
            ),
            Note::Refining {
                periods_per_step,
                change,
                next,
            } => write!(
                f,
                "design: coarse steps of {periods_per_step} periods moved σ by {:.2} % (> 1 %): searching again with at most {next} periods per step",
                100.0 * change
            ),
            Note::Fallback { within_s } => write!(
                f,
                "design: no path of the search space reaches every target within {within_s} s; searching the best worst-case σ/target within it"
            ),
        }
    }
}

/// The limits of a request on its reference scenario, checked.
#[derive(Clone, Debug)]
struct Limits {
    max_rate: f64,
    max_duration: f64,
    max_periods: u64,
    axes: Vec<NamedAxis>,
}

/// The limits of `req` on `base`, checked.
fn limits(req: &Request, base: &Scenario) -> Result<Limits, DesignError> {
    let limit = |m: String| Err(DesignError::Limit(m));
    let period_s = base.timing.period_s;
    let max_rate = req.max_rate_deg_s;
    if max_rate > 10.0 {
        return limit("--max-rate-deg-s must be ≤ 10 °/s (the scenario file's limit)".into());
    }
    if req.max_beta_deg >= 89.0 {
        return limit("--max-beta-deg must be below 89° (gimbal lock at 90°)".into());
    }
    let max_duration = req.max_duration_s.unwrap_or(base.timing.duration_s);
    let max_periods = (max_duration / period_s).floor() as u64;
    if max_periods == 0 {
        return limit("--max-duration-s is shorter than one period".into());
    }
    if max_periods > MAX_PERIODS {
        return limit(format!(
            "--max-duration-s {max_duration} is {max_periods} periods, more than the {MAX_PERIODS} this tool simulates"
        ));
    }
    let mut axes = Vec::new();
    for a in &req.axes {
        let ax = NamedAxis::named(a.trim())?;
        if !axes.contains(&ax) {
            axes.push(ax);
        }
    }
    if axes.is_empty() {
        return limit("--axes: give at least one axis".into());
    }
    Ok(Limits {
        max_rate,
        max_duration,
        max_periods,
        axes,
    })
}

/// The goal of `req`: the shortest path (within `max_periods`), or the
/// best within `--budget-s`.
fn goal_of(req: &Request, period_s: f64, max_periods: u64) -> Result<Goal, DesignError> {
    let Some(b) = req.budget_s else {
        return Ok(Goal::Reach {
            cutoff: max_periods,
        });
    };
    let p = (b / period_s).round() as u64;
    if p == 0 || ((b / period_s) - p as f64).abs() > 1e-9 {
        return Err(DesignError::Limit(format!(
            "--budget-s {b} must be a whole number of {period_s} s periods"
        )));
    }
    if p > MAX_PERIODS {
        return Err(DesignError::Limit(format!(
            "--budget-s {b} is {p} periods, more than the {MAX_PERIODS} this tool simulates"
        )));
    }
    Ok(Goal::Budget { periods: p })
}

/// The search space of `req` over `axes`.
fn space_of(req: &Request, l: &Limits) -> Space {
    Space {
        axes: l.axes.clone(),
        tilted: req.tilted,
        max_rate_deg_s: l.max_rate,
        max_duration_s: l.max_duration,
        max_rotations: usize::from(req.max_rotations),
        refine_starts: usize::from(req.refine_starts),
        dwell_steps: if req.dwells {
            DWELL_STEPS_S.to_vec()
        } else {
            Vec::new()
        },
    }
}

/// The search, its progress to `obs`, repeated with coarse steps half as
/// long while they move σ by more than 1 % (the result is then recomputed
/// period by period anyway). `kept`: stage 1 of a shortest-path search
/// that found no path, kept for the budget search ([`search_reusing`]).
fn search_until_fine(
    problem: &mut Problem,
    space: &Space,
    goal: Goal,
    max_periods: u64,
    kept: &mut Option<UnreachedStageOne>,
    obs: &dyn Observer,
) -> Result<(Design, CoarseCheck), DesignError> {
    loop {
        obs.search_started();
        let design = search_reusing(problem, space, goal, kept, &|st, d, t| obs.stage(st, d, t));
        obs.search_finished();
        let design = design?;
        let cc = coarse_check(problem, &design, goal, max_periods)?;
        if cc.change <= 0.01 || problem.max_step_periods <= 1 {
            return Ok((design, cc));
        }
        problem.max_step_periods = (cc.coarse.k / 2).max(1);
        problem.step_deg /= 2.0;
        obs.note(&Note::Refining {
            periods_per_step: cc.coarse.k,
            change: cc.change,
            next: problem.max_step_periods,
        });
    }
}

/// The reference path's bound and the floors of the targets
/// ([`reference_targets`]).
struct Reference {
    /// The reference path period by period (recorded).
    out: Outcome,
    /// σ_CRLB of every state at its end.
    sigma: Vec<f64>,
    /// The floors of the wandering terms' states.
    floors: Vec<StateFloor>,
    /// The targets below their floor (not on `problem`).
    below_floor: Vec<BelowFloor>,
}

/// The reference path period by period, and the default targets: the
/// reference scenario's σ_CRLB exactly as `host-sim observability
/// --scenario` computes it, scaled and overridden by `req`; those above
/// their floor (every target without a wander) set on `problem`, those
/// below it returned apart.
fn reference_targets(
    req: &Request,
    base: &Scenario,
    problem: &mut Problem,
    reference: &Pattern,
) -> Result<Reference, DesignError> {
    let id = req.config;
    let ref_out = problem.evaluate(
        reference,
        Goal::Budget {
            periods: base.periods() as u64,
        },
        true,
        true,
    );
    if ref_out.sigma_end.is_empty() {
        return Err(DesignError::Limit(format!(
            "{id}: the bound cannot start on this scenario"
        )));
    }
    // The default targets: the reference scenario's σ_CRLB exactly as
    // `host-sim observability --scenario` computes it, with the installation
    // model (with `--errors full` too: the installation errors at the
    // reference path's σ, as the installation model reaches them there).
    let sigma_of = |problem: &Problem, errors: ErrorModel| {
        let mut p = problem.clone();
        p.max_beta = f64::INFINITY;
        if p.errors != errors {
            p = Problem::with_errors(id, errors, base, f64::INFINITY);
        }
        observability_sigma(&p, base)
    };
    let inst_sigma = sigma_of(problem, ErrorModel::Installation)?;
    let targets = targets_with(
        id,
        problem.errors,
        &inst_sigma,
        &InstrumentTargets::PSINS,
        req.target_scale,
        &req.targets,
    )?;
    // A target below the floor its wandering term leaves is out of reach
    // of every path: set apart, not searched for.
    let floors = state_floors(id, problem.errors, base);
    let (reachable, below_floor) = split_below_floor(targets, &floors);
    problem.targets = reachable;
    // The reference σ shown: the bound of the model searched.
    let ref_sigma = match problem.errors {
        ErrorModel::Installation => inst_sigma,
        errors => sigma_of(problem, errors)?,
    };
    Ok(Reference {
        out: ref_out,
        sigma: ref_sigma,
        floors,
        below_floor,
    })
}

/// The search towards `goal`; for the full model, when no path reaches
/// every target, the budget search within the duration limit instead
/// (`true` returned; its stage 1 is the shortest-path search's, scored for
/// the budget), whose best path, when it meets every target after
/// all, is cut period by period where it does (the goal returned is then
/// a reach again: a path to every target, not the shortest).
fn search_with_fallback(
    req: &Request,
    problem: &mut Problem,
    space: &Space,
    goal: Goal,
    max_periods: u64,
    obs: &dyn Observer,
) -> Result<(Design, CoarseCheck, Goal, bool), DesignError> {
    let mut kept = None;
    let within_s = match search_until_fine(problem, space, goal, max_periods, &mut kept, obs) {
        Err(DesignError::NoPathReaches { within_s })
            if problem.errors == ErrorModel::Full && req.budget_s.is_none() =>
        {
            within_s
        }
        r => return r.map(|(d, c)| (d, c, goal, false)),
    };
    obs.note(&Note::Fallback { within_s });
    let budget = Goal::Budget {
        periods: max_periods,
    };
    let (design, mut coarse) =
        search_until_fine(problem, space, budget, max_periods, &mut kept, obs)?;
    let reach = Goal::Reach {
        cutoff: max_periods,
    };
    match problem
        .evaluate(&design.best.pattern, reach, true, false)
        .reach
    {
        Some(periods) => {
            coarse.periods = periods;
            Ok((design, coarse, reach, true))
        }
        None => Ok((design, coarse, budget, true)),
    }
}

/// A finished design: everything its printed result and files show.
#[derive(Clone, Debug)]
pub struct Run {
    /// What was asked.
    pub request: Request,
    /// The reference scenario (site, noise, truth, timing, prior, path).
    pub base: Scenario,
    /// The reference path as a pattern.
    pub reference: Pattern,
    /// The reference path period by period (recorded).
    pub ref_out: Outcome,
    /// σ_CRLB of every state at the reference path's end (rad).
    pub ref_sigma: Vec<f64>,
    /// The problem searched (targets set).
    pub problem: Problem,
    /// The search space.
    pub space: Space,
    /// The goal of the final search.
    pub goal: Goal,
    /// The search's result.
    pub design: Design,
    /// The coarse steps against period by period.
    pub coarse: CoarseCheck,
    /// The written scenario, checked.
    pub checked: Checked,
    /// The designed path period by period (recorded).
    pub fine: Outcome,
    /// The best single dwell move, when dwells are searched.
    pub probe: Option<DwellProbe>,
    /// The full model's targets out of reach within the limits (above
    /// their floor, missed by the designed path).
    pub unreached: Vec<OutOfReach>,
    /// The floor of every state of a wandering term (the full model with
    /// a wander; else empty).
    pub floors: Vec<StateFloor>,
    /// The targets below their floor: out of reach of every path, not
    /// searched for (not on [`Run::problem`]).
    pub below_floor: Vec<BelowFloor>,
    /// The shortest-path search found no path reaching every target; the
    /// result is the budget search's within the duration limit, or, when
    /// its best path meets every target ([`Run::goal`] then
    /// [`Goal::Reach`]), that path cut where it meets them (a path to every
    /// target, not the shortest).
    pub fallback: bool,
    /// Largest rotation rate (°/s).
    pub max_rate: f64,
    /// Largest duration (s).
    pub max_duration: f64,
    /// Largest duration (periods).
    pub max_periods: u64,
    /// The written scenario's name (`designed-<config>`).
    pub name: String,
}

impl Run {
    /// The designed pattern.
    pub fn best(&self) -> &Pattern {
        &self.design.best.pattern
    }

    /// The filter period (s).
    pub fn period_s(&self) -> f64 {
        self.base.timing.period_s
    }

    /// The designed path's length (periods).
    pub fn periods(&self) -> u64 {
        self.checked.periods
    }

    /// The reference path's length (periods).
    pub fn ref_periods(&self) -> u64 {
        self.base.periods() as u64
    }

    /// The designed path's length (s).
    pub fn t_design(&self) -> f64 {
        self.periods() as f64 * self.period_s()
    }

    /// The reference path's length (s).
    pub fn t_ref(&self) -> f64 {
        self.ref_periods() as f64 * self.period_s()
    }

    /// Every target asked for, `(state, σ)` by state: those searched for
    /// ([`Run::problem`]) and those below their floor.
    pub fn all_targets(&self) -> Vec<(usize, f64)> {
        let mut t = self.problem.targets.clone();
        t.extend(self.below_floor.iter().map(|b| (b.state, b.target)));
        t.sort_by_key(|(i, _)| *i);
        t
    }

    /// What the targets searched for are, in words: "every target", or,
    /// when some are below their floor, "every target above its floor".
    pub fn every_target(&self) -> &'static str {
        if self.below_floor.is_empty() {
            "every target"
        } else {
            "every target above its floor"
        }
    }

    /// The speed of one bound evaluation against one estimator run on the
    /// search's own candidate (before the polish): what every candidate
    /// of the search costs (`--measure-speed`). Returns the candidate, its
    /// periods and the measurement.
    pub fn speed(&self) -> Result<(&Pattern, u64, Speed), DesignError> {
        let p = &self.design.searched.pattern;
        let n = self.design.searched.outcome.periods.max(1);
        let sc = scenario_with(&self.base, "speed", p.segments(n, self.period_s()), n)?;
        Ok((p, n, measure_speed(&self.problem, p, n, &sc)?))
    }
}

/// Designs the path `req` asks for on the reference scenario `base`,
/// telling `obs` how it goes: the limits and targets, the reference path's
/// bound, the search (repeated with shorter coarse steps until they hold;
/// for the full model the budget search when no path reaches every
/// target, cut where its best meets them all when it does), the check of
/// the written scenario, the dwell probe and the targets out of reach.
pub fn run(req: &Request, base: Scenario, obs: &dyn Observer) -> Result<Run, DesignError> {
    let reference = pattern_of(&base)?;
    let l = limits(req, &base)?;
    let id = req.config;
    let mut problem = Problem::with_errors(id, req.errors, &base, req.max_beta_deg);
    problem.step_deg = req.step_deg;
    let Reference {
        out: ref_out,
        sigma: ref_sigma,
        floors,
        below_floor,
    } = reference_targets(req, &base, &mut problem, &reference)?;
    let goal = goal_of(req, base.timing.period_s, l.max_periods)?;
    let space = space_of(req, &l);
    obs.note(&Note::Searching {
        config: id,
        full: problem.errors == ErrorModel::Full,
        scenario: base.name.clone(),
        targets: problem.targets.len(),
        below_floor: below_floor.len(),
        max_rate: l.max_rate,
        max_duration: l.max_duration,
        max_beta_deg: req.max_beta_deg,
        axes: space.axes.iter().map(|a| a.name.clone()).collect(),
        tilted: space.tilted,
        dwells: !space.dwell_steps.is_empty(),
        threads: rayon::current_num_threads(),
    });
    let (design, coarse, goal, fallback) =
        search_with_fallback(req, &mut problem, &space, goal, l.max_periods, obs)?;
    let best = design.best.pattern.clone();
    // Check with `host-sim observability`'s computation; one more period at
    // a time in the rare case rounding of the truth simulator's increments
    // leaves a target a hair short.
    let name = format!("designed-{}", id.as_str());
    let checked = check_designed(
        &problem,
        &base,
        &name,
        &best,
        coarse.periods,
        goal,
        l.max_periods,
    )?;
    let fine = problem.evaluate(
        &best,
        Goal::Budget {
            periods: checked.periods,
        },
        true,
        true,
    );
    let probe = if space.dwell_steps.is_empty() {
        None
    } else {
        dwell_probe(&problem, &best, goal, l.max_periods, &space.dwell_steps)
    };
    // The full model: every target out of reach, with what reaches it.
    let unreached = if problem.errors == ErrorModel::Full {
        out_of_reach(
            &problem,
            &best,
            &checked.sigma,
            l.max_periods,
            l.max_rate,
            (OUT_OF_REACH_HORIZON * l.max_periods).min(MAX_PERIODS),
        )
    } else {
        Vec::new()
    };
    Ok(Run {
        request: req.clone(),
        base,
        reference,
        ref_out,
        ref_sigma,
        problem,
        space,
        goal,
        design,
        coarse,
        checked,
        fine,
        probe,
        unreached,
        floors,
        below_floor,
        fallback,
        max_rate: l.max_rate,
        max_duration: l.max_duration,
        max_periods: l.max_periods,
        name,
    })
}
