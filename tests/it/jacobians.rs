//! The analytic Jacobians of every configuration (docs/model.md §Configurations) against finite
//! differences of the model functions they linearise:
//!
//! - `accel_jacobian` vs `accel_output` and `attitude_rate_jacobian` vs
//!   `attitude_rate` (the instantaneous building blocks);
//! - the attitude rows `phi_att` of the period transition `Φ = ∂x_{k+1}/∂x_k`
//!   vs the end attitude of `propagate` (one RK4 step over the period);
//! - the filter's measurement Jacobian `H` w.r.t. the end-of-period state
//!   vs its measurement function `Filter::measurement_at`.
//!
//! Finite differences use the fourth-order central stencil
//! `[f(x−2h) − 8f(x−h) + 8f(x+h) − f(x+2h)] / (12h)` with `h = 1e-4` rad: the
//! truncation error is `h⁴|f⁽⁵⁾|/30 ≈ 3e-18` for derivatives of O(1) and
//! the rounding error is `≈ 1.5 ε |f| / h ≈ 7e-12` for values up to 2 rad
//! (the Euler attitude); measured agreement on the exact building blocks is
//! ≤ 2e-12. The tolerance `TOL = 1e-9` is two orders above that floor;
//! entries of the Jacobians are O(1) (attitude-to-attitude,
//! accelerometer-to-angle) or O(|ω T|) ≈ 1.7e-3 (attitude-to-gyro parameter).
//!
//! `phi_att` is, by design, `exp(F_mid T)` to second order, so it differs
//! from the derivative of the RK4 step by the third-order term
//! `≈ |ω T|³/6 ≈ 9e-10` at 0.1°/s (measured 7.4e-10): inside `TOL`, but
//! only just. Any error in a formula (a sign, a transpose, a missing factor
//! `J_r`) shows up at the size of the entries times the angles, ≥ 1e-6.
//!
//! The operating point is realistic: installation angles of 0.2–0.4° with
//! mixed signs, an Euler attitude (2.0, 0.05, 1.2) rad or a misalignment of
//! ≈ 0.3°, a computed frame far from n, and a rolling rate of 0.1°/s plus the
//! Earth rate at 34.25° N.

use core::f64::consts::PI;

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use rollcal::command::{CommandFrame, Period};
use rollcal::ekf::{Filter, FilterConfig, Options};
use rollcal::geometry::{dcm, earth_rate_n, EARTH_RATE};
use rollcal::models::{
    AttitudeKind, ConfigId, Environment, ErrorModel, Layout, Model, PeriodPropagation, StateInfo,
};

const DEG: f64 = PI / 180.0;
/// Finite-difference step (rad), see the module docs.
const FD_STEP: f64 = 1e-4;
/// Absolute tolerance of every comparison (rad/rad, g/rad or (rad/s)/rad).
const TOL: f64 = 1e-9;
/// Relative tolerance of the transition's (and so of `H`'s) columns of the
/// full model's gyro errors dg, D_g, kg. `phi_att` is `exp(F_mid T)` to
/// second order: for the installation angles it differs from the RK4 step's
/// derivative by ≈ |ω T|³/6 (module docs); for a parameter column `F_p` of
/// O(1) (`∂rate/∂dg = J G`: `J`, `T(θ)` or `J_r⁻¹(ψ)`, turns with the
/// attitude) it misses the curvature of `F_p` over the period,
/// ≈ T³/24 |F_p''| ≈ |θ̇ T|²/24 ≈ 1.2e-7 of the entry (measured ≤ 2.2e-7
/// relative, 2.0e-7 on entries of 0.9). That is by design (the same
/// relative accuracy as the installation gyro columns, 5e-8 of theirs;
/// 2e-7 of the drift's σ0 of 1 °/h is 1e-12 rad per period). A formula
/// error shows in the instantaneous `F` (checked at `TOL`) or at ≥ 1e-3 of
/// the entry.
const REL_TOL_TRANSITION: f64 = 1e-6;
/// Rolling rate of the paper, 0.1°/s, in rad/s.
const ROLL_RATE: f64 = 0.1 * DEG;

/// The state `x` moved by `d` along its component `j`. The analytic
/// Jacobians are with respect to the state's own (additive) coordinates; if
/// the filter's error state ever becomes multiplicative for some blocks,
/// this is the one place to apply that retraction instead.
fn perturb<const N: usize>(x: &SVector<f64, N>, j: usize, d: f64) -> SVector<f64, N> {
    let mut xk = *x;
    xk[j] += d;
    xk
}

/// Fourth-order central difference of `f` at `x` (columns = components of x).
fn fd<const R: usize, const N: usize>(
    f: impl Fn(&SVector<f64, N>) -> SVector<f64, R>,
    x: &SVector<f64, N>,
) -> SMatrix<f64, R, N> {
    let h = FD_STEP;
    let mut jac = SMatrix::<f64, R, N>::zeros();
    for j in 0..N {
        let at = |k: f64| f(&perturb(x, j, k * h));
        let col = (at(-2.0) - at(-1.0) * 8.0 + at(1.0) * 8.0 - at(2.0)) / (12.0 * h);
        jac.set_column(j, &col);
    }
    jac
}

fn env() -> Environment<f64> {
    Environment {
        earth_rate_n: earth_rate_n(EARTH_RATE, 34.25 * DEG),
        gravity_n: Vector3::new(0.0, 1.0, 0.0),
    }
}

fn set3<const N: usize>(x: &mut SVector<f64, N>, i: usize, v: [f64; 3]) {
    for (k, v) in v.into_iter().enumerate() {
        x[i + k] = v;
    }
}

/// A realistic state for `layout` (rad).
fn state<const N: usize>(layout: &Layout) -> SVector<f64, N> {
    assert_eq!(layout.n(), N);
    let mut x = SVector::<f64, N>::zeros();
    match layout.attitude {
        AttitudeKind::Misalignment => set3(&mut x, 0, [0.3 * DEG, -0.25 * DEG, 0.35 * DEG]),
        AttitudeKind::Gimbal | AttitudeKind::Attitude => set3(&mut x, 0, [2.0, 0.05, 1.2]),
    }
    set3(&mut x, 3, [0.3 * DEG, -0.3 * DEG, 0.2 * DEG]); // θgC or θgC^pa
    set3(&mut x, 6, [0.25 * DEG, 0.2 * DEG, -0.35 * DEG]); // θgT
    if let Some(i) = layout.ac() {
        set3(&mut x, i, [0.2 * DEG, -0.3 * DEG, -0.25 * DEG]); // θaC
    }
    set3(&mut x, layout.at(), [-0.2 * DEG, 0.3 * DEG, 0.4 * DEG]); // θaT
    if let Some(i) = layout.lam() {
        set3(&mut x, i, [0.2 * DEG, -0.4 * DEG, 0.3 * DEG]); // λ
    }
    if let Some(i) = layout.instruments() {
        // The full model's instrument errors, pseudo-random and far from
        // zero (larger than the instrumented scenario's, so that a missing factor
        // `I + K_a` or term `G D_g ∂f^p/∂att` shows at ≥ 1e-6): dg and D_g
        // up to 20 °/h (1e-4 rad/s), kg, ka up to 2000 ppm, ba up to 2 mg.
        let mut seed = 0x5eed_u64 + i as u64;
        let mut r = || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        for k in 0..12 {
            x[i + k] = 1e-4 * r(); // dg, D_g (rad/s, rad/s per g)
        }
        for k in 12..21 {
            x[i + k] = 2e-3 * r(); // kg, ba (g), ka
        }
    }
    x
}

/// Commanded increment over one period of 1 s for a computed frame `c_cn`:
/// the rolling rate about a fixed c-frame axis plus the Earth rate.
fn increment(c_cn: &Matrix3<f64>) -> Vector3<f64> {
    let axis = Vector3::new(1.0, -2.0, 0.5).normalize();
    axis * ROLL_RATE + c_cn * env().earth_rate_n
}

/// Max |analytic − FD| per state group (columns, in the order of
/// `id.states()`), with the largest |FD entry| of the group for scale.
#[derive(Debug, Default, Clone)]
struct Blocks(Vec<(&'static str, f64, f64)>);

impl Blocks {
    fn new<const R: usize, const N: usize>(
        states: &[StateInfo],
        an: &SMatrix<f64, R, N>,
        fdj: &SMatrix<f64, R, N>,
    ) -> Self {
        let mut out = Self::default();
        out.add(states, an, fdj);
        out
    }

    fn add<const R: usize, const N: usize>(
        &mut self,
        states: &[StateInfo],
        an: &SMatrix<f64, R, N>,
        fdj: &SMatrix<f64, R, N>,
    ) {
        assert_eq!(states.len(), N);
        for (j, info) in states.iter().enumerate() {
            let err = (an.column(j) - fdj.column(j)).amax();
            let size = fdj.column(j).amax();
            let name = info.group.as_str();
            match self.0.iter_mut().find(|(n, _, _)| *n == name) {
                Some(b) => {
                    b.1 = b.1.max(err);
                    b.2 = b.2.max(size);
                }
                None => self.0.push((name, err, size)),
            }
        }
    }

    fn max(&self) -> f64 {
        self.0.iter().map(|b| b.1).fold(0.0, f64::max)
    }

    /// The largest ratio of a group's error to what it is allowed: `TOL`,
    /// or for the full model's gyro-error groups (dg, Dg, kg) of the
    /// period's transition `TOL + REL_TOL_TRANSITION · |J|` (see
    /// [`REL_TOL_TRANSITION`]). ≤ 1 passes.
    fn worst_ratio(&self, transition: bool) -> f64 {
        self.0
            .iter()
            .map(|(n, e, s)| {
                let allowed = if transition && matches!(*n, "dg" | "Dg" | "kg") {
                    TOL + REL_TOL_TRANSITION * s
                } else {
                    TOL
                };
                e / allowed
            })
            .fold(0.0, f64::max)
    }

    fn describe(&self) -> String {
        let parts: Vec<String> = self
            .0
            .iter()
            .map(|(n, e, s)| format!("{n} {e:.1e} (|J| {s:.1e})"))
            .collect();
        parts.join(", ")
    }
}

/// The checks of one configuration, plus diagnostics of `H`.
struct Report {
    id: ConfigId,
    errors: ErrorModel,
    accel: Blocks,
    rate: Blocks,
    phi: Blocks,
    h: Blocks,
}

fn check<M: Model<N, Z>, const N: usize, const Z: usize>() -> Report {
    let id = M::ID;
    let layout = M::LAYOUT;
    let states = M::states();
    assert_eq!(layout, id.layout_with(M::ERRORS));
    assert_eq!((layout.n(), layout.z()), (N, Z));
    let env = env();
    let x: SVector<f64, N> = state(&layout);
    let c_cn0 = dcm(&Vector3::new(0.3, 1.0, -0.5));
    let frame = CommandFrame {
        c_cn: c_cn0,
        earth_rate_n: env.earth_rate_n,
    };
    let period: Period<f64> = frame.period(&increment(&c_cn0), 1.0);

    // Instantaneous accelerometer Jacobian, at the start and end nodes.
    let mut accel = Blocks::default();
    for c_cn in [period.c_cn[0], period.c_cn[2]] {
        let m = layout.matrices(&x);
        let an: SMatrix<f64, 3, N> = layout.accel_jacobian(&env, &m, &layout.attitude(&x), &c_cn);
        let fdj = fd(
            |x| layout.accel_output(&env, &layout.matrices(x), &layout.attitude(x), &c_cn),
            &x,
        );
        accel.add(states, &an, &fdj);
    }

    // Attitude-rate Jacobian (the rows of F), at the start and mid nodes.
    let mut rate = Blocks::default();
    for (w, c_cn) in [
        (period.omega_c[0], period.c_cn[0]),
        (period.omega_c[1], period.c_cn[1]),
    ] {
        let m = layout.matrices(&x);
        let an: SMatrix<f64, 3, N> = layout
            .attitude_rate_jacobian(&env, &m, &layout.attitude(&x), &w, &c_cn)
            .expect("no gimbal lock");
        let fdj = fd(
            |x| {
                layout
                    .attitude_rate(&env, &layout.matrices(x), &layout.attitude(x), &w, &c_cn)
                    .expect("no gimbal lock")
            },
            &x,
        );
        rate.add(states, &an, &fdj);
    }

    // Φ: the attitude rows of ∂x_{k+1}/∂x_k of one RK4 period.
    let propagate = |x: &SVector<f64, N>, period: &Period<f64>| -> PeriodPropagation<f64, N> {
        layout
            .propagate(&env, &layout.matrices(x), &layout.attitude(x), period)
            .expect("propagation succeeds")
    };
    let an = propagate(&x, &period).phi_att;
    let fdj = fd(|x| propagate(x, &period).att[2], &x);
    let phi = Blocks::new(states, &an, &fdj);

    // H of the filter, w.r.t. the end-of-period state (computed frame
    // starting aligned with n, as the filter's does).
    let config = FilterConfig {
        env,
        sigma_accel: 1e-6,
        sigma_gyro: 1e-9,
        sigma_gimbal: 5e-5,
        options: Options::plain(),
    };
    let mut filter =
        Filter::<f64, M, N, Z>::new(config, x, SVector::repeat(DEG)).expect("valid filter");
    let inc = increment(&Matrix3::identity());
    filter.predict(&inc, 1.0).expect("predict succeeds");
    let x_end = *filter.state();
    // The Euler attitude turns with the platform (≈ 1.7e-3 rad); the
    // misalignment ψ only by ≈ |ΔG ωc| T ≈ 1e-5 rad.
    assert!((x_end - x).amax() > 1e-6, "predict moved the attitude");
    let (_, h_an) = filter.measurement_at(&x_end).expect("measurement");
    let h_fd = fd(|x| filter.measurement_at(x).expect("measurement").0, &x_end);
    let h = Blocks::new(states, &h_an, &h_fd);

    Report {
        id,
        errors: M::ERRORS,
        accel,
        rate,
        phi,
        h,
    }
}

fn run(id: ConfigId, errors: ErrorModel) -> Report {
    let report = rollcal::with_model!(id, errors, |M, N, Z| check::<M, N, Z>());
    assert_eq!((report.id, report.errors), (id, errors));
    report
}

/// Runs every configuration, installation-only and full,
/// prints the errors of one check and asserts them against `TOL` (and,
/// for a `transition` check, the gyro errors' columns against
/// `REL_TOL_TRANSITION` of their size).
fn assert_check(
    name: &str,
    transition: bool,
    pick: impl Fn(&Report) -> &Blocks,
    diagnose: impl Fn(&Report),
) {
    let mut failures = Vec::new();
    for (id, errors) in ErrorModel::ALL
        .into_iter()
        .flat_map(|e| ConfigId::ALL.map(|id| (id, e)))
    {
        let report = run(id, errors);
        let id = format!("{id} {errors}");
        let blocks = pick(&report);
        let worst = blocks.max();
        eprintln!(
            "{id} {name}: max |analytic − FD| {worst:.2e}  [{}]",
            blocks.describe()
        );
        if blocks.worst_ratio(transition) > 1.0 {
            diagnose(&report);
            failures.push(format!(
                "{id} {name}: {worst:.2e} > {TOL:e} (or {REL_TOL_TRANSITION:e} relative)  [{}]",
                blocks.describe()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "Jacobian errors above {TOL:e}:\n{}",
        failures.join("\n")
    );
}

#[test]
fn accel_jacobian_matches_finite_differences() {
    assert_check("accel_jacobian", false, |r| &r.accel, |_| {});
}

#[test]
fn attitude_rate_jacobian_matches_finite_differences() {
    assert_check("attitude_rate_jacobian", false, |r| &r.rate, |_| {});
}

#[test]
fn transition_matches_finite_differences() {
    assert_check("phi_att", true, |r| &r.phi, |_| {});
}

#[test]
fn measurement_jacobian_matches_finite_differences() {
    assert_check("H (measurement_at)", true, |r| &r.h, |_| {});
}
