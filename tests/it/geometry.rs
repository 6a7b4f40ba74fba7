//! Properties of `rollcal::geometry` (docs/model.md §Frames) and of the exact pa-frame gyro
//! misalignment of `rollcal::instruments` (docs/model.md §Installation models, §The paper's scenario), in f64.
//!
//! Random inputs come from a seeded xorshift64* generator, so every run sees
//! the same values. Derivatives are checked against the fourth-order central
//! difference `f'(x) ≈ [f(x−2h) − 8f(x−h) + 8f(x+h) − f(x+2h)] / (12h)`,
//! whose truncation error is `h⁴|f⁽⁵⁾|/30` and whose rounding error is about
//! `1.5 ε |f| / h` (ε = 2.2e-16). With `h = 1e-3` and functions whose values
//! and derivatives are O(1) (rotations, unit-ish vectors) that is
//! ≈ 3e-14 + 3.3e-13, so the tolerance `FD_TOL = 1e-10` below has a margin of
//! ≥ 100 while any error in a formula (a sign, a transpose, a missing term)
//! shows up at the size of the entries, O(1e-2 … 1).

use core::f64::consts::{FRAC_PI_2, PI};

use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, Vector3};
use rollcal::geometry::{
    d_dcm_times, d_gimbal_dcm_times, d_gimbal_rate_inverse_times, d_lower_times, dcm, earth_rate_n,
    euler_angles, gimbal_dcm, gimbal_rate_inverse, gimbal_rate_matrix, lower, r1, r2, r3,
    right_jacobian, right_jacobian_inv, rotation_vector, skew, wrap_angle, wrap_angles,
};
use rollcal::instruments::theta_g_c_pa;

/// Seeded xorshift64* generator (Vigna 2016): deterministic, no dependency.
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(seed.max(1))
    }

    fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in [0, 1) with 53 random bits.
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Uniform on the unit sphere (rejection from the cube).
    fn unit(&mut self) -> Vector3<f64> {
        loop {
            let v = Vector3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }

    /// Random direction, norm uniform in [0, max].
    fn vector(&mut self, max: f64) -> Vector3<f64> {
        let r = self.range(0.0, max);
        self.unit() * r
    }
}

const DEG: f64 = PI / 180.0;
const ARCSEC: f64 = DEG / 3600.0;

/// Finite-difference step of the Jacobian checks (see the module docs).
const FD_STEP: f64 = 1e-3;
/// Tolerance of the Jacobian checks (see the module docs).
const FD_TOL: f64 = 1e-10;

/// Fourth-order central difference of `f` at `x`.
fn fd<const R: usize, const C: usize>(
    f: impl Fn(&SVector<f64, C>) -> SVector<f64, R>,
    x: &SVector<f64, C>,
    h: f64,
) -> SMatrix<f64, R, C> {
    let mut jac = SMatrix::<f64, R, C>::zeros();
    for j in 0..C {
        let at = |k: f64| {
            let mut xk = *x;
            xk[j] += k * h;
            f(&xk)
        };
        let col = (at(-2.0) - at(-1.0) * 8.0 + at(1.0) * 8.0 - at(2.0)) / (12.0 * h);
        jac.set_column(j, &col);
    }
    jac
}

/// The elementary rotations of docs/model.md §Notation, written out independently of the crate.
fn spec_r1(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, s, 0.0, -s, c)
}
fn spec_r2(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, 0.0, -s, 0.0, 1.0, 0.0, s, 0.0, c)
}
fn spec_r3(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0)
}

// ---------------------------------------------------------------- basics

#[test]
fn skew_and_lower_match_spec() {
    let mut rng = Rng::new(1);
    for _ in 0..100 {
        let v = rng.vector(2.0);
        let w = rng.vector(2.0);
        assert!((skew(&v) * w - v.cross(&w)).amax() < 1e-15);
        let l = lower(&v);
        let spec = Matrix3::new(0.0, 0.0, 0.0, v.x, 0.0, 0.0, v.y, v.z, 0.0);
        assert_eq!(l, spec);
    }
}

#[test]
fn earth_rate_is_north_up_east() {
    let phi = 34.25 * DEG;
    let w = earth_rate_n(rollcal::geometry::EARTH_RATE, phi);
    let omega = 7.292115e-5;
    assert!((w - Vector3::new(omega * phi.cos(), omega * phi.sin(), 0.0)).amax() < 1e-20);
    assert_eq!(earth_rate_n(0.0, phi), Vector3::zeros());
}

// ---------------------------------------------------------------- dcm

#[test]
fn dcm_is_a_proper_rotation() {
    // Entries are O(1) and every product is a 3-term dot product: the
    // orthonormality defect is a few ε; 1e-14 leaves a margin of ≈ 20.
    let mut rng = Rng::new(2);
    let mut worst = (0.0f64, 0.0f64);
    for _ in 0..2000 {
        let theta = rng.vector(3.0);
        let c = dcm(&theta);
        let ortho = (c.transpose() * c - Matrix3::identity()).amax();
        let det = (c.determinant() - 1.0).abs();
        worst = (worst.0.max(ortho), worst.1.max(det));
        assert!(ortho <= 1e-14, "θ = {theta:?}: |CᵀC − I| = {ortho:e}");
        assert!(det <= 1e-14, "θ = {theta:?}: |det C − 1| = {det:e}");
    }
    eprintln!(
        "dcm: worst |CᵀC − I| = {:.1e}, worst |det − 1| = {:.1e}",
        worst.0, worst.1
    );
}

#[test]
fn dcm_matches_an_independent_rodrigues() {
    // R(θ) = exp(−[θ×]) is nalgebra's (active) rotation by −θ.
    let mut rng = Rng::new(3);
    let mut worst = 0.0f64;
    for _ in 0..2000 {
        let theta = rng.vector(3.0);
        let reference = Rotation3::new(-theta).into_inner();
        let d = (dcm(&theta) - reference).amax();
        worst = worst.max(d);
        assert!(d <= 1e-14, "θ = {theta:?}: |dcm − exp(−[θ×])| = {d:e}");
    }
    eprintln!("dcm vs nalgebra exp(−[θ×]): worst {worst:.1e}");
}

#[test]
fn dcm_is_i_minus_skew_to_first_order() {
    // dcm(θ) = I − [θ×] + [θ×]²/2 + O(|θ|³): the entries of [θ×]²/2 are at
    // most |θ|²/2, so |dcm − (I − [θ×])| ≤ |θ|². A sign error in the first
    // order term would give 2|θ| ≫ |θ|². The second-order form leaves
    // |θ|³/6 (plus rounding, ≤ 1e-16 here).
    let mut rng = Rng::new(4);
    for _ in 0..2000 {
        let theta = rng.vector(1e-3);
        let n = theta.norm();
        let k = skew(&theta);
        let first = (dcm(&theta) - (Matrix3::identity() - k)).amax();
        assert!(
            first <= n * n,
            "θ = {theta:?}: first-order defect {first:e} > |θ|²"
        );
        let second = (dcm(&theta) - (Matrix3::identity() - k + k * k / 2.0)).amax();
        assert!(
            second <= n * n * n / 6.0 + 2.3e-16,
            "θ = {theta:?}: second-order defect {second:e}"
        );
    }
}

#[test]
fn dcm_about_an_axis_is_the_elementary_rotation() {
    let mut rng = Rng::new(5);
    for _ in 0..500 {
        let a = rng.range(-PI, PI);
        let pairs = [
            (dcm(&Vector3::new(a, 0.0, 0.0)), r1(a), spec_r1(a)),
            (dcm(&Vector3::new(0.0, a, 0.0)), r2(a), spec_r2(a)),
            (dcm(&Vector3::new(0.0, 0.0, a)), r3(a), spec_r3(a)),
        ];
        for (i, (from_dcm, elementary, spec)) in pairs.iter().enumerate() {
            assert!((from_dcm - elementary).amax() <= 1e-15, "axis {i}, a = {a}");
            assert!(
                (elementary - spec).amax() <= 1e-15,
                "axis {i}, a = {a}: r{} ≠ docs/model.md",
                i + 1
            );
        }
    }
}

// ---------------------------------------------------------------- rotation_vector

#[test]
fn rotation_vector_inverts_dcm() {
    // Away from π, θ = w |θ|/sin|θ| with w the antisymmetric part (error ≈ ε):
    // the error is ≈ ε |θ|/sin|θ| ≤ ε π / sin(1e-3) ≈ 7e-13 at the worst.
    let mut rng = Rng::new(6);
    let mut worst = 0.0f64;
    for i in 0..5000 {
        // Norms spread over [0, π − 1e-3), denser near the top end.
        let max = if i % 2 == 0 { PI - 1e-3 } else { 1.0 };
        let mut theta = rng.vector(max);
        if i % 5 == 0 {
            theta = rng.unit() * (PI - 1e-3 * rng.range(1.0, 10.0));
        }
        let n = theta.norm();
        let tol = 4.0 * f64::EPSILON * (n / n.sin()).max(1.0);
        let back = rotation_vector(&dcm(&theta));
        let d = (back - theta).amax();
        worst = worst.max(d);
        assert!(
            d <= tol,
            "θ = {theta:?} (|θ| = {n}): round trip error {d:e} > {tol:e}"
        );
    }
    eprintln!("rotation_vector(dcm(θ)), |θ| < π − 1e-3: worst error {worst:.1e}");
}

#[test]
fn rotation_vector_near_pi() {
    // Two regimes of `rotation_vector` near |θ| = π − ε:
    // - sin ε ≥ 1e-6: θ = w |θ|/sin|θ| from the antisymmetric part w (error
    //   ≈ ε_mach), so rounding is amplified by π / sin ε (7e-13 at ε = 1e-3,
    //   up to 7e-10 just above the switch at 1e-6; measured ≈ 10× below);
    // - sin ε < 1e-6: the axis from the symmetric part, accurate to a few ε_mach.
    let tol = |eps: f64| {
        if eps.sin() >= 1e-6 {
            2.0 * f64::EPSILON * PI / eps.sin()
        } else {
            1e-14
        }
    };
    let mut rng = Rng::new(7);
    let mut worst = (0.0f64, 0.0f64);
    for &eps in &[1e-3, 3e-4, 1e-5, 2e-6, 1.1e-6, 9e-7, 1e-7, 1e-9, 1e-12, 0.0] {
        for _ in 0..200 {
            let axis = rng.unit();
            let theta = axis * (PI - eps);
            let c = dcm(&theta);
            let back = rotation_vector(&c);
            // The matrix round trip holds always (θ and −θ give the same R at π).
            let dm = (dcm(&back) - c).amax();
            worst.0 = worst.0.max(dm);
            assert!(dm <= tol(eps), "|θ| = π − {eps:e}: |R(θ(C)) − C| = {dm:e}");
            assert!(back.norm() <= PI + 1e-15, "|θ(C)| = {} > π", back.norm());
            // The vector itself is recoverable while the antisymmetric part
            // (≈ sin ε) fixes the sign: its components are ≈ ε with an
            // absolute error ≈ ε_mach, so the sign is safe for ε ≥ 1e-9.
            if eps >= 1e-9 {
                let dv = (back - theta).amax();
                worst.1 = worst.1.max(dv);
                assert!(
                    dv <= tol(eps),
                    "|θ| = π − {eps:e}: θ = {theta:?}, θ(C) = {back:?}"
                );
            }
        }
    }
    eprintln!(
        "near π: worst |R(θ(C)) − C| = {:.1e}, worst |θ(C) − θ| = {:.1e}",
        worst.0, worst.1
    );
}

#[test]
fn rotation_vector_of_tiny_angles() {
    let mut rng = Rng::new(8);
    for &size in &[1e-9, 1e-12, 1e-6, 1e-4] {
        for _ in 0..200 {
            let theta = rng.unit() * size;
            let back = rotation_vector(&dcm(&theta));
            let d = (back - theta).amax();
            // Off-diagonal entries carry θ with relative error ≈ ε.
            assert!(d <= 4.0 * f64::EPSILON * size, "θ = {theta:?}: error {d:e}");
        }
    }
    assert_eq!(
        rotation_vector(&Matrix3::<f64>::identity()),
        Vector3::zeros()
    );
}

// ---------------------------------------------------------------- right Jacobian

/// `J_r(θ)` by finite differences of its defining property
/// `R(θ + δ) R(θ)ᵀ ≈ I − [(J_r δ)×] = R(J_r δ)`.
fn right_jacobian_fd(theta: &Vector3<f64>, h: f64) -> Matrix3<f64> {
    let c0t = dcm(theta).transpose();
    fd(
        |t: &Vector3<f64>| rotation_vector(&(dcm(t) * c0t)),
        theta,
        h,
    )
}

#[test]
fn right_jacobian_matches_finite_differences() {
    let mut rng = Rng::new(9);
    let mut worst = 0.0f64;
    for _ in 0..300 {
        let theta = rng.vector(3.0);
        let d = (right_jacobian(&theta) - right_jacobian_fd(&theta, FD_STEP)).amax();
        worst = worst.max(d);
        assert!(d <= FD_TOL, "θ = {theta:?}: |J_r − FD| = {d:e}");
    }
    eprintln!("right_jacobian vs FD: worst {worst:.1e}");
}

#[test]
fn right_jacobian_series_branch() {
    // |θ|² < 1e-8 uses the Taylor series. At |θ| = 5e-5 the first-order term
    // [θ×]/2 is 2.5e-5 and the second-order term [θ×]²/6 is ≈ 4e-10, both
    // far above the FD error: with h = 1e-5 the differenced values are
    // rotation vectors of size ≈ 2h, so rounding is ≈ 1.5 ε · 2h / h ≈ 7e-16
    // and truncation ≈ h⁴|f⁽⁵⁾|/30 ≈ 1e-21 (measured ≤ 2e-15). The
    // tolerance 1e-12 therefore sees both terms.
    let mut rng = Rng::new(10);
    let h = 1e-5;
    let mut worst = 0.0f64;
    for &size in &[5e-5, 9e-5, 1e-6, 1e-9] {
        for _ in 0..50 {
            let theta = rng.unit() * size;
            let fdj = right_jacobian_fd(&theta, h);
            let d = (right_jacobian(&theta) - fdj).amax();
            worst = worst.max(d);
            assert!(d <= 1e-12, "θ = {theta:?}: |J_r − FD| = {d:e}");
            // And the series itself: I − [θ×]/2 + [θ×]²/6 up to O(|θ|³).
            let k = skew(&theta);
            let series = Matrix3::identity() - k / 2.0 + k * k / 6.0;
            assert!((right_jacobian(&theta) - series).amax() <= size.powi(3) + 1e-16);
        }
    }
    eprintln!("right_jacobian vs FD, series branch: worst {worst:.1e}");
    // Both sides of the branch threshold |θ| = 1e-4 agree.
    let axis = Vector3::new(0.6, -0.48, 0.64);
    for f in [right_jacobian::<f64>, right_jacobian_inv::<f64>, dcm::<f64>] {
        let below = f(&(axis * (1e-4 * (1.0 - 1e-9))));
        let above = f(&(axis * (1e-4 * (1.0 + 1e-9))));
        let d = (below - above).amax();
        // The true change over 2e-13 rad is ≤ 1e-13; closed-form rounding
        // at |θ| = 1e-4 is ≈ ε/|θ|² · |θ| ≈ 2e-12.
        assert!(d <= 1e-11, "branch discontinuity {d:e}");
    }
}

#[test]
fn right_jacobian_inverse() {
    let mut rng = Rng::new(11);
    let mut worst = 0.0f64;
    for i in 0..2000 {
        let theta = if i % 4 == 0 {
            rng.unit() * 10f64.powf(rng.range(-10.0, -4.0))
        } else {
            rng.vector(3.0)
        };
        let d = (right_jacobian_inv(&theta) * right_jacobian(&theta) - Matrix3::identity()).amax();
        let d2 = (right_jacobian(&theta) * right_jacobian_inv(&theta) - Matrix3::identity()).amax();
        worst = worst.max(d).max(d2);
        // J_r⁻¹ grows like 1/(1 − cos) towards 2π; at |θ| ≤ 3 its entries
        // are ≤ 40, so the product is exact to ≈ 40 ε · 3.
        assert!(
            d.max(d2) <= 1e-13,
            "θ = {theta:?}: |J_r⁻¹ J_r − I| = {:e}",
            d.max(d2)
        );
    }
    eprintln!("right_jacobian_inv · right_jacobian: worst {worst:.1e}");
}

// ---------------------------------------------------------------- gimbal kinematics

fn random_gimbal(rng: &mut Rng) -> Vector3<f64> {
    Vector3::new(rng.range(-PI, PI), rng.range(-1.5, 1.5), rng.range(-PI, PI))
}

#[test]
fn gimbal_dcm_is_r3_r2_r1() {
    let mut rng = Rng::new(12);
    for _ in 0..500 {
        let t = random_gimbal(&mut rng);
        let spec = spec_r3(t.z) * spec_r2(t.y) * spec_r1(t.x);
        assert!((gimbal_dcm(&t) - r3(t.z) * r2(t.y) * r1(t.x)).amax() <= 1e-15);
        assert!((gimbal_dcm(&t) - spec).amax() <= 1e-15);
    }
}

#[test]
fn euler_angles_invert_gimbal_dcm() {
    // β = asin(C31) amplifies rounding by 1/cos β ≤ 14 at |β| < 1.5, and α, γ
    // come from entries scaled by cos β: errors ≤ ≈ 14 · 2ε ≈ 6e-15.
    let mut rng = Rng::new(13);
    let mut worst = 0.0f64;
    for _ in 0..5000 {
        let t = random_gimbal(&mut rng);
        let back = euler_angles(&gimbal_dcm(&t));
        let d = wrap_angles(&(back - t)).amax();
        worst = worst.max(d);
        assert!(d <= 1e-13, "θA = {t:?}: euler_angles → {back:?}");
    }
    // The edges of (−π, π]: α = γ = π comes back as π (or −π, the same angle).
    let t = Vector3::new(PI, 0.3, PI);
    let back = euler_angles(&gimbal_dcm(&t));
    assert!(wrap_angles(&(back - t)).amax() <= 1e-15);
    eprintln!("euler_angles(gimbal_dcm(θ)): worst {worst:.1e}");
}

#[test]
fn gimbal_rate_matrix_and_inverse() {
    let mut rng = Rng::new(14);
    for _ in 0..2000 {
        let (b, g) = (rng.range(-1.5, 1.5), rng.range(-PI, PI));
        let m = gimbal_rate_matrix(b, g);
        let (sb, cb, sg, cg) = (b.sin(), b.cos(), g.sin(), g.cos());
        let spec = Matrix3::new(cb * cg, sg, 0.0, -cb * sg, cg, 0.0, sb, 0.0, 1.0);
        assert!((m - spec).amax() <= 1e-15);
        let t = gimbal_rate_inverse(b, g).expect("β inside (−1.5, 1.5)");
        // T entries are ≤ 1/cos β ≈ 14.
        assert!(
            (m * t - Matrix3::identity()).amax() <= 1e-13,
            "β = {b}, γ = {g}"
        );
        assert!(
            (t * m - Matrix3::identity()).amax() <= 1e-13,
            "β = {b}, γ = {g}"
        );
    }
    for b in [
        FRAC_PI_2,
        -FRAC_PI_2,
        FRAC_PI_2 + 5e-10,
        FRAC_PI_2 - 5e-10,
        3.0 * FRAC_PI_2,
    ] {
        assert!(
            gimbal_rate_inverse(b, 0.7).is_none(),
            "β = {b} is gimbal lock"
        );
    }
    assert!(gimbal_rate_inverse(FRAC_PI_2 - 1e-7, 0.7).is_some());
}

#[test]
fn gimbal_kinematics_follow_spec_convention() {
    // docs/model.md §Frames: ω^p_rp = M θ̇A and dC^p_r/dt = −[ω^p_rp×] C^p_r. Over a step
    // dt: gimbal_dcm(θ + T ω dt) = (I − [ω dt×]) gimbal_dcm(θ) + O(|ω dt|²);
    // with |ω dt| ≤ 1e-4 the O(·) term is ≤ ≈ 14 · 1e-8 (T ≤ 1/cos β ≈ 14
    // turns ω into θ̇A whose second-order terms enter the DCM), while the
    // opposite sign convention would be off by 2|ω dt|.
    let mut rng = Rng::new(15);
    let mut worst_rate = 0.0f64;
    for _ in 0..500 {
        let t = random_gimbal(&mut rng);
        let omega = rng.unit() * 1e-4;
        let tm = gimbal_rate_inverse(t.y, t.z).unwrap();
        let c0 = gimbal_dcm(&t);
        let step = gimbal_dcm(&(t + tm * omega));
        let d = (step - (Matrix3::identity() - skew(&omega)) * c0).amax();
        // Second-order remainders: ≤ (Σ|δθA_i|)² ≤ 3|T ω|² from the Euler
        // angles, |ω|²/2 from I − [ω×] vs R(ω). Both ≪ 2|ω| = 2e-4.
        let bound = 3.0 * (tm * omega).norm_squared() + omega.norm_squared();
        assert!(bound < 0.1 * omega.norm());
        assert!(
            d <= bound,
            "θA = {t:?}: first-order kinematics defect {d:e} > {bound:e}"
        );
        // Sharper: the rate recovered by finite differences along θ̇A = T ω
        // for a unit ω (so that errors are relative):
        // ω = d/ds rotation_vector(C(θ + T ω s) C(θ)ᵀ) at s = 0.
        let w = rng.unit();
        let tw = tm * w;
        let rate = fd(
            |s: &SVector<f64, 1>| rotation_vector(&(gimbal_dcm(&(t + tw * s[0])) * c0.transpose())),
            &SVector::<f64, 1>::zeros(),
            1e-4,
        );
        let d = (rate.column(0) - w).amax();
        worst_rate = worst_rate.max(d);
        // |T ω| is up to ≈ 14 for a unit ω: with h = 1e-4 the truncation is
        // ≤ h⁴ 14⁵/30 ≈ 2e-12 and the rounding ≈ 1.5 ε / h ≈ 3e-12, while a
        // sign or transpose slip gives errors O(1).
        assert!(
            d <= FD_TOL,
            "θA = {t:?}, ω = {w:?}: recovered rate off by {d:e}"
        );
        // And the Jacobian form: ∂(C v)/∂θ · T ω = [(C v)×] ω = −[ω×] C v.
        let v = rng.vector(2.0);
        let lhs = d_gimbal_dcm_times(&t, &v) * tw;
        assert!((lhs + w.cross(&(c0 * v))).amax() <= 1e-13);
    }
    eprintln!("gimbal kinematics: worst recovered-rate error {worst_rate:.1e}");
}

// ---------------------------------------------------------------- derivative helpers

#[test]
fn d_dcm_times_matches_finite_differences() {
    let mut rng = Rng::new(16);
    let mut worst = 0.0f64;
    for _ in 0..300 {
        let theta = rng.vector(3.0);
        let v = rng.vector(2.0);
        let fdj = fd(|t: &Vector3<f64>| dcm(t) * v, &theta, FD_STEP);
        let d = (d_dcm_times(&theta, &v) - fdj).amax();
        worst = worst.max(d);
        assert!(d <= FD_TOL, "θ = {theta:?}, v = {v:?}: {d:e}");
    }
    eprintln!("d_dcm_times vs FD: worst {worst:.1e}");
}

#[test]
fn d_gimbal_dcm_times_matches_finite_differences() {
    let mut rng = Rng::new(17);
    let mut worst = 0.0f64;
    for _ in 0..300 {
        let t = random_gimbal(&mut rng);
        let v = rng.vector(2.0);
        let fdj = fd(|a: &Vector3<f64>| gimbal_dcm(a) * v, &t, FD_STEP);
        let d = (d_gimbal_dcm_times(&t, &v) - fdj).amax();
        worst = worst.max(d);
        assert!(d <= FD_TOL, "θA = {t:?}, v = {v:?}: {d:e}");
    }
    eprintln!("d_gimbal_dcm_times vs FD: worst {worst:.1e}");
}

#[test]
fn d_gimbal_rate_inverse_times_matches_finite_differences() {
    // T(β, γ) w has derivatives of order n growing like 1/cos^(n+1) β; with
    // |β| < 1.2 (1/cos β < 2.8) and h = 1e-4 the truncation h⁴|f⁽⁵⁾|/30 is
    // ≤ ≈ 1e-16 · 2.8⁶ · |w| ≈ 1e-13 and the rounding ≈ 1.5 ε · 2.8 |w| / h
    // ≈ 2e-11.
    let mut rng = Rng::new(18);
    let h = 1e-4;
    let mut worst = 0.0f64;
    for _ in 0..300 {
        let t = Vector3::new(rng.range(-PI, PI), rng.range(-1.2, 1.2), rng.range(-PI, PI));
        let w = rng.vector(2.0);
        let tm = gimbal_rate_inverse(t.y, t.z).unwrap();
        let fdj = fd(
            |a: &Vector3<f64>| gimbal_rate_inverse(a.y, a.z).unwrap() * w,
            &t,
            h,
        );
        let an = d_gimbal_rate_inverse_times(&tm, t.y, t.z, &w);
        let d = (an - fdj).amax();
        worst = worst.max(d);
        assert!(d <= FD_TOL, "θA = {t:?}, w = {w:?}: {d:e}");
        assert_eq!(an.column(0).amax(), 0.0, "T does not depend on α");
    }
    eprintln!("d_gimbal_rate_inverse_times vs FD: worst {worst:.1e}");
}

#[test]
fn d_lower_times_matches_finite_differences() {
    let mut rng = Rng::new(19);
    for _ in 0..100 {
        let t = rng.vector(0.1);
        let v = rng.vector(2.0);
        let fdj = fd(|a: &Vector3<f64>| lower(a) * v, &t, FD_STEP);
        // L(t) v is linear in t: only rounding remains.
        assert!((d_lower_times(&v) - fdj).amax() <= 1e-12);
    }
}

// ---------------------------------------------------------------- wrap_angle

#[test]
fn wrap_angle_range_and_edges() {
    assert_eq!(wrap_angle(PI), PI);
    assert_eq!(wrap_angle(-PI), PI);
    assert_eq!(wrap_angle(0.0), 0.0);
    assert_eq!(wrap_angle(1.0), 1.0);
    assert_eq!(wrap_angle(-1.0), -1.0);
    assert!((wrap_angle(3.0 * PI) - PI).abs() <= 1e-15);
    assert!((wrap_angle(-3.0 * PI) - PI).abs() <= 1e-15);
    assert!(wrap_angle(f64::NAN).is_nan());
    // Non-finite input stays non-finite (the doc says "returned as is"; ±∞
    // actually comes back as NaN, which is equally safe for callers).
    assert!(!wrap_angle(f64::INFINITY).is_finite());
    assert!(!wrap_angle(f64::NEG_INFINITY).is_finite());

    let in_range = |w: f64| w > -PI && w <= PI;
    let mut rng = Rng::new(20);
    // Odd and even multiples of π, including large ones, and random angles.
    let mut inputs: Vec<f64> = Vec::new();
    for k in -2000i32..=2000 {
        inputs.push(f64::from(k) * PI);
        inputs.push(f64::from(k) * 2.0 * PI + 1e-9);
        inputs.push(f64::from(k) * 2.0 * PI - 1e-9);
    }
    for _ in 0..20_000 {
        inputs.push(rng.range(-1e4, 1e4));
    }
    for &a in &inputs {
        let w = wrap_angle(a);
        assert!(in_range(w), "wrap_angle({a}) = {w} is outside (−π, π]");
        // wrap(a) − a is a multiple of 2π, up to the rounding of a (≈ ε|a|).
        let turns = (w - a) / (2.0 * PI);
        let off = (turns - turns.round()).abs() * 2.0 * PI;
        assert!(
            off <= 8.0 * f64::EPSILON * a.abs().max(1.0),
            "wrap_angle({a}) = {w}: off a multiple of 2π by {off:e}"
        );
    }
    // The fixed points: angles already inside are returned unchanged.
    for _ in 0..1000 {
        let a = rng.range(-PI, PI);
        if a > -PI {
            assert_eq!(wrap_angle(a), a);
        }
    }
}

// ---------------------------------------------------------------- instruments

#[test]
fn theta_g_c_pa_of_the_paper_values() {
    // docs/model.md §The paper's scenario: θgC = [0.3, −0.3, 0.2]°, θaC = [0.2, 0.1, −0.1]° give exactly
    // θgC^pa = [0.099913, −0.400610, 0.299214]° (quoted to 1e-6°, so 5e-7°).
    let g = Vector3::new(0.3, -0.3, 0.2) * DEG;
    let a = Vector3::new(0.2, 0.1, -0.1) * DEG;
    let exact = theta_g_c_pa(&g, &a);
    let expected = Vector3::new(0.099913, -0.400610, 0.299214);
    let err_deg = (exact / DEG - expected).amax();
    eprintln!(
        "θgC^pa = [{:.7}, {:.7}, {:.7}]°, max error vs docs/model.md {err_deg:.1e}°",
        exact.x / DEG,
        exact.y / DEG,
        exact.z / DEG
    );
    assert!(
        err_deg <= 5e-7,
        "θgC^pa = {:?}° vs docs/model.md {expected:?}°",
        exact / DEG
    );
    // Its defining property, R(θgC^pa) = R(−θaC) R(θgC).
    assert!((dcm(&exact) - dcm(&(-a)) * dcm(&g)).amax() <= 1e-15);
    // The first-order value θgC − θaC is off by more than 1″ (docs/model.md: up to 2.8″).
    let first_order = g - a;
    let diff = (exact - first_order).amax();
    eprintln!("θgC^pa − (θgC − θaC): max {:.2}″", diff / ARCSEC);
    assert!(
        diff > ARCSEC,
        "first-order θgC^pa is within 1″ of the exact value"
    );
    assert!(diff < 3.0 * ARCSEC);
}
