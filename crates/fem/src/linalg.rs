//! Small dense linear algebra for generic `D ∈ {2, 3}` without nalgebra's dimension-trait
//! bounds: each function copies into the concrete 2×2 / 3×3 (or 4×4 / 9×9) type, works there,
//! and copies back. The copies cost nothing next to the work.

use nalgebra::{Matrix2, Matrix3, Matrix4, SMatrix, SVector, SymmetricEigen, Vector3};

/// Determinant of a `D×D` matrix.
#[inline]
pub fn det<const D: usize>(m: &SMatrix<f64, D, D>) -> f64 {
    if D == 2 {
        m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)]
    } else {
        m[(0, 0)] * (m[(1, 1)] * m[(2, 2)] - m[(1, 2)] * m[(2, 1)])
            - m[(0, 1)] * (m[(1, 0)] * m[(2, 2)] - m[(1, 2)] * m[(2, 0)])
            + m[(0, 2)] * (m[(1, 0)] * m[(2, 1)] - m[(1, 1)] * m[(2, 0)])
    }
}

/// Cofactor matrix `cof(M) = det(M) M⁻ᵀ` (defined for singular `M` too).
#[inline]
pub fn cofactor<const D: usize>(m: &SMatrix<f64, D, D>) -> SMatrix<f64, D, D> {
    let mut c = SMatrix::<f64, D, D>::zeros();
    if D == 2 {
        c[(0, 0)] = m[(1, 1)];
        c[(0, 1)] = -m[(1, 0)];
        c[(1, 0)] = -m[(0, 1)];
        c[(1, 1)] = m[(0, 0)];
    } else {
        for i in 0..3 {
            for j in 0..3 {
                let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
                let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
                c[(i, j)] = m[(i1, j1)] * m[(i2, j2)] - m[(i1, j2)] * m[(i2, j1)];
            }
        }
    }
    c
}

/// Inverse, or `None` if `|det| ≤ tiny`.
#[inline]
pub fn inverse<const D: usize>(m: &SMatrix<f64, D, D>) -> Option<SMatrix<f64, D, D>> {
    let d = det(m);
    if d == 0.0 || !d.is_finite() {
        return None;
    }
    Some(cofactor(m).transpose() / d)
}

/// Rotation-variant SVD `F = U diag(σ) Vᵀ` with `U, V` proper rotations (det = +1); the sign
/// of `det F` is carried by the last singular value.
pub fn svd_rv<const D: usize>(
    f: &SMatrix<f64, D, D>,
) -> (SMatrix<f64, D, D>, SVector<f64, D>, SMatrix<f64, D, D>) {
    let mut u = SMatrix::<f64, D, D>::zeros();
    let mut s = SVector::<f64, D>::zeros();
    let mut v = SMatrix::<f64, D, D>::zeros();
    if D == 2 {
        let m = Matrix2::from_fn(|i, j| f[(i, j)]);
        let svd = m.svd(true, true);
        let (mut uu, mut ss, vt) = (svd.u.unwrap(), svd.singular_values, svd.v_t.unwrap());
        let mut vv = vt.transpose();
        if uu.determinant() < 0.0 {
            uu.column_mut(1).neg_mut();
            ss[1] = -ss[1];
        }
        if vv.determinant() < 0.0 {
            vv.column_mut(1).neg_mut();
            ss[1] = -ss[1];
        }
        for i in 0..2 {
            s[i] = ss[i];
            for j in 0..2 {
                u[(i, j)] = uu[(i, j)];
                v[(i, j)] = vv[(i, j)];
            }
        }
    } else {
        let m = Matrix3::from_fn(|i, j| f[(i, j)]);
        let svd = m.svd(true, true);
        let (mut uu, mut ss, vt) = (svd.u.unwrap(), svd.singular_values, svd.v_t.unwrap());
        let mut vv = vt.transpose();
        // Put the smallest singular value last so a sign flip lands on it.
        let mut idx = [0usize, 1, 2];
        idx.sort_by(|&a, &b| ss[b].total_cmp(&ss[a]));
        let uu0 = uu;
        let vv0 = vv;
        let ss0 = ss;
        for (k, &i) in idx.iter().enumerate() {
            uu.set_column(k, &uu0.column(i));
            vv.set_column(k, &vv0.column(i));
            ss[k] = ss0[i];
        }
        if uu.determinant() < 0.0 {
            uu.column_mut(2).neg_mut();
            ss[2] = -ss[2];
        }
        if vv.determinant() < 0.0 {
            vv.column_mut(2).neg_mut();
            ss[2] = -ss[2];
        }
        for i in 0..3 {
            s[i] = ss[i];
            for j in 0..3 {
                u[(i, j)] = uu[(i, j)];
                v[(i, j)] = vv[(i, j)];
            }
        }
    }
    (u, s, v)
}

/// Eigen-decomposition of a symmetric `D×D` matrix: eigenvalues and eigenvectors (columns).
pub fn sym_eigen<const D: usize>(m: &SMatrix<f64, D, D>) -> (SVector<f64, D>, SMatrix<f64, D, D>) {
    let mut vals = SVector::<f64, D>::zeros();
    let mut vecs = SMatrix::<f64, D, D>::zeros();
    if D == 2 {
        // Closed form: λ = (a+c)/2 ± √(((a−c)/2)² + b²), eigenvectors a rotation by θ with
        // tan 2θ = 2b/(a−c) (exactly orthonormal; no iteration).
        let (a, b, c) = (m[(0, 0)], 0.5 * (m[(0, 1)] + m[(1, 0)]), m[(1, 1)]);
        let mid = 0.5 * (a + c);
        let rad = (0.5 * (a - c)).hypot(b);
        let theta = 0.5 * (2.0 * b).atan2(a - c);
        let (sn, cs) = theta.sin_cos();
        vals[0] = mid + rad;
        vals[1] = mid - rad;
        vecs[(0, 0)] = cs;
        vecs[(1, 0)] = sn;
        vecs[(0, 1)] = -sn;
        vecs[(1, 1)] = cs;
    } else {
        let e = SymmetricEigen::new(Matrix3::from_fn(|i, j| m[(i, j)]));
        let (ev, q): (Vector3<f64>, Matrix3<f64>) = (e.eigenvalues, e.eigenvectors);
        for i in 0..3 {
            vals[i] = ev[i];
            for j in 0..3 {
                vecs[(i, j)] = q[(i, j)];
            }
        }
    }
    (vals, vecs)
}

/// Clamp the negative eigenvalues of the symmetric `n×n` top-left block (`n = 4` or 9) of `m`
/// to zero, in place. Returns the smallest eigenvalue before clamping.
pub fn project_psd_block(m: &mut SMatrix<f64, 9, 9>, n: usize) -> f64 {
    macro_rules! proj {
        ($N:literal) => {{
            let a = SMatrix::<f64, $N, $N>::from_fn(|i, j| 0.5 * (m[(i, j)] + m[(j, i)]));
            let e = SymmetricEigen::new(a);
            let min = e.eigenvalues.min();
            if min < 0.0 {
                let clamped = e.eigenvalues.map(|l| l.max(0.0));
                let b = e.eigenvectors
                    * SMatrix::<f64, $N, $N>::from_diagonal(&clamped)
                    * e.eigenvectors.transpose();
                for i in 0..$N {
                    for j in 0..$N {
                        m[(i, j)] = b[(i, j)];
                    }
                }
            }
            min
        }};
    }
    if n == 4 { proj!(4) } else { proj!(9) }
}

/// Smallest eigenvalue of the symmetric `n×n` top-left block of `m`.
pub fn min_eigenvalue_block(m: &SMatrix<f64, 9, 9>, n: usize) -> f64 {
    if n == 4 {
        SymmetricEigen::new(Matrix4::from_fn(|i, j| m[(i, j)]))
            .eigenvalues
            .min()
    } else {
        SymmetricEigen::new(*m).eigenvalues.min()
    }
}
