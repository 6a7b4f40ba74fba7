//! Single precision: the estimator of record with its covariance arithmetic
//! in `f32` against `f64` on the same recorded data (the paper stream, as a
//! platform sends it), through the library alone (docs/model.md §Estimator, "single
//! precision"). host-sim's `tests/f32.rs` adds the other scenarios and the
//! f32 Monte Carlo.

mod support;

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
