//! Small copies in and out of the state vector and of 3-column blocks of
//! matrices, on the storage arrays (no nalgebra views: their runtime
//! checks are panic paths in the firmware, tools/panic-check.py).

use nalgebra::{RealField, SMatrix, SVector, Vector3};

use super::layout::ATT;

pub(super) fn block3<T: RealField + Copy, const N: usize>(
    x: &SVector<T, N>,
    i: usize,
) -> Vector3<T> {
    Vector3::new(
        x.get(i).copied().unwrap_or_else(T::zero),
        x.get(i + 1).copied().unwrap_or_else(T::zero),
        x.get(i + 2).copied().unwrap_or_else(T::zero),
    )
}

/// The attitude columns of `m` (its first three, [`ATT`]), copied, on the
/// column arrays. Not `fixed_columns(..).clone_owned()` nor column
/// iterators: those go through nalgebra's allocation from an iterator or
/// its view constructors, whose checks are panic paths when the compiler
/// does not inline them (`tools/panic-check.py` found them).
pub(crate) fn attitude_columns<T: RealField + Copy, const R: usize, const N: usize>(
    m: &SMatrix<T, R, N>,
) -> SMatrix<T, R, 3> {
    let mut out = SMatrix::<T, R, 3>::zeros();
    for (dst, src) in out.data.0.iter_mut().zip(m.data.0.iter().skip(ATT)) {
        *dst = *src;
    }
    out
}

pub(super) fn put3<T: RealField + Copy, const N: usize>(
    x: &mut SVector<T, N>,
    i: usize,
    v: &Vector3<T>,
) {
    for (k, val) in v.iter().enumerate() {
        if let Some(dst) = x.get_mut(i + k) {
            *dst = *val;
        }
    }
}

/// Columns `col..col + 3` of `m` := `block` (columns past `N` are dropped).
///
/// On the column arrays of the storage (column-major `[[T; R]; N]`), not a
/// view: `columns_mut(col, 3)` asserts its runtime offset (a panic path
/// into `core::panicking` in the firmware, tools/panic-check.py); the
/// zipped iterators have no bounds check at all.
pub(super) fn set_cols<T: RealField + Copy, const R: usize, const N: usize>(
    m: &mut SMatrix<T, R, N>,
    col: usize,
    block: &SMatrix<T, R, 3>,
) {
    for (dst, src) in m.data.0.iter_mut().skip(col).zip(block.data.0.iter()) {
        *dst = *src;
    }
}

/// Rows of columns `0..cols` of `m` multiplied by `scale` (row `i` by
/// `scale[i]`), on the column arrays (see [`set_cols`]).
pub(super) fn scale_rows<T: RealField + Copy, const N: usize>(
    m: &mut SMatrix<T, 3, N>,
    cols: usize,
    scale: &Vector3<T>,
) {
    for col in m.data.0.iter_mut().take(cols) {
        for (v, k) in col.iter_mut().zip(scale.iter()) {
            *v *= *k;
        }
    }
}
