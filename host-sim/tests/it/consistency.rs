//! Model consistency: with the true parameters and the true initial state,
//! each configuration's dynamics and measurement functions reproduce the
//! truth simulator's noise-free trajectory and measurements over the whole
//! paper scenario (state residual < 1e-8 rad, accelerometer < 1e-9 g).

use host_sim::analysis::runner::filter_config;
use host_sim::sim::scenario::Scenario;
use host_sim::sim::truth::{simulate, truth_state, SimOptions};
use nalgebra::SVector;
use rollcal::ekf::{Filter, Options};
use rollcal::geometry::wrap_angle;
use rollcal::models::{self, ConfigId, Model};

fn check<M: Model<N, Z>, const N: usize, const Z: usize>(earth_rate: bool) -> (f64, f64) {
    let scenario = Scenario::paper();
    let sim = simulate(
        &scenario,
        SimOptions {
            seed: 0,
            noise: false,
            earth_rate,
        },
    );
    let id = M::ID;
    let x0 = SVector::<f64, N>::from_vec(truth_state(id, &sim.params, &sim.initial));
    let cfg = filter_config(&scenario, earth_rate, Options::plain());
    let mut f = Filter::<f64, M, N, Z>::new(cfg, x0, SVector::repeat(1e-3)).unwrap();
    let (mut worst_state, mut worst_accel) = (0.0f64, 0.0f64);
    for s in &sim.samples {
        f.predict(&s.dtheta_cmd, s.dt).unwrap();
        let truth = truth_state(id, &sim.params, &s.truth);
        for (i, (a, b)) in f.state().iter().zip(&truth).enumerate() {
            let d = if i < 3 { wrap_angle(a - b) } else { a - b };
            worst_state = worst_state.max(d.abs());
        }
        let (h, _) = f.measurement_at(f.state()).unwrap();
        let accel_row = if Z == 6 { 3 } else { 0 };
        for i in 0..3 {
            worst_accel = worst_accel.max((h[accel_row + i] - s.accel_mean_clean[i]).abs());
            if Z == 6 {
                worst_state = worst_state.max(wrap_angle(h[i] - s.truth.gimbal[i]).abs());
            }
        }
    }
    eprintln!("{id}: worst state residual {worst_state:.2e} rad, accel {worst_accel:.2e} g");
    (worst_state, worst_accel)
}

fn all(earth_rate: bool) {
    let results = [
        (ConfigId::M1Pa, check::<models::M1Pa, 12, 3>(earth_rate)),
        (ConfigId::M1Ps, check::<models::M1Ps, 15, 3>(earth_rate)),
        (ConfigId::M2Ps, check::<models::M2Ps, 18, 6>(earth_rate)),
        (ConfigId::M3Pa, check::<models::M3Pa, 15, 3>(earth_rate)),
        (ConfigId::M3Ps, check::<models::M3Ps, 18, 3>(earth_rate)),
        (ConfigId::M4Pa, check::<models::M4Pa, 12, 3>(earth_rate)),
        (ConfigId::M4Ps, check::<models::M4Ps, 15, 3>(earth_rate)),
    ];
    for (id, (s, a)) in results {
        assert!(s < 1e-8, "{id}: state residual {s:e} rad ≥ 1e-8");
        assert!(a < 1e-9, "{id}: accelerometer residual {a:e} g ≥ 1e-9");
    }
}

#[test]
fn models_reproduce_truth_with_earth_rate() {
    all(true);
}

#[test]
fn models_reproduce_truth_without_earth_rate() {
    all(false);
}
