//! `host-sim run`: one configuration's estimator on a simulated scenario,
//! its final table, and the JSON, CSV, matrices and HTML report asked for.

use std::path::PathBuf;
use std::time::Instant;

use rollcal::models::ConfigId;

use super::args::{load_scenario, parse_config, CommonArgs};
use super::Error;
use crate::analysis::runner::SimulatedRun;
use crate::output::report::{print_table, run_json, write_csv, write_json};
use crate::sim::truth::{simulate, SimOptions};

/// Arguments of `host-sim run`.
#[derive(clap::Args)]
pub struct RunArgs {
    /// Configuration: M1-pa, M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps (case-insensitive).
    #[arg(long, value_parser = parse_config)]
    pub config: ConfigId,
    #[command(flatten)]
    pub common: CommonArgs,
    /// Write the final states as JSON to PATH.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// Write the time history (t, then estimate and σ of every state) as CSV to PATH.
    #[arg(long, value_name = "PATH")]
    pub csv: Option<PathBuf>,
    #[command(flatten)]
    pub matrices: super::matrices::MatricesArgs,
    /// Write an HTML report to DIR/index.html (created if missing), with its
    /// PNG figures beside it: parameter table, σ(t), error, NIS and
    /// innovation figures with the segment switches, consistency checks.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
}

/// `host-sim run`.
pub fn command(args: &RunArgs) -> Result<(), Error> {
    let c = &args.common;
    let scenario = load_scenario(c.scenario.as_deref())?;
    super::args::note_instrument_prior(&scenario, c.errors);
    super::args::warn_full_first_pass(c);
    let earth_rate = !c.no_earth_rate && scenario.site.earth_rate;
    if let Some(dir) = &args.report {
        crate::output::html::prepare_dir(dir)?;
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
    crate::sim::truth::check_gimbal_lock(args.config, &sim)?;
    eprintln!("running {} estimator…", args.config);
    let run = SimulatedRun::new(args.config, &scenario, &sim, earth_rate).with_errors(c.errors);
    let r = run
        .run(
            c.estimator(),
            None,
            args.csv.is_some() || args.report.is_some(),
        )
        .map_err(|e| format!("cannot start the filter: {e}"))?;
    let crlb = run.crlb().map_err(|e| format!("Cramér–Rao bound: {e}"))?;
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
        let page = crate::output::html::report_of_run(
            dir, &r, &scenario, &sim, earth_rate, &crlb, header,
        )?;
        eprintln!("report: {}", page.display());
    }
    Ok(())
}
