//! The second-order terms of the accelerometer measurement, from its
//! analytic Hessian (the cold-start remedy of the filter, [`crate::ekf`]).
//!
//! The accelerometer output at one instant is (docs/model.md §Installation
//! models, §Configurations)
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
//!
//! The full model (docs/model.md §Instrument errors, `Z_a = ba + (I + K_a) h`) is linear in `ba`
//! and `ka`: its terms here are those of the installation output `h` alone.
//! Left out are the factor `1 + ka` (≤ 1e-3 of the terms) and the Hessian
//! blocks `ka_a × y` (`= ∂h_a/∂y`), whose share of the covariance term,
//! ≈ σ_ka² σ_att² |∂h/∂att|² ≈ 3e-10 g² at the default priors (1000 ppm,
//! 1°), is ≈ 0.6 % of the attitude's own (≈ ½ σ_att⁴ ≈ 5e-8 g²) at a cold
//! start and falls with it.
//!
//! Files: `platform` (`q` and its derivatives for each attitude kind),
//! `hessian` (the Hessian blocks and the traces); this one holds the
//! public entry points on [`Layout`] and which states are involved.

mod hessian;
mod platform;

use nalgebra::{Matrix3, RealField, SMatrix, Vector3};

use crate::geometry::d2_dcm_times;
use crate::models::{AttitudeKind, Environment, InstallationMatrices, Layout, ATT};
use hessian::Part;
use platform::Platform;

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
    /// are read (e.g. from the filter's U-D factor, element by element,
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
        let (mean, cov) = crate::ekf::predict::hessian_terms(&x, &p, relevant, |xp| {
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
