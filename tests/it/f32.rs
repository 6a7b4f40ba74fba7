//! Single precision: the estimator of record with its covariance arithmetic
//! in `f32` against `f64` on the same recorded data (the paper stream, as a
//! platform sends it), through the library alone (docs/estimator.md, "Single
//! precision"). host-sim's `tests/it/f32.rs` adds the other scenarios and the
//! f32 Monte Carlo.

use crate::support;

use nalgebra::{RealField, SVector};
use rollcal::ekf::{Observation, Options};
use rollcal::estimator::{estimate, EstimatorOptions, LogRecord, SliceLog};
use rollcal::models::{M1Pa, M2Ps, M4Pa, Model};
use rollcal::wire::{CalibratorConfig, Sample};

fn log_t<T: RealField + Copy>(samples: &[Sample]) -> Vec<LogRecord<T>> {
    let t = |v: f64| nalgebra::convert::<f64, T>(v);
    samples
        .iter()
        .map(|s| {
            let r = support::log_record(s);
            LogRecord {
                dt: r.dt,
                dtheta_cmd: r.dtheta_cmd,
                observation: r.observation.map(|o| Observation {
                    accel_mean: o.accel_mean.map(t),
                    gimbal: o.gimbal.map(|g| g.map(t)),
                }),
            }
        })
        .collect()
}

/// The estimator of record's answer `(x, σ, passes)` in precision `T`.
fn answer<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize>(
    settings: &CalibratorConfig,
    samples: &[Sample],
) -> (SVector<f64, N>, SVector<f64, N>, u32) {
    let mut records = log_t::<T>(samples);
    let mut log = SliceLog::from_records(&mut records);
    let sigma0 = nalgebra::convert::<f64, T>(settings.prior_sigma_rad);
    let o = estimate::<T, M, N, Z, _, _>(
        &support::filter_config(settings, Options::default()).to_precision::<T>(),
        &SVector::zeros(),
        &SVector::repeat(sigma0),
        &mut log,
        &EstimatorOptions::default(),
        |_| {},
    )
    .expect("the estimator runs");
    let f = |v: T| nalgebra::try_convert::<T, f64>(v).unwrap_or(f64::NAN);
    (
        *o.filter.state(),
        o.filter.sigma().map(f),
        o.report.passes.into(),
    )
}

/// `(max |x32 − x64|/σ64, max σ32/σ64, min σ32/σ64)` on the paper stream.
fn compare<M: Model<N, Z>, const N: usize, const Z: usize>(name: &str) -> (f64, f64, f64) {
    let (settings, samples) = support::paper_stream();
    let (x64, s64, p64) = answer::<f64, M, N, Z>(&settings, &samples);
    let (x32, s32, p32) = answer::<f32, M, N, Z>(&settings, &samples);
    let mut worst = (0.0_f64, 0.0_f64, f64::INFINITY);
    for i in 0..N {
        let d = (x32[i] - x64[i]).abs() / s64[i];
        let r = s32[i] / s64[i];
        worst = (worst.0.max(d), worst.1.max(r), worst.2.min(r));
    }
    eprintln!(
        "{name}: f32 {p32} passes, f64 {p64}: max |dx|/sigma {:.4}, sigma ratio {:.4}..{:.4}",
        worst.0, worst.2, worst.1
    );
    worst
}

#[test]
fn f32_matches_f64_m1pa() {
    let (d, hi, lo) = compare::<M1Pa, 12, 3>("M1-pa");
    assert!(d < 0.1 && hi < 1.05 && lo > 1.0 / 1.05);
}

#[test]
fn f32_matches_f64_m4pa() {
    let (d, hi, lo) = compare::<M4Pa, 12, 3>("M4-pa");
    assert!(d < 0.1 && hi < 1.05 && lo > 1.0 / 1.05);
}

#[test]
fn f32_matches_f64_m2ps() {
    let (d, hi, lo) = compare::<M2Ps, 18, 6>("M2-ps");
    assert!(d < 0.1 && hi < 1.05 && lo > 1.0 / 1.05);
}

/// A noise-free stream of configuration `id` rolling at `rate` (rad/s, c
/// frame, a few degrees a second) from zero errors, as the platform would
/// send it (accelerometer means and gimbal angles in f32), fed to a
/// session in precision `T`: the number of samples it refused, its final
/// estimate of record, and how close the path came to gimbal lock (the
/// smallest `90° − |β|` of the true middle gimbal angle at the period ends,
/// in degrees).
fn fast_roll<T: RealField + Copy>(
    id: rollcal::models::ConfigId,
    rate: nalgebra::Vector3<f64>,
    periods: u32,
) -> (u32, rollcal::wire::Estimate, f64) {
    use nalgebra::{SMatrix, Vector3};
    use rollcal::command::CommandFrame;
    use rollcal::geometry::{quaternion_from_dcm, wrap_angles};
    use rollcal::models::Environment;
    use rollcal::session::{Reply, Session};
    use rollcal::wire::Message;

    let settings = CalibratorConfig::paper(id);
    let env = Environment {
        earth_rate_n: Vector3::from(settings.earth_rate_n),
        gravity_n: Vector3::from(settings.gravity_n),
    };
    let layout = id.layout();
    let mut x = SVector::<f64, 18>::zeros();
    let mut frame = CommandFrame::aligned(env.earth_rate_n);
    let mut records = vec![LogRecord::<T>::predicted(1.0, Vector3::zeros()); periods as usize];
    let mut log = SliceLog::new(&mut records);
    let mut session = Session::<T>::new(None, EstimatorOptions::default());
    assert!(matches!(
        session.handle(&Message::Configure(settings), &mut log),
        Reply::Nothing
    ));
    let mut refused = 0;
    let mut lock_margin_deg = 90.0_f64;
    for seq in 1..=periods {
        let dtheta = frame.increment(&rate, 1.0);
        let period = frame.period_at_rate(&rate, 1.0);
        let m = layout.matrices(&x);
        let prop = layout
            .propagate::<f64, 18>(&env, &m, &layout.attitude(&x), &period)
            .expect("no gimbal lock");
        let mut h = SMatrix::<f64, 3, 18>::zeros();
        let (z, _) = layout.mean_accel(&env, &m, &prop, &period, &mut h);
        let [_, _, end] = prop.att;
        x.fixed_rows_mut::<3>(0).copy_from(&end);
        frame.advance(&period);
        let g = wrap_angles(&layout.attitude(&x));
        lock_margin_deg = lock_margin_deg.min(g.y.cos().abs().asin().to_degrees());
        let sample = Sample {
            seq,
            t_us: u64::from(seq) * 1_000_000,
            dt: 1.0,
            dtheta_cmd: [dtheta.x, dtheta.y, dtheta.z],
            c_cn_quat: quaternion_from_dcm(&frame.c_cn).map(|v| v as f32),
            accel_mean: [z.x as f32, z.y as f32, z.z as f32],
            gimbal: layout
                .gimbal_obs
                .then_some([g.x as f32, g.y as f32, g.z as f32]),
        };
        if let Reply::Rejected(_) = session.handle(&Message::Sample(sample), &mut log) {
            refused += 1;
        }
    }
    match session.handle(&Message::Finish, &mut log) {
        Reply::Send(Message::Estimate(e)) => (refused, e, lock_margin_deg),
        other => panic!("Finish answered {other:?}"),
    }
}

/// A fast roll drives the attitude's variance about its best-observed axis
/// to ≈ 1e-12 rad² within a few periods, while the worst stays ≈ 2e-5
/// rad²: the time update's attitude block then spans more than f32
/// resolves. Formed densely and refactored, it came out indefinite and
/// the f32 filter refused every period from the 9th on at 1.7°/s about
/// each axis (from the 19th at 0.57°/s; `CovarianceNotPositiveDefinite`,
/// found by the session fuzz target). Refactored by weighted Gram–Schmidt
/// (`factor::attitude_block`) every period is accepted, and f32 ends within
/// 0.1σ of f64 with σ within 1.05×, as on the shipped scenarios: at
/// 0.57°/s about each axis (6× the paper's rate) over 120 s, and at 1.7°/s
/// over the 72 s before the path nears gimbal lock.
///
/// Rolled on at 1.7°/s about each axis, the platform's middle gimbal
/// passes within 0.94° of gimbal lock at 80 s (a path `host-sim` refuses
/// for M2, which measures the gimbal angles: `truth::MAX_GIMBAL_BETA_DEG`,
/// 85°). There the Euler angles' sensitivity grows as `1/cos β` (≈ 60×)
/// and the linearisation breaks down, in f64 too (the measurements behind
/// `MAX_GIMBAL_BETA_DEG`: updates gated from 87.4°, divergence at 89.5°).
/// On the 120 s run
/// that crosses it the test asserts only that f32 refuses nothing and ends
/// within 0.1σ of f64; f32's σ of M2-ps's weakest states comes out up to
/// 1.5 % under f64's (printed; 22 % while f32's attitude rate rounded `G`'s
/// diagonal, docs/estimator.md). Before the crossing (72 s, 20.9° from
/// lock) they agree within 0.03 %. M1 holds no gimbal angles among its states
/// (its attitude is the platform's misalignment):
/// its σ is checked on all three runs.
#[test]
fn f32_survives_a_fast_roll() {
    use rollcal::models::ConfigId;
    let slow = nalgebra::Vector3::new(-0.01, -0.01, -0.01);
    let fast = nalgebra::Vector3::new(-0.03, -0.03, -0.03);
    // (rate, periods, whether M2's path keeps 5° from gimbal lock).
    for (rate, periods, clear_of_lock) in [(slow, 120, true), (fast, 72, true), (fast, 120, false)]
    {
        for id in [ConfigId::M1Pa, ConfigId::M2Ps] {
            let (refused64, e64, margin) = fast_roll::<f64>(id, rate, periods);
            let (refused32, e32, _) = fast_roll::<f32>(id, rate, periods);
            let mut worst = (0.0_f64, 1.0_f64, 1.0_f64);
            for ((x32, x64), (s32, s64)) in e32
                .state
                .iter()
                .zip(&e64.state)
                .zip(e32.sigma.iter().zip(&e64.sigma))
            {
                let r = s32 / s64;
                worst = (
                    worst.0.max((x32 - x64).abs() / s64),
                    worst.1.min(r),
                    worst.2.max(r),
                );
            }
            // M1 holds no gimbal angles (its attitude states are the
            // platform's small misalignment): nothing nears a lock.
            let gimbal_path = id.layout().gimbal_obs;
            let clear = !gimbal_path || margin >= 5.0;
            let lock = if gimbal_path {
                format!(", {margin:.2} deg from gimbal lock")
            } else {
                String::new()
            };
            eprintln!(
                "{id} at {:.2} rad/s per axis over {periods} s{lock}: refused f64 {refused64}, \
                 f32 {refused32}; max |dx|/sigma {:.4}, sigma ratio {:.4}..{:.4}",
                rate.x.abs(),
                worst.0,
                worst.1,
                worst.2
            );
            if gimbal_path {
                assert_eq!(clear, clear_of_lock, "{id}: {margin:.2} deg from lock");
            }
            assert_eq!((refused64, refused32), (0, 0), "{id}");
            assert_eq!(e32.kind, e64.kind, "{id}");
            assert!(worst.0 < 0.1, "{id}: f32 {:.3} sigma from f64", worst.0);
            if clear {
                assert!(
                    worst.1 > 1.0 / 1.05 && worst.2 < 1.05,
                    "{id}: sigma ratio {:.4}..{:.4}",
                    worst.1,
                    worst.2
                );
            }
        }
    }
}
