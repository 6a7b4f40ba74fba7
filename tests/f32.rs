//! The estimator is generic over the scalar: an `f32` filter builds and runs
//! on the paper's data without panicking. (Single-precision accuracy is a
//! later issue; this only asserts that the f32 path stays finite early on.)

mod support;

use nalgebra::{SVector, Vector3};
use rollcal::ekf::{M1PaFilter, M2PsFilter, Observation, Options};
use rollcal::models::Environment;
use rollcal::wire::CalibratorConfig;
use rollcal::FilterConfig;

fn config32(c: &CalibratorConfig) -> FilterConfig<f32> {
    let c = support::filter_config(c, Options::default());
    FilterConfig {
        env: Environment {
            earth_rate_n: c.env.earth_rate_n.cast(),
            gravity_n: c.env.gravity_n.cast(),
        },
        sigma_accel: c.sigma_accel as f32,
        sigma_gyro: c.sigma_gyro as f32,
        sigma_gimbal: c.sigma_gimbal as f32,
        options: c.options,
    }
}

#[test]
fn f32_filters_run() {
    // The recorded paper stream (noise seed 1): f32 samples already.
    let (settings, samples) = support::paper_stream();
    let sigma0 = settings.prior_sigma_rad as f32;
    let mut m1 = M1PaFilter::<f32>::new(
        config32(&settings),
        SVector::zeros(),
        SVector::repeat(sigma0),
    )
    .unwrap();
    let mut m2 = M2PsFilter::<f32>::new(
        config32(&settings),
        SVector::zeros(),
        SVector::repeat(sigma0),
    )
    .unwrap();
    let (mut ok1, mut ok2) = (0, 0);
    for s in samples.iter().take(300) {
        let obs = Observation::<f32> {
            accel_mean: Vector3::from(s.accel_mean),
            gimbal: s.gimbal.map(Vector3::from),
        };
        let d = Vector3::from(s.dtheta_cmd).cast::<f32>();
        ok1 += usize::from(m1.step(&d, s.dt, &obs).is_ok());
        ok2 += usize::from(m2.step(&d, s.dt, &obs).is_ok());
    }
    eprintln!("f32: M1-pa {ok1}/300 updates, M2-ps {ok2}/300 updates accepted");
    assert!(m1
        .state()
        .iter()
        .chain(m2.state().iter())
        .all(|v| v.is_finite()));
    assert!(ok1 > 0 && ok2 > 0);
}
