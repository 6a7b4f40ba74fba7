//! The attitude re-acquired after a gap across which the commanded motion is
//! not known ([`Filter::reacquire_attitude`]): the computed frame set, the
//! attitude's covariance re-opened, the parameters' information kept.

use nalgebra::{Matrix3, RealField};

use super::{all_finite, Error, Filter};
use crate::models::{Model, ATT};

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// Re-acquires the attitude after a gap across which the commanded
    /// motion is not known: the computed frame is set to `c_cn` (`C^c_n` at
    /// the start of the next period), and the attitude states' covariance
    /// is re-opened to `sigma` (rad) on each of them with no correlation to
    /// the parameters, whose covariance (their information) is kept. The
    /// attitude estimate is left as it is (the caller predicts it across the
    /// gap). In linearised mode the nominal's attitude follows the estimate,
    /// so the nominal stays a trajectory of the model.
    ///
    /// # Errors
    /// [`Error::NonFiniteInput`] or [`Error::CovarianceNotPositiveDefinite`]
    /// for a non-finite frame or a `sigma` that is not strictly positive; the
    /// filter is then left untouched.
    pub fn reacquire_attitude(&mut self, c_cn: &Matrix3<f64>, sigma: T) -> Result<(), Error> {
        if !all_finite(c_cn.iter().copied()) || !sigma.is_finite() {
            return Err(Error::NonFiniteInput);
        }
        if sigma <= T::zero() {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        // The pending time update moves only the attitude block, which this
        // replaces: it needs no applying.
        self.ud.reset_attitude(sigma * sigma);
        self.command.c_cn = *c_cn;
        if let Some(nominal) = self.reference.as_mut() {
            let att = Self::LAYOUT.attitude(&self.x);
            nominal.fixed_rows_mut::<3>(ATT).copy_from(&att);
        }
        self.pending.clear();
        Ok(())
    }
}
