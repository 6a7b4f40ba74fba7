//! The order of the states in the filter's U-D factor
//! ([`Filter::FACTOR_ORDER`]): the attitude first (the time update changes
//! only the factor's first three rows), then, in the full model, the
//! states that wander (the random walks `dg`, `ba` and the Gauss–Markov
//! parts `δ_g`, `δ_a`), then the others in the state vector's order.
//!
//! Why: `P + q e_j e_jᵀ` (a period's process noise on state `j`) changes
//! only the factor's columns `0..=j`, at a cost O(j²) (Agee–Turner,
//! [`Ud::add_variance`](super::factor::Ud::add_variance)). At the end of
//! the state vector (states 18 to 47 of 54 in the full M2-ps), the twelve
//! updates of a period cost ≈ 16 500 multiply-add pairs, 67 k instructions
//! a period on the Cortex-M4F (14 % of `Finish`); right after the attitude
//! (positions 3 to 14), ≈ 1 000 (firmware/bench.sh, BENCHMARKS.md). The covariance, the state and everything the filter
//! reports stay in the state vector's order; only the factor (and what a
//! checkpoint carries of it) is in this order.

use nalgebra::{RealField, SMatrix, SVector, Vector3};

use super::Filter;
use crate::models::{Layout, Model};
use crate::precision::scalar_to_f64;

/// The state (its index in the state vector) at position `k` of the
/// factor of a filter of `layout` (`k` itself outside the layout's
/// states): the attitude, then the states that wander (`dg`, `ba`, `δ_g`,
/// `δ_a`) for a layout with them, then the others in the state vector's
/// order. The one definition of the order ([`Filter::FACTOR_ORDER`] is
/// this at every position). Why: a period's process noise on the state at
/// position `j` changes the factor's columns `0..=j` only (Agee–Turner,
/// O(j²)), so the states that gain variance every period come first after
/// the attitude, which the time update needs first.
///
/// # Examples
///
/// A checkpoint's factor of the full M1-pa model (48 states) holds `ba_x`
/// (state 27) at position 6:
///
/// ```
/// use rollcal::ekf::factor_state;
/// use rollcal::models::ErrorModel;
/// use rollcal::ConfigId;
///
/// let layout = ConfigId::M1Pa.layout_with(ErrorModel::Full);
/// assert_eq!(layout.ba(), Some(27));
/// assert_eq!(factor_state(&layout, 6), 27);
/// assert_eq!(factor_state(&ConfigId::M1Pa.layout(), 6), 6); // installation: the identity
/// ```
pub const fn factor_state(layout: &Layout, k: usize) -> usize {
    let n = layout.n();
    let (Some(g0), Some(g1), Some(g2), Some(g3)) =
        (layout.dg(), layout.ba(), layout.dg_gm(), layout.ba_gm())
    else {
        return k;
    };
    if k < 3 || k >= n {
        return k;
    }
    if k < 15 {
        let (group, offset) = ((k - 3) / 3, (k - 3) % 3);
        return match group {
            0 => g0 + offset,
            1 => g1 + offset,
            2 => g2 + offset,
            _ => g3 + offset,
        };
    }
    // The (k − 15)-th of the other states, in order.
    let mut left = k - 15;
    let mut i = 3;
    while i < n {
        if !(in_group(i, g0) || in_group(i, g1) || in_group(i, g2) || in_group(i, g3)) {
            if left == 0 {
                return i;
            }
            left -= 1;
        }
        i += 1;
    }
    k
}

/// Whether state `i` is one of the three from `first`.
const fn in_group(i: usize, first: usize) -> bool {
    i >= first && i < first + 3
}

/// The factor's order of the `N` states of `layout`: `order[k]` is the
/// state at position `k` ([`factor_state`]).
// Evaluated at compile time only (the filter's associated constants): an
// index out of range there is a compile error, not a panic.
#[allow(clippy::indexing_slicing)]
pub(super) const fn factor_order<const N: usize>(layout: &Layout) -> [usize; N] {
    let mut order = [0usize; N];
    let mut k = 0;
    while k < N {
        order[k] = factor_state(layout, k);
        k += 1;
    }
    order
}

/// The inverse of `order`: `position[i]` is the factor's position of
/// state `i`.
// Evaluated at compile time only (the filter's associated constants): an
// index out of range there is a compile error, not a panic.
#[allow(clippy::indexing_slicing)]
pub(super) const fn positions<const N: usize>(order: &[usize; N]) -> [usize; N] {
    let mut position = [0usize; N];
    let mut k = 0;
    while k < N {
        position[order[k]] = k;
        k += 1;
    }
    position
}

/// Whether `order` is the identity.
// Evaluated at compile time only (the filter's associated constants): an
// index out of range there is a compile error, not a panic.
#[allow(clippy::indexing_slicing)]
pub(super) const fn is_identity<const N: usize>(order: &[usize; N]) -> bool {
    let mut k = 0;
    while k < N {
        if order[k] != k {
            return false;
        }
        k += 1;
    }
    true
}

/// `items[k] ← items[from[k]]` for every `k`, in place (the permutation's
/// cycles followed with one item aside). `from` must be a permutation of
/// `0..N` (the filter's constant tables are); an index out of range leaves
/// that item as it was.
pub(super) fn gather_in_place<E: Copy, const N: usize>(items: &mut [E; N], from: &[usize; N]) {
    let mut done = [false; N];
    for start in 0..N {
        if done.get(start).copied().unwrap_or(true) {
            continue;
        }
        let Some(&first) = items.get(start) else {
            continue;
        };
        let mut k = start;
        loop {
            if let Some(d) = done.get_mut(k) {
                *d = true;
            }
            let src = from.get(k).copied().unwrap_or(start);
            let value = if src == start {
                first
            } else {
                match items.get(src) {
                    Some(&v) => v,
                    None => break,
                }
            };
            if let Some(slot) = items.get_mut(k) {
                *slot = value;
            }
            if src == start || done.get(src).copied().unwrap_or(true) {
                break;
            }
            k = src;
        }
    }
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// The order of the states in the factor ([`Filter::factor`], and a
    /// checkpoint's factor): `FACTOR_ORDER[k]` is the state (its index in
    /// [`Filter::state`]) at position `k`. The identity for the
    /// installation model; for the full model the attitude, then the
    /// states that wander (`dg`, `ba`, `δ_g`, `δ_a`), then the others in
    /// order ([`factor_state`], the one definition, says why).
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::ekf::{M1PaFilter, M1PaFullFilter};
    ///
    /// let order = M1PaFullFilter::<f64>::FACTOR_ORDER;
    /// assert_eq!(order[..6], [0, 1, 2, 12, 13, 14]); // the attitude, then dg
    /// assert_eq!(order[6..9], [27, 28, 29]); // ba
    /// assert_eq!(order[15], 3); // then θgC, the first installation angle
    /// assert!(M1PaFilter::<f64>::FACTOR_ORDER.iter().enumerate().all(|(k, &i)| k == i));
    /// ```
    pub const FACTOR_ORDER: [usize; N] = factor_order::<N>(&M::LAYOUT);
    /// The factor's position of each state (the inverse of
    /// [`Filter::FACTOR_ORDER`]).
    pub(super) const POSITION: [usize; N] = positions(&Self::FACTOR_ORDER);
    /// Whether the factor is in the state vector's order (nothing to
    /// permute: the installation model).
    pub(super) const IN_STATE_ORDER: bool = is_identity(&Self::FACTOR_ORDER);

    /// The factor's position of state `i` (`i` itself outside `0..N`, and
    /// without a lookup in the state vector's order).
    pub(super) fn position(i: usize) -> usize {
        if Self::IN_STATE_ORDER {
            return i;
        }
        Self::POSITION.get(i).copied().unwrap_or(i)
    }

    /// The columns of `m` (one per state, the state vector's order) put in
    /// the factor's order, in place.
    pub(super) fn columns_to_factor_order<const R: usize>(m: &mut SMatrix<T, R, N>) {
        if !Self::IN_STATE_ORDER {
            gather_in_place(&mut m.data.0, &Self::FACTOR_ORDER);
        }
    }

    /// The columns of `m` (one per position of the factor) put back in the
    /// state vector's order, in place.
    pub(super) fn columns_to_state_order<const R: usize>(m: &mut SMatrix<T, R, N>) {
        if !Self::IN_STATE_ORDER {
            gather_in_place(&mut m.data.0, &Self::POSITION);
        }
    }

    /// A vector of the factor's positions (a correction, the variances)
    /// put in the state vector's order, in place.
    pub(super) fn vector_to_state_order(v: &mut SVector<T, N>) {
        if !Self::IN_STATE_ORDER {
            let [items] = &mut v.data.0;
            gather_in_place(items, &Self::POSITION);
        }
    }

    /// `Φ_att δ` (f64) of the attitude rows `phi` in the factor's order and
    /// a state-vector difference `delta` (the state vector's order), `δ`
    /// rounded to `T` as the product of [`super::linear_term`].
    pub(super) fn attitude_term(phi: &SMatrix<T, 3, N>, delta: &SVector<f64, N>) -> Vector3<f64> {
        let mut s = Vector3::<T>::zeros();
        for (col, i) in phi.column_iter().zip(Self::FACTOR_ORDER.iter()) {
            if let Some(d) = delta.get(*i) {
                s += col * nalgebra::convert::<f64, T>(*d);
            }
        }
        s.map(scalar_to_f64)
    }

    /// A covariance formed from the factor (rows and columns in the
    /// factor's order) put in the state vector's order.
    pub(super) fn covariance_to_state_order(mut p: SMatrix<T, N, N>) -> SMatrix<T, N, N> {
        if !Self::IN_STATE_ORDER {
            Self::columns_to_state_order(&mut p);
            p.transpose_mut();
            Self::columns_to_state_order(&mut p);
        }
        p
    }
}

#[cfg(test)]
#[allow(clippy::indexing_slicing)]
mod tests {
    use super::*;
    use crate::models::{ErrorModel, M2PsFull, Model};

    #[test]
    fn the_full_order_puts_the_wandering_states_after_the_attitude() {
        let layout = <M2PsFull as Model<54, 6>>::LAYOUT;
        let order = factor_order::<54>(&layout);
        let (dg, ba, gm, am) = (
            layout.dg().unwrap_or(99),
            layout.ba().unwrap_or(99),
            layout.dg_gm().unwrap_or(99),
            layout.ba_gm().unwrap_or(99),
        );
        let want_front: [usize; 15] = [
            0,
            1,
            2,
            dg,
            dg + 1,
            dg + 2,
            ba,
            ba + 1,
            ba + 2,
            gm,
            gm + 1,
            gm + 2,
            am,
            am + 1,
            am + 2,
        ];
        assert_eq!(order[..15], want_front);
        // The rest in the state vector's order; a permutation.
        let rest: [usize; 39] = core::array::from_fn(|k| order[15 + k]);
        assert!(rest.windows(2).all(|w| w[0] < w[1]));
        let pos = positions(&order);
        assert!((0..54).all(|i| order[pos[i]] == i));
        let installation = layout.with_errors(ErrorModel::Installation);
        assert!(is_identity(&factor_order::<18>(&installation)));
    }

    /// Every configuration's order, with either error model, is a
    /// permutation with the attitude first.
    #[test]
    fn every_order_is_a_permutation() {
        for id in crate::ConfigId::ALL {
            for errors in [ErrorModel::Installation, ErrorModel::Full] {
                let layout = id.layout_with(errors);
                let n = layout.n();
                let mut seen = [false; 64];
                for k in 0..n {
                    let i = factor_state(&layout, k);
                    assert!(i < n && !seen[i], "{id:?} {errors:?} position {k}");
                    seen[i] = true;
                }
                assert_eq!([0, 1, 2].map(|k| factor_state(&layout, k)), [0, 1, 2]);
                if errors == ErrorModel::Installation {
                    assert!((0..n).all(|k| factor_state(&layout, k) == k));
                }
            }
        }
    }

    #[test]
    fn gathering_in_place_is_indexing() {
        let order = factor_order::<54>(&<M2PsFull as Model<54, 6>>::LAYOUT);
        let v: [u32; 54] = core::array::from_fn(|i| 1000 + i as u32);
        let mut g = v;
        gather_in_place(&mut g, &order);
        assert!((0..54).all(|k| g[k] == v[order[k]]));
        gather_in_place(&mut g, &positions(&order));
        assert_eq!(g, v);
        // A swap and a 3-cycle.
        let mut w = [10, 11, 12, 13, 14];
        gather_in_place(&mut w, &[1, 0, 3, 4, 2]);
        assert_eq!(w, [11, 10, 13, 14, 12]);
    }
}
