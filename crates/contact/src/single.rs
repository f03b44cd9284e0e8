//! One contact at a time: the barrier potential of a single point against a single edge (2D
//! or 3D) or triangle (3D), with its gradient and Hessian, in one call — for users who bring
//! their own contact set (a rigid-body code, a test, a Python notebook) rather than a
//! [`ContactPotential`](crate::ContactPotential) over a whole boundary.
//!
//! The potential is `w · b(d)` with `b(d) = −κ (d/d̂ − 1)² ln(d/d̂)` (BFEMP eq. 27) on the
//! **unsigned distance `d`**, and `w` a weight (BFEMP: the particle's area or length,
//! [`particle_weight`](crate::particle_weight)). **The IPC Toolkit's barrier acts on the squared
//! distance** (`b(d², d̂²)`): the same physical `κ` and `d̂` give a different potential there, so
//! parameters do not transfer unchanged between the two (femp's `d̂` is a distance; IPC's `dhat`
//! argument is one too, but its barrier is evaluated at `d²` against `d̂²`, which changes the
//! stiffness by a factor that depends on `d`). No duplicate-removal terms (eqs. 31–32) are
//! applied: a point near a vertex shared by two edges counts against each edge it is given.
//!
//! ```
//! use femp_contact::{LogBarrier, single};
//! use nalgebra::Vector2;
//!
//! let b = LogBarrier::new(0.01, 1e4).unwrap();
//! let c = single::point_edge(&b, 1.0, &Vector2::new(0.2, 0.004), &Vector2::new(-1.0, 0.0),
//!     &Vector2::new(1.0, 0.0), single::Hessian::Projected).unwrap().unwrap();
//! assert!(c.value > 0.0 && c.gradient[0].y < 0.0); // pushed up, away from the edge
//! ```

use nalgebra::{SMatrix, SVector, Vector3};

use crate::distance::{point_edge, point_triangle};
use crate::potential::{BlockMatrix, Blocks};
use crate::{ContactError, LogBarrier, project_psd};

/// Which Hessian [`point_edge`] and [`point_triangle`] return.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Hessian {
    /// The exact Hessian `w (b_ss ∇s ∇sᵀ + b_s ∇²s)` (`s = d²`); indefinite in general.
    Exact,
    /// The exact Hessian with its negative eigenvalues clipped (on the stencil's
    /// translation-free subspace, as femp's Newton uses it): positive semi-definite.
    Projected,
}

/// One contact's potential, gradient and Hessian over the stencil `[point, vertices…]`
/// (`N` = 3 for an edge, 4 for a triangle).
#[derive(Clone, Debug, PartialEq)]
pub struct Contact<const D: usize, const N: usize> {
    /// Distance `d` (m).
    pub distance: f64,
    /// `w · b(d)`.
    pub value: f64,
    /// Gradient blocks per stencil point.
    pub gradient: [SVector<f64, D>; N],
    /// Hessian blocks `hessian[i][j] = ∂²/∂x_i∂x_j`.
    pub hessian: [[SMatrix<f64, D, D>; N]; N],
}

/// The chain rule from the squared distance `s` to `w b(d(s))`, for stencil size `n ≤ 4`.
fn chain<const D: usize>(
    barrier: &LogBarrier,
    weight: f64,
    s: f64,
    ds: &[SVector<f64, D>],
    dds: &[[SMatrix<f64, D, D>; 4]; 4],
    n: usize,
    hessian: Hessian,
) -> (f64, Blocks<D>, BlockMatrix<D>) {
    let (b, b1, b2) = barrier.sq_derivatives(s);
    let mut g = [SVector::zeros(); 4];
    let mut h = [[SMatrix::zeros(); 4]; 4];
    for i in 0..n {
        g[i] = ds[i] * (weight * b1);
        for j in 0..n {
            h[i][j] = (ds[i] * ds[j].transpose() * b2 + dds[i][j] * b1) * weight;
        }
    }
    if hessian == Hessian::Projected {
        project_psd(&mut h, n * D);
    }
    (weight * b, g, h)
}

/// Distances at or below `ROUND_OFF × stencil size` are zero to round-off (a point in the
/// triangle's plane computes `d ≈ 1e-17`, not 0): they are reported as penetrations.
pub const ROUND_OFF: f64 = 16.0 * f64::EPSILON;

/// The first stencil point (0: the point, 1…: the primitive's vertices) with a non-finite
/// coordinate, as the error naming it — every one is checked, not only those the distance
/// happens to use (a NaN vertex away from the closest feature used to pass unseen).
fn finite_stencil<const D: usize>(pts: &[&SVector<f64, D>]) -> Result<(), ContactError> {
    match pts.iter().position(|p| p.iter().any(|x| !x.is_finite())) {
        Some(index) => Err(ContactError::NonFinite {
            what: "stencil point (0: the point, 1…: the primitive's vertices)",
            index,
        }),
        None => Ok(()),
    }
}

fn check(barrier: &LogBarrier, weight: f64, d: f64, size: f64) -> Result<Option<()>, ContactError> {
    if !(weight >= 0.0 && weight.is_finite()) {
        return Err(ContactError::BadParameter {
            what: "weight",
            value: weight,
            requirement: "must be finite and ≥ 0",
        });
    }
    if !d.is_finite() {
        return Err(ContactError::NonFinite {
            what: "stencil point",
            index: 0,
        });
    }
    if !(d > ROUND_OFF * size) {
        return Err(ContactError::Penetration {
            particle: 0,
            facet: 0,
            distance: d,
        });
    }
    Ok((d < barrier.dhat).then_some(()))
}

/// Point `p` against the edge `e0 e1` (2D or 3D): `Ok(None)` when `d ≥ d̂` (no force);
/// [`ContactError::Penetration`] when `d = 0` to round-off ([`ROUND_OFF`]; the barrier is
/// infinite there), `NonFinite` for a
/// non-finite position, `BadParameter` for a negative or non-finite weight.
pub fn point_edge<const D: usize>(
    barrier: &LogBarrier,
    weight: f64,
    p: &SVector<f64, D>,
    e0: &SVector<f64, D>,
    e1: &SVector<f64, D>,
    hessian: Hessian,
) -> Result<Option<Contact<D, 3>>, ContactError> {
    finite_stencil(&[p, e0, e1])?;
    let s = point_edge::sq_dist(p, e0, e1);
    let size = (e0 - p).norm().max((e1 - p).norm());
    if check(barrier, weight, s.sqrt(), size)?.is_none() {
        return Ok(None);
    }
    let ds = point_edge::sq_dist_grad(p, e0, e1);
    let h3 = point_edge::sq_dist_hess(p, e0, e1);
    let mut dds = [[SMatrix::zeros(); 4]; 4];
    for i in 0..3 {
        for j in 0..3 {
            dds[i][j] = h3[i][j];
        }
    }
    let (value, g, h) = chain(barrier, weight, s, &ds, &dds, 3, hessian);
    Ok(Some(Contact {
        distance: s.sqrt(),
        value,
        gradient: [g[0], g[1], g[2]],
        hessian: std::array::from_fn(|i| std::array::from_fn(|j| h[i][j])),
    }))
}

/// Point `p` against the triangle `t0 t1 t2` (3D): as [`point_edge`].
pub fn point_triangle(
    barrier: &LogBarrier,
    weight: f64,
    p: &Vector3<f64>,
    t0: &Vector3<f64>,
    t1: &Vector3<f64>,
    t2: &Vector3<f64>,
    hessian: Hessian,
) -> Result<Option<Contact<3, 4>>, ContactError> {
    finite_stencil(&[p, t0, t1, t2])?;
    let s = point_triangle::sq_dist(p, t0, t1, t2);
    let size = (t0 - p).norm().max((t1 - p).norm()).max((t2 - p).norm());
    if check(barrier, weight, s.sqrt(), size)?.is_none() {
        return Ok(None);
    }
    let ds = point_triangle::sq_dist_grad(p, t0, t1, t2);
    let dds = point_triangle::sq_dist_hess(p, t0, t1, t2);
    let (value, gradient, hessian) = chain(barrier, weight, s, &ds, &dds, 4, hessian);
    Ok(Some(Contact {
        distance: s.sqrt(),
        value,
        gradient,
        hessian,
    }))
}
