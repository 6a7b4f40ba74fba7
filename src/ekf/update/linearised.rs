//! The linearised filter's update about its nominal trajectory (the later
//! passes of the estimator of record, and the posterior Cramér–Rao bound;
//! docs/model.md §Estimator).

use nalgebra::RealField;
use nalgebra::SVector;

use crate::ekf::factored::Base;
use crate::ekf::measure::Measured;
use crate::ekf::{linear_term, Error, Filter, Innovation};
use crate::geometry::wrap_angle;
use crate::models::Model;

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// The update of the linearised filter about its nominal `x_nom` with
    /// measurement `z`, or with the nominal's own noise-free measurement
    /// `h(x_nom)` for `None` (then `ν = −H (x̂ − x_nom)`; the covariance
    /// update does not depend on `z`; the update is not gated and `S` is
    /// not computed, see [`Filter::factored`]).
    #[inline(never)]
    pub(in crate::ekf) fn update_linearised(
        &mut self,
        z: Option<&SVector<f64, Z>>,
    ) -> Result<Innovation<T, Z>, Error> {
        let (Some(pending), Some(x_nom)) = (self.pending.get(), self.reference.as_ref()) else {
            return Err(Error::NoPrediction);
        };
        let layout = Self::LAYOUT;
        // The nominal's matrices (the cache holds them since `predict`).
        self.matrices.refresh(&layout, x_nom);
        // Used in place (moving its parts out would copy them in this frame).
        let mut measured = Measured::zeros();
        self.measure_into(x_nom, pending, &self.matrices, &mut measured);
        let delta = layout.difference(&self.x, x_nom);
        let h_delta = linear_term::<T, N, Z>(&measured.h, &delta);
        let mut nu = match z {
            Some(z) => z - measured.z - h_delta,
            None => -h_delta,
        };
        if layout.gimbal_obs {
            for v in nu.iter_mut().take(Self::ACCEL_ROW) {
                *v = wrap_angle(*v);
            }
        }
        let r = self.measurement_noise();
        self.factored(
            &mut measured.h,
            &nu,
            &r,
            &measured.noise,
            z.is_some(),
            Base::Nominal { delta: &delta },
        )
    }
}
