//! The reference the host goals are set against (issue 10): the naive dense
//! covariance arithmetic of one filter period in static nalgebra f64, on
//! fixed well-conditioned inputs, no model evaluation. Shared by the
//! criterion group `period` (`benches/filter_period.rs`) and the
//! instruction count `examples/period_instructions.rs`.

use nalgebra::SMatrix;

/// Fixed, well-conditioned inputs of `N` states and `Z` measurements:
/// `(Φ, P, Q, H, R)`, `Φ` near the identity, `P` and `Q` SPD.
#[allow(clippy::type_complexity)]
pub fn inputs<const N: usize, const Z: usize>() -> (
    SMatrix<f64, N, N>,
    SMatrix<f64, N, N>,
    SMatrix<f64, N, N>,
    SMatrix<f64, Z, N>,
    SMatrix<f64, Z, Z>,
) {
    let phi = SMatrix::<f64, N, N>::from_fn(|i, j| {
        if i == j {
            1.0
        } else {
            1e-3 * ((i + 2 * j) % 7) as f64
        }
    });
    let a = SMatrix::<f64, N, N>::from_fn(|i, j| 1e-2 * (((3 * i + j) % 11) as f64 - 5.0));
    let p = a * a.transpose() + SMatrix::<f64, N, N>::identity() * 1e-4;
    let q = SMatrix::<f64, N, N>::identity() * 1e-10;
    let h = SMatrix::<f64, Z, N>::from_fn(|i, j| (((i + 5 * j) % 13) as f64 - 6.0) / 6.0);
    let r = SMatrix::<f64, Z, Z>::identity() * 1e-12;
    (phi, p, q, h, r)
}

/// One period of naive dense covariance arithmetic, `N` states and `Z`
/// measurements: dense `Φ P Φᵀ + Q`, `S`, its Cholesky factor, the gain,
/// the Joseph form, symmetrisation.
pub fn period<const N: usize, const Z: usize>(
    phi: &SMatrix<f64, N, N>,
    p: &SMatrix<f64, N, N>,
    q: &SMatrix<f64, N, N>,
    h: &SMatrix<f64, Z, N>,
    r: &SMatrix<f64, Z, Z>,
) -> SMatrix<f64, N, N> {
    let pp = phi * p * phi.transpose() + q;
    let s = h * pp * h.transpose() + r;
    let Some(chol) = s.cholesky() else {
        return pp;
    };
    let k = chol.solve(&(h * pp)).transpose();
    let ikh = SMatrix::<f64, N, N>::identity() - k * h;
    let out = ikh * pp * ikh.transpose() + k * r * k.transpose();
    (out + out.transpose()) * 0.5
}
