//! The instruments' own errors in the truth simulator (docs/model.md
//! §Instrument errors): the `[instruments]` scenario table, the
//! gyro drift and scale factor acting on the platform, the accelerometer
//! bias and scale factor on the means, the 21 instrument states of the truth
//! sidecar. Zero instrument errors change nothing, bit for bit.

use crate::support;

use host_sim::io::sidecar::read_sidecar;
use host_sim::io::Error;
use host_sim::sim::instruments::{
    instrument_names, instrument_truth_state, instrument_units, DEG_H, PPM, UG,
};
use host_sim::sim::scenario::{Platform, Scenario, DEG, PAPER_TOML};
use host_sim::sim::truth::{simulate, SimOptions, Simulation, TruthParams};
use host_sim::sim::wander::WanderTruth;
use nalgebra::{Matrix3, Vector3};
use rollcal::geometry::{dcm, rotation_vector};
use rollcal::models::ConfigId;

/// A `[truth]` table without installation errors, the platform aligned
/// with n at t = 0.
const ZERO_TRUTH: &str = "[truth]
theta_a_t_deg = [0.0, 0.0, 0.0]
theta_a_c_deg = [0.0, 0.0, 0.0]
theta_g_t_deg = [0.0, 0.0, 0.0]
theta_g_c_deg = [0.0, 0.0, 0.0]
lambda_deg    = [0.0, 0.0, 0.0]
gimbal0_deg   = [0.0, 0.0, 0.0]

";

/// The paper's scenario with its path replaced by `path` (TOML `[[path]]`
/// tables), lasting `duration_s`, with `truth` for its `[truth]` table when
/// given, the Earth rate as `earth_rate`, and `instruments` appended.
fn text(
    path: &str,
    duration_s: f64,
    truth: Option<&str>,
    earth_rate: bool,
    instruments: &str,
) -> String {
    let t = PAPER_TOML.find("[truth]").unwrap();
    let site = PAPER_TOML.find("[site]").unwrap();
    let a = PAPER_TOML.find("[[path]]").unwrap();
    let b = PAPER_TOML.find("[noise]").unwrap();
    let truth = truth.unwrap_or(&PAPER_TOML[t..site]);
    format!(
        "{}{truth}{}{path}\n{}\n{instruments}",
        &PAPER_TOML[..t],
        &PAPER_TOML[site..a],
        &PAPER_TOML[b..]
    )
    .replace(
        "duration_s = 5400.0",
        &format!("duration_s = {duration_s:?}"),
    )
    .replace("earth_rate = true", &format!("earth_rate = {earth_rate}"))
}

fn scenario(path: &str, duration_s: f64, truth: Option<&str>, earth: bool, ins: &str) -> Scenario {
    Scenario::from_toml(&text(path, duration_s, truth, earth, ins)).unwrap()
}

/// 10° about South, then 10° about East, at 0.1 °/s: 200 s.
const SHORT_PATH: &str = "[[path]]\naxis = \"south\"\nangle_deg = 10.0\nrate_deg_s = 0.1\n\n\
                          [[path]]\naxis = \"east\"\nangle_deg = 10.0\nrate_deg_s = 0.1\n";

/// A pure dwell of `s` seconds: no commanded path rate.
fn dwell(s: f64) -> String {
    format!("[[path]]\naxis = \"up\"\nangle_deg = 0.0\nrate_deg_s = 0.1\ndwell_s = {s:?}\n")
}

fn sim(s: &Scenario, noise: bool) -> Simulation {
    simulate(
        s,
        SimOptions {
            seed: 3,
            noise,
            earth_rate: true,
        },
    )
}

fn v3(a: [f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

#[test]
fn zero_instrument_errors_are_bit_identical() {
    let plain = scenario(SHORT_PATH, 200.0, None, true, "");
    assert!(plain.instruments.is_zero() && plain.instruments.is_default());
    let zeros = scenario(
        SHORT_PATH,
        200.0,
        None,
        true,
        "[instruments]\ndg_deg_h = [0.0, 0.0, 0.0]\nd_g_deg_h_g = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]\n\
         kg_ppm = [0.0, 0.0, 0.0]\nba_ug = [0.0, 0.0, 0.0]\nka_ppm = [0.0, 0.0, 0.0]\n\
         [instruments.prior]\nsigma_kg_ppm = 500.0\n",
    );
    assert!(zeros.instruments.is_zero() && !zeros.instruments.is_default());
    let (a, b) = (sim(&plain, true), sim(&zeros, true));
    assert!(!b.params.has_instrument_errors());
    // Debug prints every f64 in its shortest round-trip form: equal text is
    // equal bits.
    assert_eq!(format!("{:?}", a.samples), format!("{:?}", b.samples));
    assert_eq!(format!("{:?}", a.initial), format!("{:?}", b.initial));
}

#[test]
fn accel_bias_shifts_the_clean_mean_by_exactly_ba() {
    let plain = scenario(SHORT_PATH, 200.0, None, true, "");
    let ba = [30.0, -20.0, 45.0];
    let biased = scenario(
        SHORT_PATH,
        200.0,
        None,
        true,
        &format!("[instruments]\nba_ug = {ba:?}\n"),
    );
    let (a, b) = (sim(&plain, true), sim(&biased, true));
    let ba = v3(ba) * UG;
    for (x, y) in a.samples.iter().zip(&b.samples) {
        // The gyros are untouched: the same attitude, bit for bit.
        assert_eq!(x.truth.c_ps_n, y.truth.c_ps_n);
        let d = y.accel_mean_clean - x.accel_mean_clean - ba;
        assert!(d.amax() <= 1e-15, "period {}: {d}", x.k);
        let d = y.truth.accel_at_t - x.truth.accel_at_t - ba;
        assert!(d.amax() <= 1e-15, "period {}: {d}", x.k);
        let d = y.accel_mean - x.accel_mean - ba;
        assert!(d.amax() <= 1e-15, "period {}: {d}", x.k);
    }
}

#[test]
fn accel_scale_factor_scales_the_clean_mean() {
    let plain = scenario(SHORT_PATH, 200.0, None, true, "");
    let ka = [400.0, -250.0, 350.0];
    let scaled = scenario(
        SHORT_PATH,
        200.0,
        None,
        true,
        &format!("[instruments]\nka_ppm = {ka:?}\n"),
    );
    let (a, b) = (sim(&plain, false), sim(&scaled, false));
    let k = Vector3::repeat(1.0) + v3(ka) * PPM;
    for (x, y) in a.samples.iter().zip(&b.samples) {
        assert_eq!(x.truth.c_ps_n, y.truth.c_ps_n);
        let d = y.accel_mean_clean - x.accel_mean_clean.component_mul(&k);
        assert!(d.amax() <= 1e-15, "period {}: {d}", x.k);
    }
    // Each axis is scaled by its own factor: not by a common one.
    let last = (a.samples.last().unwrap(), b.samples.last().unwrap());
    let ratio = last.1.accel_mean_clean.y / last.0.accel_mean_clean.y - 1.0;
    assert!((ratio - ka[1] * PPM).abs() < 1e-12, "{ratio}");
}

/// A constant drift at rest (no path rate, no Earth rate, no noise) turns
/// the platform at the constant body rate `G dg`: `C^ps_n(t) = R(G dg t)
/// C^ps_n(0)`, with the paper's installation errors in G; the error-free
/// platform does not move.
#[test]
fn constant_drift_rotates_the_platform_by_g_dg_t() {
    let path = dwell(600.0);
    let plain = scenario(&path, 600.0, None, false, "");
    let dg = [2.0, -3.0, 1.5];
    let drifting = scenario(
        &path,
        600.0,
        None,
        false,
        &format!("[instruments]\ndg_deg_h = {dg:?}\n"),
    );
    let (a, b) = (sim(&plain, false), sim(&drifting, false));
    let rate = b.params.g() * v3(dg) * DEG_H;
    for (x, y) in a.samples.iter().zip(&b.samples) {
        assert_eq!(x.truth.c_ps_n, a.initial.c_ps_n);
        let turned = rotation_vector(&(y.truth.c_ps_n * b.initial.c_ps_n.transpose()));
        let d = turned - rate * y.truth.t;
        assert!(d.amax() < 1e-12, "t = {} s: {d}", y.truth.t);
    }
    // 600 s of ≈ 3.9 °/h: ≈ 0.65°, nowhere near the tolerance.
    assert!((rate * 600.0).norm() > 0.01);
}

/// A commanded rotation about one axis turns the platform by
/// `(1 + kg_i)` times the angle (no installation errors, no Earth rate):
/// the error against the error-free run is `kg_i · angle` about that axis.
#[test]
fn gyro_scale_factor_scales_a_commanded_rotation() {
    let kg = [300.0, 1000.0, -500.0];
    for (axis, i) in [("north", 0), ("up", 1), ("east", 2)] {
        let path = format!("[[path]]\naxis = \"{axis}\"\nangle_deg = 90.0\nrate_deg_s = 1.0\n");
        let plain = scenario(&path, 90.0, Some(ZERO_TRUTH), false, "");
        let scaled = scenario(
            &path,
            90.0,
            Some(ZERO_TRUTH),
            false,
            &format!("[instruments]\nkg_ppm = {kg:?}\n"),
        );
        let (a, b) = (sim(&plain, false), sim(&scaled, false));
        let (x, y) = (a.samples.last().unwrap(), b.samples.last().unwrap());
        let error = rotation_vector(&(y.truth.c_ps_n * x.truth.c_ps_n.transpose()));
        let mut expected = Vector3::zeros();
        expected[i] = kg[i] * PPM * 90.0 * DEG;
        let d = error - expected;
        assert!(d.amax() < 1e-12, "{axis}: {error} vs {expected}");
        // And the platform itself turned by (1 + kg_i)·90° about the axis.
        let turned = rotation_vector(&y.truth.c_ps_n);
        assert!((turned[i] - (1.0 + kg[i] * PPM) * 90.0 * DEG).abs() < 1e-12);
    }
}

/// The g-sensitive drift turns a platform at rest at `D_g f^ps` with
/// `f^ps = C^ps_n f^n` (a tilted platform, so every column of D_g counts):
/// over the first second the turn is `D_g f^ps(0) · 1 s` up to the change
/// of `f^ps` within it (≈ 1e-10 rad); a transposed D_g or `f^n` in place of
/// `f^ps` would be off by ≈ 1e-5 rad.
#[test]
fn g_sensitive_drift_is_d_g_times_the_specific_force() {
    let truth = ZERO_TRUTH.replace(
        "gimbal0_deg   = [0.0, 0.0, 0.0]",
        "gimbal0_deg   = [30.0, 20.0, -40.0]",
    );
    let d_g = [[3.0, 1.0, -0.5], [-1.0, 2.0, 0.8], [0.6, -1.2, 2.5]];
    let sc = scenario(
        &dwell(60.0),
        60.0,
        Some(&truth),
        false,
        &format!("[instruments]\nd_g_deg_h_g = {d_g:?}\n"),
    );
    let s = sim(&sc, false);
    let f_ps = s.initial.c_ps_n * Vector3::new(0.0, 1.0, 0.0);
    let d = Matrix3::from_fn(|r, c| d_g[r][c]) * DEG_H;
    assert_eq!(s.params.d_g, d);
    let first = &s.samples[0].truth;
    let turned = rotation_vector(&(first.c_ps_n * s.initial.c_ps_n.transpose()));
    let diff = turned - d * f_ps;
    assert!(diff.amax() < 1e-9, "{turned} vs {}", d * f_ps);
    assert!((d.transpose() * f_ps - d * f_ps).amax() > 1e-6);
    // The accelerometers (no installation errors) see f^ps itself.
    assert!((s.initial.accel_at_t - f_ps).amax() < 1e-15);
}

#[test]
fn scenario_errors_name_the_field() {
    let zero3 = "[0.0, 0.0, 0.0]";
    for (table, field) in [
        (
            "[instruments]\ndg_deg_h = [11.0, 0.0, 0.0]\n",
            "instruments.dg_deg_h",
        ),
        (
            &format!("[instruments]\nd_g_deg_h_g = [{zero3}, [0.0, nan, 0.0], {zero3}]\n"),
            "instruments.d_g_deg_h_g[1]",
        ),
        (
            "[instruments]\nkg_ppm = [0.0, 2e4, 0.0]\n",
            "instruments.kg_ppm",
        ),
        (
            "[instruments]\nba_ug = [-2e4, 0.0, 0.0]\n",
            "instruments.ba_ug",
        ),
        (
            "[instruments]\nka_ppm = [0.0, 0.0, inf]\n",
            "instruments.ka_ppm",
        ),
        (
            "[instruments.prior]\nsigma_kg_ppm = nan\n",
            "instruments.prior.sigma_kg_ppm",
        ),
        (
            "[instruments.wander]\naccel_bias_instability_ug = 2.0\n",
            "instruments.wander.accel_correlation_time_s",
        ),
        (
            "[instruments.wander]\ngyro_rate_random_walk_deg_h_rt_h = -0.002\n",
            "instruments.wander.gyro_rate_random_walk_deg_h_rt_h",
        ),
        (
            "[instruments.wander]\naccel_random_walk_ug_rt_h = 1e9\n",
            "instruments.wander.accel_random_walk_ug_rt_h",
        ),
        (
            "[instruments.prior]\nsigma_ba_ug = 0.0\n[instruments.wander]\naccel_random_walk_ug_rt_h = 1.0\n",
            "instruments.prior.sigma_ba_ug = 0 (not estimated)",
        ),
        (
            "[instruments.warmup]\naccel_ug = [3.0, 0.0, 0.0]\n",
            "instruments.warmup.time_constant_s",
        ),
        (
            "[instruments]\nk2_ug_g2 = [1e5, 0.0, 0.0]\n",
            "instruments.k2_ug_g2",
        ),
        (
            "[instruments.prior]\nsigma_dg_deg_h = -1.0\n",
            "instruments.prior.sigma_dg_deg_h",
        ),
        (
            "[instruments]\nbias_ug = [1.0, 2.0, 3.0]\n",
            "unknown field `bias_ug`",
        ),
        (
            "[instruments.prior]\nsigma_foo = 1.0\n",
            "unknown field `sigma_foo`",
        ),
        ("[instruments]\nkg_ppm = [1.0, 2.0]\n", "line "),
    ] {
        let e = Scenario::from_toml(&format!("{PAPER_TOML}\n{table}")).unwrap_err();
        assert!(e.0.contains(field), "{table}: {e}");
        assert!(!e.0.contains('\n'), "{e}");
    }
}

#[test]
fn instrumented_scenario_has_the_spec_values() {
    let file =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/instrumented.toml");
    let sc = Scenario::from_file(&file).unwrap();
    let ins = &sc.instruments;
    assert_eq!(ins.dg_deg_h, [0.02, -0.03, 0.015]);
    assert_eq!(
        ins.d_g_deg_h_g,
        [
            [0.03, 0.01, -0.005],
            [-0.01, 0.02, 0.008],
            [0.006, -0.012, 0.025]
        ]
    );
    assert_eq!(ins.kg_ppm, [60.0, -40.0, 80.0]);
    assert_eq!(ins.ba_ug, [30.0, -20.0, 45.0]);
    assert_eq!(ins.ka_ppm, [40.0, -25.0, 35.0]);
    assert!(!ins.is_zero());
    let s0 = ins.prior.to_wire().sigma(&ins.wander.to_model());
    assert_eq!(s0[0], DEG_H);
    assert_eq!(s0[11], DEG_H);
    assert_eq!(s0[12], 2000.0 * PPM);
    assert_eq!(s0[17], 1000.0 * UG);
    assert_eq!(s0[20], 1000.0 * PPM);
    assert_eq!(s0[21], 100.0 * UG);
    assert_eq!(s0[24..], [0.0; 12]); // no wandering parts in this scenario
                                     // A written scenario (`design --out`) keeps the table; the paper's has none.
    let written = toml::to_string(&sc).unwrap();
    assert_eq!(Scenario::from_toml(&written).unwrap(), sc);
    assert!(!toml::to_string(&Scenario::paper())
        .unwrap()
        .contains("instruments"));
    // Everything else is the paper's scenario.
    let mut rest = sc.clone();
    rest.instruments = Default::default();
    rest.name = "paper".into();
    assert_eq!(rest, Scenario::paper());

    let p = TruthParams::from_scenario(&sc);
    assert!(p.has_instrument_errors());
    assert_eq!(p.dg, v3([0.02, -0.03, 0.015]) * DEG_H);
    assert_eq!(p.ba, v3([30.0, -20.0, 45.0]) * UG);
    // The ps state holds D_g; the pa state D_g R(θaC), so that
    // D_g^pa f^pa = D_g f^ps for f^pa = R(−θaC) f^ps.
    let ps = instrument_truth_state(ConfigId::M2Ps, &p, &WanderTruth::zero());
    let pa = instrument_truth_state(ConfigId::M1Pa, &p, &WanderTruth::zero());
    assert_eq!(ps[4], 0.01 * DEG_H);
    assert_eq!((&ps[..3], &ps[12..]), (&pa[..3], &pa[12..]));
    let f_ps = Vector3::new(0.3, 0.9, -0.2);
    let f_pa = dcm(&(-p.theta_a_c)) * f_ps;
    let d_pa = Matrix3::from_fn(|r, c| pa[3 + 3 * r + c]);
    assert!((d_pa * f_pa - p.d_g * f_ps).amax() < 1e-22);
    assert!((d_pa - p.d_g).amax() > 1e-10, "pa differs from ps");
    assert_eq!(p.gyro_input(&Vector3::zeros(), &f_ps), p.dg + p.d_g * f_ps);
    assert!(
        (p.accel_output(&f_ps)
            - (p.ba + (p.a() * f_ps).component_mul(&(Vector3::repeat(1.0) + p.ka))))
        .amax()
            < 1e-15
    );
}

/// `record` writes the 21 true instrument errors into the truth sidecar
/// (`Dgpa_*` for a pa configuration), `--accel-bias-ug` added to the
/// scenario's `ba`; a sidecar without them reads as zero; a wrong length
/// is an error.
#[test]
fn sidecar_records_the_instrument_truth() {
    let dir = support::scratch("instruments-sidecar");
    let file = dir.join("short.toml");
    let instrumented = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/instrumented.toml"),
    )
    .unwrap();
    let ins = &instrumented[instrumented.find("[instruments]").unwrap()..];
    std::fs::write(&file, text(SHORT_PATH, 200.0, None, true, ins)).unwrap();
    let sc = Scenario::from_file(&file).unwrap();
    for (config, bias, names) in [
        (
            ConfigId::M1Pa,
            [10.0, 0.0, -5.0],
            instrument_names(ConfigId::M1Pa),
        ),
        (ConfigId::M2Ps, [0.0; 3], instrument_names(ConfigId::M2Ps)),
    ] {
        let truth = dir.join(format!("{config}.json"));
        let bias_arg = format!("{},{},{}", bias[0], bias[1], bias[2]);
        let out = support::host_sim()
            .args(["record", "--config", config.as_str(), "--seed", "1"])
            .args(["--accel-bias-ug", &bias_arg, "--out"])
            .arg(dir.join("s.bin"))
            .arg("--scenario")
            .arg(&file)
            .arg("--truth")
            .arg(&truth)
            .output()
            .unwrap();
        support::assert_success(&out);
        let json = support::json_file(&truth);
        assert_eq!(json["instrument_names"], serde_json::json!(names.to_vec()));
        assert_eq!(
            json["instrument_units"],
            serde_json::json!(instrument_units().to_vec())
        );
        // The labels are the units of the numbers: internal (rad/s, g, …).
        assert_eq!(
            (&json["instrument_units"][0], &json["instrument_units"][15]),
            (&serde_json::json!("rad/s"), &serde_json::json!("g"))
        );
        let mut with_bias = sc.clone();
        for (a, b) in with_bias.instruments.ba_ug.iter_mut().zip(bias) {
            *a += b;
        }
        let expected = instrument_truth_state(
            config,
            &TruthParams::from_scenario(&with_bias),
            &WanderTruth::zero(),
        );
        let got = read_sidecar(&truth, config).unwrap().instruments;
        for (i, (g, e)) in got.iter().zip(expected).enumerate() {
            assert!((g - e).abs() <= 1e-15 * e.abs(), "{}: {g} vs {e}", names[i]);
        }
        assert!((got[15] - 40.0 * UG).abs() < 1e-18 || bias[0] == 0.0);
    }

    // A sidecar of before: no instrument keys, zero errors.
    let truth = dir.join("M2-ps.json");
    let mut json = support::json_file(&truth);
    for key in ["instrument_names", "instrument_units", "instrument_truth"] {
        json.as_object_mut().unwrap().remove(key);
    }
    let old = dir.join("old.json");
    std::fs::write(&old, json.to_string()).unwrap();
    let s = read_sidecar(&old, ConfigId::M2Ps).unwrap();
    assert_eq!(s.instruments, [0.0; 36]);
    assert!(!s.truth.is_empty());

    // A wrong length or a non-array is a typed error naming the key.
    json["instrument_truth"] = serde_json::json!(vec![0.0; 20]);
    std::fs::write(&old, json.to_string()).unwrap();
    let e = read_sidecar(&old, ConfigId::M2Ps).err().unwrap();
    assert!(
        matches!(
            e,
            Error::SidecarLength {
                found: 20,
                expected: 36,
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string()
            .contains("'instrument_truth' has 20 values, not 36"),
        "{e}"
    );
    json["instrument_truth"] = serde_json::json!("none");
    std::fs::write(&old, json.to_string()).unwrap();
    let e = read_sidecar(&old, ConfigId::M2Ps).err().unwrap();
    assert!(matches!(e, Error::SidecarArray { .. }), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The keys of the errors that wander, in a scenario file and in a
/// platform file alike: a negative σ, a zero or negative correlation or
/// warm-up time where its term is given, an absurd magnitude or time, a
/// prior σ of k2 below zero, and a figure outside the calibrator's bounds
/// (`rollcal::wire::ConfigField::bounds`) are refused naming the key.
#[test]
fn wandering_keys_are_validated_naming_the_field() {
    let w = "[instruments.wander]\n";
    let wander_cases = [
        (
            "gyro_bias_instability_deg_h = -0.003\ngyro_correlation_time_s = 600.0",
            "instruments.wander.gyro_bias_instability_deg_h = -0.003",
        ),
        (
            "accel_bias_instability_ug = -2.0\naccel_correlation_time_s = 900.0",
            "instruments.wander.accel_bias_instability_ug = -2",
        ),
        (
            "accel_random_walk_ug_rt_h = -1.0",
            "instruments.wander.accel_random_walk_ug_rt_h = -1",
        ),
        (
            "gyro_warmup_deg_h = -0.005\nwarmup_time_constant_s = 1200.0",
            "instruments.wander.gyro_warmup_deg_h = -0.005",
        ),
        (
            "accel_warmup_ug = nan\nwarmup_time_constant_s = 1200.0",
            "instruments.wander.accel_warmup_ug = NaN",
        ),
        // Zero or negative correlation time with its instability given.
        (
            "gyro_bias_instability_deg_h = 0.003\ngyro_correlation_time_s = 0.0",
            "instruments.wander.gyro_correlation_time_s = 0 s: a bias instability",
        ),
        (
            "gyro_bias_instability_deg_h = 0.003\ngyro_correlation_time_s = -600.0",
            "instruments.wander.gyro_correlation_time_s = -600 must be finite, ≥ 0",
        ),
        (
            "accel_bias_instability_ug = 2.0\naccel_correlation_time_s = -900.0",
            "instruments.wander.accel_correlation_time_s = -900 must be finite, ≥ 0",
        ),
        (
            "accel_warmup_ug = 3.0\nwarmup_time_constant_s = 0.0",
            "instruments.wander.warmup_time_constant_s = 0 s: a warm-up",
        ),
        (
            "accel_warmup_ug = 3.0\nwarmup_time_constant_s = -1200.0",
            "instruments.wander.warmup_time_constant_s = -1200 must be finite, ≥ 0",
        ),
        // Absurd magnitudes and times.
        (
            "gyro_bias_instability_deg_h = 1e6\ngyro_correlation_time_s = 600.0",
            "instruments.wander.gyro_bias_instability_deg_h = 1000000 must be finite, ≥ 0 and ≤",
        ),
        (
            "accel_warmup_ug = 1e9\nwarmup_time_constant_s = 1200.0",
            "instruments.wander.accel_warmup_ug = 1000000000 must be finite, ≥ 0 and ≤",
        ),
        (
            "accel_bias_instability_ug = 2.0\naccel_correlation_time_s = 1e12",
            "instruments.wander.accel_correlation_time_s = 1000000000000 must be finite, ≥ 0 and ≤",
        ),
        (
            "gyro_warmup_deg_h = 0.005\nwarmup_time_constant_s = inf",
            "instruments.wander.warmup_time_constant_s = inf must be finite",
        ),
    ];
    let cases: Vec<(String, &str)> = wander_cases
        .iter()
        .map(|(t, f)| (format!("{w}{t}\n"), *f))
        .chain([
            (
                "[instruments.prior]\nsigma_k2_ug_g2 = -100.0\n".to_string(),
                "instruments.prior.sigma_k2_ug_g2",
            ),
            (
                "[instruments.prior]\nsigma_dg_deg_h = 0.0\n[instruments.wander]\ngyro_rate_random_walk_deg_h_rt_h = 0.002\n".to_string(),
                "instruments.prior.sigma_dg_deg_h = 0 (not estimated)",
            ),
            // Outside the calibrator's bounds (issue 43): named by the key,
            // in its units, with the Configure field it becomes.
            (
                "[instruments.prior]\nsigma_k2_ug_g2 = 1e8\n".to_string(),
                "instruments.prior.sigma_k2_ug_g2 = 1e8 µg/g² is outside the calibrator's bounds: instrument_prior.k2 = 100, not 0 or 1e-12..0.01 g/g²",
            ),
            (
                "[instruments.prior]\nsigma_kg_ppm = 1e6\n".to_string(),
                "instruments.prior.sigma_kg_ppm = 1e6 ppm is outside the calibrator's bounds: instrument_prior.kg = 1, not 0 or 1e-12..0.1",
            ),
            (
                format!("{w}gyro_bias_instability_deg_h = 1e-12\ngyro_correlation_time_s = 600.0\n"),
                "instruments.wander.gyro_bias_instability_deg_h = 1e-12 °/h is outside the calibrator's bounds: wander.gyro_markov_sigma = 4.8481e-18, not 0 or 1e-15..4.848e-3 rad/s",
            ),
        ])
        .collect();
    let platform_head =
        "config = \"M2-ps\"\nerrors = \"full\"\n[site]\nlatitude_deg = 34.25\nearth_rate = true\n\
                         [noise]\naccel_g = 1e-6\ngyro_deg_h = 0.1\ngimbal_arcsec = 10.0\n\
                         [timing]\nperiod_s = 1.0\n[prior]\nsigma_deg = 1.0\n";
    for (table, field) in &cases {
        let e = Scenario::from_toml(&format!("{PAPER_TOML}\n{table}")).unwrap_err();
        assert!(e.0.contains(field), "scenario {table}: {e}");
        let e = Platform::from_toml(&format!("{platform_head}{table}")).unwrap_err();
        assert!(e.0.contains(field), "platform {table}: {e}");
    }
    // The truth's warm-up (a scenario's alone): a negative or zero time
    // constant with a warm-up, an absurd amplitude.
    for (table, field) in [
        (
            "[instruments.warmup]\naccel_ug = [2.0, 2.0, 2.0]\ntime_constant_s = -1200.0\n",
            "instruments.warmup.time_constant_s = -1200",
        ),
        (
            "[instruments.warmup]\ngyro_deg_h = [0.005, 0.0, 0.0]\ntime_constant_s = 0.0\n",
            "instruments.warmup.time_constant_s = 0",
        ),
        (
            "[instruments.warmup]\ngyro_deg_h = [1e6, 0.0, 0.0]\ntime_constant_s = 1200.0\n",
            "instruments.warmup.gyro_deg_h",
        ),
    ] {
        let e = Scenario::from_toml(&format!("{PAPER_TOML}\n{table}")).unwrap_err();
        assert!(e.0.contains(field), "scenario {table}: {e}");
    }
    // A platform file has no truth: a warm-up's values are refused there.
    let e = Platform::from_toml(&format!(
        "{platform_head}[instruments.warmup]\naccel_ug = [2.0, 2.0, 2.0]\ntime_constant_s = 1200.0\n"
    ))
    .unwrap_err();
    assert!(e.0.contains("unknown field `warmup`"), "{e}");
}
