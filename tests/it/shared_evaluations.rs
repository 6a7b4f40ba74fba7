//! The shared evaluations of the model give exactly (bit for bit) what the
//! functions they replace give:
//!
//! - [`EulerTrig`] (one `sin`/`cos` of the Euler angles per attitude) against
//!   `gimbal_dcm`, `gimbal_rate_matrix`, `gimbal_rate_inverse`,
//!   `d_gimbal_rate_inverse_times` and `d_gimbal_dcm_times`;
//! - [`InstallationMatrices`] (rotations and right Jacobians of the
//!   installation angles, computed once per parameter value) against
//!   `gyro_matrix`, `accel_matrix`, `dcm` and `d_dcm_times`;
//! - `Layout::accel_output_and_jacobian` (one rotation per node) against
//!   `accel_output` and `accel_jacobian` apart, for every configuration.
//!
//! (The U-D factor's shared evaluations, `Ud::covariance_entry` and the
//! time update's rows without forming the factor, are checked the same way
//! by the unit tests of the crate's private `ekf::factor`.)
//!
//! Equality is exact: these replace their originals on the estimator's path,
//! and `tools/compare-runs.sh` relies on the answers not moving at all.
//!
//! Two are not exact. `EulerTrig::rotate` rotates a vector in its own order
//! of operations (to rounding). `Layout::mean_accel_output`, the single-precision
//! filter's f64 value of the period's mean specific force, applies Simpson's
//! rule before `A` and forms M1's small rotations and the Euler angles'
//! increments of trigonometry in the filter's precision;
//! it is checked against `Layout::mean_accel`'s value to the error its
//! documentation states.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use rollcal::command::{CommandFrame, PeriodIn};
use rollcal::geometry::{
    d_dcm_times, d_gimbal_dcm_times, d_gimbal_rate_inverse_times, dcm, earth_rate_n, gimbal_dcm,
    gimbal_rate_inverse, gimbal_rate_matrix, gravity_n, EulerTrig, EARTH_RATE,
};
use rollcal::instruments::{accel_matrix, gyro_matrix};
use rollcal::models::{ConfigId, Environment, InstallationMatrices, Model, PeriodPropagation};

/// A deterministic sequence in (−1, 1).
fn lcg(state: &mut u64) -> f64 {
    *state = state
        .wrapping_mul(6_364_136_223_846_793_005)
        .wrapping_add(1_442_695_040_888_963_407);
    ((*state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
}

fn vec3(s: &mut u64, scale: f64) -> Vector3<f64> {
    Vector3::new(lcg(s) * scale, lcg(s) * scale, lcg(s) * scale)
}

#[test]
fn euler_trig_equals_the_free_functions() {
    let mut s = 7;
    for _ in 0..200 {
        let angles = vec3(&mut s, 3.0);
        let w = vec3(&mut s, 1e-3);
        let trig = EulerTrig::new(&angles);
        let c = trig.dcm();
        assert_eq!(c, gimbal_dcm(&angles));
        // Rotating a vector: to rounding (its own order of operations).
        let v = vec3(&mut s, 1.0);
        assert!((trig.rotate(&v) - c * v).amax() < 4.0 * f64::EPSILON);
        assert_eq!(trig.rate_matrix(), gimbal_rate_matrix(angles.y, angles.z));
        let t = trig.rate_inverse();
        assert_eq!(t, gimbal_rate_inverse(angles.y, angles.z));
        if let Some(t) = t {
            assert_eq!(
                trig.d_rate_inverse_times(&t, &w),
                d_gimbal_rate_inverse_times(&t, angles.y, angles.z, &w)
            );
        }
        assert_eq!(trig.d_dcm_times(&c, &w), d_gimbal_dcm_times(&angles, &w));
    }
    // At gimbal lock both refuse.
    let lock = EulerTrig::new(&Vector3::new(0.3, core::f64::consts::FRAC_PI_2, 0.1));
    assert!(lock.rate_inverse().is_none());
}

#[test]
fn installation_matrices_equal_their_definitions() {
    let mut s = 11;
    for _ in 0..200 {
        let x = SVector::<f64, 18>::from_fn(|_, _| lcg(&mut s) * 0.05);
        let layout = ConfigId::M2Ps.layout();
        let m = layout.matrices(&x);
        let p = &m.params;
        assert_eq!(m.g, gyro_matrix(&p.theta_g_c, &p.theta_g_t));
        assert_eq!(m.a, accel_matrix(&p.theta_a_c, &p.theta_a_t));
        assert_eq!(m.c_rn, dcm(&p.lambda));
        let v = vec3(&mut s, 1.0);
        assert_eq!(
            InstallationMatrices::d_rotation_times(&m.r_g_c, &m.jr_g_c, &v),
            d_dcm_times(&p.theta_g_c, &v)
        );
        assert_eq!(
            InstallationMatrices::d_rotation_times(&m.r_a_c, &m.jr_a_c, &v),
            d_dcm_times(&(-p.theta_a_c), &v)
        );
        assert_eq!(
            InstallationMatrices::d_rotation_times(&m.c_rn, &m.jr_lambda, &v),
            d_dcm_times(&p.lambda, &v)
        );
        // Rounded to f32 element by element.
        let m32: InstallationMatrices<f32> = m.to_precision();
        assert_eq!(m32.a, m.a.map(|e| e as f32));
        assert_eq!(m32.params.lambda, p.lambda.map(|e| e as f32));
        // G − I, formed without the identity: G less I to f64's rounding,
        // and computed in f32 to a few of f32's roundings of |G − I|
        // itself, where G in f32 less I keeps only ε_f32 of 1.
        let dev = m.g - Matrix3::identity();
        assert!((m.g_deviation - dev).amax() < 4.0 * f64::EPSILON);
        let g32 = InstallationMatrices::new(m32.params);
        let err = (g32.g_deviation.map(f64::from) - dev).amax();
        assert!(
            err < 8.0 * f64::from(f32::EPSILON) * dev.amax(),
            "f32's G − I off by {err:e} (|G − I| {:e})",
            dev.amax()
        );
    }
}

fn accel_pair<M: Model<N, Z>, const N: usize, const Z: usize>(seed: u64) {
    let mut s = seed;
    let layout = M::LAYOUT;
    let env = Environment {
        earth_rate_n: earth_rate_n(EARTH_RATE, 0.6),
        gravity_n: gravity_n(),
    };
    for _ in 0..50 {
        let mut x = SVector::<f64, N>::from_fn(|_, _| lcg(&mut s) * 0.01);
        for v in x.iter_mut().take(3) {
            *v *= 100.0;
        }
        let c_cn = dcm(&vec3(&mut s, 2.0));
        let m = layout.matrices(&x);
        let att = layout.attitude(&x);
        let (z, h): (Vector3<f64>, SMatrix<f64, 3, N>) =
            layout.accel_output_and_jacobian(&env, &m, &att, &c_cn);
        assert_eq!(z, layout.accel_output(&env, &m, &att, &c_cn));
        let h_apart: SMatrix<f64, 3, N> = layout.accel_jacobian(&env, &m, &att, &c_cn);
        assert_eq!(h, h_apart);
        // And the value against the definition Z_a = A C^p_n f^n.
        let c_pn: Matrix3<f64> = layout.platform_dcm(&att, &m.c_rn, &c_cn);
        assert_eq!(z, m.a * (c_pn * env.gravity_n));
    }
}

/// The largest difference (g) of `mean_accel_output` in f64 and in f32 from
/// `mean_accel`'s value, over periods at random attitudes (misalignment
/// angles up to 1 mrad, Euler angles up to 2 rad), installation errors and
/// commanded increments (up to 3 mrad per axis).
fn mean_accel_output_error<M: Model<N, Z>, const N: usize, const Z: usize>(
    seed: u64,
) -> (f64, f64) {
    let mut s = seed;
    let layout = M::LAYOUT;
    let env = Environment {
        earth_rate_n: earth_rate_n(EARTH_RATE, 0.6),
        gravity_n: gravity_n(),
    };
    let (mut err64, mut err32): (f64, f64) = (0.0, 0.0);
    for _ in 0..50 {
        let mut x = SVector::<f64, N>::from_fn(|_, _| lcg(&mut s) * 1e-3);
        if layout.attitude != rollcal::models::AttitudeKind::Misalignment {
            for v in x.iter_mut().take(3) {
                *v *= 2000.0;
            }
        }
        let frame = CommandFrame {
            c_cn: dcm(&vec3(&mut s, 2.0)),
            earth_rate_n: env.earth_rate_n,
        };
        let increment = vec3(&mut s, 3e-3);
        let period = frame.period(&increment, 1.0);
        let m = layout.matrices(&x);
        let prop: PeriodPropagation<f64, N> = layout
            .propagate(&env, &m, &layout.attitude(&x), &period)
            .expect("no gimbal lock");
        let mut h = SMatrix::<f64, 3, N>::zeros();
        let (z, _) = layout.mean_accel(&env, &m, &prop, &period, &mut h);
        let turn64 = PeriodIn::<f64>::of(&period).turn;
        let z64 = layout.mean_accel_output(
            &env,
            &m.a,
            &m.c_rn,
            &m.params.instruments,
            &prop.att,
            &period,
            &turn64,
        );
        // In f32 with the frame's turn as the single-precision filter forms
        // it (its f64 nodes are `period`'s to 1e-13).
        let (period32, period_in32) = frame.period_in::<f32>(&increment, 1.0);
        let z32 = layout.mean_accel_output(
            &env,
            &m.a,
            &m.c_rn,
            &m.params.instruments,
            &prop.att,
            &period32,
            &period_in32.turn,
        );
        err64 = err64.max((z64 - z).amax());
        err32 = err32.max((z32 - z).amax());
    }
    (err64, err32)
}

#[test]
fn mean_accel_output_is_mean_accels_value() {
    use rollcal::models::{M1Pa, M1PaFull, M2Ps, M2PsFull, M4Pa, M4PaFull};
    for (name, (e64, e32)) in [
        ("M1-pa", mean_accel_output_error::<M1Pa, 12, 3>(21)),
        ("M2-ps", mean_accel_output_error::<M2Ps, 18, 6>(22)),
        ("M4-pa", mean_accel_output_error::<M4Pa, 12, 3>(23)),
        // The full model: instrument errors of 1e-3 in their units (ba, ka
        // act on the mean exactly as on each node's output).
        ("M1-pa full", mean_accel_output_error::<M1PaFull, 48, 3>(24)),
        ("M2-ps full", mean_accel_output_error::<M2PsFull, 54, 6>(25)),
        ("M4-pa full", mean_accel_output_error::<M4PaFull, 48, 3>(26)),
    ] {
        eprintln!("{name}: mean_accel_output − mean_accel: f64 {e64:.1e} g, f32 {e32:.1e} g");
        // f64: rounding (a few ulp of 1 g). f32: M1's rotations of ≤ 1.7 mrad
        // and its frame's turn within the period (≤ 5.2 mrad) in f32,
        // ε_f32 |θ| ≈ 1e-10 g and ε_f32 |uT| ≈ 3e-10 g; the Euler kinds' steps of ≤ 3e-3 rad
        // in f32, ≤ 3 ε_f32 |δ| ≤ 7.2e-10 per sine and cosine
        // (EulerTrig::advanced_in), a few of them in each entry of the DCM.
        assert!(e64 < 2e-15, "{name}: f64 value off by {e64:e} g");
        assert!(e32 < 1e-9, "{name}: f32 value off by {e32:e} g");
    }
}

#[test]
fn accel_output_and_jacobian_equal_the_two_apart() {
    use rollcal::models::{M1Pa, M1Ps, M2Ps, M3Pa, M3Ps, M4Pa, M4Ps};
    accel_pair::<M1Pa, 12, 3>(1);
    accel_pair::<M1Ps, 15, 3>(2);
    accel_pair::<M2Ps, 18, 6>(3);
    accel_pair::<M3Pa, 15, 3>(4);
    accel_pair::<M3Ps, 18, 3>(5);
    accel_pair::<M4Pa, 12, 3>(6);
    accel_pair::<M4Ps, 15, 3>(7);
}
