//! What `host-sim design` shows of a finished design
//! ([`crate::design::Run`]): the printed result (headline, path, targets,
//! targets out of reach, search, dwell probe), the information shares of
//! `--explain`, the speed of `--measure-speed`, and the files (`files`:
//! scenario, figure, CSV, JSON).

mod files;

pub use files::{result_json, speed_json, write_figure, write_scenario, write_sigma_csv};

use rollcal::models::ErrorModel;

use crate::design::{
    contributions, floor_of, target_groups, BelowFloor, Goal, OutOfReach, Outcome, Pattern,
    Problem, Run, Speed,
};
use crate::sim::instruments::printed_value;
use crate::sim::scenario::Axis;

/// The printed result: headline, path, targets, targets out of reach,
/// search, dwell probe.
pub fn print_result(r: &Run) {
    print_headline(r);
    print_path(r);
    print_targets(r);
    print_unreached(r);
    print_search(r);
    print_probe(r);
}

/// max over the targets of `sigma`/target.
fn worst_ratio(problem: &Problem, sigma: &[f64]) -> f64 {
    problem
        .targets
        .iter()
        .map(|&(i, t)| sigma[i] / t)
        .fold(0.0, f64::max)
}

/// The limits and the headline: the reach time, or the best ratio within
/// the budget.
fn print_headline(r: &Run) {
    let base = &r.base;
    println!(
        "Designed rolling path for {} on '{}' (Earth rate {}, latitude {}°), limits: rate ≤ {} °/s, duration ≤ {} s, |β| ≤ {}°",
        r.request.config,
        base.name,
        if base.site.earth_rate { "on" } else { "off" },
        base.site.latitude_deg,
        r.max_rate,
        r.max_duration,
        r.request.max_beta_deg
    );
    let (t_design, t_ref) = (r.t_design(), r.t_ref());
    let every = r.every_target();
    let gave_up = format!("the shortest-path search found none (no pattern of its stage 1, the coarse grammar, reaches {every} within the duration limit, and its refinement starts from those)");
    // The worst-case σ/target is over the targets searched for.
    let over = if r.below_floor.is_empty() {
        ""
    } else {
        " (over the targets above their floor)"
    };
    match r.goal {
        Goal::Reach { .. } if r.fallback => println!(
            "\nA path to {every}: {t_design} s ({:.1} % of the reference path's {t_ref} s){}\n  Not the shortest: {gave_up}; the budget search over the same space found this one within {} s, cut where it meets {every}.",
            100.0 * t_design / t_ref,
            if r.checked.met { "" } else { "  — WARNING: the observability check misses a target" },
            r.max_duration
        ),
        Goal::Reach { .. } => {
            println!(
                "\nShortest path to {every}: {t_design} s ({:.1} % of the reference path's {t_ref} s){}",
                100.0 * t_design / t_ref,
                if r.checked.met { "" } else { "  — WARNING: the observability check misses a target" }
            );
            if r.periods() >= r.ref_periods() {
                println!("  No path of the search space reaches the targets sooner than the reference path.");
            }
        }
        Goal::Budget { periods: b } if r.fallback => println!(
            "\nNo path to {every} within {} s: {gave_up}, and the budget search over the same space reaches a worst-case σ/target{over} of {:.3} at best (the reference path in its {t_ref} s: {:.3}).",
            b as f64 * r.period_s(),
            worst_ratio(&r.problem, &r.checked.sigma),
            worst_ratio(&r.problem, &r.ref_sigma)
        ),
        Goal::Budget { periods: b } => println!(
            "\nBest worst-case σ/target{over} within {} s: {:.3} (the reference path in its {t_ref} s: {:.3})",
            b as f64 * r.period_s(),
            worst_ratio(&r.problem, &r.checked.sigma),
            worst_ratio(&r.problem, &r.ref_sigma)
        ),
    }
    print_below_floor_headline(r);
}

/// The headline's second part when targets lie below their floor: which,
/// the target and the floor of each (grouped where they agree).
fn print_below_floor_headline(r: &Run) {
    if r.below_floor.is_empty() {
        return;
    }
    let names = r.request.config.states_with(r.problem.errors);
    // Consecutive states of one target and one floor, together.
    let mut groups: Vec<(Vec<&str>, &BelowFloor)> = Vec::new();
    for b in &r.below_floor {
        match groups.last_mut() {
            Some((states, first))
                if first.target == b.target
                    && first.floor == b.floor
                    && names[first.state].group == names[b.state].group =>
            {
                states.push(names[b.state].name)
            }
            _ => groups.push((vec![names[b.state].name], b)),
        }
    }
    let parts: Vec<String> = groups
        .iter()
        .map(|(states, b)| {
            let g = names[b.state].group;
            let unit = g.printed_scale().1;
            format!(
                "{} target {:.4} {unit} < floor {:.4} {unit}{}",
                states.join(", "),
                printed_value(g, b.target),
                printed_value(g, b.floor.limit),
                flat_after(b.floor.flat_after_s, ", flat after ")
            )
        })
        .collect();
    println!(
        "  Out of reach of any path of any length: {} target(s) below the floor the wandering errors leave (not searched for): {}.",
        r.below_floor.len(),
        parts.join("; ")
    );
}

/// "`prefix`T s" of a floor's flat point, or its note that the floor keeps
/// falling (no random walk).
fn flat_after(flat_after_s: Option<f64>, prefix: &str) -> String {
    match flat_after_s {
        Some(t) => format!("{prefix}{t:.0} s"),
        None => ", the floor keeps falling (no random walk)".to_string(),
    }
}

/// The designed pattern and its segments.
fn print_path(r: &Run) {
    let designed = &r.checked.scenario;
    println!("  pattern: {}", r.best().describe());
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
}

/// Per target: the target, the reference and the designed σ (″; with the
/// full model, an instrument term in its printed unit, in a unit column).
fn print_targets(r: &Run) {
    let (problem, check) = (&r.problem, &r.checked.sigma);
    let names = r.request.config.states_with(problem.errors);
    let full = problem.errors == ErrorModel::Full;
    let floors = !r.floors.is_empty();
    if full {
        print!(
            "\n  {:<10} {:<6} {:>12} {:>14} {:>14} {:>8}",
            "state", "unit", "target", "reference", "designed", "σ/target"
        );
        if floors {
            print!(" {:>12} {:>10}", "floor", "flat after");
        }
        println!();
    } else {
        println!(
            "\n  {:<10} {:>12} {:>14} {:>14} {:>8}",
            "state", "target ″", "reference ″", "designed ″", "σ/target"
        );
    }
    for (i, t) in r.all_targets() {
        let g = names[i].group;
        let unit = if full {
            format!(" {:<6}", g.printed_scale().1)
        } else {
            String::new()
        };
        // The floor of a wandering term's state, and where it flattens; a
        // target below it is out of reach of every path.
        let floor = match (floors, floor_of(&r.floors, i)) {
            (false, _) => String::new(),
            (true, None) => format!(" {:>12} {:>10}", "—", "—"),
            (true, Some(f)) => format!(
                " {:>12.4} {:>10}{}",
                printed_value(g, f.limit),
                f.flat_after_s
                    .map_or("—".to_string(), |t| format!("{t:.0} s")),
                if t < f.limit { "  below the floor" } else { "" }
            ),
        };
        println!(
            "  {:<10}{unit} {:>12.4} {:>14.4} {:>14.4} {:>8.3}{floor}",
            names[i].name,
            printed_value(g, t),
            printed_value(g, r.ref_sigma[i]),
            printed_value(g, check[i]),
            check[i] / t
        );
    }
    if full {
        let scale = r.request.target_scale;
        println!("  (targets: the installation errors at the reference path's σ_CRLB of the installation model, the instrument terms at dg 0.005 °/h, Dg 0.005 °/h/g, kg 1 ppm, ba 1 µg, ka 1 ppm{}; reference and designed σ: `host-sim observability --errors full --scenario` of the reference and the written scenario)",
            if scale == 1.0 { String::new() } else { format!(", × {scale}") });
        if floors {
            println!("  (floor: the smallest σ any path of any length reaches on the persistent part of a wandering drift or bias, `host-sim observability --errors full`'s floor; flat after: the log length from which that floor is within 5 % of its limit, rolling longer no longer helping; —: none, or a floor that keeps falling without a random walk; docs/path-design.md, \"The floor of the errors that wander\")");
        }
    } else {
        println!("  (designed σ: `host-sim observability --scenario` of the written scenario)");
    }
}

/// The full model: each target out of reach within the limits, the σ the
/// bound reaches, and the time or rate that reaches it; then each target
/// below its floor, with the floor.
fn print_unreached(r: &Run) {
    let problem = &r.problem;
    let (max_rate, max_duration) = (r.max_rate, r.max_duration);
    if problem.errors != ErrorModel::Full {
        return;
    }
    let every = capitalised(r.every_target());
    let names = r.request.config.states_with(problem.errors);
    if r.unreached.is_empty() && matches!(r.goal, Goal::Reach { .. }) {
        // The written path is cut where it meets them all (the headline's).
        println!(
            "\n  {every} is met within the limits (rate ≤ {max_rate} °/s, {max_duration} s), at {} s.",
            r.t_design()
        );
    } else if r.unreached.is_empty() {
        // Period by period, when the designed pattern first meets them all.
        let first = problem
            .evaluate(
                r.best(),
                Goal::Reach {
                    cutoff: r.periods(),
                },
                true,
                false,
            )
            .reach
            .map_or(String::new(), |p| {
                format!(
                    "; the designed pattern meets them all at {} s",
                    p as f64 * r.period_s()
                )
            });
        println!("\n  {every} is met within the limits (rate ≤ {max_rate} °/s, {max_duration} s){first}.");
    } else {
        println!(
            "\n  Out of reach within the limits (rate ≤ {max_rate} °/s, {max_duration} s), by the bound (σ_CRLB):"
        );
        for u in &r.unreached {
            print_out_of_reach(r, u, names);
        }
    }
    if r.below_floor.is_empty() {
        return;
    }
    println!(
        "\n  Out of reach of any path of any length, below the floor the wandering errors leave (not searched for):"
    );
    for b in &r.below_floor {
        let g = names[b.state].group;
        let unit = g.printed_scale().1;
        println!(
            "    {:<10} target {:.4} {unit} < floor {:.4} {unit} ({:.2}× the target{}); the written path reaches {:.4} {unit}",
            names[b.state].name,
            printed_value(g, b.target),
            printed_value(g, b.floor.limit),
            b.floor.limit / b.target,
            flat_after(b.floor.flat_after_s, "; within 5 % of it after "),
            printed_value(g, r.checked.sigma[b.state]),
        );
    }
}

/// `s` with its first letter a capital.
fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map_or(String::new(), |f| f.to_uppercase().chain(c).collect())
}

/// One target out of reach within the limits: the σ reached, and what
/// time or rate reaches it (and its floor, when it has one).
fn print_out_of_reach(r: &Run, u: &OutOfReach, names: &[rollcal::models::StateInfo]) {
    let max_duration = r.max_duration;
    let g = names[u.state].group;
    let unit = g.printed_scale().1;
    let time = match u.time_s {
        Some(t) => format!("the designed pattern repeated reaches it at {t} s"),
        None => format!(
            "not within {} s of the designed pattern repeated",
            u.horizon_s
        ),
    };
    let rate = match u.rate {
        Some((rate, s)) => format!(
            "; at {rate} °/s (the same angles) it reaches {:.4} {unit} within {max_duration} s",
            printed_value(g, s)
        ),
        None => {
            format!("; no rate up to 10 °/s of the same angles reaches it within {max_duration} s")
        }
    };
    let floor = floor_of(&r.floors, u.state).map_or(String::new(), |f| {
        format!(" (its floor: {:.4} {unit})", printed_value(g, f.limit))
    });
    println!(
        "    {:<10} target {:.4} {unit}, reached {:.4} {unit} ({:.2}× the target){floor}: {time}{rate}",
        names[u.state].name,
        printed_value(g, u.target),
        printed_value(g, u.sigma),
        u.sigma / u.target
    );
}

/// The search statistics, the coarse steps and the optimality.
fn print_search(r: &Run) {
    let space = &r.space;
    println!("\nSearch:");
    for s in &r.design.stages {
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
        r.coarse.coarse.k,
        r.coarse.coarse_periods as f64 * r.period_s(),
        100.0 * r.coarse.change
    );
    if matches!(r.goal, Goal::Reach { .. }) && !r.fallback {
        println!(
            "  optimality: exact over the exhaustive grammar (patterns of ≤ {} rotations about {} axes by 90°·n at {} °/s, repeated) to one coarse step; the refinement only improves on it (local optimum over 30° angles, ¾ and ½ rates{}{})",
            space.max_rotations,
            space.axes.len(),
            r.max_rate,
            if space.tilted { ", tilted axes" } else { "" },
            if space.dwell_steps.is_empty() { "" } else { ", dwells of ±60, ±180, ±600 s" }
        );
    }
}

/// The dwell probe, when run.
fn print_probe(r: &Run) {
    let Some(pr) = &r.probe else {
        return;
    };
    let reach = matches!(r.goal, Goal::Reach { .. });
    let what = if reach {
        "reaches every target in"
    } else {
        "worst σ/target"
    };
    let unit = if reach { " s" } else { "" };
    println!(
        "  dwells: the best single dwell move on the designed pattern, {}: {what} {}{unit} against {}{unit} without it ({:+.2} %), period by period",
        pr.pattern.describe(),
        pr.score,
        pr.base,
        100.0 * (pr.score / pr.base - 1.0)
    );
}

/// Prints which rotations excite which parameter groups (`--explain`), on
/// the designed and the reference path.
pub fn print_explain(r: &Run) {
    for (label, p, o) in [
        ("designed", r.best(), &r.fine),
        ("reference", &r.reference, &r.ref_out),
    ] {
        print_explain_path(&r.problem, label, p, o);
    }
}

/// [`print_explain`] of one path.
fn print_explain_path(problem: &Problem, label: &str, p: &Pattern, o: &Outcome) {
    let groups = target_groups(problem);
    println!(
        "\nWhich rotations excite which parameters, {label} path: share of each group's information gain Σ(1/σ²_end − 1/σ²_start) (σ_CRLB, marginal) per rotation"
    );
    print!("  {:<28} {:>13}", "rotation", "t [s]");
    for g in &groups {
        print!(" {:>7}", g.as_str());
    }
    println!();
    let c = contributions(problem, p, o);
    for row in &c {
        print!("  {:<28} {:>6.0}–{:<6.0}", row.rotation, row.t0_s, row.t1_s);
        for (_, s) in &row.shares {
            print!(" {:>6.1}%", 100.0 * s);
        }
        println!();
    }
    // By axis.
    let axis_of = |rotation: &str| rotation.split(' ').next().unwrap_or("").to_string();
    let mut axes: Vec<String> = Vec::new();
    for row in &c {
        let a = axis_of(&row.rotation);
        if !axes.contains(&a) {
            axes.push(a);
        }
    }
    println!("  by axis (share of the information; in brackets, per second relative to the whole path's average: > 1 excites the group more than the average second):");
    let total_t = c.last().map_or(1.0, |row| row.t1_s).max(1e-9);
    for a in &axes {
        let on_axis = || c.iter().filter(|row| axis_of(&row.rotation) == *a);
        let t: f64 = on_axis().map(|row| row.t1_s - row.t0_s).sum();
        let tf = t / total_t;
        print!("  {:<28} {:>13}", a, format!("{:.0} % of t", 100.0 * tf));
        for (gi, _) in groups.iter().enumerate() {
            let s: f64 = on_axis().map(|row| row.shares[gi].1).sum();
            print!(" {:>5.1}% ({:.2})", 100.0 * s, s / tf.max(1e-9));
        }
        println!();
    }
}

/// Prints the speed of the bound against the estimator (`--measure-speed`)
/// on the candidate `best` of `periods` periods of `period_s`.
pub fn print_speed(best: &Pattern, periods: u64, period_s: f64, s: &Speed) {
    println!(
        "\nSpeed on the search's best candidate {} ({} s): one bound evaluation {:.2} ms ({} periods per step; period by period {:.2} ms); one estimator run ({} passes) {:.1} ms, {:.0}× the bound; with the simulation of its data ({:.1} ms, as in a Monte Carlo run) {:.1} ms, {:.0}× the bound; {:.0} full candidate evaluations per minute on {} threads",
        best.describe(),
        periods as f64 * period_s,
        s.bound_eval_s * 1e3,
        s.step_periods,
        s.bound_eval_fine_s * 1e3,
        s.estimator_passes,
        s.estimator_run_s * 1e3,
        s.estimator_run_s / s.bound_eval_s,
        s.simulation_s * 1e3,
        (s.simulation_s + s.estimator_run_s) * 1e3,
        (s.simulation_s + s.estimator_run_s) / s.bound_eval_s,
        s.full_evaluations_per_minute,
        s.threads
    );
}
