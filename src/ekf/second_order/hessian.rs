//! The Hessians `∇²h_a` of the accelerometer output on the at most 12
//! states it depends on, block by block from the platform's derivatives
//! (the formulas of the [module documentation](super)), and the traces the
//! filter needs, `½ tr(∇²h_a P)` and `½ tr(∇²h_a P ∇²h_b P)`
//! ([`Layout::second_order_terms`]).

use nalgebra::{Matrix3, RealField, SMatrix, Vector3};

use super::platform::{Block, Platform};
use super::AccelSecondOrder;
use crate::geometry::skew;
use crate::models::{InstallationMatrices, Layout};

/// The blocks of states `h` depends on: attitude, `θaC`, `θaT`, `λ`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Part {
    Att,
    Ac,
    At,
    Lam,
}

/// Column `k` of `m` (the last one for `k > 2`).
fn col<T: RealField + Copy>(m: &Matrix3<T>, k: usize) -> Vector3<T> {
    let [c0, c1, c2] = m.data.0;
    match k {
        0 => c0.into(),
        1 => c1.into(),
        _ => c2.into(),
    }
}

/// `a ← (a + aᵀ) / 2` in place (`half` = ½): the diagonal blocks of a
/// Hessian are symmetric only up to rounding.
fn symmetrise<T: RealField + Copy, const R: usize>(a: &mut SMatrix<T, R, R>, half: T) {
    for c in 0..R {
        for r in (c + 1)..R {
            if let (Some(&x), Some(&y)) = (a.get((r, c)), a.get((c, r))) {
                let v = (x + y) * half;
                if let Some(e) = a.get_mut((r, c)) {
                    *e = v;
                }
                if let Some(e) = a.get_mut((c, r)) {
                    *e = v;
                }
            }
        }
    }
}

/// `a ← a b` for square `R×R` matrices with `b` symmetric, in place, one
/// row of `a` at a time (each row of the product needs only the same row of
/// `a`): one row of temporaries instead of an `R×R` product. The row is
/// accumulated from the columns of `b`, which equal its rows (contiguous
/// and vectorisable, where `b`'s rows are strided); every element is still
/// `Σ_k a_ik b_kj` summed over ascending `k` from zero, as nalgebra's
/// product would.
fn mul_rows_by_symmetric_in_place<T: RealField + Copy, const R: usize>(
    a: &mut SMatrix<T, R, R>,
    b: &SMatrix<T, R, R>,
) {
    for r in 0..R {
        let mut row = [T::zero(); R];
        for (k, b_k) in b.data.0.iter().enumerate() {
            let Some(&a_rk) = a.get((r, k)) else {
                continue;
            };
            // b_k is column k of b, equal to its row k: b_kj for every j.
            for (o, b_kj) in row.iter_mut().zip(b_k.iter()) {
                *o += a_rk * *b_kj;
            }
        }
        for (c, v) in row.iter().enumerate() {
            if let Some(e) = a.get_mut((r, c)) {
                *e = *v;
            }
        }
    }
}

/// `E_k = ∂L(t)/∂t_k` times `m`.
fn e_times<T: RealField + Copy>(k: usize, m: &Matrix3<T>) -> Matrix3<T> {
    let mut e = Matrix3::zeros();
    let (r, c) = match k {
        0 => (1, 0),
        1 => (2, 0),
        _ => (2, 1),
    };
    if let Some(v) = e.get_mut((r, c)) {
        *v = T::one();
    }
    e * m
}

/// The pieces every block is made of.
struct Pieces<'a, T: RealField + Copy> {
    /// `I + L(θaT)`.
    unit_t: &'a Matrix3<T>,
    /// `R(−θaC)`.
    r_c: &'a Matrix3<T>,
    /// `J_r(−θaC)`.
    j_c: &'a Matrix3<T>,
    platform: &'a Platform<T>,
    /// `∂²(R(−θaC) q)/∂θaC²` ([`d2_dcm_times`] at `−θaC`), when `θaC` is
    /// a state.
    ac_ac: &'a Option<Block<T>>,
}

impl<T: RealField + Copy> Pieces<'_, T> {
    /// `∂(R(−θaC) q)/∂part` (3×3).
    fn f_jacobian(&self, part: Part) -> Matrix3<T> {
        match part {
            Part::Att => self.r_c * self.platform.d_att,
            Part::Lam => self.r_c * self.platform.d_lam,
            // ∂(R(−θ) q)/∂θ = −∂(R(φ) q)/∂φ at φ = −θ.
            Part::Ac => -(skew(&(self.r_c * self.platform.q)) * *self.j_c),
            Part::At => Matrix3::zeros(),
        }
    }

    /// `∂q/∂part` for the attitude and `λ`.
    fn q_jacobian(&self, part: Part) -> Matrix3<T> {
        match part {
            Part::Att => self.platform.d_att,
            Part::Lam => self.platform.d_lam,
            _ => Matrix3::zeros(),
        }
    }

    /// Writes the block `∂²h/∂(part i)_k ∂(part j)_l` ([`Block`]) into the
    /// three Hessians at local rows `li..li + 3`, columns `lj..lj + 3`, and
    /// mirrored. A pair the formulas take in the other order is the
    /// [`Pieces::canonical`] block `(j, i)` written at `(lj, li)` (and
    /// mirrored): `∂²h/∂x_i∂x_j = ∂²h/∂x_j∂x_i`. Out of line: the block's
    /// temporaries are not in the frame that holds the Hessians (firmware
    /// stack).
    #[inline(never)]
    fn write_block<const R: usize>(
        &self,
        i: Part,
        j: Part,
        li: usize,
        lj: usize,
        hess: &mut [SMatrix<T, R, R>; 3],
    ) {
        let mirrored = matches!(
            (i, j),
            (Part::Att | Part::Lam, Part::Ac)
                | (Part::Att | Part::Ac | Part::Lam, Part::At)
                | (Part::Lam, Part::Att)
        );
        let (i, j, li, lj) = if mirrored {
            (j, i, lj, li)
        } else {
            (i, j, li, lj)
        };
        for k in 0..3 {
            let mk = self.canonical(i, j, k);
            for (l, v) in mk.data.0.iter().enumerate() {
                for (ha, va) in hess.iter_mut().zip(v.iter()) {
                    if let Some(e) = ha.get_mut((li + k, lj + l)) {
                        *e = *va;
                    }
                    if let Some(e) = ha.get_mut((lj + l, li + k)) {
                        *e = *va;
                    }
                }
            }
        }
    }

    /// Element `k` of the block `∂²h/∂(part i)_k ∂(part j)_l` ([`Block`])
    /// for the pairs in the order the formulas take them (see
    /// [`Pieces::write_block`]). One matrix at a time, not the block: this
    /// is the deepest frame of a pass-1 filter step (firmware stack).
    fn canonical(&self, i: Part, j: Part, k: usize) -> Matrix3<T> {
        let pl = &self.platform;
        let of = |b: &Block<T>| match b {
            [b0, _, _] if k == 0 => *b0,
            [_, b1, _] if k == 1 => *b1,
            [_, _, b2] => *b2,
        };
        match (i, j) {
            (Part::Att, Part::Att) => self.unit_t * self.r_c * of(&pl.att_att),
            (Part::Att, Part::Lam) => self.unit_t * self.r_c * of(&pl.att_lam),
            (Part::Lam, Part::Lam) => self.unit_t * self.r_c * of(&pl.lam_lam),
            (Part::Ac, Part::Ac) => match self.ac_ac {
                Some(b) => self.unit_t * of(b),
                // (Not reached: `ac_ac` is there when θaC is a state.)
                None => Matrix3::zeros(),
            },
            (Part::Ac, y @ (Part::Att | Part::Lam)) => {
                let ry = self.r_c * self.q_jacobian(y);
                self.unit_t * skew(&col(self.j_c, k)) * ry
            }
            (Part::At, Part::At) => Matrix3::zeros(),
            (Part::At, other) => e_times(k, &self.f_jacobian(other)),
            // Mirrored pairs (see `write_block`).
            _ => Matrix3::zeros(),
        }
    }
}

impl Layout {
    /// [`Layout::accel_second_order`] with the Hessians on the `R` states of
    /// `at` ([`Layout::accel_blocks`]), from the platform's `q` and its
    /// derivatives, and the covariance `p_r` of those states. Out of line:
    /// the three sizes' frames would otherwise add up in
    /// [`Layout::accel_second_order_from`]'s.
    #[inline(never)]
    pub(super) fn second_order_terms<T: RealField + Copy, const R: usize>(
        &self,
        m: &InstallationMatrices<T>,
        platform: &Platform<T>,
        ac_ac: &Option<Block<T>>,
        p_r: &SMatrix<T, R, R>,
        at: &[(Part, usize, usize)],
    ) -> AccelSecondOrder<T> {
        let half: T = nalgebra::convert(0.5);
        let pieces = Pieces {
            unit_t: &m.unit_a_t,
            r_c: &m.r_a_c,
            j_c: &m.jr_a_c,
            platform,
            ac_ac,
        };
        let mut hess = [SMatrix::<T, R, R>::zeros(); 3];
        for (n, &(pi, li, _)) in at.iter().enumerate() {
            for &(pj, lj, _) in at.iter().skip(n) {
                pieces.write_block(pi, pj, li, lj, &mut hess);
            }
        }
        // ∇²h_a P in place of each Hessian, row by row (one row of R
        // temporaries: this frame is on the deepest path of a filter step).
        let mut mean = Vector3::zeros();
        for (ha, mu) in hess.iter_mut().zip(mean.iter_mut()) {
            symmetrise(ha, half);
            mul_rows_by_symmetric_in_place(ha, p_r);
            *mu = ha.trace() * half;
        }
        let hp = &hess;
        let mut cov = Matrix3::zeros();
        for (a, ha) in hp.iter().enumerate() {
            for (b, hb) in hp.iter().enumerate().skip(a) {
                // tr(A B) = Σ_ij A_ij B_ji, column by column of A.
                let mut t = T::zero();
                for (c, ca) in ha.data.0.iter().enumerate() {
                    for (r, x) in ca.iter().enumerate() {
                        if let Some(y) = hb.data.0.get(r).and_then(|col| col.get(c)) {
                            t += *x * *y;
                        }
                    }
                }
                t *= half;
                if let Some(v) = cov.get_mut((a, b)) {
                    *v = t;
                }
                if let Some(v) = cov.get_mut((b, a)) {
                    *v = t;
                }
            }
        }
        AccelSecondOrder { mean, cov }
    }
}
