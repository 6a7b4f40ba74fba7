//! A log may start anywhere on the path: the start acquired from the first
//! sample of a run (after [`Calibrator::new`] or a reset), and found again
//! from the end of the run for the final passes ([`Calibrator::log_start`];
//! see [`LogStart`]).

use nalgebra::{RealField, Vector3};

use super::Calibrator;
use crate::ekf;
use crate::estimator::{EstimatorError, LogStart, SampleLog};
use crate::geometry::dcm_from_quaternion;
use crate::models::Model;
use crate::wire::Sample;

impl<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>
    Calibrator<T, M, N, Z>
{
    /// The start of a run whose first sample is `s` (validated): its
    /// reported `C^c_n` walked back over its period
    /// ([`LogStart::of_first_sample`], to the frame tolerance).
    fn start_of(&self, s: &Sample) -> LogStart {
        let lim = &self.settings.limits;
        let q = s.c_cn_quat.map(f64::from);
        // Validated: a unit quaternion within the tolerance.
        match dcm_from_quaternion(&q, lim.frame_tolerance_rad) {
            Some(reported) => LogStart::of_first_sample(
                &reported,
                &Vector3::from(s.dtheta_cmd),
                f64::from(s.dt),
                &Vector3::from(self.settings.earth_rate_n),
                lim.frame_tolerance_rad,
            ),
            None => LogStart::aligned(),
        }
    }

    /// Before the first sample `s` of a run: when its reported frame is not
    /// the path's start, the filter starts again from its prior there (the
    /// computed frame set, the attitude states acquired from it,
    /// [`LogStart::state`]; the prior's σ covers the rest). Returns whether
    /// it did; at the path's start nothing changes. The filter is at its
    /// prior before a run's first sample, so [`Calibrator::unacquire`]
    /// takes it back. Out of line: its prior's vectors are on the stack
    /// only at a run's first sample, not under every sample's filter step.
    #[inline(never)]
    pub(super) fn acquire_start(&mut self, s: &Sample) -> Result<bool, ekf::Error> {
        let start = self.start_of(s);
        if start.is_aligned() {
            return Ok(false);
        }
        let (config, x0, sigma0) = Self::prior(&self.settings);
        self.filter
            .restart(config, start.state(M::LAYOUT, &x0), sigma0)?;
        self.filter.start_at(start.c_cn())?;
        self.start = start;
        Ok(true)
    }

    /// Undoes [`Calibrator::acquire_start`] when the first sample's own
    /// period failed: the filter back at its prior on the path's start, as
    /// the run's first sample found it. Out of line (see
    /// [`Calibrator::acquire_start`]).
    #[inline(never)]
    pub(super) fn unacquire(&mut self) {
        let (config, x0, sigma0) = Self::prior(&self.settings);
        // The prior was accepted when the calibrator was built.
        let _ = self.filter.restart(config, x0, sigma0);
        self.start = LogStart::aligned();
    }

    /// Where this run's log started: the computed frame now, walked back
    /// through the `log` it appended ([`LogStart::walked_back`], to the
    /// frame tolerance), which must hold what this calibrator logged (as
    /// for [`Calibrator::finish`]). The final passes start there, also after
    /// a restore from a checkpoint (which carries only the current frame).
    /// When the log does not hold the whole run
    /// ([`Progress::log_incomplete`](crate::wire::Progress::log_incomplete),
    /// or another number of records than [`Progress::logged`](crate::wire::Progress::logged))
    /// it is the start acquired from the run's first sample (aligned after
    /// a restore).
    ///
    /// # Errors
    /// [`EstimatorError::Read`] when the log does not return a record.
    pub fn log_start(&self, log: &mut (dyn SampleLog<T> + '_)) -> Result<LogStart, EstimatorError> {
        let whole_run = u32::try_from(log.len()).ok() == Some(self.progress.logged);
        if self.progress.log_incomplete.is_some() || !whole_run {
            return Ok(self.start);
        }
        LogStart::walked_back(
            self.filter.command_frame(),
            log,
            self.settings.limits.frame_tolerance_rad,
        )
    }
}
