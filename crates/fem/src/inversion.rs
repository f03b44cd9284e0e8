//! Largest inversion-free step: the first `τ ∈ (0, 1]` at which `det(A₀ + τ A₁)` reaches zero
//! (BFEMP §5, line-search filter (b)).
//!
//! `det(A₀ + τA₁)` is a polynomial `c₀ + c₁τ + … + c_Dτ^D` of degree `D` in `τ`, with
//! `c₀ = det A₀`, `c_D = det A₁`, and the mixed coefficients sums of determinants whose columns
//! are taken from `A₀` and `A₁` (multilinearity of the determinant in the columns). [`first_det_root`] isolates the roots robustly: the critical points of
//! the polynomial (roots of its derivative) split `[0, 1]` into monotone pieces; the first piece
//! whose right end is `≤ 10⁻¹² c₀` holds the first root, found by bisection to 1e-13 and returned from
//! the *feasible* side (never after the true root). A double root (the determinant touching
//! zero) sits at a critical point and is caught exactly there; tiny leading coefficients just
//! lower the degree. No iteration is unbounded.

use nalgebra::SMatrix;

use crate::linalg::det;

/// Coefficients `[c₀, c₁, c₂, c₃]` of `det(A₀ + τA₁)` (`c₃ = 0` in 2D).
pub fn det_polynomial<const D: usize>(
    a0: &SMatrix<f64, D, D>,
    a1: &SMatrix<f64, D, D>,
) -> [f64; 4] {
    if D == 2 {
        let c1 = a0[(0, 0)] * a1[(1, 1)] + a1[(0, 0)] * a0[(1, 1)]
            - a0[(0, 1)] * a1[(1, 0)]
            - a1[(0, 1)] * a0[(1, 0)];
        [det(a0), c1, det(a1), 0.0]
    } else {
        // Mixed terms: replace columns of A₀ by those of A₁.
        let mix = |cols: [bool; 3]| -> f64 {
            let m =
                SMatrix::<f64, D, D>::from_fn(|r, c| if cols[c] { a1[(r, c)] } else { a0[(r, c)] });
            det(&m)
        };
        let c1 = mix([true, false, false]) + mix([false, true, false]) + mix([false, false, true]);
        let c2 = mix([true, true, false]) + mix([true, false, true]) + mix([false, true, true]);
        [det(a0), c1, c2, det(a1)]
    }
}

#[inline]
fn eval(c: &[f64; 4], t: f64) -> f64 {
    ((c[3] * t + c[2]) * t + c[1]) * t + c[0]
}

/// Real roots of `a t² + b t + c` in `(0, 1)`, sorted (numerically stable formula).
fn quadratic_roots_01(a: f64, b: f64, c: f64) -> ([f64; 2], usize) {
    let mut out = [0.0; 2];
    let mut n = 0;
    let scale = a.abs().max(b.abs()).max(c.abs());
    if scale == 0.0 {
        return (out, 0);
    }
    let (a, b, c) = (a / scale, b / scale, c / scale);
    let mut push = |t: f64| {
        if t > 0.0 && t < 1.0 && t.is_finite() {
            out[n] = t;
            n += 1;
        }
    };
    if a.abs() < 1e-14 {
        if b.abs() > 1e-300 {
            push(-c / b);
        }
    } else {
        let disc = b * b - 4.0 * a * c;
        if disc >= 0.0 {
            let q = -0.5 * (b + b.signum() * disc.sqrt());
            if q != 0.0 {
                push(q / a);
                push(c / q);
            } else {
                push(0.0_f64.max(-b / (2.0 * a)));
            }
        }
    }
    if n == 2 && out[0] > out[1] {
        out.swap(0, 1);
    }
    (out, n)
}

/// The first `τ ∈ (0, 1]` with `det(A₀ + τA₁) ≤ 0`, or `None` if the determinant stays positive
/// on `(0, 1]`. If `det A₀ ≤ 0` already, returns `Some(0.0)`.
pub fn first_det_root<const D: usize>(
    a0: &SMatrix<f64, D, D>,
    a1: &SMatrix<f64, D, D>,
) -> Option<f64> {
    first_root_01(&det_polynomial(a0, a1))
}

/// First root in `(0, 1]` of the cubic `c₀ + c₁τ + c₂τ² + c₃τ³` given `c₀ > 0` (see the module
/// documentation); `Some(0.0)` if `c₀ ≤ 0`.
pub fn first_root_01(c: &[f64; 4]) -> Option<f64> {
    if !(c[0] > 0.0) {
        return Some(0.0);
    }
    // Treat a determinant that drops below 1e-12 of its start as zero: a near-touching double
    // root is caught even if the computed critical point is off by round-off.
    let floor = 1e-12 * c[0];
    // Quick exit (most particles and elements of a Newton step): on [0, 1] the cubic is at
    // least c₀ − |c₁| − |c₂| − |c₃|; with that above the floor by more than the evaluations'
    // round-off, every evaluation below would stay above it too — no root.
    let spread = c[1].abs() + c[2].abs() + c[3].abs();
    if c[0] - spread > floor + 1e-13 * (c[0] + spread) {
        return None;
    }
    // Breakpoints: 0, critical points in (0, 1), 1.
    let (crit, nc) = quadratic_roots_01(3.0 * c[3], 2.0 * c[2], c[1]);
    let mut pts = [0.0; 4];
    let mut np = 1;
    for &t in &crit[..nc] {
        pts[np] = t;
        np += 1;
    }
    pts[np] = 1.0;
    np += 1;
    for w in pts[..np].windows(2) {
        let (a, b) = (w[0], w[1]);
        if eval(c, b) <= floor {
            // p(a) > 0 ≥ p(b): bisect, keeping `lo` feasible.
            let (mut lo, mut hi) = (a, b);
            for _ in 0..200 {
                if hi - lo <= 1e-13 * hi.max(1e-300) {
                    break;
                }
                let mid = 0.5 * (lo + hi);
                if eval(c, mid) > floor {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            return Some(lo);
        }
    }
    None
}
