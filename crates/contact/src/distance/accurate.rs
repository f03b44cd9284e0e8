//! The accurate fallback of the distance kernels, for the inputs double precision gets wrong:
//! points very close to an edge's line or a triangle's plane relative to the primitive's size,
//! and slivers and needles (whose plane, computed from rounded edge vectors, tilts).
//!
//! Differences of the input coordinates are taken exactly (`a − b` of two doubles is exactly a
//! double-double) and everything after them — cross products, dot products, squares — in
//! double-double arithmetic ([`twofloat`]; relative error of each operation a few units of
//! 2⁻¹⁰⁶). Every result is therefore computed *relative to the primitive*: an offset of the
//! whole configuration far from the origin changes nothing but the rounding of the inputs
//! themselves.
//!
//! The kernels call these only when the double-precision value's own error bound is too large
//! to trust (a few per cent of calls on adversarial meshes, none on regular ones), so the fast
//! path keeps its cost.

use nalgebra::{SVector, Vector3};
use twofloat::TwoFloat as T;

/// `[x − y]` per axis, exactly.
#[inline]
fn diff<const D: usize>(x: &SVector<f64, D>, y: &SVector<f64, D>) -> [T; D] {
    std::array::from_fn(|k| T::new_sub(x[k], y[k]))
}

#[inline]
fn dot<const D: usize>(a: &[T; D], b: &[T; D]) -> T {
    let mut s = a[0] * b[0];
    for k in 1..D {
        s += a[k] * b[k];
    }
    s
}

#[inline]
fn cross(a: &[T; 3], b: &[T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Squared distance from `p` to the *line* through `e0` and `e1` (`e0 ≠ e1`):
/// `|a × e|² / |e|²` with `a = p − e0`, `e = e1 − e0`.
pub(crate) fn point_line_sq<const D: usize>(
    p: &SVector<f64, D>,
    e0: &SVector<f64, D>,
    e1: &SVector<f64, D>,
) -> f64 {
    let (a, e) = (diff(p, e0), diff(e1, e0));
    let ee = dot(&e, &e);
    let num = if D == 2 {
        let c = a[0] * e[1] - a[1] * e[0];
        c * c
    } else {
        let a3 = [a[0], a[1], a[D - 1]];
        let e3 = [e[0], e[1], e[D - 1]];
        let c = cross(&a3, &e3);
        dot(&c, &c)
    };
    f64::from(num / ee)
}

/// Squared distance from `p` to the *plane* of the triangle `(t0, t1, t2)` (non-degenerate):
/// `(a · n)² / |n|²` with `a = p − t0`, `n = (t1 − t0) × (t2 − t0)`.
pub(crate) fn point_plane_sq(
    p: &Vector3<f64>,
    t0: &Vector3<f64>,
    t1: &Vector3<f64>,
    t2: &Vector3<f64>,
) -> f64 {
    let (a, e1, e2) = (diff(p, t0), diff(t1, t0), diff(t2, t0));
    let n = cross(&e1, &e2);
    let g = dot(&a, &n);
    f64::from(g * g / dot(&n, &n))
}

/// The sides of the three edge lines on which the projection of `p` onto the triangle's plane
/// lies, as the signs (−1, 0, 1) of `n · ((t_{j} − t_i) × (p − t_i))` for the edges
/// `(t0, t1)`, `(t1, t2)`, `(t2, t0)`, and the sign of `|n|²` (0: degenerate triangle).
pub(crate) fn face_sides(
    p: &Vector3<f64>,
    t0: &Vector3<f64>,
    t1: &Vector3<f64>,
    t2: &Vector3<f64>,
) -> ([i8; 3], bool) {
    let (e1, e2) = (diff(t1, t0), diff(t2, t0));
    let n = cross(&e1, &e2);
    let nn = dot(&n, &n);
    let sign = |x: T| {
        if x.hi() > 0.0 {
            1
        } else if x.hi() < 0.0 {
            -1
        } else {
            0
        }
    };
    let side = |u: &Vector3<f64>, v: &Vector3<f64>| {
        let (e, b) = (diff(v, u), diff(p, u));
        sign(dot(&n, &cross(&e, &b)))
    };
    ([side(t0, t1), side(t1, t2), side(t2, t0)], nn.hi() > 0.0)
}
