//! The cases of `host-sim checks` and their rates over seeds: how often
//! `calibrate`'s data checks ([`crate::analysis::checks`]) flag a log,
//! name its likely cause ([`crate::analysis::calibration::diagnose`]) and
//! leave every estimated state within 4σ of the truth.
//!
//! A case is a log made wrong one way against the estimator's model:
//!
//! - `clean`: the truth is the model (the scenario's);
//! - `noise`, `bias`: accelerometer defects of the stream
//!   ([`AccelDefects`]): 3× the noise, an unmodelled constant bias;
//! - `k2`, `accel-rw`, `warmup`, `gyro-instability`: a term of the truth
//!   that the estimator's model (the platform file) leaves out
//!   ([`Omission`]), everything else the scenario's, truth and model alike;
//! - `creep`: an accelerometer bias that creeps linearly by [`CREEP_UG`]
//!   over the log, a term no model has (its persistent part: the truth of
//!   `ba` at the end of the log is the bias plus the whole creep).

use crate::analysis::calibration::calibrator_config;
use crate::analysis::checks::{gimbal_lock_check, judge, DataVerdict, Judgement};
use crate::analysis::runner::{Estimator, SimulatedRun};
use crate::sim::impair::AccelDefects;
use crate::sim::scenario::Scenario;

/// A term of the truth that the estimator's model leaves out (the
/// platform file gives it σ 0), at a magnitude a navigation-grade data
/// sheet gives (docs/own-platform.md, "Terms the model leaves out").
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Omission {
    /// `k2` of [`K2_UG_G2`] µg/g² on every accelerometer; the model's
    /// `sigma_k2_ug_g2` 0 (not estimated).
    K2,
    /// An accelerometer bias random walk of [`ACCEL_RW_UG_RT_H`] µg/√h;
    /// the model's `accel_random_walk_ug_rt_h` 0.
    AccelRw,
    /// An accelerometer warm-up of [`WARMUP_UG`] µg on every axis with
    /// time constant [`WARMUP_TAU_S`]; the model's `accel_warmup_ug` 0.
    Warmup,
    /// A gyro bias instability (Gauss–Markov drift) of
    /// [`GYRO_INSTABILITY_DEG_H`] °/h, correlation time the scenario's
    /// (600 s when it has none); the model's `gyro_bias_instability_deg_h` 0.
    GyroInstability,
}

/// The `k2` of the `k2` case (µg/g², every axis).
pub const K2_UG_G2: f64 = 10.0;
/// The accelerometer bias random walk of the `accel-rw` case (µg/√h).
pub const ACCEL_RW_UG_RT_H: f64 = 1.0;
/// The accelerometer warm-up of the `warmup` case (µg, every axis).
pub const WARMUP_UG: f64 = 2.0;
/// The warm-up's time constant of the `warmup` case (s).
pub const WARMUP_TAU_S: f64 = 1200.0;
/// The gyro bias instability of the `gyro-instability` case (°/h).
pub const GYRO_INSTABILITY_DEG_H: f64 = 0.005;
/// Its correlation time when the scenario gives none (s).
pub const GYRO_CORRELATION_S: f64 = 600.0;
/// The linear creep of the accelerometer bias over the log of the `creep`
/// case (µg, every axis, instrument frame).
pub const CREEP_UG: f64 = 2.0;

impl Omission {
    /// Every term, in the order of the table.
    pub const ALL: [Omission; 4] = [
        Omission::K2,
        Omission::AccelRw,
        Omission::Warmup,
        Omission::GyroInstability,
    ];

    /// The case's name on the command line (`--case`).
    pub fn key(self) -> &'static str {
        match self {
            Omission::K2 => "k2",
            Omission::AccelRw => "accel-rw",
            Omission::Warmup => "warmup",
            Omission::GyroInstability => "gyro-instability",
        }
    }

    /// The case's label in the table.
    pub fn label(self) -> &'static str {
        match self {
            Omission::K2 => "k2 10 µg/g² left out",
            Omission::AccelRw => "accel RW 1 µg/√h left out",
            Omission::Warmup => "accel warm-up 2 µg left out",
            Omission::GyroInstability => "gyro instability 0.005 °/h left out",
        }
    }

    /// The words a likely cause that names this term contains (the
    /// platform file's key of the term).
    pub fn key_in_cause(self) -> &'static str {
        match self {
            Omission::K2 => "sigma_k2_ug_g2",
            Omission::AccelRw => "accel_random_walk_ug_rt_h",
            Omission::Warmup => "accel_warmup_ug",
            Omission::GyroInstability => "gyro_bias_instability_deg_h",
        }
    }

    /// The truth: scenario `sc` with the term.
    pub fn truth(self, sc: &Scenario) -> Scenario {
        let mut t = sc.clone();
        let ins = &mut t.instruments;
        match self {
            Omission::K2 => ins.k2_ug_g2 = [K2_UG_G2; 3],
            Omission::AccelRw => ins.wander.accel_random_walk_ug_rt_h = ACCEL_RW_UG_RT_H,
            Omission::Warmup => {
                ins.warmup.accel_ug = [WARMUP_UG; 3];
                ins.warmup.time_constant_s = WARMUP_TAU_S;
            }
            Omission::GyroInstability => {
                ins.wander.gyro_bias_instability_deg_h = GYRO_INSTABILITY_DEG_H;
                if ins.wander.gyro_correlation_time_s <= 0.0 {
                    ins.wander.gyro_correlation_time_s = GYRO_CORRELATION_S;
                }
            }
        }
        t
    }

    /// The estimator's model: scenario `sc` without the term (its σ 0).
    pub fn model(self, sc: &Scenario) -> Scenario {
        let mut m = sc.clone();
        let ins = &mut m.instruments;
        match self {
            Omission::K2 => ins.prior.sigma_k2_ug_g2 = 0.0,
            Omission::AccelRw => ins.wander.accel_random_walk_ug_rt_h = 0.0,
            Omission::Warmup => ins.wander.accel_warmup_ug = 0.0,
            Omission::GyroInstability => ins.wander.gyro_bias_instability_deg_h = 0.0,
        }
        m
    }
}

/// One case of [`rates`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Case {
    /// Its name on the command line (`--case`), e.g. `noise`.
    pub key: &'static str,
    /// Label, e.g. `"accel noise 3×"`.
    pub label: &'static str,
    /// The defect applied to the simulated accelerometer means.
    #[serde(skip)]
    pub defect: AccelDefects,
    /// The term of the truth the model leaves out, if any.
    pub omission: Option<Omission>,
    /// A linear creep of the accelerometer bias over the log (µg, every
    /// axis; 0: none).
    pub creep_ug: f64,
    /// What a likely cause that names this case's defect contains
    /// (`None`: nothing to name, the clean case).
    pub cause: Option<&'static str>,
}

/// The three cases of the stream's defects: clean, accelerometer noise 3×
/// the platform's, an unmodelled constant bias of `bias_ug` (µg per axis,
/// instrument frame).
pub fn cases(bias_ug: [f64; 3]) -> [Case; 3] {
    let clean = Case {
        key: "clean",
        label: "clean",
        defect: AccelDefects::default(),
        omission: None,
        creep_ug: 0.0,
        cause: None,
    };
    [
        clean,
        Case {
            key: "noise",
            label: "accel noise 3×",
            defect: AccelDefects {
                accel_noise_scale: 3.0,
                accel_bias_ug: None,
            },
            cause: Some("the noise level"),
            ..clean
        },
        Case {
            key: "bias",
            label: "accel bias",
            defect: AccelDefects {
                accel_noise_scale: 1.0,
                accel_bias_ug: Some(bias_ug),
            },
            cause: Some("the instruments' own errors"),
            ..clean
        },
    ]
}

/// The cases of the terms the model leaves out ([`Omission::ALL`]).
pub fn omission_cases() -> [Case; 4] {
    Omission::ALL.map(|o| Case {
        key: o.key(),
        label: o.label(),
        defect: AccelDefects::default(),
        omission: Some(o),
        creep_ug: 0.0,
        cause: Some(o.key_in_cause()),
    })
}

/// The `creep` case: the accelerometer bias creeps linearly by
/// [`CREEP_UG`] over the log, everything else matched. No model has such a
/// term; the likely cause to name is a bias that wanders (its random walk).
pub fn creep_case() -> Case {
    Case {
        key: "creep",
        label: "accel bias creep 2 µg/log",
        defect: AccelDefects::default(),
        omission: None,
        creep_ug: CREEP_UG,
        cause: Some("accel_random_walk_ug_rt_h"),
    }
}

/// Every case, the stream's defects first.
pub fn all_cases(bias_ug: [f64; 3]) -> Vec<Case> {
    cases(bias_ug)
        .into_iter()
        .chain(omission_cases())
        .chain([creep_case()])
        .collect()
}

/// The outcome of one case over the seeds.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Rate {
    /// The case.
    pub case: String,
    /// Its `--case` name.
    pub key: &'static str,
    /// Seeds run.
    pub seeds: usize,
    /// Seeds whose judgement was a warning.
    pub flagged: usize,
    /// Seeds whose warning's likely cause names the case's defect.
    pub named: usize,
    /// Seeds whose answer (every estimated state but the nuisances: the
    /// attitude, the Gauss–Markov parts, the warm-ups) is within 4σ of
    /// the truth at the end of the log (the persistent truth of a term
    /// that wanders).
    pub within_4_sigma: usize,
    /// Seeds with a nuisance state beyond 4σ of its truth (not the
    /// answer), each with that state, its |error|/σ and whether the log
    /// was flagged.
    pub nuisance_beyond_4_sigma: Vec<(u64, String, f64, bool)>,
    /// Seeds judged consistent with a state beyond 4σ of the truth, each
    /// with that state and its |error|/σ.
    pub consistent_beyond_4_sigma: Vec<(u64, String, f64)>,
    /// Every seed with a state beyond 4σ of the truth: the state farthest
    /// from it, its |error|/σ, and whether the log was flagged.
    pub beyond_4_sigma: Vec<(u64, String, f64, bool)>,
    /// Per check name, the seeds in which that check failed.
    pub by_check: Vec<(&'static str, usize)>,
    /// Seeds whose estimator failed (counted as not flagged).
    pub errors: usize,
    /// The flagged seeds, each with its worst failed check
    /// (`"<name> <scope>: <statistic> outside [lo, hi]"`).
    pub flagged_seeds: Vec<(u64, String)>,
    /// The likely causes given, each with the number of seeds that got it
    /// (its text up to its evidence in parentheses).
    pub causes: Vec<(String, usize)>,
    /// Every seed: its verdict, likely cause, farthest state and every
    /// check's statistic.
    pub runs: Vec<SeedRun>,
}

/// One seed of a case, for the JSON.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SeedRun {
    /// The seed.
    pub seed: u64,
    /// `consistent`, `warning`, `not_checked`, or `error` (the estimator
    /// failed).
    pub verdict: &'static str,
    /// The likely cause of a warning.
    pub cause: Option<String>,
    /// The state of the answer farthest from its truth, and its
    /// |error|/σ.
    pub worst: (&'static str, f64),
    /// The nuisance state farthest from its truth, and its |error|/σ.
    pub worst_nuisance: (&'static str, f64),
    /// Every check as `[name, scope, statistic, lower, upper]`.
    pub checks: Vec<(&'static str, String, f64, f64, f64)>,
}

/// A state beyond this many σ of its truth is a wrong answer.
pub const ANSWER_SIGMA: f64 = 4.0;

/// One judged run of a case.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The judgement, with the likely cause of a warning as `calibrate`
    /// gives it.
    pub judgement: Judgement,
    /// The state of the answer (estimated, not a nuisance) farthest from
    /// its truth at the end of the log and its |error|/σ.
    pub worst: (&'static str, f64),
    /// The estimated nuisance state (the attitude, a Gauss–Markov part, a
    /// warm-up) farthest from its truth, and its |error|/σ.
    pub worst_nuisance: (&'static str, f64),
}

/// The judgement of one simulated run of configuration `id` with `defect`
/// on its accelerometer means, the estimator (error model `errors`) told
/// the scenario's noise.
pub fn judge_simulated(
    id: rollcal::models::ConfigId,
    errors: rollcal::models::ErrorModel,
    scenario: &Scenario,
    seed: u64,
    defect: &AccelDefects,
) -> Result<Judgement, crate::analysis::Error> {
    let case = Case {
        key: "",
        label: "",
        defect: *defect,
        omission: None,
        creep_ug: 0.0,
        cause: None,
    };
    run_case(id, errors, scenario, seed, &case, false).map(|o| o.judgement)
}

/// One simulated run of `case` on `scenario` (seed `seed`): the truth
/// simulated with the case's term and defect, the estimator of record
/// (error model `errors`, the model without the case's term) run over it,
/// and its data judged: with `full`, as `calibrate` judges them
/// ([`crate::analysis::calibration::judge`]: the test of the terms the
/// model leaves out, a warning's likely cause); else by the innovation
/// checks alone ([`judge`]).
pub fn run_case(
    id: rollcal::models::ConfigId,
    errors: rollcal::models::ErrorModel,
    scenario: &Scenario,
    seed: u64,
    case: &Case,
    full: bool,
) -> Result<Outcome, crate::analysis::Error> {
    use crate::sim::truth::{simulate, SimOptions};
    let (truth, model) = match case.omission {
        Some(o) => (o.truth(scenario), o.model(scenario)),
        None => (scenario.clone(), scenario.clone()),
    };
    let earth_rate = scenario.site.earth_rate;
    let defect = &case.defect;
    // The bias is the truth simulator's (added to the scenario's `ba`).
    let mut sim = simulate(
        &defect.biased(&truth),
        SimOptions {
            seed,
            noise: true,
            earth_rate,
        },
    );
    let offsets = defect.offsets(sim.samples.len(), scenario.noise.accel_g, seed);
    for (s, o) in sim.samples.iter_mut().zip(offsets) {
        for (a, d) in s.accel_mean.iter_mut().zip(o) {
            *a += d;
        }
    }
    creep(&mut sim, case.creep_ug);
    let run = SimulatedRun::new(id, &model, &sim, earth_rate).with_errors(errors);
    let r = run
        .run(Estimator::default(), None, false)
        .map_err(|e| crate::analysis::Error::filter(format_args!("{id} seed {seed}"), e))?;
    let records = run.records();
    let judgement = if full {
        let settings = calibrator_config(&model, id, errors, earth_rate);
        crate::analysis::calibration::judge(&settings, &r, &records, Some(model.site.latitude_deg))
    } else {
        judge(&r).with_path(gimbal_lock_check(id, &records))
    };
    let farthest = |nuisance: bool| {
        r.states
            .iter()
            .filter(|s| s.estimated() && s.info.group.is_nuisance() == nuisance)
            .map(|s| (s.name, s.ratio()))
            .fold(("", 0.0), |w, s| if s.1 > w.1 { s } else { w })
    };
    Ok(Outcome {
        judgement,
        worst: farthest(false),
        worst_nuisance: farthest(true),
    })
}

/// The accelerometer means of `sim` given a bias that creeps linearly from
/// 0 at the start to `ug` µg (every axis) at the end of the log, and its
/// truth: the creep is persistent (it stays), so it is added to the
/// random walk of the bias `r_a`, the part of the truth of `ba`.
fn creep(sim: &mut crate::sim::truth::Simulation, ug: f64) {
    let end = sim.samples.last().map_or(0.0, |s| s.truth.t);
    if ug == 0.0 || end <= 0.0 {
        return;
    }
    for s in &mut sim.samples {
        let c = ug * 1e-6 * s.truth.t / end;
        s.accel_mean.add_scalar_mut(c);
        s.wander.r_a.add_scalar_mut(c);
    }
}

/// The cause of a likely-cause line, without its evidence: the text after
/// `likely cause: ` up to the first ` (` .
fn cause_head(cause: &str) -> String {
    let c = cause.strip_prefix("likely cause: ").unwrap_or(cause);
    c.split(" (").next().unwrap_or(c).to_string()
}

/// False-alarm and detection rates: every case over seeds `1..=seeds`, in
/// parallel (rayon), `progress` called after every run; each warning's
/// likely cause found as `calibrate` finds it.
pub fn rates(
    id: rollcal::models::ConfigId,
    errors: rollcal::models::ErrorModel,
    scenario: &Scenario,
    seeds: u64,
    cases: &[Case],
    progress: &(dyn Fn() + Sync),
) -> Vec<Rate> {
    use rayon::prelude::*;
    let jobs: Vec<(usize, u64)> = (0..cases.len())
        .flat_map(|c| (1..=seeds).map(move |s| (c, s)))
        .collect();
    let out: Vec<(usize, u64, Option<Outcome>)> = jobs
        .par_iter()
        .map(|&(c, seed)| {
            let o = run_case(id, errors, scenario, seed, &cases[c], true).ok();
            progress();
            (c, seed, o)
        })
        .collect();
    cases
        .iter()
        .enumerate()
        .map(|(c, case)| {
            let mine: Vec<(u64, &Option<Outcome>)> = out
                .iter()
                .filter(|(k, _, _)| *k == c)
                .map(|(_, s, o)| (*s, o))
                .collect();
            rate_of(case, &mine)
        })
        .collect()
}

/// The [`Rate`] of `case` from its seeds' outcomes (`None`: the estimator
/// failed).
fn rate_of(case: &Case, mine: &[(u64, &Option<Outcome>)]) -> Rate {
    let done: Vec<(u64, &Outcome)> = mine
        .iter()
        .filter_map(|(s, o)| o.as_ref().map(|o| (*s, o)))
        .collect();
    let flagged_seeds = done
        .iter()
        .filter_map(|(seed, o)| match &o.judgement.verdict {
            DataVerdict::Warning { failed } => failed.first().map(|f| {
                (
                    *seed,
                    format!(
                        "{} {}: {:.4} outside [{:.4}, {:.4}]",
                        f.name, f.scope, f.statistic, f.band.0, f.band.1
                    ),
                )
            }),
            _ => None,
        })
        .collect();
    let by_check = ["nis", "whiteness", "bias", "left_out"]
        .into_iter()
        .map(|name| {
            let n = done
                .iter()
                .filter(|(_, o)| {
                    o.judgement
                        .checks
                        .iter()
                        .any(|k| k.name == name && !k.passed)
                })
                .count();
            (name, n)
        })
        .collect();
    let mut causes: Vec<(String, usize)> = Vec::new();
    for c in done
        .iter()
        .filter_map(|(_, o)| o.judgement.cause.as_deref())
    {
        let head = cause_head(c);
        match causes.iter_mut().find(|(h, _)| *h == head) {
            Some(e) => e.1 += 1,
            None => causes.push((head, 1)),
        }
    }
    causes.sort_by_key(|c| std::cmp::Reverse(c.1));
    let warned = |o: &Outcome| o.judgement.verdict.is_warning();
    Rate {
        case: case.label.to_string(),
        key: case.key,
        seeds: mine.len(),
        flagged: done.iter().filter(|(_, o)| warned(o)).count(),
        named: done
            .iter()
            .filter(|(_, o)| {
                warned(o)
                    && case.cause.is_some_and(|w| {
                        o.judgement.cause.as_deref().is_some_and(|c| c.contains(w))
                    })
            })
            .count(),
        within_4_sigma: done
            .iter()
            .filter(|(_, o)| o.worst.1 <= ANSWER_SIGMA)
            .count(),
        consistent_beyond_4_sigma: done
            .iter()
            .filter(|(_, o)| !warned(o) && o.worst.1 > ANSWER_SIGMA)
            .map(|(s, o)| (*s, o.worst.0.to_string(), o.worst.1))
            .collect(),
        beyond_4_sigma: done
            .iter()
            .filter(|(_, o)| o.worst.1 > ANSWER_SIGMA)
            .map(|(s, o)| (*s, o.worst.0.to_string(), o.worst.1, warned(o)))
            .collect(),
        nuisance_beyond_4_sigma: done
            .iter()
            .filter(|(_, o)| o.worst_nuisance.1 > ANSWER_SIGMA)
            .map(|(s, o)| {
                let w = o.worst_nuisance;
                (*s, w.0.to_string(), w.1, warned(o))
            })
            .collect(),
        by_check,
        errors: mine.len() - done.len(),
        flagged_seeds,
        causes,
        runs: mine
            .iter()
            .map(|(seed, o)| match o {
                Some(o) => SeedRun {
                    seed: *seed,
                    verdict: o.judgement.verdict.word(),
                    cause: o.judgement.cause.clone(),
                    worst: o.worst,
                    worst_nuisance: o.worst_nuisance,
                    checks: o
                        .judgement
                        .checks
                        .iter()
                        .map(|c| (c.name, c.scope.clone(), c.statistic, c.band.0, c.band.1))
                        .collect(),
                },
                None => SeedRun {
                    seed: *seed,
                    verdict: "error",
                    cause: None,
                    worst: ("", f64::NAN),
                    worst_nuisance: ("", f64::NAN),
                    checks: Vec::new(),
                },
            })
            .collect(),
    }
}
