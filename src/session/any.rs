//! [`AnyCalibrator`] and [`AnyFilter`]: a calibrator and a filter of any of
//! the seven configurations, each call dispatched to the configuration's
//! own out-of-line function (one configuration's frame on a firmware's
//! stack, not seven).

use nalgebra::RealField;

use crate::calibrator::{self, Calibrator, RejectReason};
use crate::ekf::Filter;
use crate::estimator::{EstimatorError, LogStart, SampleLog};
#[allow(unused_imports)] // the configurations left out of a build (cargo features)
use crate::models::{ConfigId, ErrorModel, M1Pa, M1Ps, M2Ps, M3Pa, M3Ps, M4Pa, M4Ps, Model};
#[allow(unused_imports)] // the configurations left out of a build (cargo features)
use crate::models::{M1PaFull, M1PsFull, M2PsFull, M3PaFull, M3PsFull, M4PaFull, M4PsFull};
use crate::wire::{CalibratorConfig, Checkpoint, Estimate, Progress};

/// A calibrator of any of the seven configurations (the value-level side of
/// [`crate::with_config!`]).
// The variants differ in size by their covariance; no heap to box them.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum AnyCalibrator<T: RealField + Copy> {
    /// M1-pa.
    #[cfg(all(feature = "m1-pa", feature = "installation-model"))]
    M1Pa(Calibrator<T, M1Pa, 12, 3>),
    /// M1-ps.
    #[cfg(all(feature = "m1-ps", feature = "installation-model"))]
    M1Ps(Calibrator<T, M1Ps, 15, 3>),
    /// M2-ps.
    #[cfg(all(feature = "m2-ps", feature = "installation-model"))]
    M2Ps(Calibrator<T, M2Ps, 18, 6>),
    /// M3-pa.
    #[cfg(all(feature = "m3-pa", feature = "installation-model"))]
    M3Pa(Calibrator<T, M3Pa, 15, 3>),
    /// M3-ps.
    #[cfg(all(feature = "m3-ps", feature = "installation-model"))]
    M3Ps(Calibrator<T, M3Ps, 18, 3>),
    /// M4-pa.
    #[cfg(all(feature = "m4-pa", feature = "installation-model"))]
    M4Pa(Calibrator<T, M4Pa, 12, 3>),
    /// M4-ps.
    #[cfg(all(feature = "m4-ps", feature = "installation-model"))]
    M4Ps(Calibrator<T, M4Ps, 15, 3>),
    /// M1-pa, full model.
    #[cfg(all(feature = "m1-pa", feature = "full-model"))]
    M1PaFull(Calibrator<T, M1PaFull, 48, 3>),
    /// M1-ps, full model.
    #[cfg(all(feature = "m1-ps", feature = "full-model"))]
    M1PsFull(Calibrator<T, M1PsFull, 51, 3>),
    /// M2-ps, full model.
    #[cfg(all(feature = "m2-ps", feature = "full-model"))]
    M2PsFull(Calibrator<T, M2PsFull, 54, 6>),
    /// M3-pa, full model.
    #[cfg(all(feature = "m3-pa", feature = "full-model"))]
    M3PaFull(Calibrator<T, M3PaFull, 51, 3>),
    /// M3-ps, full model.
    #[cfg(all(feature = "m3-ps", feature = "full-model"))]
    M3PsFull(Calibrator<T, M3PsFull, 54, 3>),
    /// M4-pa, full model.
    #[cfg(all(feature = "m4-pa", feature = "full-model"))]
    M4PaFull(Calibrator<T, M4PaFull, 48, 3>),
    /// M4-ps, full model.
    #[cfg(all(feature = "m4-ps", feature = "full-model"))]
    M4PsFull(Calibrator<T, M4PsFull, 51, 3>),
}

/// A filter of any of the seven configurations: the one in which a
/// session runs `Finish`'s passes ([`AnyCalibrator::finish`]). The session
/// keeps it, so a firmware that holds its session in static memory has no
/// filter on its stack under the passes (the M7's 5.8 KB f64 M2-ps filter).
// The variants differ in size by their covariance; no heap to box them.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum AnyFilter<T: RealField + Copy> {
    /// M1-pa.
    #[cfg(all(feature = "m1-pa", feature = "installation-model"))]
    M1Pa(Filter<T, M1Pa, 12, 3>),
    /// M1-ps.
    #[cfg(all(feature = "m1-ps", feature = "installation-model"))]
    M1Ps(Filter<T, M1Ps, 15, 3>),
    /// M2-ps.
    #[cfg(all(feature = "m2-ps", feature = "installation-model"))]
    M2Ps(Filter<T, M2Ps, 18, 6>),
    /// M3-pa.
    #[cfg(all(feature = "m3-pa", feature = "installation-model"))]
    M3Pa(Filter<T, M3Pa, 15, 3>),
    /// M3-ps.
    #[cfg(all(feature = "m3-ps", feature = "installation-model"))]
    M3Ps(Filter<T, M3Ps, 18, 3>),
    /// M4-pa.
    #[cfg(all(feature = "m4-pa", feature = "installation-model"))]
    M4Pa(Filter<T, M4Pa, 12, 3>),
    /// M4-ps.
    #[cfg(all(feature = "m4-ps", feature = "installation-model"))]
    M4Ps(Filter<T, M4Ps, 15, 3>),
    /// M1-pa, full model.
    #[cfg(all(feature = "m1-pa", feature = "full-model"))]
    M1PaFull(Filter<T, M1PaFull, 48, 3>),
    /// M1-ps, full model.
    #[cfg(all(feature = "m1-ps", feature = "full-model"))]
    M1PsFull(Filter<T, M1PsFull, 51, 3>),
    /// M2-ps, full model.
    #[cfg(all(feature = "m2-ps", feature = "full-model"))]
    M2PsFull(Filter<T, M2PsFull, 54, 6>),
    /// M3-pa, full model.
    #[cfg(all(feature = "m3-pa", feature = "full-model"))]
    M3PaFull(Filter<T, M3PaFull, 51, 3>),
    /// M3-ps, full model.
    #[cfg(all(feature = "m3-ps", feature = "full-model"))]
    M3PsFull(Filter<T, M3PsFull, 54, 3>),
    /// M4-pa, full model.
    #[cfg(all(feature = "m4-pa", feature = "full-model"))]
    M4PaFull(Filter<T, M4PaFull, 48, 3>),
    /// M4-ps, full model.
    #[cfg(all(feature = "m4-ps", feature = "full-model"))]
    M4PsFull(Filter<T, M4PsFull, 51, 3>),
}

impl<T: RealField + Copy> AnyCalibrator<T> {
    /// A calibrator of `settings.config` at the prior.
    pub fn new(settings: CalibratorConfig) -> Result<Self, calibrator::Error> {
        let mut slot = None;
        Self::build_into(&mut slot, settings)?;
        slot.ok_or(calibrator::Error::ConfigMismatch {
            expected: ConfigId::first_built(),
            found: settings.config,
        })
    }

    /// Puts a calibrator of `settings.config` and `settings.errors` at the
    /// prior into `slot`
    /// (whatever it held; untouched on error). Each configuration is built
    /// by its own out-of-line function, so a firmware's stack holds one
    /// configuration's temporaries, not seven; the prior is checked first
    /// and the calibrator then made in `slot` itself: one of the same
    /// configuration is re-initialised in place, any other slot first
    /// receives a placeholder of zeros, which the compiler writes straight
    /// into it (`Calibrator::init_in_place`). No calibrator-sized value
    /// is on the stack: on the all-configuration M7 image (f64, the full
    /// model's 54 states) the largest frame of this path is 3.8 KB and its
    /// deepest call path 9.6 KB, where building the calibrator by value
    /// took a 38.4 KB frame (issue 43; `python3 tools/stack-usage.py ELF
    /// 'build_one|session::any::place'`, the ELF
    /// `firmware/target/m7/thumbv7em-none-eabihf/release/rollcal-firmware`
    /// of `firmware/run-qemu.sh`).
    pub fn build_into(
        slot: &mut Option<Self>,
        settings: CalibratorConfig,
    ) -> Result<(), calibrator::Error> {
        // `$v`: the configuration's variant.
        macro_rules! build_as {
            ($v:ident) => {
                Self::build_one(
                    slot,
                    settings,
                    |any| match any {
                        Self::$v(c) => Some(c),
                        #[allow(unreachable_patterns)] // a build of one configuration
                        _ => None,
                    },
                    Self::$v,
                )
            };
        }
        match (settings.config, settings.errors) {
            #[cfg(all(feature = "m1-pa", feature = "installation-model"))]
            (ConfigId::M1Pa, ErrorModel::Installation) => {
                build_as!(M1Pa)
            }
            #[cfg(all(feature = "m1-ps", feature = "installation-model"))]
            (ConfigId::M1Ps, ErrorModel::Installation) => {
                build_as!(M1Ps)
            }
            #[cfg(all(feature = "m2-ps", feature = "installation-model"))]
            (ConfigId::M2Ps, ErrorModel::Installation) => {
                build_as!(M2Ps)
            }
            #[cfg(all(feature = "m3-pa", feature = "installation-model"))]
            (ConfigId::M3Pa, ErrorModel::Installation) => {
                build_as!(M3Pa)
            }
            #[cfg(all(feature = "m3-ps", feature = "installation-model"))]
            (ConfigId::M3Ps, ErrorModel::Installation) => {
                build_as!(M3Ps)
            }
            #[cfg(all(feature = "m4-pa", feature = "installation-model"))]
            (ConfigId::M4Pa, ErrorModel::Installation) => {
                build_as!(M4Pa)
            }
            #[cfg(all(feature = "m4-ps", feature = "installation-model"))]
            (ConfigId::M4Ps, ErrorModel::Installation) => {
                build_as!(M4Ps)
            }
            #[cfg(all(feature = "m1-pa", feature = "full-model"))]
            (ConfigId::M1Pa, ErrorModel::Full) => build_as!(M1PaFull),
            #[cfg(all(feature = "m1-ps", feature = "full-model"))]
            (ConfigId::M1Ps, ErrorModel::Full) => build_as!(M1PsFull),
            #[cfg(all(feature = "m2-ps", feature = "full-model"))]
            (ConfigId::M2Ps, ErrorModel::Full) => build_as!(M2PsFull),
            #[cfg(all(feature = "m3-pa", feature = "full-model"))]
            (ConfigId::M3Pa, ErrorModel::Full) => build_as!(M3PaFull),
            #[cfg(all(feature = "m3-ps", feature = "full-model"))]
            (ConfigId::M3Ps, ErrorModel::Full) => build_as!(M3PsFull),
            #[cfg(all(feature = "m4-pa", feature = "full-model"))]
            (ConfigId::M4Pa, ErrorModel::Full) => build_as!(M4PaFull),
            #[cfg(all(feature = "m4-ps", feature = "full-model"))]
            (ConfigId::M4Ps, ErrorModel::Full) => build_as!(M4PsFull),
            // A configuration or an error model left out of this build
            // (cargo features).
            #[allow(unreachable_patterns)]
            (found, errors) => Err(calibrator::Error::not_built(found, errors)),
        }
    }

    /// [`AnyCalibrator::build_into`] for one configuration: `of` is its
    /// variant (`None` for another), `wrap` makes one. A slot that holds
    /// this configuration's calibrator is made a new one in place; any
    /// other is first filled with a placeholder ([`place`]), made one in
    /// place then.
    #[inline(never)]
    fn build_one<M: Model<N, Z> + Clone, const N: usize, const Z: usize>(
        slot: &mut Option<Self>,
        settings: CalibratorConfig,
        of: fn(&mut Self) -> Option<&mut Calibrator<T, M, N, Z>>,
        wrap: fn(Calibrator<T, M, N, Z>) -> Self,
    ) -> Result<(), calibrator::Error> {
        let variance = Calibrator::<T, M, N, Z>::prior_variance(&settings)?;
        if slot.as_mut().and_then(of).is_none() {
            place(slot, settings, wrap);
        }
        match slot.as_mut().and_then(of) {
            Some(c) => {
                c.init_in_place(settings, &variance);
                Ok(())
            }
            // Not reached: `place` has just put this variant there.
            None => Err(calibrator::Error::ConfigMismatch {
                expected: M::ID,
                found: settings.config,
            }),
        }
    }

    /// The calibrator's settings.
    pub fn settings(&self) -> &CalibratorConfig {
        each!(self, c => c.settings())
    }

    /// Its bookkeeping.
    pub fn progress(&self) -> &Progress {
        each!(self, c => c.progress())
    }

    /// [`Calibrator::push_logged`].
    pub fn push_logged(
        &mut self,
        s: &crate::wire::Sample,
        log: &mut (dyn SampleLog<T> + '_),
    ) -> Result<Option<Estimate>, RejectReason> {
        each!(self, c => c.push_logged(s, log))
    }

    /// [`Calibrator::estimate`] (running).
    pub fn estimate(&self) -> Estimate {
        each!(self, c => c.estimate())
    }

    /// [`Calibrator::checkpoint`].
    pub fn checkpoint(&self) -> Checkpoint {
        each!(self, c => c.checkpoint())
    }

    /// [`Calibrator::checkpoint_into`]: written into `cp`, whatever it held.
    pub fn checkpoint_into(&self, cp: &mut Checkpoint) {
        each!(self, c => c.checkpoint_into(cp))
    }

    /// [`Calibrator::reset`].
    pub fn reset(&mut self) -> Result<(), calibrator::Error> {
        each!(self, c => c.reset())
    }

    /// Restores from `cp` with the current settings; on error the calibrator
    /// is unchanged.
    pub fn restore(&mut self, cp: &Checkpoint) -> Result<(), calibrator::Error> {
        let settings = *self.settings();
        each!(self, c => restore_into(c, settings, cp))
    }

    /// [`Calibrator::replay_log`]: the log's records past the calibrator's
    /// count run through its filter (after a device reset).
    pub fn replay_log(&mut self, log: &mut (dyn SampleLog<T> + '_)) -> u32 {
        each!(self, c => c.replay_log(log))
    }

    /// [`Calibrator::set_frame_errors`].
    pub fn set_frame_errors(&mut self, n: u32) {
        each!(self, c => c.set_frame_errors(n))
    }

    /// [`Calibrator::log_start`]: where the run's log started.
    pub fn log_start(&self, log: &mut (dyn SampleLog<T> + '_)) -> Result<LogStart, EstimatorError> {
        each!(self, c => c.log_start(log))
    }
}

/// `*slot` becomes `wrap`'s variant holding [`Calibrator::placeholder`],
/// in a frame of its own: the placeholder's zeros are written straight
/// into the slot, with no calibrator-sized temporary.
#[inline(never)]
fn place<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>(
    slot: &mut Option<AnyCalibrator<T>>,
    settings: CalibratorConfig,
    wrap: fn(Calibrator<T, M, N, Z>) -> AnyCalibrator<T>,
) {
    *slot = Some(wrap(Calibrator::placeholder(settings)));
}

/// [`Calibrator::restore_in_place`], in a frame of its own (one
/// configuration's temporaries on the stack, not seven).
#[inline(never)]
fn restore_into<
    T: RealField + Copy,
    M: crate::models::Model<N, Z> + Clone,
    const N: usize,
    const Z: usize,
>(
    c: &mut Calibrator<T, M, N, Z>,
    settings: CalibratorConfig,
    cp: &Checkpoint,
) -> Result<(), calibrator::Error> {
    c.restore_in_place(settings, cp)
}
