//! Whether two boundary primitives of different bodies intersect: a segment and a segment in
//! 2D, a segment and a triangle in 3D — for refusing bodies that start crossed and for counting
//! crossings in the penetration metric (bodies can cross with no vertex inside the other).
//!
//! Decided by exact orientation predicates (Shewchuk's adaptive-precision `orient2d` /
//! `orient3d`, the `robust` crate): the signs are right for every input, slivers and
//! coincident points included, so "crossing" and "touching" are never confused by rounding.
//!
//! * [`Intersection::Crossing`] — the interiors cross transversally (a segment passes through
//!   the other segment's, or the triangle's, interior from one side to the other);
//! * [`Intersection::Touching`] — they meet, but only at an endpoint, an edge or in a common
//!   line or plane (bodies touching, or coincident);
//! * [`Intersection::None`] — disjoint.

use nalgebra::{Vector2, Vector3};
use robust::{Coord, Coord3D, orient2d, orient3d};

/// How two primitives meet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Intersection {
    /// Disjoint.
    None,
    /// They meet only at a boundary point of one of them, or overlap in a common line/plane.
    Touching,
    /// Their interiors cross transversally.
    Crossing,
}

fn c2(v: &Vector2<f64>) -> Coord<f64> {
    Coord { x: v.x, y: v.y }
}

fn c3(v: &Vector3<f64>) -> Coord3D<f64> {
    Coord3D {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

/// Sign of an exact predicate value.
fn sign(x: f64) -> i8 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}

/// `c` lies in the closed box of `a` and `b` (for collinear points: on the segment).
fn within(a: &Vector2<f64>, b: &Vector2<f64>, c: &Vector2<f64>) -> bool {
    (0..2).all(|k| c[k] >= a[k].min(b[k]) && c[k] <= a[k].max(b[k]))
}

/// Segments `[a0, a1]` and `[b0, b1]` in the plane.
pub fn segment_segment_2d(
    a0: &Vector2<f64>,
    a1: &Vector2<f64>,
    b0: &Vector2<f64>,
    b1: &Vector2<f64>,
) -> Intersection {
    let o1 = sign(orient2d(c2(a0), c2(a1), c2(b0)));
    let o2 = sign(orient2d(c2(a0), c2(a1), c2(b1)));
    let o3 = sign(orient2d(c2(b0), c2(b1), c2(a0)));
    let o4 = sign(orient2d(c2(b0), c2(b1), c2(a1)));
    if o1 * o2 < 0 && o3 * o4 < 0 {
        return Intersection::Crossing;
    }
    let touches = (o1 == 0 && within(a0, a1, b0))
        || (o2 == 0 && within(a0, a1, b1))
        || (o3 == 0 && within(b0, b1, a0))
        || (o4 == 0 && within(b0, b1, a1));
    if touches {
        Intersection::Touching
    } else {
        Intersection::None
    }
}

/// Segment `[p, q]` and triangle `(a, b, c)` in space.
pub fn segment_triangle(
    p: &Vector3<f64>,
    q: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> Intersection {
    let sp = sign(orient3d(c3(a), c3(b), c3(c), c3(p)));
    let sq = sign(orient3d(c3(a), c3(b), c3(c), c3(q)));
    if sp * sq > 0 {
        return Intersection::None;
    }
    if sp != 0 && sq != 0 {
        // The segment crosses the plane at one interior point: where, relative to the edges.
        let t = [
            sign(orient3d(c3(p), c3(q), c3(a), c3(b))),
            sign(orient3d(c3(p), c3(q), c3(b), c3(c))),
            sign(orient3d(c3(p), c3(q), c3(c), c3(a))),
        ];
        if t.iter().all(|&x| x > 0) || t.iter().all(|&x| x < 0) {
            return Intersection::Crossing;
        }
        let (pos, neg) = (t.iter().any(|&x| x > 0), t.iter().any(|&x| x < 0));
        return if pos && neg {
            Intersection::None
        } else {
            // Through an edge or a vertex of the triangle (or a degenerate triangle).
            Intersection::Touching
        };
    }
    // An endpoint in the triangle's plane, or the whole segment: decide in the plane, projected
    // along the normal's largest axis (orientation signs survive the projection exactly).
    let n = (b - a).cross(&(c - a));
    let drop = n.iamax();
    let pr = |v: &Vector3<f64>| {
        let k: Vec<usize> = (0..3).filter(|&k| k != drop).collect();
        Vector2::new(v[k[0]], v[k[1]])
    };
    let (a2, b2, c2_) = (pr(a), pr(b), pr(c));
    let inside = |v: &Vector3<f64>| {
        let v2 = pr(v);
        let s = [
            sign(orient2d(c2(&a2), c2(&b2), c2(&v2))),
            sign(orient2d(c2(&b2), c2(&c2_), c2(&v2))),
            sign(orient2d(c2(&c2_), c2(&a2), c2(&v2))),
        ];
        !(s.iter().any(|&x| x > 0) && s.iter().any(|&x| x < 0))
    };
    if n.iter().all(|&x| x == 0.0) {
        // A degenerate triangle: its edges.
        return [(a, b), (b, c), (c, a)]
            .into_iter()
            .map(|(u, v)| segment_segment_3d_touch(p, q, u, v))
            .find(|&t| t)
            .map_or(Intersection::None, |_| Intersection::Touching);
    }
    if (sp == 0 && inside(p)) || (sq == 0 && inside(q)) {
        return Intersection::Touching;
    }
    if sp == 0 && sq == 0 {
        let (p2, q2) = (pr(p), pr(q));
        for (u, v) in [(a2, b2), (b2, c2_), (c2_, a2)] {
            if segment_segment_2d(&p2, &q2, &u, &v) != Intersection::None {
                return Intersection::Touching;
            }
        }
    }
    Intersection::None
}

/// Whether two segments in space meet (for degenerate triangles; an approximate test in
/// double precision is enough there: the answer is only ever `Touching`).
fn segment_segment_3d_touch(
    p: &Vector3<f64>,
    q: &Vector3<f64>,
    u: &Vector3<f64>,
    v: &Vector3<f64>,
) -> bool {
    let (d1, d2, r) = (q - p, v - u, p - u);
    let (a, e, f) = (d1.dot(&d1), d2.dot(&d2), d2.dot(&r));
    let (b, c) = (d1.dot(&d2), d1.dot(&r));
    let den = a * e - b * b;
    let s = if den > 0.0 {
        ((b * f - c * e) / den).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let t = if e > 0.0 {
        ((b * s + f) / e).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let s = if a > 0.0 {
        ((b * t - c) / a).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let gap = (p + d1 * s) - (u + d2 * t);
    gap.norm() <= 1e-14 * (a.max(e)).sqrt().max(1e-300)
}
