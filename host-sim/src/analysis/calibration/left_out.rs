//! The terms the platform file leaves out of the full model, tested
//! against the data: does the log need them?
//!
//! A platform file (or `Configure`) leaves a term of the full model out by
//! giving it σ 0 (not estimated). Where the term has a fixed signature —
//! a constant (`dg`, `D_g`, `kg`, `ba`, `ka`, `k2`: prior σ 0) or a warm-up
//! of known time constant (`gyro_warmup_deg_h` or `accel_warmup_ug` 0 with
//! `warmup_time_constant_s` given) — the estimator of record is run once
//! more with every such term given a diffuse prior ([`AUGMENTED`]), and
//! each term is tested by its Wald statistic `x̂ᵀ P⁻¹ x̂` (its block of the
//! final estimate and covariance). When the data have no such term the
//! estimate is noise of covariance `P − P Σ₀⁻¹ P ≤ P` (`Σ₀` the diffuse
//! prior), so the statistic is at most `χ²(d)`, `d` the term's states: the
//! test `left_out` of [`crate::analysis::checks`], one of the judgement's
//! `m` checks at `α/m`.
//!
//! The bias and drift that wander (a Gauss–Markov instability or a random
//! walk given σ 0) are not tested here: a variance has no such estimate.
//! Whether the data can tell them from the noise is for the innovation
//! checks (docs/own-platform.md, "Terms the model leaves out").

use rollcal::estimator::{self, LogRecord};
use rollcal::models::ErrorModel;
use rollcal::wire::{CalibratorConfig, InstrumentPrior};

use super::diagnose::{trial, Trial};
use crate::analysis::checks::Wald;
use crate::analysis::runner::Update;
use crate::sim::instruments::{printed_unit, printed_value};

/// The diffuse prior a left-out term is given in the augmented run: the
/// default prior of the calibrator ([`InstrumentPrior::default`]: 1 °/h,
/// 1 °/h/g, 2000 ppm, 1000 µg, 1000 ppm, 100 µg/g²); a warm-up that of
/// its instrument's constant (1 °/h, 1000 µg).
pub const AUGMENTED: &str = "the calibrator's default prior";

/// A term of the full model the platform file can leave out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Term {
    /// The platform file's key that leaves it out (set to 0).
    pub key: &'static str,
    /// Its table in the platform file.
    pub table: &'static str,
    /// What it is.
    pub what: &'static str,
    /// Its first state among the 36 instrument states.
    pub offset: usize,
    /// Its number of states.
    pub len: usize,
}

/// Every term with a fixed signature, in state order.
pub const TERMS: [Term; 8] = [
    Term {
        key: "sigma_dg_deg_h",
        table: "instruments.prior",
        what: "the gyro drift dg",
        offset: 0,
        len: 3,
    },
    Term {
        key: "sigma_d_g_deg_h_g",
        table: "instruments.prior",
        what: "the g-sensitive drift D_g",
        offset: 3,
        len: 9,
    },
    Term {
        key: "sigma_kg_ppm",
        table: "instruments.prior",
        what: "the gyro scale factors kg",
        offset: 12,
        len: 3,
    },
    Term {
        key: "sigma_ba_ug",
        table: "instruments.prior",
        what: "the accelerometer bias ba",
        offset: 15,
        len: 3,
    },
    Term {
        key: "sigma_ka_ppm",
        table: "instruments.prior",
        what: "the accelerometer scale factors ka",
        offset: 18,
        len: 3,
    },
    Term {
        key: "sigma_k2_ug_g2",
        table: "instruments.prior",
        what: "the accelerometers' second-order term k2",
        offset: 21,
        len: 3,
    },
    Term {
        key: "gyro_warmup_deg_h",
        table: "instruments.wander",
        what: "the gyro warm-up",
        offset: 30,
        len: 3,
    },
    Term {
        key: "accel_warmup_ug",
        table: "instruments.wander",
        what: "the accelerometer warm-up",
        offset: 33,
        len: 3,
    },
];

impl Term {
    /// Its σ in `settings` (internal units; 0: left out).
    fn sigma(&self, settings: &CalibratorConfig) -> f64 {
        settings
            .instrument_prior
            .sigma(&settings.wander)
            .get(self.offset)
            .copied()
            .unwrap_or(0.0)
    }

    /// Whether `settings` leave it out and it can be tested: σ 0, and a
    /// warm-up's time constant given.
    fn left_out(&self, settings: &CalibratorConfig) -> bool {
        let warmup = self.offset >= 30;
        self.sigma(settings) == 0.0 && (!warmup || settings.wander.warmup_tau_s > 0.0)
    }

    /// `settings` with it given its diffuse prior ([`AUGMENTED`]).
    fn augment(&self, settings: &mut CalibratorConfig) {
        let d = InstrumentPrior::default();
        let p = &mut settings.instrument_prior;
        match self.offset {
            0 => p.dg_rad_s = d.dg_rad_s,
            3 => p.d_g_rad_s_g = d.d_g_rad_s_g,
            12 => p.kg = d.kg,
            15 => p.ba_g = d.ba_g,
            18 => p.ka = d.ka,
            21 => p.k2 = d.k2,
            30 => settings.wander.gyro_warmup_sigma = d.dg_rad_s,
            _ => settings.wander.accel_warmup_sigma = d.ba_g,
        }
    }
}

/// The terms `settings` leave out that can be tested (none for the
/// installation model, which has no instrument states).
pub fn left_out_terms(settings: &CalibratorConfig) -> Vec<Term> {
    if settings.errors != ErrorModel::Full {
        return Vec::new();
    }
    TERMS.into_iter().filter(|t| t.left_out(settings)).collect()
}

/// What the augmented run says of one left-out term.
#[derive(Clone, Debug)]
pub struct Finding {
    /// The term.
    pub term: Term,
    /// Its test, for the judgement.
    pub wald: Wald,
    /// Its estimate and σ in printed units, e.g. `(9.8, 10.3, 9.6) ± (2.3,
    /// 2.3, 1.5) µg/g²`.
    pub estimate: String,
}

/// The augmented run and its findings.
#[derive(Clone, Debug)]
pub struct LeftOut {
    /// One per left-out term.
    pub findings: Vec<Finding>,
    /// The augmented run's last-pass updates (for the likely cause: with
    /// the terms, do the data fit?).
    pub updates: Vec<Update>,
}

/// The Wald test of every term `settings` leave out, from the estimator of
/// record over `records` with them given their diffuse prior; `None` when
/// nothing is left out or the augmented run fails.
pub fn test(settings: &CalibratorConfig, records: &[LogRecord<f64>]) -> Option<LeftOut> {
    let terms = left_out_terms(settings);
    if terms.is_empty() {
        return None;
    }
    let mut aug = *settings;
    for t in &terms {
        t.augment(&mut aug);
    }
    let Trial {
        updates,
        state,
        covariance,
        ..
    } = trial(&aug, records, estimator::DEFAULT_MAX_PASSES)?;
    let n = state.len();
    let base = settings.config.layout().installation_n();
    let infos = settings.config.states_with(ErrorModel::Full);
    let findings = terms
        .iter()
        .filter_map(|t| {
            let group = infos.get(base + t.offset)?.group;
            finding(t, group, &state, &covariance, n, base + t.offset)
        })
        .collect();
    Some(LeftOut { findings, updates })
}

/// The Wald statistic of the states `at..at + term.len` (of group
/// `group`) of the estimate `x` (covariance `p`, `n` × `n` row-major).
fn finding(
    term: &Term,
    group: rollcal::models::Group,
    x: &[f64],
    p: &[f64],
    n: usize,
    at: usize,
) -> Option<Finding> {
    let d = term.len;
    let xs = nalgebra::DVector::from_vec(
        (at..at + d)
            .map(|i| x.get(i).copied())
            .collect::<Option<Vec<f64>>>()?,
    );
    let block = nalgebra::DMatrix::from_fn(d, d, |r, c| {
        p.get((at + r) * n + at + c).copied().unwrap_or(f64::NAN)
    });
    let w = block
        .clone()
        .cholesky()
        .map(|c| {
            let y = c
                .l()
                .solve_lower_triangular(&xs)
                .unwrap_or_else(|| xs.clone());
            y.norm_squared()
        })
        .unwrap_or(f64::INFINITY);
    let show = |v: &mut dyn Iterator<Item = f64>| {
        v.map(|v| format!("{:.3}", printed_value(group, v)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let estimate = format!(
        "({}) ± ({}) {}",
        show(&mut xs.iter().copied()),
        show(&mut (0..d).map(|i| block[(i, i)].max(0.0).sqrt())),
        printed_unit(group)
    );
    Some(Finding {
        term: *term,
        wald: Wald {
            scope: format!("{} ({}.{} = 0)", short(term), term.table, term.key),
            statistic: w,
            dof: d,
            detail: format!(
                "{} estimated with {AUGMENTED}: {estimate}; x̂ᵀP⁻¹x̂ ~ χ²({d}) at most when the data have none",
                term.what
            ),
        },
        estimate,
    })
}

/// The term's short name in a check's scope: `k2`, `D_g`, `accel warm-up`.
fn short(term: &Term) -> &'static str {
    match term.offset {
        0 => "dg",
        3 => "D_g",
        12 => "kg",
        15 => "ba",
        18 => "ka",
        21 => "k2",
        30 => "gyro warm-up",
        _ => "accel warm-up",
    }
}
