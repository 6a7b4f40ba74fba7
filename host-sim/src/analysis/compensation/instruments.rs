//! The full model's part of the compensation (docs/model.md
//! §Compensation, §Instrument errors): the instruments' own errors in their printed units, the
//! torquer command and the compensated specific force they give, and the
//! covariance of those outputs propagated from the states' covariance.
//!
//! In the configuration's frame p (ps, or pa with `D_g^pa`):
//!
//! - gyros: commanded with `ωc`, the platform turns at
//!   `ω^p_ip = G [(I + K_g) ωc + dg + D_g f^p]` ([`Compensation::platform_rate`],
//!   the core's [`InstrumentErrors::gyro_input`]); so the command that
//!   turns it at a wanted `ω^p` under the specific force `f^p` is
//!   `ωc = (I + K_g)⁻¹ (G⁻¹ ω^p − dg − D_g f^p)`
//!   ([`Compensation::torquer_command`]);
//! - accelerometers: `Z_a = ba + (I + K_a) A f^p` (the core's
//!   [`InstrumentErrors::accel`]); so `f^p = A⁻¹ (I + K_a)⁻¹ (Z_a − ba)`
//!   ([`Compensation::compensate_accel`]).
//!
//! With every instrument error zero (the installation model) these are
//! `G⁻¹ ω^p` and `A⁻¹ Z_a` exactly (`x − 0` and `x / 1` are exact).
//!
//! The σ of a compensated output is that of its first-order error:
//! `J P Jᵀ`, with `J` the derivative of the output with respect to the
//! states at the estimate (central differences with a step of 1 % of each
//! state's σ, over the states the output depends on: the instrument angles
//! and errors; the attitude and `λ` do not enter).

use nalgebra::{Matrix3, Vector3};
use rollcal::models::{ConfigId, ErrorModel, Group, InstrumentErrors};

use super::{finite_or_null, rows, Compensation, Error};

/// The conventions of the full model's `--matrices`, written into its JSON
/// (for [`super::CONVENTIONS`]) and, in words, into its text.
pub const FULL_CONVENTIONS: &str = "Full model: the installation errors and the instruments' \
own errors, in the configuration's platform frame p (ps: the platform cube; pa: the \
accelerometer axes, thaC absorbed into the frame, C^pa_ps = R(-thaC)). Internal units: \
angles rad, rates rad/s, specific force g; printed: deg/h, deg/h/g, ppm, ug. Matrices are \
row-major [[r1],[r2],[r3]]. C^b_a maps a-coordinates to b; R(theta) = exp(-[theta x]) \
(passive, R ~ I - [theta x]); L(t) = [[0,0,0],[t1,0,0],[t2,t3,0]]. \
Gyros: commanded with w_c (the torquer command, gyro axes), the platform turns at \
w^p_ip = G ((I + K_g) w_c + dg + D_g f^p), G = R(thgC)(I + L(thgT)) (pa: R(thgC^pa)), \
K_g = diag(kg) the torquer scale-factor errors, dg the constant drift, D_g the g-sensitive \
drift (row = gyro, column = axis of the specific force f^p in p; in pa D_g^pa = D_g R(thaC)). \
Torquer compensation: to turn the platform at a wanted rate w^p (rad/s, p) under the \
specific force f^p (g, p), command w_c = (I + K_g)^-1 (G^-1 w^p - dg - D_g f^p), i.e. per \
gyro i: w_c_i = ((G^-1 w^p)_i - dg_i - (D_g f^p)_i) / (1 + kg_i) \
(G^-1 = compensation.platform_to_gyro_command, (I + K_g)^-1 = compensation.gyro_scale_inverse, \
dg = compensation.dg_rad_s, D_g = compensation.d_g_rad_s_per_g). \
Accelerometers: Z_a = ba + (I + K_a) A f^p, A = (I + L(thaT)) R(-thaC) (pa: I + L(thaT)), \
ba the bias (g), K_a = diag(ka) the scale-factor errors. Compensation of a raw output: \
f^p = A^-1 (I + K_a)^-1 (Z_a - ba): subtract the bias, divide axis i by 1 + ka_i, apply A^-1 \
(A^-1 = compensation.accel_to_platform, (I + K_a)^-1 = compensation.accel_scale_inverse, \
ba = compensation.ba_g). The f^p of the torquer command may be this compensated output. \
Base (M2, M3): C^r_n = R(lam) (base_dcm). names, estimate_rad, sigma_rad and correlation \
cover the installation states (rad) as with --errors installation; instruments and \
instrument_terms give dg, D_g, kg, ba, ka in their printed units with sigma; all_states \
gives every state's estimate, sigma, covariance and correlation in its internal unit \
(all_states.units).";

/// The installation matrices and instrument errors of one state vector.
#[derive(Clone, Copy, Debug)]
pub(super) struct Params {
    /// `G`.
    pub g: Matrix3<f64>,
    /// `G⁻¹`.
    pub g_inv: Matrix3<f64>,
    /// `A`.
    pub a: Matrix3<f64>,
    /// `A⁻¹`.
    pub a_inv: Matrix3<f64>,
    /// `C^r_n = R(λ)`.
    pub c_rn: Matrix3<f64>,
    /// The instruments' own errors (zero for the installation model).
    pub e: InstrumentErrors<f64>,
}

impl Params {
    /// Of the state vector `x` of `config` with the error model `errors`
    /// (its length checked by the caller: N of the layout).
    pub fn of(config: ConfigId, errors: ErrorModel, x: &[f64]) -> Result<Self, Error> {
        let layout = config.layout_with(errors);
        let m = rollcal::with_model!(config, errors, |M, N, Z| {
            layout.matrices(&nalgebra::SVector::<f64, N>::from_column_slice(x))
        });
        let (Some(g_inv), Some(a_inv)) = (m.g.try_inverse(), m.a.try_inverse()) else {
            return Err(Error::Singular);
        };
        let e = m.params.instruments;
        let positive = |k: &Vector3<f64>| k.iter().all(|v| (1.0 + v) > 0.0);
        if !positive(&e.kg) || !positive(&e.ka) {
            return Err(Error::SingularScale);
        }
        Ok(Self {
            g: m.g,
            g_inv,
            a: m.a,
            a_inv,
            c_rn: m.c_rn,
            e,
        })
    }

    /// `G [(I + K_g) ωc + dg + D_g f^p]`.
    fn platform_rate(&self, w_c: &Vector3<f64>, f_p: &Vector3<f64>) -> Vector3<f64> {
        self.g * self.e.gyro_input(w_c, f_p)
    }

    /// `(I + K_g)⁻¹ (G⁻¹ ω^p − dg − D_g f^p)`.
    fn torquer_command(&self, w_p: &Vector3<f64>, f_p: &Vector3<f64>) -> Vector3<f64> {
        (self.g_inv * w_p - self.e.dg - self.e.d_g * f_p).component_div(&one_plus(&self.e.kg))
    }

    /// `A⁻¹ (I + K_a)⁻¹ (Z_a − ba)`.
    fn specific_force(&self, z: &Vector3<f64>) -> Vector3<f64> {
        self.a_inv * (z - self.e.ba).component_div(&one_plus(&self.e.ka))
    }
}

/// `1 + k` per axis.
fn one_plus(k: &Vector3<f64>) -> Vector3<f64> {
    k.map(|v| 1.0 + v)
}

impl Compensation {
    /// The model's matrices and instrument errors at the estimate.
    fn params(&self) -> Params {
        Params {
            g: self.gyro_matrix,
            g_inv: self.platform_to_gyro_command(),
            a: self.accel_matrix,
            a_inv: self.accel_to_platform(),
            c_rn: self.base_dcm.unwrap_or(Matrix3::identity()),
            e: self.instruments,
        }
    }

    /// The platform rate (rad/s, frame p) that the torquer command `w_c`
    /// (rad/s, gyro axes) gives under the specific force `f_p` (g, frame
    /// p): `G [(I + K_g) ωc + dg + D_g f^p]` (`G ωc` for the installation
    /// model).
    pub fn platform_rate(&self, w_c: &Vector3<f64>, f_p: &Vector3<f64>) -> Vector3<f64> {
        self.params().platform_rate(w_c, f_p)
    }

    /// The torquer command (rad/s, gyro axes) that turns the platform at
    /// the wanted rate `w_p` (rad/s, frame p) under the specific force
    /// `f_p` (g, frame p): `(I + K_g)⁻¹ (G⁻¹ ω^p − dg − D_g f^p)` (`G⁻¹ ω^p`
    /// for the installation model).
    pub fn torquer_command(&self, w_p: &Vector3<f64>, f_p: &Vector3<f64>) -> Vector3<f64> {
        self.params().torquer_command(w_p, f_p)
    }

    /// Compensated specific force (g, frame p) of a raw accelerometer
    /// output `z` (g): `A⁻¹ (I + K_a)⁻¹ (Z_a − ba)` (`A⁻¹ Z_a` for the
    /// installation model).
    pub fn compensate_accel(&self, z: &Vector3<f64>) -> Vector3<f64> {
        self.params().specific_force(z)
    }

    /// `∂out/∂x` at the estimate, one column per state (zero for the
    /// attitude, `λ` and any state of zero σ): central differences with a
    /// step of 1 % of the state's σ. NaN columns where a stepped state
    /// gives a singular model.
    fn jacobian(&self, out: impl Fn(&Params) -> Vector3<f64>) -> Vec<Vector3<f64>> {
        let mut x = self.estimate.clone();
        self.config
            .states_with(self.errors)
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let h = 0.01 * self.sigma[i];
                if matches!(s.group, Group::Attitude | Group::Lambda) || !(h > 0.0 && h.is_finite())
                {
                    return Vector3::zeros();
                }
                let x0 = x[i];
                x[i] = x0 + h;
                let up = Params::of(self.config, self.errors, &x);
                x[i] = x0 - h;
                let down = Params::of(self.config, self.errors, &x);
                x[i] = x0;
                match (up, down) {
                    (Ok(u), Ok(d)) => (out(&u) - out(&d)) / (2.0 * h),
                    _ => Vector3::repeat(f64::NAN),
                }
            })
            .collect()
    }

    /// `J P Jᵀ` of a 3×N Jacobian (columns); None without the covariance.
    fn propagate(&self, j: &[Vector3<f64>]) -> Option<Matrix3<f64>> {
        if !self.covariance_known {
            return None;
        }
        let n = j.len();
        let mut s = Matrix3::zeros();
        for (a, ja) in j
            .iter()
            .enumerate()
            .filter(|(_, v)| **v != Vector3::zeros())
        {
            for (b, jb) in j
                .iter()
                .enumerate()
                .filter(|(_, v)| **v != Vector3::zeros())
            {
                s += ja * jb.transpose() * self.covariance[a * n + b];
            }
        }
        Some(s)
    }

    /// `∂(platform rate)/∂x` (columns, per state) of the command `w_c`
    /// under `f_p` ([`Compensation::platform_rate`]): the residual rate of a
    /// compensated command is this times the states' error
    /// (truth − estimate), to first order.
    pub fn platform_rate_jacobian(
        &self,
        w_c: &Vector3<f64>,
        f_p: &Vector3<f64>,
    ) -> Vec<Vector3<f64>> {
        self.jacobian(|p| p.platform_rate(w_c, f_p))
    }

    /// The covariance ((rad/s)², frame p) of the platform rate that the
    /// command `w_c` gives under `f_p`, from the states' covariance: the
    /// uncertainty of the residual rate `ω^p_true − ω^p` left by the
    /// command [`Compensation::torquer_command`]`(ω^p, f^p)`. None without
    /// the covariance. (The error of `f_p` itself, µg when it comes from
    /// the compensated accelerometers, moves it by `D_g δf`: negligible.)
    pub fn platform_rate_covariance(
        &self,
        w_c: &Vector3<f64>,
        f_p: &Vector3<f64>,
    ) -> Option<Matrix3<f64>> {
        self.propagate(&self.platform_rate_jacobian(w_c, f_p))
    }

    /// `∂(compensated specific force)/∂x` (columns, per state) of the raw
    /// output `z` ([`Compensation::compensate_accel`]): its error is this
    /// times the states' error (estimate − truth), to first order.
    pub fn accel_jacobian(&self, z: &Vector3<f64>) -> Vec<Vector3<f64>> {
        self.jacobian(|p| p.specific_force(z))
    }

    /// The covariance (g², frame p) of the compensated specific force of
    /// the raw output `z`, from the states' covariance (the raw output's
    /// own noise not included). None without the covariance.
    pub fn accel_covariance(&self, z: &Vector3<f64>) -> Option<Matrix3<f64>> {
        self.propagate(&self.accel_jacobian(z))
    }

    /// Index of the first instrument state (`dg_x`), for the full model.
    pub fn instrument_index(&self) -> Option<usize> {
        self.config.layout_with(self.errors).instruments()
    }

    /// The instrument terms in their printed units: `(name, group, unit,
    /// estimate, σ)` per instrument state, in state order (empty for the
    /// installation model).
    pub fn instrument_rows(&self) -> Vec<(&'static str, Group, &'static str, f64, f64)> {
        let Some(i0) = self.instrument_index() else {
            return Vec::new();
        };
        self.config
            .states_with(self.errors)
            .iter()
            .enumerate()
            .skip(i0)
            .map(|(i, s)| {
                let (k, unit) = s.printed_scale();
                (
                    s.name,
                    s.group,
                    unit,
                    self.estimate[i] * k,
                    self.sigma[i] * k,
                )
            })
            .collect()
    }
}

/// The full model's additions to the `--matrices` JSON `v` of `c`
/// ([`Compensation::to_json`]): `errors`, `conventions` =
/// [`FULL_CONVENTIONS`], the compensation's formulas and terms (internal
/// units), `instruments` (per state, printed units), `instrument_terms`
/// (`dg`, `D_g`, `kg`, `ba`, `ka` as vectors and a 3×3, printed units) and
/// `all_states` (every state: names, internal units, estimate, σ,
/// covariance, correlation).
pub fn full_json(c: &Compensation, v: &mut serde_json::Value) {
    let e = &c.instruments;
    let diag_inv = |k: &Vector3<f64>| rows(&Matrix3::from_diagonal(&one_plus(k).map(|v| 1.0 / v)));
    v["errors"] = c.errors.as_str().into();
    v["conventions"] = FULL_CONVENTIONS.into();
    let comp = &mut v["compensation"];
    comp["torquer_command"] = "w_c = (I + K_g)^-1 (G^-1 w^p - dg - D_g f^p)".into();
    comp["specific_force"] = "f^p = A^-1 (I + K_a)^-1 (Z_a - ba)".into();
    comp["gyro_scale_inverse"] = serde_json::json!(diag_inv(&e.kg));
    comp["dg_rad_s"] = serde_json::json!(e.dg.as_slice());
    comp["d_g_rad_s_per_g"] = serde_json::json!(rows(&e.d_g));
    comp["accel_scale_inverse"] = serde_json::json!(diag_inv(&e.ka));
    comp["ba_g"] = serde_json::json!(e.ba.as_slice());
    let list = c.instrument_rows();
    v["instruments"] = list
        .iter()
        .map(|(name, group, unit, est, sigma)| {
            serde_json::json!({
                "name": name,
                "group": group.as_str(),
                "unit": unit,
                "estimate": est,
                "sigma": sigma,
            })
        })
        .collect();
    // The 21 in state order: dg (3), D_g (9, row-major), kg, ba, ka.
    let col = |k: usize, from: usize, len: usize| -> Vec<f64> {
        list.iter()
            .skip(from)
            .take(len)
            .map(|r| if k == 0 { r.3 } else { r.4 })
            .collect()
    };
    let unit = |from: usize| list.get(from).map_or("", |r| r.2);
    let vector = |from: usize| serde_json::json!({"unit": unit(from), "estimate": col(0, from, 3), "sigma": col(1, from, 3)});
    let matrix =
        |k: usize| -> Vec<Vec<f64>> { col(k, 3, 9).chunks(3).map(<[f64]>::to_vec).collect() };
    v["instrument_terms"] = serde_json::json!({
        "dg": vector(0),
        "D_g": {
            "unit": unit(3),
            "frame": c.frame(),
            "rows": "gyro x, y, z",
            "columns": "axis of the specific force in the frame",
            "estimate": matrix(0),
            "sigma": matrix(1),
        },
        "kg": vector(12),
        "ba": vector(15),
        "ka": vector(18),
    });
    let n = c.names.len();
    let states = c.config.states_with(c.errors);
    v["all_states"] = serde_json::json!({
        "names": c.names,
        "units": states.iter().map(|s| s.unit).collect::<Vec<_>>(),
        "estimate": c.estimate,
        "sigma": c.sigma,
        "covariance": c.covariance_known.then(|| {
            c.covariance.chunks(n).map(<[f64]>::to_vec).collect::<Vec<_>>()
        }),
        "correlation": c.correlation.iter()
            .map(|r| r.iter().map(|v| finite_or_null(*v)).collect::<Vec<_>>())
            .collect::<Vec<_>>(),
    });
}

#[cfg(test)]
mod tests {
    use super::super::tests::paper_ps;
    use super::*;

    /// A full M2-ps estimate: the paper's installation, the instrumented
    /// scenario's instrument errors in internal units.
    fn full_m2_ps() -> Vec<f64> {
        const DEG_H: f64 = std::f64::consts::PI / 180.0 / 3600.0;
        let mut x = paper_ps();
        x.extend([0.02, -0.03, 0.015].map(|v| v * DEG_H));
        x.extend([0.03, 0.01, -0.005, -0.01, 0.02, 0.008, 0.006, -0.012, 0.025].map(|v| v * DEG_H));
        x.extend([
            60e-6, -40e-6, 80e-6, 30e-6, -20e-6, 45e-6, 40e-6, -25e-6, 35e-6,
        ]);
        x
    }

    #[test]
    fn the_compensation_inverts_the_core_model() {
        let x = full_m2_ps();
        let n = x.len();
        assert_eq!(n, 39);
        let c = Compensation::with_errors(ConfigId::M2Ps, ErrorModel::Full, &x, &[1e-6; 39], &[])
            .unwrap();
        assert_eq!(c.instruments.kg.z, 80e-6);
        assert_eq!(c.instruments.d_g[(2, 1)], x[18 + 3 + 7]);
        // The core's forward models, inverted.
        let f = Vector3::new(0.3, 0.9, -0.2);
        let z = c.instruments.accel(&(c.accel_matrix * f));
        assert!((c.compensate_accel(&z) - f).amax() < 1e-15);
        let w = Vector3::new(1e-3, -2e-3, 5e-4);
        let w_c = c.torquer_command(&w, &f);
        assert!((c.gyro_matrix * c.instruments.gyro_input(&w_c, &f) - w).amax() < 1e-18);
        assert!((c.platform_rate(&w_c, &f) - w).amax() < 1e-18);
        // A sign of the bias wrong would show: the check can fail.
        let z_wrong = c.accel_matrix * f - c.instruments.ba;
        assert!((c.compensate_accel(&z_wrong) - f).amax() > 1e-5);
        // Without a covariance, no σ.
        assert!(c.accel_covariance(&z).is_none());
    }

    #[test]
    fn with_zero_instrument_errors_the_installation_compensation_bit_for_bit() {
        let x = paper_ps();
        let mut full = x.clone();
        full.extend([0.0; 21]);
        let c = Compensation::new(ConfigId::M2Ps, &x, &[1e-6; 18], &[]).unwrap();
        let d =
            Compensation::with_errors(ConfigId::M2Ps, ErrorModel::Full, &full, &[1e-6; 39], &[])
                .unwrap();
        let (z, w) = (
            Vector3::new(0.1, 0.98, -0.05),
            Vector3::new(1e-3, 2e-4, -3e-4),
        );
        assert_eq!(c.compensate_accel(&z), c.accel_to_platform() * z);
        assert_eq!(d.compensate_accel(&z), c.accel_to_platform() * z);
        assert_eq!(d.torquer_command(&w, &z), c.platform_to_gyro_command() * w);
        assert_eq!(c.torquer_command(&w, &z), c.platform_to_gyro_command() * w);
        assert!(c.instrument_rows().is_empty());
        assert_eq!(d.instrument_rows().len(), 21);
    }

    #[test]
    fn the_propagated_covariance_is_j_p_jt() {
        // A diagonal covariance on ba_x alone: the compensated f_x moves by
        // −δba_x / (1 + ka_x), through A⁻¹.
        let x = full_m2_ps();
        let n = x.len();
        let s = 1e-7;
        let mut p = vec![0.0_f64; n * n];
        let ba = 18 + 15;
        p[ba * n + ba] = s * s;
        let sigma: Vec<f64> = (0..n).map(|i| p[i * n + i].sqrt()).collect();
        let c =
            Compensation::with_errors(ConfigId::M2Ps, ErrorModel::Full, &x, &sigma, &p).unwrap();
        let z = Vector3::new(0.0, 1.0, 0.0);
        let cov = c.accel_covariance(&z).unwrap();
        let col = c.accel_to_platform().column(0) / (1.0 + x[18 + 18]);
        let expect = col * col.transpose() * (s * s);
        assert!((cov - expect).amax() < 1e-6 * s * s, "{cov} {expect}");
        // Every other state has σ = 0: no other column.
        let j = c.accel_jacobian(&z);
        assert!(j
            .iter()
            .enumerate()
            .all(|(i, v)| i == ba || *v == Vector3::zeros()));
        let json = c.to_json();
        assert_eq!(json["errors"], "full");
        assert_eq!(json["names"].as_array().unwrap().len(), 18);
        assert_eq!(json["all_states"]["names"].as_array().unwrap().len(), 39);
        assert_eq!(json["all_states"]["units"][ba], "g");
        assert_eq!(json["instrument_terms"]["ba"]["unit"], "µg");
        assert!((json["instrument_terms"]["ba"]["sigma"][0].as_f64().unwrap() - 0.1).abs() < 1e-12);
        assert!(
            (json["instrument_terms"]["D_g"]["estimate"][2][1]
                .as_f64()
                .unwrap()
                + 0.012)
                .abs()
                < 1e-12
        );
        assert_eq!(json["conventions"], FULL_CONVENTIONS);
    }
}
