//! Unit tests of the geometry: the rotations against their definitions
//! and each other, the single-precision parts against f64.

use super::*;

/// Angles (rad) over several turns, both signs, and the exact values
/// where a sine or cosine term vanishes or a product is exact.
fn angles() -> impl Iterator<Item = f64> {
    let specials = [
        0.0,
        -0.0,
        1e-9,
        -3e-5,
        0.5,
        -1.0,
        core::f64::consts::FRAC_PI_2,
        3.0,
    ];
    (0..97)
        .map(|i| -7.3 + 0.1517 * f64::from(i) + 1e-3 * f64::from(i % 7))
        .chain(specials)
}

/// Equal as numbers, and bit for bit unless both are zeros (the written
/// out forms leave out the product's `±0` terms, which can flip the
/// sign of an exact zero and nothing else).
fn same(a: &Matrix3<f64>, b: &Matrix3<f64>) -> bool {
    a.iter()
        .zip(b.iter())
        .all(|(x, y)| x.to_bits() == y.to_bits() || (*x == 0.0 && *y == 0.0))
}

/// The series of the rotation coefficients against their closed forms,
/// which lose `ε/x²` to cancellation (`1 − cos x`, `x − sin x`, the
/// inverse Jacobian's `1/x² − …`), from 1e-4 rad to the 0.1 rad
/// threshold, and continuity there.
#[test]
fn rotation_series_agree_with_the_closed_forms() {
    let eps = f64::EPSILON;
    for i in 0..=400 {
        let x = 1e-4 * 10f64.powf(3.0 * f64::from(i) / 400.0) * 0.9999;
        let y = x * x;
        let k = RotationCoefficients::new(y);
        let (s, c) = (x.sin(), x.cos());
        let cancel = 4.0 * eps / y;
        assert!((k.sinc - s / x).abs() <= 4.0 * eps, "sinc at {x}");
        assert!(
            (k.cosc - (1.0 - c) / y).abs() <= 4.0 * eps + cancel,
            "cosc at {x}"
        );
        assert!(
            (k.sinc3 - (x - s) / (y * x)).abs() <= 4.0 * eps + cancel,
            "sinc3 at {x}"
        );
        let theta = Vector3::new(0.6 * x, -0.8 * x, 0.0);
        let jinv = right_jacobian_inv(&theta);
        let closed = 1.0 / y - (1.0 + c) / (2.0 * x * s);
        let from_series = (jinv - Matrix3::identity() - skew(&theta) / 2.0).m11 / (-y * 0.64);
        // m11 of [θ×]² is −(θy² + θz²) = −0.64 y.
        assert!(
            (from_series - closed).abs() <= 8.0 * eps + cancel,
            "J_r⁻¹ at {x}"
        );
    }
    // Either side of the thresholds (1e-8 and 1e-2 rad²).
    for y in [1e-8f64, 1e-2] {
        let (below, above) = (
            RotationCoefficients::new(y * (1.0 - 1e-12)),
            RotationCoefficients::new(y),
        );
        // Rounding, plus the functions' own change over 1e-12 of y.
        let tol = 4.0 * eps + 1e-12 * y;
        assert!((below.sinc - above.sinc).abs() < tol, "sinc at {y}");
        assert!((below.cosc - above.cosc).abs() < tol, "cosc at {y}");
        assert!((below.sinc3 - above.sinc3).abs() < tol, "sinc3 at {y}");
    }
}

#[test]
fn right_jacobian_times_a_vector_is_the_product() {
    for (i, a) in angles().enumerate() {
        let theta = Vector3::new(a, 0.3 - 0.2 * a, 1e-3 * f64::from(i as u8)) * 0.05;
        let v = Vector3::new(7.3e-5, -2.1e-5, 4.4e-5 + 1e-6 * a);
        let d = right_jacobian_times(&theta, &v) - right_jacobian(&theta) * v;
        assert!(
            d.amax() <= 4.0 * f64::EPSILON * v.amax(),
            "at {theta:?}: {d:?}"
        );
    }
}

#[test]
fn advanced_trigonometry_is_within_a_few_ulp_of_the_direct_one() {
    let deltas = [
        0.0, 1e-9, -3.3e-4, 1.7e-3, -8.7e-3, 0.049, -0.05, 0.051, -0.4,
    ];
    for (i, a) in angles().enumerate() {
        let angles = Vector3::new(a, -0.5 * a, 0.3 + a);
        let trig = EulerTrig::new(&angles);
        for (j, &d) in deltas.iter().enumerate() {
            let delta = Vector3::new(d, -d, deltas[(i + j) % deltas.len()]);
            let advanced = trig.advanced_by(&angles, &delta);
            let direct = EulerTrig::new(&(angles + delta));
            for (x, y) in [
                (advanced.alpha, direct.alpha),
                (advanced.beta, direct.beta),
                (advanced.gamma, direct.gamma),
            ] {
                assert!((x.0 - y.0).abs() <= 4.0 * f64::EPSILON, "sin at {a} + {d}");
                assert!((x.1 - y.1).abs() <= 4.0 * f64::EPSILON, "cos at {a} + {d}");
            }
        }
    }
}

/// The deviations of `R(θ)` and `J_r(θ)` formed without the identity
/// equal their definitions where those do not cancel, and keep their
/// relative precision in f32 where they would.
#[test]
fn deviations_keep_their_relative_precision() {
    for theta in [
        Vector3::new(0.3, -0.2, 0.5),
        Vector3::new(1.2e-3, -0.7e-3, 0.4e-3),
        Vector3::new(2e-6, 1e-6, -3e-6),
    ] {
        let v = Vector3::new(0.1, 0.9, -0.4);
        let size = theta.norm();
        // In f64 against the definitions (cancellation: ε of 1).
        let deviation = dcm_deviation(&theta);
        assert!((deviation - (dcm(&theta) - Matrix3::identity())).amax() < 4e-16);
        let jv = right_jacobian_deviation_times(&theta, &v);
        assert!((jv - (right_jacobian_times(&theta, &v) - v)).amax() < 4e-16);
        // In f32 against f64, relative to their size (|θ|, |θ|/2).
        let eps = f64::from(f32::EPSILON);
        let t32 = theta.map(|x| x as f32);
        let d32 = dcm_deviation(&t32).map(f64::from);
        assert!((d32 - deviation).amax() / size < 4.0 * eps);
        let jv32 = right_jacobian_deviation_times(&t32, &v.map(|x| x as f32));
        assert!((jv32.map(f64::from) - jv).amax() / (size / 2.0) < 4.0 * eps);
    }
}

/// `R(θ) C` with its first-order part in f64 and the rest in f32 is
/// `dcm(θ) C` to `ε_f32 |θ|²/2` (and in f64 to rounding), where the
/// whole product in f32 would be `ε_f32` off; its turn `R(θ) C − C` in
/// f32 is `dcm(θ) C − C` to a few `ε_f32 |θ|`.
#[test]
fn rotated_in_keeps_the_first_order_part_in_f64() {
    let c = dcm(&Vector3::new(0.4, -1.1, 2.3));
    let eps = f64::from(f32::EPSILON);
    for theta in [
        Vector3::new(1.7e-3, -2.0e-3, 0.9e-3),
        Vector3::new(2e-6, 1e-6, -3e-6),
        Vector3::new(0.02, 0.05, -0.03),
        Vector3::new(0.3, -0.2, 0.5),
    ] {
        let exact = dcm(&theta) * c;
        let (r64, turn64) = rotated_in::<f64>(&theta, &c);
        assert!((r64 - exact).amax() < 4e-16);
        assert!((turn64 - (exact - c)).amax() < 4e-16);
        let (r32, turn32) = rotated_in::<f32>(&theta, &c);
        let err = (r32 - exact).amax();
        let bound = 4.0 * eps * theta.norm_squared() / 2.0;
        assert!(
            err < bound + 4e-16,
            "θ {theta:?}: {err:e} against {bound:e}"
        );
        let turn_err = (turn32.map(f64::from) - (exact - c)).amax();
        let turn_bound = 2.0 * eps * theta.norm();
        assert!(
            turn_err < turn_bound,
            "θ {theta:?}: turn {turn_err:e} against {turn_bound:e}"
        );
    }
}

#[test]
fn trigonometry_advanced_in_f32_is_within_its_bound() {
    let deltas = [0.0, 1e-9, -3.3e-4, 1.7e-3, -4e-3, 4e-3, -8.7e-3, 0.049];
    let mut worst: f64 = 0.0;
    for (i, a) in angles().enumerate() {
        let angles = Vector3::new(a, -0.5 * a, 0.3 + a);
        let trig = EulerTrig::new(&angles);
        for (j, &d) in deltas.iter().enumerate() {
            let delta = Vector3::new(d, -d, deltas[(i + j) % deltas.len()]);
            let exact = trig.advanced_by(&angles, &delta);
            assert_eq!(trig.advanced_in::<f64>(&angles, &delta), exact);
            let in_f32 = trig.advanced_in::<f32>(&angles, &delta);
            if delta.amax() > 4e-3 {
                assert_eq!(in_f32, exact, "beyond 4e-3 rad it is advanced_by");
                continue;
            }
            for (x, y) in [
                (in_f32.alpha, exact.alpha),
                (in_f32.beta, exact.beta),
                (in_f32.gamma, exact.gamma),
            ] {
                worst = worst.max((x.0 - y.0).abs()).max((x.1 - y.1).abs());
            }
        }
    }
    // 3 ε_f32 |δ| at |δ| = 4e-3 rad.
    assert!(
        worst > 0.0 && worst <= 3.0 * f64::from(f32::EPSILON) / 2.0 * 4e-3,
        "{worst:e}"
    );
}

#[test]
fn written_out_products_equal_the_products_bit_for_bit() {
    let all: [f64; 105] = core::array::from_fn(|i| angles().nth(i).unwrap_or(0.0));
    for (i, &a) in all.iter().enumerate() {
        let b = all[(i * 31 + 7) % all.len()];
        let g = all[(i * 17 + 3) % all.len()];
        let trig = EulerTrig::new(&Vector3::new(a, b, g));
        let product = r3(g) * r2(b) * r1(a);
        assert!(same(&trig.dcm(), &product), "dcm at {a} {b} {g}");
        let v = Vector3::new(a, b, g) * 0.37;
        assert!(
            same(&skew_squared(&v), &(skew(&v) * skew(&v))),
            "skew² at {v:?}"
        );
    }
}

#[test]
fn wrap_edges() {
    let pi = core::f64::consts::PI;
    assert_eq!(wrap_angle(pi), pi);
    assert!((wrap_angle(-pi) - pi).abs() < 1e-15);
    assert!((wrap_angle(3.0 * pi) - pi).abs() < 1e-12);
    assert!((wrap_angle(2.5 * pi) - 0.5 * pi).abs() < 1e-12);
    assert!((wrap_angle(-2.5 * pi) + 0.5 * pi).abs() < 1e-12);
    assert!(wrap_angle(f64::NAN).is_nan());
    assert_eq!(wrap_angle(f64::INFINITY), f64::INFINITY);
}
