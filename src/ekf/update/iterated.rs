//! The iterated EKF's update (`Options::iterations`, research builds):
//! dense Gauss–Newton relinearisations of the measurement before the
//! factored update.

use nalgebra::{Matrix3, RealField, SMatrix, SVector, Vector3};

use crate::ekf::cache::MatricesCache;
use crate::ekf::factored::Base;
use crate::ekf::measure::{Measured, Noise};
use crate::ekf::pending::Pending;
use crate::ekf::{Error, Filter, Innovation};
use crate::models::Model;
use crate::precision::to_f64;

/// One Kalman gain with correlated noise, dense (the iterated filter's
/// intermediate relinearisation points only).
struct Gain<T: RealField + Copy, const N: usize, const Z: usize> {
    k: SMatrix<T, N, Z>,
}

/// The dense gain with measurement noise `R_v + D Dᵀ` correlated with the
/// process noise by `C = G Dᵀ`: `S = H P Hᵀ + H C + Cᵀ Hᵀ + R_eff`,
/// `K = (P Hᵀ + C) S⁻¹`, for the predicted covariance `p`.
fn dense_gain<T: RealField + Copy, const N: usize, const Z: usize>(
    p: &SMatrix<T, N, N>,
    h: &SMatrix<T, Z, N>,
    r: &SMatrix<T, Z, Z>,
    noise: &Noise<T, N, Z>,
) -> Result<Gain<T, N, Z>, Error> {
    let c = noise.g() * noise.d.transpose();
    let r_eff = r + noise.d * noise.d.transpose();
    let ph = p * h.transpose() + c;
    let mut s = h * ph + h * c + r_eff;
    s = (s + s.transpose()) * nalgebra::convert::<f64, T>(0.5);
    let chol = s.cholesky().ok_or(Error::InnovationNotPositiveDefinite)?;
    let k = chol.solve(&ph.transpose()).transpose();
    Ok(Gain { k })
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// [`Filter::update_extended`] linearised at the iterated EKF's
    /// relinearisation point ([`Filter::iterated_innovation`]). Out of line:
    /// its measurement model stays out of the frame of every update that
    /// does not iterate (the default).
    #[inline(never)]
    pub(super) fn update_iterated(
        &mut self,
        z: &SVector<f64, Z>,
        cov2: &Matrix3<f64>,
        mean2: &Vector3<f64>,
        iterations: u8,
    ) -> Result<Innovation<T, Z>, Error> {
        let pending = self.pending.get().ok_or(Error::NoPrediction)?;
        let r_v = self.extended_noise(cov2);
        let mut measured = Measured::zeros();
        let nu = self.iterated_innovation(z, pending, &r_v, mean2, iterations, &mut measured)?;
        self.factored(
            &mut measured.h,
            &nu,
            &r_v,
            &measured.noise,
            true,
            Base::Estimate,
        )
    }

    /// [`Filter::innovation_at`] the iterated EKF's relinearisation point:
    /// `iterations` dense Gauss–Newton steps from the prediction (double
    /// precision, the dense gain), then the period's trajectory retraced
    /// to end there. Out of line: its N×N temporaries and the retraced
    /// period (≈ 1.8 KB) stay out of the frame of every update that does
    /// not iterate (the default).
    #[inline(never)]
    fn iterated_innovation(
        &self,
        z: &SVector<f64, Z>,
        pending: &Pending<T, N>,
        r_v: &SMatrix<T, Z, Z>,
        mean2: &Vector3<f64>,
        iterations: u8,
        measured: &mut Measured<T, N, Z>,
    ) -> Result<SVector<f64, Z>, Error> {
        let p_prior = to_f64(&Self::covariance_to_state_order(
            self.settled().covariance(),
        ));
        let r_v = to_f64(r_v);
        let mut x_lin = self.x;
        let mut lin = *pending;
        for it in 0..iterations {
            if it > 0 {
                lin = self.retrace(&x_lin, pending)?;
            }
            let m = MatricesCache::new(Self::LAYOUT.installation(&x_lin));
            let nu = self.innovation_at(z, &x_lin, &lin, mean2, &m, measured);
            let noise = Noise::new(to_f64(&measured.noise.g_att), to_f64(&measured.noise.d));
            let gain = dense_gain(&p_prior, &to_f64(&measured.h), &r_v, &noise)?;
            x_lin = self.x + gain.k * nu;
        }
        let lin = self.retrace(&x_lin, pending)?;
        let m = MatricesCache::new(Self::LAYOUT.installation(&x_lin));
        Ok(self.innovation_at(z, &x_lin, &lin, mean2, &m, measured))
    }
}
