//! Test helpers shared by the femp crates (dev-dependency only): central finite differences,
//! scaled tolerance checks, and proptest strategies that build valid inputs by construction.

use nalgebra::{DMatrix, DVector, SMatrix, SVector};
use proptest::prelude::*;

/// Relative difference `|a − b| / max(|a|, |b|, floor)`.
pub fn rel_diff(a: f64, b: f64, floor: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(floor)
}

/// Assert `|a − b| ≤ tol · max(|a|, |b|, floor)`, with a message naming `what`.
#[track_caller]
pub fn assert_close(a: f64, b: f64, tol: f64, floor: f64, what: &str) {
    assert!(
        rel_diff(a, b, floor) <= tol,
        "{what}: {a:e} vs {b:e} (rel diff {:e} > {tol:e})",
        rel_diff(a, b, floor)
    );
}

/// Assert two slices agree entrywise to `tol` relative to the largest magnitude in either
/// (the scaled tolerance of fenris: `tol · amax`), floored at `floor`.
#[track_caller]
pub fn assert_slices_close(a: &[f64], b: &[f64], tol: f64, floor: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths differ");
    let amax = a
        .iter()
        .chain(b)
        .fold(0.0f64, |m, x| m.max(x.abs()))
        .max(floor);
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(
            (x - y).abs() <= tol * amax,
            "{what}[{i}]: {x:e} vs {y:e} (|diff| {:e} > {tol:e} · {amax:e})",
            (x - y).abs()
        );
    }
}

/// Central-difference gradient of `f` at `x` with step `eps`.
pub fn fd_gradient(f: impl Fn(&DVector<f64>) -> f64, x: &DVector<f64>, eps: f64) -> DVector<f64> {
    let mut g = DVector::zeros(x.len());
    let mut xp = x.clone();
    for i in 0..x.len() {
        let xi = x[i];
        xp[i] = xi + eps;
        let fp = f(&xp);
        xp[i] = xi - eps;
        let fm = f(&xp);
        xp[i] = xi;
        g[i] = (fp - fm) / (2.0 * eps);
    }
    g
}

/// Central-difference Jacobian of a vector function (rows: outputs, columns: inputs).
pub fn fd_jacobian(
    f: impl Fn(&DVector<f64>) -> DVector<f64>,
    x: &DVector<f64>,
    eps: f64,
) -> DMatrix<f64> {
    let m = f(x).len();
    let mut j = DMatrix::zeros(m, x.len());
    let mut xp = x.clone();
    for i in 0..x.len() {
        let xi = x[i];
        xp[i] = xi + eps;
        let fp = f(&xp);
        xp[i] = xi - eps;
        let fm = f(&xp);
        xp[i] = xi;
        j.set_column(i, &((fp - fm) / (2.0 * eps)));
    }
    j
}

/// Strategy: a vector with components in `[-r, r]`.
pub fn vector<const D: usize>(r: f64) -> impl Strategy<Value = SVector<f64, D>> {
    proptest::collection::vec(-r..=r, D).prop_map(|v| SVector::from_column_slice(&v))
}

/// Strategy: a matrix with entries in `[-r, r]`.
pub fn matrix<const D: usize>(r: f64) -> impl Strategy<Value = SMatrix<f64, D, D>> {
    proptest::collection::vec(-r..=r, D * D).prop_map(|v| SMatrix::from_column_slice(&v))
}

/// Strategy: a deformation gradient `F = R(θ) · S` with `S` symmetric positive definite with
/// eigenvalues in `[lo, hi]` (so `det F > 0` by construction) times a random rotation.
pub fn deformation_gradient<const D: usize>(
    lo: f64,
    hi: f64,
) -> impl Strategy<Value = SMatrix<f64, D, D>> {
    (
        proptest::collection::vec(lo..=hi, D),
        proptest::collection::vec(-std::f64::consts::PI..std::f64::consts::PI, 3),
        proptest::collection::vec(-std::f64::consts::PI..std::f64::consts::PI, 3),
    )
        .prop_map(|(sig, a, b)| {
            let u = rotation::<D>(&a);
            let v = rotation::<D>(&b);
            let s = SMatrix::<f64, D, D>::from_diagonal(&SVector::from_column_slice(&sig));
            u * s * v.transpose()
        })
}

/// A rotation matrix from up to three angles (2D uses the first).
pub fn rotation<const D: usize>(angles: &[f64]) -> SMatrix<f64, D, D> {
    let mut r = SMatrix::<f64, D, D>::identity();
    if D == 2 {
        let (s, c) = angles[0].sin_cos();
        r[(0, 0)] = c;
        r[(0, 1)] = -s;
        r[(1, 0)] = s;
        r[(1, 1)] = c;
    } else {
        for (axis, &t) in angles.iter().take(3).enumerate() {
            let (s, c) = t.sin_cos();
            let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut g = SMatrix::<f64, D, D>::identity();
            g[(i, i)] = c;
            g[(i, j)] = -s;
            g[(j, i)] = s;
            g[(j, j)] = c;
            r *= g;
        }
    }
    r
}
