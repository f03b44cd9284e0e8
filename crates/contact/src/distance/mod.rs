//! Squared distances between a point and the primitives of a boundary, with gradients and
//! Hessians, as explicit closest-feature regions.
//!
//! Conventions:
//! * Everything here is a **squared** distance `s = d²` (names say `sq`).
//! * Derivatives are per-vertex blocks in the order of the arguments: the point first, then the
//!   primitive's vertices (`[SVector; n]` gradients, `[[SMatrix; n]; n]` Hessians) — exactly what
//!   assembly scatters, and what BFEMP chains from a particle to its grid nodes (eq. 29).
//! * Regions are enums (`PointEdgeRegion::{V0, V1, Interior}`, …). On a region boundary the
//!   lower region wins (`t ≤ 0` is `V0`); the value and gradient are continuous there, the
//!   Hessian is not (it cannot be).
//! * Degenerate primitives fall back to the lower-dimensional feature: an edge of zero length is
//!   a point, a triangle of zero area is handled through its edges.

mod accurate;
pub mod point_edge;
pub mod point_point;
pub mod point_triangle;

use nalgebra::{SMatrix, SVector};

/// `a bᵀ`.
#[inline]
pub(crate) fn outer<const D: usize>(
    a: &SVector<f64, D>,
    b: &SVector<f64, D>,
) -> SMatrix<f64, D, D> {
    a * b.transpose()
}
