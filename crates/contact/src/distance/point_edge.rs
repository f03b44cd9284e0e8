//! Point–edge squared distance in 2D and 3D.
//!
//! With `a = p − e0`, `e = e1 − e0` and `t = (a·e)/(e·e)` the parameter of the projection:
//! `t ≤ 0` → region `V0` (`s = |p − e0|²`), `t ≥ 1` → `V1` (`s = |p − e1|²`), otherwise
//! `Interior` with `s = a·a − (a·e)²/(e·e)`. Interior derivatives, first in `(a, e)`:
//!
//! ```text
//! ∂s/∂a = 2a − 2(a·e)/(e·e) e          ∂s/∂e = −2(a·e)/(e·e) a + 2(a·e)²/(e·e)² e
//! H_aa = 2I − 2 e eᵀ/(e·e)
//! H_ae = −2 (e aᵀ + (a·e) I)/(e·e) + 4 (a·e) e eᵀ/(e·e)²
//! H_ee = −2 a aᵀ/(e·e) + 4 (a·e)(a eᵀ + e aᵀ)/(e·e)² + 2 (a·e)² I/(e·e)² − 8 (a·e)² e eᵀ/(e·e)³
//! ```
//!
//! then mapped to `(p, e0, e1)` through `a = p − e0`, `e = e1 − e0`.

use nalgebra::{SMatrix, SVector};

use super::{outer, point_point};

/// Closest-feature region of a point relative to an edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PointEdgeRegion {
    /// Closest to `e0`.
    V0,
    /// Closest to `e1`.
    V1,
    /// Closest to a point strictly inside the edge.
    Interior,
}

/// Projection parameter `t` of `p` on the line of the edge (0 for a zero-length edge).
#[inline]
pub fn parameter<const D: usize>(
    p: &SVector<f64, D>,
    e0: &SVector<f64, D>,
    e1: &SVector<f64, D>,
) -> f64 {
    let e = e1 - e0;
    let ee = e.norm_squared();
    if ee == 0.0 {
        0.0
    } else {
        (p - e0).dot(&e) / ee
    }
}

/// The region of `p`.
#[inline]
pub fn region<const D: usize>(
    p: &SVector<f64, D>,
    e0: &SVector<f64, D>,
    e1: &SVector<f64, D>,
) -> PointEdgeRegion {
    let t = parameter(p, e0, e1);
    if t <= 0.0 {
        PointEdgeRegion::V0
    } else if t >= 1.0 {
        PointEdgeRegion::V1
    } else {
        PointEdgeRegion::Interior
    }
}

/// Squared distance from `p` to the segment `[e0, e1]`.
#[inline]
pub fn sq_dist<const D: usize>(
    p: &SVector<f64, D>,
    e0: &SVector<f64, D>,
    e1: &SVector<f64, D>,
) -> f64 {
    sq_dist_in(region(p, e0, e1), p, e0, e1)
}

/// Squared distance evaluated with the formula of a given region.
#[inline]
pub fn sq_dist_in<const D: usize>(
    r: PointEdgeRegion,
    p: &SVector<f64, D>,
    e0: &SVector<f64, D>,
    e1: &SVector<f64, D>,
) -> f64 {
    match r {
        PointEdgeRegion::V0 => point_point::sq_dist(p, e0),
        PointEdgeRegion::V1 => point_point::sq_dist(p, e1),
        PointEdgeRegion::Interior => interior_sq_dist(p, e0, e1),
    }
}

/// The squared distance to the edge's line. The residual form `|a − t e|²` is accurate to
/// about `ε|a|` in the distance (rounded differences and products; the equivalent
/// `a·a − (a·e)²/(e·e)` would cancel catastrophically): plenty away from the line. Closer than
/// `1e-7 |a|` — a point almost on the line of a long edge, or far along a needle's line — the
/// distance is recomputed from exact differences in double-double arithmetic
/// ([`super::accurate`]), so its relative accuracy never falls below ~1e-12 (CCD marches on
/// it; a distance overestimated by more than the gap lets it step through).
#[inline]
fn interior_sq_dist<const D: usize>(
    p: &SVector<f64, D>,
    e0: &SVector<f64, D>,
    e1: &SVector<f64, D>,
) -> f64 {
    let (a, e) = (p - e0, e1 - e0);
    let ee = e.norm_squared();
    let t = a.dot(&e) / ee;
    let s = (a - e * t).norm_squared();
    if s > 1e-14 * a.norm_squared() && s.is_finite() {
        s
    } else if ee > 0.0 && ee.is_finite() {
        super::accurate::point_line_sq(p, e0, e1)
    } else {
        s
    }
}

/// Gradient blocks `[∂s/∂p, ∂s/∂e0, ∂s/∂e1]`.
pub fn sq_dist_grad<const D: usize>(
    p: &SVector<f64, D>,
    e0: &SVector<f64, D>,
    e1: &SVector<f64, D>,
) -> [SVector<f64, D>; 3] {
    sq_dist_grad_in(region(p, e0, e1), p, e0, e1)
}

/// Gradient with the formula of a given region.
pub fn sq_dist_grad_in<const D: usize>(
    r: PointEdgeRegion,
    p: &SVector<f64, D>,
    e0: &SVector<f64, D>,
    e1: &SVector<f64, D>,
) -> [SVector<f64, D>; 3] {
    let z = SVector::zeros();
    match r {
        PointEdgeRegion::V0 => {
            let [gp, gq] = point_point::sq_dist_grad(p, e0);
            [gp, gq, z]
        }
        PointEdgeRegion::V1 => {
            let [gp, gq] = point_point::sq_dist_grad(p, e1);
            [gp, z, gq]
        }
        PointEdgeRegion::Interior => {
            let (a, e) = (p - e0, e1 - e0);
            let (ae, ee) = (a.dot(&e), e.norm_squared());
            let ga = a * 2.0 - e * (2.0 * ae / ee);
            let ge = a * (-2.0 * ae / ee) + e * (2.0 * ae * ae / (ee * ee));
            [ga, -ga - ge, ge]
        }
    }
}

/// Hessian blocks `∂²s/∂x_i∂x_j`, `x = (p, e0, e1)`.
pub fn sq_dist_hess<const D: usize>(
    p: &SVector<f64, D>,
    e0: &SVector<f64, D>,
    e1: &SVector<f64, D>,
) -> [[SMatrix<f64, D, D>; 3]; 3] {
    sq_dist_hess_in(region(p, e0, e1), p, e0, e1)
}

/// Hessian with the formula of a given region.
pub fn sq_dist_hess_in<const D: usize>(
    r: PointEdgeRegion,
    p: &SVector<f64, D>,
    e0: &SVector<f64, D>,
    e1: &SVector<f64, D>,
) -> [[SMatrix<f64, D, D>; 3]; 3] {
    let z = SMatrix::<f64, D, D>::zeros();
    let mut h = [[z; 3]; 3];
    match r {
        PointEdgeRegion::V0 | PointEdgeRegion::V1 => {
            let k = if r == PointEdgeRegion::V0 { 1 } else { 2 };
            let pp = point_point::sq_dist_hess::<D>();
            h[0][0] = pp[0][0];
            h[0][k] = pp[0][1];
            h[k][0] = pp[1][0];
            h[k][k] = pp[1][1];
        }
        PointEdgeRegion::Interior => {
            let (a, e) = (p - e0, e1 - e0);
            let (ae, ee) = (a.dot(&e), e.norm_squared());
            let i = SMatrix::<f64, D, D>::identity();
            let eet = outer(&e, &e);
            let haa = i * 2.0 - eet * (2.0 / ee);
            let hae = (outer(&e, &a) + i * ae) * (-2.0 / ee) + eet * (4.0 * ae / (ee * ee));
            let hee = outer(&a, &a) * (-2.0 / ee)
                + (outer(&a, &e) + outer(&e, &a)) * (4.0 * ae / (ee * ee))
                + i * (2.0 * ae * ae / (ee * ee))
                - eet * (8.0 * ae * ae / (ee * ee * ee));
            let hea = hae.transpose();
            // Jacobian blocks of (a, e) w.r.t. (p, e0, e1): p → (I, 0), e0 → (−I, −I), e1 → (0, I).
            let ja: [f64; 3] = [1.0, -1.0, 0.0];
            let je: [f64; 3] = [0.0, -1.0, 1.0];
            for x in 0..3 {
                for y in 0..3 {
                    h[x][y] = haa * (ja[x] * ja[y])
                        + hae * (ja[x] * je[y])
                        + hea * (je[x] * ja[y])
                        + hee * (je[x] * je[y]);
                }
            }
        }
    }
    h
}
