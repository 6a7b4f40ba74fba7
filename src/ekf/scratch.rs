//! The update's working memory, kept in the filter ([`Scratch`]): the
//! measurement rows' projections of the congruence `H P Hᵀ` and the
//! whitened update ([`Whitened`]), which are `Z×N` and `3×N` of the
//! filter's precision, the factor as it was before the update (`N×N`),
//! to which a failed update returns, the estimate before the step (`N`,
//! f64), to which a refused step returns, and the one the update forms. On a firmware's stack they were 3.5 KB of f64 for
//! the full M2-ps model (39 states, 6 measurements), a step's stack budget
//! being 8 KB; in the filter, which a firmware keeps in static memory, they
//! cost that much static memory once per filter instead.
//!
//! Nothing in it outlives the period that writes it: every value is written
//! before it is read, in [`Filter::whiten`](super::Filter) and then read by
//! the scalar updates and the time update of the same period; the saved
//! factor is written before the scalar updates and read only when the
//! update fails after them. So it is not
//! part of the filter's state: two filters whose scratch differs are equal
//! (`==`), and a checkpoint does not carry it.

use core::fmt;

use nalgebra::{RealField, SVector};

use super::whiten::Whitened;

/// The update's working memory (see the [module docs](self)).
#[derive(Clone, Copy)]
pub(super) struct Scratch<T: RealField + Copy, const N: usize, const Z: usize> {
    /// `v = D Uᵀ hᵀ` of each measurement row (the congruence's).
    pub(super) projections: [[T; N]; Z],
    /// The whitened update of the period.
    pub(super) whitened: Whitened<T, N, Z>,
    /// The factor before the period's scalar updates: Bierman's updates
    /// and the time update after them change the factor in place, and an
    /// update that fails after them (an overflow, an attitude block that
    /// is no longer positive definite) returns the factor to this, so that
    /// a refused period leaves the covariance as it was.
    /// A plain array (the factor's storage, column by column), zeroed in
    /// place when a filter is built in its slot: no `N×N` temporary on a
    /// firmware's stack.
    pub(super) factor: [[T; N]; N],
    /// The estimate before the step being taken (rad), to which a refused
    /// step returns: kept here, not in the step's frame, which is on the
    /// deepest path of a step (the full M2-ps model's linearised update, 54
    /// states in f64: over 8 KB on the M7).
    pub(super) x_before: SVector<f64, N>,
    /// The estimate the update forms (rad), checked before it becomes the
    /// filter's: here for the same reason.
    pub(super) x_new: SVector<f64, N>,
}

impl<T: RealField + Copy, const N: usize, const Z: usize> Scratch<T, N, Z> {
    #[inline(always)]
    pub(super) fn zeros() -> Self {
        Self {
            projections: [[T::zero(); N]; Z],
            whitened: Whitened::zeros(),
            factor: [[T::zero(); N]; N],
            x_before: SVector::zeros(),
            x_new: SVector::zeros(),
        }
    }
}

/// Working memory, not state: always equal.
impl<T: RealField + Copy, const N: usize, const Z: usize> PartialEq for Scratch<T, N, Z> {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl<T: RealField + Copy, const N: usize, const Z: usize> fmt::Debug for Scratch<T, N, Z> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Scratch { .. }")
    }
}
