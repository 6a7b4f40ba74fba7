//! The observability module: the eigen-solver, the null-space basis, and
//! the verdicts on the paper's scenario (the latter in host-sim's tests).

use nalgebra::{SMatrix, SVector};
use rollcal::observability::{jacobi_eigen, Spectrum};

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
