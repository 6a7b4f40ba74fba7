//! The attitude rows of the discrete transition `Φ = exp(F τ)` to second
//! order, and `H ← H Φ` without forming `Φ` (the parameter rows of `Φ` are
//! the identity: the installation parameters are constant).

use nalgebra::{Matrix3, RealField, SMatrix, Vector3};

use super::blocks::attitude_columns;
use super::layout::ATT;

/// Attitude rows of `exp(F τ)` to second order for `F = [[F_a, F_p],[0, 0]]`:
/// `[I + F_a τ + (F_a τ)²/2, (I + F_a τ/2) F_p τ]`.
pub fn transition_rows<T: RealField + Copy, const N: usize>(
    f: &SMatrix<T, 3, N>,
    tau: T,
) -> SMatrix<T, 3, N> {
    let mut phi = SMatrix::zeros();
    transition_rows_into(f, tau, &mut phi);
    phi
}

/// [`transition_rows`] written into `phi` (every entry): no 3×N copy of
/// the result where the caller keeps it.
pub fn transition_rows_into<T: RealField + Copy, const N: usize>(
    f: &SMatrix<T, 3, N>,
    tau: T,
    phi: &mut SMatrix<T, 3, N>,
) {
    let pieces = TransitionPieces::new(f, tau);
    for (j, (col, f_col)) in phi.data.0.iter_mut().zip(f.data.0.iter()).enumerate() {
        *col = pieces.column(j, f_col, tau).into();
    }
}

/// The two matrices of [`transition_rows`] of `F` and `τ`, from which each
/// of its columns follows alone (see [`TransitionPieces::column`]).
struct TransitionPieces<T> {
    /// `F_a τ/2 + (F_a τ)²/6`: a parameter column is `(I + mix) F_j τ`.
    mix: Matrix3<T>,
    /// The attitude block `I + F_a τ + (F_a τ)²/2 + (F_a τ)³/6` (error
    /// ≈ |F τ|⁴/24 < 1e-12).
    aa: Matrix3<T>,
}

impl<T: RealField + Copy> TransitionPieces<T> {
    fn new<const N: usize>(f: &SMatrix<T, 3, N>, tau: T) -> Self {
        let half: T = nalgebra::convert(0.5);
        let sixth: T = nalgebra::convert(1.0 / 6.0);
        let fa = attitude_columns(f) * tau;
        let fa2 = fa * fa;
        Self {
            mix: fa * half + fa2 * sixth,
            aa: Matrix3::identity() + fa + fa2 * half + fa2 * fa * sixth,
        }
    }

    /// Column `j` of the transition rows, `f_col` being column `j` of `F`:
    /// a column of the attitude block, or `F_j τ + mix F_j τ` (the same
    /// operations as the whole-matrix products).
    fn column(&self, j: usize, f_col: &[T; 3], tau: T) -> Vector3<T> {
        match j.checked_sub(ATT) {
            Some(a) if a < 3 => self
                .aa
                .data
                .0
                .get(a)
                .map_or_else(Vector3::zeros, |c| Vector3::from(*c)),
            _ => {
                let ft = Vector3::from(*f_col) * tau;
                ft + self.mix * ft
            }
        }
    }
}

/// `H ← H Φ` with Φ's attitude rows the [`transition_rows`] of `F` and `τ`,
/// each column of Φ formed where it is used ([`apply_transition`] of
/// `transition_rows(f, tau)` without the 3×N Φ; the same operations).
pub fn apply_transition_of<T: RealField + Copy, const R: usize, const N: usize>(
    h: &mut SMatrix<T, R, N>,
    f: &SMatrix<T, 3, N>,
    tau: T,
) {
    let pieces = TransitionPieces::new(f, tau);
    mix_columns(h, f, |j, f_col| pieces.column(j, f_col, tau));
}

/// `H ← H Φ` for a Φ whose parameter rows are the identity: only the
/// attitude columns of `H` mix; `phi_att` are the attitude rows of Φ. In
/// place, one column at a time (no `R×N` temporary).
pub fn apply_transition<T: RealField + Copy, const R: usize, const N: usize>(
    h: &mut SMatrix<T, R, N>,
    phi_att: &SMatrix<T, 3, N>,
) {
    mix_columns(h, phi_att, |_, phi_col| Vector3::from(*phi_col));
}

/// `H ← H Φ` for a Φ whose parameter rows are the identity, column `j` of
/// Φ's attitude rows being `phi_column(j, &source[j])`: the attitude
/// columns become `H_a Φ_aa`, the parameter columns `H_p + H_a Φ_ap`.
fn mix_columns<T: RealField + Copy, const R: usize, const N: usize>(
    h: &mut SMatrix<T, R, N>,
    source: &SMatrix<T, 3, N>,
    phi_column: impl Fn(usize, &[T; 3]) -> Vector3<T>,
) {
    let h_att = attitude_columns(h);
    for (j, (mut col, src)) in h.column_iter_mut().zip(source.data.0.iter()).enumerate() {
        let mixed = h_att * phi_column(j, src);
        if j < ATT + 3 {
            col.copy_from(&mixed);
        } else {
            col += mixed;
        }
    }
}
