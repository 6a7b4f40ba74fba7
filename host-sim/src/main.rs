//! `host-sim`: the command-line tool of rollcal.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand, ValueEnum};
use host_sim::progress::Progress;
use host_sim::report::{group_of, print_table, run_json, write_csv, write_json};
use host_sim::runner::{expected_observable, run_filter, Precision};
use host_sim::scenario::Scenario;
use host_sim::truth::{simulate, SimOptions};
use rollcal::ekf::Options;
use rollcal::models::ConfigId;

#[derive(Parser)]
#[command(
    name = "host-sim",
    version,
    about = "Truth simulator and estimator runs for rollcal (continuous rolling self-calibration)",
    long_about = "Truth simulator and estimator runs for rollcal.\n\n\
        Without a subcommand, regenerates the whole paper (`paper`): observability tables, \
        all seven estimator runs on the paper's scenario (docs/model.md §The paper's scenario), figures and a summary \
        in ./paper-out/."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Run one configuration's estimator on a scenario and print the final table.
    Run(RunArgs),
    /// Run all seven configurations and print one summary line each.
    Summary(CommonArgs),
    /// Compare the cold-start remedies over seeds and scenarios (the study
    /// behind the default estimator; see README).
    Remedies(RemediesArgs),
    /// Observability of all seven configurations along the scenario's path:
    /// rank, unobservable combinations, Cramér–Rao σ and verdict per state.
    Observability(ObservabilityArgs),
    /// Seeded Monte Carlo runs of one configuration in parallel: RMS error
    /// against the Cramér–Rao bound, parameter-block NEES and NIS.
    Montecarlo(MonteCarloArgs),
    /// Design the rolling path: the shortest sequence of constant-rate
    /// rotations (each optionally followed by a dwell) whose Cramér–Rao σ
    /// reaches every target (default: the reference path's final σ), or the
    /// best within --budget-s; writes it as a scenario file and a σ(t)
    /// figure.
    Design(Box<host_sim::cli::design::DesignArgs>),
    /// Simulate a scenario and write it as a stream of wire frames
    /// (docs/wire.md) or, with --format csv, as a CSV log (docs/csv.md).
    Record(host_sim::stream::RecordArgs),
    /// Run the calibrator on a frame stream from a file, stdin or a serial
    /// port, or on a CSV log with a platform file (docs/csv.md).
    Calibrate(host_sim::stream::CalibrateArgs),
    /// False-alarm and detection rates of calibrate's data checks (without a
    /// truth) over seeds: a clean stream, accelerometer noise 3×, an
    /// unmodelled accelerometer bias.
    Checks(host_sim::checks::ChecksArgs),
    /// The whole paper regenerated (the default): observability tables with
    /// the Earth rate on and off, all seven estimator runs, one PNG figure
    /// per configuration and parameter group, summary.md and summary.json.
    Paper(PaperArgs),
}

#[derive(clap::Args)]
struct PaperArgs {
    /// Scenario file (TOML); default: the paper's scenario.
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// RNG seed of the noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR", default_value = "paper-out")]
    out: PathBuf,
}

#[derive(clap::Args)]
struct MonteCarloArgs {
    /// Configuration: M1-pa, M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps (case-insensitive).
    #[arg(long, value_parser = parse_config)]
    config: ConfigId,
    /// Number of runs (seeds 1..=N).
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u64).range(2..=100_000))]
    runs: u64,
    /// Scenario file (TOML); default: the paper's scenario.
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// Precision of the filter's covariance arithmetic (state, nominal and
    /// residuals are f64 in both).
    #[arg(long, value_enum, default_value_t = Precision::F64)]
    precision: Precision,
    /// Write the statistics as JSON to PATH.
    #[arg(long, value_name = "PATH")]
    json: Option<PathBuf>,
}

#[derive(clap::Args)]
struct ObservabilityArgs {
    /// Scenario file (TOML); default: the paper's scenario.
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// Switch the Earth rate off (the paper's assumption in its proofs).
    #[arg(long)]
    no_earth_rate: bool,
    /// Write the analysis as JSON to PATH.
    #[arg(long, value_name = "PATH")]
    json: Option<PathBuf>,
}

#[derive(clap::Args)]
struct RemediesArgs {
    /// Seeds per scenario (1..=N).
    #[arg(long, default_value_t = 8)]
    seeds: u64,
    /// Scenario files to add to the paper's scenario.
    #[arg(long = "scenario", value_name = "FILE")]
    scenarios: Vec<PathBuf>,
    /// Write the results as JSON to PATH.
    #[arg(long, value_name = "PATH")]
    json: Option<PathBuf>,
}

#[derive(clap::Args, Clone)]
struct CommonArgs {
    /// Scenario file (TOML); default: the paper's scenario (scenarios/paper.toml).
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// RNG seed of the noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Switch the Earth rate off (the paper's assumption in its proofs).
    #[arg(long)]
    no_earth_rate: bool,
    /// Cold-start remedy of the (first-pass) filter (for comparisons).
    #[arg(long, value_enum, default_value_t = Remedy::SecondOrder)]
    remedy: Remedy,
    /// At most this many passes over the data: 1 = extended filter only; each
    /// further pass is linearised about the previous pass's estimate, until
    /// the estimate moves by less than 0.1σ.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(1..=8))]
    passes: u8,
    /// Precision of the filter's covariance arithmetic (state, nominal and
    /// residuals are f64 in both).
    #[arg(long, value_enum, default_value_t = Precision::F64)]
    precision: Precision,
}

#[derive(clap::Args)]
struct RunArgs {
    /// Configuration: M1-pa, M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps (case-insensitive).
    #[arg(long, value_parser = parse_config)]
    config: ConfigId,
    #[command(flatten)]
    common: CommonArgs,
    /// Write the final states as JSON to PATH.
    #[arg(long, value_name = "PATH")]
    json: Option<PathBuf>,
    /// Write the time history (t, then estimate and σ of every state) as CSV to PATH.
    #[arg(long, value_name = "PATH")]
    csv: Option<PathBuf>,
    #[command(flatten)]
    matrices: host_sim::compensation::MatricesArgs,
    /// Write an HTML report to DIR/index.html (created if missing), with its
    /// PNG figures beside it: parameter table, σ(t), error, NIS and
    /// innovation figures with the segment switches, consistency checks.
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
}

/// Cold-start remedies (see the `ekf` module docs and the README).
#[derive(Clone, Copy, Debug, ValueEnum, PartialEq, Eq)]
enum Remedy {
    /// Second-order terms in the innovation covariance (the default).
    SecondOrder,
    /// Second-order covariance and second-order mean (Gaussian second-order filter).
    SecondOrderMean,
    /// Plain EKF (inconsistent from a zero start; for comparison).
    Plain,
    /// Iterated EKF: 5 iterations on the first 20 updates.
    Iekf,
    /// Iterated EKF on the first 20 updates plus second-order covariance.
    IekfSecondOrder,
    /// Second-order covariance terms of both the measurement and the dynamics.
    SecondOrderDynamics,
}

impl Remedy {
    fn options(self) -> Options {
        // Every remedy runs with the default NIS gate, as the default estimator.
        let plain = Options {
            nis_gate: rollcal::ekf::DEFAULT_NIS_GATE,
            ..Options::plain()
        };
        match self {
            Remedy::SecondOrder => Options::default(),
            Remedy::SecondOrderMean => Options {
                second_order_mean: true,
                ..Options::default()
            },
            Remedy::Plain => plain,
            Remedy::SecondOrderDynamics => Options {
                second_order_dynamics: true,
                ..Options::default()
            },
            Remedy::Iekf => Options {
                iterations: 5,
                iterate_updates: 20,
                ..plain
            },
            Remedy::IekfSecondOrder => Options {
                iterations: 5,
                iterate_updates: 20,
                ..Options::default()
            },
        }
    }
}

impl CommonArgs {
    fn estimator(&self) -> host_sim::runner::Estimator {
        host_sim::runner::Estimator {
            options: self.remedy.options(),
            passes: self.passes,
            precision: self.precision,
        }
    }
}

fn parse_config(s: &str) -> Result<ConfigId, String> {
    ConfigId::parse(s).ok_or_else(|| {
        let ids: Vec<&str> = ConfigId::ALL.iter().map(|c| c.as_str()).collect();
        format!(
            "unknown configuration '{s}' (expected one of {})",
            ids.join(", ")
        )
    })
}

fn load_scenario(path: Option<&Path>) -> Result<Scenario, String> {
    match path {
        Some(p) => Scenario::from_file(p).map_err(|e| e.to_string()),
        None => Ok(Scenario::paper()),
    }
}

fn main() -> ExitCode {
    // Die quietly on a closed pipe (`host-sim | head`) like other Unix tools,
    // instead of panicking in println!.
    #[cfg(unix)]
    // SAFETY: called first thing in main, before any thread exists; resets a
    // signal disposition to its default.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Run(args)) => cmd_run(&args),
        Some(Command::Summary(args)) => cmd_summary(&args),
        Some(Command::Remedies(args)) => cmd_remedies(&args),
        Some(Command::Observability(args)) => cmd_observability(&args),
        Some(Command::Montecarlo(args)) => cmd_montecarlo(&args),
        Some(Command::Paper(args)) => cmd_paper(&args),
        Some(Command::Design(args)) => host_sim::cli::design::command(&args),
        Some(Command::Record(args)) => host_sim::stream::record(&args),
        Some(Command::Calibrate(args)) => match host_sim::stream::calibrate_judged(&args) {
            // A data-model warning: its own exit status (README "Judging a
            // calibration without a truth").
            Ok(v) if v.is_warning() => return ExitCode::from(host_sim::checks::WARNING_EXIT),
            r => r.map(|_| ()),
        },
        Some(Command::Checks(args)) => host_sim::checks::command(&args),
        None => cmd_paper(&PaperArgs {
            scenario: None,
            seed: 1,
            out: PathBuf::from("paper-out"),
        }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("host-sim: error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn cmd_run(args: &RunArgs) -> Result<(), String> {
    let c = &args.common;
    let scenario = load_scenario(c.scenario.as_deref())?;
    let earth_rate = !c.no_earth_rate && scenario.site.earth_rate;
    if let Some(dir) = &args.report {
        host_sim::html::prepare_dir(dir)?;
    }
    let t0 = Instant::now();
    eprintln!(
        "simulating '{}' ({} periods, seed {})…",
        scenario.name,
        scenario.periods(),
        c.seed
    );
    let sim = simulate(
        &scenario,
        SimOptions {
            seed: c.seed,
            noise: true,
            earth_rate,
        },
    );
    host_sim::truth::check_gimbal_lock(args.config, &sim)?;
    eprintln!("running {} estimator…", args.config);
    let r = run_filter(
        args.config,
        &scenario,
        &sim,
        earth_rate,
        c.estimator(),
        None,
        args.csv.is_some() || args.report.is_some(),
    )
    .map_err(|e| format!("cannot start the filter: {e}"))?;
    let crlb = host_sim::runner::crlb_sigma(args.config, &scenario, &sim, earth_rate)
        .map_err(|e| format!("Cramér–Rao bound: {e}"))?;
    print_table(&r, &crlb);
    eprintln!("done in {:.2} s", t0.elapsed().as_secs_f64());
    if let Some(path) = &args.json {
        let json = run_json(&r, c.seed, earth_rate, scenario.timing.duration_s);
        write_json(path, &json)?;
    }
    if let Some(path) = &args.csv {
        write_csv(path, &r).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    args.matrices.write(&r)?;
    if let Some(dir) = &args.report {
        let header = vec![
            ("configuration".into(), r.config.to_string()),
            (
                "input".into(),
                format!("simulated '{}', seed {}", scenario.name, c.seed),
            ),
            (
                "Earth rate".into(),
                if earth_rate { "on" } else { "off" }.into(),
            ),
            ("passes".into(), r.passes.to_string()),
            ("precision".into(), c.precision.as_str().into()),
        ];
        let page =
            host_sim::html::report_of_run(dir, &r, &scenario, &sim, earth_rate, &crlb, header)?;
        eprintln!("report: {}", page.display());
    }
    Ok(())
}

fn cmd_summary(c: &CommonArgs) -> Result<(), String> {
    let scenario = load_scenario(c.scenario.as_deref())?;
    let earth_rate = !c.no_earth_rate && scenario.site.earth_rate;
    println!(
        "scenario '{}', seed {}, Earth rate {}, first-pass remedy {:?}, {} pass(es)",
        scenario.name,
        c.seed,
        if earth_rate { "on" } else { "off" },
        c.remedy,
        c.passes
    );
    println!(
        "{:<7} {:>6} {:>12} {:>16} {:>14} {:>9}",
        "config", "states", "within 3σ", "observable ≤4σ", "max |err|/σ", "wall s"
    );
    let t_all = Instant::now();
    let sim = simulate(
        &scenario,
        SimOptions {
            seed: c.seed,
            noise: true,
            earth_rate,
        },
    );
    for id in ConfigId::ALL {
        let t0 = Instant::now();
        let r = run_filter(id, &scenario, &sim, earth_rate, c.estimator(), None, false)
            .map_err(|e| format!("{id}: {e}"))?;
        let within = r.states.iter().filter(|s| s.ratio() <= 3.0).count();
        let obs: Vec<_> = r
            .states
            .iter()
            .filter(|s| expected_observable(id, s.name, group_of(s.group)))
            .collect();
        let obs_ok = obs.iter().filter(|s| s.ratio() <= 4.0).count();
        let max = r.states.iter().map(|s| s.ratio()).fold(0.0, f64::max);
        println!(
            "{:<7} {:>6} {:>9}/{:<2} {:>13}/{:<2} {:>14.2} {:>9.2}",
            id.as_str(),
            r.states.len(),
            within,
            r.states.len(),
            obs_ok,
            obs.len(),
            max,
            t0.elapsed().as_secs_f64()
        );
    }
    println!(
        "total wall time {:.2} s (simulation included)",
        t_all.elapsed().as_secs_f64()
    );
    Ok(())
}

fn cmd_remedies(args: &RemediesArgs) -> Result<(), String> {
    use host_sim::runner::Estimator;
    if args.seeds == 0 {
        return Err("--seeds must be at least 1 (no seed, no run to report)".into());
    }
    let mut scenarios = vec![Scenario::paper()];
    for p in &args.scenarios {
        scenarios.push(Scenario::from_file(p).map_err(|e| e.to_string())?);
    }
    let configs = [ConfigId::M1Pa, ConfigId::M4Pa, ConfigId::M2Ps];
    let remedies: Vec<(&str, Estimator)> = vec![
        (
            "plain EKF",
            Estimator {
                options: Remedy::Plain.options(),
                passes: 1,
                precision: Precision::F64,
            },
        ),
        (
            "IEKF (first 20 updates)",
            Estimator {
                options: Remedy::Iekf.options(),
                passes: 1,
                precision: Precision::F64,
            },
        ),
        (
            "2nd-order S",
            Estimator {
                options: Remedy::SecondOrder.options(),
                passes: 1,
                precision: Precision::F64,
            },
        ),
        (
            "2nd-order S + mean",
            Estimator {
                options: Remedy::SecondOrderMean.options(),
                passes: 1,
                precision: Precision::F64,
            },
        ),
        (
            "2nd-order S + dynamics",
            Estimator {
                options: Remedy::SecondOrderDynamics.options(),
                passes: 1,
                precision: Precision::F64,
            },
        ),
        (
            "IEKF + 2nd-order S",
            Estimator {
                options: Remedy::IekfSecondOrder.options(),
                passes: 1,
                precision: Precision::F64,
            },
        ),
        (
            "2nd-order S, then linearised passes",
            Estimator {
                options: Remedy::SecondOrder.options(),
                passes: 4,
                precision: Precision::F64,
            },
        ),
    ];
    // One job per (scenario, seed): simulate once, run every remedy and configuration.
    let jobs: Vec<(usize, u64)> = (0..scenarios.len())
        .flat_map(|i| (1..=args.seeds).map(move |s| (i, s)))
        .collect();
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new(Vec::new());
    let progress = Progress::stderr("remedies", jobs.len() as u64, "seeds simulated and run");
    let done = std::sync::atomic::AtomicU64::new(0);
    std::thread::scope(|scope| {
        for _ in 0..std::thread::available_parallelism().map_or(2, |n| n.get()) {
            scope.spawn(|| loop {
                let j = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(&(si, seed)) = jobs.get(j) else {
                    break;
                };
                let sc = &scenarios[si];
                let sim = simulate(
                    sc,
                    SimOptions {
                        seed,
                        noise: true,
                        earth_rate: sc.site.earth_rate,
                    },
                );
                for (ri, (_, est)) in remedies.iter().enumerate() {
                    for id in configs {
                        let worst =
                            match run_filter(id, sc, &sim, sc.site.earth_rate, *est, None, false) {
                                Ok(r) => r
                                    .states
                                    .iter()
                                    .filter(|s| expected_observable(id, s.name, group_of(s.group)))
                                    .map(|s| s.ratio())
                                    .fold(0.0, f64::max),
                                Err(_) => f64::INFINITY,
                            };
                        results
                            .lock()
                            .map(|mut v| v.push((si, seed, ri, id, worst)))
                            .ok();
                    }
                }
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress.update(n, "");
            });
        }
    });
    progress.finish(done.load(std::sync::atomic::Ordering::Relaxed), "");
    let results = results.into_inner().map_err(|e| e.to_string())?;
    println!(
        "Cold-start remedies: worst |error|/σ over the claimed parameters, per run; a run fails above 4σ.\n\
         {} scenario(s) × {} seeds, zero start, Earth rate as in each scenario.\n",
        scenarios.len(),
        args.seeds
    );
    print!("{:<36}", "remedy");
    for id in configs {
        print!(" {:>20}", format!("{id} fail / max"));
    }
    println!();
    let mut json = Vec::new();
    for (ri, (name, _)) in remedies.iter().enumerate() {
        print!("{name:<36}");
        for id in configs {
            let v: Vec<f64> = results
                .iter()
                .filter(|r| r.2 == ri && r.3 == id)
                .map(|r| r.4)
                .collect();
            let fails = v.iter().filter(|w| **w > 4.0).count();
            let max = v.iter().copied().fold(0.0, f64::max);
            print!(" {:>20}", format!("{fails}/{} {max:>8.2}", v.len()));
            json.push(serde_json::json!({"remedy": name, "config": id.as_str(), "runs": v.len(), "failures": fails, "max_ratio": max}));
        }
        println!();
    }
    for (i, sc) in scenarios.iter().enumerate() {
        println!("scenario {i}: {}", sc.name);
    }
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?;
        std::fs::write(path, text + "\n")
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    Ok(())
}

fn analyse_all(
    scenario: &Scenario,
    earth_rate: bool,
) -> Result<Vec<host_sim::observe::ConfigObs>, String> {
    let sim = simulate(
        scenario,
        SimOptions {
            seed: 0,
            noise: false,
            earth_rate,
        },
    );
    ConfigId::ALL
        .iter()
        .map(|&id| {
            host_sim::observe::analyse(id, scenario, &sim, earth_rate, false)
                .map_err(|e| format!("{id}: {e}"))
        })
        .collect()
}

fn cmd_observability(args: &ObservabilityArgs) -> Result<(), String> {
    use host_sim::observe::{changes, print_report, report_json, verdict_matrix_markdown};
    let scenario = load_scenario(args.scenario.as_deref())?;
    let earth_rate = !args.no_earth_rate && scenario.site.earth_rate;
    let t0 = Instant::now();
    eprintln!(
        "analysing 7 configurations along '{}' (Earth rate {})…",
        scenario.name,
        if earth_rate { "on" } else { "off" }
    );
    let configs = analyse_all(&scenario, earth_rate)?;
    print_report(&configs, earth_rate);
    println!(
        "
Verdicts (x y z per group; yes: observable in practice, weak: σ_CRLB/σ_prior ≥ 0.01, no: in the null space):\n"
    );
    print!("{}", verdict_matrix_markdown(&configs));
    if earth_rate {
        let off = analyse_all(&scenario, false)?;
        let lines = changes(&off, &configs);
        println!("\nWhat the Earth rate changes (against the paper's Earth-off analysis):");
        if lines.is_empty() {
            println!("  nothing");
        }
        for l in lines {
            println!("  {l}");
        }
    }
    eprintln!("done in {:.2} s", t0.elapsed().as_secs_f64());
    if let Some(path) = &args.json {
        write_json(path, &report_json(earth_rate, &configs))?;
    }
    Ok(())
}

fn cmd_montecarlo(args: &MonteCarloArgs) -> Result<(), String> {
    let scenario = load_scenario(args.scenario.as_deref())?;
    let runs = usize::try_from(args.runs).map_err(|e| e.to_string())?;
    eprintln!(
        "{} runs of {} on '{}' with {} threads…",
        runs,
        args.config,
        scenario.name,
        rayon::current_num_threads()
    );
    let progress = Progress::stderr("montecarlo", args.runs, "runs");
    let done = std::sync::atomic::AtomicU64::new(0);
    let mc = host_sim::montecarlo::monte_carlo(
        args.config,
        &scenario,
        runs,
        host_sim::runner::Estimator {
            precision: args.precision,
            ..host_sim::runner::Estimator::default()
        },
        &|n| {
            done.fetch_max(n as u64, std::sync::atomic::Ordering::Relaxed);
            progress.update(n as u64, "");
        },
    );
    progress.finish(done.load(std::sync::atomic::Ordering::Relaxed), "");
    let mc = mc?;
    host_sim::montecarlo::print_monte_carlo(&mc);
    if let Some(path) = &args.json {
        let v = serde_json::to_value(&mc).map_err(|e| e.to_string())?;
        write_json(path, &v)?;
    }
    Ok(())
}

fn cmd_paper(args: &PaperArgs) -> Result<(), String> {
    use host_sim::paper::{all_good, overview_markdown, paper, PROGRESS_STEPS};
    let scenario = load_scenario(args.scenario.as_deref())?;
    eprintln!(
        "regenerating the paper on '{}' (seed {}) into {}/ with {} threads…",
        scenario.name,
        args.seed,
        args.out.display(),
        rayon::current_num_threads()
    );
    let progress = Progress::stderr("paper", PROGRESS_STEPS, "steps");
    let done = std::sync::atomic::AtomicU64::new(0);
    let p = paper(
        &scenario,
        args.scenario.as_deref(),
        args.seed,
        &args.out,
        &|what| {
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress.update(n, what);
        },
    );
    progress.finish(
        done.load(std::sync::atomic::Ordering::Relaxed),
        if p.is_ok() { "done" } else { "failed" },
    );
    let p = p?;
    println!(
        "Scenario '{}', seed {}, Earth rate {}: {} periods; the seven estimator runs took {:.2} s \
         (in parallel), everything {:.2} s.\n",
        p.scenario,
        p.seed,
        if p.earth_rate { "on" } else { "off" },
        scenario.periods(),
        p.runs_wall_s,
        p.wall_s
    );
    println!("Which errors can each model observe? (Earth rate off, the paper's assumption)\n");
    print!("{}", host_sim::observe::verdict_matrix_markdown(&p.obs_off));
    println!("\nWith the Earth rate on:\n");
    print!("{}", host_sim::observe::verdict_matrix_markdown(&p.obs_on));
    println!("\nEstimator runs:\n");
    print!("{}", overview_markdown(&p));
    println!(
        "\nWrote {}/summary.md, summary.json, observability-earth-{{on,off}}.json and {} figures.",
        args.out.display(),
        p.configs.iter().map(|c| c.figures.len()).sum::<usize>()
    );
    if all_good(&p) {
        println!(
            "Every observable state converged within 4σ and every verdict agrees with the paper."
        );
        Ok(())
    } else {
        Err("some states failed or disagree with the paper: see summary.md".to_string())
    }
}
