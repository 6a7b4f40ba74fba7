//! The verdict on one state: the one vocabulary of `run`, `calibrate`,
//! `observability` and `paper` (docs/cli.md, "Verdict words"). The words are
//! printed by [`Verdict`]'s `Display` and nowhere else.

use std::fmt;

use crate::analysis::runner::StateResult;

pub use rollcal::observability::{expected_observable, PRACTICAL_RATIO};

/// What a run or an analysis says of one state.
///
/// The JSON values (`serde`) are an interface and stay as they were:
/// `converged`, `failed`, `observable`, `weakly_observable`,
/// `structurally_unobservable`, `not_observable`, and for the full model
/// `not_estimated` and `nuisance`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Observable in practice and within 4σ of the truth (a run).
    Converged,
    /// Observable in practice but more than 4σ from the truth (a run).
    Failed,
    /// Observable in practice: outside the null space of the information
    /// matrix and `σ / σ_prior < 0.01` (`run`: σ of the filter, for a state
    /// the paper does not claim; `observability`: σ_CRLB).
    Observable,
    /// Outside the null space but `σ_CRLB / σ_prior ≥ 0.01`.
    WeaklyObservable,
    /// In the null space of the information matrix.
    StructurallyUnobservable,
    /// Not observable in practice: in the null space, or
    /// `σ / σ_prior ≥ 0.01`.
    NotObservable,
    /// Not estimated: the model holds the term at zero (its prior σ is 0,
    /// e.g. a platform file that says its instrument has no such term, or
    /// a Gauss–Markov part without a bias instability).
    NotEstimated,
    /// A nuisance of the full model that wanders (the Gauss–Markov parts
    /// of the drift and the bias, and their warm-ups): estimated to keep
    /// the others honest, reported at the final time, not a value to
    /// compensate or judge.
    Nuisance,
}

impl Verdict {
    /// Every verdict.
    pub const ALL: [Verdict; 8] = [
        Verdict::Converged,
        Verdict::Failed,
        Verdict::Observable,
        Verdict::WeaklyObservable,
        Verdict::StructurallyUnobservable,
        Verdict::NotObservable,
        Verdict::NotEstimated,
        Verdict::Nuisance,
    ];

    /// The printed word (docs/cli.md, "Verdict words").
    pub const fn as_str(self) -> &'static str {
        match self {
            Verdict::Converged => "converged",
            Verdict::Failed => "FAILED",
            Verdict::Observable => "observable in practice",
            Verdict::WeaklyObservable => "weakly observable",
            Verdict::StructurallyUnobservable => "not observable (null space)",
            Verdict::NotObservable => "not observable",
            Verdict::NotEstimated => "not estimated",
            Verdict::Nuisance => "nuisance (wanders)",
        }
    }

    /// The cell of the verdict matrices: `yes` (observable in practice),
    /// `weak`, `no` (not observable).
    pub const fn cell(self) -> &'static str {
        match self {
            Verdict::Converged | Verdict::Failed | Verdict::Observable => "yes",
            Verdict::WeaklyObservable => "weak",
            Verdict::StructurallyUnobservable | Verdict::NotObservable => "no",
            Verdict::NotEstimated => "—",
            Verdict::Nuisance => "n/a",
        }
    }

    /// The verdict of an observability analysis on one state: in the null
    /// space of the information matrix (`structural`), else observable in
    /// practice when its bound is below [`PRACTICAL_RATIO`] of the prior
    /// (`ratio = σ_bound / σ_prior`), else weakly observable. `observability`
    /// (σ_CRLB along the true path) and `calibrate` without a truth (the
    /// bound at the estimate along the received path) both use it.
    pub fn of_bound(structural: bool, ratio: f64) -> Verdict {
        if structural {
            Verdict::StructurallyUnobservable
        } else if ratio < PRACTICAL_RATIO {
            Verdict::Observable
        } else {
            Verdict::WeaklyObservable
        }
    }

    /// Observable in practice (a converged or failed state included).
    pub const fn is_observable(self) -> bool {
        matches!(
            self,
            Verdict::Converged | Verdict::Failed | Verdict::Observable
        )
    }
}

/// The verdict of a full-model state that is not judged against a bound:
/// [`Verdict::NotEstimated`] for a prior σ of zero, [`Verdict::Nuisance`]
/// for a Gauss–Markov part that wanders.
pub fn special(group: rollcal::models::Group, prior: f64) -> Option<Verdict> {
    if prior == 0.0 {
        Some(Verdict::NotEstimated)
    } else if group.is_nuisance() && group != rollcal::models::Group::Attitude {
        Some(Verdict::Nuisance)
    } else {
        None
    }
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The verdict on a state whose truth is known, the one judgement of
/// `run`, `calibrate --truth` and `paper`: observable in practice
/// (`observable`) and within 4σ of the truth (`ratio = |error|/σ ≤ 4`):
/// `converged`; observable and beyond 4σ (or a ratio that is not a
/// number): `FAILED`; not observable in practice: `not observable`. Every
/// state is judged alike: the installation angles, the attitude, the
/// instrument terms of the full model.
pub fn against_truth(observable: bool, ratio: f64) -> Verdict {
    if !observable {
        Verdict::NotObservable
    } else if ratio <= 4.0 {
        Verdict::Converged
    } else {
        Verdict::Failed
    }
}

/// The verdict on state `s` of a run against its truth
/// ([`against_truth`]): observable in practice when the filter's σ is below
/// [`PRACTICAL_RATIO`] of the state's prior `s.prior` (a path that does
/// not excite a state leaves σ near the prior: `not observable` on that
/// path, whatever the paper claims); a state the model does not estimate
/// or a nuisance that wanders has its own word ([`special`]).
pub fn verdict(s: &StateResult) -> Verdict {
    special(s.info.group, s.prior)
        .unwrap_or_else(|| against_truth(s.sigma_rad < PRACTICAL_RATIO * s.prior, s.ratio()))
}
