//! The continuous-time dynamics of the attitude states and their Jacobian
//! (docs/model.md §Configurations, paper §1.3; M1's first-order form is
//! paper eq. 11): M1 `ψ̇ = J_r⁻¹(ψ)(G ωc − R(ψ) ωc)`, M2/M3
//! `θ̇A = T(θA)[G ωc − C^p_r R(λ) ω^n_ie]`, M4 `θ̇p = T(θp)[G ωc − C^p_n ω^n_ie]`.
//! The installation parameters are constant: only the attitude rows of the
//! system matrix `F` are not zero.

use nalgebra::{RealField, SMatrix, Vector3};

use super::blocks::set_cols;
use super::installation::InstallationMatrices;
use super::layout::{AttitudeKind, Layout, ATT, GC, GT};
use super::Environment;
use crate::geometry::{d_lower_times, dcm, right_jacobian, right_jacobian_inv, skew, EulerTrig};

impl Layout {
    /// The attitude-state rate (rad/s) at attitude `att` under commanded rate
    /// `omega_c` (docs/model.md §Configurations): M1 `ψ̇ = J_r⁻¹(ψ)(G ωc − R(ψ) ωc)`;
    /// M2/M3 `θ̇A = T(θA)[G ωc − C^p_r R(λ) ω^n_ie]`;
    /// M4 `θ̇p = T(θp)[G ωc − C^p_n ω^n_ie]`. `None` at gimbal lock.
    pub fn attitude_rate<T: RealField + Copy>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        omega_c: &Vector3<T>,
    ) -> Option<Vector3<T>> {
        let w_ip = m.g * omega_c;
        match self.attitude {
            AttitudeKind::Misalignment => {
                Some(right_jacobian_inv(att) * (w_ip - dcm(att) * omega_c))
            }
            AttitudeKind::Gimbal | AttitudeKind::Attitude => {
                let trig = EulerTrig::new(att);
                let t = trig.rate_inverse()?;
                let c_pn = trig.dcm() * m.c_rn;
                Some(t * (w_ip - c_pn * env.earth_rate_n))
            }
        }
    }

    /// `∂(attitude rate)/∂x` (3×N) at state `x`: the rows of the continuous
    /// system matrix `F` that are not zero (parameters are constant).
    pub fn attitude_rate_jacobian<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        omega_c: &Vector3<T>,
    ) -> Option<SMatrix<T, 3, N>> {
        let mut f = SMatrix::<T, 3, N>::zeros();
        self.attitude_rate_jacobian_into(env, m, att, omega_c, &mut f)?;
        Some(f)
    }

    /// [`Layout::attitude_rate_jacobian`] written into `f` (every entry;
    /// `None` at gimbal lock, `f` then unspecified): no 3×N copy of the
    /// result where the caller keeps it.
    pub fn attitude_rate_jacobian_into<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        omega_c: &Vector3<T>,
        f: &mut SMatrix<T, 3, N>,
    ) -> Option<()> {
        f.fill(T::zero());
        // ∂(G ωc)/∂θgC and ∂(G ωc)/∂θgT.
        let d_g_c =
            InstallationMatrices::d_rotation_times(&m.r_g_c, &m.jr_g_c, &(m.unit_g_t * omega_c));
        let d_g_t = m.r_g_c * d_lower_times(omega_c);
        let w_ip = m.g * omega_c;
        match self.attitude {
            AttitudeKind::Misalignment => {
                let jinv = right_jacobian_inv(att);
                let r_wc = dcm(att) * omega_c;
                let w_cp = w_ip - r_wc;
                // ∂(J_r⁻¹(ψ) w)/∂ψ to second order: −½[w×] − (1/12)([(ψ×w)×] + [ψ×][w×]).
                let two: T = nalgebra::convert(2.0);
                let twelve: T = nalgebra::convert(12.0);
                let d_jinv = -skew(&w_cp) / two
                    - (skew(&att.cross(&w_cp)) + skew(att) * skew(&w_cp)) / twelve;
                let d_att = d_jinv - jinv * skew(&r_wc) * right_jacobian(att);
                set_cols(f, ATT, &d_att);
                set_cols(f, GC, &(jinv * d_g_c));
                set_cols(f, GT, &(jinv * d_g_t));
            }
            AttitudeKind::Gimbal | AttitudeKind::Attitude => {
                let trig = EulerTrig::new(att);
                let t = trig.rate_inverse()?;
                let c = trig.dcm();
                let rl_w = m.c_rn * env.earth_rate_n;
                let w = w_ip - c * rl_w;
                let d_att = trig.d_rate_inverse_times(&t, &w) - t * trig.d_dcm_times(&c, &rl_w);
                set_cols(f, ATT, &d_att);
                set_cols(f, GC, &(t * d_g_c));
                set_cols(f, GT, &(t * d_g_t));
                if let Some(il) = self.lam() {
                    let d_lam = -(t
                        * c
                        * InstallationMatrices::d_rotation_times(
                            &m.c_rn,
                            &m.jr_lambda,
                            &env.earth_rate_n,
                        ));
                    set_cols(f, il, &d_lam);
                }
            }
        }
        Some(())
    }
}
