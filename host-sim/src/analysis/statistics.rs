//! The statistics of the consistency checks and the Monte Carlo bands:
//! the standard normal and χ² quantiles.

/// Standard normal quantile `Φ⁻¹(p)`, `0 < p < 1` (Acklam's rational
/// approximation, relative error below 1.2e-9; NaN outside (0, 1)).
pub fn normal_quantile(p: f64) -> f64 {
    if !(p > 0.0 && p < 1.0) {
        return f64::NAN;
    }
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383_577_518_672_69e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// The `p` quantile of χ²(k) by the Wilson–Hilferty approximation
/// `k (1 − 2/(9k) + z_p √(2/(9k)))³` (relative error below 1 % for k ≥ 10
/// in the tails used here, far smaller for the thousands of degrees of
/// freedom of a log).
pub fn chi2_quantile(p: f64, k: f64) -> f64 {
    let a = 2.0 / (9.0 * k);
    let c = 1.0 - a + normal_quantile(p) * a.sqrt();
    k * c.max(0.0).powi(3)
}

/// The upper tail `P(χ²(k) > x)` for a whole number of degrees of freedom
/// `k ≥ 1` (the regularised upper incomplete gamma `Q(k/2, x/2)`: its
/// series below `a + 1`, its continued fraction above; relative error
/// below 1e-12). The share of clean updates an NIS gate at `x` refuses.
///
/// # Examples
///
/// ```
/// use host_sim::analysis::statistics::chi2_upper_tail;
///
/// assert!((chi2_upper_tail(2.0, 2) - (-1.0f64).exp()).abs() < 1e-14);
/// // The calibrator's gate of 30 on 3 and 6 degrees of freedom.
/// assert!((chi2_upper_tail(30.0, 3) / 1.380057031e-6 - 1.0).abs() < 1e-9);
/// assert!((chi2_upper_tail(30.0, 6) / 3.930844818e-5 - 1.0).abs() < 1e-9);
/// ```
pub fn chi2_upper_tail(x: f64, k: usize) -> f64 {
    if k == 0 || x.is_nan() {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 1.0;
    }
    let (a, x) = (k as f64 / 2.0, x / 2.0);
    // ln Γ(a) for a whole or half-whole a.
    let mut ln_gamma = if k.is_multiple_of(2) {
        0.0
    } else {
        0.5 * std::f64::consts::PI.ln()
    };
    let mut t = if k.is_multiple_of(2) { 1.0 } else { 0.5 };
    while t < a - 0.25 {
        ln_gamma += t.ln();
        t += 1.0;
    }
    let front = (-x + a * x.ln() - ln_gamma).exp();
    if x < a + 1.0 {
        // P(a, x) by its series; Q = 1 − P.
        let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
        for _ in 0..1000 {
            n += 1.0;
            term *= x / n;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        1.0 - sum * front
    } else {
        // Q(a, x) by Lentz's continued fraction.
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < 1e-16 {
                break;
            }
        }
        front * h
    }
}
