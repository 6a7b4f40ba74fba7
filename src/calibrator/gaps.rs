//! Lost data: the periods missing before a sample are bridged along the
//! commanded motion ([`CommandFrame::motion_across`](crate::command::CommandFrame::motion_across)) or, when it is not
//! known, predicted along the shortest rotation to the reported frame with
//! the attitude re-acquired (see the [module docs](super), "Lost data").

use nalgebra::{RealField, Vector3};

use super::{to_t, Calibrator, RejectReason};
use crate::command::{Gap, GapMotion};
use crate::ekf;
use crate::estimator::{LogRecord, SampleLog};
use crate::geometry::{dcm_from_quaternion, rotation_vector};
use crate::models::Model;
use crate::wire::{Sample, SinglePassReason};

/// The most periods a gap of unknown motion costs: across a longer gap the
/// motion to the reported frame is predicted over its last
/// `MAX_UNKNOWN_GAP_PERIODS` periods only, and the model's time is not
/// advanced over the earlier part (the parameters are constant; the
/// attitude, whose motion is not known, is re-acquired: its covariance is
/// re-opened to the prior without correlation to the parameters). One
/// sample then never costs more than the configured bridge search
/// ([`Limits::max_bridge`](crate::wire::Limits::max_bridge) periods) and this many predictions, where a jump
/// of the sequence number and the time by 2³² periods, which validation
/// accepts, took hours (fuzz/README.md). 7200 is the default
/// [`Limits::max_bridge`](crate::wire::Limits::max_bridge) (2 h of 1 s periods); every gap up to it is
/// predicted period by period over its whole length.
pub const MAX_UNKNOWN_GAP_PERIODS: u32 = 7200;

impl<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>
    Calibrator<T, M, N, Z>
{
    /// The commanded motion across the `gap` missing periods before sample
    /// `s` (see the module docs, "Lost data"): the computed frame's search
    /// ([`CommandFrame::motion_across`](crate::command::CommandFrame::motion_across)) from the last accepted sample to
    /// the frame `s` reports.
    fn motion_across(&self, s: &Sample, gap: u32) -> GapMotion {
        let lim = &self.settings.limits;
        let q = s.c_cn_quat.map(f64::from);
        let tol = lim.frame_tolerance_rad;
        let frame = *self.filter.command_frame();
        // Validated: a unit quaternion within the tolerance.
        let reported = dcm_from_quaternion(&q, tol).unwrap_or(frame.c_cn);
        let gap = Gap {
            missing: gap,
            dt: f64::from(s.dt),
            last_increment: Vector3::from(self.progress.last_increment),
            increment: Vector3::from(s.dtheta_cmd),
            reported,
        };
        frame.motion_across(&gap, lim.max_bridge, tol)
    }

    /// Predicts the `gap` missing periods along `motion` (and logs them as
    /// predicted periods); re-acquires the attitude when the motion is
    /// unknown.
    fn bridge(
        &mut self,
        gap: u32,
        dt: f64,
        motion: &GapMotion,
        mut log: Option<&mut (dyn SampleLog<T> + '_)>,
    ) -> Result<Vector3<f64>, ekf::Error> {
        let mut last = Vector3::zeros();
        match motion {
            GapMotion::Found { old, u_old, u_new } => {
                for i in 0..gap {
                    let u = if i < *old { u_old } else { u_new };
                    let inc = self.filter.command_frame().increment(u, dt);
                    self.filter.predict(&inc, dt)?;
                    self.append(log.as_deref_mut(), &LogRecord::predicted(dt, inc));
                    last = inc;
                }
                Ok(last)
            }
            GapMotion::Unknown { start } => {
                // At most MAX_UNKNOWN_GAP_PERIODS periods are predicted: the
                // model's time is not advanced over the earlier part of a
                // longer gap (see the constant).
                let predicted = gap.min(MAX_UNKNOWN_GAP_PERIODS);
                if predicted > 0 {
                    let c0 = self.filter.command_frame().c_cn;
                    let periods = f64::from(predicted);
                    let u = rotation_vector(&(start * c0.transpose())) / (dt * periods);
                    for _ in 0..predicted {
                        let inc = self.filter.command_frame().increment(&u, dt);
                        self.filter.predict(&inc, dt)?;
                        last = inc;
                    }
                }
                self.log_broken(SinglePassReason::Reacquired);
                self.filter
                    .reacquire_attitude(start, to_t(self.settings.prior_sigma_rad))?;
                Ok(last)
            }
        }
    }

    /// Bridges the `gap` periods lost before sample `s` (along the
    /// commanded motion, or re-acquiring the attitude), rolling the filter
    /// back if that fails. The point to roll back to is the state, the
    /// factor's attitude rows and the frame (`ekf::rollback`), not a copy of
    /// the filter (18 KB for the full M2-ps model in f64). Out of line: it
    /// is on the stack only while a gap is bridged, not under every
    /// sample's filter step.
    #[inline(never)]
    pub(super) fn bridge_gap(
        &mut self,
        s: &Sample,
        gap: u32,
        reanchored: bool,
        log: Option<&mut (dyn SampleLog<T> + '_)>,
    ) -> Result<(), RejectReason> {
        let dt = f64::from(s.dt);
        let motion = self.motion_across(s, gap);
        let saved = match self.filter.rollback_point() {
            Ok(point) => point,
            Err(e) => return Err(self.reject(RejectReason::Filter(e))),
        };
        let logged_before = self.progress.logged;
        match self.bridge(gap, dt, &motion, log) {
            Ok(last) => {
                // The bridged periods are consumed whatever the sample's
                // own period does: a refused sample leaves a gap of one
                // period, not one that grows with every refusal.
                let p = &mut self.progress;
                match motion {
                    GapMotion::Found { .. } => p.bridged = p.bridged.saturating_add(gap),
                    GapMotion::Unknown { .. } => {
                        p.reacquired = p.reacquired.saturating_add(1);
                        p.reacquired_periods = p.reacquired_periods.saturating_add(gap);
                    }
                }
                if reanchored {
                    p.clock_steps = p.clock_steps.saturating_add(1);
                }
                p.clock_candidate = None;
                let dt_us = libm::round(f64::from(s.dt) * 1e6) as u64;
                p.last_seq = Some(s.seq - 1);
                p.last_t_us = Some(s.t_us.saturating_sub(dt_us));
                p.last_increment = [last.x, last.y, last.z];
            }
            Err(e) => {
                self.filter.roll_back(&saved);
                if self.progress.logged != logged_before {
                    self.log_broken(SinglePassReason::FilterFailed);
                }
                return Err(self.reject(RejectReason::Filter(e)));
            }
        }
        Ok(())
    }
}
