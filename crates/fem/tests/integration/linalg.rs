//! The small dense kernels behind the materials: symmetric eigen-decomposition (closed form in
//! 2D) against its definition.

use femp_fem::linalg::sym_eigen;
use femp_testkit::matrix;
use nalgebra::SMatrix;
use proptest::prelude::*;

fn check<const D: usize>(m: SMatrix<f64, D, D>) -> Result<(), TestCaseError> {
    let a = 0.5 * (m + m.transpose());
    let (vals, vecs) = sym_eigen(&a);
    let scale = 1.0 + a.norm();
    prop_assert!(
        (vecs.transpose() * vecs - SMatrix::<f64, D, D>::identity()).norm() < 1e-12,
        "eigenvectors not orthonormal"
    );
    for k in 0..D {
        let v = vecs.column(k);
        prop_assert!(
            (a * v - v * vals[k]).norm() < 1e-12 * scale,
            "A v ≠ λ v for pair {k}"
        );
    }
    Ok(())
}

proptest! {
    #[test]
    fn eigen_pairs_2d(m in matrix::<2>(1e3)) { check(m)?; }
    #[test]
    fn eigen_pairs_3d(m in matrix::<3>(1e3)) { check(m)?; }
    #[test]
    fn eigen_pairs_2d_near_multiple(d in -1.0f64..1.0, e in -1e-9f64..1e-9) {
        check(SMatrix::<f64, 2, 2>::new(d, e, e, d + e))?;
    }
}
