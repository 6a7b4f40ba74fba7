//! The first half of the factored update: the measurement decorrelated from
//! the period's gyro noise and whitened (Anderson & Moore, *Optimal
//! Filtering*, §5.5; docs/model.md §Measurement timing), the decorrelated
//! time update factored, `S` formed and the NIS gate decided
//! ([`Filter::whiten`]), all before the factor is touched.

use nalgebra::{Matrix3, RealField, SMatrix, SVector};

use super::factor::AttitudeNoise;
use super::measure::Noise;
use super::options::MAX_GATED_RUN;
use super::{all_finite, Error, Filter, Innovation};
use crate::models::Model;
use crate::precision::to_t;

/// The factored update's inputs ([`Filter::whiten`]), all formed and
/// checked before the factor is touched ([`Filter::apply_whitened`]).
/// The whitened rows `L⁻¹ H Φ` (`L = chol(R_e)`) take the place of the
/// measurement's `H`.
#[derive(Clone, Copy)]
pub(super) struct Whitened<T: RealField + Copy, const N: usize, const Z: usize> {
    /// The whitened innovation `L⁻¹ ν`.
    pub(super) nu_w: SVector<T, Z>,
    /// The decorrelation gain times `L`, `J L` (attitude rows).
    pub(super) j_l: SMatrix<T, 3, Z>,
    /// The decorrelated transition `Φ − J H Φ` (attitude rows).
    pub(super) phi_dec: SMatrix<T, 3, N>,
    /// The decorrelated process noise `G Gᵀ − J R_e Jᵀ` (rad²), factored.
    pub(super) q: AttitudeNoise<T>,
    /// `ν` and `S` as reported (`nis` is the update's).
    pub(super) innovation: Innovation<T, Z>,
}

impl<T: RealField + Copy, const N: usize, const Z: usize> Whitened<T, N, Z> {
    pub(super) fn zeros() -> Self {
        Self {
            nu_w: SVector::zeros(),
            j_l: SMatrix::zeros(),
            phi_dec: SMatrix::zeros(),
            q: AttitudeNoise::zero(),
            innovation: Innovation {
                nu: SVector::zeros(),
                s: SMatrix::zeros(),
                nis: T::zero(),
            },
        }
    }
}

/// The NIS gate's verdict on an update ([`Filter::whiten`]).
pub(super) enum Gate {
    /// The update goes ahead.
    Pass,
    /// Refused: the period gets its time update only.
    Refuse,
}

/// `L⁻¹ B` in place of `B` for the lower triangle of `l` (its upper
/// triangle is not read: a Cholesky factor's `l_dirty`). The operations of
/// nalgebra's `solve_lower_triangular_mut`, in the same order (each column:
/// `b_i ← b_i / L_ii`, then `b_k ← b_k − b_i L_ki` below it), so the same
/// bits, without its per-column views: at fixed sizes it unrolls (the M4F's
/// whitening of the `Z × N` rows). `false` (and `b` untouched) if a diagonal
/// element is zero.
fn solve_lower<T: RealField + Copy, const Z: usize, const C: usize>(
    l: &SMatrix<T, Z, Z>,
    b: &mut SMatrix<T, Z, C>,
) -> bool {
    let l = &l.data.0; // l[col][row]
    let diagonal = |(i, l_i): (usize, &[T; Z])| l_i.get(i).copied();
    if !l
        .iter()
        .enumerate()
        .all(|c| diagonal(c).is_some_and(|d| !d.is_zero()))
    {
        return false;
    }
    for col in b.data.0.iter_mut() {
        for (i, l_i) in l.iter().enumerate() {
            let (Some(d), Some((b_i, below))) = (
                diagonal((i, l_i)),
                col.get_mut(i..).and_then(|rest| rest.split_first_mut()),
            ) else {
                continue;
            };
            let coeff = *b_i / d;
            *b_i = coeff;
            for (b_k, l_ki) in below.iter_mut().zip(l_i.iter().skip(i + 1)) {
                *b_k -= coeff * *l_ki;
            }
        }
    }
    true
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// The first half of [`Filter::factored`]: the whitened rows `L⁻¹ H Φ`
    /// in place of `h`; the whitened innovation, the decorrelated time
    /// update and `S` into `w`; and the NIS gate's verdict, without touching
    /// the factor. Out of line: its temporaries
    /// (the Choleskys, `R_e`, `M`) are not below the factor's updates.
    #[inline(never)]
    pub(super) fn whiten(
        &mut self,
        h: &mut SMatrix<T, Z, N>,
        nu_f64: &SVector<f64, Z>,
        r_v: &SMatrix<T, Z, Z>,
        noise: &Noise<T, N, Z>,
        measured: bool,
    ) -> Result<Gate, Error> {
        let w = &mut self.scratch.whitened;
        let half: T = nalgebra::convert(0.5);
        let phi_att = &self.pending.get().ok_or(Error::NoPrediction)?.prop.phi_att;
        let nu: SVector<T, Z> = to_t(nu_f64);
        let g_att: Matrix3<T> = noise.g_att;
        let h_att: SMatrix<T, Z, 3> = crate::models::attitude_columns(h);
        // H Φ in T (f64 is emulated on an FPU without it), in place, in the
        // factor's order (as `phi_att`). It becomes the whitened rows in
        // place below.
        Self::columns_to_factor_order(h);
        crate::models::apply_transition(h, phi_att);
        let m_e = h_att * g_att + noise.d;
        let mut r_e = m_e * m_e.transpose() + r_v;
        r_e = (r_e + r_e.transpose()) * half;
        // S = H Φ P Φᵀ Hᵀ + R_e, for the innovation report and the gate.
        let s = if measured {
            r_e + self.ud.congruence_into(h, &mut self.scratch.projections)
        } else {
            r_e
        };
        let Some(chol) = r_e.cholesky() else {
            return Err(Error::InnovationNotPositiveDefinite);
        };
        // The factor's lower triangle (the solves read nothing else).
        let l = chol.l_dirty();
        // The triangular solves in place (no Option/Result moves of the
        // Z×N results).
        w.nu_w = nu;
        // J L = G Mᵀ L⁻ᵀ (attitude rows), so J z = (J L) ν_w.
        let mut l_inv_m_g = m_e * g_att.transpose();
        if !(solve_lower(l, &mut w.nu_w) && solve_lower(l, h) && solve_lower(l, &mut l_inv_m_g)) {
            return Err(Error::InnovationNotPositiveDefinite);
        }
        w.j_l = l_inv_m_g.transpose();
        // Time update with Φ' = Φ − J H Φ and Q' = G Gᵀ − J R_e Jᵀ.
        // Column by column, in place (no 3×N temporaries): the same
        // products and differences as `phi_att − J_L H`.
        w.phi_dec.copy_from(phi_att);
        for (mut col, h_col) in w.phi_dec.column_iter_mut().zip(h.column_iter()) {
            col -= w.j_l * h_col;
        }
        let q = g_att * g_att.transpose() - w.j_l * w.j_l.transpose();
        // Factored here, before the factor is touched: a `Q'` that is not
        // positive semi-definite (garbage noise settings) is refused now,
        // not after the scalar updates have been applied.
        w.q = AttitudeNoise::from_covariance(&((q + q.transpose()) * half))
            .ok_or(Error::CovarianceNotPositiveDefinite)?;
        let gate = self.config.options.nis_gate;
        if measured && gate > 0.0 && !self.gate_open && self.gated_run < MAX_GATED_RUN {
            let Some(chol_s) = s.cholesky() else {
                return Err(Error::InnovationNotPositiveDefinite);
            };
            let mut y = nu;
            if !chol_s.l_dirty().solve_lower_triangular_mut(&mut y) {
                return Err(Error::InnovationNotPositiveDefinite);
            }
            let nis_prior = y.norm_squared();
            if !nis_prior.is_finite() {
                return Err(Error::NonFiniteState);
            }
            if nis_prior > nalgebra::convert(gate) {
                return Ok(Gate::Refuse);
            }
        }
        // The factor is updated in place: check everything it reads first
        // (slice by slice: a chain of iterators costs more than the checks).
        let read = [
            h.as_slice(),
            w.nu_w.as_slice(),
            w.j_l.as_slice(),
            phi_att.as_slice(),
            w.phi_dec.as_slice(),
        ];
        if !read.iter().all(|part| all_finite(part.iter().copied())) {
            return Err(Error::NonFiniteState);
        }
        w.innovation = Innovation {
            nu,
            s,
            nis: T::zero(),
        };
        Ok(Gate::Pass)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `solve_lower` gives nalgebra's `solve_lower_triangular_mut` bit for
    /// bit (the same operations in the same order), reading only the lower
    /// triangle, and refuses a zero on the diagonal with `b` untouched.
    #[test]
    fn solve_lower_is_nalgebras_solve() {
        let a = SMatrix::<f64, 6, 6>::from_fn(|i, j| ((7 * i + 3 * j) % 11) as f64 / 3.0 - 1.4);
        let s = a * a.transpose() + SMatrix::identity() * 0.3;
        let chol = s.cholesky().expect("positive definite");
        let mut l = chol.l();
        let want_l = l;
        // Garbage above the diagonal, as in a Cholesky's `l_dirty`.
        for i in 0..6 {
            for j in i + 1..6 {
                l[(i, j)] = f64::NAN;
            }
        }
        let b = SMatrix::<f64, 6, 18>::from_fn(|i, j| ((5 * i + j) % 13) as f64 * 0.37 - 2.0);
        let mut want = b;
        assert!(want_l.solve_lower_triangular_mut(&mut want));
        let mut got = b;
        assert!(solve_lower(&l, &mut got));
        assert_eq!(got, want);
        let mut f32_got = b.map(|v| v as f32);
        let mut f32_want = f32_got;
        assert!(want_l
            .map(|v| v as f32)
            .solve_lower_triangular_mut(&mut f32_want));
        assert!(solve_lower(&l.map(|v| v as f32), &mut f32_got));
        assert_eq!(f32_got, f32_want);
        l[(3, 3)] = 0.0;
        let mut refused = b;
        assert!(!solve_lower(&l, &mut refused));
        assert_eq!(refused, b);
    }
}
