//! The checks of a designed path: the coarse steps against period by
//! period ([`coarse_check`]), the bound of the written scenario exactly as
//! `host-sim observability --scenario` computes it ([`observability_sigma`],
//! [`check_designed`]), and the scenario file itself ([`scenario_toml`]).

use crate::sim::scenario::{Scenario, Segment, DEG};

use super::{Design, DesignError, Goal, Outcome, Pattern, Problem};

/// σ of every target of `problem` after the bound of `scenario`'s
/// simulated run (`host-sim observability --scenario` exactly).
pub fn observability_sigma(problem: &Problem, s: &Scenario) -> Result<Vec<f64>, DesignError> {
    let sim = crate::sim::truth::simulate(
        s,
        crate::sim::truth::SimOptions {
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
        return Err(DesignError::BetaExceeded {
            beta_deg: max_beta / DEG,
            limit_deg: problem.max_beta / DEG,
        });
    }
    let run =
        crate::analysis::runner::SimulatedRun::new(problem.config, s, &sim, s.site.earth_rate)
            .with_errors(problem.errors);
    let obs = crate::analysis::observe::analyse_run(run, false)
        .map_err(|e| DesignError::Observability(e.to_string()))?;
    Ok(obs.states.iter().map(|x| x.sigma_crlb_rad).collect())
}

/// `base` with `name`, `path` and a duration of `periods` periods,
/// validated.
pub fn scenario_with(
    base: &Scenario,
    name: &str,
    path: Vec<Segment>,
    periods: u64,
) -> Result<Scenario, DesignError> {
    let mut s = base.clone();
    s.name = name.to_string();
    s.path = path;
    s.timing.duration_s = periods as f64 * base.timing.period_s;
    s.validate()
        .map_err(|e| DesignError::Scenario(e.to_string()))?;
    Ok(s)
}

/// The TOML text of a designed scenario, with a header saying how it was made.
pub fn scenario_toml(s: &Scenario, header: &str) -> Result<String, DesignError> {
    let body = toml::to_string(s).map_err(|e| DesignError::Scenario(e.to_string()))?;
    let text = format!("{header}{body}");
    // It must read back as the same scenario.
    let back = Scenario::from_toml(&text).map_err(|e| DesignError::Scenario(e.to_string()))?;
    if &back != s {
        return Err(DesignError::NotIdentical);
    }
    Ok(text)
}

/// The designed path's length and its coarse steps against period by
/// period.
#[derive(Clone, Debug)]
pub struct CoarseCheck {
    /// Periods of the designed path (reach: period by period).
    pub periods: u64,
    /// Periods at which the coarse steps are compared (reach: the coarse
    /// reach time).
    pub coarse_periods: u64,
    /// The coarse outcome at `coarse_periods`.
    pub coarse: Outcome,
    /// max over the targets of |σ coarse / σ period by period − 1| there.
    pub change: f64,
}

/// The length of the best path of `design` and the relative change of σ
/// its coarse steps make at the coarse end (it must stay within 1 %).
pub fn coarse_check(
    problem: &Problem,
    design: &Design,
    goal: Goal,
    max_periods: u64,
) -> Result<CoarseCheck, DesignError> {
    let best = &design.best.pattern;

    // The designed path, period by period.
    let (periods, coarse_periods) = match goal {
        Goal::Reach { .. } => {
            let r = design
                .fine
                .as_ref()
                .and_then(|f| f.reach)
                .ok_or(DesignError::NotReachedFine)?;
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
    let change = problem
        .targets
        .iter()
        .map(|&(i, _)| (coarse.sigma_end[i] / fine_at.sigma_end[i] - 1.0).abs())
        .fold(0.0, f64::max);
    Ok(CoarseCheck {
        periods,
        coarse_periods,
        coarse,
        change,
    })
}

/// The designed scenario checked by `host-sim observability`'s computation.
#[derive(Clone, Debug)]
pub struct Checked {
    /// The designed scenario.
    pub scenario: Scenario,
    /// σ_CRLB of every state at its end (rad).
    pub sigma: Vec<f64>,
    /// Its periods.
    pub periods: u64,
    /// Whether every target is met.
    pub met: bool,
}

/// The scenario `name` of `best` over `periods` periods on `base`, checked
/// with `host-sim observability`'s computation; one more period at a time
/// (at most 10, up to `max_periods`) in the rare case rounding of the
/// truth simulator's increments leaves a target a hair short.
pub fn check_designed(
    problem: &Problem,
    base: &Scenario,
    name: &str,
    best: &Pattern,
    mut periods: u64,
    goal: Goal,
    max_periods: u64,
) -> Result<Checked, DesignError> {
    let period_s = base.timing.period_s;
    let mut designed;
    let mut check;
    let mut tries = 0;
    loop {
        designed = scenario_with(base, name, best.segments(periods, period_s), periods)?;
        check = observability_sigma(problem, &designed)?;
        let met = problem.targets.iter().all(|&(i, t)| check[i] <= t);
        if met || matches!(goal, Goal::Budget { .. }) || tries >= 10 || periods >= max_periods {
            break;
        }
        periods += 1;
        tries += 1;
    }
    let met = problem.targets.iter().all(|&(i, t)| check[i] <= t);
    Ok(Checked {
        scenario: designed,
        sigma: check,
        periods,
        met,
    })
}
