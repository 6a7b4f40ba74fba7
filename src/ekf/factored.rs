//! The factored update of one period, measurement and time update together
//! ([`Filter::factored`]; docs/model.md §Measurement timing): the whitened
//! rows of [`Filter::whiten`] applied by Bierman's scalar updates, then the
//! decorrelated structured time update, then the new state.

use nalgebra::{RealField, SMatrix, SVector};

use super::measure::Noise;
use super::whiten::{Gate, Whitened};
use super::{all_finite, Error, Filter, Innovation};
use crate::geometry::wrap_angle;
use crate::models::{Model, ATT};
use crate::precision::to_f64;

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// The factored update of one period, measurement and time update
    /// together (docs/model.md §Measurement timing, the gyro noise; Anderson &
    /// Moore, *Optimal Filtering*, §5.5).
    ///
    /// The measurement `z = H x_{k+1} + D u + v` shares the period's gyro
    /// noise `u` with the dynamics `x_{k+1} = Φ x_k + G u`. Written as a
    /// measurement of `x_k`, `z = H Φ x_k + e` with `e = M u + v`,
    /// `M = H G + D`, `R_e = M Mᵀ + R_v`, it is decorrelated from the
    /// dynamics by subtracting `J (z − H Φ x_k − e)`, `J = G Mᵀ R_e⁻¹`:
    /// `x_{k+1} = (Φ − J H Φ) x_k + J z + (G u − J e)`, whose noise is
    /// uncorrelated with `e`, with covariance `G Gᵀ − J R_e Jᵀ`. Whitening
    /// by `L = chol(R_e)` makes the `Z` components independent: Bierman's
    /// scalar updates of the factor at `t_k` take them one at a time, then
    /// the structured time update (`G` and `J` touch only the attitude rows)
    /// brings the factor to `t_{k+1}`. The result equals the dense filter's
    /// `K = (P⁻ Hᵀ + G Dᵀ) S⁻¹` update in exact arithmetic.
    ///
    /// Everything the update reads (the whitened rows, the decorrelation
    /// gain, `S`) is computed and checked before the factor is touched; the
    /// NIS gate is decided from `S` then, so a refused update costs only the
    /// time update. The factor is then updated in place (no copy of it;
    /// see [`Filter::update`] for what a failure part-way leaves). The
    /// reported NIS is that of the scalar updates (equal to `νᵀ S⁻¹ ν` in
    /// exact arithmetic). On success the state becomes `x_base` (`None`:
    /// the estimate itself) plus the correction and the pending period is
    /// cleared.
    ///
    /// `measured`: a real measurement: compute the innovation covariance
    /// `S` for the [`Innovation`] and apply the NIS gate; without it (the
    /// noise-free step of the bound) the result's `s` is `R_e` only (the
    /// update itself never uses `S`) and nothing is gated.
    // Out of line: the whitened update it holds is in no frame above the
    // measurement model's, and the updates' frames are not above the factor's
    // (firmware stack).
    #[inline(never)]
    pub(super) fn factored(
        &mut self,
        h: &mut SMatrix<T, Z, N>,
        nu_f64: &SVector<f64, Z>,
        r_v: &SMatrix<T, Z, Z>,
        noise: &Noise<T, N, Z>,
        measured: bool,
        x_base: Option<&SVector<f64, N>>,
    ) -> Result<Innovation<T, Z>, Error> {
        let mut w = Whitened::zeros();
        if let Gate::Refuse = self.whiten(h, nu_f64, r_v, noise, measured, &mut w)? {
            // Predicted only: the time update without the measurement.
            self.settle()?;
            self.gated_run += 1;
            self.pending.clear();
            return Err(Error::Gated);
        }
        self.apply_whitened(h, &w, measured, x_base)
    }

    /// The second half of [`Filter::factored`]: Bierman's scalar updates of
    /// the whitened rows `h_w`, the decorrelated time update, the new state.
    #[inline(never)]
    fn apply_whitened(
        &mut self,
        h_w: &SMatrix<T, Z, N>,
        w: &Whitened<T, N, Z>,
        measured: bool,
        x_base: Option<&SVector<f64, N>>,
    ) -> Result<Innovation<T, Z>, Error> {
        let phi_att = &self.pending.get().ok_or(Error::NoPrediction)?.prop.phi_att;
        let mut dx = SVector::<T, N>::zeros();
        let mut nis = T::zero();
        for (row, nu_i) in h_w.row_iter().zip(w.nu_w.iter()) {
            let row = row.transpose();
            let resid = *nu_i - row.dot(&dx);
            let Some(up) = self.ud.update(&row, T::one()) else {
                return Err(Error::CovarianceNotPositiveDefinite);
            };
            nis += resid * resid / up.alpha;
            dx += up.gain * resid;
        }
        self.ud
            .predict_attitude(&w.phi_dec, &w.q)
            .ok_or(Error::CovarianceNotPositiveDefinite)?;
        // x̂_{k+1} − x̂⁻_{k+1} = Φ δ + J (z − H Φ δ) for the correction δ at t_k.
        let d_att = phi_att * dx + w.j_l * (w.nu_w - h_w * dx);
        dx.fixed_rows_mut::<3>(ATT).copy_from(&d_att);
        let x_new = x_base.unwrap_or(&self.x) + to_f64(&dx);
        if !all_finite(x_new.iter().copied()) || !nis.is_finite() {
            return Err(Error::NonFiniteState);
        }
        let gate = self.config.options.nis_gate;
        let above = measured && gate > 0.0 && nis > nalgebra::convert(gate);
        // Keep the Euler attitude angles in (−π, π]; P is unchanged by 2π shifts.
        let mut x = x_new;
        if Self::LAYOUT.attitude != crate::models::AttitudeKind::Misalignment {
            for v in x.iter_mut().take(3) {
                *v = wrap_angle(*v);
            }
        }
        self.x = x;
        self.pending.clear();
        self.updates = self.updates.saturating_add(1);
        self.gated_run = 0;
        self.gate_open = above;
        Ok(Innovation {
            nu: w.innovation.nu,
            s: w.innovation.s,
            nis,
        })
    }
}
