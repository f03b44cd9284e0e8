//! Point–triangle squared distance (3D).
//!
//! **Regions.** The projection of `p` onto the triangle's plane has barycentric coordinates
//! `(β₁, β₂)` solving the 2×2 normal equations; inside the triangle (`β₁, β₂ ≥ 0`,
//! `β₁ + β₂ ≤ 1`) the region is `Face`. Otherwise the closest point is on the boundary, and the
//! region is the closest of the three point–edge distances (an edge or a vertex region). A
//! triangle of zero area has no face region.
//!
//! **Face derivatives.** With `a = p − t0`, `e₁ = t1 − t0`, `e₂ = t2 − t0`, `n = e₁ × e₂`,
//! `g = a·n` (a triple product) and `m = n·n`, `s = g²/m`. In the variables `y = (a, e₁, e₂)`:
//!
//! ```text
//! ∇g = (n, e₂ × a, a × e₁)
//! H_g: [a][e₁] = −[e₂]×, [a][e₂] = [e₁]×, [e₁][e₂] = −[a]×   (zero diagonal, symmetric)
//! ∇m = (0, 2 e₂ × n, 2 n × e₁)
//! H_m: [e₁][e₁] = −2[e₂]×², [e₂][e₂] = −2[e₁]×², [e₁][e₂] = 2([e₂]×[e₁]× − [n]×)
//! ∇s = 2g∇g/m − g²∇m/m²
//! H_s = 2∇g∇gᵀ/m + 2g H_g/m − 2g(∇g∇mᵀ + ∇m∇gᵀ)/m² − g² H_m/m² + 2g²∇m∇mᵀ/m³
//! ```
//!
//! (`[v]×` is the cross-product matrix, `[v]× w = v × w`), then mapped to `(p, t0, t1, t2)`
//! through `a = p − t0`, `e₁ = t1 − t0`, `e₂ = t2 − t0`. Checked against finite differences and
//! against the IPC Toolkit.

use nalgebra::{Matrix3, Vector3};

use super::point_edge::{self, PointEdgeRegion};
use super::point_point;

/// Closest-feature region of a point relative to a triangle `(t0, t1, t2)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PointTriangleRegion {
    /// Closest to vertex `t0`.
    V0,
    /// Closest to vertex `t1`.
    V1,
    /// Closest to vertex `t2`.
    V2,
    /// Closest to the interior of edge `t0–t1`.
    E01,
    /// Closest to the interior of edge `t1–t2`.
    E12,
    /// Closest to the interior of edge `t2–t0`.
    E20,
    /// Closest to the interior of the face.
    Face,
}

type V3 = Vector3<f64>;
type M3 = Matrix3<f64>;

/// Barycentric coordinates `(β₁, β₂)` of the projection of `p` (`None` for a degenerate
/// triangle).
pub fn barycentric(p: &V3, t0: &V3, t1: &V3, t2: &V3) -> Option<(f64, f64)> {
    let (a, e1, e2) = (p - t0, t1 - t0, t2 - t0);
    let (a11, a12, a22) = (e1.dot(&e1), e1.dot(&e2), e2.dot(&e2));
    let det = a11 * a22 - a12 * a12;
    if !(det > 1e-30 * a11 * a22) {
        return None;
    }
    let (r1, r2) = (a.dot(&e1), a.dot(&e2));
    Some(((a22 * r1 - a12 * r2) / det, (a11 * r2 - a12 * r1) / det))
}

/// The region of `p`.
pub fn region(p: &V3, t0: &V3, t1: &V3, t2: &V3) -> PointTriangleRegion {
    if let Some((b1, b2)) = barycentric(p, t0, t1, t2)
        && b1 >= 0.0
        && b2 >= 0.0
        && b1 + b2 <= 1.0
    {
        return PointTriangleRegion::Face;
    }
    // On the boundary: the closest of the three edges, and its sub-region.
    let edges = [(t0, t1), (t1, t2), (t2, t0)];
    let mut best = (f64::INFINITY, PointTriangleRegion::V0);
    for (k, (a, b)) in edges.iter().enumerate() {
        let r = point_edge::region(p, a, b);
        let s = point_edge::sq_dist_in(r, p, a, b);
        if s < best.0 {
            let reg = match (k, r) {
                (0, PointEdgeRegion::Interior) => PointTriangleRegion::E01,
                (1, PointEdgeRegion::Interior) => PointTriangleRegion::E12,
                (2, PointEdgeRegion::Interior) => PointTriangleRegion::E20,
                (0, PointEdgeRegion::V0) | (2, PointEdgeRegion::V1) => PointTriangleRegion::V0,
                (0, PointEdgeRegion::V1) | (1, PointEdgeRegion::V0) => PointTriangleRegion::V1,
                _ => PointTriangleRegion::V2,
            };
            best = (s, reg);
        }
    }
    best.1
}

/// Squared distance from `p` to the triangle: `|p − c|²` with `c` the closest point (see
/// [`closest_point`]); the fast path CCD marches with.
pub fn sq_dist(p: &V3, t0: &V3, t1: &V3, t2: &V3) -> f64 {
    (p - closest_point(p, t0, t1, t2)).norm_squared()
}

/// The point of the triangle closest to `p`, by Voronoi-region tests on dot products
/// (Ericson, *Real-Time Collision Detection*, §5.1.5). Degenerate triangles fall back to the
/// closest point on their edges.
pub fn closest_point(p: &V3, a: &V3, b: &V3, c: &V3) -> V3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let sum = va + vb + vc;
    if !(sum.abs() > 0.0) || !sum.is_finite() {
        // Degenerate: the closest of the three edges.
        let best = [(a, b), (b, c), (c, a)]
            .into_iter()
            .map(|(u, v)| {
                let t = point_edge::parameter(p, u, v).clamp(0.0, 1.0);
                u + (v - u) * t
            })
            .min_by(|x, y| (p - x).norm_squared().total_cmp(&(p - y).norm_squared()));
        return best.unwrap_or(*a);
    }
    a + ab * (vb / sum) + ac * (vc / sum)
}

/// Squared distance with the formula of a given region.
pub fn sq_dist_in(r: PointTriangleRegion, p: &V3, t0: &V3, t1: &V3, t2: &V3) -> f64 {
    use PointTriangleRegion::*;
    match r {
        V0 => point_point::sq_dist(p, t0),
        V1 => point_point::sq_dist(p, t1),
        V2 => point_point::sq_dist(p, t2),
        E01 => point_edge::sq_dist_in(PointEdgeRegion::Interior, p, t0, t1),
        E12 => point_edge::sq_dist_in(PointEdgeRegion::Interior, p, t1, t2),
        E20 => point_edge::sq_dist_in(PointEdgeRegion::Interior, p, t2, t0),
        Face => {
            let n = (t1 - t0).cross(&(t2 - t0));
            let g = (p - t0).dot(&n);
            g * g / n.norm_squared()
        }
    }
}

/// Which of `(t0, t1, t2)` an edge or vertex region involves, as indices 1..=3 of the 4-point
/// stencil `(p, t0, t1, t2)`.
fn sub_indices(r: PointTriangleRegion) -> &'static [usize] {
    use PointTriangleRegion::*;
    match r {
        V0 => &[1],
        V1 => &[2],
        V2 => &[3],
        E01 => &[1, 2],
        E12 => &[2, 3],
        E20 => &[3, 1],
        Face => &[1, 2, 3],
    }
}

/// Gradient blocks `[∂s/∂p, ∂s/∂t0, ∂s/∂t1, ∂s/∂t2]`.
pub fn sq_dist_grad(p: &V3, t0: &V3, t1: &V3, t2: &V3) -> [V3; 4] {
    sq_dist_grad_in(region(p, t0, t1, t2), p, t0, t1, t2)
}

/// Gradient with the formula of a given region.
pub fn sq_dist_grad_in(r: PointTriangleRegion, p: &V3, t0: &V3, t1: &V3, t2: &V3) -> [V3; 4] {
    let pts = [p, t0, t1, t2];
    let mut out = [V3::zeros(); 4];
    match r {
        PointTriangleRegion::Face => {
            let (gy, _) = face_derivatives(p, t0, t1, t2, false);
            // a = p − t0, e1 = t1 − t0, e2 = t2 − t0.
            out[0] = gy[0];
            out[1] = -gy[0] - gy[1] - gy[2];
            out[2] = gy[1];
            out[3] = gy[2];
        }
        _ => {
            let idx = sub_indices(r);
            if idx.len() == 1 {
                let g = point_point::sq_dist_grad(p, pts[idx[0]]);
                out[0] = g[0];
                out[idx[0]] = g[1];
            } else {
                let g = point_edge::sq_dist_grad_in(
                    PointEdgeRegion::Interior,
                    p,
                    pts[idx[0]],
                    pts[idx[1]],
                );
                out[0] = g[0];
                out[idx[0]] = g[1];
                out[idx[1]] = g[2];
            }
        }
    }
    out
}

/// Hessian blocks, `x = (p, t0, t1, t2)`.
pub fn sq_dist_hess(p: &V3, t0: &V3, t1: &V3, t2: &V3) -> [[M3; 4]; 4] {
    sq_dist_hess_in(region(p, t0, t1, t2), p, t0, t1, t2)
}

/// Hessian with the formula of a given region.
pub fn sq_dist_hess_in(r: PointTriangleRegion, p: &V3, t0: &V3, t1: &V3, t2: &V3) -> [[M3; 4]; 4] {
    let pts = [p, t0, t1, t2];
    let mut out = [[M3::zeros(); 4]; 4];
    match r {
        PointTriangleRegion::Face => {
            let (_, hy) = face_derivatives(p, t0, t1, t2, true);
            // Jacobian of y = (a, e1, e2) w.r.t. x = (p, t0, t1, t2), per block (scalar × I).
            const J: [[f64; 3]; 4] = [
                [1.0, 0.0, 0.0],
                [-1.0, -1.0, -1.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ];
            for x in 0..4 {
                for y in 0..4 {
                    let mut h = M3::zeros();
                    for u in 0..3 {
                        for v in 0..3 {
                            let c = J[x][u] * J[y][v];
                            if c != 0.0 {
                                h += hy[u][v] * c;
                            }
                        }
                    }
                    out[x][y] = h;
                }
            }
        }
        _ => {
            let idx = sub_indices(r);
            let mut map = vec![0usize];
            map.extend_from_slice(idx);
            if idx.len() == 1 {
                let h = point_point::sq_dist_hess::<3>();
                for (i, &xi) in map.iter().enumerate() {
                    for (j, &xj) in map.iter().enumerate() {
                        out[xi][xj] = h[i][j];
                    }
                }
            } else {
                let h = point_edge::sq_dist_hess_in(
                    PointEdgeRegion::Interior,
                    p,
                    pts[idx[0]],
                    pts[idx[1]],
                );
                for (i, &xi) in map.iter().enumerate() {
                    for (j, &xj) in map.iter().enumerate() {
                        out[xi][xj] = h[i][j];
                    }
                }
            }
        }
    }
    out
}

#[inline]
fn cross_matrix(v: &V3) -> M3 {
    M3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Gradient and (optionally) Hessian of the face formula `s = (a·n)²/(n·n)` in `y = (a, e1, e2)`
/// (see the module documentation).
fn face_derivatives(p: &V3, t0: &V3, t1: &V3, t2: &V3, hessian: bool) -> ([V3; 3], [[M3; 3]; 3]) {
    let (a, e1, e2) = (p - t0, t1 - t0, t2 - t0);
    let n = e1.cross(&e2);
    let g = a.dot(&n);
    let m = n.norm_squared();
    let dg = [n, e2.cross(&a), a.cross(&e1)];
    let dm = [V3::zeros(), e2.cross(&n) * 2.0, n.cross(&e1) * 2.0];
    let mut gs = [V3::zeros(); 3];
    for k in 0..3 {
        gs[k] = dg[k] * (2.0 * g / m) - dm[k] * (g * g / (m * m));
    }
    let mut hs = [[M3::zeros(); 3]; 3];
    if hessian {
        let (ca, c1, c2, cn) = (
            cross_matrix(&a),
            cross_matrix(&e1),
            cross_matrix(&e2),
            cross_matrix(&n),
        );
        let z = M3::zeros();
        let hg = [[z, -c2, c1], [c2, z, -ca], [-c1, ca, z]];
        let hm = [
            [z, z, z],
            [z, -(c2 * c2) * 2.0, (c2 * c1 - cn) * 2.0],
            [z, (c1 * c2 + cn) * 2.0, -(c1 * c1) * 2.0],
        ];
        for u in 0..3 {
            for v in 0..3 {
                hs[u][v] = dg[u] * dg[v].transpose() * (2.0 / m) + hg[u][v] * (2.0 * g / m)
                    - (dg[u] * dm[v].transpose() + dm[u] * dg[v].transpose()) * (2.0 * g / (m * m))
                    - hm[u][v] * (g * g / (m * m))
                    + dm[u] * dm[v].transpose() * (2.0 * g * g / (m * m * m));
            }
        }
    }
    (gs, hs)
}
