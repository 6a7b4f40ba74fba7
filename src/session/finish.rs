//! `Finish` for a calibrator of any configuration: the estimator of record
//! run in the calibrator's own filter, the running one saved meanwhile
//! ([`AnyCalibrator::finish_in_place`], the session's), or in a filter the
//! caller holds ([`AnyCalibrator::finish`]).

use nalgebra::RealField;

use super::{AnyCalibrator, AnyFilter};
use crate::calibrator::{Calibrator, Passed};
use crate::ekf::Filter;
use crate::estimator::{EstimatorOptions, SampleLog};
use crate::models::Model;
use crate::wire::{Checkpoint, Estimate, SinglePassReason};

impl<T: RealField + Copy> AnyCalibrator<T> {
    /// [`Calibrator::finish_in_place`]: the final answer computed in the
    /// calibrator's own filter, the running filter kept meanwhile in
    /// `saved` (a checkpoint: 13.0 KB for the full M2-ps model, where a
    /// second filter is 59.7 KB in f64) and put back after, bit for bit.
    /// What `Finish` does in a [`crate::session::Session`], `saved` being
    /// its reply slot. `on_update(pass, nis)` is called for every update of
    /// every pass (`nis` `None` for a period without measurement, or a
    /// refused update).
    pub fn finish_in_place(
        &mut self,
        saved: &mut Checkpoint,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        on_update: &mut dyn FnMut(u8, Option<T>),
    ) -> Estimate {
        let passed = self.finish_passes(saved, log, passes, on_update);
        self.finish_answer(passed, saved)
    }

    /// [`Calibrator::finish_passes`]: the first half of
    /// [`AnyCalibrator::finish_in_place`].
    pub(crate) fn finish_passes(
        &mut self,
        saved: &mut Checkpoint,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        on_update: &mut dyn FnMut(u8, Option<T>),
    ) -> Passed {
        each!(self, c => c.finish_passes(saved, log, passes, |e| {
            on_update(
                e.pass,
                e.result.as_ref().ok().and_then(|r| r.map(|i| i.nis)),
            );
        }))
    }

    /// [`Calibrator::finish_answer`]: the second half of
    /// [`AnyCalibrator::finish_in_place`].
    pub(crate) fn finish_answer(&mut self, passed: Passed, saved: &Checkpoint) -> Estimate {
        each!(self, c => c.finish_answer(passed, saved))
    }

    /// [`Calibrator::finish_in`] (the final answer) in the filter held by
    /// `scratch`: one of this configuration when it holds one (what it
    /// held does not matter otherwise), else one built there first. The
    /// calibrator is not touched; the cost is a second filter
    /// ([`AnyCalibrator::finish_in_place`] needs none). `on_update(pass, nis)` is called for every update
    /// of every pass (`nis` `None` for a period without measurement, or a
    /// refused update).
    pub fn finish(
        &self,
        scratch: &mut Option<AnyFilter<T>>,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        on_update: &mut dyn FnMut(u8, Option<T>),
    ) -> Estimate {
        // `$v`: the configuration's variant of both enums.
        macro_rules! finish_as {
            ($c:ident, $v:ident) => {
                finish_one(
                    $c,
                    scratch,
                    |any| match any {
                        AnyFilter::$v(f) => Some(f),
                        #[allow(unreachable_patterns)] // a build of one configuration
                        _ => None,
                    },
                    AnyFilter::$v,
                    log,
                    passes,
                    on_update,
                )
            };
        }
        match self {
            #[cfg(all(feature = "m1-pa", feature = "installation-model"))]
            AnyCalibrator::M1Pa(c) => finish_as!(c, M1Pa),
            #[cfg(all(feature = "m1-ps", feature = "installation-model"))]
            AnyCalibrator::M1Ps(c) => finish_as!(c, M1Ps),
            #[cfg(all(feature = "m2-ps", feature = "installation-model"))]
            AnyCalibrator::M2Ps(c) => finish_as!(c, M2Ps),
            #[cfg(all(feature = "m3-pa", feature = "installation-model"))]
            AnyCalibrator::M3Pa(c) => finish_as!(c, M3Pa),
            #[cfg(all(feature = "m3-ps", feature = "installation-model"))]
            AnyCalibrator::M3Ps(c) => finish_as!(c, M3Ps),
            #[cfg(all(feature = "m4-pa", feature = "installation-model"))]
            AnyCalibrator::M4Pa(c) => finish_as!(c, M4Pa),
            #[cfg(all(feature = "m4-ps", feature = "installation-model"))]
            AnyCalibrator::M4Ps(c) => finish_as!(c, M4Ps),
            #[cfg(all(feature = "m1-pa", feature = "full-model"))]
            AnyCalibrator::M1PaFull(c) => finish_as!(c, M1PaFull),
            #[cfg(all(feature = "m1-ps", feature = "full-model"))]
            AnyCalibrator::M1PsFull(c) => finish_as!(c, M1PsFull),
            #[cfg(all(feature = "m2-ps", feature = "full-model"))]
            AnyCalibrator::M2PsFull(c) => finish_as!(c, M2PsFull),
            #[cfg(all(feature = "m3-pa", feature = "full-model"))]
            AnyCalibrator::M3PaFull(c) => finish_as!(c, M3PaFull),
            #[cfg(all(feature = "m3-ps", feature = "full-model"))]
            AnyCalibrator::M3PsFull(c) => finish_as!(c, M3PsFull),
            #[cfg(all(feature = "m4-pa", feature = "full-model"))]
            AnyCalibrator::M4PaFull(c) => finish_as!(c, M4PaFull),
            #[cfg(all(feature = "m4-ps", feature = "full-model"))]
            AnyCalibrator::M4PsFull(c) => finish_as!(c, M4PsFull),
        }
    }
}

/// [`AnyCalibrator::finish`] for one configuration: `of` is its variant of
/// [`AnyFilter`] (`None` for another), `wrap` makes one.
#[inline(never)]
fn finish_one<
    T: RealField + Copy,
    M: crate::models::Model<N, Z> + Clone,
    const N: usize,
    const Z: usize,
>(
    c: &Calibrator<T, M, N, Z>,
    scratch: &mut Option<AnyFilter<T>>,
    of: fn(&mut AnyFilter<T>) -> Option<&mut Filter<T, M, N, Z>>,
    wrap: impl Fn(Filter<T, M, N, Z>) -> AnyFilter<T>,
    log: &mut (dyn SampleLog<T> + '_),
    passes: &EstimatorOptions,
    on_update: &mut dyn FnMut(u8, Option<T>),
) -> Estimate {
    if scratch.as_mut().and_then(of).is_none() {
        fill_scratch(scratch, c, wrap);
    }
    match scratch.as_mut().and_then(of) {
        Some(filter) => c.finish_in(filter, log, passes, |e| {
            on_update(
                e.pass,
                e.result.as_ref().ok().and_then(|r| r.map(|i| i.nis)),
            );
        }),
        // Not reached: `fill_scratch` has just put this variant there.
        None => c.single_pass(SinglePassReason::Estimator),
    }
}

/// `*scratch` becomes a filter of `c`'s configuration, in a frame of its
/// own, which has returned before the passes run. What it holds does not
/// matter (the passes restart it in place, [`Calibrator::finish_in`]):
/// it is [`Calibrator::scratch_filter`]'s placeholder, zeros written
/// straight into the slot (`wrap`, the variant's constructor, is inlined
/// here), neither a filter built from the prior by value (its factor a
/// temporary in this frame: 24–36 KB on the M7 for the full model) nor a
/// copy of the running filter.
#[inline(never)]
fn fill_scratch<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>(
    scratch: &mut Option<AnyFilter<T>>,
    c: &Calibrator<T, M, N, Z>,
    wrap: impl Fn(Filter<T, M, N, Z>) -> AnyFilter<T>,
) {
    *scratch = Some(wrap(c.scratch_filter()));
}
