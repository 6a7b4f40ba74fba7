//! The second-order terms of the accelerometer measurement, from its
//! analytic Hessian (the cold-start remedy of the filter, [`crate::ekf`]).
//!
//! The accelerometer output at one instant is (paper eqs. 6, 10, 11)
//!
//! `h(x) = A f^p = (I + L(θaT)) R(−θaC) q`,  `q = C^p_n f^n`,
//!
//! with `q = R(ψ) C^c_n f^n` (M1), `C(θA) R(λ) f^n` (M2, M3) or
//! `C(θp) f^n` (M4), `C` the Euler DCM of [`crate::geometry::gimbal_dcm`].
//! Only the attitude, `θaC`, `θaT` and `λ` enter it, so its Hessian
//! `∇²h_a` (`a` = accelerometer axis) lives on at most 12 of the states.
//! Blockwise, with `F_y = ∂(R(−θaC) q)/∂y` and `E_k = ∂L/∂t_k`:
//!
//! - attitude/λ × attitude/λ: `A ∂²q/∂y_k∂y_l`;
//! - `θaC_k` × attitude/λ: `(I + L) [(J_r(−θaC) e_k)×] R(−θaC) ∂q/∂y_l`;
//! - `θaC` × `θaC`: `(I + L) ∂²(R(θ) q)/∂θ_k∂θ_l` at `θ = −θaC`;
//! - `θaT_k` × anything else: `E_k F_y e_l`; `θaT` × `θaT`: 0 (`L` is linear).
//!
//! The terms the filter needs are `½ tr(∇²h_a P)` (the mean) and
//! `½ tr(∇²h_a P ∇²h_b P)` (the covariance, added to the accelerometer
//! noise): with the Hessians restricted to those states, `3 m³`
//! multiplications (`m` = 6, 9 or 12) instead of 24 Jacobian evaluations and
//! `3 N³` of central differences.

use nalgebra::{Matrix3, RealField, SMatrix, Vector3};

use crate::geometry::{d2_dcm_times, d_dcm_times, dcm, gimbal_dcm_partials, skew};
use crate::models::{AttitudeKind, Environment, InstallationMatrices, Layout, ATT};

/// `½ tr(∇²h_a P)` (g) and `½ tr(∇²h_a P ∇²h_b P)` (g²) of the
/// accelerometer output `h` of [`Layout::accel_output`] at the state whose
/// installation matrices are `m` and attitude states `att` (rad), the
/// computed frame `c_cn` (M1), for the state covariance `p` (rad²).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccelSecondOrder<T: RealField + Copy> {
    /// `½ tr(∇²h_a P)`, `a` = accelerometer axis (g).
    pub mean: Vector3<T>,
    /// `½ tr(∇²h_a P ∇²h_b P)` (g²), symmetric.
    pub cov: Matrix3<T>,
}

/// A 3×3 block of second derivatives of `h`: element `k` is the matrix
/// whose column `l` is `∂²h/∂x_{i+k} ∂x_{j+l}`.
type Block<T> = [Matrix3<T>; 3];

/// Where [`Layout::accel_second_order_from`] reads the covariance of the
/// at most 12 states the accelerometer output depends on.
pub trait AccelCovariance<T: RealField + Copy> {
    /// Writes into `p_r` the covariance (rad²) of the `R` states of
    /// `layout`'s accelerometer blocks (the attitude, `θaC`, `θaT` and `λ`
    /// blocks that are states, in that order; [`Layout::accel_covariance`]).
    fn fill<const R: usize>(&self, layout: &Layout, p_r: &mut SMatrix<T, R, R>);
}

/// An [`AccelCovariance`] given by its elements, `P_ij = f(i, j)` (rad²;
/// `None` outside the state).
pub struct Elements<F>(pub F);

impl<T: RealField + Copy, F: Fn(usize, usize) -> Option<T>> AccelCovariance<T> for Elements<F> {
    fn fill<const R: usize>(&self, layout: &Layout, p_r: &mut SMatrix<T, R, R>) {
        layout.accel_covariance(&self.0, p_r);
    }
}

/// The blocks of states `h` depends on: attitude, `θaC`, `θaT`, `λ`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Part {
    Att,
    Ac,
    At,
    Lam,
}

/// `q` and its derivatives with respect to the attitude and `λ`.
struct Platform<T: RealField + Copy> {
    q: Vector3<T>,
    /// `∂q/∂att`, `∂q/∂λ`.
    d_att: Matrix3<T>,
    d_lam: Matrix3<T>,
    /// Second derivatives (see [`Block`]).
    att_att: Block<T>,
    att_lam: Block<T>,
    lam_lam: Block<T>,
}

fn zero_block<T: RealField + Copy>() -> Block<T> {
    [Matrix3::zeros(); 3]
}

fn map_block<T: RealField + Copy>(b: &Block<T>, f: impl Fn(&Matrix3<T>) -> Matrix3<T>) -> Block<T> {
    let [b0, b1, b2] = b;
    [f(b0), f(b1), f(b2)]
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

impl<T: RealField + Copy> Platform<T> {
    /// `q` and its derivatives for `layout`'s attitude kind. Inlined, each
    /// kind out of line: with the layout a constant (the filter's) only its
    /// kind's code is linked, and the temporaries are not in the frame that
    /// keeps the result under the Hessians (firmware stack).
    #[inline(always)]
    fn new(
        layout: &Layout,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
    ) -> Self {
        match layout.attitude {
            AttitudeKind::Misalignment => Self::misalignment(env, att, c_cn),
            AttitudeKind::Attitude => Self::gimbals(env, m, att, None),
            AttitudeKind::Gimbal => Self::gimbals(env, m, att, Some(layout.lam().is_some())),
        }
    }

    /// M1: `q = R(ψ) C^c_n f^n`.
    #[inline(never)]
    fn misalignment(env: &Environment<T>, att: &Vector3<T>, c_cn: &Matrix3<T>) -> Self {
        let w = c_cn * env.gravity_n;
        Self {
            q: dcm(att) * w,
            d_att: d_dcm_times(att, &w),
            d_lam: Matrix3::zeros(),
            att_att: d2_dcm_times(att, &w),
            att_lam: zero_block(),
            lam_lam: zero_block(),
        }
    }

    /// M2–M4: `q = C(θ) u`, `u = R(λ) f^n` when `gimbal` is `Some` (the
    /// gimbal angles are the attitude; `Some(true)`: `λ` is a state), else
    /// `u = f^n`.
    #[inline(never)]
    fn gimbals(
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        gimbal: Option<bool>,
    ) -> Self {
        let g = env.gravity_n;
        let e = gimbal_dcm_partials(att);
        let (u, base) = match gimbal {
            Some(lam) => (m.c_rn * g, lam),
            None => (g, false),
        };
        let [d0, d1, d2] = e.d;
        let [[a00, a01, a02], [_, a11, a12], [_, _, a22]] = e.d2;
        let d_att = Matrix3::from_columns(&[d0 * u, d1 * u, d2 * u]);
        let att_att = [
            Matrix3::from_columns(&[a00 * u, a01 * u, a02 * u]),
            Matrix3::from_columns(&[a01 * u, a11 * u, a12 * u]),
            Matrix3::from_columns(&[a02 * u, a12 * u, a22 * u]),
        ];
        let (d_lam, att_lam, lam_lam) = if base {
            let lam = &m.params.lambda;
            let d1_lam = InstallationMatrices::d_rotation_times(&m.c_rn, &m.jr_lambda, &g);
            (
                e.c * d1_lam,
                [d0 * d1_lam, d1 * d1_lam, d2 * d1_lam],
                map_block(&d2_dcm_times(lam, &g), |b| e.c * b),
            )
        } else {
            (Matrix3::zeros(), zero_block(), zero_block())
        };
        Self {
            q: e.c * u,
            d_att,
            d_lam,
            att_att,
            att_lam,
            lam_lam,
        }
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
    /// The parts of the state the accelerometer output depends on, in state
    /// order, with their first state index.
    fn accel_parts(&self) -> [Option<(Part, usize)>; 4] {
        let lam = match self.attitude {
            AttitudeKind::Gimbal => self.lam().map(|i| (Part::Lam, i)),
            _ => None,
        };
        [
            Some((Part::Att, ATT)),
            self.ac().map(|i| (Part::Ac, i)),
            Some((Part::At, self.at())),
            lam,
        ]
    }

    /// The parts of [`Layout::accel_parts`] that are states, each with the
    /// local index of its first state (in the Hessians and in the
    /// covariance of [`AccelCovariance::fill`]) and its state index; and how
    /// many there are.
    fn accel_blocks(&self) -> ([(Part, usize, usize); 4], usize) {
        let mut at = [(Part::Att, 0usize, 0usize); 4];
        let mut count = 0;
        for ((part, state), slot) in self.accel_parts().iter().flatten().zip(at.iter_mut()) {
            *slot = (*part, 3 * count, *state);
            count += 1;
        }
        (at, count)
    }

    /// The second-order terms of the accelerometer output
    /// ([`AccelSecondOrder`]) from its analytic Hessian. `p` is the state
    /// covariance (rad²), `m`, `att` and `c_cn` as for
    /// [`Layout::accel_jacobian`].
    pub fn accel_second_order<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
        p: &SMatrix<T, N, N>,
    ) -> AccelSecondOrder<T> {
        self.accel_second_order_with(env, m, att, c_cn, |i, j| p.get((i, j)).copied())
    }

    /// [`Layout::accel_second_order`] with the covariance given by its
    /// elements, `p(i, j) = P_ij` (rad²; `None` outside the state): only
    /// those of the at most 12 states the accelerometer output depends on
    /// are read (e.g. from the U-D factor, [`crate::factor::Ud::covariance_entry`],
    /// without forming `P`).
    pub fn accel_second_order_with<T: RealField + Copy>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
        p: impl Fn(usize, usize) -> Option<T>,
    ) -> AccelSecondOrder<T> {
        self.accel_second_order_from(env, m, att, c_cn, &Elements(p))
    }

    /// Writes into `p_r` the covariance of the `R` states the accelerometer
    /// output depends on ([`AccelCovariance::fill`]) from its elements,
    /// `p(i, j) = P_ij` (rad²; `None` outside the state, leaving the
    /// element as it was): each read once, on or above the diagonal, and
    /// mirrored.
    pub fn accel_covariance<T: RealField + Copy, const R: usize>(
        &self,
        p: impl Fn(usize, usize) -> Option<T>,
        p_r: &mut SMatrix<T, R, R>,
    ) {
        let (at, count) = self.accel_blocks();
        let at = at.get(..count).unwrap_or(&[]);
        // The state index of local index `i` (block `i / 3`, element `i % 3`).
        let state = |i: usize| at.get(i / 3).map(|&(_, _, s)| s + i % 3);
        for c in 0..R {
            for r in 0..=c {
                let (Some(si), Some(sj)) = (state(r), state(c)) else {
                    continue;
                };
                if let Some(v) = p(si, sj) {
                    if let Some(dst) = p_r.get_mut((r, c)) {
                        *dst = v;
                    }
                    if let Some(dst) = p_r.get_mut((c, r)) {
                        *dst = v;
                    }
                }
            }
        }
    }

    /// [`Layout::accel_second_order`] with the covariance of the states the
    /// output depends on from `source`, which the filter fills in a frame
    /// of its own, returned before the Hessians are formed (firmware
    /// stack). Inlined, as is the size's part: with the layout a constant
    /// (the filter's) one size is left, and the platform's derivatives are
    /// in the caller's frame, not in one more above the Hessians'.
    #[inline(always)]
    pub fn accel_second_order_from<T: RealField + Copy>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
        source: &impl AccelCovariance<T>,
    ) -> AccelSecondOrder<T> {
        // (Folds to one size when the layout is a constant.)
        match self.accel_parts().iter().flatten().count() {
            2 => self.accel_second_order_sized::<T, 6>(env, m, att, c_cn, source),
            3 => self.accel_second_order_sized::<T, 9>(env, m, att, c_cn, source),
            _ => self.accel_second_order_sized::<T, 12>(env, m, att, c_cn, source),
        }
    }

    /// [`Layout::accel_second_order_from`] for `R` states.
    #[inline(always)]
    fn accel_second_order_sized<T: RealField + Copy, const R: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        c_cn: &Matrix3<T>,
        source: &impl AccelCovariance<T>,
    ) -> AccelSecondOrder<T> {
        let mut p_r = SMatrix::<T, R, R>::zeros();
        source.fill(self, &mut p_r);
        // The platform's derivatives and the θaC curvature here, not in
        // `second_order_terms`: their frames (and their trigonometry) are
        // then not nested below the Hessians' (firmware stack).
        let platform = Platform::new(self, env, m, att, c_cn);
        let ac_ac = self
            .ac()
            .is_some()
            .then(|| d2_dcm_times(&-m.params.theta_a_c, &platform.q));
        let (at, count) = self.accel_blocks();
        let at = at.get(..count).unwrap_or(&[]);
        self.second_order_terms::<T, R>(m, &platform, &ac_ac, &p_r, at)
    }

    /// [`Layout::accel_second_order`] with the Hessians on the `R` states of
    /// `at` ([`Layout::accel_blocks`]), from the platform's `q` and its
    /// derivatives, and the covariance `p_r` of those states. Out of line:
    /// the three sizes' frames would otherwise add up in
    /// [`Layout::accel_second_order_from`]'s.
    #[inline(never)]
    fn second_order_terms<T: RealField + Copy, const R: usize>(
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

#[cfg(test)]
mod tests {
    use nalgebra::{SMatrix, SVector};

    use crate::geometry::{earth_rate_n, gravity_n, EARTH_RATE};
    use crate::models::{AttitudeKind, ConfigId, Environment};

    /// A deterministic pseudo-random sequence in (−1, 1).
    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    /// The analytic terms against central differences of the analytic
    /// Jacobian (`ekf::hessian_terms`) at a state far from zero, for a
    /// dense covariance.
    fn check<const N: usize>(id: ConfigId, seed: u64) -> Result<(), &'static str> {
        let layout = id.layout();
        let mut s = seed;
        let env = Environment {
            earth_rate_n: earth_rate_n(EARTH_RATE, 0.6),
            gravity_n: gravity_n(),
        };
        let mut x = SVector::<f64, N>::zeros();
        for v in x.iter_mut() {
            // Installation angles up to 0.05 rad: past the series branch
            // of d_right_jacobian (0.1 rad in |θ|) for some of them.
            *v = 0.05 * lcg(&mut s);
        }
        let att_scale = match layout.attitude {
            AttitudeKind::Misalignment => 0.1,
            _ => 1.3,
        };
        for v in x.iter_mut().take(3) {
            *v = att_scale * lcg(&mut s);
        }
        let c_cn = crate::geometry::gimbal_dcm(&nalgebra::Vector3::new(0.4, -0.7, 2.0));
        let mut a = SMatrix::<f64, N, N>::zeros();
        for v in a.iter_mut() {
            *v = 0.01 * lcg(&mut s);
        }
        let p = a * a.transpose() + SMatrix::<f64, N, N>::identity() * 1e-6;
        let m = layout.matrices(&x);
        let att = layout.attitude(&x);
        let analytic = layout.accel_second_order(&env, &m, &att, &c_cn, &p);
        let relevant = |j: usize| {
            j < 3
                || layout.ac().is_some_and(|i| (i..i + 3).contains(&j))
                || (layout.at()..layout.at() + 3).contains(&j)
                || layout.lam().is_some_and(|i| (i..i + 3).contains(&j))
        };
        let (mean, cov) = crate::ekf::hessian_terms(&x, &p, relevant, |xp| {
            Some(layout.accel_jacobian(&env, &layout.matrices(xp), &layout.attitude(xp), &c_cn))
        })
        .ok_or("central differences of the Jacobian failed at the test point")?;
        let scale_m = mean.amax();
        let scale_c = cov.amax();
        assert!(scale_m > 1e-6 && scale_c > 1e-10, "{id}: degenerate test");
        let dm = (analytic.mean - mean).amax() / scale_m;
        let dc = (analytic.cov - cov).amax() / scale_c;
        // Printed with --nocapture; measured ≤ 4.8e-11 (the differences' own error).
        extern crate std;
        std::eprintln!("{id} seed {seed}: analytic vs differences: mean {dm:.1e}, cov {dc:.1e}");
        assert!(
            dm < 1e-8 && dc < 1e-8,
            "{id} seed {seed}: mean {dm:.2e}, cov {dc:.2e}"
        );
        // Symmetric, as a covariance must be.
        assert_eq!(analytic.cov, analytic.cov.transpose());
        Ok(())
    }

    #[test]
    fn analytic_hessian_matches_central_differences() -> Result<(), &'static str> {
        for seed in 1..=5 {
            check::<12>(ConfigId::M1Pa, seed)?;
            check::<15>(ConfigId::M1Ps, seed)?;
            check::<18>(ConfigId::M2Ps, seed)?;
            check::<15>(ConfigId::M3Pa, seed)?;
            check::<18>(ConfigId::M3Ps, seed)?;
            check::<12>(ConfigId::M4Pa, seed)?;
            check::<15>(ConfigId::M4Ps, seed)?;
        }
        Ok(())
    }

    /// The exact and series branches of `d_right_jacobian` agree where they
    /// meet, and match central differences of `right_jacobian`.
    #[test]
    fn d_right_jacobian_matches_differences() {
        use crate::geometry::{d_right_jacobian, right_jacobian};
        for theta in [
            nalgebra::Vector3::new(0.0999, 0.003, -0.002),
            nalgebra::Vector3::new(0.1001, 0.003, -0.002),
            nalgebra::Vector3::new(1e-3, -2e-3, 5e-4),
            nalgebra::Vector3::new(0.7, -1.1, 0.4),
        ] {
            let d = d_right_jacobian(&theta);
            for (k, dk) in d.iter().enumerate() {
                let mut e = nalgebra::Vector3::zeros();
                e[k] = 1e-4;
                let fd = (right_jacobian(&(theta + e)) - right_jacobian(&(theta - e))) / 2e-4;
                let err = (dk - fd).amax();
                assert!(err < 1e-8, "θ = {theta:?}, k = {k}: {err:.2e}");
            }
        }
    }
}
