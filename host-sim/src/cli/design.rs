//! `host-sim design`: its arguments ([`DesignArgs`]) and the command
//! ([`command`]) over the library's design ([`crate::design::run`]) and
//! its output ([`crate::output::design`]): the progress and notes on
//! stderr, the result on stdout, the files.

use std::path::PathBuf;
use std::sync::Mutex;

use rollcal::models::{ConfigId, ErrorModel};

use crate::design::{
    nominal_scenario, parse_target, run, Goal, Note, Observer, Request, Run, TargetArg,
    DEFAULT_STEP_DEG,
};
use crate::output::design as show;
use crate::output::progress::Progress;
use crate::sim::scenario::{Platform, Scenario};

/// Arguments of `host-sim design`.
#[derive(clap::Args, Clone, Debug)]
pub struct DesignArgs {
    /// Configuration: M1-pa, M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps
    /// (case-insensitive); optional when the platform file names one (it
    /// must then agree).
    #[arg(long, value_parser = super::args::parse_config)]
    pub config: Option<ConfigId>,
    /// Scenario file (TOML): site, noise, truth, timing, prior, and the
    /// reference path the targets default to; default: the paper's scenario.
    #[arg(long, value_name = "FILE", conflicts_with = "platform")]
    pub scenario: Option<PathBuf>,
    /// Platform file (TOML, docs/csv.md; the one `calibrate` reads): site,
    /// noise, period, prior, the instruments' prior and the path rolled
    /// today (`[[path]]`: the reference of the default targets; the
    /// paper's when absent). No truth: the bound at nominal values, zero
    /// installation errors and instrument terms (docs/path-design.md,
    /// "Your own platform").
    #[arg(long, value_name = "FILE")]
    pub platform: Option<PathBuf>,
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
    /// worst-case σ/target within the duration limit. With errors that
    /// wander (`[instruments.wander]`), each drift and bias target shows
    /// the floor no path of any length gets below and the log length past
    /// which rolling longer does not help; a target below its floor is
    /// listed out of reach with it and not searched for (exit status 1,
    /// the path to every other target written).
    /// Default: the platform file's `errors`, else `installation`.
    #[arg(long, value_parser = super::args::parse_errors)]
    pub errors: Option<ErrorModel>,
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

/// The reference scenario of `args`: the scenario file, the platform file
/// at nominal values (with its notes on stderr), or the paper's; with the
/// configuration and error model the platform file names, if any.
fn reference_of(
    args: &DesignArgs,
) -> Result<(Scenario, Option<ConfigId>, Option<ErrorModel>), String> {
    if let Some(p) = &args.scenario {
        return Ok((
            Scenario::from_file(p).map_err(|e| e.to_string())?,
            None,
            None,
        ));
    }
    let Some(path) = &args.platform else {
        return Ok((Scenario::paper(), None, None));
    };
    let platform = Platform::from_file(path).map_err(|e| e.to_string())?;
    let (scenario, paper_path) = nominal_scenario(&platform)?;
    eprintln!(
        "note: {}: the bound at nominal values (zero installation errors, initial gimbal angles and instrument terms; docs/path-design.md, \"Your own platform\")",
        path.display()
    );
    if paper_path {
        eprintln!(
            "note: {} has no [[path]]: the reference path (the default targets, the duration limit) is the paper's, {} s",
            path.display(),
            scenario.timing.duration_s
        );
    }
    Ok((scenario, platform.config_id(), platform.error_model()))
}

/// The configuration: `--config`, or the platform file's; both must agree.
fn config_of(args: &DesignArgs, platform: Option<ConfigId>) -> Result<ConfigId, String> {
    match (args.config, platform) {
        (Some(a), Some(b)) if a != b => Err(format!(
            "--config {a} contradicts the configuration {b} of the platform file {}",
            args.platform
                .as_deref()
                .unwrap_or(std::path::Path::new(""))
                .display()
        )),
        (Some(a), _) | (None, Some(a)) => Ok(a),
        (None, None) => {
            Err("give --config (or a platform file with config = \"…\", --platform FILE)".into())
        }
    }
}

/// The library's request of `args` for `config` and `errors`.
fn request_of(args: &DesignArgs, config: ConfigId, errors: ErrorModel) -> Request {
    Request {
        config,
        errors,
        targets: args.targets.clone(),
        target_scale: args.target_scale,
        max_rate_deg_s: args.max_rate_deg_s,
        max_duration_s: args.max_duration_s,
        max_beta_deg: args.max_beta_deg,
        axes: args.axes.clone(),
        tilted: args.tilted,
        max_rotations: args.max_rotations,
        refine_starts: args.refine_starts,
        dwells: !args.no_dwells,
        budget_s: args.budget_s,
        step_deg: args.step_deg,
    }
}

/// The search's progress and the design's notes on stderr.
#[derive(Default)]
struct Stderr {
    /// The progress of the running search and its last count.
    search: Mutex<Option<(Progress, u64)>>,
}

impl Observer for Stderr {
    fn search_started(&self) {
        if let Ok(mut s) = self.search.lock() {
            *s = Some((Progress::stderr("design", 1, "candidates"), 0));
        }
    }
    fn stage(&self, stage: &str, done: usize, total: usize) {
        if let Ok(mut s) = self.search.lock() {
            if let Some((progress, last)) = s.as_mut() {
                *last = done as u64;
                progress.stage(stage, done as u64, total as u64, "");
            }
        }
    }
    fn search_finished(&self) {
        if let Ok(mut s) = self.search.lock() {
            if let Some((progress, last)) = s.take() {
                progress.finish(last, "");
            }
        }
    }
    fn note(&self, note: &Note) {
        eprintln!("{note}");
    }
}

/// `--measure-speed`: the speed printed, and its JSON.
fn speed(r: &Run) -> Result<serde_json::Value, String> {
    let (p, n, s) = r.speed()?;
    show::print_speed(p, n, r.problem.period_s, &s);
    Ok(show::speed_json(&s))
}

/// Runs `host-sim design`.
pub fn command(args: &DesignArgs) -> Result<(), String> {
    let t_all = std::time::Instant::now();
    let (base, platform_config, platform_errors) = reference_of(args)?;
    let config = config_of(args, platform_config)?;
    let errors = args.errors.or(platform_errors).unwrap_or_default();
    if errors == ErrorModel::Full {
        super::args::note_instrument_prior(&base, errors);
    }
    let r = run(&request_of(args, config, errors), base, &Stderr::default())?;
    show::print_result(&r);
    if args.explain {
        show::print_explain(&r);
    }
    let speed = if args.measure_speed {
        speed(&r)?
    } else {
        serde_json::Value::Null
    };
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{}.toml", r.name)));
    show::write_scenario(&r, &out)?;
    let figure = args
        .figure
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{}.png", r.name)));
    show::write_figure(&r, &figure)?;
    if let Some(p) = &args.csv {
        show::write_sigma_csv(p, &r)?;
    }
    if let Some(p) = &args.json {
        let json = show::result_json(&r, speed, t_all.elapsed().as_secs_f64());
        crate::output::report::write_json(p, &json)?;
    }
    eprintln!("design: done in {:.1} s", t_all.elapsed().as_secs_f64());
    exit_status(&r, &out)
}

/// The exit status of a finished design: an error (status 1) when the
/// written path misses a target it was to meet: in the observability
/// check, out of reach within the limits (the shortest path to every
/// target was asked for and the budget search stood in), or below the
/// floor the wandering errors leave (out of reach of every path). A
/// budget (`--budget-s`) asks for the best path within it, not for the
/// targets: it succeeds whichever it meets.
fn exit_status(r: &Run, out: &std::path::Path) -> Result<(), String> {
    let below = r.below_floor.len();
    let of_them = if below > 0 {
        format!("; {below} of them below the floor the wandering errors leave, out of reach of any path")
    } else {
        String::new()
    };
    match r.goal {
        Goal::Reach { .. } if !r.checked.met => {
            Err("the designed path misses a target in the observability check".into())
        }
        // The shortest path to every target was asked for and none exists
        // within the limits: the best path within them is written, and the
        // exit status says the goal was not reached.
        Goal::Budget { .. } if r.fallback => Err(format!(
            "{} target(s) out of reach within the limits (listed above): the best path within them is written to {}{of_them}",
            r.unreached.len() + below,
            out.display()
        )),
        Goal::Reach { .. } if below > 0 => Err(format!(
            "{below} target(s) below the floor the wandering errors leave, out of reach of any path (listed above): {} to every other target is written to {}",
            if r.fallback { "a path" } else { "the shortest path" },
            out.display()
        )),
        _ => Ok(()),
    }
}
