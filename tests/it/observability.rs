//! The observability module: the eigen-solver, the null-space basis, the
//! Cramér–Rao bound against the information matrix, and the bound of a run
//! with lost periods (on the recorded paper stream); the verdicts on the
//! paper's scenario are in host-sim's tests.

use crate::support;

use nalgebra::{SMatrix, SVector};
use rollcal::models::{M1Pa, M2Ps, Model};
use rollcal::observability::{jacobi_eigen, Bound, Observability, Spectrum};
use rollcal::Options;

#[test]
fn jacobi_diagonalises_a_symmetric_matrix() {
    let b = SMatrix::<f64, 6, 6>::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
    let a = b * b.transpose();
    let (vals, vecs) = jacobi_eigen(a).unwrap();
    for i in 0..6 {
        let v = vecs.column(i);
        let r = a * v - v * vals[i];
        assert!(r.norm() < 1e-12 * a.norm(), "residual {}", r.norm());
    }
    assert!((vecs.transpose() * vecs - SMatrix::<f64, 6, 6>::identity()).norm() < 1e-13);
}

#[test]
fn null_space_basis_is_canonical() {
    // Null space spanned by e0+e1+e2 and e3 (mixed by a rotation).
    let u = SVector::<f64, 5>::from_column_slice(&[1.0, 1.0, 1.0, 0.0, 0.0]).normalize();
    let w = SVector::<f64, 5>::from_column_slice(&[0.0, 0.0, 0.0, 1.0, 0.0]);
    let (c, s) = (0.6_f64, 0.8_f64);
    let n1 = u * c + w * s;
    let n2 = -u * s + w * c;
    let mut vecs = SMatrix::<f64, 5, 5>::zeros();
    vecs.set_column(3, &n1);
    vecs.set_column(4, &n2);
    let spec = Spectrum {
        eigenvalues: SVector::<f64, 5>::from_column_slice(&[3.0, 2.0, 1.0, 0.0, 0.0]),
        eigenvectors: vecs,
        rel_tol: 1e-12,
        rank: 3,
    };
    let basis = spec.null_space_basis();
    let b0 = basis.column(0).clone_owned();
    let b1 = basis.column(1).clone_owned();
    println!("{b0} {b1}");
    assert!((b0 - u).norm() < 1e-12);
    assert!((b1 - w).norm() < 1e-12);
}

/// A true state of small installation errors and attitude (≈ 0.1°).
fn true_state<const N: usize>() -> SVector<f64, N> {
    SVector::from_fn(|i, _| 2e-3 * (((i * 7) % 5) as f64 - 2.0) + 1e-4)
}

/// Observability of `M` over the first `periods` periods of the recorded
/// paper stream, the periods in `lost` predicted only, with the gyro noise
/// scaled by `gyro_scale` (0: no process noise) and the measurement noise
/// by `meas_scale`.
fn observability<M: Model<N, Z>, const N: usize, const Z: usize>(
    periods: usize,
    lost: impl Fn(usize) -> bool,
    gyro_scale: f64,
    meas_scale: f64,
) -> Observability<f64, M, N, Z> {
    let (settings, samples) = support::paper_stream();
    let mut cfg = support::filter_config(&settings, Options::plain());
    cfg.sigma_gyro *= gyro_scale;
    cfg.sigma_accel *= meas_scale;
    cfg.sigma_gimbal *= meas_scale;
    let prior = SVector::<f64, N>::repeat(settings.prior_sigma_rad);
    let mut obs = Observability::<f64, M, N, Z>::new(cfg, true_state(), prior).unwrap();
    for (i, s) in samples.iter().take(periods).enumerate() {
        let (dt, d) = support::period(s);
        if lost(i) {
            obs.predict(&d, dt).unwrap();
        } else {
            obs.step(&d, dt).unwrap();
        }
    }
    assert_eq!(obs.periods() as usize, periods);
    obs
}

/// Without process noise the bound is the information form: the
/// covariance recursion (`crlb_covariance`, a Kalman filter linearised
/// along the true trajectory) equals `Φ(k,0) (P₀⁻¹ + J)⁻¹ Φ(k,0)ᵀ` computed
/// from the information matrix, with the periods of a lost burst only
/// propagated (they add nothing to `J`).
///
/// The measurement noise is 1000× the paper's: at the paper's, the
/// prior-scaled `J` spans about twelve decades and the two routes differ by
/// their round-off, up to 6e-5 of `σ_i σ_j` (it falls as the noise grows:
/// 1e-8 at ×100, 4e-10 at ×1000), which would hide a real disagreement.
fn information_form<M: Model<N, Z>, const N: usize, const Z: usize>() {
    let lost = |i: usize| (300..500).contains(&i);
    let obs = observability::<M, N, Z>(1200, lost, 0.0, 1000.0);
    let prior = support::paper_stream().0.prior_sigma_rad;
    // In prior-scaled coordinates: P = Φ S (I + S J S)⁻¹ S Φᵀ.
    let s = SMatrix::<f64, N, N>::identity() * prior;
    let scaled = SMatrix::<f64, N, N>::identity() + s * obs.information() * s;
    let inv = scaled.cholesky().unwrap().inverse();
    let phi = obs.transition();
    let p_info = phi * s * inv * s * phi.transpose();
    let p = obs.crlb_covariance();
    let mut worst: f64 = 0.0;
    for i in 0..N {
        for j in 0..N {
            // Relative to the σ of the two states (a correlation-scale error).
            let scale = (p[(i, i)] * p[(j, j)]).sqrt();
            worst = worst.max((p[(i, j)] - p_info[(i, j)]).abs() / scale);
        }
    }
    eprintln!("{}: worst |ΔP_ij|/(σ_i σ_j) = {worst:.2e}", M::ID);
    assert!(worst < 1e-8, "{}: {worst:e}", M::ID);
    // And the bound did learn: some parameter far below its prior.
    let sigma = obs.crlb_sigma();
    assert!(sigma.iter().skip(3).any(|v| *v < 1e-2 * prior));
}

#[test]
fn the_bound_without_process_noise_is_the_inverse_information() {
    information_form::<M1Pa, 12, 3>();
    information_form::<M2Ps, 18, 6>();
}

/// The bound of the samples received: a lost burst never lowers it, and it
/// raises it for every parameter the burst carried information on.
fn lost_burst_raises_the_bound<M: Model<N, Z>, const N: usize, const Z: usize>() {
    let burst = |i: usize| (2000..3000).contains(&i);
    let full = observability::<M, N, Z>(5400, |_| false, 1.0, 1.0);
    let drop = observability::<M, N, Z>(5400, burst, 1.0, 1.0);
    // The same through log records (what a calibrator logged): a record
    // without observation is a lost period; nothing lost, the full bound.
    let (settings, samples) = support::paper_stream();
    for (lose, reference) in [(false, &full), (true, &drop)] {
        let cfg = support::filter_config(&settings, Options::plain());
        let prior = SVector::<f64, N>::repeat(settings.prior_sigma_rad);
        let mut obs = Observability::<f64, M, N, Z>::new(cfg, true_state(), prior).unwrap();
        for (i, s) in samples.iter().enumerate() {
            let mut r = support::log_record(s);
            if lose && burst(i) {
                r.observation = None;
            }
            obs.record(&r).unwrap();
        }
        assert_eq!(obs.crlb_covariance(), reference.crlb_covariance());
        assert_eq!(obs.information(), reference.information());
    }
    // P_drop − P_full is positive semi-definite.
    let diff = drop.crlb_covariance() - full.crlb_covariance();
    let (vals, _) = jacobi_eigen(diff).unwrap();
    let norm = full.crlb_covariance().norm();
    let min = vals.iter().fold(f64::INFINITY, |a, b| a.min(*b));
    assert!(min > -1e-9 * norm, "{}: λ_min(ΔP) = {min:e}", M::ID);
    let (sf, sd) = (full.crlb_sigma(), drop.crlb_sigma());
    // What the burst told about each initial state: the diagonal of its
    // share of J, relative to the whole run's.
    let (jf, jd) = (full.information(), drop.information());
    let mut raised = 0;
    for i in 0..N {
        assert!(sd[i] >= sf[i] * (1.0 - 1e-9), "{} state {i}", M::ID);
        let share = (jf[(i, i)] - jd[(i, i)]) / jf[(i, i)];
        // Parameters (constants): their information is the burst's own.
        if i >= 3 && share > 0.05 {
            assert!(
                sd[i] > sf[i] * (1.0 + 1e-6),
                "{} state {i}: burst carried {:.0} % of its information but σ {:e} → {:e}",
                M::ID,
                share * 100.0,
                sf[i],
                sd[i]
            );
            raised += 1;
        }
    }
    eprintln!("{}: {raised} parameters raised by the burst", M::ID);
    assert!(raised > 0, "{}: the burst carried no information", M::ID);
}

#[test]
fn a_lost_burst_raises_the_bound_and_nothing_lowers_it() {
    lost_burst_raises_the_bound::<M1Pa, 12, 3>();
    lost_burst_raises_the_bound::<M2Ps, 18, 6>();
}

/// The bound-only mode (`Observability::bound_only`, what `host-sim design`
/// scores candidates with) advances the same bound as the full mode: on the
/// recorded paper stream with a lost burst, the covariance, σ and true
/// state agree bit for bit after every period, and the bound did learn.
fn bound_only_is_the_full_bound<M: Model<N, Z>, const N: usize, const Z: usize>() {
    let (settings, samples) = support::paper_stream();
    let cfg = support::filter_config(&settings, Options::plain());
    let prior = SVector::<f64, N>::repeat(settings.prior_sigma_rad);
    let mut full = Observability::<f64, M, N, Z>::new(cfg, true_state(), prior).unwrap();
    let mut bound = Bound::<f64, M, N, Z>::bound_only(cfg, true_state(), prior).unwrap();
    for (i, s) in samples.iter().enumerate() {
        let (dt, d) = support::period(s);
        if (2000..2300).contains(&i) {
            full.predict(&d, dt).unwrap();
            bound.predict(&d, dt).unwrap();
        } else {
            full.step(&d, dt).unwrap();
            bound.step(&d, dt).unwrap();
        }
        if i % 500 == 0 || i + 1 == samples.len() {
            assert_eq!(
                bound.crlb_covariance(),
                full.crlb_covariance(),
                "{} period {i}",
                M::ID
            );
            assert_eq!(
                bound.true_state(),
                full.true_state(),
                "{} period {i}",
                M::ID
            );
        }
    }
    assert_eq!(bound.periods(), full.periods());
    assert_eq!(bound.crlb_sigma(), full.crlb_sigma());
    assert_eq!(bound.ratio(), full.ratio());
    // Not a bound that never moved: some parameter far below its prior,
    // and the full mode did accumulate J.
    assert!(bound.ratio().iter().skip(3).any(|r| *r < 1e-2));
    assert!(full.information().norm() > 0.0);
}

#[test]
fn the_bound_only_mode_gives_the_full_bound() {
    bound_only_is_the_full_bound::<M1Pa, 12, 3>();
    bound_only_is_the_full_bound::<M2Ps, 18, 6>();
}
