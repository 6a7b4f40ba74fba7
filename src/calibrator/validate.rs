//! Sample validation: what makes a sample unusable ([`RejectReason`]),
//! the checks in the order they are made, and the counters by reason.

use nalgebra::RealField;

use super::Calibrator;
use crate::ekf;
use crate::models::Model;
use crate::wire::{Limits, Sample};

/// Why a sample was rejected. A rejected sample leaves the filter untouched
/// and loses only its own period (bridged with the next accepted sample).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum RejectReason {
    /// A used field is NaN or infinite.
    NonFinite,
    /// `dt` is outside the configured period ± tolerance.
    Period,
    /// A specific-force component exceeds [`Limits::max_accel_g`].
    AccelRange,
    /// A commanded-increment component exceeds [`Limits::max_increment_rad`].
    IncrementRange,
    /// A gimbal angle exceeds [`Limits::max_gimbal_rad`].
    GimbalRange,
    /// The configuration observes gimbal angles and the sample has none.
    MissingGimbal,
    /// Same sequence number as the last accepted sample.
    Duplicate,
    /// Sequence number below the last accepted one.
    OutOfOrder,
    /// Timestamp not after the last accepted one.
    TimeBackwards,
    /// Timestamp difference disagrees with `dt` × elapsed periods.
    TimeMismatch,
    /// The computed-frame quaternion is not a unit quaternion (within
    /// [`Limits::frame_tolerance_rad`]).
    FrameAttitude,
    /// The filter refused the period (its state was restored).
    Filter(ekf::Error),
}

impl core::fmt::Display for RejectReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RejectReason::NonFinite => f.write_str("a field is not finite"),
            RejectReason::Period => f.write_str("period outside the configured tolerance"),
            RejectReason::AccelRange => f.write_str("specific force out of range"),
            RejectReason::IncrementRange => f.write_str("commanded increment out of range"),
            RejectReason::GimbalRange => f.write_str("gimbal angle out of range"),
            RejectReason::MissingGimbal => f.write_str("gimbal angles required but missing"),
            RejectReason::Duplicate => f.write_str("duplicate sequence number"),
            RejectReason::OutOfOrder => f.write_str("sequence number out of order"),
            RejectReason::TimeBackwards => f.write_str("timestamp does not advance"),
            RejectReason::TimeMismatch => f.write_str("timestamp disagrees with the period"),
            RejectReason::FrameAttitude => {
                f.write_str("computed-frame quaternion is not a unit quaternion")
            }
            RejectReason::Filter(e) => write!(f, "filter refused the period: {e}"),
        }
    }
}

impl core::error::Error for RejectReason {}

/// `|d| ≤ tol`, false when either is NaN (a NaN limit rejects).
fn within(d: f64, tol: f64) -> bool {
    d.abs() <= tol
}

/// A sample that passed validation.
#[derive(Clone, Copy, Debug)]
pub(super) struct Validated {
    /// Missing periods before it.
    pub(super) gap: u32,
    /// Its timestamp re-anchors the time after a clock step.
    pub(super) reanchored: bool,
}

impl<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>
    Calibrator<T, M, N, Z>
{
    /// Checks `s` against the limits and the last accepted sample: the
    /// gap before it, or why it is rejected.
    pub(super) fn validate(&self, s: &Sample) -> Result<Validated, RejectReason> {
        let lim: &Limits = &self.settings.limits;
        let gimbal_obs = M::LAYOUT.gimbal_obs;
        let gimbal = if gimbal_obs { s.gimbal } else { None };
        let values = || {
            s.accel_mean
                .iter()
                .chain(s.c_cn_quat.iter())
                .chain(gimbal.iter().flatten())
                .chain(core::iter::once(&s.dt))
                .map(|v| f64::from(*v))
                .chain(s.dtheta_cmd.iter().copied())
        };
        if !values().all(f64::is_finite) {
            return Err(RejectReason::NonFinite);
        }
        let dt = f64::from(s.dt);
        if !within(dt - lim.period_s, lim.period_tolerance_s) || dt <= 0.0 {
            return Err(RejectReason::Period);
        }
        let over = |a: &[f32; 3], max: f64| a.iter().any(|v| f64::from(*v).abs() > max);
        if over(&s.accel_mean, lim.max_accel_g) {
            return Err(RejectReason::AccelRange);
        }
        if s.dtheta_cmd.iter().any(|v| v.abs() > lim.max_increment_rad) {
            return Err(RejectReason::IncrementRange);
        }
        match gimbal {
            Some(g) if over(&g, lim.max_gimbal_rad) => return Err(RejectReason::GimbalRange),
            None if gimbal_obs => return Err(RejectReason::MissingGimbal),
            _ => {}
        }
        let norm = libm::sqrt(
            s.c_cn_quat
                .iter()
                .map(|v| f64::from(*v) * f64::from(*v))
                .sum::<f64>(),
        );
        if !within(norm - 1.0, lim.frame_tolerance_rad) {
            return Err(RejectReason::FrameAttitude);
        }
        let (Some(last_seq), Some(last_t)) = (self.progress.last_seq, self.progress.last_t_us)
        else {
            return Ok(Validated {
                gap: 0,
                reanchored: false,
            });
        };
        if s.seq == last_seq {
            return Err(RejectReason::Duplicate);
        }
        if s.seq < last_seq {
            return Err(RejectReason::OutOfOrder);
        }
        // The time elapsed since (seq0, t0) agrees with the elapsed periods.
        let agrees = |seq0: u32, t0: u64| {
            s.seq > seq0
                && s.t_us > t0
                && within(
                    (s.t_us - t0) as f64 * 1e-6 - f64::from(s.seq - seq0) * dt,
                    f64::from(s.seq - seq0) * lim.period_tolerance_s,
                )
        };
        let reanchored = if agrees(last_seq, last_t) {
            false
        } else if self
            .progress
            .clock_candidate
            .is_some_and(|(seq0, t0)| agrees(seq0, t0))
        {
            true
        } else if s.t_us <= last_t {
            return Err(RejectReason::TimeBackwards);
        } else {
            return Err(RejectReason::TimeMismatch);
        };
        Ok(Validated {
            gap: s.seq - last_seq - 1,
            reanchored,
        })
    }

    /// Counts `r` by reason and returns it.
    pub(super) fn reject(&mut self, r: RejectReason) -> RejectReason {
        let c = &mut self.progress.rejects;
        let slot = match r {
            RejectReason::NonFinite => &mut c.non_finite,
            RejectReason::Period => &mut c.period,
            RejectReason::AccelRange => &mut c.accel_range,
            RejectReason::IncrementRange => &mut c.increment_range,
            RejectReason::GimbalRange => &mut c.gimbal_range,
            RejectReason::MissingGimbal => &mut c.missing_gimbal,
            RejectReason::Duplicate => &mut c.duplicate,
            RejectReason::OutOfOrder => &mut c.out_of_order,
            RejectReason::TimeBackwards => &mut c.time_backwards,
            RejectReason::TimeMismatch => &mut c.time_mismatch,
            RejectReason::FrameAttitude => &mut c.frame_attitude,
            RejectReason::Filter(_) => &mut c.filter,
        };
        *slot = slot.saturating_add(1);
        r
    }
}
