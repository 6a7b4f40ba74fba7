//! Results a user can apply (docs/model.md §Compensation): from a final
//! estimate (state, covariance, configuration) the calibrated installation
//! matrices, the compensation of the raw instrument outputs, the base DCM
//! and the parameters' σ and correlation matrix.
//!
//! The installation model (docs/model.md §Installation models) is
//!
//! - gyros: the platform is torqued so that each gyro follows its command,
//!   and the platform turns at `ω^p_ip = G ω_g`, `G = R(θgC)(I + L(θgT))`,
//!   where `ω_g` is the gyro triad's rate (the torquing command `ωc`, in
//!   gyro axes);
//! - accelerometers: `Z_a = A f^p`, `A = (I + L(θaT)) R(−θaC)`.
//!
//! So the compensation is `ω^p_ip = G ω_g` (gyro rates into the platform
//! frame), `ωc = G⁻¹ ω^p_wanted` (the command that turns the platform at a
//! wanted rate), and `f^p = A⁻¹ Z_a` (accelerometer outputs into the
//! platform frame). `G` and `A` are rollcal's
//! [`rollcal::instruments::gyro_matrix`] and
//! [`rollcal::instruments::accel_matrix`], evaluated by
//! [`rollcal::models::Layout::matrices`].
//!
//! In a pa configuration the frame p is pa, defined by the accelerometer
//! axes: `θaC` is absorbed into the frame (`C^pa_ps = R(−θaC)`, not
//! estimated), `A = I + L(θaT)` and `G = R(θgC^pa)(I + L(θgT))`; the
//! compensated outputs are in pa coordinates.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use rollcal::geometry::rotation_vector;
use rollcal::models::{ConfigId, Group, PlatformFrame};

/// The short statement of conventions written into the JSON and the text.
pub const CONVENTIONS: &str = "Angles in rad. Matrices are row-major [[r1],[r2],[r3]]. \
C^b_a maps a-coordinates to b; R(theta) = exp(-[theta x]) (passive, R ~ I - [theta x]); \
L(t) = [[0,0,0],[t1,0,0],[t2,t3,0]]. Gyros: the platform turns at w^p_ip = G w_g, \
G = R(thgC)(I + L(thgT)), w_g = the gyro triad's rate (its torquing command); \
compensation: w^p = gyro_to_platform * w_g, and the command for a wanted platform rate \
is w_g = platform_to_gyro_command * w^p (= G^-1). Accelerometers: Z_a = A f^p, \
A = (I + L(thaT)) R(-thaC); compensation: f^p = accel_to_platform * Z_a (= A^-1). \
Base (M2, M3): C^r_n = R(lam) (base_dcm). In the pa frame (accelerometer axes) thaC is \
absorbed into the frame definition (C^pa_ps = R(-thaC), not estimated), A = I + L(thaT) \
and G uses thgC^pa.";

/// A final estimate turned into what a user applies.
#[derive(Clone, Debug, PartialEq)]
pub struct Compensation {
    /// The configuration.
    pub config: ConfigId,
    /// State names ([`ConfigId::states`]), in state order.
    pub names: Vec<&'static str>,
    /// Estimate of every state (rad).
    pub estimate: Vec<f64>,
    /// σ of every state, `√P_ii` (rad).
    pub sigma: Vec<f64>,
    /// Correlation matrix `P_ij / (σ_i σ_j)` (row-major rows; NaN where
    /// the covariance is unknown).
    pub correlation: Vec<Vec<f64>>,
    /// Whether the covariance was known (else `sigma` came alone and the
    /// correlation is NaN off the diagonal).
    pub covariance_known: bool,
    /// Calibrated gyro installation matrix `G`.
    pub gyro_matrix: Matrix3<f64>,
    /// Calibrated accelerometer installation matrix `A`.
    pub accel_matrix: Matrix3<f64>,
    /// Base mounting DCM `C^r_n = R(λ)` (M2, M3).
    pub base_dcm: Option<Matrix3<f64>>,
}

/// Why a compensation cannot be built.
#[derive(Clone, Debug, PartialEq)]
pub enum Error {
    /// `estimate` or `sigma` does not have one value per state, or the
    /// covariance is neither empty nor N×N.
    Dimension {
        /// Expected states.
        expected: usize,
        /// What was found (estimate, sigma, covariance lengths).
        found: (usize, usize, usize),
    },
    /// A matrix cannot be inverted (an absurd estimate).
    Singular,
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Error::Dimension { expected, found } => write!(
                f,
                "{expected} states expected, found estimate {}, sigma {}, covariance {}",
                found.0, found.1, found.2
            ),
            Error::Singular => f.write_str("an installation matrix is singular"),
        }
    }
}

impl Compensation {
    /// From a final estimate: `estimate` and `sigma` (rad, N values) and the
    /// row-major covariance (rad², N·N values, or empty when unknown).
    pub fn new(
        config: ConfigId,
        estimate: &[f64],
        sigma: &[f64],
        covariance: &[f64],
    ) -> Result<Self, Error> {
        let n = config.layout().n();
        if estimate.len() != n
            || sigma.len() != n
            || !(covariance.is_empty() || covariance.len() == n * n)
        {
            return Err(Error::Dimension {
                expected: n,
                found: (estimate.len(), sigma.len(), covariance.len()),
            });
        }
        let m = rollcal::with_config!(config, |M, N, Z| {
            let x = nalgebra::SVector::<f64, N>::from_column_slice(estimate);
            config.layout().matrices(&x)
        });
        let correlation = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| match covariance.get(i * n + j) {
                        Some(p) if i != j => p / (sigma[i] * sigma[j]),
                        _ if i == j => 1.0,
                        _ => f64::NAN,
                    })
                    .collect()
            })
            .collect();
        let c = Self {
            config,
            names: config.states().iter().map(|s| s.name).collect(),
            estimate: estimate.to_vec(),
            sigma: sigma.to_vec(),
            correlation,
            covariance_known: !covariance.is_empty(),
            gyro_matrix: m.g,
            accel_matrix: m.a,
            base_dcm: config.layout().base.then_some(m.c_rn),
        };
        if c.gyro_matrix.try_inverse().is_none() || c.accel_matrix.try_inverse().is_none() {
            return Err(Error::Singular);
        }
        Ok(c)
    }

    /// The platform frame of the matrices: `"ps"` or `"pa"`.
    pub fn frame(&self) -> &'static str {
        match self.config.layout().frame {
            PlatformFrame::Ps => "ps",
            PlatformFrame::Pa => "pa",
        }
    }

    /// `ω^p_ip = G ω_g`: the gyro triad's rate into the platform frame (= G).
    pub fn gyro_to_platform(&self) -> Matrix3<f64> {
        self.gyro_matrix
    }

    /// `ω_g = G⁻¹ ω^p`: the gyro command for a wanted platform rate.
    pub fn platform_to_gyro_command(&self) -> Matrix3<f64> {
        self.gyro_matrix.try_inverse().unwrap_or(Matrix3::zeros())
    }

    /// `f^p = A⁻¹ Z_a`: accelerometer outputs into the platform frame.
    pub fn accel_to_platform(&self) -> Matrix3<f64> {
        self.accel_matrix.try_inverse().unwrap_or(Matrix3::zeros())
    }

    /// Compensated platform rate `G ω_g` of a gyro rate `omega_g`.
    pub fn compensate_gyro(&self, omega_g: &Vector3<f64>) -> Vector3<f64> {
        self.gyro_to_platform() * omega_g
    }

    /// Compensated specific force `A⁻¹ Z_a` of an accelerometer output `z`.
    pub fn compensate_accel(&self, z: &Vector3<f64>) -> Vector3<f64> {
        self.accel_to_platform() * z
    }

    /// The installation parameters (not the attitude) left after applying
    /// this compensation to instruments whose true matrices (in this
    /// configuration's frame) are `g_true`, `a_true` and, with a base,
    /// `base_true` = `R(λ)`: [`residual_angles`] of the residual
    /// installations. One value per state, in state order, NaN for the
    /// attitude states.
    pub fn residual(
        &self,
        g_true: &Matrix3<f64>,
        a_true: &Matrix3<f64>,
        base_true: Option<&Matrix3<f64>>,
    ) -> Vec<f64> {
        // The compensated triads: commanded with G⁻¹ the platform turns at
        // G_true G⁻¹ ω; compensated with A⁻¹ the accelerometers read
        // A⁻¹ A_true f^p.
        let g_res = g_true * self.platform_to_gyro_command();
        let a_res = self.accel_to_platform() * a_true;
        let (gc, gt) = residual_angles(&g_res, Triad::Gyro);
        let (ac, at) = residual_angles(&a_res, Triad::Accel);
        let lam = match (base_true, self.base_dcm) {
            (Some(t), Some(e)) => rotation_vector(&(t * e.transpose())),
            _ => Vector3::repeat(f64::NAN),
        };
        let mut count = [0usize; 6];
        self.config
            .states()
            .iter()
            .map(|s| {
                let (v, k) = match s.group {
                    // The instrument errors of the full model are no
                    // installation residual (`states()` has none of them).
                    Group::Attitude
                    | Group::GyroDrift
                    | Group::GyroGDrift
                    | Group::GyroScale
                    | Group::AccelBias
                    | Group::AccelScale => (Vector3::repeat(f64::NAN), 0),
                    Group::ThetaGC => (gc, 1),
                    Group::ThetaGT => (gt, 2),
                    Group::ThetaAC => (ac, 3),
                    Group::ThetaAT => (at, 4),
                    Group::Lambda => (lam, 5),
                };
                let i = count[k];
                count[k] += 1;
                v[i.min(2)]
            })
            .collect()
    }

    /// The JSON document of `--matrices`.
    pub fn to_json(&self) -> serde_json::Value {
        let m = |a: &Matrix3<f64>| -> Vec<[f64; 3]> {
            (0..3).map(|i| [a[(i, 0)], a[(i, 1)], a[(i, 2)]]).collect()
        };
        let finite_or_null = |v: f64| {
            if v.is_finite() {
                serde_json::json!(v)
            } else {
                serde_json::Value::Null
            }
        };
        serde_json::json!({
            "config": self.config.as_str(),
            "frame": self.frame(),
            "conventions": CONVENTIONS,
            "gyro_matrix": m(&self.gyro_matrix),
            "accel_matrix": m(&self.accel_matrix),
            "compensation": {
                "gyro_to_platform": m(&self.gyro_to_platform()),
                "platform_to_gyro_command": m(&self.platform_to_gyro_command()),
                "accel_to_platform": m(&self.accel_to_platform()),
            },
            "base_dcm": self.base_dcm.as_ref().map(&m),
            "names": self.names,
            "estimate_rad": self.estimate,
            "sigma_rad": self.sigma,
            "covariance_known": self.covariance_known,
            "correlation": self.correlation.iter()
                .map(|r| r.iter().map(|v| finite_or_null(*v)).collect::<Vec<_>>())
                .collect::<Vec<_>>(),
        })
    }

    /// The readable text report: matrices, how to apply them, the
    /// parameters with σ, and the strongest correlations. States whose σ
    /// is at least 1 % of `prior_sigma` (rad) are marked as not determined.
    pub fn text(&self, prior_sigma: f64) -> String {
        use std::fmt::Write;
        const ARCSEC: f64 = std::f64::consts::PI / (180.0 * 3600.0);
        let mut t = String::new();
        let frame = self.frame();
        let _ = writeln!(
            t,
            "Calibration result, {} (platform frame {frame}{})",
            self.config,
            if frame == "pa" {
                ": the accelerometer axes; θaC is absorbed into the frame"
            } else {
                ": the platform cube"
            }
        );
        let mat = |t: &mut String, name: &str, a: &Matrix3<f64>| {
            let _ = writeln!(t, "  {name}");
            for i in 0..3 {
                let _ = writeln!(
                    t,
                    "    [{:>19.15} {:>19.15} {:>19.15}]",
                    a[(i, 0)],
                    a[(i, 1)],
                    a[(i, 2)]
                );
            }
        };
        mat(
            &mut t,
            if frame == "pa" {
                "G = R(θgC^pa)(I + L(θgT))  (gyros)"
            } else {
                "G = R(θgC)(I + L(θgT))  (gyros)"
            },
            &self.gyro_matrix,
        );
        mat(
            &mut t,
            &if frame == "pa" {
                "A = I + L(θaT)  (accelerometers)".to_string()
            } else {
                "A = (I + L(θaT)) R(−θaC)  (accelerometers)".to_string()
            },
            &self.accel_matrix,
        );
        let _ = writeln!(t, "Apply:");
        let _ = writeln!(
            t,
            "  gyro rate ω_g (its torquing command) into the platform: ω^{frame}_ip = G ω_g"
        );
        mat(
            &mut t,
            "G⁻¹: the command for a wanted platform rate, ω_g = G⁻¹ ω^p",
            &self.platform_to_gyro_command(),
        );
        mat(
            &mut t,
            "A⁻¹: accelerometer output into the platform, f^p = A⁻¹ Z_a",
            &self.accel_to_platform(),
        );
        if let Some(b) = &self.base_dcm {
            mat(&mut t, "C^r_n = R(λ)  (base mounting)", b);
        }
        let _ = writeln!(t, "Parameters (″; attitude states at the final time):");
        let _ = writeln!(t, "  {:<11} {:>12} {:>10}", "state", "estimate ″", "σ ″");
        for (i, name) in self.names.iter().enumerate() {
            let note = if self.sigma[i] >= 0.01 * prior_sigma {
                "  not determined (σ ≥ 1 % of the prior)"
            } else {
                ""
            };
            let _ = writeln!(
                t,
                "  {:<11} {:>12.3} {:>10.4}{note}",
                name,
                self.estimate[i] / ARCSEC,
                self.sigma[i] / ARCSEC
            );
        }
        if self.covariance_known {
            let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
            for i in 0..self.names.len() {
                for j in 0..i {
                    pairs.push((self.correlation[i][j], i, j));
                }
            }
            pairs.sort_by(|a, b| b.0.abs().total_cmp(&a.0.abs()));
            let _ = writeln!(t, "Strongest correlations (full matrix in the JSON):");
            for (r, i, j) in pairs.iter().take(5) {
                let _ = writeln!(
                    t,
                    "  {:<11} {:<11} {:>+7.3}",
                    self.names[*i], self.names[*j], r
                );
            }
        } else {
            let _ = writeln!(t, "Correlations: not available (σ only).");
        }
        t
    }
}

/// The compensation of a run's final estimate and covariance.
pub fn of_run(r: &crate::analysis::runner::RunResult) -> Result<Compensation, Error> {
    let est: Vec<f64> = r.states.iter().map(|s| s.estimate_rad).collect();
    let sig: Vec<f64> = r.states.iter().map(|s| s.sigma_rad).collect();
    Compensation::new(r.config, &est, &sig, &r.covariance)
}

/// Which triad's model a residual matrix follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Triad {
    /// `G = R(c)(I + L(t)) ≈ I − [c×] + L(t)`.
    Gyro,
    /// `A = (I + L(t)) R(−c) ≈ I + [c×] + L(t)`.
    Accel,
}

/// The misalignment `c` and non-orthogonality `t` (rad) of a near-identity
/// installation matrix `e` of the given triad's model, to first order:
/// with `X = e − I`, the upper triangle of `X` is the rotation part alone
/// and `t_k` is the sum of the two mirrored entries
/// (`t = (X21 + X12, X31 + X13, X32 + X23)`). Exact to first order in
/// the angles; the neglected terms are products of angles (≤ 1e-8 rad for
/// residuals of a few µrad on 0.4° errors).
pub fn residual_angles(e: &Matrix3<f64>, triad: Triad) -> (Vector3<f64>, Vector3<f64>) {
    let x = e - Matrix3::identity();
    let rot = Vector3::new(x[(1, 2)], -x[(0, 2)], x[(0, 1)]);
    let c = match triad {
        Triad::Gyro => rot,
        Triad::Accel => -rot,
    };
    let t = Vector3::new(
        x[(1, 0)] + x[(0, 1)],
        x[(2, 0)] + x[(0, 2)],
        x[(2, 1)] + x[(1, 2)],
    );
    (c, t)
}

/// The covariance (row-major, N·N) of a packed U-D factor (row-major: `D`
/// on the diagonal, the unit upper-triangular `U` strictly above;
/// [`rollcal::wire::Checkpoint::factor`]): `P = U D Uᵀ`.
pub fn covariance_of_packed_ud(n: usize, packed: &[f64]) -> Vec<f64> {
    if packed.len() != n * n {
        return Vec::new();
    }
    let a = DMatrix::from_row_slice(n, n, packed);
    let d = DVector::from_iterator(n, (0..n).map(|i| a[(i, i)]));
    let mut u = a.upper_triangle();
    u.fill_diagonal(1.0);
    let p = &u * DMatrix::from_diagonal(&d) * u.transpose();
    (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        // Symmetric by construction (the product rounds differently).
        .map(|(i, j)| 0.5 * (p[(i, j)] + p[(j, i)]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rollcal::geometry::dcm;
    use rollcal::instruments::{accel_matrix, gyro_matrix};

    const DEG: f64 = std::f64::consts::PI / 180.0;

    fn paper_ps() -> Vec<f64> {
        let v = |a: [f64; 3]| a.map(|x| x * DEG);
        [
            v([0.21, -0.08, 0.13]),
            v([0.3, -0.3, 0.2]),
            v([0.1, 0.2, -0.1]),
            v([0.2, 0.1, -0.1]),
            v([0.1, -0.1, 0.2]),
            v([0.2, -0.1, 0.1]),
        ]
        .concat()
    }

    #[test]
    fn matrices_are_the_crates_and_the_compensation_inverts_them() {
        let x = paper_ps();
        let v = |i: usize| Vector3::new(x[i], x[i + 1], x[i + 2]);
        let c = Compensation::new(ConfigId::M2Ps, &x, &[1e-6; 18], &[]).unwrap();
        assert_eq!(c.gyro_matrix, gyro_matrix(&v(3), &v(6)));
        assert_eq!(c.accel_matrix, accel_matrix(&v(9), &v(12)));
        assert_eq!(c.base_dcm, Some(dcm(&v(15))));
        let i = Matrix3::identity();
        assert!(
            (c.platform_to_gyro_command() * c.gyro_matrix - i)
                .abs()
                .max()
                < 1e-15
        );
        assert!((c.accel_to_platform() * c.accel_matrix - i).abs().max() < 1e-15);
        assert!(!c.covariance_known);
        assert!(c.correlation[0][1].is_nan());
        assert_eq!(c.frame(), "ps");
    }

    #[test]
    fn residual_angles_invert_the_models_to_first_order() {
        // Small angles: the first-order inverse is good to |θ|².
        let c = Vector3::new(3e-6, -2e-6, 5e-6);
        let t = Vector3::new(-1e-6, 4e-6, 2e-6);
        for (triad, m) in [
            (Triad::Gyro, gyro_matrix(&c, &t)),
            (Triad::Accel, accel_matrix(&c, &t)),
        ] {
            let (rc, rt) = residual_angles(&m, triad);
            assert!((rc - c).abs().max() < 1e-10, "{triad:?} {rc} {c}");
            assert!((rt - t).abs().max() < 1e-10, "{triad:?} {rt} {t}");
            // The other model's signs would be wrong: the test can fail.
            let other = if triad == Triad::Gyro {
                Triad::Accel
            } else {
                Triad::Gyro
            };
            assert!((residual_angles(&m, other).0 - c).abs().max() > 1e-6);
        }
    }

    #[test]
    fn with_the_true_parameters_the_residual_is_zero() {
        let x = paper_ps();
        let c = Compensation::new(ConfigId::M2Ps, &x, &[1e-6; 18], &[]).unwrap();
        let (g, a, b) = (c.gyro_matrix, c.accel_matrix, c.base_dcm.unwrap());
        let r = c.residual(&g, &a, Some(&b));
        assert!(r[..3].iter().all(|v| v.is_nan()));
        for v in &r[3..] {
            assert!(v.abs() < 1e-15, "{r:?}");
        }
        // A wrong estimate leaves its error: the check can fail.
        let mut y = x.clone();
        y[7] += 1e-5;
        let d = Compensation::new(ConfigId::M2Ps, &y, &[1e-6; 18], &[]).unwrap();
        let r = d.residual(&g, &a, Some(&b));
        assert!((r[7] + 1e-5).abs() < 1e-7, "{}", r[7]);
    }

    #[test]
    fn correlation_of_a_covariance_and_of_a_ud_factor() {
        let n = 12;
        // P = U D Uᵀ of a known factor.
        let mut packed = vec![0.0; n * n];
        for i in 0..n {
            packed[i * n + i] = 1e-12 * (i + 1) as f64;
            for j in i + 1..n {
                packed[i * n + j] = 0.1 * ((i + 2 * j) % 5) as f64 - 0.2;
            }
        }
        let p = covariance_of_packed_ud(n, &packed);
        let sigma: Vec<f64> = (0..n).map(|i| p[i * n + i].sqrt()).collect();
        let x = vec![0.0; n];
        let c = Compensation::new(ConfigId::M1Pa, &x, &sigma, &p).unwrap();
        for i in 0..n {
            assert!((c.correlation[i][i] - 1.0).abs() < 1e-12);
            for j in 0..n {
                assert!(c.correlation[i][j].abs() <= 1.0 + 1e-12);
                assert_eq!(c.correlation[i][j], c.correlation[j][i]);
            }
        }
        // P_{n−2,n−1} = U_{n−2,n−1} D_{n−1}.
        let (i, j) = (n - 2, n - 1);
        let expect = packed[i * n + j] * packed[j * n + j];
        assert!((p[i * n + j] - expect).abs() < 1e-24);
        assert_eq!(c.frame(), "pa");
        assert!(Compensation::new(ConfigId::M1Pa, &x, &sigma, &p[1..]).is_err());
    }

    #[test]
    fn the_json_holds_every_field() {
        let x = paper_ps();
        let v = Compensation::new(ConfigId::M2Ps, &x, &[1e-6; 18], &[])
            .unwrap()
            .to_json();
        for key in [
            "config",
            "frame",
            "conventions",
            "gyro_matrix",
            "accel_matrix",
            "compensation",
            "base_dcm",
            "names",
            "estimate_rad",
            "sigma_rad",
            "correlation",
        ] {
            assert!(!v[key].is_null(), "{key}");
        }
        assert_eq!(v["names"][15], "lam_x");
        assert!(v["correlation"][0][1].is_null());
        assert_eq!(v["correlation"][1][1], 1.0);
    }
}
