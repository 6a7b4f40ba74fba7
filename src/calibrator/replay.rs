//! After a device reset: the records the sample log kept past the last
//! checkpoint, run through the filter again ([`Calibrator::replay_log`]),
//! so that a calibration resumes from everything that survived, not only
//! from the checkpoint.

use nalgebra::RealField;

use super::{to_f64, Calibrator};
use crate::ekf;
use crate::estimator::SampleLog;
use crate::models::Model;

impl<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>
    Calibrator<T, M, N, Z>
{
    /// Runs the filter over the records of `log` past the
    /// [`Progress::logged`](crate::wire::Progress::logged) it counts (those
    /// a run appended after the checkpoint this calibrator was restored
    /// from), one filter period each, as [`Calibrator::push_logged`] ran
    /// them, and counts them as its own. Returns how many it replayed.
    ///
    /// It stops at the first record it cannot replay as the run did: a
    /// period without measurement (a bridged gap, whose bookkeeping the
    /// log does not hold), an unreadable one, or one the filter refuses; the
    /// log is truncated there (those records are forgotten, as a device
    /// that lost them would). Nothing is replayed into a calibrator that has
    /// not taken its first sample (its start is not known) or whose log is
    /// already incomplete.
    ///
    /// The replayed periods are the log's, as a packed log rounds them
    /// (increments to 2⁻⁴⁰ rad, accelerometer means to 2⁻²⁷ g: 0.004 of
    /// the paper's noise), so the running filter agrees with the
    /// uninterrupted run's within that rounding (1.1e-3σ after 143
    /// replayed periods of the realistic M2-ps stream, `firmware/run-qemu.sh`'s
    /// reset run). The final answer
    /// ([`Calibrator::finish`]) runs over the log from the prior and does
    /// not depend on it: it is the uninterrupted run's, bit for bit. The
    /// time of the last sample is advanced by each record's period
    /// (rounded to 1 µs), which a host whose clock ticks the sample periods
    /// reproduces exactly.
    // Not inlined: the session dispatches to fourteen of these.
    #[inline(never)]
    pub fn replay_log(&mut self, log: &mut (dyn SampleLog<T> + '_)) -> u32 {
        if self.progress.log_incomplete.is_some() || self.progress.last_seq.is_none() {
            return 0;
        }
        let mut replayed = 0u32;
        while (self.progress.logged as usize) < log.len() {
            if !self.replay_one(log) {
                break;
            }
            replayed = replayed.saturating_add(1);
        }
        if log.len() > self.progress.logged as usize {
            log.truncate(self.progress.logged as usize);
        }
        replayed
    }

    /// One record of [`Calibrator::replay_log`]; `false` where it stops.
    fn replay_one(&mut self, log: &mut (dyn SampleLog<T> + '_)) -> bool {
        let k = self.progress.logged as usize;
        let Some(record) = log.get(k) else {
            return false;
        };
        let Some(obs) = record.observation else {
            return false;
        };
        let (Some(seq), Some(t_us)) = (self.progress.last_seq, self.progress.last_t_us) else {
            return false;
        };
        let Some(seq) = seq.checked_add(1) else {
            return false;
        };
        if !record.has_valid_period() {
            return false;
        }
        let nis = match self.filter.step(&record.dtheta_cmd, record.dt, &obs) {
            Ok(innovation) => Some(to_f64(innovation.nis)),
            Err(ekf::Error::Gated) => None,
            Err(_) => return false,
        };
        let p = &mut self.progress;
        match nis {
            Some(v) => p.last_nis = v,
            None => p.gated = p.gated.saturating_add(1),
        }
        let dt_us = libm::round(record.dt * 1e6) as u64;
        p.logged = p.logged.saturating_add(1);
        p.accepted = p.accepted.saturating_add(1);
        p.clock_candidate = None;
        p.last_seq = Some(seq);
        p.last_t_us = Some(t_us.saturating_add(dt_us));
        p.last_increment = [
            record.dtheta_cmd.x,
            record.dtheta_cmd.y,
            record.dtheta_cmd.z,
        ];
        p.since_estimate = p.since_estimate.saturating_add(1);
        let every = self.settings.estimate_every;
        if every > 0 && p.since_estimate >= every {
            p.since_estimate = 0;
        }
        true
    }
}
