//! Where a log starts on its rolling path ([`LogStart`]): the computed
//! frame `C^c_n` at the start of its first period, and the attitude states
//! that frame gives.
//!
//! A path starts with the computed frame aligned with n (`C^c_n = I`,
//! docs/model.md §The paper's scenario), and a filter started there knows
//! its attitude to the prior. A log that starts anywhere else (a recording
//! switched on mid-path, a stream that `Reset`s and starts again) does not:
//! the filter's computed frame would be wrong by the whole rotation so far,
//! and so would every commanded rate and predicted measurement. Every
//! [`Sample`](crate::wire::Sample) reports `C^c_n` at the end of its period,
//! so the first sample gives the start ([`LogStart::of_first_sample`]), and
//! the end of a run walked back through its log gives it again
//! ([`LogStart::walked_back`]), which is how the final passes find it
//! after a restore from a checkpoint (which carries only the current
//! frame). The attitude states at the start follow from the frame
//! ([`LogStart::attitude`]) to within the installation errors, which the
//! prior covers.

use nalgebra::{Matrix3, RealField, SVector, Vector3};

use super::{EstimatorError, SampleLog};
use crate::command::CommandFrame;
use crate::geometry::{angle_between, euler_angles, wrap_angles};
use crate::models::{AttitudeKind, Layout, ATT};

/// The computed frame `C^c_n` at the start of a log's first period: the
/// path's start (`C^c_n = I`), or where a log that starts elsewhere on
/// the path began, from its first sample or walked back from its end.
///
/// # Examples
///
/// A log that starts a quarter turn about East into the path: the start
/// from its first sample, and the attitude states it gives each model.
///
/// ```
/// use nalgebra::Vector3;
/// use rollcal::command::CommandFrame;
/// use rollcal::estimator::LogStart;
/// use rollcal::geometry::{earth_rate_n, r3, EARTH_RATE};
/// use rollcal::models::ConfigId;
///
/// let deg = core::f64::consts::PI / 180.0;
/// let w_ie = earth_rate_n(EARTH_RATE, 34.25 * deg);
/// let mut frame = CommandFrame::aligned(w_ie);
/// frame.c_cn = r3(90.0 * deg);
/// // The platform computer's first period: 0.1°/s about East.
/// let dtheta_c = frame.increment(&(Vector3::z() * 0.1 * deg), 1.0);
/// let period = frame.period(&dtheta_c, 1.0);
/// // The sample reports C^c_n at the end of its period.
/// let start = LogStart::of_first_sample(&period.c_cn[2], &dtheta_c, 1.0, &w_ie, 1e-5);
/// assert!(!start.is_aligned());
/// assert!((start.c_cn() - r3(90.0 * deg)).amax() < 1e-15);
/// // M1's misalignment from the computed frame is zero; M2's gimbal angles
/// // and M4's attitude angles are those of C^c_n.
/// assert_eq!(start.attitude(ConfigId::M1Pa.layout()), Vector3::zeros());
/// let gimbal = start.attitude(ConfigId::M2Ps.layout());
/// assert!((gimbal - Vector3::new(0.0, 0.0, 90.0 * deg)).amax() < 1e-14);
/// // At the path's start the first sample is explained by C^c_n = I.
/// let aligned = CommandFrame::aligned(w_ie);
/// let first = aligned.period(&dtheta_c, 1.0);
/// let start = LogStart::of_first_sample(&first.c_cn[2], &dtheta_c, 1.0, &w_ie, 1e-5);
/// assert!(start.is_aligned());
/// assert_eq!(start, LogStart::aligned());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogStart {
    /// `C^c_n` at the start of the first period; exactly `I` when aligned.
    c_cn: Matrix3<f64>,
}

impl Default for LogStart {
    fn default() -> Self {
        Self::aligned()
    }
}

impl LogStart {
    /// The path's start: the computed frame aligned with n, `C^c_n = I`.
    pub fn aligned() -> Self {
        Self {
            c_cn: Matrix3::identity(),
        }
    }

    /// The start at `c_cn` (`C^c_n` at the start of the first period), or
    /// [`LogStart::aligned`] when `c_cn` is within `tolerance` (rad, the
    /// angle of the rotation between them) of `I`: a log that starts
    /// where the path starts, to the precision of the reported frames
    /// ([`Limits::frame_tolerance_rad`](crate::wire::Limits::frame_tolerance_rad),
    /// the tolerance the calibrator bridges gaps to). A non-finite `c_cn`
    /// is taken as aligned (the calibrator has refused such a frame before).
    pub fn at(c_cn: &Matrix3<f64>, tolerance: f64) -> Self {
        let angle = angle_between(c_cn, &Matrix3::identity());
        if angle <= tolerance || !c_cn.iter().all(|v| v.is_finite()) {
            Self::aligned()
        } else {
            Self { c_cn: *c_cn }
        }
    }

    /// The start of a log whose first sample reports `reported` (`C^c_n`
    /// at the end of its period) after the commanded increment `dtheta_c`
    /// (rad, c frame) over `dt` (s), with the Earth rate `earth_rate_n`
    /// (rad/s, n frame): the reported frame walked back over the period
    /// ([`CommandFrame::period_before`]), then [`LogStart::at`].
    pub fn of_first_sample(
        reported: &Matrix3<f64>,
        dtheta_c: &Vector3<f64>,
        dt: f64,
        earth_rate_n: &Vector3<f64>,
        tolerance: f64,
    ) -> Self {
        let end = CommandFrame {
            c_cn: *reported,
            earth_rate_n: *earth_rate_n,
        };
        let [start, _, _] = end.period_before(dtheta_c, dt).c_cn;
        Self::at(&start, tolerance)
    }

    /// The start of the run recorded in `log` that ends at `frame_end`
    /// (`C^c_n` after its last period): the frame walked back through every
    /// record ([`CommandFrame::period_before`]; records whose period is
    /// unusable are skipped, as the filter skips them), then
    /// [`LogStart::at`]. A run that began aligned comes back to `I` within
    /// 6e-14 after the paper's 5400 periods, far inside any tolerance, and
    /// is aligned exactly.
    ///
    /// # Errors
    /// [`EstimatorError::Read`] when the log does not return a record.
    pub fn walked_back<T, L>(
        frame_end: &CommandFrame<f64>,
        log: &mut L,
        tolerance: f64,
    ) -> Result<Self, EstimatorError>
    where
        T: RealField + Copy,
        L: SampleLog<T> + ?Sized,
    {
        let mut frame = *frame_end;
        for index in (0..log.len()).rev() {
            let record = log.get(index).ok_or(EstimatorError::Read { index })?;
            if record.has_valid_period() {
                let period = frame.period_before(&record.dtheta_cmd, record.dt);
                frame.retreat(&period);
            }
        }
        Ok(Self::at(&frame.c_cn, tolerance))
    }

    /// `C^c_n` at the start of the first period.
    pub fn c_cn(&self) -> &Matrix3<f64> {
        &self.c_cn
    }

    /// Whether this is the path's start, `C^c_n = I` exactly.
    pub fn is_aligned(&self) -> bool {
        self.c_cn == Matrix3::identity()
    }

    /// The computed frame at this start, with the Earth rate
    /// `earth_rate_n` (rad/s, n frame).
    pub fn frame(&self, earth_rate_n: Vector3<f64>) -> CommandFrame<f64> {
        CommandFrame {
            c_cn: self.c_cn,
            earth_rate_n,
        }
    }

    /// The attitude states of `layout` at this start (rad), the platform
    /// taken on the computed frame and the base on n: M1's misalignment
    /// `ψ` from the computed frame is zero; M2's and M3's gimbal angles
    /// `θA` (`C^p_r = R3(γ)R2(β)R1(α)`, `C^p_r ≈ C^c_n`) and M4's attitude
    /// angles `θp` (`C^p_n ≈ C^c_n`) are the Euler angles of `C^c_n`,
    /// wrapped into `(−π, π]` as the gimbal encoders read them. The
    /// truth differs by the platform's drift from the computed frame and,
    /// for M2 and M3, the base mounting `λ`: installation errors, which
    /// the prior covers. Zero at the aligned start.
    pub fn attitude(&self, layout: Layout) -> Vector3<f64> {
        if self.is_aligned() {
            return Vector3::zeros();
        }
        match layout.attitude {
            AttitudeKind::Misalignment => Vector3::zeros(),
            AttitudeKind::Gimbal | AttitudeKind::Attitude => wrap_angles(&euler_angles(&self.c_cn)),
        }
    }

    /// `x0` with its attitude states set to [`LogStart::attitude`]: the
    /// initial estimate of a filter started here from the estimate `x0`
    /// (`x0` itself at the aligned start).
    pub fn state<const N: usize>(&self, layout: Layout, x0: &SVector<f64, N>) -> SVector<f64, N> {
        let mut x = *x0;
        if !self.is_aligned() {
            x.fixed_rows_mut::<3>(ATT).copy_from(&self.attitude(layout));
        }
        x
    }
}
