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

/// The region of `p`: `Face` if its projection onto the triangle's plane lies in the closed
/// triangle (and the triangle has an area), else the closest of the three edges' regions.
///
/// The projection test is the sign of `n · ((t_j − t_i) × (p − t_i))` for each edge `(t_i,
/// t_j)`, `n = (t1 − t0) × (t2 − t0)` — the projection's signed sub-areas, which need no
/// projected point. It is evaluated in double precision with an error bound, and again from
/// exact differences in double-double arithmetic when a sign is within the bound (points near
/// an edge's line in the plane; every point of a sliver, whose normal rounding tilts).
/// Outside the face the closest edge is the one whose (accurate) segment distance is least —
/// the closest point of the triangle is then on its boundary. Every distance and derivative
/// evaluates the formula of this one decision ([`sq_dist`] is `sq_dist_in(region(..))`).
pub fn region(p: &V3, t0: &V3, t1: &V3, t2: &V3) -> PointTriangleRegion {
    if projects_inside(p, t0, t1, t2) {
        return PointTriangleRegion::Face;
    }
    boundary_region(p, t0, t1, t2)
}

/// Whether the projection of `p` lies in the closed triangle, which has an area.
fn projects_inside(p: &V3, t0: &V3, t1: &V3, t2: &V3) -> bool {
    let (e1, e2) = (t1 - t0, t2 - t0);
    let n = e1.cross(&e2);
    // Squared bounds throughout (no square roots on the fast path).
    let nbound2 = e1.norm_squared() * e2.norm_squared();
    // |fl(n) − n| ≤ ~4ε |e1||e2| (including the rounding of e1, e2 themselves).
    const K: f64 = 32.0 * f64::EPSILON;
    const K2: f64 = K * K;
    let mut uncertain = !(n.norm_squared() > 1e6 * K2 * nbound2);
    if !uncertain {
        for (u, v) in [(t0, t1), (t1, t2), (t2, t0)] {
            let (e, b) = (v - u, p - u);
            let c = n.dot(&e.cross(&b));
            // Error of the triple product: the normal's error times |e × b| plus the
            // product's own rounding, both below K |e1||e2| |e| |b|.
            let bound2 = K2 * nbound2 * e.norm_squared() * b.norm_squared();
            if !(c * c > bound2) {
                uncertain = true;
                break;
            }
            if c < 0.0 {
                return false;
            }
        }
    }
    if uncertain {
        if !(p.iter().chain(t0.iter()).chain(t1.iter()).chain(t2.iter())).all(|x| x.is_finite()) {
            return false;
        }
        let (s, area) = super::accurate::face_sides(p, t0, t1, t2);
        return area && s.iter().all(|&x| x >= 0);
    }
    true
}

/// The closest of the three edges (and the edge's sub-region), for a point whose closest
/// triangle point is on the boundary.
fn boundary_region(p: &V3, t0: &V3, t1: &V3, t2: &V3) -> PointTriangleRegion {
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

/// Squared distance from `p` to the triangle: the formula of its [`region`] (the same
/// decision the derivatives take). Accurate to ~1e-12 relative for every triangle — slivers,
/// needles, coincident vertices — and relative to the triangle, not the origin.
pub fn sq_dist(p: &V3, t0: &V3, t1: &V3, t2: &V3) -> f64 {
    sq_dist_in(region(p, t0, t1, t2), p, t0, t1, t2)
}

/// The point of the triangle closest to `p` (of its [`region`]; a degenerate triangle's
/// closest point is on its edges).
pub fn closest_point(p: &V3, t0: &V3, t1: &V3, t2: &V3) -> V3 {
    use PointTriangleRegion::*;
    let on_edge = |a: &V3, b: &V3| a + (b - a) * point_edge::parameter(p, a, b).clamp(0.0, 1.0);
    match region(p, t0, t1, t2) {
        V0 => *t0,
        V1 => *t1,
        V2 => *t2,
        E01 => on_edge(t0, t1),
        E12 => on_edge(t1, t2),
        E20 => on_edge(t2, t0),
        Face => {
            let n = (t1 - t0).cross(&(t2 - t0));
            p - n * ((p - t0).dot(&n) / n.norm_squared())
        }
    }
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
        Face => face_sq_dist(p, t0, t1, t2),
    }
}

/// `(a·n)²/(n·n)`: in double precision when its error estimate (`~ε |a||e1||e2|` in `a·n`,
/// `~ε |e1||e2|` in `n`) is below 1e-8 of the value, else from exact differences in
/// double-double ([`super::accurate`]).
fn face_sq_dist(p: &V3, t0: &V3, t1: &V3, t2: &V3) -> f64 {
    let (a, e1, e2) = (p - t0, t1 - t0, t2 - t0);
    let n = e1.cross(&e2);
    let g = a.dot(&n);
    let m = n.norm_squared();
    let scale2 = e1.norm_squared() * e2.norm_squared();
    const K: f64 = 8.0 * f64::EPSILON;
    const TRUST2: f64 = (1e8 * K) * (1e8 * K);
    if m > TRUST2 * scale2 && g * g > TRUST2 * scale2 * a.norm_squared() && m.is_finite() {
        return g * g / m;
    }
    if m > 0.0 && m.is_finite() {
        super::accurate::point_plane_sq(p, t0, t1, t2)
    } else {
        g * g / m
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
