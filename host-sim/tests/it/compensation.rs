//! The reported matrices compensate the simulator's instruments: applied to
//! the true installation (the truth's G and A, built independently of the
//! crate's instrument functions in `truth.rs`), they leave residual
//! installation angles within 4σ of the reported σ of each parameter; with
//! the true parameters the compensation of the raw outputs is exact.

use crate::support;
use host_sim::analysis::compensation::{of_run, Compensation};
use host_sim::analysis::runner::{run_filter, Estimator};
use host_sim::sim::scenario::Scenario;
use host_sim::sim::truth::{simulate, truth_state, SimOptions, Simulation, TruthParams};
use nalgebra::{Matrix3, Vector3};
use rollcal::geometry::{dcm, right_jacobian};
use rollcal::models::{ConfigId, Group, PlatformFrame};
use support::assert_success;

/// The true G, A (in the configuration's frame) and R(λ), from the truth's
/// ps matrices: in pa, `G^pa = C^pa_ps G`, `A^pa = A C^ps_pa` with
/// `C^pa_ps = R(−θaC)`.
fn true_matrices(id: ConfigId, p: &TruthParams) -> (Matrix3<f64>, Matrix3<f64>, Matrix3<f64>) {
    let base = dcm(&p.lambda);
    match id.layout().frame {
        PlatformFrame::Ps => (p.g(), p.a(), base),
        PlatformFrame::Pa => {
            let c_pa_ps = dcm(&(-p.theta_a_c));
            (c_pa_ps * p.g(), p.a() * c_pa_ps.transpose(), base)
        }
    }
}

fn sim(seed: u64) -> (Scenario, Simulation) {
    let sc = Scenario::paper();
    let sim = simulate(
        &sc,
        SimOptions {
            seed,
            noise: true,
            earth_rate: true,
        },
    );
    (sc, sim)
}

/// The worst |residual| / σ over the parameters of `id` after compensating
/// with the estimate of one seeded run, after checking each against 4σ
/// and against the parameter error (first order).
fn worst_ratio(id: ConfigId, sc: &Scenario, sim: &Simulation) -> f64 {
    let r = run_filter(id, sc, sim, true, Estimator::default(), None, false).unwrap();
    let c = of_run(&r).unwrap();
    assert!(c.covariance_known);
    let (g, a, b) = true_matrices(id, &sim.params);
    let res = c.residual(&g, &a, Some(&b));
    let mut worst: (f64, &str) = (0.0, "");
    for (i, s) in id.states().iter().enumerate() {
        if s.group == Group::Attitude {
            assert!(res[i].is_nan());
            continue;
        }
        // The base residual is a rotation, R(λ_true) R(λ)ᵀ ≈ I − [(J_r(λ) δλ)×]
        // (geometry::right_jacobian): its σ is that of J_r(λ) δλ.
        let (sigma, err) = if s.group == Group::Lambda {
            let il = id.layout().lam().unwrap();
            let k = i - il;
            let lam = Vector3::new(c.estimate[il], c.estimate[il + 1], c.estimate[il + 2]);
            let j = right_jacobian(&lam);
            let n = c.sigma.len();
            let p = Matrix3::from_fn(|a, b| r.covariance[(il + a) * n + il + b]);
            let d =
                Vector3::from_fn(|a, _| r.states[il + a].truth_rad - r.states[il + a].estimate_rad);
            ((j * p * j.transpose())[(k, k)].sqrt(), (j * d)[k])
        } else {
            (c.sigma[i], r.states[i].truth_rad - r.states[i].estimate_rad)
        };
        let ratio = res[i].abs() / sigma;
        println!(
            "{id} {:<9} residual {:>+10.4}″  σ {:>8.4}″  ratio {ratio:.2}",
            s.name,
            res[i] / host_sim::sim::scenario::ARCSEC,
            sigma / host_sim::sim::scenario::ARCSEC
        );
        assert!(
            ratio <= 4.0,
            "{id} {}: residual {:e} rad is {ratio:.2}σ",
            s.name,
            res[i]
        );
        // The residual angle is the parameter error truth − estimate, to
        // first order (products of 0.4° and a few σ).
        assert!(
            (res[i] - err).abs() <= 0.1 * sigma,
            "{id} {}: residual {:e}, parameter error {err:e}",
            s.name,
            res[i]
        );
        if ratio > worst.0 {
            worst = (ratio, s.name);
        }
    }
    println!("{id}: worst residual {:.2}σ ({})", worst.0, worst.1);
    // Uncompensated (the nominal G = A = I, R(λ) = I), the residual is the
    // installation itself: tens of σ. The 4σ check above can fail.
    let zero = Compensation::new(id, &vec![0.0; c.sigma.len()], &c.sigma, &[]).unwrap();
    let raw = zero.residual(&g, &a, Some(&b));
    let raw_worst = id
        .states()
        .iter()
        .zip(raw.iter().zip(&c.sigma))
        .filter(|(s, _)| s.group != Group::Attitude && s.group != Group::Lambda)
        .map(|(_, (v, s))| v.abs() / s)
        .fold(0.0, f64::max);
    assert!(raw_worst > 100.0, "{id}: uncompensated {raw_worst:.1}σ");
    worst.0
}

#[test]
fn reported_matrices_leave_residuals_within_4_sigma_m2_ps_and_m1_pa() {
    let (sc, sim) = sim(1);
    let w2 = worst_ratio(ConfigId::M2Ps, &sc, &sim);
    let w1 = worst_ratio(ConfigId::M1Pa, &sc, &sim);
    println!("worst ratio: M2-ps {w2:.2}σ, M1-pa {w1:.2}σ");
}

#[test]
fn with_the_true_parameters_the_compensation_of_the_raw_outputs_is_exact() {
    let sc = {
        let mut sc = Scenario::paper();
        sc.timing.duration_s = 600.0;
        sc.path.truncate(1);
        sc.path[0].angle_deg = 60.0;
        sc
    };
    let sim = simulate(
        &sc,
        SimOptions {
            seed: 1,
            noise: false,
            earth_rate: true,
        },
    );
    let f_n = rollcal::geometry::gravity_n::<f64>();
    for id in [ConfigId::M2Ps, ConfigId::M1Pa, ConfigId::M3Pa] {
        let last = sim.samples.last().unwrap().truth;
        let x = truth_state(id, &sim.params, &last);
        let n = x.len();
        let c = Compensation::new(id, &x, &vec![1e-6; n], &[]).unwrap();
        let (g, a, b) = true_matrices(id, &sim.params);
        // The matrices are the truth's, also in pa (exact composition).
        assert!((c.gyro_matrix - g).abs().max() < 1e-14, "{id} G");
        assert!((c.accel_matrix - a).abs().max() < 1e-14, "{id} A");
        let mut worst = 0.0_f64;
        for (v, s) in c.residual(&g, &a, Some(&b)).iter().zip(id.states()) {
            if s.group != Group::Attitude {
                worst = worst.max(v.abs());
            }
        }
        // The raw accelerometer outputs of the simulator, compensated, are
        // the specific force in the platform frame p.
        let c_p_ps = match id.layout().frame {
            PlatformFrame::Ps => Matrix3::identity(),
            PlatformFrame::Pa => dcm(&(-sim.params.theta_a_c)),
        };
        for s in &sim.samples {
            let f_p = c_p_ps * s.truth.c_ps_n * f_n;
            worst = worst.max((c.compensate_accel(&s.truth.accel_at_t) - f_p).abs().max());
        }
        // The platform rate of the gyro triad's rate, and back.
        let w = Vector3::new(1e-3, -2e-3, 5e-4);
        worst = worst.max((c.compensate_gyro(&w) - g * w).abs().max() / w.norm());
        worst = worst.max((g * (c.platform_to_gyro_command() * w) - w).abs().max() / w.norm());
        println!("{id}: worst residual with the true parameters {worst:e}");
        assert!(worst < 1e-14, "{id}: {worst:e}");
    }
}

/// `run --matrices` and `calibrate --matrices` write the documented JSON
/// and text; `calibrate` reports the final filter's covariance.
#[test]
fn run_and_calibrate_write_the_matrices() {
    use std::process::Command;
    let bin = env!("CARGO_BIN_EXE_host-sim");
    let dir = std::env::temp_dir().join(format!("rollcal-matrices-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (run_json, run_txt) = (dir.join("run.json"), dir.join("run.txt"));
    let out = Command::new(bin)
        .args(["run", "--config", "m1-pa", "--seed", "2", "--matrices"])
        .arg(&run_json)
        .arg("--matrices-txt")
        .arg(&run_txt)
        .output()
        .unwrap();
    assert_success(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        !stdout.contains("Apply:"),
        "the text went to --matrices-txt"
    );
    let txt = std::fs::read_to_string(&run_txt).unwrap();
    for needle in [
        "M1-pa",
        "platform frame pa",
        "G = R(θgC^pa)",
        "A⁻¹",
        "thaT_3",
        "correlations",
    ] {
        assert!(txt.contains(needle), "{needle} in\n{txt}");
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&run_json).unwrap()).unwrap();
    assert_eq!(v["config"], "M1-pa");
    assert_eq!(v["frame"], "pa");
    assert!(v["conventions"].as_str().unwrap().contains("R(theta)"));
    assert!(v["base_dcm"].is_null());
    let names: Vec<&str> = v["names"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    let expect: Vec<&str> = ConfigId::M1Pa.states().iter().map(|s| s.name).collect();
    assert_eq!(names, expect);
    let rows = |key: &serde_json::Value| -> Vec<Vec<f64>> {
        key.as_array()
            .unwrap()
            .iter()
            .map(|r| {
                r.as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_f64().unwrap())
                    .collect()
            })
            .collect()
    };
    let g = rows(&v["gyro_matrix"]);
    let g_inv = rows(&v["compensation"]["platform_to_gyro_command"]);
    let a = rows(&v["accel_matrix"]);
    let a_inv = rows(&v["compensation"]["accel_to_platform"]);
    assert_eq!(g, rows(&v["compensation"]["gyro_to_platform"]));
    for i in 0..3 {
        for j in 0..3 {
            let id = if i == j { 1.0 } else { 0.0 };
            let gg: f64 = (0..3).map(|k| g[i][k] * g_inv[k][j]).sum();
            let aa: f64 = (0..3).map(|k| a_inv[i][k] * a[k][j]).sum();
            assert!((gg - id).abs() < 1e-12 && (aa - id).abs() < 1e-12);
        }
        // pa: A = I + L(θaT) is unit lower triangular.
        assert_eq!(a[i][i], 1.0);
        assert!(a[i].iter().skip(i + 1).all(|v| *v == 0.0));
    }
    let corr = rows(&v["correlation"]);
    assert_eq!(corr.len(), 12);
    assert!(corr
        .iter()
        .all(|r| r.len() == 12 && r.iter().all(|x| x.abs() <= 1.0 + 1e-9)));
    assert_eq!(v["sigma_rad"].as_array().unwrap().len(), 12);

    // record | calibrate --matrices (M2-ps): the text on stdout, R(λ), the
    // final filter's correlations.
    let (bin_file, cal_json) = (dir.join("run.bin"), dir.join("cal.json"));
    let rec = Command::new(bin)
        .args(["record", "--config", "M2-ps", "--seed", "2", "--out"])
        .arg(&bin_file)
        .output()
        .unwrap();
    assert!(
        rec.status.success(),
        "{}",
        String::from_utf8_lossy(&rec.stderr)
    );
    let out = Command::new(bin)
        .args(["calibrate", "--config", "M2-ps", "--input"])
        .arg(&bin_file)
        .arg("--matrices")
        .arg(&cal_json)
        .output()
        .unwrap();
    assert_success(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("Calibration result, M2-ps"), "{stdout}");
    assert!(stdout.contains("C^r_n = R(λ)"), "{stdout}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cal_json).unwrap()).unwrap();
    assert_eq!(v["frame"], "ps");
    assert_eq!(v["covariance_known"], true);
    assert_eq!(rows(&v["base_dcm"]).len(), 3);
    let corr = rows(&v["correlation"]);
    assert_eq!(corr.len(), 18);
    // A full covariance: some off-diagonal correlation is far from zero.
    let max_off = (0..18)
        .flat_map(|i| (0..18).filter(move |j| *j != i).map(move |j| (i, j)))
        .map(|(i, j)| corr[i][j].abs())
        .fold(0.0, f64::max);
    assert!(max_off > 0.1, "{max_off}");
    std::fs::remove_dir_all(&dir).ok();
}
