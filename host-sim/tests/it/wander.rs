//! The truth of the errors that wander and of the accelerometers'
//! second-order term against their closed forms (docs/model.md §Errors that
//! wander): the Gauss–Markov parts' stationary σ and correlation, the random
//! walks' `K √t` growth, the warm-up, and the `k2 u²` output on a known
//! attitude.

use host_sim::sim::scenario::{Scenario, Wander, Warmup};
use host_sim::sim::truth::{simulate, SimOptions, TruthParams};
use host_sim::sim::wander::WanderProcess;
use nalgebra::Vector3;

const DEG_H: f64 = std::f64::consts::PI / 180.0 / 3600.0;

/// The realistic scenario's wandering figures.
fn realistic_wander() -> Wander {
    Wander {
        gyro_bias_instability_deg_h: 0.003,
        gyro_correlation_time_s: 600.0,
        gyro_rate_random_walk_deg_h_rt_h: 0.002,
        accel_bias_instability_ug: 2.0,
        accel_correlation_time_s: 900.0,
        accel_random_walk_ug_rt_h: 1.0,
        ..Wander::default()
    }
}

fn params(wander: Wander, warmup: Warmup) -> TruthParams {
    let mut s = Scenario::paper();
    s.instruments.wander = wander;
    s.instruments.warmup = warmup;
    TruthParams::from_scenario(&s)
}

/// Over many independent runs (seeds), the Gauss–Markov parts have their
/// stationary σ at the start and after 1 800 s, their correlation over a
/// lag τ is e⁻¹, and the random walks' σ after t is `K √t` (each within
/// the sampling spread of 2 000 runs: 3σ of a σ estimate is 3/√(2n) ≈ 4.7 %,
/// of a correlation 3·√((1 − ρ²)/n) ≈ 0.062).
#[test]
fn wandering_processes_follow_their_closed_forms() {
    let p = params(realistic_wander(), Warmup::default());
    let runs = 2000;
    let (h, t1) = (0.5, 1800.0);
    let steps = (t1 / h) as usize;
    let lag = (900.0 / h) as usize; // τ_a
    let mut a0 = Vec::new();
    let mut a_lag = Vec::new();
    let mut a_end = Vec::new();
    let mut g_end = Vec::new();
    let mut ra = Vec::new();
    let mut rg = Vec::new();
    for seed in 0..runs {
        let mut w = WanderProcess::new(&p, seed, true);
        a0.push(w.truth(0.0).delta_a.x);
        for k in 0..steps {
            w.advance(h);
            if k + 1 == lag {
                a_lag.push(w.truth(0.0).delta_a.x);
            }
        }
        let t = w.truth(t1);
        a_end.push(t.delta_a.y);
        g_end.push(t.delta_g.z);
        ra.push(t.r_a.x);
        rg.push(t.r_g.y);
    }
    let sd = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    let within = |got: f64, want: f64, what: &str| {
        assert!(
            (got / want - 1.0).abs() < 0.047,
            "{what}: {got:e} against {want:e}"
        );
    };
    within(sd(&a0), 2e-6, "σ of δ_a at the start");
    within(sd(&a_end), 2e-6, "σ of δ_a after 1800 s");
    within(sd(&g_end), 0.003 * DEG_H, "σ of δ_g after 1800 s");
    within(
        sd(&ra),
        1e-6 * (t1 / 3600.0).sqrt(),
        "σ of r_a after 1800 s (K √t)",
    );
    within(
        sd(&rg),
        0.002 * DEG_H * (t1 / 3600.0).sqrt(),
        "σ of r_g after 1800 s (K √t)",
    );
    let corr = a0.iter().zip(&a_lag).map(|(x, y)| x * y).sum::<f64>()
        / (a0.len() as f64 * sd(&a0) * sd(&a_lag));
    assert!(
        (corr - (-1.0f64).exp()).abs() < 0.062,
        "correlation of δ_a over τ: {corr}"
    );
}

/// Without noise (the golden run) the stochastic parts stay at zero and
/// the warm-up is `Δ e^(−t/τ_w)`.
#[test]
fn the_warm_up_decays_and_a_noise_free_run_does_not_wander() {
    let warmup = Warmup {
        gyro_deg_h: [0.005, -0.004, 0.006],
        accel_ug: [3.0, -2.0, 4.0],
        time_constant_s: 1200.0,
    };
    let p = params(realistic_wander(), warmup);
    let mut w = WanderProcess::new(&p, 7, false);
    for _ in 0..100 {
        w.advance(1.0);
    }
    let t = w.truth(2400.0);
    let k = (-2.0f64).exp();
    assert_eq!(t.delta_a, Vector3::zeros());
    assert_eq!(t.r_g, Vector3::zeros());
    assert!((t.warmup_a - Vector3::new(3e-6, -2e-6, 4e-6) * k).amax() < 1e-20);
    assert!((t.warmup_g.x - 0.005 * DEG_H * k).abs() < 1e-22);
    assert!((t.bias() - t.warmup_a).amax() == 0.0);
}

/// The second-order term on a known attitude: the platform level and
/// still, the accelerometers with `k2` only, read `k2_i u_i²`: 0 on the
/// horizontal axes and `k2_y` on the vertical one (u = 1 g), exactly as
/// the truth simulator's mean over a period; and with a 90° roll about
/// North the vertical moves to z.
#[test]
fn the_second_order_term_on_a_known_attitude() {
    let mut s = Scenario::paper();
    s.truth.theta_a_t_deg = [0.0; 3];
    s.truth.theta_a_c_deg = [0.0; 3];
    s.truth.theta_g_t_deg = [0.0; 3];
    s.truth.theta_g_c_deg = [0.0; 3];
    s.truth.lambda_deg = [0.0; 3];
    s.truth.gimbal0_deg = [0.0; 3];
    s.instruments.k2_ug_g2 = [15.0, -10.0, 20.0];
    s.site.earth_rate = false;
    let p = TruthParams::from_scenario(&s);
    let up = Vector3::new(0.0, 1.0, 0.0);
    assert!((p.accel_output(&up) - Vector3::new(0.0, 1.0 - 10e-6, 0.0)).amax() < 1e-16);
    let tilted = Vector3::new(0.0, 0.5f64.sqrt(), 0.5f64.sqrt());
    let want = tilted + Vector3::new(0.0, -10e-6 * 0.5, 20e-6 * 0.5);
    assert!((p.accel_output(&tilted) - want).amax() < 1e-16);
    // The simulator's period mean on the still, level platform.
    s.path = vec![host_sim::sim::scenario::Segment {
        axis: host_sim::sim::scenario::Axis::Named("north".into()),
        angle_deg: 0.0,
        rate_deg_s: 0.1,
        dwell_s: 10.0,
    }];
    s.timing.duration_s = 10.0;
    let sim = simulate(
        &s,
        SimOptions {
            seed: 1,
            noise: false,
            earth_rate: false,
        },
    );
    let m = sim.samples[3].accel_mean_clean;
    assert!(
        (m - Vector3::new(0.0, 1.0 - 10e-6, 0.0)).amax() < 1e-15,
        "{m}"
    );
}

/// `record --truth-history`: the sidecar holds every state at the end of
/// every period (the installation states in rad, the 36 instrument errors
/// in internal units); the last period's are the final truth, and the
/// persistent drift walks (its random walk) while the Gauss–Markov part
/// wanders about zero. Without the flag only the attitude's history.
#[test]
fn the_truth_sidecar_gives_the_history_on_request() {
    let dir = crate::support::scratch("truth-history");
    let sc = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/realistic.toml");
    let record = |name: &str, extra: &[&str]| {
        let truth = dir.join(name);
        let out = crate::support::host_sim()
            .args(["record", "--config", "M2-ps", "--seed", "2", "--scenario"])
            .arg(&sc)
            .args(["--out", "-", "--truth"])
            .arg(&truth)
            .args(extra)
            .output()
            .unwrap();
        crate::support::assert_success(&out);
        crate::support::json_file(&truth)
    };
    let full = record("full.json", &["--truth-history"]);
    let rows = |v: &serde_json::Value, k: &str| v[k].as_array().unwrap().clone();
    let history = rows(&full, "history_rad");
    let instruments = rows(&full, "instrument_history");
    assert_eq!(history.len(), 5400);
    assert_eq!(instruments.len(), 5400);
    assert_eq!(history[5399], full["truth_rad"]);
    assert_eq!(instruments[5399], full["instrument_truth"]);
    assert_eq!(instruments[0].as_array().unwrap().len(), 36);
    // dg_x (index 0) takes the random walk; dg_gm_x (index 24) the
    // Gauss–Markov part: both move over the run.
    let at = |k: usize, i: usize| instruments[k][i].as_f64().unwrap();
    assert_ne!(at(0, 0), at(5399, 0));
    assert_ne!(at(0, 24), at(5399, 24));
    let plain = record("plain.json", &[]);
    assert!(plain.get("history_rad").is_none());
    let attitude = rows(&plain, "attitude_history_rad");
    assert_eq!(attitude.len(), 5400);
    assert_eq!(attitude[5399].as_array().unwrap().len(), 3);
    std::fs::remove_dir_all(&dir).ok();
}

/// The data-sheet example of docs/model.md §Errors that wander: its
/// platform-file fragment (the page's ```toml block that starts with
/// `name = "data-sheet example"`) read as `calibrate --platform` reads it,
/// and every per-period figure the page's table quotes, as the code
/// derives it (`Noise::normalise`, `Wander::to_model`, `Wander::step`,
/// `InstrumentPrior::sigma`). Prints the table (`-- --nocapture`).
#[test]
fn the_data_sheet_example_of_the_model_page() {
    use host_sim::sim::scenario::Platform;
    let page = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/model.md");
    let text = std::fs::read_to_string(page).unwrap();
    let start = text.find("```toml\nname = \"data-sheet example\"").unwrap() + "```toml\n".len();
    let end = start + text[start..].find("```").unwrap();
    let p = Platform::from_toml(&text[start..end]).unwrap();
    let t = p.timing.period_s;
    let w = p.instruments.wander.to_model();
    let step = w.step(t);
    let sigma0 = p.instruments.prior.to_wire().sigma(&w);
    let ug = |g: f64| g * 1e6;
    let deg_h = |r: f64| r / DEG_H;
    let log_s: f64 = 5400.0;
    let rows = [
        ("period T (s)", t),
        ("noise.gyro_deg_h (°/h)", p.noise.gyro_deg_h),
        ("noise.accel_g (µg)", ug(p.noise.accel_g)),
        ("gyro GM σ (rad/s)", w.gyro_markov_sigma),
        ("gyro GM φ", step.gyro_phi),
        (
            "gyro GM driving σ per period (°/h)",
            deg_h(step.gyro_markov_q.sqrt()),
        ),
        ("gyro RW K (rad/s/√s)", w.gyro_random_walk),
        ("gyro RW σ per period (°/h)", deg_h(step.gyro_walk_q.sqrt())),
        (
            "gyro RW σ over 5400 s (°/h)",
            deg_h(w.gyro_random_walk * log_s.sqrt()),
        ),
        ("accel GM σ (g)", w.accel_markov_sigma),
        ("accel GM φ", step.accel_phi),
        (
            "accel GM driving σ per period (µg)",
            ug(step.accel_markov_q.sqrt()),
        ),
        ("accel RW K (g/√s)", w.accel_random_walk),
        ("accel RW σ per period (µg)", ug(step.accel_walk_q.sqrt())),
        (
            "accel RW σ over 5400 s (µg)",
            ug(w.accel_random_walk * log_s.sqrt()),
        ),
        ("warm-up φ_w", step.warmup_phi),
        (
            "warm-up left after 3600 s",
            (-3600.0 / w.warmup_tau_s).exp(),
        ),
        ("prior σ k2 (1/g)", sigma0[21]),
        ("prior σ dg_gm (°/h)", deg_h(sigma0[24])),
        ("prior σ ba_gm (µg)", ug(sigma0[27])),
        ("prior σ dg_wu (°/h)", deg_h(sigma0[30])),
        ("prior σ ba_wu (µg)", ug(sigma0[33])),
    ];
    for (name, v) in rows {
        println!("{name:40} {v:.6e}");
    }
    // The figures the page quotes, to the digits it prints.
    let want = [
        1.0, 0.102, 1.0, 1.4544e-8, 0.998335, 1.7306e-4, 1.6160e-10, 3.3333e-5, 2.4495e-3, 2e-6,
        0.998890, 0.094229, 1.6667e-8, 0.016667, 1.2247, 0.999167, 0.049787, 1.5e-5, 0.003, 2.0,
        0.005, 3.0,
    ];
    for ((name, got), want) in rows.iter().zip(want) {
        assert!(
            (got / want - 1.0).abs() < 5e-5,
            "{name}: {got:e}, the page says {want:e}"
        );
    }
}
