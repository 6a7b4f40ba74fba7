//! Estimates: the running one, and the final answer of the estimator of
//! record over the sample log ([`Calibrator::finish`] and its variants).

use nalgebra::RealField;

use super::{to_f64, Calibrator};
use crate::ekf::Filter;
use crate::estimator::{self, EstimatorOptions, PassEvent, PassStart, SampleLog};
use crate::models::Model;
use crate::wire::{Estimate, EstimateKind, SinglePassReason};

impl<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>
    Calibrator<T, M, N, Z>
{
    /// The current (running) estimate and health.
    pub fn estimate(&self) -> Estimate {
        self.estimate_of(&self.filter, EstimateKind::Running)
    }

    /// The final answer: the estimator of record ([`crate::estimator`]: pass
    /// 1, back-propagation, linearised passes until no state moves by more
    /// than `passes.tolerance` σ) over `log`, which must hold what
    /// [`Calibrator::push_logged`] appended, from where the log starts
    /// ([`Calibrator::log_start`]). When it does not (no log, full,
    /// a re-acquired attitude, a mismatch) the answer is the running
    /// estimate, marked [`EstimateKind::SinglePass`] with the reason. The
    /// calibrator itself is unchanged: more samples may follow. Also returns
    /// the final filter when the passes ran. `observer` sees every step of
    /// every pass ([`PassEvent`]; `|_| {}` when not needed).
    pub fn finish<F: FnMut(&PassEvent<'_, T, M, N, Z>)>(
        &self,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        observer: F,
    ) -> (Estimate, Option<Filter<T, M, N, Z>>) {
        let mut last = None;
        let estimate = self.finish_with(log, passes, observer, |f| last = Some(f.clone()));
        (estimate, last)
    }

    /// [`Calibrator::finish`] without a filter returned by value: `on_final`
    /// sees the final filter when the passes ran (it is not called for a
    /// single-pass answer). The passes run in a copy of the running filter
    /// in this function's frame ([`Calibrator::finish_in`]).
    pub fn finish_with<F, G>(
        &self,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        observer: F,
        on_final: G,
    ) -> Estimate
    where
        F: FnMut(&PassEvent<'_, T, M, N, Z>),
        G: FnOnce(&Filter<T, M, N, Z>),
    {
        let mut filter = self.filter.clone();
        let estimate = self.finish_in(&mut filter, log, passes, observer);
        if matches!(estimate.kind, EstimateKind::Final { .. }) {
            on_final(&filter);
        }
        estimate
    }

    /// [`Calibrator::finish`] in the caller's `filter`: the passes restart
    /// it ([`estimator::estimate_in`]; what it held does not matter), and
    /// after an [`EstimateKind::Final`] answer it is the final filter
    /// (otherwise it is left as it was or as the failing pass left it). A
    /// firmware whose session keeps this filter in static memory
    /// ([`crate::session::AnyFilter`]) has no filter on its stack under the
    /// passes (5.8 KB of f64 filter on the M7).
    // Not inlined: the session dispatches to seven of these, and their
    // frames must not add up in one caller's frame (firmware stack).
    #[inline(never)]
    pub fn finish_in<F>(
        &self,
        filter: &mut Filter<T, M, N, Z>,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        observer: F,
    ) -> Estimate
    where
        F: FnMut(&PassEvent<'_, T, M, N, Z>),
    {
        let logged = self.progress.logged;
        if log.len() > logged as usize && self.progress.log_incomplete.is_none() {
            log.truncate(logged as usize);
        }
        let reason = match self.progress.log_incomplete {
            Some(r) => Some(r),
            None if u32::try_from(log.len()).ok() != Some(logged) => {
                Some(SinglePassReason::LogMismatch)
            }
            None => None,
        };
        if let Some(r) = reason {
            return self.single_pass(r);
        }
        let Ok(at) = self.log_start(log) else {
            return self.single_pass(SinglePassReason::Estimator);
        };
        let (config, x0, sigma0) = Self::prior(&self.settings);
        let x0 = at.state(M::LAYOUT, &x0);
        let start = PassStart {
            x0: &x0,
            sigma0: &sigma0,
            at,
        };
        match estimator::estimate_from(filter, &config, &start, log, passes, observer) {
            Ok(report) => {
                let kind = EstimateKind::Final {
                    passes: report.passes,
                    converged: report.converged,
                };
                self.estimate_of(filter, kind)
            }
            Err(_) => self.single_pass(SinglePassReason::Estimator),
        }
    }

    /// A filter of this configuration for [`Calibrator::finish_in`], which
    /// restarts it (what it holds does not matter):
    /// [`Filter::placeholder`]'s zeros, which the compiler writes straight
    /// into the caller's place (inlined; no filter-sized temporary on a
    /// firmware's stack, as the prior's factor built by value was: 23 KB
    /// for the full M2-ps model in f64).
    #[inline(always)]
    pub(crate) fn scratch_filter(&self) -> Filter<T, M, N, Z> {
        Filter::placeholder(crate::ekf::FilterConfig::from(&self.settings))
    }

    /// The running estimate as the final answer when the passes cannot
    /// run: [`EstimateKind::SinglePass`] with `reason`.
    pub(crate) fn single_pass(&self, reason: SinglePassReason) -> Estimate {
        let logged = self.progress.logged;
        self.estimate_of(&self.filter, EstimateKind::SinglePass { reason, logged })
    }

    pub(super) fn estimate_of(&self, filter: &Filter<T, M, N, Z>, kind: EstimateKind) -> Estimate {
        let mut state = heapless::Vec::new();
        let mut sigma = heapless::Vec::new();
        for (x, s) in filter.state().iter().zip(filter.sigma().iter()) {
            // N ≤ MAX_STATES (`check_config`): the pushes cannot fail.
            let _ = state.push(*x);
            let _ = sigma.push(to_f64(*s));
        }
        Estimate {
            config: M::ID,
            errors: M::ERRORS,
            seq: self.progress.last_seq.unwrap_or(0),
            updates: filter.updates(),
            state,
            sigma,
            progress: self.progress,
            frame_errors: self.frame_errors,
            kind,
        }
    }
}
