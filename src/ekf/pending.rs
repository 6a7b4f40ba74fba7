//! The deferred time update: a period the state has been propagated over
//! whose covariance time update is still to be applied ([`Pending`]), with
//! the period's measurement (docs/model.md §Measurement timing: the gyro
//! noise of a period is also measurement noise) or alone
//! ([`Filter::settle`]).

use nalgebra::{Matrix3, RealField, Vector3};

use super::factor::{AttitudeNoise, Ud};
use super::{Error, Filter};
use crate::command::{Period, PeriodIn};
use crate::models::{Model, PeriodPropagation};

/// A period the state has been propagated over whose covariance time
/// update is still to be applied (with the period's measurement, or alone).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Pending<T: RealField + Copy, const N: usize> {
    pub(super) period: Period<f64>,
    /// The same period in `T` (each value rounded once,
    /// [`CommandFrame::period_in_into`](crate::command::CommandFrame::period_in_into)):
    /// what the Jacobians and the attitude's increments read, and the
    /// frame's turn within it (M1's specific force).
    pub(super) period_t: PeriodIn<T>,
    /// The attitude at the period's three nodes (rad).
    pub(super) att: [Vector3<f64>; 3],
    /// The same nodes rounded to `T`, with the period's transition rows,
    /// `F` and noise map, computed in `T`.
    pub(super) prop: PeriodPropagation<T, N>,
    /// Second-order process noise of the attitude (rad², zero unless
    /// [`Options::second_order_dynamics`]).
    pub(super) q_extra: Matrix3<T>,
}

impl<T: RealField + Copy, const N: usize> Pending<T, N> {
    /// An all-zero period (the content of an empty slot).
    fn zeros() -> Self {
        Self {
            period: Period::zeros(),
            period_t: PeriodIn::zeros(),
            att: [Vector3::zeros(); 3],
            prop: PeriodPropagation::zeros(),
            q_extra: Matrix3::zeros(),
        }
    }
}

/// The filter's storage of the pending period. It stays in place from
/// period to period ([`Filter::predict`] propagates straight into it: no
/// copy of the ≈ 1.8 KB period on the hot path); `valid` says whether it
/// holds one. Two slots compare equal when neither holds a period or both
/// hold equal ones.
#[derive(Clone, Copy, Debug)]
pub(super) struct PendingSlot<T: RealField + Copy, const N: usize> {
    pub(super) value: Pending<T, N>,
    pub(super) valid: bool,
}

impl<T: RealField + Copy, const N: usize> PartialEq for PendingSlot<T, N> {
    fn eq(&self, other: &Self) -> bool {
        self.get() == other.get()
    }
}

impl<T: RealField + Copy, const N: usize> PendingSlot<T, N> {
    pub(super) fn empty() -> Self {
        Self {
            value: Pending::zeros(),
            valid: false,
        }
    }

    /// The pending period, if any.
    pub(super) fn get(&self) -> Option<&Pending<T, N>> {
        self.valid.then_some(&self.value)
    }

    /// No period pending (the storage is kept).
    pub(super) fn clear(&mut self) {
        self.valid = false;
    }
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// The factor with any pending time update applied (the unpropagated
    /// one in the impossible case that it fails: predict checks it).
    pub(super) fn settled(&self) -> Ud<T, N> {
        self.propagated_factor().unwrap_or(self.ud)
    }

    /// The process noise of a pending period on the attitude (rad²): the
    /// gyro noise's map `B Bᵀ` as it is, factored only with second-order
    /// dynamics' `Q_extra` added. `None` if it is not finite (or, with
    /// `Q_extra`, not positive semi-definite).
    pub(super) fn process_noise(&self, pending: &Pending<T, N>) -> Option<AttitudeNoise<T>> {
        let b = pending.prop.noise_map
            * (self.config.sigma_gyro * nalgebra::convert::<f64, T>(pending.period.dt));
        if pending.q_extra.iter().all(|v| *v == T::zero()) {
            AttitudeNoise::from_map(&b)
        } else {
            AttitudeNoise::from_covariance(&(b * b.transpose() + pending.q_extra))
        }
    }

    /// Applies the pending period's time update without a measurement, in
    /// place (the pending period stays recorded; callers clear it), and
    /// the end of the period for the errors that wander (the factor and the
    /// estimate's Gauss–Markov states, [`Filter::wander_jump`]). On error
    /// the factor and the estimate are untouched.
    pub(super) fn settle(&mut self) -> Result<(), Error> {
        if let Some(pending) = self.pending.get() {
            let q = self
                .process_noise(pending)
                .ok_or(Error::CovarianceNotPositiveDefinite)?;
            let dt = pending.period.dt;
            self.ud
                .predict_attitude(&pending.prop.phi_att, &q)
                .ok_or(Error::CovarianceNotPositiveDefinite)?;
            self.wander_jump(dt);
        }
        Ok(())
    }

    /// The factor at the current time: the pending time update applied
    /// without a measurement (the covariance of the predicted state, whose
    /// wandering parts still hold the period's values: their move at the
    /// period's end, [`Filter::wander_jump`], is not in it).
    pub(super) fn propagated_factor(&self) -> Result<Ud<T, N>, Error> {
        let mut ud = self.ud;
        if let Some(pending) = self.pending.get() {
            let q = self
                .process_noise(pending)
                .ok_or(Error::CovarianceNotPositiveDefinite)?;
            ud.predict_attitude(&pending.prop.phi_att, &q)
                .ok_or(Error::CovarianceNotPositiveDefinite)?;
        }
        Ok(ud)
    }
}
