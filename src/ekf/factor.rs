//! The U-D factored state covariance `P = U D Uᵀ` (docs/model.md §Estimator, single
//! precision).
//!
//! `U` is unit upper triangular and `D` diagonal and positive. The factor
//! carries the square root of the covariance's dynamic range: the states'
//! σ span 1° to 0.014″ (cond P ≈ 7e10, beyond what f32 resolves) while
//! `U D^{1/2}` spans ≈ 3e5, which f32 holds with three digits to spare.
//!
//! - measurement updates are Bierman's scalar updates ([`Ud::update`],
//!   Bierman 1977, *Factorization Methods for Discrete Sequential
//!   Estimation*, §V.3): the filter first decorrelates the period's
//!   measurement components;
//! - the time update ([`Ud::predict_attitude`]) exploits the structure of
//!   this problem: the parameters are constant, so only the three attitude
//!   states (the first three, [`crate::models::ATT`]) move. With `Φ` equal to
//!   the identity below its first three rows, `U₁₂ ← A U₁₂ + B U₂₂` and the
//!   3×3 block `A U₁₁ D₁ U₁₁ᵀ Aᵀ + Q` is refactored, by Thornton's weighted
//!   Gram–Schmidt on its square-root form, never formed (in f32 its
//!   eigenvalues can span more than f32 resolves); `U₂₂` and `D₂` do not
//!   change. That costs `3 N²/2` products instead of Thornton's `N³`.
//!
//! The factor is stored packed in one `N×N` matrix: `D` on the diagonal,
//! `U`'s strict upper triangle above it, zeros below (checkpoints carry it
//! in this form, so a restored filter continues bit-identically).
//!
//! Every index in this module is a loop index below the const size `N` (or
//! 3), so the indexing cannot be broken by input; `tools/panic-check.py`
//! verifies that the compiler removed every bounds check. The loops index
//! by the matrix's row and column as the algorithms are written (Bierman,
//! Thornton), and a test `!(v > 0)` is meant to reject NaN too.
#![allow(
    clippy::indexing_slicing,
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord
)]

use nalgebra::{Matrix3, RealField, SMatrix, SVector};

use crate::models::ATT;

/// A U-D factored covariance of `N` states (rad²), attitude states first.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ud<T: RealField + Copy, const N: usize> {
    /// Packed: `D` on the diagonal, `U` strictly above, zeros below.
    m: SMatrix<T, N, N>,
}

/// Gain and innovation variance of one scalar update (the tests' view of
/// [`Ud::update_into`]).
#[cfg(test)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScalarUpdate<T: RealField + Copy, const N: usize> {
    /// Kalman gain `K = P hᵀ / α` (state units per measurement unit).
    pub gain: SVector<T, N>,
    /// Innovation variance `α = h P hᵀ + r` (measurement units²).
    pub alpha: T,
}

const _ATTITUDE_FIRST: () = assert!(ATT == 0);

/// Calls `column(j)` for `j = 0, 1, …, N − 1`, in order, as four loops
/// (columns `[0, N/2)`, `[N/2, 3N/4)`, `[3N/4, 7N/8)`, `[7N/8, N)`) over the
/// triangle a column-oriented factor algorithm walks. Each run holds at most
/// 48 of the 153 products of `N = 18`, few enough for the compiler to
/// unroll it whole; one loop over the triangle is not unrolled, and its inner
/// loops of varying length cost more than their multiply-adds (Cortex-M4F:
/// a projection `Uᵀ h` of 18 states 1 480 → 738 instructions, a scalar
/// update 2 650 → 1 190, counted with `tools/qemu-insnmark` on the call
/// site; `firmware/bench.sh` counts the periods).
///
/// Above [`UNROLLED_UP_TO`] states (the full model's 33 to 39) the
/// triangle is one loop of `N` columns, which is too long for the compiler
/// to unroll whole (it unrolls runs of up to 19): unrolled, the 780 products of `N = 39` made one
/// scalar update 40 KB of code and 5 KB of stack (Cortex-M7), a flight
/// image's whole budget. The columns and the products are the same, in
/// the same order, so the results are the same bits.
#[inline(always)]
fn in_runs<const N: usize>(mut column: impl FnMut(usize)) {
    if N > UNROLLED_UP_TO {
        for j in 0..N {
            column(j);
        }
        return;
    }
    for j in 0..N / 2 {
        column(j);
    }
    for j in N / 2..3 * N / 4 {
        column(j);
    }
    for j in 3 * N / 4..7 * N / 8 {
        column(j);
    }
    for j in 7 * N / 8..N {
        column(j);
    }
}

/// The most states whose triangles [`in_runs`] lets the compiler unroll:
/// the installation models' (12 to 18).
const UNROLLED_UP_TO: usize = 18;

/// The new attitude rows of column `j ≥ 3` of the factor after the time
/// update (`U₁₂ ← A U₁₂ + B U₂₂`, U₂₂ unit upper): row `r` is
/// `Φ_rj + Σ_{k<j} Φ_rk U_kj`, summed in order of `k`, the three rows
/// together; `u` is the column above its diagonal (`U_kj`, `k < j`).
#[inline(always)]
fn attitude_column<T: RealField + Copy, const N: usize>(
    phi: &[[T; 3]; N],
    u: &[T],
    j: usize,
) -> [T; 3] {
    let mut s = phi[j];
    for (phi_k, u_kj) in phi.iter().zip(u) {
        for (s_r, phi_rk) in s.iter_mut().zip(phi_k) {
            *s_r += *phi_rk * *u_kj;
        }
    }
    s
}

/// Process noise on the three attitude states (rad²) in the form the time
/// update reads: `Q = B diag(w) Bᵀ`, `w ≥ 0` (3×3 each).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AttitudeNoise<T: RealField + Copy> {
    /// `B`: its columns are the directions of independent noises.
    b: Matrix3<T>,
    /// `w`: their variances (rad² for a unit column).
    w: [T; 3],
}

impl<T: RealField + Copy> AttitudeNoise<T> {
    /// No process noise.
    pub fn zero() -> Self {
        Self {
            b: Matrix3::zeros(),
            w: [T::zero(); 3],
        }
    }

    /// `Q = B Bᵀ` (rad²), e.g. a rate noise's map to the attitude times its
    /// σ and the period: nothing to factor. `None` unless `B` is finite.
    pub fn from_map(b: &Matrix3<T>) -> Option<Self> {
        b.iter().all(|v| v.is_finite()).then_some(Self {
            b: *b,
            w: [T::one(); 3],
        })
    }

    /// A symmetric positive semi-definite `Q` (rad²), factored as
    /// `U D Uᵀ` (`B = U`, `w = D`). A pivot within a few roundings of zero
    /// (`|D_j| ≤ 16 ε max_k Q_kk`: a singular `Q` formed as a difference,
    /// e.g. the decorrelated process noise when the accelerometers see the
    /// gyro noise far above their own) counts as zero and leaves its column
    /// of `U` zero. `None` if a pivot is more negative than that or an
    /// entry is not finite.
    pub fn from_covariance(q: &Matrix3<T>) -> Option<Self> {
        let sixteen: T = nalgebra::convert(16.0);
        let scale = q[(0, 0)].abs().max(q[(1, 1)].abs()).max(q[(2, 2)].abs());
        let packed = backward_ud(q, Some(sixteen * T::default_epsilon() * scale))?;
        let mut b = packed.upper_triangle();
        let w = [packed[(0, 0)], packed[(1, 1)], packed[(2, 2)]];
        b.fill_diagonal(T::one());
        Some(Self { b, w })
    }

    /// `Q = B diag(w) Bᵀ` (rad²; the tests' reference).
    #[cfg(test)]
    pub fn covariance(&self) -> Matrix3<T> {
        self.b * Matrix3::from_diagonal(&nalgebra::Vector3::from(self.w)) * self.b.transpose()
    }
}

/// `P = U D Uᵀ` by the backward modified Cholesky decomposition, packed
/// (`D` on the diagonal, `U` strictly above, zeros below). Without
/// `zero_pivot`, every pivot must be positive and finite; with
/// `Some(tolerance)`, a pivot down to `−tolerance` counts as zero and
/// leaves its column of `U` zero (a positive semi-definite `P`). `None`
/// otherwise, or if an entry of `P` is not finite.
fn backward_ud<T: RealField + Copy, const N: usize>(
    p: &SMatrix<T, N, N>,
    zero_pivot: Option<T>,
) -> Option<SMatrix<T, N, N>> {
    if p.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mut m = SMatrix::<T, N, N>::zeros();
    let a = &mut m.data.0; // a[col][row]
    let p = &p.data.0;
    for j in (0..N).rev() {
        let mut d = p[j][j];
        for k in j + 1..N {
            d -= a[k][j] * a[k][j] * a[k][k];
        }
        let d = match zero_pivot {
            None if d > T::zero() && d.is_finite() => d,
            Some(tolerance) if d.is_finite() && d >= -tolerance => d.max(T::zero()),
            _ => return None,
        };
        a[j][j] = d;
        for i in 0..j {
            let mut s = p[j][i];
            for k in j + 1..N {
                s -= a[k][i] * a[k][j] * a[k][k];
            }
            a[j][i] = if d > T::zero() { s / d } else { T::zero() };
        }
    }
    Some(m)
}

/// The U-D factor of `W diag(d) Wᵀ + Q` (3×3, rad²), formed without
/// that matrix: Thornton's modified weighted Gram–Schmidt (Bierman 1977,
/// §VI.2; Grewal & Andrews, *Kalman Filtering*, §6.6) on the rows of
/// `[W  B]` with weights `[d  w]`, where `Q = B diag(w) Bᵀ`. The rows are
/// made orthogonal in that weighting from the last up; each new `D` is a
/// row's weighted sum of squares, so it keeps its own relative precision.
/// Formed densely, the block's smallest eigenvalue drowns in the rounding
/// of its largest: after a few periods of a fast roll the attitude about
/// the best-observed axis has a variance of ≈ 1e-12 rad² beside ≈ 2e-5
/// rad² about the worst, a ratio beyond f32's `1/ε`, and the f32 filter
/// refused every later period (`CovarianceNotPositiveDefinite`; found by
/// `fuzz/`'s session target). `None` if the block comes out singular or
/// not finite.
fn attitude_block<T: RealField + Copy>(
    w: &Matrix3<T>,
    d: [T; 3],
    q: &AttitudeNoise<T>,
) -> Option<Ud<T, 3>> {
    // y[i] = row i of [W  B]; weights [d  w].
    let mut y = [[T::zero(); 6]; 3];
    for (i, row) in y.iter_mut().enumerate() {
        for k in 0..3 {
            row[k] = w[(i, k)];
            row[3 + k] = q.b[(i, k)];
        }
    }
    let weights = [d[0], d[1], d[2], q.w[0], q.w[1], q.w[2]];
    let mut out = Matrix3::<T>::zeros();
    for j in (0..3).rev() {
        let y_j = y[j];
        let mut d_j = T::zero();
        for (v, wt) in y_j.iter().zip(&weights) {
            d_j += *wt * *v * *v;
        }
        if !(d_j > T::zero()) || !d_j.is_finite() {
            return None;
        }
        out[(j, j)] = d_j;
        for i in 0..j {
            let mut s = T::zero();
            for ((v_i, v_j), wt) in y[i].iter().zip(&y_j).zip(&weights) {
                s += *wt * *v_i * *v_j;
            }
            let u_ij = s / d_j;
            out[(i, j)] = u_ij;
            for (v_i, v_j) in y[i].iter_mut().zip(&y_j) {
                *v_i -= u_ij * *v_j;
            }
        }
    }
    Some(Ud { m: out })
}

impl<T: RealField + Copy, const N: usize> Ud<T, N> {
    /// All zeros (not a factor: the storage a filter is built in before
    /// [`Ud::set_diagonal`] makes it one, in place).
    #[inline(always)]
    pub(crate) fn zeros() -> Self {
        Self {
            m: SMatrix::zeros(),
        }
    }

    /// Copies the factor's storage (column by column) into `out`, in place.
    pub(crate) fn save_into(&self, out: &mut [[T; N]; N]) {
        for (o, c) in out.iter_mut().zip(self.m.data.0.iter()) {
            o.copy_from_slice(c);
        }
    }

    /// Makes this factor the one [`Ud::save_into`] saved in `saved`, in
    /// place.
    pub(crate) fn restore_from(&mut self, saved: &[[T; N]; N]) {
        for (c, s) in self.m.data.0.iter_mut().zip(saved.iter()) {
            c.copy_from_slice(s);
        }
    }

    /// Makes this factor the one of a diagonal covariance with these
    /// variances (rad²), position `k` of the factor holding state
    /// `order[k]` (a permutation of `0..N`: the filter's
    /// [`FACTOR_ORDER`](super::Filter::FACTOR_ORDER)), in place; `false`
    /// (and the factor unchanged) unless every variance is finite and not
    /// negative (zero: a state the model does not estimate).
    pub fn set_diagonal(&mut self, variances: &SVector<T, N>, order: &[usize; N]) -> bool {
        if variances.iter().any(|v| !v.is_finite() || *v < T::zero()) {
            return false;
        }
        self.m.fill(T::zero());
        for (k, i) in order.iter().enumerate() {
            if let (Some(v), Some(d)) = (variances.get(*i), self.m.get_mut((k, k))) {
                *d = *v;
            }
        }
        true
    }

    /// Makes this factor the one whose packed form ([`Ud::packed`]) has
    /// the upper triangle, diagonal included, `at(r, c)` (`c ≥ r`, in f64,
    /// rounded to `T`; a checkpoint's values), zeros below, in place;
    /// `false` (and the factor unchanged) unless every such entry is there
    /// (`Some`) and finite in `T`, every `D` is positive or zero, and the
    /// column of `U` above a zero `D` and its row to the right are zero (a
    /// state the model does not estimate, as the filter keeps it); a zero
    /// `D` only at states `held_from..N` (those before it keep `D > 0`:
    /// [`Ud::update_into`]).
    // One body per filter type, whatever gives the entries (`dyn`): a
    // restore is rare, its code is not worth a copy per caller in flash.
    #[inline(never)]
    pub fn set_upper_with(
        &mut self,
        at: &dyn Fn(usize, usize) -> Option<f64>,
        held_from: usize,
    ) -> bool {
        let t = |r: usize, c: usize| at(r, c).map(|v| -> T { nalgebra::convert(v) });
        // Row by row: every entry there and finite, D ≥ 0 (zero only from
        // `held_from`), the row right of a zero D zero.
        let mut zero_d = [false; N];
        for r in 0..N {
            for c in r..N {
                let Some(v) = t(r, c).filter(|v| v.is_finite()) else {
                    return false;
                };
                let valid = if c == r {
                    v > T::zero() || (v == T::zero() && r >= held_from)
                } else {
                    v == T::zero() || !zero_d.get(r).copied().unwrap_or(true)
                };
                if !valid {
                    return false;
                }
                if c == r {
                    if let Some(z) = zero_d.get_mut(r) {
                        *z = v == T::zero();
                    }
                }
            }
        }
        // The column above a zero D zero.
        for (c, _) in zero_d.iter().enumerate().filter(|(_, z)| **z) {
            if (0..c).any(|r| t(r, c) != Some(T::zero())) {
                return false;
            }
        }
        for (c, column) in self.m.column_iter_mut().enumerate() {
            for (r, e) in column.into_iter().enumerate() {
                *e = if c >= r {
                    t(r, c).unwrap_or_else(T::zero)
                } else {
                    T::zero()
                };
            }
        }
        true
    }

    /// The factor of a symmetric positive definite covariance (rad²), by the
    /// backward modified Cholesky decomposition; `None` if `p` is not
    /// positive definite or not finite (the tests' reference).
    #[cfg(test)]
    pub fn from_covariance(p: &SMatrix<T, N, N>) -> Option<Self> {
        backward_ud(p, None).map(|m| Self { m })
    }

    /// The packed factor: `D` on the diagonal, `U` strictly above.
    pub fn packed(&self) -> &SMatrix<T, N, N> {
        &self.m
    }

    /// The covariance `P = U D Uᵀ` (rad²).
    pub fn covariance(&self) -> SMatrix<T, N, N> {
        let a = &self.m.data.0;
        let mut p = SMatrix::<T, N, N>::zeros();
        for i in 0..N {
            for j in i..N {
                // P_ij = Σ_{k ≥ j} U_ik D_k U_jk (U_kk = 1).
                let mut s = if i == j { a[j][j] } else { a[j][i] * a[j][j] };
                for k in j + 1..N {
                    s += a[k][i] * a[k][j] * a[k][k];
                }
                p[(i, j)] = s;
                p[(j, i)] = s;
            }
        }
        p
    }

    /// One element `P_ij` of the covariance (rad²), as
    /// [`Ud::covariance`] computes it (the same operations); `None` outside
    /// `N × N`.
    pub fn covariance_entry(&self, i: usize, j: usize) -> Option<T> {
        self.entry_with(i, j, |r, c| {
            self.m.data.0.get(c).and_then(|col| col.get(r)).copied()
        })
    }

    /// [`Ud::covariance_entry`] of the factor whose first three (attitude)
    /// rows are `rows` (packed as the factor: `D` on the diagonal, `U` to
    /// the right; from [`Ud::predicted_attitude_rows`]) and whose other rows
    /// are this factor's: `P` after the time update, without forming that
    /// factor.
    pub fn covariance_entry_with_rows(
        &self,
        rows: &SMatrix<T, 3, N>,
        i: usize,
        j: usize,
    ) -> Option<T> {
        self.entry_with(i, j, |r, c| {
            if r < 3 {
                rows.get((r, c)).copied()
            } else {
                self.m.data.0.get(c).and_then(|col| col.get(r)).copied()
            }
        })
    }

    /// [`Ud::variances`] of the factor whose first three rows are `rows`
    /// (as [`Ud::covariance_entry_with_rows`]; the same operations): the
    /// variances after the time update, without forming that factor.
    pub fn variances_with_rows(&self, rows: &SMatrix<T, 3, N>) -> SVector<T, N> {
        SVector::from_fn(|i, _| {
            self.covariance_entry_with_rows(rows, i, i)
                .unwrap_or_else(T::zero)
        })
    }

    /// `P_ij = Σ_{k ≥ j} U_ik D_k U_jk` over the packed factor read
    /// through `at(row, col)`. Not inlined: a caller that reads many
    /// elements (pass 1's second-order terms) would hold an unrolled copy of
    /// this loop for each.
    #[inline(never)]
    fn entry_with(&self, i: usize, j: usize, at: impl Fn(usize, usize) -> Option<T>) -> Option<T> {
        let (i, j) = if i <= j { (i, j) } else { (j, i) };
        if j >= N {
            return None;
        }
        let d_j = at(j, j)?;
        let mut s = if i == j { d_j } else { at(i, j)? * d_j };
        for k in j + 1..N {
            if let (Some(u_i), Some(u_j), Some(d_k)) = (at(i, k), at(j, k), at(k, k)) {
                s += u_i * u_j * d_k;
            }
        }
        Some(s)
    }

    /// The variances `P_ii` (rad²).
    pub fn variances(&self) -> SVector<T, N> {
        let a = &self.m.data.0;
        let mut v = SVector::<T, N>::zeros();
        for i in 0..N {
            let mut s = a[i][i];
            for k in i + 1..N {
                s += a[k][i] * a[k][i] * a[k][k];
            }
            v[i] = s;
        }
        v
    }

    /// `f = Uᵀ h` for a row `h`, written into `f` (every element).
    #[inline(always)]
    fn project_f(&self, h: &SVector<T, N>, f: &mut [T; N]) {
        let a = &self.m.data.0;
        let h = h.as_slice();
        in_runs::<N>(|j| {
            // f_j = h_j + Σ_{i<j} U_ij h_i, summed in order of i.
            f[j] = a[j][..j]
                .iter()
                .zip(h)
                .fold(h[j], |s, (u, h_i)| s + *u * *h_i);
        });
    }

    /// `f = Uᵀ h` and `v = D Uᵀ h` for a row `h`, written into `f` and `v`
    /// (every element).
    #[inline(always)]
    fn project_to(&self, h: &SVector<T, N>, f: &mut [T; N], v: &mut [T; N]) {
        self.project_f(h, f);
        let a = &self.m.data.0;
        for j in 0..N {
            v[j] = f[j] * a[j][j];
        }
    }

    /// [`Ud::project_to`] out of line, for the congruence's rows: its
    /// temporaries are then not in the frame of the congruence's caller
    /// (the whitening, on the deepest stack path of a filter step).
    #[inline(never)]
    fn project_row(&self, h: &SVector<T, N>, f: &mut [T; N], v: &mut [T; N]) {
        self.project_to(h, f, v);
    }

    /// `H P Hᵀ` for the `R` rows of `h` (one projection `Uᵀ hᵢᵀ` per row,
    /// then `Fᵀ D F`), the rows' projections kept in `earlier` (`R×N`,
    /// whatever it held): the caller's memory (the filter's, so that they
    /// are not on a Cortex-M's stack: 1.9 KB of f64 for the full model's 6
    /// rows of 39 states).
    pub fn congruence_into<const R: usize>(
        &self,
        h: &SMatrix<T, R, N>,
        earlier: &mut [[T; N]; R],
    ) -> SMatrix<T, R, R> {
        // Row by row, keeping only the earlier rows' `v = D f` (half the
        // projections' memory): the pair (b, a), b ≤ a, is `f_a · v_b`.
        let mut f_a = [T::zero(); N];
        let mut out = SMatrix::<T, R, R>::zeros();
        for (a, row) in h.row_iter().enumerate() {
            let Some(v_a) = earlier.get_mut(a) else {
                break;
            };
            self.project_row(&row.transpose(), &mut f_a, v_a);
            let f_a = SVector::from(f_a);
            for (b, v_b) in earlier.iter().enumerate().take(a + 1) {
                let x = f_a.dot(&SVector::from(*v_b));
                out[(a, b)] = x;
                out[(b, a)] = x;
            }
        }
        out
    }

    /// [`Ud::update_into`] with the gain returned (the tests' form).
    #[cfg(test)]
    pub fn update(&mut self, h: &SVector<T, N>, r: T) -> Option<ScalarUpdate<T, N>> {
        let mut gain = [T::zero(); N];
        let alpha = self.update_into(h, r, &mut gain, 0)?;
        Some(ScalarUpdate {
            gain: SVector::from(gain),
            alpha,
        })
    }

    /// Bierman's scalar measurement update for `z = h x + v`, `var v = r`:
    /// the factor becomes that of `P − P hᵀ h P / α`. Writes the gain
    /// `K = P hᵀ / α` into `b` (every element; its old values do not
    /// matter) and returns `α`; `None` (factor untouched) if `r` is not
    /// strictly positive or the update would leave `D` non-positive or
    /// non-finite.
    ///
    /// Two arrays of `N`: `f = Uᵀ h` and the running `b`, which becomes the
    /// gain; `v_j = D_j f_j`, the `α` sequence and the new `D` are formed
    /// where they are used, twice (a checking pass, then the update), the
    /// same operations in the same order both times. No gain-sized value is
    /// returned by value (0.3 KB of f64 on a Cortex-M's stack for 39
    /// states).
    ///
    /// States `held_from..N` may have `D = 0` (not estimated: they stay
    /// so); those before it must have `D > 0` (the filter's invariant: its
    /// prior and checkpoints give a zero variance only to instrument
    /// states), so their zero tests are left out (with a constant
    /// `held_from`, at compile time: `N` for the installation model).
    #[inline(always)]
    pub fn update_into(
        &mut self,
        h: &SVector<T, N>,
        r: T,
        b: &mut [T; N],
        held_from: usize,
    ) -> Option<T> {
        if !(r > T::zero()) {
            return None;
        }
        let mut f = [T::zero(); N];
        self.project_f(h, &mut f);
        // The α sequence and the new D depend only on f and the old D:
        // check them first, so the update itself runs in place and cannot
        // fail half-way (no copy of the factor for a rollback).
        {
            let a = &self.m.data.0;
            let mut alpha = r;
            // Σ D⁺: finite if and only if every D⁺ is (they are positive).
            let mut sum_d = T::zero();
            for j in 0..N {
                let beta = alpha;
                alpha += f[j] * a[j][j] * f[j];
                // A NaN, non-positive or infinite α gives a D⁺ that is NaN,
                // non-positive or infinite: one test below covers them. A
                // state of zero variance (not estimated) stays at zero.
                let d = a[j][j] * (beta / alpha);
                let pinned = j >= held_from && a[j][j] == T::zero() && alpha.is_finite();
                if !(d > T::zero() || pinned) {
                    return None;
                }
                sum_d += d;
            }
            if !sum_d.is_finite() {
                return None;
            }
        }
        let a = &mut self.m.data.0;
        b.fill(T::zero());
        // Column j: U's column becomes U_j + λ_j b and b becomes b + v_j U_j
        // (the old U_j), λ_j = −f_j / α_{j−1} (α_{−1} = r); then b_j = v_j.
        let mut alpha = r;
        in_runs::<N>(|j| {
            let beta = alpha;
            let col = &mut a[j];
            if j >= held_from && col[j] == T::zero() {
                // A state of zero variance (not estimated): its column of U
                // stays zero (it multiplies D_j = 0), its gain is zero.
                b[j] = T::zero();
                return;
            }
            let v_j = f[j] * col[j];
            alpha += v_j * f[j];
            let lambda = -f[j] / beta;
            col[j] *= beta / alpha;
            for (u, b_i) in col[..j].iter_mut().zip(b.iter_mut()) {
                let u_old = *u;
                *u = u_old + *b_i * lambda;
                *b_i += u_old * v_j;
            }
            b[j] = v_j;
        });
        // α after the last state (r for a factor of no states).
        for b_i in b.iter_mut() {
            *b_i /= alpha;
        }
        Some(alpha)
    }

    /// The time update `P ← Φ P Φᵀ + Q` of a transition `Φ` that is the
    /// identity but for its first three (attitude) rows `phi_att` (3×N), with
    /// process noise `q` (rad², [`AttitudeNoise`]) on the attitude states only. `None`
    /// (factor untouched) if the new attitude block is not positive definite.
    ///
    /// In place, column by column: each column's new attitude rows read its
    /// old ones and no other column's, and the new attitude block, formed
    /// from the old one first, is written last (no 3×N temporary: 0.9 KB
    /// of f64 for 39 states on a Cortex-M's stack). The same values as
    /// [`Ud::predicted_attitude_rows`], bit for bit.
    // Out of line: called once a period, from the update's frame.
    #[inline(never)]
    pub fn predict_attitude(
        &mut self,
        phi_att: &SMatrix<T, 3, N>,
        q: &AttitudeNoise<T>,
    ) -> Option<()> {
        let phi = &phi_att.data.0; // phi[col][row]
        let blk = self.predicted_attitude_block(phi_att, q)?;
        let a = &mut self.m.data.0;
        in_runs::<N>(|j| {
            if j >= 3 {
                let new = if a[j][j] == T::zero() {
                    // A state of zero variance: its column stays zero.
                    [T::zero(); 3]
                } else {
                    attitude_column(phi, &a[j][..j], j)
                };
                a[j][..3].copy_from_slice(&new);
            }
        });
        let b = &blk.m.data.0;
        for c in 0..3 {
            for r in 0..=c {
                a[c][r] = b[c][r];
            }
        }
        Some(())
    }

    /// The factor of the attitude block after [`Ud::predict_attitude`],
    /// from the old `U₁₁`, `D₁` only: `W = A U₁₁` (U₁₁ unit upper), then
    /// the factor of `W D₁ Wᵀ + Q`, without forming that block
    /// (`attitude_block`). `None` if it is not positive definite.
    fn predicted_attitude_block(
        &self,
        phi_att: &SMatrix<T, 3, N>,
        q: &AttitudeNoise<T>,
    ) -> Option<Ud<T, 3>> {
        let phi = &phi_att.data.0; // phi[col][row]
        let a = &self.m.data.0;
        let mut w = Matrix3::<T>::zeros();
        for c in 0..3 {
            for r in 0..3 {
                let mut s = if c < N { phi[c][r] } else { T::zero() };
                for k in 0..c {
                    s += phi[k][r] * a[c][k];
                }
                w[(r, c)] = s;
            }
        }
        attitude_block(&w, [a[0][0], a[1][1], a[2][2]], q)
    }

    /// The first three rows of the factor after [`Ud::predict_attitude`]
    /// (packed: `D` on the diagonal, `U` to its right, zeros to its left);
    /// the other rows do not change. The factor itself is not modified.
    /// `None` if the new attitude block is not positive definite.
    pub fn predicted_attitude_rows(
        &self,
        phi_att: &SMatrix<T, 3, N>,
        q: &AttitudeNoise<T>,
    ) -> Option<SMatrix<T, 3, N>> {
        let phi = &phi_att.data.0; // phi[col][row]
        let a = &self.m.data.0;
        let blk = self.predicted_attitude_block(phi_att, q)?;
        let mut rows = SMatrix::<T, 3, N>::zeros();
        in_runs::<N>(|j| {
            if j >= 3 && a[j][j] != T::zero() {
                rows.data.0[j] = attitude_column(phi, &a[j][..j], j);
            }
        });
        let b = &blk.m.data.0;
        for c in 0..3 {
            for r in 0..=c {
                rows[(r, c)] = b[c][r];
            }
        }
        Some(rows)
    }

    /// `P ← S P S` for `S` the identity but `s` at state `j` (a
    /// Gauss–Markov state's decay over a period, `0 < s ≤ 1`): row `j` of
    /// `U` times `s`, column `j` divided by it, `D_j` times `s²`
    /// (`U' = S U S⁻¹`, `D' = S D S`). O(N); nothing for `j ≥ N`.
    pub fn scale_state(&mut self, j: usize, s: T) {
        if j >= N {
            return;
        }
        let a = &mut self.m.data.0; // a[col][row]
        a[j][j] *= s * s;
        for col in a.iter_mut().skip(j + 1) {
            col[j] *= s;
        }
        let inv = T::one() / s;
        for u in a[j][..j].iter_mut() {
            *u *= inv;
        }
    }

    /// `P ← P + q e_j e_jᵀ` (process noise of variance `q ≥ 0` on state
    /// `j`) by the Agee–Turner rank-one update (Bierman 1977, §V.3; its
    /// positive-weight form, which is stable): only columns `0..=j` of the
    /// factor change, O(j²). The work vector `a` is the caller's (`N`
    /// elements, whatever they held). `false` (factor untouched) unless `q`
    /// is finite and not negative; nothing for `q = 0` or `j ≥ N`.
    ///
    /// A state whose variance is zero (`D_j = 0`, its column of `U` and its
    /// row to the right zero: a term the model does not estimate) gains
    /// `D_j = q` and no correlation.
    pub fn add_variance(&mut self, j: usize, q: T, a: &mut [T; N]) -> bool {
        if !(q >= T::zero()) || !q.is_finite() {
            return false;
        }
        if q == T::zero() || j >= N {
            return true;
        }
        let m = &mut self.m.data.0; // m[col][row]
        a.fill(T::zero());
        a[j] = T::one();
        let mut c = q;
        for k in (0..=j).rev() {
            let p = a[k];
            if p == T::zero() || c == T::zero() {
                // No change to column k, and c stays (a_i −= 0).
                continue;
            }
            let d_old = m[k][k];
            let d_new = d_old + c * p * p;
            let beta = c * p / d_new;
            c = c * d_old / d_new;
            m[k][k] = d_new;
            let (col, a_head) = (&mut m[k][..k], &mut a[..k]);
            for (u, a_i) in col.iter_mut().zip(a_head.iter_mut()) {
                *a_i -= p * *u;
                *u += beta * *a_i;
            }
        }
        true
    }

    /// Re-opens the attitude: its covariance becomes `variance · I` (rad²)
    /// with no correlation to the parameters, whose covariance is kept.
    pub fn reset_attitude(&mut self, variance: T) {
        let a = &mut self.m.data.0;
        for (j, col) in a.iter_mut().enumerate() {
            for (i, v) in col.iter_mut().enumerate().take(3) {
                if i < j {
                    *v = T::zero();
                } else if i == j {
                    *v = variance;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A well-conditioned 6-state covariance with correlations.
    fn covariance() -> SMatrix<f64, 6, 6> {
        let a = SMatrix::<f64, 6, 6>::from_fn(|i, j| ((3 * i + 5 * j) % 7) as f64 / 7.0 - 0.4);
        a * a.transpose() + SMatrix::identity() * 0.1
    }

    /// `W diag(d) Wᵀ + Q` of an attitude block (3×3, f64).
    fn dense_block(w: &Matrix3<f64>, d: [f64; 3], q: &Matrix3<f64>) -> Matrix3<f64> {
        w * Matrix3::from_diagonal(&nalgebra::Vector3::from(d)) * w.transpose() + q
    }

    /// A factor set from its upper triangle holds those values above and
    /// on the diagonal and zeros below; a zero `D` is taken only from
    /// `held_from` on and with its row and column zero; a missing or
    /// non-finite entry, a negative `D` refuse it, the factor unchanged.
    #[test]
    fn set_upper_with_takes_a_factor_and_refuses_what_is_not_one() {
        // 4 states; D_3 = 0 (a held state): its row and column are zero.
        let upper = [
            [2.0, 0.5, -0.25, 0.0],
            [0.0, 3.0, 0.125, 0.0],
            [0.0, 0.0, 4.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
        ];
        let at = |u: [[f64; 4]; 4]| move |r: usize, c: usize| u.get(r)?.get(c).copied();
        let mut ud = Ud::<f64, 4>::zeros();
        assert!(ud.set_upper_with(&at(upper), 3));
        for r in 0..4 {
            for c in 0..4 {
                let want = if c >= r { upper[r][c] } else { 0.0 };
                assert_eq!(ud.packed()[(r, c)], want, "({r}, {c})");
            }
        }
        let kept = ud;
        let with = |r: usize, c: usize, v: f64| {
            let mut u = upper;
            u[r][c] = v;
            u
        };
        for (bad, held_from, what) in [
            (upper, 4, "a zero D before held_from"),
            (with(0, 3, 0.5), 3, "U above a zero D"),
            (with(1, 1, -1.0), 3, "a negative D"),
            (with(0, 2, f64::NAN), 3, "a NaN"),
            (with(2, 2, f64::INFINITY), 3, "an infinite D"),
        ] {
            assert!(!ud.set_upper_with(&at(bad), held_from), "{what}");
            assert_eq!(ud, kept, "{what}");
        }
        // A zero D with U to its right.
        // A zero D with its column above zero but U to its right.
        let mut u = upper;
        (u[0][2], u[1][2], u[2][2]) = (0.0, 0.0, 0.0);
        assert!(ud.set_upper_with(&at(u), 2), "a held state at 2");
        ud = kept;
        u[2][3] = 0.5;
        assert!(!ud.set_upper_with(&at(u), 2), "U right of a zero D");
        // A missing entry.
        assert!(!ud.set_upper_with(&|r, c| (r + c < 6).then_some(1.0), 0));
        assert_eq!(ud, kept);
    }

    /// The weighted Gram–Schmidt factor of the attitude block is the
    /// factor of the block formed densely (f64, well conditioned), also
    /// with no process noise at all or on one combination only.
    #[test]
    fn attitude_block_is_the_dense_blocks_factor() {
        let w = Matrix3::new(1.0, 0.05, -0.3, -0.04, 1.0, 0.7, 0.02, -0.06, 1.0);
        let d = [2e-4, 3e-5, 7e-6];
        let g = Matrix3::new(1.0, 0.2, 0.0, -0.1, 0.9, 0.3, 0.05, 0.0, 1.1) * 1e-3;
        let rank_one = nalgebra::Vector3::new(1e-3, -2e-3, 5e-4);
        for q in [
            g * g.transpose(),
            Matrix3::zeros(),
            rank_one * rank_one.transpose(),
        ] {
            let noise = AttitudeNoise::from_covariance(&q).expect("semi-definite");
            assert!((noise.covariance() - q).amax() < 1e-22);
            let got = attitude_block(&w, d, &noise).expect("positive definite");
            let want = dense_block(&w, d, &q);
            let err = (got.covariance() - want).amax();
            assert!(err < 1e-16, "{err:e}");
            let dense = Ud::<f64, 3>::from_covariance(&want).expect("positive definite");
            assert!((got.packed() - dense.packed()).amax() < 1e-11);
        }
        // Q = G Gᵀ given by its map: the same factor to rounding.
        let by_map = attitude_block(&w, d, &AttitudeNoise::from_map(&g).expect("finite"))
            .expect("positive definite");
        let by_covariance = attitude_block(
            &w,
            d,
            &AttitudeNoise::from_covariance(&(g * g.transpose())).expect("semi-definite"),
        )
        .expect("positive definite");
        assert!((by_map.packed() - by_covariance.packed()).amax() < 1e-15);
    }

    /// In f32, a block whose eigenvalues span more than `1/ε_f32` (the
    /// attitude after a few periods of a fast roll: 1e-12 rad² about one
    /// axis, 2e-5 rad² about another): formed densely and refactored in
    /// f32 its smallest `D` comes out 25 % off (in the filter, a little
    /// further on, not positive at all); the weighted Gram–Schmidt factor
    /// keeps every `D` within 1e-5 of f64's.
    #[test]
    fn attitude_block_in_f32_keeps_what_the_dense_block_loses() {
        // A rotation of 3° mixes the axes, as a period of the fast roll does.
        let c = (3.0_f64).to_radians();
        let w = Matrix3::new(1.0, -0.05, 0.4, c, 1.0, -0.2, -c, c, 1.0);
        let d = [9e-13, 5e-9, 2e-5];
        let q = Matrix3::from_diagonal(&nalgebra::Vector3::new(2.4e-13, 2.2e-13, 2.3e-13));
        let f32_of = |m: &Matrix3<f64>| m.map(|v| v as f32);
        let noise = AttitudeNoise::from_covariance(&q).expect("semi-definite");
        let noise32 = AttitudeNoise::from_covariance(&f32_of(&q)).expect("semi-definite");
        let want = attitude_block(&w, d, &noise).expect("positive definite in f64");
        let dense32 = Ud::<f32, 3>::from_covariance(&f32_of(&dense_block(&w, d, &q)));
        let got = attitude_block(&f32_of(&w), d.map(|v| v as f32), &noise32)
            .expect("positive definite in f32");
        for i in 0..3 {
            let (g, x) = (f64::from(got.packed()[(i, i)]), want.packed()[(i, i)]);
            assert!((g - x).abs() < 1e-5 * x, "D_{i}: f32 {g:e}, f64 {x:e}");
        }
        let dense_d0 = dense32.map(|u| f64::from(u.packed()[(0, 0)]));
        let want_d0 = want.packed()[(0, 0)];
        assert!(
            dense_d0.is_none_or(|v| (v - want_d0).abs() > 0.01 * want_d0),
            "the dense block in f32 was good enough: {dense_d0:?} against {want_d0:e}"
        );
    }

    /// A process noise that is not positive semi-definite, or not finite,
    /// is refused; one within a few roundings of singular is not.
    #[test]
    fn a_process_noise_that_is_not_semi_definite_is_refused() {
        let mut q = Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-12, 1e-12, -1e-12));
        assert!(AttitudeNoise::from_covariance(&q).is_none());
        q[(2, 2)] = -1e-12 * f64::EPSILON;
        let noise = AttitudeNoise::from_covariance(&q).expect("singular to rounding");
        assert_eq!(noise.w[2], 0.0);
        q[(2, 2)] = f64::NAN;
        assert!(AttitudeNoise::from_covariance(&q).is_none());
        let mut b = Matrix3::identity();
        b[(1, 2)] = f64::INFINITY;
        assert!(AttitudeNoise::from_map(&b).is_none());
    }

    /// Bierman's update gives the dense `P − P hᵀ h P / α`, its gain and α.
    #[test]
    fn update_is_the_dense_update() {
        let p = covariance();
        let mut ud = Ud::from_covariance(&p).expect("positive definite");
        let h = SVector::<f64, 6>::from_fn(|i, _| 0.3 * i as f64 - 0.7);
        let r = 0.05;
        let up = ud.update(&h, r).expect("a valid update");
        let ph = p * h;
        let alpha = h.dot(&ph) + r;
        let want = p - ph * ph.transpose() / alpha;
        assert!((up.alpha - alpha).abs() < 1e-13 * alpha);
        assert!((up.gain - ph / alpha).amax() < 1e-13);
        assert!(
            (ud.covariance() - want).amax() < 1e-13,
            "{}",
            ud.covariance() - want
        );
    }

    /// Every update that would leave `D` non-positive or non-finite is
    /// refused with the factor untouched: a NaN or an infinity in `h`, an
    /// α that overflows, a variance `r` that is not positive.
    #[test]
    fn a_refused_update_leaves_the_factor_untouched() {
        let before = Ud::from_covariance(&covariance()).expect("positive definite");
        let ok = SVector::<f64, 6>::repeat(0.5);
        let cases = [
            (ok, 0.0),
            (ok, -1.0),
            (ok, f64::NAN),
            (
                SVector::from_fn(|i, _| if i == 3 { f64::NAN } else { 0.5 }),
                1.0,
            ),
            (
                SVector::from_fn(|i, _| if i == 4 { f64::INFINITY } else { 0.5 }),
                1.0,
            ),
            (
                SVector::from_fn(|i, _| if i == 0 { 1e200 } else { 0.5 }),
                1.0,
            ),
            // Only the last α overflows: its D⁺ is 0, the others valid.
            (
                SVector::from_fn(|i, _| if i == 5 { 1e200 } else { 0.5 }),
                1.0,
            ),
            (SVector::repeat(1e160), 1.0),
        ];
        for (h, r) in cases {
            let mut ud = before;
            assert!(ud.update(&h, r).is_none(), "h = {h:?}, r = {r}");
            assert_eq!(ud, before, "h = {h:?}, r = {r}");
        }
        let mut ud = before;
        assert!(ud.update(&ok, 1.0).is_some());
    }

    /// A deterministic sequence in (−1, 1).
    fn lcg(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((*state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    /// `Ud::covariance_entry` (one element of `P` from the factor, shared by
    /// the second-order terms) gives `Ud::covariance`'s element bit for bit.
    #[test]
    fn covariance_entry_equals_the_covariance() {
        let mut s = 13;
        let a = SMatrix::<f64, 18, 18>::from_fn(|_, _| lcg(&mut s));
        let p = a * a.transpose() + SMatrix::<f64, 18, 18>::identity();
        let ud = Ud::from_covariance(&p).expect("positive definite");
        let full = ud.covariance();
        for i in 0..18 {
            for j in 0..18 {
                assert_eq!(ud.covariance_entry(i, j), Some(full[(i, j)]), "({i}, {j})");
            }
        }
        assert_eq!(ud.covariance_entry(18, 0), None);
        assert_eq!(ud.covariance_entry(0, 18), None);
    }

    /// `Ud::predicted_attitude_rows`, `Ud::covariance_entry_with_rows` and
    /// `Ud::variances_with_rows` (`P` after the time update without forming
    /// its factor) give `Ud::predict_attitude`'s on a copy, bit for bit.
    #[test]
    fn predicted_attitude_rows_equal_the_time_update() {
        let mut s = 29;
        let a = SMatrix::<f64, 18, 18>::from_fn(|_, _| lcg(&mut s));
        let p = a * a.transpose() + SMatrix::<f64, 18, 18>::identity();
        let ud = Ud::from_covariance(&p).expect("positive definite");
        let phi_att = SMatrix::<f64, 3, 18>::from_fn(|r, c| {
            let v = 0.1 * lcg(&mut s);
            if r == c {
                1.0 + v
            } else {
                v
            }
        });
        let b = SMatrix::<f64, 3, 3>::from_fn(|_, _| lcg(&mut s));
        let q = AttitudeNoise::from_map(&b).expect("finite");
        let mut propagated = ud;
        propagated
            .predict_attitude(&phi_att, &q)
            .expect("positive definite");
        let rows = ud
            .predicted_attitude_rows(&phi_att, &q)
            .expect("positive definite");
        // The factor is not modified, and the rows are the propagated ones.
        assert_eq!(ud, Ud::from_covariance(&p).expect("positive definite"));
        for r in 0..3 {
            for c in r..18 {
                assert_eq!(rows[(r, c)], propagated.packed()[(r, c)], "({r}, {c})");
            }
        }
        for i in 0..18 {
            for j in 0..18 {
                assert_eq!(
                    ud.covariance_entry_with_rows(&rows, i, j),
                    propagated.covariance_entry(i, j),
                    "({i}, {j})"
                );
            }
        }
        assert_eq!(ud.covariance_entry_with_rows(&rows, 18, 0), None);
        assert_eq!(ud.variances_with_rows(&rows), propagated.variances());
    }
}
