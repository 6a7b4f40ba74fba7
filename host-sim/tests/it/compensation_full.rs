//! The full model's compensation (issue 31 item 7, docs/model.md
//! §Compensation): the reported instrument terms and installation matrices,
//! applied to the truth simulator's raw outputs, give the true specific
//! force and the wanted platform rate to within the σ propagated from the
//! reported covariance; the residual is the first-order effect of the
//! estimate's error (truth − estimate), so a wrong sign or frame in either
//! formula shows as a residual of many σ; without the instrument terms the
//! residual is many σ.
//!
//! The truth side is `sim::truth` (its own `G`, `A` and instrument
//! arithmetic, `TruthParams::gyro_input`, `accel_output`), not the
//! compensation's.

use crate::support;

use host_sim::analysis::compensation::{of_run, Compensation};
use host_sim::analysis::runner::{Estimator, SimulatedRun};
use host_sim::sim::instruments::{instrument_truth_state, DEG_H, UG};
use host_sim::sim::scenario::{Scenario, DEG};
use host_sim::sim::truth::{simulate, truth_state, SimOptions, Simulation, TruthParams};
use nalgebra::{Matrix3, Vector3};
use rollcal::geometry::dcm;
use rollcal::models::{ConfigId, ErrorModel, PlatformFrame};

/// The bound on every residual component, in σ of the propagated
/// covariance.
const K_SIGMA: f64 = 4.0;

fn instrumented() -> Scenario {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/instrumented.toml"
    );
    Scenario::load(Some(std::path::Path::new(path))).unwrap()
}

fn instrumented_seed1() -> (Scenario, Simulation) {
    let sc = instrumented();
    let sim = simulate(
        &sc,
        SimOptions {
            seed: 1,
            noise: true,
            earth_rate: true,
        },
    );
    (sc, sim)
}

/// `C^p_ps`: I in ps, `R(−θaC)` in pa.
fn c_p_ps(id: ConfigId, p: &TruthParams) -> Matrix3<f64> {
    match id.layout().frame {
        PlatformFrame::Ps => Matrix3::identity(),
        PlatformFrame::Pa => dcm(&(-p.theta_a_c)),
    }
}

/// One compensated output against the truth: the residual, its σ per
/// component (propagated covariance) and the first-order prediction
/// `J (x_a − x_b)` of it.
struct Check {
    residual: Vector3<f64>,
    sigma: Vector3<f64>,
    predicted: Vector3<f64>,
}

impl Check {
    fn new(residual: Vector3<f64>, cov: Matrix3<f64>, j: &[Vector3<f64>], dx: &[f64]) -> Self {
        let predicted = j
            .iter()
            .zip(dx)
            .filter(|(c, _)| **c != Vector3::zeros())
            .map(|(c, d)| c * *d)
            .sum();
        Self {
            residual,
            sigma: cov.diagonal().map(f64::sqrt),
            predicted,
        }
    }
    /// The worst |residual| / σ.
    fn ratio(&self) -> f64 {
        self.residual.component_div(&self.sigma).amax()
    }
    /// The worst |residual − prediction| / σ.
    fn first_order(&self) -> f64 {
        (self.residual - self.predicted)
            .component_div(&self.sigma)
            .amax()
    }
}

/// The worst residuals (σ) of the accelerometer and torquer compensation
/// `applied` of configuration `id` over the path's samples (its raw
/// accelerometer outputs and commanded rates), the six ±1 g positions and
/// rates of 0.1 and 1 °/s about each axis, in σ of the covariance
/// propagated through the reported compensation `c`. With `strict` (when
/// `applied` is `c`), each is checked against [`K_SIGMA`] and against its
/// first-order prediction from the truth `x_true` of every state.
fn worst(
    id: ConfigId,
    applied: &Compensation,
    c: &Compensation,
    x_true: &[f64],
    sim: &Simulation,
    strict: bool,
) -> (f64, f64) {
    let p = &sim.params;
    let c_p = c_p_ps(id, p);
    let f_n = Vector3::new(0.0, 1.0, 0.0);
    // truth − estimate, and estimate − truth.
    let d_te: Vec<f64> = x_true.iter().zip(&c.estimate).map(|(t, e)| t - e).collect();
    let d_et: Vec<f64> = d_te.iter().map(|d| -d).collect();
    // The specific forces (ps) and wanted platform rates (p) to try.
    // (f^ps, wanted ω^p, the simulator's raw accelerometer output if any).
    type Case = (Vector3<f64>, Vector3<f64>, Option<Vector3<f64>>);
    let mut cases: Vec<Case> = Vec::new();
    for s in sim.samples.iter().step_by(90) {
        // The platform follows the computed frame: the wanted rate is the
        // commanded ωc of the period. The raw output is the simulator's.
        let w = s.dtheta_cmd / s.dt;
        cases.push((s.truth.c_ps_n * f_n, w, Some(s.truth.accel_at_t)));
    }
    for axis in 0..3 {
        for sign in [1.0, -1.0] {
            let e = Vector3::ith(axis, sign);
            for rate in [0.1, 1.0] {
                cases.push((e, Vector3::ith((axis + 1) % 3, rate * DEG), None));
            }
        }
    }
    let (mut wa, mut wg) = (0.0_f64, 0.0_f64);
    for (f_ps, w_p, raw) in cases {
        // Accelerometers: the raw output, compensated.
        let z = raw.unwrap_or_else(|| p.accel_output(&f_ps));
        let f_true = c_p * f_ps;
        let f_hat = applied.compensate_accel(&z);
        let a = Check::new(
            f_hat - f_true,
            c.accel_covariance(&z).unwrap(),
            &c.accel_jacobian(&z),
            &d_et,
        );
        // Torquers: the command for the wanted rate under the compensated
        // specific force, applied to the true platform.
        let w_c = applied.torquer_command(&w_p, &f_hat);
        let w_true = c_p * (p.g() * p.gyro_input(&w_c, &f_ps));
        let g = Check::new(
            w_true - w_p,
            c.platform_rate_covariance(&w_c, &f_hat).unwrap(),
            &c.platform_rate_jacobian(&w_c, &f_hat),
            &d_te,
        );
        for (what, k) in [("specific force", &a), ("platform rate", &g)] {
            if !strict {
                continue;
            }
            assert!(
                k.ratio() <= K_SIGMA,
                "{id} {what}: residual {} is {:.2}σ (σ {})",
                k.residual,
                k.ratio(),
                k.sigma
            );
            assert!(
                k.first_order() <= 0.05,
                "{id} {what}: residual {} against its first-order prediction {} (σ {})",
                k.residual,
                k.predicted,
                k.sigma
            );
        }
        wa = wa.max(a.ratio());
        wg = wg.max(g.ratio());
    }
    (wa, wg)
}

/// Every state's truth (installation then instrument) for `id`'s full
/// model.
fn full_truth(id: ConfigId, sim: &Simulation) -> Vec<f64> {
    let last = sim.samples.last().unwrap().truth;
    let mut x = truth_state(id, &sim.params, &last);
    x.extend(instrument_truth_state(id, &sim.params, &sim.final_wander()));
    x
}

#[test]
fn reported_instrument_terms_compensate_the_raw_outputs_within_sigma() {
    let (sc, sim) = instrumented_seed1();
    for id in [ConfigId::M2Ps, ConfigId::M1Pa] {
        let r = SimulatedRun::new(id, &sc, &sim, true)
            .with_errors(ErrorModel::Full)
            .run(Estimator::default(), None, false)
            .unwrap();
        let c = of_run(&r).unwrap();
        assert!(c.covariance_known && c.errors == ErrorModel::Full);
        let x_true = full_truth(id, &sim);
        assert_eq!(x_true.len(), c.estimate.len());
        let (wa, wg) = worst(id, &c, &c, &x_true, &sim, true);
        println!("{id}: worst residual, specific force {wa:.2}σ, platform rate {wg:.2}σ");

        // With the true values the compensation is exact (the formulas
        // invert the simulator's model): residuals at rounding level.
        let exact =
            Compensation::with_errors(id, ErrorModel::Full, &x_true, &c.sigma, &[]).unwrap();
        let f_ps = sim.samples[100].truth.c_ps_n * Vector3::new(0.0, 1.0, 0.0);
        let f_true = c_p_ps(id, &sim.params) * f_ps;
        let z = sim.samples[100].truth.accel_at_t;
        let f_hat = exact.compensate_accel(&z);
        assert!((f_hat - f_true).amax() < 1e-14, "{id}: {}", f_hat - f_true);
        let w_p = Vector3::new(1e-3, -2e-3, 5e-4);
        let w_c = exact.torquer_command(&w_p, &f_true);
        let w = c_p_ps(id, &sim.params) * sim.params.g() * sim.params.gyro_input(&w_c, &f_ps);
        assert!((w - w_p).amax() < 1e-17, "{id}: {}", w - w_p);

        // Without the instrument terms (the installation part alone) the
        // same checks fail by many σ: the bound above can fail.
        let mut bare = c.estimate.clone();
        let i0 = c.instrument_index().unwrap();
        bare[i0..].iter_mut().for_each(|v| *v = 0.0);
        let b = Compensation::with_errors(id, ErrorModel::Full, &bare, &c.sigma, &c.covariance)
            .unwrap();
        let (ra, rg) = worst(id, &b, &c, &x_true, &sim, false);
        println!(
            "{id}: without the instrument terms, specific force {ra:.0}σ, platform rate {rg:.1}σ"
        );
        assert!(ra > 100.0 && rg > 2.0 * K_SIGMA, "{id}: {ra}σ, {rg}σ");
    }
}

/// `run --errors full --matrices`: the JSON's terms alone, applied as
/// written in its conventions, compensate the simulator's raw outputs as
/// the library does; its `all_states` covariance gives the same σ; the text
/// writes the formulas and every instrument term with its unit.
#[test]
fn run_errors_full_matrices_json_applies_as_documented() {
    let dir = support::scratch("matrices-full");
    let (json, txt) = (dir.join("m.json"), dir.join("m.txt"));
    let scenario = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/instrumented.toml"
    );
    let out = support::host_sim()
        .args([
            "run", "--config", "M2-ps", "--errors", "full", "--seed", "1",
        ])
        .args(["--scenario", scenario, "--matrices"])
        .arg(&json)
        .arg("--matrices-txt")
        .arg(&txt)
        .output()
        .unwrap();
    support::assert_success(&out);
    let v = support::json_file(&json);
    assert_eq!(v["errors"], "full");
    assert_eq!(v["names"].as_array().unwrap().len(), 18);
    assert_eq!(v["all_states"]["names"].as_array().unwrap().len(), 54);
    let conv = v["conventions"].as_str().unwrap();
    assert!(
        conv.contains("w_c = (I + K_g)^-1 (G^-1 w^p - dg - D_g f^p)"),
        "{conv}"
    );
    assert!(
        conv.contains("u_i = 2 c_i / (b_i + sqrt(b_i^2 + 4 k2_i c_i))"),
        "{conv}"
    );
    let m3 = |x: &serde_json::Value| Matrix3::from_fn(|i, j| x[i][j].as_f64().unwrap());
    let v3 = |x: &serde_json::Value| Vector3::from_fn(|i, _| x[i].as_f64().unwrap());
    let comp = &v["compensation"];
    let g_inv = m3(&comp["platform_to_gyro_command"]);
    let a_inv = m3(&comp["accel_to_platform"]);
    let kg_inv = m3(&comp["gyro_scale_inverse"]);
    let ka_inv = m3(&comp["accel_scale_inverse"]);
    let (dg, d_g, ba, k2) = (
        v3(&comp["dg_rad_s"]),
        m3(&comp["d_g_rad_s_per_g"]),
        v3(&comp["ba_g"]),
        v3(&comp["k2_g_per_g2"]),
    );
    // The printed terms are the internal ones in their units.
    let terms = &v["instrument_terms"];
    assert!((terms["ba"]["estimate"][2].as_f64().unwrap() * UG - ba.z).abs() < 1e-18);
    assert!((terms["D_g"]["estimate"][1][2].as_f64().unwrap() * DEG_H - d_g[(1, 2)]).abs() < 1e-20);
    assert_eq!(terms["kg"]["unit"], "ppm");
    // The library's compensation of the JSON's every-state estimate and
    // covariance.
    let all = &v["all_states"];
    let list = |x: &serde_json::Value| -> Vec<f64> {
        x.as_array()
            .unwrap()
            .iter()
            .map(|y| y.as_f64().unwrap())
            .collect()
    };
    let cov: Vec<f64> = all["covariance"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(&list)
        .collect();
    let c = Compensation::with_errors(
        ConfigId::M2Ps,
        ErrorModel::Full,
        &list(&all["estimate"]),
        &list(&all["sigma"]),
        &cov,
    )
    .unwrap();
    let (_, sim) = instrumented_seed1();
    let x_true = full_truth(ConfigId::M2Ps, &sim);
    let f_n = Vector3::new(0.0, 1.0, 0.0);
    let mut worst = (0.0_f64, 0.0_f64);
    for s in sim.samples.iter().step_by(300) {
        let z = s.truth.accel_at_t;
        let f_ps = s.truth.c_ps_n * f_n;
        // As the conventions say: subtract the bias, solve each axis's
        // k2 u² + (1 + ka) u = c for the root near c / (1 + ka), A⁻¹.
        let c_ = z - ba;
        let u = Vector3::from_fn(|i, _| {
            let b = 1.0 / ka_inv[(i, i)];
            2.0 * c_[i] / (b + (b * b + 4.0 * k2[i] * c_[i]).sqrt())
        });
        let f = a_inv * u;
        assert!((f - c.compensate_accel(&z)).amax() < 1e-15);
        let w_p = s.dtheta_cmd / s.dt;
        let w_c = kg_inv * (g_inv * w_p - dg - d_g * f);
        assert!((w_c - c.torquer_command(&w_p, &f)).amax() < 1e-18);
        let w = sim.params.g() * sim.params.gyro_input(&w_c, &f_ps);
        let sa = c.accel_covariance(&z).unwrap().diagonal().map(f64::sqrt);
        let sg = c
            .platform_rate_covariance(&w_c, &f)
            .unwrap()
            .diagonal()
            .map(f64::sqrt);
        let ra = (f - f_ps).component_div(&sa).amax();
        let rg = (w - w_p).component_div(&sg).amax();
        assert!(ra <= K_SIGMA && rg <= K_SIGMA, "{ra}σ {rg}σ");
        worst = (worst.0.max(ra), worst.1.max(rg));
    }
    assert!(x_true.len() == 54);
    println!(
        "JSON applied: worst specific force {:.2}σ, platform rate {:.2}σ",
        worst.0, worst.1
    );
    let text = std::fs::read_to_string(&txt).unwrap();
    for needle in [
        "full model",
        "ωc = (I + K_g)⁻¹ (G⁻¹ ω^p − dg − D_g f^p)",
        "f^p = A⁻¹ (I + K_a)⁻¹ (Z_a − ba)",
        "Instrument errors (printed units)",
        "Dg_zy",
        "°/h/g",
        "µg",
    ] {
        assert!(text.contains(needle), "{needle} in\n{text}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
