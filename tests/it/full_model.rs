//! The full model of docs/model.md §Instrument errors (installation errors followed by the
//! instruments' own errors `dg, D_g, kg, ba, ka`) in the core crate:
//!
//! - a full state with zero instrument errors gives the installation
//!   layout's attitude rate, accelerometer output and mean over a period
//!   (to rounding), and its Jacobians' installation columns;
//! - every one of the 14 model types has `N` state names, the full ones the
//!   installation names followed by the 21 instrument names;
//! - `ErrorModel` parses its names back;
//! - `mean_accel`'s Jacobian with respect to the end-of-period state
//!   against central differences of its value, for the seven full models;
//! - a `Filter` of `M2PsFull` and `M1PaFull` (f64, and `M1PaFull` in f32)
//!   constructs and steps on the recorded paper stream.
//!
//! The Jacobians of the full models against finite differences are in
//! `jacobians` (the same checks as the installation models', over both
//! error models); the mean over a period against its single-precision
//! value in `shared_evaluations`.

use core::f64::consts::PI;

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use rollcal::command::{CommandFrame, Period};
use rollcal::ekf::{Filter, Observation, Options};
use rollcal::geometry::{dcm, earth_rate_n, EARTH_RATE};
use rollcal::models::{
    ConfigId, Environment, ErrorModel, Group, M1PaFull, M2PsFull, Model, ParseErrorModelError,
    PeriodPropagation,
};

use crate::support;

const DEG: f64 = PI / 180.0;

fn lcg(seed: &mut u64) -> f64 {
    *seed = seed
        .wrapping_mul(6_364_136_223_846_793_005)
        .wrapping_add(1_442_695_040_888_963_407);
    ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
}

fn env() -> Environment<f64> {
    Environment {
        earth_rate_n: earth_rate_n(EARTH_RATE, 34.25 * DEG),
        gravity_n: Vector3::new(0.0, 1.0, 0.0),
    }
}

/// The installation model `I` (`NI` states) and the full one `F` (`NF`)
/// of one configuration agree at a full state whose instrument errors are
/// zero: rate, its Jacobian's installation columns, the instantaneous
/// accelerometer output and Jacobian, the propagation and the mean over a
/// period. Returns the largest difference seen.
fn zero_errors_agree<
    I: Model<NI, Z>,
    F: Model<NF, Z>,
    const NI: usize,
    const NF: usize,
    const Z: usize,
>(
    seed: u64,
) -> f64 {
    assert_eq!(I::ID, F::ID);
    assert_eq!(
        (I::ERRORS, F::ERRORS),
        (ErrorModel::Installation, ErrorModel::Full)
    );
    let (li, lf) = (I::LAYOUT, F::LAYOUT);
    assert_eq!(lf.instruments(), Some(NI));
    let env = env();
    let mut s = seed;
    let mut worst: f64 = 0.0;
    for _ in 0..20 {
        let mut xi = SVector::<f64, NI>::from_fn(|_, _| 5e-3 * lcg(&mut s));
        if li.attitude != rollcal::models::AttitudeKind::Misalignment {
            for v in xi.iter_mut().take(3) {
                *v *= 200.0;
            }
        }
        let mut xf = SVector::<f64, NF>::zeros();
        xf.fixed_rows_mut::<NI>(0).copy_from(&xi);
        let (mi, mf) = (li.matrices(&xi), lf.matrices(&xf));
        let att = li.attitude(&xi);
        let c_cn = dcm(&Vector3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)));
        let w = Vector3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)) * 2e-3;
        let mut diff = |a: f64| worst = worst.max(a);

        let ri = li.attitude_rate(&env, &mi, &att, &w, &c_cn).unwrap();
        let rf = lf.attitude_rate(&env, &mf, &att, &w, &c_cn).unwrap();
        diff((ri - rf).amax());
        let ji: SMatrix<f64, 3, NI> = li
            .attitude_rate_jacobian(&env, &mi, &att, &w, &c_cn)
            .unwrap();
        let jf: SMatrix<f64, 3, NF> = lf
            .attitude_rate_jacobian(&env, &mf, &att, &w, &c_cn)
            .unwrap();
        diff((ji - jf.fixed_columns::<NI>(0)).amax());

        let (zi, hi): (Vector3<f64>, SMatrix<f64, 3, NI>) =
            li.accel_output_and_jacobian(&env, &mi, &att, &c_cn);
        let (zf, hf): (Vector3<f64>, SMatrix<f64, 3, NF>) =
            lf.accel_output_and_jacobian(&env, &mf, &att, &c_cn);
        diff((zi - zf).amax());
        diff((hi - hf.fixed_columns::<NI>(0)).amax());
        // ∂Z/∂ba = I and ∂Z/∂ka = diag(A f^p) even at zero errors.
        let iba = lf.ba().unwrap();
        diff((hf.fixed_columns::<3>(iba) - Matrix3::identity()).amax());
        let ika = lf.ka().unwrap();
        diff((hf.fixed_columns::<3>(ika) - Matrix3::from_diagonal(&zi)).amax());

        let frame = CommandFrame {
            c_cn,
            earth_rate_n: env.earth_rate_n,
        };
        let period: Period<f64> = frame.period(&w, 1.0);
        let pi: PeriodPropagation<f64, NI> = li.propagate(&env, &mi, &att, &period).unwrap();
        let pf: PeriodPropagation<f64, NF> = lf.propagate(&env, &mf, &att, &period).unwrap();
        for (a, b) in pi.att.iter().zip(pf.att.iter()) {
            diff((a - b).amax());
        }
        let (mut hmi, mut hmf) = (
            SMatrix::<f64, 3, NI>::zeros(),
            SMatrix::<f64, 3, NF>::zeros(),
        );
        let (zmi, _) = li.mean_accel(&env, &mi, &pi, &period, &mut hmi);
        let (zmf, _) = lf.mean_accel(&env, &mf, &pf, &period, &mut hmf);
        diff((zmi - zmf).amax());
        diff((hmi - hmf.fixed_columns::<NI>(0)).amax());
    }
    worst
}

#[test]
fn full_model_with_zero_instrument_errors_is_the_installation_model() {
    use rollcal::models::*;
    for (name, worst) in [
        ("M1-pa", zero_errors_agree::<M1Pa, M1PaFull, 12, 48, 3>(1)),
        ("M1-ps", zero_errors_agree::<M1Ps, M1PsFull, 15, 51, 3>(2)),
        ("M2-ps", zero_errors_agree::<M2Ps, M2PsFull, 18, 54, 6>(3)),
        ("M3-pa", zero_errors_agree::<M3Pa, M3PaFull, 15, 51, 3>(4)),
        ("M3-ps", zero_errors_agree::<M3Ps, M3PsFull, 18, 54, 3>(5)),
        ("M4-pa", zero_errors_agree::<M4Pa, M4PaFull, 12, 48, 3>(6)),
        ("M4-ps", zero_errors_agree::<M4Ps, M4PsFull, 15, 51, 3>(7)),
    ] {
        eprintln!("{name}: full (zero instrument errors) − installation: {worst:.1e}");
        // Rounding: the full model adds zeros (`0 · f`, `+ 0`) and
        // recomputes C^p_n f^n; a few ulp of values ≤ 2.
        assert!(worst < 1e-14, "{name}: {worst:e}");
    }
}

/// `N` names for each of the 14 model types, the full ones the
/// installation names followed by the 21 instrument names, units and
/// groups as docs/model.md §Instrument errors has them.
fn names_of<M: Model<N, Z>, const N: usize, const Z: usize>() {
    let states = M::states();
    assert_eq!(states.len(), N, "{} {}", M::ID, M::ERRORS);
    assert_eq!(states, M::ID.states_with(M::ERRORS));
    assert_eq!(M::LAYOUT.n(), N);
    let installation = M::ID.states();
    assert_eq!(&states[..installation.len()], installation);
    if M::ERRORS == ErrorModel::Full {
        let pa = M::LAYOUT.frame == rollcal::models::PlatformFrame::Pa;
        let d = if pa { "Dgpa" } else { "Dg" };
        let mut expected: Vec<String> = ["dg_x", "dg_y", "dg_z"].map(String::from).to_vec();
        for r in ["x", "y", "z"] {
            for c in ["x", "y", "z"] {
                expected.push(format!("{d}_{r}{c}"));
            }
        }
        for g in ["kg", "ba", "ka", "k2", "dg_gm", "ba_gm", "dg_wu", "ba_wu"] {
            for a in ["x", "y", "z"] {
                expected.push(format!("{g}_{a}"));
            }
        }
        let tail: Vec<String> = states[installation.len()..]
            .iter()
            .map(|s| s.name.to_string())
            .collect();
        assert_eq!(tail, expected);
        let i = M::LAYOUT.instruments().unwrap();
        let expect = |k: usize, group: Group, unit: &str, printed: &str| {
            let s = &states[i + k];
            assert_eq!(
                (s.group, s.unit, s.printed_scale().1),
                (group, unit, printed),
                "{}",
                s.name
            );
        };
        expect(0, Group::GyroDrift, "rad/s", "°/h");
        expect(3, Group::GyroGDrift, "rad/s/g", "°/h/g");
        expect(12, Group::GyroScale, "1", "ppm");
        expect(15, Group::AccelBias, "g", "µg");
        expect(18, Group::AccelScale, "1", "ppm");
        expect(21, Group::AccelSecondOrder, "1/g", "µg/g²");
        expect(24, Group::GyroMarkov, "rad/s", "°/h");
        expect(27, Group::AccelMarkov, "g", "µg");
        expect(30, Group::GyroWarmup, "rad/s", "°/h");
        expect(33, Group::AccelWarmup, "g", "µg");
        assert_eq!(Some(i + 15), M::LAYOUT.ba());
    } else {
        assert!(states
            .iter()
            .all(|s| s.unit == "rad" && !s.group.is_instrument()));
    }
    // The group names round trip (JSON keys).
    for s in states {
        assert_eq!(Group::from_name(s.group.as_str()), Some(s.group));
    }
}

#[test]
fn every_model_type_has_n_state_names() {
    for errors in ErrorModel::ALL {
        for id in ConfigId::ALL {
            rollcal::with_model!(id, errors, |M, N, Z| names_of::<M, N, Z>());
            let n = rollcal::with_model!(id, errors, |M, N, Z| {
                assert_eq!((M::ID, M::ERRORS), (id, errors));
                N
            });
            assert_eq!(n, id.layout_with(errors).n());
            assert_eq!(n, id.states().len() + errors.extra_states());
        }
    }
}

#[test]
fn error_model_parses_its_names() {
    for e in ErrorModel::ALL {
        assert_eq!(e.as_str().parse::<ErrorModel>(), Ok(e));
        assert_eq!(
            e.to_string().to_ascii_uppercase().parse::<ErrorModel>(),
            Ok(e)
        );
        assert_eq!(ErrorModel::parse(e.as_str()), Some(e));
    }
    assert_eq!(ErrorModel::default(), ErrorModel::Installation);
    assert_eq!("bias".parse::<ErrorModel>(), Err(ParseErrorModelError));
    assert_eq!("".parse::<ErrorModel>(), Err(ParseErrorModelError));
    assert_eq!(
        ParseErrorModelError.to_string(),
        "unknown error model (expected installation or full)"
    );
}

/// The default priors of the 21 instrument errors in internal units, after
/// the installation σ0 of the stream's settings.
fn sigma0<M: Model<N, Z>, const N: usize, const Z: usize>(installation: f64) -> SVector<f64, N> {
    let deg_h = DEG / 3600.0;
    let mut s = SVector::<f64, N>::repeat(installation);
    let l = M::LAYOUT;
    let set = |s: &mut SVector<f64, N>, i: Option<usize>, k: usize, v: f64| {
        for j in 0..k {
            s[i.unwrap() + j] = v;
        }
    };
    set(&mut s, l.dg(), 3, deg_h);
    set(&mut s, l.d_g(), 9, deg_h);
    set(&mut s, l.kg(), 3, 2000e-6);
    set(&mut s, l.ba(), 3, 1000e-6);
    set(&mut s, l.ka(), 3, 1000e-6);
    s
}

/// Steps a filter of model `M` in precision `T` over `periods` periods of
/// the recorded paper stream (installation errors only in its truth, so
/// the instrument errors' truth is zero); returns the state and σ.
fn run_stream<T: nalgebra::RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize>(
    periods: usize,
) -> (SVector<f64, N>, SVector<f64, N>) {
    let (settings, samples) = support::paper_stream();
    let config = support::filter_config(&settings, Options::default()).to_precision::<T>();
    let s0 = sigma0::<M, N, Z>(settings.prior_sigma_rad).map(nalgebra::convert::<f64, T>);
    let mut f = Filter::<T, M, N, Z>::new(config, SVector::zeros(), s0).expect("valid filter");
    let sigma_start = f
        .sigma()
        .map(|v| nalgebra::try_convert::<T, f64>(v).unwrap());
    for s in samples.iter().take(periods) {
        let (dt, inc) = support::period(s);
        let obs = support::observation(s);
        let to_t = |v: Vector3<f64>| v.map(nalgebra::convert::<f64, T>);
        let obs = Observation {
            accel_mean: to_t(obs.accel_mean),
            gimbal: obs.gimbal.filter(|_| M::LAYOUT.gimbal_obs).map(to_t),
        };
        f.step(&inc, dt, &obs).expect("step succeeds");
    }
    assert_eq!(f.updates() as usize, periods);
    let x = *f.state();
    let sigma = f
        .sigma()
        .map(|v| nalgebra::try_convert::<T, f64>(v).unwrap());
    assert!(x.iter().chain(sigma.iter()).all(|v| v.is_finite()));
    // The accelerometer bias is learnt from the first periods on.
    let iba = M::LAYOUT.ba().unwrap();
    for k in iba..iba + 3 {
        assert!(sigma[k] < sigma_start[k], "{} σ(ba) did not fall", M::ID);
    }
    (x, sigma)
}

#[test]
fn filters_of_full_models_construct_and_step() {
    let (x, sigma) = run_stream::<f64, M2PsFull, 54, 6>(300);
    let iba = <M2PsFull as Model<54, 6>>::LAYOUT.ba().unwrap();
    eprintln!(
        "M2-ps full after 300 s: ba {:?} µg, σ {:?} µg",
        x.fixed_rows::<3>(iba).map(|v| v * 1e6).as_slice(),
        sigma.fixed_rows::<3>(iba).map(|v| v * 1e6).as_slice()
    );
    run_stream::<f64, M1PaFull, 48, 3>(300);
    run_stream::<f32, M1PaFull, 48, 3>(100);
}

/// `mean_accel`'s Jacobian with respect to the state at the end of the
/// period against central differences of its value, the period's
/// trajectory traced back from that state as the filter does
/// (`Filter::retrace`), for a full model at a state with instrument errors
/// far from zero. Returns per column `(|analytic − FD|, |FD|)`.
fn mean_accel_check<M: Model<N, Z>, const N: usize, const Z: usize>() -> Vec<(f64, f64)> {
    let layout = M::LAYOUT;
    let env = env();
    let mut s = 77 + N as u64;
    let mut x = SVector::<f64, N>::from_fn(|_, _| 5e-3 * lcg(&mut s));
    if layout.attitude != rollcal::models::AttitudeKind::Misalignment {
        x.fixed_rows_mut::<3>(0)
            .copy_from(&Vector3::new(2.0, 0.05, 1.2));
    }
    let i = layout.instruments().unwrap();
    for k in 0..36 {
        // dg, D_g up to 1e-4 rad/s(/g); kg, ba, ka up to 2e-3; k2 up to
        // 5e-4 g/g²; the Gauss–Markov parts and the warm-up up to 1e-5
        // rad/s and 2e-5 g.
        let scale = match k {
            0..=11 => 1e-4,
            12..=20 => 2e-3,
            21..=23 => 5e-4,
            24..=26 | 30..=32 => 1e-5,
            _ => 2e-5,
        };
        x[i + k] = scale * lcg(&mut s);
    }
    let c_cn0 = dcm(&Vector3::new(0.3, 1.0, -0.5));
    let frame = CommandFrame {
        c_cn: c_cn0,
        earth_rate_n: env.earth_rate_n,
    };
    let inc = Vector3::new(1.0, -2.0, 0.5).normalize() * (0.1 * DEG) + c_cn0 * env.earth_rate_n;
    let period: Period<f64> = frame.period(&inc, 1.0);
    // The mean over the period that ends at `x`, and its Jacobian.
    let mean = |x: &SVector<f64, N>| -> (Vector3<f64>, SMatrix<f64, 3, N>) {
        let m = layout.matrices(x);
        let back: PeriodPropagation<f64, N> = layout
            .propagate(&env, &m, &layout.attitude(x), &period.reversed())
            .unwrap();
        let [a1, am, a0] = back.att;
        let prop = PeriodPropagation {
            att: [a0, am, a1],
            phi_att: rollcal::models::transition_rows(&back.f_mid, period.dt),
            f_mid: back.f_mid,
            f_end: layout
                .attitude_rate_jacobian(
                    &env,
                    &m,
                    &layout.attitude(x),
                    &period.omega_c[2],
                    &period.c_cn[2],
                )
                .unwrap(),
            noise_map: back.noise_map,
        };
        let mut h = SMatrix::<f64, 3, N>::zeros();
        let (z, _) = layout.mean_accel(&env, &m, &prop, &period, &mut h);
        (z, h)
    };
    let (_, h) = mean(&x);
    let step = 1e-4;
    (0..N)
        .map(|j| {
            let at = |k: f64| {
                let mut xk = x;
                xk[j] += k * step;
                mean(&xk).0
            };
            let fd = (at(-2.0) - at(-1.0) * 8.0 + at(1.0) * 8.0 - at(2.0)) / (12.0 * step);
            ((h.column(j) - fd).amax(), fd.amax())
        })
        .collect()
}

#[test]
fn full_mean_accel_jacobian_matches_finite_differences() {
    for id in ConfigId::ALL {
        let cols =
            rollcal::with_model!(id, ErrorModel::Full, |M, N, Z| mean_accel_check::<M, N, Z>(
            ));
        let states = id.states_with(ErrorModel::Full);
        let mut worst: f64 = 0.0;
        for ((err, size), s) in cols.iter().zip(states) {
            // TOL of tests/it/jacobians.rs; the gyro errors' columns go
            // through the period's transition (REL_TOL_TRANSITION there).
            let allowed = if matches!(
                s.group,
                Group::GyroDrift
                    | Group::GyroGDrift
                    | Group::GyroScale
                    | Group::GyroMarkov
                    | Group::GyroWarmup
            ) {
                1e-9 + 1e-6 * size
            } else {
                1e-9
            };
            worst = worst.max(err / allowed);
            assert!(
                err <= &allowed,
                "{id} full {}: {err:.2e} (|J| {size:.1e})",
                s.name
            );
        }
        eprintln!("{id} full mean_accel: worst error / allowed {worst:.2e}");
        // The new columns are not trivially zero: ba, ka of O(1).
        let ika = id.layout_with(ErrorModel::Full).ka().unwrap();
        assert!(cols[ika].1 > 0.1 && cols[ika - 3].1 > 0.9);
    }
}
