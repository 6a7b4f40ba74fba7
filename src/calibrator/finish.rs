//! Estimates: the running one, and the final answer of the estimator of
//! record over the sample log ([`Calibrator::finish`] and its variants).

use nalgebra::RealField;

use super::{to_f64, Calibrator};
use crate::ekf::Filter;
use crate::estimator::{self, EstimatorOptions, LogStart, PassEvent, PassStart, SampleLog};
use crate::models::Model;
use crate::wire::{CalibratorConfig, Checkpoint, Estimate, EstimateKind, SinglePassReason};

/// What [`Calibrator::finish_passes`] did, for
/// [`Calibrator::finish_answer`].
pub(crate) enum Passed {
    /// The passes could not run (the filter was not touched).
    NotRun(SinglePassReason),
    /// They ran in the calibrator's filter: the answer's kind (`None`: a
    /// pass failed).
    Ran(Option<EstimateKind>),
}

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
    /// (otherwise it is left as it was or as the failing pass left it).
    /// With `filter` in static memory ([`crate::session::AnyFilter`]) no
    /// filter is on the stack under the passes; a firmware with room for
    /// one filter only uses [`Calibrator::finish_in_place`].
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
        let at = match self.final_start(log) {
            Ok(at) => at,
            Err(r) => return self.single_pass(r),
        };
        match Self::passes_in(filter, &self.settings, at, log, passes, observer) {
            Some(kind) => self.estimate_of(filter, kind),
            None => self.single_pass(SinglePassReason::Estimator),
        }
    }

    /// [`Calibrator::finish`] in the calibrator's own filter, for a
    /// firmware with room for one filter: the running filter is saved into
    /// `saved` ([`Calibrator::checkpoint_into`], the factor's upper
    /// triangle: 13.0 KB for the full M2-ps model, where a filter is
    /// 59.7 KB in f64), the passes run in its place, and it is put back
    /// from `saved` ([`Filter::set_parts`]). Afterwards the calibrator is
    /// as it was, bit for bit (`==`), and more samples may follow; `saved`
    /// holds its checkpoint (what it held before does not matter). The
    /// session answers `Finish` with this, `saved` being its reply slot
    /// ([`crate::session::Session::handle_into`]).
    ///
    /// The put-back cannot fail (the checkpoint is the filter's own, whose
    /// values are finite); were it to, the calibrator is reset
    /// ([`Calibrator::reset`]) rather than left holding the final filter.
    ///
    /// # Examples
    ///
    /// ```
    /// use nalgebra::Vector3;
    /// use rollcal::calibrator::Calibrator;
    /// use rollcal::estimator::{EstimatorOptions, LogRecord, SliceLog};
    /// use rollcal::models::{ConfigId, M1Pa};
    /// use rollcal::wire::{CalibratorConfig, Checkpoint, EstimateKind, Sample};
    ///
    /// let mut cal = Calibrator::<f64, M1Pa, 12, 3>::new(CalibratorConfig::paper(ConfigId::M1Pa))?;
    /// let mut records = [LogRecord::predicted(0.0, Vector3::zeros()); 20];
    /// let mut log = SliceLog::new(&mut records);
    /// let e = cal.settings().earth_rate_n; // at rest: the Earth rate alone
    /// for k in 0..20 {
    ///     let s = Sample {
    ///         seq: k,
    ///         t_us: (u64::from(k) + 1) * 1_000_000,
    ///         dt: 1.0,
    ///         dtheta_cmd: e,
    ///         c_cn_quat: [1.0, 0.0, 0.0, 0.0],
    ///         accel_mean: [0.0, 1.0, 0.0],
    ///         gimbal: None,
    ///     };
    ///     cal.push_logged(&s, &mut log).expect("a valid sample");
    /// }
    /// let before = cal.clone();
    /// let mut saved = Checkpoint::empty();
    /// let passes = EstimatorOptions::default();
    /// let answer = cal.finish_in_place(&mut saved, &mut log, &passes, |_| {});
    /// assert!(matches!(answer.kind, EstimateKind::Final { .. }));
    /// // The same answer as `finish`'s, and the calibrator as it was.
    /// assert_eq!(before.finish(&mut log, &passes, |_| {}).0, answer);
    /// assert_eq!(cal, before);
    /// # Ok::<(), rollcal::calibrator::Error>(())
    /// ```
    pub fn finish_in_place<F>(
        &mut self,
        saved: &mut Checkpoint,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        observer: F,
    ) -> Estimate
    where
        F: FnMut(&PassEvent<'_, T, M, N, Z>),
    {
        let passed = self.finish_passes(saved, log, passes, observer);
        self.finish_answer(passed, saved)
    }

    /// The first half of [`Calibrator::finish_in_place`]: the passes in the
    /// calibrator's filter, the running one saved into `saved`.
    /// [`Calibrator::finish_answer`] must follow, with `saved` as this left
    /// it. In two halves so that a caller whose return slot for the
    /// estimate would be on the stack under the passes (the session's) can
    /// build it after them.
    // Not inlined: the session dispatches to seven of these (firmware stack).
    #[inline(never)]
    pub(crate) fn finish_passes<F>(
        &mut self,
        saved: &mut Checkpoint,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        observer: F,
    ) -> Passed
    where
        F: FnMut(&PassEvent<'_, T, M, N, Z>),
    {
        let at = match self.final_start(log) {
            Ok(at) => at,
            Err(r) => return Passed::NotRun(r),
        };
        self.checkpoint_into(saved);
        let kind = Self::passes_in(&mut self.filter, &self.settings, at, log, passes, observer);
        Passed::Ran(kind)
    }

    /// The second half of [`Calibrator::finish_in_place`]: the answer of
    /// the passes, and the running filter put back from `saved`.
    // Not inlined: the estimate is in this frame only, not in one below
    // which the passes run (firmware stack).
    #[inline(never)]
    pub(crate) fn finish_answer(&mut self, passed: Passed, saved: &Checkpoint) -> Estimate {
        let kind = match passed {
            Passed::NotRun(reason) => return self.single_pass(reason),
            Passed::Ran(kind) => kind,
        };
        let estimate = kind.map(|kind| self.estimate_of(&self.filter, kind));
        if self.put_back(saved).is_err() {
            // Not reached (see `finish_in_place`); never continue from the
            // final filter.
            let _ = self.reset();
        }
        estimate.unwrap_or_else(|| self.single_pass(SinglePassReason::Estimator))
    }

    /// Where the passes of [`Calibrator::finish_in`] start over `log`, or
    /// why they cannot run (a log that does not hold what was pushed,
    /// truncated first to what the calibrator counted when it holds more).
    /// Out of line: the walk back along the log is not in the frame below
    /// which the passes run.
    #[inline(never)]
    fn final_start(&self, log: &mut (dyn SampleLog<T> + '_)) -> Result<LogStart, SinglePassReason> {
        let logged = self.progress.logged;
        if log.len() > logged as usize && self.progress.log_incomplete.is_none() {
            log.truncate(logged as usize);
        }
        match self.progress.log_incomplete {
            Some(r) => return Err(r),
            None if u32::try_from(log.len()).ok() != Some(logged) => {
                return Err(SinglePassReason::LogMismatch)
            }
            None => {}
        }
        self.log_start(log).map_err(|_| SinglePassReason::Estimator)
    }

    /// The estimator of record in `filter` from the prior of `settings`
    /// at `at`: the final answer's kind, `None` when a pass failed. Out of
    /// line: the prior's vectors are in this frame, not in the callers'.
    #[inline(never)]
    fn passes_in<F>(
        filter: &mut Filter<T, M, N, Z>,
        settings: &CalibratorConfig,
        at: LogStart,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        observer: F,
    ) -> Option<EstimateKind>
    where
        F: FnMut(&PassEvent<'_, T, M, N, Z>),
    {
        let (config, x0, sigma0) = Self::prior(settings);
        let x0 = at.state(M::LAYOUT, &x0);
        let start = PassStart {
            x0: &x0,
            sigma0: &sigma0,
            at,
        };
        estimator::estimate_from(filter, &config, &start, log, passes, observer)
            .ok()
            .map(|report| EstimateKind::Final {
                passes: report.passes,
                converged: report.converged,
            })
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
    /// run: [`EstimateKind::SinglePass`] with `reason`. Out of line: its
    /// estimate is written into the caller's return slot, not built in a
    /// frame below which the passes run (firmware stack).
    #[inline(never)]
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
