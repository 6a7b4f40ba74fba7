//! The update of one period ([`Filter::update`]): the observation checked
//! and laid out as the measurement vector, then the update variant of the
//! filter's mode: the extended filter's (pass 1, with the cold-start
//! remedies; [`extended`], [`iterated`]) or the linearised filter's about
//! its nominal ([`linearised`]). Every variant ends in the factored update
//! ([`Filter::factored`](super::Filter::factored)).

mod extended;
mod iterated;
mod linearised;

use nalgebra::{RealField, SVector};

use super::{all_finite, Error, Filter, Innovation, Observation};
use crate::models::Model;
use crate::precision::to_f64;

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// Processes the measurement of the period that [`Filter::predict`] just
    /// propagated over.
    ///
    /// On error the state is left untouched. So is the covariance, with one
    /// exception: the factor is updated in place (no copy of it on the hot
    /// path), so when the factored update itself fails part-way
    /// ([`Error::CovarianceNotPositiveDefinite`], or
    /// [`Error::NonFiniteState`] for a non-finite result) the factor keeps
    /// the part already applied. Every input of the update is checked
    /// before the factor is touched, so this takes a covariance that has
    /// already lost its numerical positive definiteness; no test reaches it.
    pub fn update(&mut self, obs: &Observation<T>) -> Result<Innovation<T, Z>, Error> {
        let layout = Self::LAYOUT;
        if self.pending.get().is_none() {
            return Err(Error::NoPrediction);
        }
        let gimbal = match (layout.gimbal_obs, obs.gimbal) {
            (true, None) => return Err(Error::MissingGimbal),
            (true, Some(g)) => Some(g),
            (false, _) => None,
        };
        if !all_finite(
            obs.accel_mean
                .iter()
                .chain(gimbal.iter().flat_map(|g| g.iter()))
                .copied(),
        ) {
            return Err(Error::NonFiniteInput);
        }
        let mut z = SVector::<f64, Z>::zeros();
        if let Some(g) = gimbal {
            z.fixed_rows_mut::<3>(0).copy_from(&to_f64(&g));
        }
        z.fixed_rows_mut::<3>(Self::ACCEL_ROW)
            .copy_from(&to_f64(&obs.accel_mean));
        if self.reference.is_some() {
            self.update_linearised(Some(&z))
        } else {
            self.update_extended(&z)
        }
    }
}
