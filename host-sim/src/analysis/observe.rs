//! The observability analysis of every configuration along a scenario's path
//! (docs/model.md §Observability), on top of [`rollcal::observability`].

use nalgebra::SVector;
use rollcal::ekf;
use rollcal::models::{ConfigId, ErrorModel, Group, Model};
use rollcal::observability::{
    Observability, Spectrum, COEF_THRESHOLD, PRACTICAL_RATIO, RANK_TOLERANCE,
};

use crate::analysis::runner::SimulatedRun;
use crate::analysis::Error;
use crate::sim::instruments::printed_value;
use crate::sim::scenario::Scenario;
use crate::sim::truth::Simulation;

/// One term of an unobservable combination.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Term {
    /// State name (as in the `run` JSON).
    pub state: &'static str,
    /// Coefficient of the normalised combination.
    pub coef: f64,
}

pub use crate::analysis::verdict::Verdict;

/// One state of the analysis.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StateObs {
    /// State name.
    pub name: &'static str,
    /// Its group name (e.g. `thgC`).
    #[serde(skip)]
    pub group: Group,
    /// The unit of `sigma_crlb_rad` of an instrument state of the full
    /// model (`rad/s`, `rad/s/g`, `1`, `g`); absent for the angles (rad).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<&'static str>,
    /// Posterior Cramér–Rao σ at the end of the path (rad).
    pub sigma_crlb_rad: f64,
    /// `σ_CRLB / σ_prior`.
    pub ratio: f64,
    /// Observable in practice: outside the null space and ratio < 0.01.
    pub observable: bool,
    /// Norm of the state's projection on the null space (zero-state
    /// linearisation).
    pub null_participation: f64,
    /// The same at the true state (non-zero on states that only the tilt of
    /// the null directions by the true errors touches).
    pub null_leak_at_truth: f64,
    /// The verdict.
    pub verdict: Verdict,
}

/// The analysis of one configuration.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ConfigObs {
    /// Configuration id.
    #[serde(serialize_with = "ser_config")]
    pub config: ConfigId,
    /// Error model (written only for the full model).
    #[serde(skip_serializing_if = "is_installation", serialize_with = "ser_errors")]
    pub errors: ErrorModel,
    /// Number of states of the structural analysis: those the model
    /// estimates as constants (not those of prior σ zero, held at zero, nor
    /// the nuisances of errors that wander: the Gauss–Markov parts and the
    /// warm-ups).
    pub n: usize,
    /// Numerical rank of the information matrix (zero-state linearisation).
    pub rank: usize,
    /// The same along the true trajectory.
    pub rank_at_truth: usize,
    /// Eigenvalues of the prior-scaled information matrix, decreasing.
    pub eigenvalues: Vec<f64>,
    /// Unobservable combinations (null-space basis, canonical form).
    pub null_space: Vec<Vec<Term>>,
    /// Per state.
    pub states: Vec<StateObs>,
    /// σ_CRLB (rad) of every state after every period, when asked for.
    #[serde(skip)]
    pub crlb_history: Vec<Vec<f64>>,
}

/// A configuration in JSON: its name (`"M1-pa"`).
pub(crate) fn ser_config<S: serde::Serializer>(c: &ConfigId, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(c.as_str())
}

/// Whether `e` is the installation model (the JSON key `errors` is then
/// left out, so that the installation documents stay as they were).
pub(crate) fn is_installation(e: &ErrorModel) -> bool {
    *e == ErrorModel::Installation
}

/// An error model in JSON: its name (`"full"`).
pub(crate) fn ser_errors<S: serde::Serializer>(e: &ErrorModel, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(e.as_str())
}

impl ConfigObs {
    /// Dimension of the null space.
    pub fn nullity(&self) -> usize {
        self.n - self.rank
    }
}

/// Formats a combination like `+0.577 psi_x +0.577 thgC_x +0.577 thaC_x`.
pub fn format_combination(terms: &[Term]) -> String {
    terms
        .iter()
        .map(|t| format!("{:+.3} {}", t.coef, t.state))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The prior of the structural analysis. The structure is that of the
/// states the model holds constant: the information matrix of the initial
/// state has no process noise, and the nuisances of errors that wander are
/// left out of it (prior σ 0, no wander), as are the states it does not
/// estimate: the Gauss–Markov parts (whose information the model forgets
/// at the rate 1/τ) and the warm-ups (told from a constant only by their
/// decay, which the structure's model without wander does not have).
fn structure_prior<const N: usize>(
    layout: &rollcal::models::Layout,
    prior: SVector<f64, N>,
) -> SVector<f64, N> {
    let nuisances = [
        layout.dg_gm(),
        layout.ba_gm(),
        layout.dg_wu(),
        layout.ba_wu(),
    ];
    let nuisance = |i: usize| {
        nuisances
            .into_iter()
            .flatten()
            .any(|first| (first..first + 3).contains(&i))
    };
    let mut p = prior;
    for (i, v) in p.iter_mut().enumerate() {
        if nuisance(i) {
            *v = 0.0;
        }
    }
    p
}

fn analyse_typed<M: Model<N, Z>, const N: usize, const Z: usize>(
    run: SimulatedRun,
    keep_history: bool,
) -> Result<ConfigObs, ekf::Error> {
    let (id, sim) = (run.config, run.sim);
    let cfg = run.filter_config(ekf::Options::plain());
    let truth0 = run.truth_at_start();
    let x0 = SVector::<f64, N>::from_iterator(truth0.iter().copied());
    let prior = SVector::<f64, N>::from_iterator(run.prior_sigma());
    let prior_struct = structure_prior(&M::LAYOUT, prior);
    let cfg_struct = ekf::FilterConfig {
        wander: rollcal::models::Wander::none(),
        ..cfg
    };
    let separate = prior_struct != prior || cfg_struct != cfg;
    // The bound, along the true trajectory.
    let mut obs = Observability::<f64, M, N, Z>::new(cfg, x0, prior)?;
    // The structure at the true state, when it is not the bound's model.
    let mut truth_struct = if separate {
        Some(Observability::<f64, M, N, Z>::new(
            cfg_struct,
            x0,
            prior_struct,
        )?)
    } else {
        None
    };
    // The structure, along the path linearised at zero state (the paper's
    // first-order analysis): there the null directions are exact
    // combinations of the named states. At the true state they tilt by the
    // errors themselves (coefficients ≈ 1e-3 on neighbouring states, e.g.
    // the λy null direction of M2-ps picks up 0.001 λx), which is reported
    // as `null_leak_at_truth`.
    let mut zero = Observability::<f64, M, N, Z>::new(cfg_struct, SVector::zeros(), prior_struct)?;
    let mut history = Vec::new();
    for s in &sim.samples {
        obs.step(&s.dtheta_cmd, s.dt)?;
        zero.step(&s.dtheta_cmd, s.dt)?;
        if let Some(t) = truth_struct.as_mut() {
            t.step(&s.dtheta_cmd, s.dt)?;
        }
        if keep_history {
            history.push(obs.crlb_sigma().iter().copied().collect());
        }
    }
    let spec: Spectrum<f64, N> = zero.analyse(RANK_TOLERANCE)?;
    let at_truth: Spectrum<f64, N> = truth_struct
        .as_ref()
        .unwrap_or(&obs)
        .analyse(RANK_TOLERANCE)?;
    let leak = at_truth.participation();
    let names = id.states_with(run.errors);
    let basis = spec.null_space_basis();
    // A state outside the structure (not estimated, or a Gauss–Markov
    // nuisance) is a zero row and column of the prior-scaled information: a
    // null direction of its own, which is not a combination of anything.
    // Left out of the null space and of the dimension.
    let estimated = |i: usize| prior_struct[i] > 0.0;
    let fixed = (0..N).filter(|&i| !estimated(i)).count();
    let null_space: Vec<Vec<Term>> = (0..spec.nullity())
        .map(|c| {
            basis
                .column(c)
                .iter()
                .zip(names)
                .enumerate()
                .filter(|(i, (v, _))| v.abs() > COEF_THRESHOLD && estimated(*i))
                .map(|(_, (v, info))| Term {
                    state: info.name,
                    coef: *v,
                })
                .collect()
        })
        .filter(|terms: &Vec<Term>| !terms.is_empty())
        .collect();
    let sigma = obs.crlb_sigma();
    let ratio = obs.ratio();
    let part = spec.participation();
    let states = names
        .iter()
        .enumerate()
        .map(|(i, info)| {
            let structural = part[i] > COEF_THRESHOLD && prior_struct[i] > 0.0;
            let verdict = crate::analysis::verdict::special(info.group, prior[i])
                .unwrap_or_else(|| Verdict::of_bound(structural, ratio[i]));
            StateObs {
                name: info.name,
                group: info.group,
                unit: info.group.is_instrument().then_some(info.unit),
                sigma_crlb_rad: sigma[i],
                ratio: ratio[i],
                observable: verdict == Verdict::Observable,
                null_participation: part[i],
                null_leak_at_truth: leak[i],
                verdict,
            }
        })
        .collect();
    Ok(ConfigObs {
        config: id,
        errors: run.errors,
        n: N - fixed,
        rank: spec.rank,
        rank_at_truth: at_truth.rank,
        eigenvalues: spec.eigenvalues.iter().copied().collect(),
        null_space,
        states,
        crlb_history: history,
    })
}

/// Analyses configuration `id` along the commanded path of `sim` from its
/// true initial state (the measurements and noise of `sim` are not used).
/// With `keep_history`, the σ_CRLB of every period is kept (for plots).
pub fn analyse(
    id: ConfigId,
    scenario: &Scenario,
    sim: &Simulation,
    earth_rate: bool,
    keep_history: bool,
) -> Result<ConfigObs, ekf::Error> {
    analyse_run(
        SimulatedRun::new(id, scenario, sim, earth_rate),
        keep_history,
    )
}

/// [`analyse`] of the model of `run` (its configuration under its error
/// model, [`SimulatedRun::with_errors`]), with the prior of every state
/// ([`SimulatedRun::prior_sigma`]).
pub fn analyse_run(run: SimulatedRun, keep_history: bool) -> Result<ConfigObs, ekf::Error> {
    rollcal::with_model!(run.config, run.errors, |M, N, Z| analyse_typed::<M, N, Z>(
        run,
        keep_history
    ))
}

/// [`analyse`] of all seven configurations along the noise-free run of
/// `scenario` (seed 0), without the σ_CRLB history.
pub fn analyse_all(scenario: &Scenario, earth_rate: bool) -> Result<Vec<ConfigObs>, Error> {
    analyse_all_with(scenario, ErrorModel::Installation, earth_rate)
}

/// [`analyse_all`] under error model `errors`.
pub fn analyse_all_with(
    scenario: &Scenario,
    errors: ErrorModel,
    earth_rate: bool,
) -> Result<Vec<ConfigObs>, Error> {
    let sim = crate::sim::truth::simulate(
        scenario,
        crate::sim::truth::SimOptions {
            seed: 0,
            noise: false,
            earth_rate,
        },
    );
    ConfigId::ALL
        .iter()
        .map(|&id| {
            let run = SimulatedRun::new(id, scenario, &sim, earth_rate).with_errors(errors);
            analyse_run(run, false).map_err(|e| Error::filter(id, e))
        })
        .collect()
}

/// The JSON document of `host-sim observability` (an interface: keep the
/// keys stable).
pub fn report_json(earth_rate: bool, configs: &[ConfigObs]) -> serde_json::Value {
    serde_json::json!({
        "earth_rate": earth_rate,
        "rank_rel_tol": RANK_TOLERANCE,
        "coef_threshold": COEF_THRESHOLD,
        "practical_ratio": PRACTICAL_RATIO,
        "structure_linearised_at": "zero state (the paper's first-order analysis); sigma_crlb along the true trajectory",
        "configs": configs,
    })
}

/// The verdict matrix as a Markdown table: one row per configuration, one
/// column per state group, each cell the verdicts of the group's x/y/z (or
/// 1/2/3) components, e.g. `yes yes weak`.
pub fn verdict_matrix_markdown(configs: &[ConfigObs]) -> String {
    let mut groups = vec![
        (Group::Attitude, "attitude"),
        (Group::ThetaGC, "θgC"),
        (Group::ThetaGT, "θgT"),
        (Group::ThetaAC, "θaC"),
        (Group::ThetaAT, "θaT"),
        (Group::Lambda, "λ"),
    ];
    if configs.iter().any(|c| c.errors == ErrorModel::Full) {
        groups.extend([
            (Group::GyroDrift, "dg"),
            (Group::GyroGDrift, "D_g"),
            (Group::GyroScale, "kg"),
            (Group::AccelBias, "ba"),
            (Group::AccelScale, "ka"),
            (Group::AccelSecondOrder, "k2"),
        ]);
    }
    let mut out = String::from("| config | rank/n |");
    for (_, title) in &groups {
        out.push_str(&format!(" {title} |"));
    }
    out.push_str(&format!("\n|---|---|{}\n", "---|".repeat(groups.len())));
    for c in configs {
        out.push_str(&format!("| {} | {}/{} |", c.config, c.rank, c.n));
        for &(g, _) in &groups {
            let cells: Vec<&str> = c
                .states
                .iter()
                .filter(|s| s.group == g)
                .map(|s| s.verdict.cell())
                .collect();
            if cells.is_empty() {
                out.push_str(" — |");
            } else {
                out.push_str(&format!(" {} |", cells.join(" ")));
            }
        }
        out.push('\n');
    }
    out
}

/// The states whose verdict differs between two analyses of the same
/// configurations (Earth rate off, then on), as text lines.
pub fn changes(off: &[ConfigObs], on: &[ConfigObs]) -> Vec<String> {
    let mut lines = Vec::new();
    for (a, b) in off.iter().zip(on) {
        if a.rank != b.rank {
            lines.push(format!(
                "{}: rank {} → {} with the Earth rate",
                a.config, a.rank, b.rank
            ));
        }
        for (sa, sb) in a.states.iter().zip(&b.states) {
            if sa.verdict != sb.verdict {
                let ka = |v| printed_value(sa.group, v);
                let unit = sa.group.printed_scale().1;
                lines.push(format!(
                    "{} {}: {} → {} (σ_CRLB {:.3}{unit} → {:.3}{unit}, ratio {:.2e} → {:.2e})",
                    a.config,
                    sa.name,
                    sa.verdict,
                    sb.verdict,
                    ka(sa.sigma_crlb_rad),
                    ka(sb.sigma_crlb_rad),
                    sa.ratio,
                    sb.ratio
                ));
            }
        }
    }
    lines
}
