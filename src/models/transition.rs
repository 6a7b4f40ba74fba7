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
        Self::of_attitude_block(attitude_columns(f), tau)
    }

    /// From `F`'s attitude columns `f_att` (3×3).
    fn of_attitude_block(f_att: Matrix3<T>, tau: T) -> Self {
        let half: T = nalgebra::convert(0.5);
        let sixth: T = nalgebra::convert(1.0 / 6.0);
        let fa = f_att * tau;
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
    let columns = f.data.0.iter().enumerate();
    mix_columns(h, columns.map(|(j, f_col)| pieces.column(j, f_col, tau)));
}

/// [`apply_transition_of`] for `F = (F_a + F_b) / 2`, each column of which
/// is formed where it is used (the same values as the sum halved, without
/// its 3×N temporary: the accelerometer model's late node, whose 0.9 KB of
/// f64 for the full model's 39 states were on a Cortex-M's stack).
pub fn apply_transition_of_mean<T: RealField + Copy, const R: usize, const N: usize>(
    h: &mut SMatrix<T, R, N>,
    f_a: &SMatrix<T, 3, N>,
    f_b: &SMatrix<T, 3, N>,
    tau: T,
) {
    let half: T = nalgebra::convert(0.5);
    let mean = |a: &[T; 3], b: &[T; 3]| -> [T; 3] {
        [
            (a[0] + b[0]) * half,
            (a[1] + b[1]) * half,
            (a[2] + b[2]) * half,
        ]
    };
    let mut f_att = Matrix3::zeros();
    for (dst, (a, b)) in f_att
        .data
        .0
        .iter_mut()
        .zip(f_a.data.0.iter().skip(ATT).zip(f_b.data.0.iter().skip(ATT)))
    {
        *dst = mean(a, b);
    }
    let pieces = TransitionPieces::of_attitude_block(f_att, tau);
    let columns = f_a.data.0.iter().zip(f_b.data.0.iter()).enumerate();
    mix_columns(
        h,
        columns.map(|(j, (a, b))| pieces.column(j, &mean(a, b), tau)),
    );
}

/// `H ← H Φ` for a Φ whose parameter rows are the identity: only the
/// attitude columns of `H` mix; `phi_att` are the attitude rows of Φ. In
/// place, one column at a time (no `R×N` temporary).
pub fn apply_transition<T: RealField + Copy, const R: usize, const N: usize>(
    h: &mut SMatrix<T, R, N>,
    phi_att: &SMatrix<T, 3, N>,
) {
    mix_columns(h, phi_att.data.0.iter().map(|c| Vector3::from(*c)));
}

/// `H ← H Φ` for a Φ whose parameter rows are the identity, the columns of
/// Φ's attitude rows given in order by `phi_columns`: the attitude columns
/// become `H_a Φ_aa`, the parameter columns `H_p + H_a Φ_ap`.
fn mix_columns<T: RealField + Copy, const R: usize, const N: usize>(
    h: &mut SMatrix<T, R, N>,
    phi_columns: impl Iterator<Item = Vector3<T>>,
) {
    let h_att = attitude_columns(h);
    for (j, (mut col, phi_col)) in h.column_iter_mut().zip(phi_columns).enumerate() {
        let mixed = h_att * phi_col;
        if j < ATT + 3 {
            col.copy_from(&mixed);
        } else {
            col += mixed;
        }
    }
}
