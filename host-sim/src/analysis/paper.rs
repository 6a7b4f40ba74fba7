//! `host-sim paper`: the whole paper regenerated — observability tables with
//! the Earth rate on and off, every configuration's estimator run, one figure
//! per configuration and parameter group, and `summary.md`/`summary.json`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use rollcal::models::{ConfigId, ErrorModel, Group, StateInfo};

use crate::analysis::observe::{self, ConfigObs};
use crate::analysis::runner::{expected_observable, Estimator, RunResult, SimulatedRun};
use crate::analysis::verdict::Verdict;
use crate::analysis::Error;
use crate::output::plots::{plot_group_marked, Curve};
use crate::sim::instruments::{printed_unit, printed_value};
use crate::sim::scenario::Scenario;
use crate::sim::truth::{simulate, SimOptions, Simulation};

/// One state of the summary.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SummaryState {
    /// State name (as in the `run` JSON).
    pub name: &'static str,
    /// Group name.
    pub group: &'static str,
    /// The state's group and printed unit (the `*_rad` values of an
    /// instrument state are in its internal unit, `unit` below).
    #[serde(skip)]
    pub info: rollcal::models::StateInfo,
    /// The internal unit of an instrument state's `*_rad` values (`rad/s`,
    /// `rad/s/g`, `1`, `g`); absent for the angles.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<&'static str>,
    /// Truth at the end of the run (rad).
    pub truth_rad: f64,
    /// Estimate (rad).
    pub estimate_rad: f64,
    /// Estimate − truth (rad; wrapped).
    pub error_rad: f64,
    /// Final filter σ (rad).
    pub sigma_filter_rad: f64,
    /// Posterior Cramér–Rao σ (rad).
    pub sigma_crlb_rad: f64,
    /// The verdict of the run.
    pub verdict: Verdict,
    /// Observable in practice with the Earth rate off (the paper's assumption).
    pub observable_earth_off: bool,
    /// Observable in practice with the Earth rate on.
    pub observable_earth_on: bool,
    /// The paper's claim (docs/model.md §Configurations), for installation errors and λ; `null`
    /// for the attitude states, on which the paper claims nothing per axis.
    pub paper_observable: Option<bool>,
    /// Whether the Earth-off analysis agrees with the paper's claim.
    pub agrees_with_paper: Option<bool>,
}

/// One configuration of the summary.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SummaryConfig {
    /// Configuration id.
    pub config: &'static str,
    /// Passes the estimator ran.
    pub passes: u8,
    /// Mean NIS of the final pass.
    pub mean_nis: f64,
    /// Failed updates.
    pub failed_updates: usize,
    /// Per state.
    pub states: Vec<SummaryState>,
    /// Figures written (paths relative to the output directory).
    pub figures: Vec<String>,
}

/// Everything `paper` computes.
pub struct Paper {
    /// Scenario name.
    pub scenario: String,
    /// The command line that regenerates these outputs (see [`reproduce_command`]).
    pub command: String,
    /// Seed of the noise.
    pub seed: u64,
    /// Whether the runs had the Earth rate.
    pub earth_rate: bool,
    /// The error model of the analyses and runs.
    pub errors: ErrorModel,
    /// Observability with the Earth rate off.
    pub obs_off: Vec<ConfigObs>,
    /// Observability with the Earth rate on (as the runs).
    pub obs_on: Vec<ConfigObs>,
    /// Per configuration.
    pub configs: Vec<SummaryConfig>,
    /// Wall time of the seven estimator runs (s, in parallel).
    pub runs_wall_s: f64,
    /// Total wall time (s).
    pub wall_s: f64,
}

/// The groups plotted, in the paper's order, with their file-name stems.
const GROUPS: [(Group, &str); 6] = [
    (Group::ThetaAT, "thaT"),
    (Group::ThetaAC, "thaC"),
    (Group::ThetaGT, "thgT"),
    (Group::ThetaGC, "thgC"),
    (Group::Lambda, "lam"),
    (Group::Attitude, "attitude"),
];

fn figure_title(id: ConfigId, g: Group) -> String {
    format!(
        "{id}: {} — estimation error, ±3σ filter, ±3σ_CRLB",
        crate::output::groups::title(g)
    )
}

/// Writes the figures of one run; returns their file names.
fn figures(
    out: &Path,
    run: &RunResult,
    obs: &ConfigObs,
    truth: &[Vec<f64>],
) -> Result<Vec<String>, Error> {
    let id = run.config;
    let t: Vec<f64> = run.history.iter().map(|h| h.0).collect();
    let mut names = Vec::new();
    // The installation groups in the paper's order, then every other group
    // of the run (the full model's instrument terms) in state order.
    let infos: Vec<StateInfo> = run.states.iter().map(|s| s.info).collect();
    let mut groups: Vec<(Group, &str)> = GROUPS.to_vec();
    for g in crate::output::groups::in_order(infos.iter().map(|s| s.group)) {
        if !groups.iter().any(|(h, _)| *h == g) {
            groups.push((g, g.as_str()));
        }
    }
    for (g, stem) in groups {
        let idx: Vec<usize> = (0..infos.len()).filter(|&i| infos[i].group == g).collect();
        if idx.is_empty() {
            continue;
        }
        let show = |v: f64| printed_value(g, v);
        let series: Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> = idx
            .iter()
            .map(|&i| {
                let err = run
                    .history
                    .iter()
                    .zip(truth)
                    .map(|(h, tr)| {
                        let d = h.1[i] - tr.get(i).copied().unwrap_or(f64::NAN);
                        show(if g.unit() == "rad" {
                            rollcal::geometry::wrap_angle(d)
                        } else {
                            d
                        })
                    })
                    .collect();
                let sig = run.history.iter().map(|h| show(h.2[i])).collect();
                let crlb = obs
                    .crlb_history
                    .iter()
                    .map(|c| c.get(i).map_or(f64::NAN, |v| show(*v)))
                    .collect();
                (err, sig, crlb)
            })
            .collect();
        let curves: Vec<Curve<'_>> = idx
            .iter()
            .zip(&series)
            .map(|(&i, (e, s, c))| Curve {
                label: infos[i].name,
                unit: printed_unit(g),
                error: e,
                sigma: s,
                crlb: c,
            })
            .collect();
        let file = format!("{}-{stem}.png", id.as_str());
        plot_group_marked(
            &out.join(&file),
            &figure_title(id, g),
            &t,
            &curves,
            &crate::sim::segments::switch_times(&run.segments),
        )
        .map_err(Error::Figure)?;
        names.push(file);
    }
    Ok(names)
}

fn summarise(
    run: &RunResult,
    off: &ConfigObs,
    on: &ConfigObs,
    earth_rate: bool,
    figures: Vec<String>,
) -> SummaryConfig {
    let id = run.config;
    let at_run = if earth_rate { on } else { off };
    let states = run
        .states
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let group = s.info.group;
            let observable = at_run.states[i].observable;
            let verdict = crate::analysis::verdict::special(group, s.prior)
                .unwrap_or_else(|| crate::analysis::verdict::against_truth(observable, s.ratio()));
            // The paper claims nothing per attitude axis, nor of the
            // instruments' own errors (taken as calibrated).
            let paper = (group != Group::Attitude && !group.is_instrument())
                .then(|| expected_observable(id, s.name, group));
            SummaryState {
                name: s.name,
                group: s.group,
                info: s.info,
                unit: group.is_instrument().then_some(s.info.unit),
                truth_rad: s.truth_rad,
                estimate_rad: s.estimate_rad,
                error_rad: s.error(),
                sigma_filter_rad: s.sigma_rad,
                sigma_crlb_rad: at_run.states[i].sigma_crlb_rad,
                verdict,
                observable_earth_off: off.states[i].observable,
                observable_earth_on: on.states[i].observable,
                paper_observable: paper,
                agrees_with_paper: paper.map(|p| p == off.states[i].observable),
            }
        })
        .collect();
    let n = run.nis.len().max(1) as f64;
    SummaryConfig {
        config: id.as_str(),
        passes: run.passes,
        mean_nis: run.nis.iter().sum::<f64>() / n,
        failed_updates: run.failures.len(),
        states,
        figures,
    }
}

/// The command line that regenerates `paper`'s outputs from a clone of the
/// repository: the scenario file (when one was given, as it was given), the
/// seed and the output directory (when not the default `paper-out`).
pub fn reproduce_command(
    scenario_path: Option<&Path>,
    seed: u64,
    out: &Path,
    errors: ErrorModel,
) -> String {
    let mut c = format!("cargo run --release -p host-sim -- paper --seed {seed}");
    if errors != ErrorModel::Installation {
        c.push_str(&format!(" --errors {}", errors.as_str()));
    }
    if let Some(p) = scenario_path {
        c.push_str(&format!(" --scenario {}", p.display()));
    }
    if out != Path::new("paper-out") {
        c.push_str(&format!(" --out {}", out.display()));
    }
    c
}

/// Runs everything and writes it into `out` (created if missing).
/// `scenario_path` is the file `scenario` was read from (`None`: the
/// built-in paper scenario), for the command line written into the summary.
/// `errors` is the error model of every analysis and run (the figures show
/// the installation groups). `progress(what)` is called as tasks finish.
pub fn paper(
    scenario: &Scenario,
    scenario_path: Option<&Path>,
    seed: u64,
    out: &Path,
    errors: ErrorModel,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<Paper, Error> {
    let t0 = std::time::Instant::now();
    std::fs::create_dir_all(out).map_err(|source| Error::Create {
        path: out.display().to_string(),
        source,
    })?;
    let earth_rate = scenario.site.earth_rate;
    let sim_for = |seed: u64, noise: bool, er: bool| {
        simulate(
            scenario,
            SimOptions {
                seed,
                noise,
                earth_rate: er,
            },
        )
    };
    let (sim, (clean_on, clean_off)) = rayon::join(
        || sim_for(seed, true, earth_rate),
        || {
            rayon::join(
                || sim_for(0, false, earth_rate),
                || sim_for(0, false, false),
            )
        },
    );
    progress("simulated the truth");
    let analyse = |sim: &Simulation, er: bool, hist: bool| -> Result<Vec<ConfigObs>, Error> {
        ConfigId::ALL
            .par_iter()
            .map(|&id| {
                let run = SimulatedRun::new(id, scenario, sim, er).with_errors(errors);
                let r = observe::analyse_run(run, hist).map_err(|e| Error::filter(id, e));
                progress(&format!(
                    "observability of {id} (Earth rate {})",
                    if er { "on" } else { "off" }
                ));
                r
            })
            .collect()
    };
    let obs_on = analyse(&clean_on, earth_rate, true)?;
    let obs_off = analyse(&clean_off, false, false)?;
    let t_runs = std::time::Instant::now();
    let runs: Vec<RunResult> = ConfigId::ALL
        .par_iter()
        .map(|&id| {
            let r = SimulatedRun::new(id, scenario, &sim, earth_rate)
                .with_errors(errors)
                .run(Estimator::default(), None, true)
                .map_err(|e| Error::filter(id, e));
            progress(&format!("estimator run of {id}"));
            r
        })
        .collect::<Result<_, _>>()?;
    let runs_wall_s = t_runs.elapsed().as_secs_f64();
    let configs: Vec<SummaryConfig> = runs
        .par_iter()
        .zip(obs_on.par_iter().zip(obs_off.par_iter()))
        .map(|(run, (on, off))| {
            let truth = SimulatedRun::new(run.config, scenario, &sim, earth_rate)
                .with_errors(errors)
                .truth_history();
            let figs = figures(out, run, on, &truth)?;
            progress(&format!("figures of {}", run.config));
            Ok(summarise(run, off, on, earth_rate, figs))
        })
        .collect::<Result<_, Error>>()?;
    let paper = Paper {
        scenario: scenario.name.clone(),
        command: reproduce_command(scenario_path, seed, out, errors),
        seed,
        earth_rate,
        errors,
        obs_off,
        obs_on,
        configs,
        runs_wall_s,
        wall_s: t0.elapsed().as_secs_f64(),
    };
    write_outputs(out, &paper)?;
    Ok(paper)
}

/// Number of progress steps [`paper`] reports.
pub const PROGRESS_STEPS: u64 = 1 + 7 + 7 + 7 + 7;

fn write_outputs(out: &Path, p: &Paper) -> Result<(), Error> {
    let write = |name: &str, text: String| -> Result<PathBuf, Error> {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|source| Error::Write {
            path: path.display().to_string(),
            source,
        })?;
        Ok(path)
    };
    let mut json = serde_json::json!({
        "scenario": p.scenario,
        "command": p.command,
        "seed": p.seed,
        "earth_rate": p.earth_rate,
        "configs": p.configs,
    });
    if p.errors != ErrorModel::Installation {
        json["errors"] = p.errors.as_str().into();
    }
    write(
        "summary.json",
        serde_json::to_string_pretty(&json).map_err(Error::Json)? + "\n",
    )?;
    for (name, obs, er) in [
        ("observability-earth-off.json", &p.obs_off, false),
        ("observability-earth-on.json", &p.obs_on, true),
    ] {
        let v = observe::report_json(er, obs);
        write(
            name,
            serde_json::to_string_pretty(&v).map_err(Error::Json)? + "\n",
        )?;
    }
    write("summary.md", summary_markdown(p))?;
    Ok(())
}

/// The Markdown summary (also what `paper` prints, without the per-state
/// tables).
pub fn summary_markdown(p: &Paper) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# rollcal: the paper's scenario regenerated\n\nScenario `{}`, seed {}, Earth rate {}. \
         Generated by `{}`.\n",
        p.scenario,
        p.seed,
        if p.earth_rate { "on" } else { "off" },
        p.command
    );
    s.push_str(&overview_markdown(p));
    let _ = writeln!(
        s,
        "\n## Which errors can each model observe?\n\n### Earth rate off (the paper's assumption)\n\n{}",
        observe::verdict_matrix_markdown(&p.obs_off)
    );
    let _ = writeln!(
        s,
        "### Earth rate on\n\n{}",
        observe::verdict_matrix_markdown(&p.obs_on)
    );
    let _ = writeln!(s, "Cells: x y z (or 1 2 3) of each group. yes: observable in practice (σ_CRLB/σ_prior < 0.01); weak: outside the null space but above that ratio; no: in the null space of the information matrix.\n");
    let _ = writeln!(s, "What the Earth rate changes:\n");
    for l in observe::changes(&p.obs_off, &p.obs_on) {
        let _ = writeln!(s, "- {l}");
    }
    let _ = writeln!(s, "\nUnobservable combinations (Earth rate on / off):\n");
    for (on, off) in p.obs_on.iter().zip(&p.obs_off) {
        let fmt = |c: &ConfigObs| {
            if c.null_space.is_empty() {
                "none".to_string()
            } else {
                c.null_space
                    .iter()
                    .map(|t| format!("`{}`", observe::format_combination(t)))
                    .collect::<Vec<_>>()
                    .join("; ")
            }
        };
        let _ = writeln!(s, "- **{}** on: {}; off: {}", on.config, fmt(on), fmt(off));
    }
    for c in &p.configs {
        let _ = writeln!(
            s,
            "\n## {}\n\n{} pass(es), mean NIS {:.3}, {} failed updates.\n",
            c.config, c.passes, c.mean_nis, c.failed_updates
        );
        let _ = writeln!(
            s,
            "| state | unit | truth | estimate | error | σ filter | σ_CRLB | σ/σ_CRLB | verdict | paper | agrees |\n|---|---|---:|---:|---:|---:|---:|---:|---|---|---|"
        );
        for st in &c.states {
            let paper = match st.paper_observable {
                Some(true) => "observable",
                Some(false) => "not observable",
                None => "—",
            };
            let agrees = match st.agrees_with_paper {
                Some(true) => "yes",
                Some(false) => "**no**",
                None => "—",
            };
            // Every state in its printed unit, named in the unit column.
            let show = |v| printed_value(st.info.group, v);
            let _ = writeln!(
                s,
                "| {} | {} | {:.3} | {:.3} | {:.4} | {:.4} | {:.4} | {:.3} | {} | {} | {} |",
                st.name,
                printed_unit(st.info.group),
                show(st.truth_rad),
                show(st.estimate_rad),
                show(st.error_rad),
                show(st.sigma_filter_rad),
                show(st.sigma_crlb_rad),
                st.sigma_filter_rad / st.sigma_crlb_rad,
                st.verdict.as_str(),
                paper,
                agrees
            );
        }
        if !c.figures.is_empty() {
            s.push('\n');
            for f in &c.figures {
                let _ = writeln!(s, "![{f}]({f})");
            }
        }
    }
    s
}

/// One line per configuration: verdict counts and agreement with the paper.
pub fn overview_markdown(p: &Paper) -> String {
    let mut s = String::from(
        "| config | converged | not observable | failed | agrees with paper | max \\|err\\|/σ (observable) | max σ/σ_CRLB (observable) | mean NIS |\n|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for c in &p.configs {
        let count = |v: Verdict| c.states.iter().filter(|s| s.verdict == v).count();
        let judged: Vec<_> = c
            .states
            .iter()
            .filter(|s| s.agrees_with_paper.is_some())
            .collect();
        let agree = judged
            .iter()
            .filter(|s| s.agrees_with_paper == Some(true))
            .count();
        let obs: Vec<_> = c
            .states
            .iter()
            .filter(|s| s.verdict != Verdict::NotObservable)
            .collect();
        let max_ratio = obs
            .iter()
            .map(|s| s.error_rad.abs() / s.sigma_filter_rad)
            .fold(0.0, f64::max);
        let max_eff = obs
            .iter()
            .map(|s| s.sigma_filter_rad / s.sigma_crlb_rad)
            .fold(0.0, f64::max);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {}/{} | {:.2} | {:.3} | {:.3} |",
            c.config,
            count(Verdict::Converged),
            count(Verdict::NotObservable),
            count(Verdict::Failed),
            agree,
            judged.len(),
            max_ratio,
            max_eff,
            c.mean_nis
        );
    }
    s
}

/// Whether every state agrees with the paper and none failed.
pub fn all_good(p: &Paper) -> bool {
    p.configs.iter().all(|c| {
        c.states
            .iter()
            .all(|s| s.verdict != Verdict::Failed && s.agrees_with_paper != Some(false))
    })
}

#[cfg(test)]
mod tests {
    use super::reproduce_command;
    use rollcal::models::ErrorModel;
    use std::path::Path;

    #[test]
    fn the_reproducing_command_carries_the_given_options() {
        let default = Path::new("paper-out");
        assert_eq!(
            reproduce_command(None, 1, default, ErrorModel::Installation),
            "cargo run --release -p host-sim -- paper --seed 1"
        );
        assert_eq!(
            reproduce_command(
                Some(Path::new("scenarios/southern-slow.toml")),
                7,
                Path::new("out"),
                ErrorModel::Installation
            ),
            "cargo run --release -p host-sim -- paper --seed 7 --scenario scenarios/southern-slow.toml --out out"
        );
    }
}
