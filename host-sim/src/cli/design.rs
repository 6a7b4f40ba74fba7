//! `host-sim design`: its arguments ([`DesignArgs`]) and its driver
//! ([`command`]): the limits and targets from the arguments, the search
//! ([`crate::design::search`]) until its coarse steps hold, the check of
//! the written scenario, the printed result and the files (scenario,
//! figure, CSV, JSON). The only part of the path design that prints.

use std::path::PathBuf;

use rollcal::models::{ConfigId, ErrorModel};

use crate::design::{
    check_designed, coarse_check, contributions, dwell_probe, measure_speed, observability_sigma,
    out_of_reach, parse_target, pattern_of, scenario_toml, scenario_with, search, target_groups,
    targets_with, CoarseCheck, Design, DesignError, DwellProbe, Goal, InstrumentTargets, NamedAxis,
    OutOfReach, Outcome, Pattern, Problem, Space, Speed, TargetArg, DEFAULT_STEP_DEG,
    DWELL_STEPS_S,
};
use crate::sim::instruments::printed_value;
use crate::sim::scenario::{Axis, Scenario, MAX_PERIODS};

/// Arguments of `host-sim design`.
#[derive(clap::Args, Clone, Debug)]
pub struct DesignArgs {
    /// Configuration: M1-pa, M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps (case-insensitive).
    #[arg(long, value_parser = super::args::parse_config)]
    pub config: ConfigId,
    /// Scenario file (TOML): site, noise, truth, timing, prior, and the
    /// reference path the targets default to; default: the paper's scenario.
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// A target σ, NAME=VALUE, NAME a state (thgC_x) or a group (thgC),
    /// VALUE in arcseconds (with `--errors full`, an instrument term's in
    /// °/h, °/h/g, ppm or µg: dg=0.01); repeatable. Default: the reference
    /// path's final σ_CRLB on every parameter the configuration observes
    /// (the parameter block); with `--errors full` also dg 0.005 °/h, Dg
    /// 0.005 °/h/g, kg 1 ppm, ba 1 µg, ka 1 ppm.
    #[arg(long = "target", value_name = "NAME=VALUE", value_parser = parse_target)]
    pub targets: Vec<TargetArg>,
    /// Error model of the bound: `installation` (the paper's states) or
    /// `full` (followed by the instruments' 21 errors, with the scenario's
    /// `[instruments.prior]`). With `full`, a target out of reach is
    /// reported with the σ reached and what time or rate reaches it, and
    /// when no path reaches every target the search falls back to the best
    /// worst-case σ/target within the duration limit.
    #[arg(long, default_value = "installation", value_parser = super::args::parse_errors)]
    pub errors: ErrorModel,
    /// Multiply the default targets by this factor (e.g. 2: half the accuracy).
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive)]
    pub target_scale: f64,
    /// Maximum rotation rate (°/s). At the paper's 0.1 °/s no path of the
    /// search space beats the paper's (see docs/path-design.md, "Half the
    /// paper's time at 0.1 °/s is out of reach").
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
    /// costs 1–22 % more search time (docs/path-design.md, "Dwells").
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

fn parse_positive(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}' must be a positive number")),
    }
}

/// What the arguments set before the search: the reference scenario and
/// path, and the limits.
struct Setup {
    base: Scenario,
    reference: Pattern,
    ref_periods: u64,
    max_rate: f64,
    max_duration: f64,
    max_periods: u64,
    axes: Vec<NamedAxis>,
}

/// The reference scenario and the limits of `args`, checked.
fn setup(args: &DesignArgs) -> Result<Setup, String> {
    let base = match &args.scenario {
        Some(p) => Scenario::from_file(p).map_err(|e| e.to_string())?,
        None => Scenario::paper(),
    };
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
    let limit = crate::sim::scenario::MAX_PERIODS;
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
    Ok(Setup {
        base,
        reference,
        ref_periods,
        max_rate,
        max_duration,
        max_periods,
        axes,
    })
}

/// The goal of `args`: the shortest path (within `max_periods`), or the
/// best within `--budget-s`.
fn goal_of(args: &DesignArgs, period_s: f64, max_periods: u64) -> Result<Goal, String> {
    let limit = crate::sim::scenario::MAX_PERIODS;
    Ok(match args.budget_s {
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
    })
}

/// The search space of `args` over `axes`.
fn space_of(args: &DesignArgs, axes: Vec<NamedAxis>, max_rate: f64, max_duration: f64) -> Space {
    Space {
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
    }
}

/// The search, with progress on stderr, repeated with coarse steps half as
/// long while they move σ by more than 1 % (the result is then recomputed
/// period by period anyway).
fn search_until_fine(
    problem: &mut Problem,
    space: &Space,
    goal: Goal,
    max_periods: u64,
) -> Result<(Design, CoarseCheck), DesignError> {
    loop {
        let progress = crate::output::progress::Progress::stderr("design", 1, "candidates");
        let last = std::sync::Mutex::new(0u64);
        let design = search(problem, space, goal, &|st, d, t| {
            if let Ok(mut l) = last.lock() {
                *l = d as u64;
            }
            progress.stage(st, d as u64, t as u64, "")
        });
        if let Ok(l) = last.lock() {
            progress.finish(*l, "");
        }
        let design = design?;
        let cc = coarse_check(problem, &design, goal, max_periods)?;
        // The coarse steps must leave σ within 1 % (the result is then
        // recomputed period by period anyway): otherwise search again with
        // steps half as long.
        if cc.change <= 0.01 || problem.max_step_periods <= 1 {
            return Ok((design, cc));
        }
        problem.max_step_periods = (cc.coarse.k / 2).max(1);
        problem.step_deg /= 2.0;
        eprintln!(
            "design: coarse steps of {} periods moved σ by {:.2} % (> 1 %): searching again with at most {} periods per step",
            cc.coarse.k,
            100.0 * cc.change,
            problem.max_step_periods
        );
    }
}

/// The reference path period by period, and the default targets: the
/// reference scenario's σ_CRLB exactly as `host-sim observability
/// --scenario` computes it, scaled and overridden by `args` (set on
/// `problem`). Returns the reference outcome (recorded) and σ.
fn reference_targets(
    args: &DesignArgs,
    base: &Scenario,
    problem: &mut Problem,
    reference: &Pattern,
    ref_periods: u64,
) -> Result<(Outcome, Vec<f64>), String> {
    let id = args.config;
    // The reference path, period by period: the default targets.
    let ref_out = problem.evaluate(
        reference,
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
    problem.targets = targets_with(
        id,
        problem.errors,
        &inst_sigma,
        &InstrumentTargets::PSINS,
        args.target_scale,
        &args.targets,
    )?;
    // The reference σ shown: the bound of the model searched.
    let ref_sigma = match problem.errors {
        ErrorModel::Installation => inst_sigma,
        errors => sigma_of(problem, errors)?,
    };

    Ok((ref_out, ref_sigma))
}

/// Runs `host-sim design`.
pub fn command(args: &DesignArgs) -> Result<(), String> {
    let t_all = std::time::Instant::now();
    let Setup {
        base,
        reference,
        ref_periods,
        max_rate,
        max_duration,
        max_periods,
        axes,
    } = setup(args)?;
    let id = args.config;
    let period_s = base.timing.period_s;
    if args.errors == ErrorModel::Full {
        super::args::note_instrument_prior(&base, args.errors);
    }
    let mut problem = Problem::with_errors(id, args.errors, &base, args.max_beta_deg);
    problem.step_deg = args.step_deg;

    let (ref_out, ref_sigma) =
        reference_targets(args, &base, &mut problem, &reference, ref_periods)?;

    let mut goal = goal_of(args, period_s, max_periods)?;
    let space = space_of(args, axes, max_rate, max_duration);
    eprintln!(
        "design: {id}{} on '{}': {} targets, max rate {max_rate} °/s, {} s at most, |β| ≤ {}°, axes {}{}, {}; {} threads",
        if problem.errors == ErrorModel::Full { " (full model)" } else { "" },
        base.name,
        problem.targets.len(),
        max_duration,
        args.max_beta_deg,
        space.axes.iter().map(|a| a.name.as_str()).collect::<Vec<_>>().join(","),
        if space.tilted { " (+ tilted)" } else { "" },
        if space.dwell_steps.is_empty() { "no dwells" } else { "dwells" },
        rayon::current_num_threads()
    );
    let mut fallback = false;
    let (design, cc) = match search_until_fine(&mut problem, &space, goal, max_periods) {
        // The full model: no path reaches every target within the limits;
        // the best worst-case σ/target within the duration limit instead,
        // and the targets out of reach are reported with the bound.
        Err(DesignError::NoPathReaches { within_s })
            if problem.errors == ErrorModel::Full && args.budget_s.is_none() =>
        {
            eprintln!(
                "design: no path of the search space reaches every target within {within_s} s; searching the best worst-case σ/target within it"
            );
            goal = Goal::Budget {
                periods: max_periods,
            };
            fallback = true;
            search_until_fine(&mut problem, &space, goal, max_periods)?
        }
        r => r?,
    };
    let best = &design.best.pattern;

    // Check with `host-sim observability`'s computation; one more period at
    // a time in the rare case rounding of the truth simulator's increments
    // leaves a target a hair short.
    let name = format!("designed-{}", id.as_str());
    let checked = check_designed(&problem, &base, &name, best, cc.periods, goal, max_periods)?;
    let periods = checked.periods;
    let fine_rec = problem.evaluate(best, Goal::Budget { periods }, true, true);
    let probe = if space.dwell_steps.is_empty() {
        None
    } else {
        dwell_probe(&problem, best, goal, max_periods, &space.dwell_steps)
    };
    // The full model: every target out of reach, with what reaches it.
    let unreached = if problem.errors == ErrorModel::Full {
        out_of_reach(
            &problem,
            best,
            &checked.sigma,
            max_periods,
            max_rate,
            (OUT_OF_REACH_HORIZON * max_periods).min(MAX_PERIODS),
        )
    } else {
        Vec::new()
    };

    // Report.
    let summary = Summary {
        id,
        base: &base,
        args,
        problem: &problem,
        space: &space,
        goal,
        design: &design,
        best,
        designed: &checked.scenario,
        check: &checked.sigma,
        ref_sigma: &ref_sigma,
        met: checked.met,
        periods,
        ref_periods,
        period_s,
        t_design: periods as f64 * period_s,
        t_ref: ref_periods as f64 * period_s,
        max_rate,
        max_duration,
        coarse: &cc.coarse,
        coarse_periods: cc.coarse_periods,
        coarse_change: cc.change,
        probe: probe.as_ref(),
        unreached: &unreached,
        fallback,
    };
    print_result(&summary);

    if args.explain {
        print_explain(&problem, best, &fine_rec, &reference, &ref_out);
    }

    let speed = if args.measure_speed {
        speed_of(&problem, &design, &base)?
    } else {
        serde_json::Value::Null
    };

    // Files.
    write_scenario(&summary, &name)?;
    write_figure(&summary, &name, &fine_rec, &ref_out)?;
    if let Some(p) = &args.csv {
        write_sigma_csv(p, &problem, &fine_rec, &ref_out)?;
    }
    if let Some(p) = &args.json {
        let json = result_json(&summary, speed, t_all.elapsed().as_secs_f64());
        crate::output::report::write_json(p, &json)?;
    }
    eprintln!("design: done in {:.1} s", t_all.elapsed().as_secs_f64());
    if matches!(goal, Goal::Reach { .. }) && !checked.met {
        return Err("the designed path misses a target in the observability check".into());
    }
    Ok(())
}

/// `--measure-speed` on the search's own candidate (before the polish):
/// what every candidate of the search costs; prints it and returns its
/// JSON.
fn speed_of(
    problem: &Problem,
    design: &Design,
    base: &Scenario,
) -> Result<serde_json::Value, String> {
    let period_s = base.timing.period_s;
    let p = &design.searched.pattern;
    let n = design.searched.outcome.periods.max(1);
    let sc = scenario_with(base, "speed", p.segments(n, period_s), n)?;
    let s = measure_speed(problem, p, n, &sc)?;
    print_speed(p, n, problem.period_s, &s);
    Ok(speed_json(&s))
}

/// Everything the printed result and the files of a design show.
#[derive(Clone, Copy)]
struct Summary<'a> {
    id: ConfigId,
    base: &'a Scenario,
    args: &'a DesignArgs,
    problem: &'a Problem,
    space: &'a Space,
    goal: Goal,
    design: &'a Design,
    best: &'a Pattern,
    designed: &'a Scenario,
    check: &'a [f64],
    ref_sigma: &'a [f64],
    met: bool,
    periods: u64,
    ref_periods: u64,
    period_s: f64,
    t_design: f64,
    t_ref: f64,
    max_rate: f64,
    max_duration: f64,
    coarse: &'a Outcome,
    coarse_periods: u64,
    coarse_change: f64,
    probe: Option<&'a DwellProbe>,
    unreached: &'a [OutOfReach],
    /// The shortest-path search found no path reaching every target; the
    /// result is the budget search's within the duration limit.
    fallback: bool,
}

/// How far past the duration limit (× the limit) the designed pattern is
/// repeated to tell when a target out of reach is met.
const OUT_OF_REACH_HORIZON: u64 = 10;

/// The printed result: headline, path, targets, search, dwell probe.
fn print_result(o: &Summary<'_>) {
    print_headline(o);
    print_path(o);
    print_targets(o);
    print_unreached(o);
    print_search(o);
    print_probe(o);
}

/// The limits and the headline: the reach time, or the best ratio within the budget.
fn print_headline(o: &Summary<'_>) {
    let Summary {
        id,
        base,
        args,
        problem,
        goal,
        check,
        ref_sigma,
        met,
        periods,
        ref_periods,
        period_s,
        t_design,
        t_ref,
        max_rate,
        max_duration,
        ..
    } = *o;
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
            "\n{}Best worst-case σ/target within {} s: {:.3} (the reference path in its {t_ref} s: {:.3})",
            if o.fallback {
                "The shortest-path search found none: no path of its stage 1 (the coarse grammar) reaches every target within the duration limit, and its refinement starts from those; instead, the budget search over the same space:\n"
            } else {
                ""
            },
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
}

/// The designed pattern and its segments.
fn print_path(o: &Summary<'_>) {
    let Summary { best, designed, .. } = *o;
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
}

/// Per target: the target, the reference and the designed σ (″; with the
/// full model, an instrument term in its printed unit, in a unit column).
fn print_targets(o: &Summary<'_>) {
    let Summary {
        problem,
        check,
        ref_sigma,
        ..
    } = *o;
    let names = o.id.states_with(problem.errors);
    let full = problem.errors == ErrorModel::Full;
    if full {
        println!(
            "\n  {:<10} {:<6} {:>12} {:>14} {:>14} {:>8}",
            "state", "unit", "target", "reference", "designed", "σ/target"
        );
    } else {
        println!(
            "\n  {:<10} {:>12} {:>14} {:>14} {:>8}",
            "state", "target ″", "reference ″", "designed ″", "σ/target"
        );
    }
    for &(i, t) in &problem.targets {
        let g = names[i].group;
        let unit = if full {
            format!(" {:<6}", g.printed_scale().1)
        } else {
            String::new()
        };
        println!(
            "  {:<10}{unit} {:>12.4} {:>14.4} {:>14.4} {:>8.3}",
            names[i].name,
            printed_value(g, t),
            printed_value(g, ref_sigma[i]),
            printed_value(g, check[i]),
            check[i] / t
        );
    }
    if full {
        println!("  (targets: the installation errors at the reference path's σ_CRLB of the installation model, the instrument terms at dg 0.005 °/h, Dg 0.005 °/h/g, kg 1 ppm, ba 1 µg, ka 1 ppm{}; reference and designed σ: `host-sim observability --errors full --scenario` of the reference and the written scenario)",
            if o.args.target_scale == 1.0 { String::new() } else { format!(", × {}", o.args.target_scale) });
    } else {
        println!("  (designed σ: `host-sim observability --scenario` of the written scenario)");
    }
}

/// The full model: each target out of reach within the limits, the σ the
/// bound reaches, and the time or rate that reaches it.
fn print_unreached(o: &Summary<'_>) {
    let Summary {
        problem,
        unreached,
        max_rate,
        max_duration,
        ..
    } = *o;
    if problem.errors != ErrorModel::Full {
        return;
    }
    if unreached.is_empty() {
        // Period by period, when the designed pattern first meets them all.
        let first = problem
            .evaluate(o.best, Goal::Reach { cutoff: o.periods }, true, false)
            .reach
            .map_or(String::new(), |r| {
                format!(
                    "; the designed pattern meets them all at {} s",
                    r as f64 * o.period_s
                )
            });
        println!("\n  Every target is met within the limits (rate ≤ {max_rate} °/s, {max_duration} s){first}.");
        return;
    }
    let names = o.id.states_with(problem.errors);
    println!(
        "\n  Out of reach within the limits (rate ≤ {max_rate} °/s, {max_duration} s), by the bound (σ_CRLB):"
    );
    for u in unreached {
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
            Some((r, s)) => format!(
                "; at {r} °/s (the same angles) it reaches {:.4} {unit} within {max_duration} s",
                printed_value(g, s)
            ),
            None => format!(
                "; no rate up to 10 °/s of the same angles reaches it within {max_duration} s"
            ),
        };
        println!(
            "    {:<10} target {:.4} {unit}, reached {:.4} {unit} ({:.2}× the target): {time}{rate}",
            names[u.state].name,
            printed_value(g, u.target),
            printed_value(g, u.sigma),
            u.sigma / u.target
        );
    }
}

/// The search statistics, the coarse steps and the optimality.
fn print_search(o: &Summary<'_>) {
    let Summary {
        space,
        goal,
        design,
        period_s,
        max_rate,
        coarse,
        coarse_periods,
        coarse_change,
        ..
    } = *o;
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
}

/// The dwell probe, when run.
fn print_probe(o: &Summary<'_>) {
    let Summary { goal, probe, .. } = *o;
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
}

/// Writes the designed scenario (`--out`, default `NAME.toml`).
fn write_scenario(o: &Summary<'_>, name: &str) -> Result<(), String> {
    let Summary {
        id,
        args,
        goal,
        best,
        designed,
        t_design,
        t_ref,
        ..
    } = *o;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{name}.toml")));
    let full = if o.problem.errors == ErrorModel::Full {
        " --errors full"
    } else {
        ""
    };
    let header = format!(
        "# Designed by `host-sim design --config {id}{full}` (rollcal): {}\n# reaches {} in {t_design} s (reference path: {t_ref} s); check with\n#   host-sim observability{full} --scenario {}\n",
        best.describe(),
        match goal {
            Goal::Reach { .. } => "every target".to_string(),
            Goal::Budget { .. } => "the best worst-case σ/target of the budget".to_string(),
        },
        out.display()
    );
    std::fs::write(&out, scenario_toml(designed, &header)?)
        .map_err(|e| format!("cannot write {}: {e}", out.display()))?;
    println!("\nWrote the designed scenario to {}", out.display());
    Ok(())
}

/// Writes the σ(t) figure (`--figure`, default `NAME.png`), designed against reference.
fn write_figure(
    o: &Summary<'_>,
    name: &str,
    fine_rec: &Outcome,
    ref_out: &Outcome,
) -> Result<(), String> {
    let Summary {
        id,
        args,
        problem,
        t_design,
        t_ref,
        ..
    } = *o;
    let names = id.states_with(problem.errors);
    let fig = args
        .figure
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{name}.png")));
    let series: Vec<crate::output::plots::SigmaCurve> = problem
        .targets
        .iter()
        .map(|&(i, t)| crate::output::plots::SigmaCurve {
            label: names[i].name,
            target: printed_value(names[i].group, t),
            a: fine_rec
                .history
                .iter()
                .map(|h| (h.0, printed_value(names[i].group, h.1[i])))
                .collect(),
            b: ref_out
                .history
                .iter()
                .map(|h| (h.0, printed_value(names[i].group, h.1[i])))
                .collect(),
        })
        .collect();
    // The angles in the figure; with the full model, the instrument terms
    // (their printed units) in a second one beside it, `<figure>-instruments.png`.
    let (angles, instruments): (Vec<_>, Vec<_>) = series
        .into_iter()
        .zip(&problem.targets)
        .partition(|(_, &(i, _))| !names[i].group.is_instrument());
    let title =
        format!("{id}: σ_CRLB(t), designed path ({t_design} s) vs reference path ({t_ref} s)");
    let mut figures = vec![(fig.clone(), angles, title.clone(), "″")];
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
        crate::output::plots::plot_sigma_comparison_in(
            &path,
            &title,
            "designed",
            "reference",
            &curves,
            unit,
        )?;
        println!("Wrote the σ(t) figure to {}", path.display());
    }
    Ok(())
}

/// The JSON of the result (`--json`).
fn result_json(o: &Summary<'_>, speed: serde_json::Value, wall_s: f64) -> serde_json::Value {
    let Summary {
        id,
        base,
        args,
        problem,
        space,
        goal,
        design,
        best,
        designed,
        check,
        ref_sigma,
        met,
        period_s,
        t_design,
        t_ref,
        max_rate,
        max_duration,
        coarse,
        coarse_change,
        probe,
        unreached,
        ..
    } = *o;
    let names = id.states_with(problem.errors);
    let mut json = serde_json::json!({
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
        "wall_s": wall_s,
    });
    // The full model only (the installation document stays as it was): the
    // error model, each instrument target's internal unit (`target_rad`
    // &c. hold rad/s, rad/s/g, 1 or g there), and the targets out of reach.
    if problem.errors == ErrorModel::Full {
        if let Some(m) = json.as_object_mut() {
            m.insert("errors".into(), problem.errors.as_str().into());
            if let Some(serde_json::Value::Array(ts)) = m.get_mut("targets") {
                for (t, &(i, _)) in ts.iter_mut().zip(&problem.targets) {
                    if let (Some(t), true) = (t.as_object_mut(), names[i].group.is_instrument()) {
                        t.insert("unit".into(), names[i].unit.into());
                    }
                }
            }
            m.insert(
                "out_of_reach".into(),
                unreached
                    .iter()
                    .map(|u| {
                        serde_json::json!({
                        "state": names[u.state].name, "target": u.target, "sigma": u.sigma,
                        "time_s": u.time_s, "horizon_s": u.horizon_s,
                        "rate_deg_s": u.rate.map(|r| r.0), "sigma_at_rate": u.rate.map(|r| r.1)})
                    })
                    .collect::<Vec<_>>()
                    .into(),
            );
        }
    }
    json
}

/// Writes σ(t) of every target state, designed and reference, as CSV.
fn write_sigma_csv(
    path: &std::path::Path,
    problem: &Problem,
    a: &Outcome,
    b: &Outcome,
) -> Result<(), String> {
    use std::fmt::Write;
    let names = problem.config.states_with(problem.errors);
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

/// Prints which rotations excite which parameter groups (`--explain`).
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

/// Prints the speed of the bound against the estimator (`--measure-speed`).
fn print_speed(best: &Pattern, periods: u64, period_s: f64, s: &Speed) {
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

/// The JSON of the speed measurement.
fn speed_json(s: &Speed) -> serde_json::Value {
    serde_json::json!({
        "bound_eval_s": s.bound_eval_s, "bound_eval_fine_s": s.bound_eval_fine_s, "step_periods": s.step_periods,
        "estimator_run_s": s.estimator_run_s, "estimator_passes": s.estimator_passes, "ratio": s.estimator_run_s / s.bound_eval_s,
        "simulation_s": s.simulation_s, "ratio_with_simulation": (s.simulation_s + s.estimator_run_s) / s.bound_eval_s,
        "full_evaluations_per_minute": s.full_evaluations_per_minute, "threads": s.threads})
}
