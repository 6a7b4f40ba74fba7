//! `host-sim paper` (the default): the whole paper regenerated
//! ([`crate::analysis::paper`]) and its overview printed.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

use super::args::{load_scenario, note_instrument_prior, parse_errors};
use super::Error;
use crate::analysis::observe::verdict_matrix_markdown;
use crate::analysis::paper::{all_good, overview_markdown, paper, PROGRESS_STEPS};
use crate::output::progress::Progress;
use rollcal::models::ErrorModel;

/// Arguments of `host-sim paper`.
#[derive(clap::Args)]
pub struct PaperArgs {
    /// Scenario file (TOML); default: the paper's scenario.
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// RNG seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR", default_value = "paper-out")]
    pub out: PathBuf,
    /// Error model: `installation` (the paper's states) or `full` (followed
    /// by the instruments' 21 errors; docs/model.md §Full model). The
    /// figures show the installation groups.
    #[arg(long, default_value = "installation", value_parser = parse_errors)]
    pub errors: ErrorModel,
}

/// `host-sim paper`.
pub fn command(args: &PaperArgs) -> Result<(), Error> {
    let scenario = load_scenario(args.scenario.as_deref())?;
    note_instrument_prior(&scenario, args.errors);
    eprintln!(
        "regenerating the paper on '{}' (seed {}) into {}/ with {} threads…",
        scenario.name,
        args.seed,
        args.out.display(),
        rayon::current_num_threads()
    );
    let progress = Progress::stderr("paper", PROGRESS_STEPS, "steps");
    let done = AtomicU64::new(0);
    let p = paper(
        &scenario,
        args.scenario.as_deref(),
        args.seed,
        &args.out,
        args.errors,
        &|what| {
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress.update(n, what);
        },
    );
    progress.finish(
        done.load(Ordering::Relaxed),
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
    if args.errors == ErrorModel::Full {
        println!("Error model: full (the installation states and the instruments' 24 terms; the Gauss–Markov parts of the drift and the bias where the instruments wander).\n");
    }
    println!("Which errors can each model observe? (Earth rate off, the paper's assumption)\n");
    print!("{}", verdict_matrix_markdown(&p.obs_off));
    println!("\nWith the Earth rate on:\n");
    print!("{}", verdict_matrix_markdown(&p.obs_on));
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
        Err("some states failed or disagree with the paper: see summary.md".into())
    }
}
