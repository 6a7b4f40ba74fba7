//! `host-sim remedies`: the cold-start remedies compared over seeds and
//! scenarios ([`crate::analysis::remedies`]).

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

use super::Error;
use crate::analysis::remedies::{estimators, study, tally, CONFIGS};
use crate::output::progress::Progress;
use crate::sim::scenario::Scenario;

/// Arguments of `host-sim remedies`.
#[derive(clap::Args)]
pub struct RemediesArgs {
    /// Seeds per scenario (1..=N).
    #[arg(long, default_value_t = 8)]
    pub seeds: u64,
    /// Scenario files to add to the paper's scenario.
    #[arg(long = "scenario", value_name = "FILE")]
    pub scenarios: Vec<PathBuf>,
    /// Write the results as JSON to PATH.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
}

/// `host-sim remedies`.
pub fn command(args: &RemediesArgs) -> Result<(), Error> {
    if args.seeds == 0 {
        return Err("--seeds must be at least 1 (no seed, no run to report)".into());
    }
    let mut scenarios = vec![Scenario::paper()];
    for p in &args.scenarios {
        scenarios.push(Scenario::from_file(p).map_err(|e| e.to_string())?);
    }
    let remedies = estimators();
    let jobs = scenarios.len() as u64 * args.seeds;
    let progress = Progress::stderr("remedies", jobs, "seeds simulated and run");
    let done = AtomicU64::new(0);
    let results = study(&scenarios, args.seeds, &remedies, &|n| {
        done.fetch_max(n, Ordering::Relaxed);
        progress.update(n, "");
    });
    progress.finish(done.load(Ordering::Relaxed), "");
    let results = results?;
    println!(
        "Cold-start remedies: worst |error|/σ over the claimed parameters, per run; a run fails above 4σ.\n\
         {} scenario(s) × {} seeds, zero start, Earth rate as in each scenario.\n",
        scenarios.len(),
        args.seeds
    );
    print!("{:<36}", "remedy");
    for id in CONFIGS {
        print!(" {:>20}", format!("{id} fail / max"));
    }
    println!();
    let mut json = Vec::new();
    for (ri, (name, _)) in remedies.iter().enumerate() {
        print!("{name:<36}");
        for id in CONFIGS {
            let t = tally(&results, ri, id);
            let (fails, max) = (t.failures, t.max_ratio);
            print!(" {:>20}", format!("{fails}/{} {max:>8.2}", t.runs));
            json.push(serde_json::json!({"remedy": name, "config": id.as_str(), "runs": t.runs, "failures": fails, "max_ratio": max}));
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
