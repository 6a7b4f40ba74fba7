//! The continuous-time dynamics of the attitude states and their Jacobian
//! (docs/model.md §Configurations, which also gives M1's first-order
//! form): M1 `ψ̇ = J_r⁻¹(ψ)(G ωc − R(ψ) ωc)`, M2/M3
//! `θ̇A = T(θA)[G ωc − C^p_r R(λ) ω^n_ie]`, M4 `θ̇p = T(θp)[G ωc − C^p_n ω^n_ie]`.
//! The installation parameters are constant: only the attitude rows of the
//! system matrix `F` are not zero.
//!
//! The full model ([`ErrorModel::Full`], docs/model.md §Instrument errors) takes
//! `G [(I + K_g) ωc + dg + D_g f^p]` for `G ωc`, with `f^p = C^p_n f^n`
//! from the attitude state ([`Layout::platform_dcm`]; M1 needs the
//! computed frame `C^c_n` for it). An installation-only layout evaluates
//! exactly the operations it did before the full model existed.

use core::any::TypeId;

use nalgebra::{Matrix3, RealField, SMatrix, Vector3};

use super::blocks::set_cols;
use super::error_model::ErrorModel;
use super::installation::InstallationMatrices;
use super::layout::{AttitudeKind, Layout, ATT, GC, GT};
use super::Environment;
use crate::geometry::{
    d_lower_times, dcm, dcm_deviation, right_jacobian, right_jacobian_inv, skew, EulerTrig,
};

impl Layout {
    /// The attitude-state rate (rad/s) at attitude `att` under commanded rate
    /// `omega_c` (docs/model.md §Configurations): M1 `ψ̇ = J_r⁻¹(ψ)(G ωc − R(ψ) ωc)`;
    /// M2/M3 `θ̇A = T(θA)[G ωc − C^p_r R(λ) ω^n_ie]`;
    /// M4 `θ̇p = T(θp)[G ωc − C^p_n ω^n_ie]`. `None` at gimbal lock.
    ///
    /// `c_cn` is the computed frame `C^c_n` at the same instant: the full
    /// model's M1 needs it for the specific force `f^p = R(ψ) C^c_n f^n` of
    /// the g-sensitive drift (every other case ignores it). For the full
    /// model ([`ErrorModel::Full`]) `G ωc` is `G [(I + K_g) ωc + dg + D_g f^p]`
    /// with the instrument errors of `m.params.instruments`.
    ///
    /// In a precision other than f64 (f32) the commanded rate is kept out of
    /// the rate's small parts: `G u = ωc + s`, `s = ε + (G − I) u` with
    /// `ε = u − ωc` the gyros' errors ([`InstrumentErrors::gyro_error`](super::InstrumentErrors::gyro_error))
    /// and [`InstallationMatrices::g_deviation`], and M1's `G u − R(ψ) ωc`
    /// is `s − (R(ψ) − I) ωc` ([`crate::geometry::dcm_deviation`]). `G ωc`
    /// in f32 rounds `G`'s diagonal (`1 − O(θ²)`, off by up to ≈ 7e-8, as
    /// M1's `R(ψ) ωc` rounds `R(ψ)`'s): a relative error of the commanded
    /// rotation that every period repeats, a torquer scale factor (the
    /// full model's `kg`, docs/estimator.md §"The full model in single
    /// precision"). In f64 the rate is evaluated as written above.
    pub fn attitude_rate<T: RealField + Copy>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        omega_c: &Vector3<T>,
        c_cn: &Matrix3<T>,
    ) -> Option<Vector3<T>> {
        if TypeId::of::<T>() != TypeId::of::<f64>() {
            return self.attitude_rate_single(env, m, att, omega_c, c_cn);
        }
        let w_ip = match self.errors {
            ErrorModel::Installation => m.g * omega_c,
            ErrorModel::Full => m.g * self.gyro_input(env, m, att, omega_c, c_cn),
        };
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

    /// [`Layout::attitude_rate`] in a precision other than f64: `ωc` apart,
    /// the small parts without it (rounded to `ε_J` of themselves, not of
    /// `ωc`).
    fn attitude_rate_single<T: RealField + Copy>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        omega_c: &Vector3<T>,
        c_cn: &Matrix3<T>,
    ) -> Option<Vector3<T>> {
        let small = match self.errors {
            ErrorModel::Installation => m.g_deviation * omega_c,
            ErrorModel::Full => {
                let f_p = self.platform_dcm(att, &m.c_rn, c_cn) * env.gravity_n;
                let e = m.params.instruments.gyro_error(omega_c, &f_p);
                e + m.g_deviation * (omega_c + e)
            }
        };
        match self.attitude {
            AttitudeKind::Misalignment => {
                Some(right_jacobian_inv(att) * (small - dcm_deviation(att) * omega_c))
            }
            AttitudeKind::Gimbal | AttitudeKind::Attitude => {
                let trig = EulerTrig::new(att);
                let t = trig.rate_inverse()?;
                let c_pn = trig.dcm() * m.c_rn;
                Some(t * (omega_c + (small - c_pn * env.earth_rate_n)))
            }
        }
    }

    /// The gyro input `u = (I + K_g) ωc + dg + D_g f^p` (rad/s) of the full
    /// model at attitude `att` (`f^p = C^p_n f^n`, [`Layout::platform_dcm`]
    /// with `c_cn` for M1); the platform rate is `G u`.
    pub fn gyro_input<T: RealField + Copy>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        omega_c: &Vector3<T>,
        c_cn: &Matrix3<T>,
    ) -> Vector3<T> {
        let f_p = self.platform_dcm(att, &m.c_rn, c_cn) * env.gravity_n;
        m.params.instruments.gyro_input(omega_c, &f_p)
    }

    /// `∂(attitude rate)/∂x` (3×N) at state `x`: the rows of the continuous
    /// system matrix `F` that are not zero (parameters are constant). `c_cn`
    /// as in [`Layout::attitude_rate`].
    pub fn attitude_rate_jacobian<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        omega_c: &Vector3<T>,
        c_cn: &Matrix3<T>,
    ) -> Option<SMatrix<T, 3, N>> {
        let mut f = SMatrix::<T, 3, N>::zeros();
        self.attitude_rate_jacobian_into(env, m, att, omega_c, c_cn, &mut f)?;
        Some(f)
    }

    /// [`Layout::attitude_rate_jacobian`] written into `f` (every entry;
    /// `None` at gimbal lock, `f` then unspecified): no 3×N copy of the
    /// result where the caller keeps it.
    ///
    /// For the full model the `G` columns act on the whole gyro input `u`
    /// ([`Layout::gyro_input`]), the attitude (and `λ`) columns gain
    /// `J G D_g ∂f^p/∂(att, λ)` (`J` = `J_r⁻¹(ψ)` or `T(θ)`), and the
    /// instrument columns are `∂/∂dg = J G`, `∂/∂D_g[i][j] = (J G)_i f^p_j`,
    /// `∂/∂kg_i = (J G)_i ωc_i` (`(J G)_i` its column i).
    pub fn attitude_rate_jacobian_into<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        att: &Vector3<T>,
        omega_c: &Vector3<T>,
        c_cn: &Matrix3<T>,
        f: &mut SMatrix<T, 3, N>,
    ) -> Option<()> {
        f.fill(T::zero());
        // The gyro input: ωc itself (installation only: the same value,
        // so the same operations as before), or (I + K_g) ωc + ε.
        let u = match self.errors {
            ErrorModel::Installation => *omega_c,
            ErrorModel::Full => self.gyro_input(env, m, att, omega_c, c_cn),
        };
        // ∂(G u)/∂θgC and ∂(G u)/∂θgT.
        let d_g_c = InstallationMatrices::d_rotation_times(&m.r_g_c, &m.jr_g_c, &(m.unit_g_t * u));
        let d_g_t = m.r_g_c * d_lower_times(&u);
        let w_ip = m.g * u;
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
                let d_att = match self.errors {
                    ErrorModel::Installation => d_att,
                    ErrorModel::Full => {
                        // ∂f^p/∂ψ = [(R(ψ) C^c_n f^n)×] J_r(ψ).
                        let d_fp = skew(&(dcm(att) * (c_cn * env.gravity_n))) * right_jacobian(att);
                        d_att + jinv * m.g * m.params.instruments.d_g * d_fp
                    }
                };
                set_cols(f, ATT, &d_att);
                set_cols(f, GC, &(jinv * d_g_c));
                set_cols(f, GT, &(jinv * d_g_t));
                self.instrument_rate_columns(env, m, &jinv, att, omega_c, c_cn, f);
            }
            AttitudeKind::Gimbal | AttitudeKind::Attitude => {
                let trig = EulerTrig::new(att);
                let t = trig.rate_inverse()?;
                let c = trig.dcm();
                let rl_w = m.c_rn * env.earth_rate_n;
                let w = w_ip - c * rl_w;
                let d_att = trig.d_rate_inverse_times(&t, &w) - t * trig.d_dcm_times(&c, &rl_w);
                // Full model: J G D_g, the map of ∂f^p into the rate.
                let tgd = match self.errors {
                    ErrorModel::Installation => None,
                    ErrorModel::Full => Some(t * m.g * m.params.instruments.d_g),
                };
                let d_att = match (tgd, self.attitude) {
                    (Some(tgd), AttitudeKind::Gimbal) => {
                        d_att + tgd * trig.d_dcm_times(&c, &(m.c_rn * env.gravity_n))
                    }
                    (Some(tgd), _) => d_att + tgd * trig.d_dcm_times(&c, &env.gravity_n),
                    (None, _) => d_att,
                };
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
                    let d_lam = match tgd {
                        None => d_lam,
                        // f^p = C(θA) R(λ) f^n (λ is a state of M2/M3 only).
                        Some(tgd) => {
                            d_lam
                                + tgd
                                    * c
                                    * InstallationMatrices::d_rotation_times(
                                        &m.c_rn,
                                        &m.jr_lambda,
                                        &env.gravity_n,
                                    )
                        }
                    };
                    set_cols(f, il, &d_lam);
                }
                self.instrument_rate_columns(env, m, &t, att, omega_c, c_cn, f);
            }
        }
        Some(())
    }

    /// The full model's instrument columns of `F` (nothing, and no
    /// arithmetic, for an installation-only layout): with `jmap` the rate's
    /// map `J` (`J_r⁻¹(ψ)` or `T(θ)`), `∂/∂dg = ∂/∂δ_g = ∂/∂w_g = J G`,
    /// `∂/∂D_g[i][j] = (J G)_i f^p_j` (row-major), `∂/∂kg_i = (J G)_i ωc_i`.
    #[allow(clippy::too_many_arguments)]
    fn instrument_rate_columns<T: RealField + Copy, const N: usize>(
        &self,
        env: &Environment<T>,
        m: &InstallationMatrices<T>,
        jmap: &Matrix3<T>,
        att: &Vector3<T>,
        omega_c: &Vector3<T>,
        c_cn: &Matrix3<T>,
        f: &mut SMatrix<T, 3, N>,
    ) {
        let (Some(idg), Some(id), Some(ikg), Some(idg_gm), Some(idg_wu)) =
            (self.dg(), self.d_g(), self.kg(), self.dg_gm(), self.dg_wu())
        else {
            return;
        };
        let jg = jmap * m.g;
        let f_p = self.platform_dcm(att, &m.c_rn, c_cn) * env.gravity_n;
        set_cols(f, idg, &jg);
        set_cols(f, idg_gm, &jg);
        set_cols(f, idg_wu, &jg);
        for (i, col) in jg.column_iter().enumerate() {
            let col = col.into_owned();
            let per_force = Matrix3::from_columns(&[col * f_p.x, col * f_p.y, col * f_p.z]);
            set_cols(f, id + 3 * i, &per_force);
        }
        set_cols(f, ikg, &(jg * Matrix3::from_diagonal(omega_c)));
    }
}
