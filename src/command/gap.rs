//! The commanded motion across a gap of lost periods, from what the sample
//! after the gap reports ([`Gap`]): pure kinematics of the computed frame
//! (docs/model.md §Frames), searched by [`CommandFrame::motion_across`].
//!
//! A rolling path changes its rate only at period boundaries, so across a
//! gap inside one path segment, or one that contains one segment switch,
//! the motion is `j` periods at the last sample's path rate and the others
//! at the new sample's, for some `j`. The search tries every `j` and keeps
//! the first that carries the frame to the reported one; when none does,
//! the motion is not known.

use nalgebra::{Matrix3, Vector3};

use super::CommandFrame;
use crate::geometry::angle_between;

/// What is known across a gap of `missing` lost periods: the last accepted
/// sample's commanded increment, and the commanded increment and reported
/// computed frame of the sample after the gap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gap {
    /// Periods lost between the two samples.
    pub missing: u32,
    /// Period length `T` (s).
    pub dt: f64,
    /// The commanded increment of the last period before the gap (rad, c
    /// frame).
    pub last_increment: Vector3<f64>,
    /// The commanded increment of the first period after the gap, the new
    /// sample's (rad, c frame).
    pub increment: Vector3<f64>,
    /// `C^c_n` reported at the end of the new sample's period.
    pub reported: Matrix3<f64>,
}

/// The commanded motion across a gap ([`CommandFrame::motion_across`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GapMotion {
    /// `old` periods at the last sample's path rate `u_old`, the rest at
    /// the new sample's `u_new` (rad/s, c frame).
    Found {
        /// Missing periods at the last sample's rate (the first ones).
        old: u32,
        /// The last sample's path rate (rad/s, c frame).
        u_old: Vector3<f64>,
        /// The new sample's path rate (rad/s, c frame).
        u_new: Vector3<f64>,
    },
    /// Not found: `start` is `C^c_n` at the start of the new sample's
    /// period, from its report.
    Unknown {
        /// `C^c_n` at the start of the new sample's period.
        start: Matrix3<f64>,
    },
}

impl CommandFrame<f64> {
    /// The commanded motion across `gap`, starting at this frame (the end
    /// of the last period before the gap): the first hypothesis, from the
    /// most periods at the last sample's rate down, whose end frame is
    /// within `tolerance` (rad) of the reported one, searched only for a
    /// gap of at most `max_bridge` periods; else [`GapMotion::Unknown`].
    ///
    /// # Examples
    ///
    /// Three periods lost while the platform rolls at a constant rate: the
    /// motion is found, all at the last sample's rate.
    ///
    /// ```
    /// use nalgebra::Vector3;
    /// use rollcal::command::{CommandFrame, Gap, GapMotion};
    /// use rollcal::geometry::{earth_rate_n, EARTH_RATE};
    ///
    /// let w = earth_rate_n(EARTH_RATE, 34.25_f64.to_radians());
    /// let (dt, u) = (1.0, Vector3::new(0.0, 1e-3, 0.0)); // 0.057 °/s about y
    /// let mut frame = CommandFrame::aligned(w);
    /// let last_increment = frame.increment(&u, dt);
    /// frame.c_cn = frame.after(&u, dt, 1); // the last accepted period
    /// // Three periods lost, then the new sample's own period.
    /// let lost = CommandFrame { c_cn: frame.after(&u, dt, 3), ..frame };
    /// let gap = Gap {
    ///     missing: 3,
    ///     dt,
    ///     last_increment,
    ///     increment: lost.increment(&u, dt),
    ///     reported: frame.after(&u, dt, 4),
    /// };
    /// match frame.motion_across(&gap, 7200, 1e-5) {
    ///     GapMotion::Found { old, u_old, .. } => {
    ///         assert_eq!(old, 3);
    ///         assert!((u_old - u).amax() < 1e-12);
    ///     }
    ///     GapMotion::Unknown { .. } => unreachable!(),
    /// }
    /// ```
    pub fn motion_across(&self, gap: &Gap, max_bridge: u32, tolerance: f64) -> GapMotion {
        if gap.missing <= max_bridge {
            if let Some(found) = self.two_rate_motion(gap, tolerance) {
                return found;
            }
        }
        let [start, _, _] = self
            .at(gap.reported)
            .period_before(&gap.increment, gap.dt)
            .c_cn;
        GapMotion::Unknown { start }
    }

    /// This frame's Earth rate at `c_cn`.
    fn at(&self, c_cn: Matrix3<f64>) -> Self {
        Self {
            c_cn,
            earth_rate_n: self.earth_rate_n,
        }
    }

    /// The search over the number of periods at the last sample's rate.
    fn two_rate_motion(&self, gap: &Gap, tolerance: f64) -> Option<GapMotion> {
        let (dt, last) = (gap.dt, &gap.last_increment);
        let [last_start, _, _] = self.period_before(last, dt).c_cn;
        let u_old = self.at(last_start).path_rate(last, dt);
        for old in (0..=gap.missing).rev() {
            let c_switch = self.after(&u_old, dt, old);
            let (start, u_new) =
                self.at(c_switch)
                    .rate_after(&gap.increment, dt, gap.missing - old, tolerance);
            let end = self.at(start).after(&u_new, dt, 1);
            if angle_between(&end, &gap.reported) <= tolerance {
                return Some(GapMotion::Found { old, u_old, u_new });
            }
        }
        None
    }

    /// The new path rate, at the start of the sample's own period
    /// `periods` periods at that rate after this frame, and that start:
    /// a fixed point, as the start frame enters only through the Earth-rate
    /// term (contraction ≈ |ω_ie| T × missing periods at the new rate,
    /// < 0.5 up to 7200 periods).
    fn rate_after(
        &self,
        increment: &Vector3<f64>,
        dt: f64,
        periods: u32,
        tolerance: f64,
    ) -> (Matrix3<f64>, Vector3<f64>) {
        let mut u_new = self.path_rate(increment, dt);
        let mut start = self.c_cn;
        for _ in 0..8 {
            let next = self.after(&u_new, dt, periods);
            let moved = angle_between(&next, &start);
            start = next;
            u_new = self.at(start).path_rate(increment, dt);
            if moved < tolerance * 1e-3 {
                break;
            }
        }
        (start, u_new)
    }
}
