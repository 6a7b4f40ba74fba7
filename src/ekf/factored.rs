//! The factored update of one period, measurement and time update together
//! ([`Filter::factored`]; docs/model.md §Measurement timing): the whitened
//! rows of [`Filter::whiten`] applied by Bierman's scalar updates, then the
//! decorrelated structured time update, then the new state.

use nalgebra::{RealField, SMatrix, SVector, Vector3};

use super::measure::Noise;
use super::whiten::Gate;
use super::{all_finite, Error, Filter, Innovation};
use crate::geometry::wrap_angle;
use crate::models::{Model, ATT};
use crate::precision::scalar_to_f64;

/// `Φ_att δ` (3 of `N` columns), column by column as nalgebra's product
/// sums it (the same operations in the same order: the same bits), in
/// scalars: the product's per-column temporaries took 0.9 KB of stack for
/// 39 states (Cortex-M7).
fn rows_times<T: RealField + Copy, const N: usize>(
    phi: &SMatrix<T, 3, N>,
    x: &SVector<T, N>,
) -> Vector3<T> {
    let mut y = [T::zero(); 3];
    for (j, (col, x_j)) in phi.data.0.iter().zip(x.iter()).enumerate() {
        for (y_r, phi_rj) in y.iter_mut().zip(col) {
            let p = *phi_rj * *x_j;
            *y_r = if j == 0 { p } else { p + *y_r };
        }
    }
    Vector3::from(y)
}

/// What the factored update adds its correction to.
#[derive(Clone, Copy)]
pub(super) enum Base<'a, const N: usize> {
    /// The estimate itself (the extended filter).
    Estimate,
    /// The nominal (the filter's reference) plus the estimate's offset
    /// `δ` from it, `x_nom + δ` (the linearised filter).
    Nominal { delta: &'a SVector<f64, N> },
}

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
    /// exact arithmetic). On success the state becomes `base` plus the
    /// correction and the pending period is
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
        base: Base<'_, N>,
    ) -> Result<Innovation<T, Z>, Error> {
        // The whitened update goes into the filter's working memory
        // (`Scratch`), not this frame.
        if let Gate::Refuse = self.whiten(h, nu_f64, r_v, noise, measured)? {
            // Predicted only: the time update without the measurement.
            self.settle()?;
            self.gated_run += 1;
            self.pending.clear();
            return Err(Error::Gated);
        }
        self.apply_whitened(h, measured, base)
    }

    /// The second half of [`Filter::factored`]: Bierman's scalar updates of
    /// the whitened rows `h_w`, the decorrelated time update, the new state,
    /// from the whitened update [`Filter::whiten`] left in the filter's
    /// working memory. On error the factor is returned to what it was
    /// before (saved in the working memory), so a refused period leaves
    /// the covariance untouched.
    #[inline(never)]
    fn apply_whitened(
        &mut self,
        h_w: &SMatrix<T, Z, N>,
        measured: bool,
        base: Base<'_, N>,
    ) -> Result<Innovation<T, Z>, Error> {
        self.ud.save_into(&mut self.scratch.factor);
        let applied = self.apply_whitened_in_place(h_w, measured, base);
        if applied.is_err() {
            self.ud.restore_from(&self.scratch.factor);
        }
        applied
    }

    /// [`Filter::apply_whitened`] without the rollback: on error the
    /// factor may keep some of the scalar updates.
    #[inline(always)]
    fn apply_whitened_in_place(
        &mut self,
        h_w: &SMatrix<T, Z, N>,
        measured: bool,
        base: Base<'_, N>,
    ) -> Result<Innovation<T, Z>, Error> {
        let mut dx = SVector::<T, N>::zeros();
        let nu_w = self.scratch.whitened.nu_w;
        let nis = self.scalar_updates(h_w, &nu_w, &mut dx)?;
        let w = &self.scratch.whitened;
        self.ud
            .predict_attitude(&w.phi_dec, &w.q)
            .ok_or(Error::CovarianceNotPositiveDefinite)?;
        let phi_att = &self.pending.get().ok_or(Error::NoPrediction)?.prop.phi_att;
        // x̂_{k+1} − x̂⁻_{k+1} = Φ δ + J (z − H Φ δ) for the correction δ at t_k.
        let d_att = rows_times(phi_att, &dx) + w.j_l * (w.nu_w - h_w * dx);
        dx.fixed_rows_mut::<3>(ATT).copy_from(&d_att);
        // The correction in the state vector's order (the factor's so far).
        Self::vector_to_state_order(&mut dx);
        // The base (the estimate, or the nominal plus its offset) plus the
        // correction, element by element, formed in the working memory (not
        // in this frame, which is on a step's deepest path).
        let x = &mut self.scratch.x_new;
        match (base, &self.reference) {
            (Base::Nominal { delta }, Some(nominal)) => {
                for ((x_i, n_i), d_i) in x.iter_mut().zip(nominal.iter()).zip(delta.iter()) {
                    *x_i = *n_i + *d_i;
                }
            }
            (Base::Nominal { .. }, None) => return Err(Error::NoPrediction),
            (Base::Estimate, _) => x.copy_from(&self.x),
        }
        for (x_i, dx_i) in x.iter_mut().zip(dx.iter()) {
            *x_i += scalar_to_f64(*dx_i);
        }
        if !all_finite(x.iter().copied()) || !nis.is_finite() {
            return Err(Error::NonFiniteState);
        }
        let gate = self.config.options.nis_gate;
        let above = measured && gate > 0.0 && nis > nalgebra::convert(gate);
        // Keep the Euler attitude angles in (−π, π]; P is unchanged by 2π shifts.
        if Self::LAYOUT.attitude != crate::models::AttitudeKind::Misalignment {
            for v in x.iter_mut().take(3) {
                *v = wrap_angle(*v);
            }
        }
        // The end of the period for the errors that wander (cannot fail).
        let dt = self.pending.get().map_or(0.0, |p| p.period.dt);
        self.x = *x;
        self.wander_jump(dt);
        self.pending.clear();
        self.updates = self.updates.saturating_add(1);
        self.gated_run = 0;
        self.gate_open = above;
        let innovation = &self.scratch.whitened.innovation;
        Ok(Innovation {
            nu: innovation.nu,
            s: innovation.s,
            nis,
        })
    }

    /// Bierman's scalar updates of the whitened rows `h_w` with their
    /// whitened innovations `nu_w`, in order: the factor updated in place,
    /// the correction accumulated in `dx`, the NIS returned. Out of line:
    /// the updates' vectors are not on the stack under the time update that
    /// follows (nor its rows under these).
    #[inline(never)]
    fn scalar_updates(
        &mut self,
        h_w: &SMatrix<T, Z, N>,
        nu_w: &SVector<T, Z>,
        dx: &mut SVector<T, N>,
    ) -> Result<T, Error> {
        let mut nis = T::zero();
        let mut gain = [T::zero(); N];
        for (row, nu_i) in h_w.row_iter().zip(nu_w.iter()) {
            let row = row.transpose();
            let resid = *nu_i - row.dot(&*dx);
            let Some(alpha) = self
                .ud
                .update_into(&row, T::one(), &mut gain, Self::HELD_FROM)
            else {
                return Err(Error::CovarianceNotPositiveDefinite);
            };
            nis += resid * resid / alpha;
            for (d, g) in dx.iter_mut().zip(gain.iter()) {
                *d += *g * resid;
            }
        }
        Ok(nis)
    }
}
