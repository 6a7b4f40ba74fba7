//! The files of a design: the scenario of the designed path, its σ(t)
//! figure against the reference path, the σ(t) CSV and the result as JSON.

use std::path::{Path, PathBuf};

use rollcal::models::ErrorModel;

use crate::design::{floor_of, scenario_toml, Goal, Outcome, Problem, Run, Speed, StateFloor};
use crate::output::plots::{plot_sigma_comparison_in, SigmaCurve};
use crate::sim::instruments::printed_value;

/// Writes the designed scenario to `out`, with a header saying how it was
/// made, and says so on stdout.
pub fn write_scenario(r: &Run, out: &Path) -> Result<(), String> {
    let id = r.request.config;
    let full = if r.problem.errors == ErrorModel::Full {
        " --errors full"
    } else {
        ""
    };
    let header = format!(
        "# Designed by `host-sim design --config {id}{full}` (rollcal): {}\n# reaches {} in {} s (reference path: {} s); check with\n#   host-sim observability{full} --scenario {}\n",
        r.best().describe(),
        match r.goal {
            Goal::Reach { .. } => r.every_target().to_string(),
            Goal::Budget { .. } if r.fallback => {
                "the best worst-case σ/target within the limit (not every target)".to_string()
            }
            Goal::Budget { .. } => "the best worst-case σ/target of the budget".to_string(),
        },
        r.t_design(),
        r.t_ref(),
        out.display()
    );
    std::fs::write(out, scenario_toml(&r.checked.scenario, &header)?)
        .map_err(|e| format!("cannot write {}: {e}", out.display()))?;
    println!("\nWrote the designed scenario to {}", out.display());
    Ok(())
}

/// One σ(t) curve per target of `targets` (of `problem`'s states): the
/// designed path `a` against the reference path `b`, each in the state's
/// printed unit, with the state's floor of `floors` when it has one.
fn sigma_curves(
    problem: &Problem,
    targets: &[(usize, f64)],
    floors: &[StateFloor],
    a: &Outcome,
    b: &Outcome,
) -> Vec<SigmaCurve> {
    let names = problem.config.states_with(problem.errors);
    let curve = |o: &Outcome, i: usize| {
        o.history
            .iter()
            .map(|h| (h.0, printed_value(names[i].group, h.1[i])))
            .collect()
    };
    targets
        .iter()
        .map(|&(i, t)| SigmaCurve {
            label: names[i].name,
            target: printed_value(names[i].group, t),
            floor: floor_of(floors, i).map(|f| printed_value(names[i].group, f.limit)),
            a: curve(a, i),
            b: curve(b, i),
        })
        .collect()
}

/// Writes the σ(t) figure to `fig`, designed against reference: the angles
/// in it; with the full model, the instrument terms (their printed units)
/// in a second one beside it, `<figure>-instruments.png`.
pub fn write_figure(r: &Run, fig: &Path) -> Result<(), String> {
    let problem = &r.problem;
    let id = r.request.config;
    let names = id.states_with(problem.errors);
    let targets = r.all_targets();
    let series = sigma_curves(problem, &targets, &r.floors, &r.fine, &r.ref_out);
    let (angles, instruments): (Vec<_>, Vec<_>) = series
        .into_iter()
        .zip(&targets)
        .partition(|(_, &(i, _))| !names[i].group.is_instrument());
    let title = format!(
        "{id}: σ_CRLB(t), designed path ({} s) vs reference path ({} s)",
        r.t_design(),
        r.t_ref()
    );
    let mut figures = vec![(fig.to_path_buf(), angles, title.clone(), "″")];
    if !instruments.is_empty() {
        let stem = fig.with_extension("");
        let inst = PathBuf::from(format!("{}-instruments.png", stem.display()));
        figures.push((
            inst,
            instruments,
            format!("{title}, instrument terms"),
            "°/h, °/h/g, ppm, µg",
        ));
    }
    for (path, curves, title, unit) in figures {
        let curves: Vec<_> = curves.into_iter().map(|(c, _)| c).collect();
        if curves.is_empty() {
            continue;
        }
        plot_sigma_comparison_in(&path, &title, "designed", "reference", &curves, unit)?;
        println!("Wrote the σ(t) figure to {}", path.display());
    }
    Ok(())
}

/// Writes σ(t) of every target state, designed and reference, as CSV
/// (rows `designed` and `reference`, time `t_s`); with errors that wander,
/// then a `target` row and a `floor` row (no time; the floor empty for a
/// state without one).
pub fn write_sigma_csv(path: &Path, r: &Run) -> Result<(), String> {
    use std::fmt::Write;
    let problem = &r.problem;
    let names = problem.config.states_with(problem.errors);
    let targets = r.all_targets();
    let mut text = String::from("path,t_s");
    for &(i, _) in &targets {
        let _ = write!(text, ",{}_sigma_rad", names[i].name);
    }
    text.push('\n');
    for (label, o) in [("designed", &r.fine), ("reference", &r.ref_out)] {
        for h in &o.history {
            let _ = write!(text, "{label},{}", h.0);
            for &(i, _) in &targets {
                let _ = write!(text, ",{:e}", h.1[i]);
            }
            text.push('\n');
        }
    }
    // With errors that wander: the targets, and the floor of each drift
    // and bias state (empty for a state without one), the floor the σ of
    // no path gets below; a target below its floor is out of reach.
    if !r.floors.is_empty() {
        let _ = write!(text, "target,");
        for &(_, t) in &targets {
            let _ = write!(text, ",{t:e}");
        }
        let _ = write!(text, "\nfloor,");
        for &(i, _) in &targets {
            let f = floor_of(&r.floors, i).map_or(String::new(), |f| format!("{:e}", f.limit));
            let _ = write!(text, ",{f}");
        }
        text.push('\n');
    }
    std::fs::write(path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// The JSON of the result (`--json`), with the speed measurement's JSON
/// (`null` without one) and the wall time.
pub fn result_json(r: &Run, speed: serde_json::Value, wall_s: f64) -> serde_json::Value {
    let problem = &r.problem;
    let id = r.request.config;
    let names = id.states_with(problem.errors);
    let space = &r.space;
    let mut json = serde_json::json!({
        "config": id.as_str(),
        "scenario": r.base.name,
        "goal": match r.goal { Goal::Reach{..} => "shortest".to_string(), Goal::Budget{periods} => format!("budget {} s", periods as f64 * r.period_s()) },
        "limits": {"max_rate_deg_s": r.max_rate, "max_duration_s": r.max_duration, "max_beta_deg": r.request.max_beta_deg,
            "axes": space.axes.iter().map(|a| a.name.clone()).collect::<Vec<_>>(), "tilted": space.tilted,
            "dwell_steps_s": space.dwell_steps},
        "pattern": r.best(),
        "duration_s": r.t_design(),
        "reference_duration_s": r.t_ref(),
        "all_targets_met": r.checked.met && r.below_floor.is_empty(),
        "targets": r.all_targets().iter().map(|&(i, t)| serde_json::json!({
            "state": names[i].name, "target_rad": t, "reference_sigma_rad": r.ref_sigma[i],
            "designed_sigma_rad": r.checked.sigma[i]})).collect::<Vec<_>>(),
        "path": r.checked.scenario.path,
        "stages": r.design.stages,
        "coarse_step_periods": r.coarse.coarse.k,
        "coarse_step_max_change": r.coarse.change,
        "speed": speed,
        "dwell_probe": r.probe.as_ref().map(|p| serde_json::json!({
            "pattern": p.pattern, "score": p.score, "without": p.base})),
        "wall_s": wall_s,
    });
    // The full model only (the installation document stays as it was): the
    // error model, each instrument target's internal unit (`target_rad`
    // &c. hold rad/s, rad/s/g, 1 or g there), and the targets out of reach.
    if problem.errors == ErrorModel::Full {
        if let Some(m) = json.as_object_mut() {
            m.insert("errors".into(), problem.errors.as_str().into());
            m.insert("fallback".into(), r.fallback.into());
            // Met: every target searched for (those above their floor).
            m.insert("targets_above_floor_met".into(), r.checked.met.into());
            if let Some(serde_json::Value::Array(ts)) = m.get_mut("targets") {
                for (t, (i, target)) in ts.iter_mut().zip(r.all_targets()) {
                    let Some(t) = t.as_object_mut() else { continue };
                    if names[i].group.is_instrument() {
                        t.insert("unit".into(), names[i].unit.into());
                    }
                    let f = floor_of(&r.floors, i);
                    t.insert("floor".into(), f.map(|f| f.limit).into());
                    t.insert("flat_after_s".into(), f.and_then(|f| f.flat_after_s).into());
                    t.insert(
                        "below_floor".into(),
                        f.is_some_and(|f| target < f.limit).into(),
                    );
                }
            }
            // Every target the written path misses: those out of reach
            // within the limits, then those below their floor (out of reach
            // of every path, not searched for).
            let within = r.unreached.iter().map(|u| {
                let f = floor_of(&r.floors, u.state);
                serde_json::json!({
                "state": names[u.state].name, "target": u.target, "sigma": u.sigma,
                "time_s": u.time_s, "horizon_s": u.horizon_s,
                "rate_deg_s": u.rate.map(|r| r.0), "sigma_at_rate": u.rate.map(|r| r.1),
                "below_floor": false, "floor": f.map(|f| f.limit),
                "flat_after_s": f.and_then(|f| f.flat_after_s)})
            });
            let below = r.below_floor.iter().map(|b| {
                serde_json::json!({
                "state": names[b.state].name, "target": b.target, "sigma": r.checked.sigma[b.state],
                "time_s": null, "horizon_s": null, "rate_deg_s": null, "sigma_at_rate": null,
                "below_floor": true, "floor": b.floor.limit, "flat_after_s": b.floor.flat_after_s})
            });
            m.insert(
                "out_of_reach".into(),
                within.chain(below).collect::<Vec<_>>().into(),
            );
        }
    }
    json
}

/// The JSON of the speed measurement.
pub fn speed_json(s: &Speed) -> serde_json::Value {
    serde_json::json!({
        "bound_eval_s": s.bound_eval_s, "bound_eval_fine_s": s.bound_eval_fine_s, "step_periods": s.step_periods,
        "estimator_run_s": s.estimator_run_s, "estimator_passes": s.estimator_passes, "ratio": s.estimator_run_s / s.bound_eval_s,
        "simulation_s": s.simulation_s, "ratio_with_simulation": (s.simulation_s + s.estimator_run_s) / s.bound_eval_s,
        "full_evaluations_per_minute": s.full_evaluations_per_minute, "threads": s.threads})
}
