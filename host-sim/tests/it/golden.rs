//! The truth simulator reproduces the golden vectors of an independent
//! implementation of docs/model.md (the root crate's `tests/data/paper_scenario_clean.csv`, see
//! `tests/data/GOLDEN-README.md`) to 1e-10.

use host_sim::sim::scenario::Scenario;
use host_sim::sim::truth::{simulate, SimOptions};

struct Row(Vec<f64>);

fn golden() -> (Vec<String>, Vec<Row>) {
    let text = include_str!("../../../tests/data/paper_scenario_clean.csv");
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_owned)
        .collect();
    let rows = lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            Row(l
                .split(',')
                .map(|v| v.trim().parse::<f64>().unwrap())
                .collect())
        })
        .collect();
    (header, rows)
}

#[test]
fn truth_simulator_matches_golden_vectors() {
    let (header, rows) = golden();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no column {name}"))
    };
    let sim = simulate(
        &Scenario::paper(),
        SimOptions {
            seed: 0,
            noise: false,
            earth_rate: true,
        },
    );
    assert_eq!(rows.len(), sim.samples.len() + 1);
    let axes = ["x", "y", "z"];
    let mut worst = [0.0f64; 5];
    for (k, row) in rows.iter().enumerate() {
        let g = |name: &str| row.0[col(name)];
        let at = if k == 0 {
            &sim.initial
        } else {
            &sim.samples[k - 1].truth
        };
        for (i, a) in axes.iter().enumerate() {
            let d = (g(&format!("accel_at_t_{a}_g")) - at.accel_at_t[i]).abs();
            worst[0] = worst[0].max(d);
            if k > 0 {
                let d = (g(&format!("accel_mean_prev_period_{a}_g"))
                    - sim.samples[k - 1].accel_mean_clean[i])
                    .abs();
                worst[1] = worst[1].max(d);
            }
            if k < sim.samples.len() {
                let d = (g(&format!("dtheta_cmd_{a}_rad")) - sim.samples[k].dtheta_cmd[i]).abs();
                worst[2] = worst[2].max(d);
            }
        }
        for (i, a) in ["alpha", "beta", "gamma"].iter().enumerate() {
            let d =
                rollcal::geometry::wrap_angle(g(&format!("gimbal_{a}_rad")) - at.gimbal[i]).abs();
            worst[3] = worst[3].max(d);
        }
        for i in 0..3 {
            for j in 0..3 {
                let d = (g(&format!("C_ps_n_{i}{j}")) - at.c_ps_n[(i, j)]).abs();
                worst[4] = worst[4].max(d);
            }
        }
    }
    let names = ["accel_at_t", "accel_mean", "dtheta_cmd", "gimbal", "C_ps_n"];
    for (n, w) in names.iter().zip(worst) {
        assert!(w < 1e-10, "{n}: worst difference {w:e} ≥ 1e-10");
        eprintln!("{n}: worst |difference| {w:.2e}");
    }
}
