//! Results a user can apply (docs/model.md §Compensation): from a final
//! estimate (state, covariance, configuration, error model) the calibrated
//! installation matrices, the instruments' own errors of the full model,
//! the compensation of the raw instrument outputs, the base DCM and the
//! parameters' σ, covariance and correlation matrix.
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
//! The full model (docs/model.md §Instrument errors) adds the
//! instruments' own errors: `ω^p_ip = G [(I + K_g) ωc + dg + D_g f^p]` and
//! `Z_a = ba + (I + K_a) A f^p`, so the torquer command is
//! `ωc = (I + K_g)⁻¹ (G⁻¹ ω^p − dg − D_g f^p)` and the compensated specific
//! force `f^p = A⁻¹ (I + K_a)⁻¹ (Z_a − ba)` ([`instruments`]); with the
//! instrument errors zero (the installation model) these are the formulas
//! above, bit for bit.
//!
//! In a pa configuration the frame p is pa, defined by the accelerometer
//! axes: `θaC` is absorbed into the frame (`C^pa_ps = R(−θaC)`, not
//! estimated), `A = I + L(θaT)`, `G = R(θgC^pa)(I + L(θgT))` and the
//! g-sensitive drift is `D_g^pa = D_g R(θaC)`; the compensated outputs are
//! in pa coordinates.
//!
//! Split by concern: this file builds a [`Compensation`] and its JSON;
//! `installation` the residual installation after compensation,
//! [`instruments`] the full model's terms, their compensation and the
//! propagation of the covariance to the compensated outputs, `text` the
//! readable report.

mod installation;
pub mod instruments;
mod text;

pub use installation::{residual_angles, Triad};
pub use instruments::FULL_CONVENTIONS;

use nalgebra::{DMatrix, DVector, Matrix3};
use rollcal::models::{ConfigId, ErrorModel, InstrumentErrors, PlatformFrame};

/// The short statement of conventions written into the JSON and the text
/// of the installation model ([`FULL_CONVENTIONS`] for the full model).
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
    /// The error model of the estimate: the installation errors alone, or
    /// followed by the instruments' own (the full model).
    pub errors: ErrorModel,
    /// State names ([`ConfigId::states_with`]), in state order: every
    /// state of the error model.
    pub names: Vec<&'static str>,
    /// Estimate of every state (internal unit: rad; rad/s, rad/s per g, 1,
    /// g for the instrument errors, [`rollcal::models::Group::unit`]).
    pub estimate: Vec<f64>,
    /// σ of every state, `√P_ii` (internal unit).
    pub sigma: Vec<f64>,
    /// Covariance of the states, row-major N·N (internal units); empty
    /// when unknown.
    pub covariance: Vec<f64>,
    /// Correlation matrix `P_ij / (σ_i σ_j)` (row-major rows; NaN where
    /// the covariance is unknown).
    pub correlation: Vec<Vec<f64>>,
    /// Whether the covariance was known (else `sigma` came alone and the
    /// correlation is NaN off the diagonal).
    pub covariance_known: bool,
    /// Prior σ of every state (internal unit), when known (else empty):
    /// the text marks an instrument term whose σ is still ≥ 1 % of it.
    pub prior: Vec<f64>,
    /// Calibrated gyro installation matrix `G`.
    pub gyro_matrix: Matrix3<f64>,
    /// Calibrated accelerometer installation matrix `A`.
    pub accel_matrix: Matrix3<f64>,
    /// Base mounting DCM `C^r_n = R(λ)` (M2, M3).
    pub base_dcm: Option<Matrix3<f64>>,
    /// The instruments' own errors in the frame p (internal units; all
    /// zero for the installation model): `dg`, `D_g` (`D_g^pa` in pa),
    /// `kg`, `ba`, `ka`.
    pub instruments: InstrumentErrors<f64>,
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
    /// A scale factor `1 + kg_i` or `1 + ka_i` is not positive (an absurd
    /// estimate of the full model).
    SingularScale,
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
            Error::SingularScale => f.write_str("a scale factor 1 + kg or 1 + ka is not positive"),
        }
    }
}

impl Compensation {
    /// From a final estimate of the installation model: `estimate` and
    /// `sigma` (rad, N values) and the row-major covariance (rad², N·N
    /// values, or empty when unknown).
    pub fn new(
        config: ConfigId,
        estimate: &[f64],
        sigma: &[f64],
        covariance: &[f64],
    ) -> Result<Self, Error> {
        Self::with_errors(
            config,
            ErrorModel::Installation,
            estimate,
            sigma,
            covariance,
        )
    }

    /// From a final estimate of error model `errors`: `estimate` and
    /// `sigma` (internal units, N values of
    /// [`ConfigId::states_with`]`(errors)`) and the row-major covariance
    /// (N·N values, or empty when unknown).
    pub fn with_errors(
        config: ConfigId,
        errors: ErrorModel,
        estimate: &[f64],
        sigma: &[f64],
        covariance: &[f64],
    ) -> Result<Self, Error> {
        let n = config.layout_with(errors).n();
        if estimate.len() != n
            || sigma.len() != n
            || !(covariance.is_empty() || covariance.len() == n * n)
        {
            return Err(Error::Dimension {
                expected: n,
                found: (estimate.len(), sigma.len(), covariance.len()),
            });
        }
        let m = instruments::Params::of(config, errors, estimate)?;
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
        Ok(Self {
            config,
            errors,
            names: config.states_with(errors).iter().map(|s| s.name).collect(),
            estimate: estimate.to_vec(),
            sigma: sigma.to_vec(),
            covariance: covariance.to_vec(),
            correlation,
            covariance_known: !covariance.is_empty(),
            prior: Vec::new(),
            gyro_matrix: m.g,
            accel_matrix: m.a,
            base_dcm: config.layout().base.then_some(m.c_rn),
            instruments: m.e,
        })
    }

    /// The same with the prior σ of every state (internal units, N values;
    /// ignored otherwise).
    pub fn with_prior(self, prior: &[f64]) -> Self {
        if prior.len() != self.estimate.len() {
            return self;
        }
        Self {
            prior: prior.to_vec(),
            ..self
        }
    }

    /// Number of installation states (attitude, instrument angles, `λ`):
    /// the first states, those of `names`, `estimate_rad`, `sigma_rad` and
    /// `correlation` in the JSON.
    pub fn installation_n(&self) -> usize {
        self.config.layout().n()
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

    /// `ω_g = G⁻¹ ω^p`: the gyro command for a wanted platform rate
    /// (installation model; the full model's command is
    /// [`Compensation::torquer_command`]).
    pub fn platform_to_gyro_command(&self) -> Matrix3<f64> {
        self.gyro_matrix.try_inverse().unwrap_or(Matrix3::zeros())
    }

    /// `f^p = A⁻¹ Z_a`: accelerometer outputs into the platform frame
    /// (after the bias and scale factors of the full model,
    /// [`Compensation::compensate_accel`]).
    pub fn accel_to_platform(&self) -> Matrix3<f64> {
        self.accel_matrix.try_inverse().unwrap_or(Matrix3::zeros())
    }

    /// Compensated platform rate `G ω_g` of a gyro rate `omega_g`
    /// (installation model; [`Compensation::platform_rate`] in full).
    pub fn compensate_gyro(&self, omega_g: &nalgebra::Vector3<f64>) -> nalgebra::Vector3<f64> {
        self.gyro_to_platform() * omega_g
    }

    /// The JSON document of `--matrices`. The installation model's keys and
    /// values are those it always had; the full model replaces
    /// `conventions` by [`FULL_CONVENTIONS`], keeps `names`,
    /// `estimate_rad`, `sigma_rad` and `correlation` to the installation
    /// states and adds `errors`, the compensation's formulas and terms,
    /// `instruments`, `instrument_terms` and `all_states` (every state's
    /// estimate, σ, covariance and correlation;
    /// [`instruments::full_json`]).
    pub fn to_json(&self) -> serde_json::Value {
        let n = self.installation_n();
        let mut v = serde_json::json!({
            "config": self.config.as_str(),
            "frame": self.frame(),
            "conventions": CONVENTIONS,
            "gyro_matrix": rows(&self.gyro_matrix),
            "accel_matrix": rows(&self.accel_matrix),
            "compensation": {
                "gyro_to_platform": rows(&self.gyro_to_platform()),
                "platform_to_gyro_command": rows(&self.platform_to_gyro_command()),
                "accel_to_platform": rows(&self.accel_to_platform()),
            },
            "base_dcm": self.base_dcm.as_ref().map(rows),
            "names": self.names.get(..n),
            "estimate_rad": self.estimate.get(..n),
            "sigma_rad": self.sigma.get(..n),
            "covariance_known": self.covariance_known,
            "correlation": self.correlation.iter().take(n)
                .map(|r| r.iter().take(n).map(|v| finite_or_null(*v)).collect::<Vec<_>>())
                .collect::<Vec<_>>(),
        });
        if self.errors == ErrorModel::Full {
            instruments::full_json(self, &mut v);
        }
        v
    }

    /// The readable text report: matrices, how to apply them, the
    /// parameters with σ, and the strongest correlations. Installation
    /// states whose σ is at least 1 % of `prior_sigma` (rad), and
    /// instrument terms whose σ is at least 1 % of their own prior
    /// ([`Compensation::prior`], when known), are marked as not
    /// determined.
    pub fn text(&self, prior_sigma: f64) -> String {
        text::text(self, prior_sigma)
    }
}

/// A 3×3 matrix as JSON rows.
pub(crate) fn rows(a: &Matrix3<f64>) -> Vec<[f64; 3]> {
    (0..3).map(|i| [a[(i, 0)], a[(i, 1)], a[(i, 2)]]).collect()
}

/// A finite number, or JSON null.
pub(crate) fn finite_or_null(v: f64) -> serde_json::Value {
    if v.is_finite() {
        serde_json::json!(v)
    } else {
        serde_json::Value::Null
    }
}

/// The compensation of a run's final estimate and covariance, in the run's
/// error model, with each state's prior σ.
pub fn of_run(r: &crate::analysis::runner::RunResult) -> Result<Compensation, Error> {
    let est: Vec<f64> = r.states.iter().map(|s| s.estimate_rad).collect();
    let sig: Vec<f64> = r.states.iter().map(|s| s.sigma_rad).collect();
    let prior: Vec<f64> = r.states.iter().map(|s| s.prior).collect();
    Ok(
        Compensation::with_errors(r.config, r.errors, &est, &sig, &r.covariance)?
            .with_prior(&prior),
    )
}

/// The covariance (row-major, N·N, the state vector's order) of the
/// packed U-D factor of a filter of `layout` given by its upper triangle
/// row by row (`D` on the diagonal, the unit upper-triangular `U` strictly
/// above; [`rollcal::wire::Checkpoint::factor`]), whose rows and columns
/// are in the factor's order ([`rollcal::ekf::factor_state`]):
/// `P = U D Uᵀ`, permuted back. Empty unless `packed` has `N (N + 1) / 2`
/// values.
pub fn covariance_of_packed_ud(layout: &rollcal::models::Layout, packed: &[f64]) -> Vec<f64> {
    let n = layout.n();
    if packed.len() != rollcal::wire::factor_len(n) {
        return Vec::new();
    }
    let mut values = packed.iter().copied();
    let mut a = DMatrix::<f64>::zeros(n, n);
    for r in 0..n {
        for c in r..n {
            a[(r, c)] = values.next().unwrap_or(0.0);
        }
    }
    let d = DVector::from_iterator(n, (0..n).map(|i| a[(i, i)]));
    let mut u = a.upper_triangle();
    u.fill_diagonal(1.0);
    let p = &u * DMatrix::from_diagonal(&d) * u.transpose();
    // State i sits at position position[i] of the factor.
    let mut position = vec![0; n];
    for k in 0..n {
        position[rollcal::ekf::factor_state(layout, k)] = k;
    }
    (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .map(|(i, j)| (position[i], position[j]))
        // Symmetric by construction (the product rounds differently).
        .map(|(a, b)| 0.5 * (p[(a, b)] + p[(b, a)]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use rollcal::geometry::dcm;
    use rollcal::instruments::{accel_matrix, gyro_matrix};

    const DEG: f64 = std::f64::consts::PI / 180.0;

    pub(super) fn paper_ps() -> Vec<f64> {
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
        let upper: Vec<f64> = (0..n)
            .flat_map(|i| (i..n).map(move |j| (i, j)))
            .map(|(i, j)| packed[i * n + j])
            .collect();
        let p = covariance_of_packed_ud(&ConfigId::M1Pa.layout(), &upper);
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

    /// The full model's factor is in the factor's order (the wandering
    /// states after the attitude): its covariance, permuted back, is the
    /// filter's, after updates that correlate the states.
    #[test]
    fn a_full_models_checkpoint_factor_gives_the_filters_covariance() {
        use rollcal::estimator::{LogRecord, SliceLog};
        use rollcal::session::AnyCalibrator;
        use rollcal::wire::{CalibratorConfig, Sample};
        let mut settings = CalibratorConfig::paper(ConfigId::M1Pa);
        settings.errors = ErrorModel::Full;
        // The realistic scenario's errors that wander (its file, as `run`
        // reads it).
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/realistic.toml");
        let scenario =
            crate::sim::scenario::Scenario::from_file(std::path::Path::new(path)).unwrap();
        settings.wander = scenario.instruments.wander.to_model();
        assert!(!settings.wander.is_none());
        let mut cal = AnyCalibrator::<f64>::new(settings).unwrap();
        let mut records = [LogRecord::predicted(0.0, Vector3::zeros()); 30];
        let mut log = SliceLog::new(&mut records);
        let e = settings.earth_rate_n;
        for k in 0..30u32 {
            let turn = 0.02 * f64::from(k);
            let s = Sample {
                seq: k,
                t_us: (u64::from(k) + 1) * 1_000_000,
                dt: 1.0,
                dtheta_cmd: [e[0] + 0.02, e[1], e[2]],
                c_cn_quat: [
                    (turn / 2.0).cos() as f32,
                    (turn / 2.0).sin() as f32,
                    0.0,
                    0.0,
                ],
                accel_mean: [0.0, turn.cos() as f32, -turn.sin() as f32],
                gimbal: None,
            };
            cal.push_logged(&s, &mut log).unwrap();
        }
        let layout = ConfigId::M1Pa.layout_with(ErrorModel::Full);
        let n = layout.n();
        let p = covariance_of_packed_ud(&layout, &cal.checkpoint().factor);
        let AnyCalibrator::M1PaFull(c) = &cal else {
            panic!("the full M1-pa calibrator");
        };
        let want = c.filter().covariance().transpose();
        assert_eq!((p.len(), want.len()), (n * n, n * n));
        for (a, b) in p.iter().zip(want.iter()) {
            assert!((a - b).abs() <= 1e-9 * (a.abs() + 1e-30), "{a:e} {b:e}");
        }
        // Not the identity order: ba's variance is at ba's index.
        let ba = layout.ba().unwrap();
        assert_ne!(rollcal::ekf::factor_state(&layout, ba), ba);
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
