//! Built-in mesh generators for the shapes the papers' scenes use. All produce positively
//! oriented cells and validate like [`Mesh::new`]; bad arguments are errors.
//!
//! | generator | shape | used by |
//! |---|---|---|
//! | [`rectangle`] | axis-aligned rectangle, alternating diagonals | plates, slope, boxes (2D) |
//! | [`cuboid`] | axis-aligned box, 6 tetrahedra per cell (Freudenthal) | 3D boxes, ramp |
//! | [`disk`] | disk, rings of 6k vertices (nearly equilateral triangles) | disks |
//! | [`ring`] | annulus, structured polar | colliding rings (BFEMP §6.1) |
//! | [`semicircular_ring`] | upper half annulus, structured polar | buckling (BFEMP §6.6) |
//! | [`curve_strip`] | band of thickness `t` along the graph `y = f(x)` | sine-wave boundary (§6.2) |
//!
//! The spherical shell of BFEMP §6.7 is a Gmsh mesh (`fixtures/meshes/`, made by a committed
//! script).

use nalgebra::{SVector, Vector2, Vector3};

use super::Mesh;
use crate::FemError;

fn bad(what: &'static str, value: f64, requirement: &'static str) -> FemError {
    FemError::BadArgument {
        what,
        value,
        requirement,
    }
}

/// The most cells or vertices a generated mesh may have: indices are stored as `u32` in contact
/// (and no machine holds that many tetrahedra anyway).
pub const MAX_GENERATED: f64 = u32::MAX as f64;

/// Every count at least 1, and the mesh they make (at most 6 cells per grid cell, the
/// vertices of the `(n + 1)` lattice) within [`MAX_GENERATED`] — checked in floating point, so
/// that absurd counts are refused instead of overflowing a product or an allocation.
fn check_counts(counts: &[(&'static str, usize)]) -> Result<(), FemError> {
    for &(name, n) in counts {
        if n == 0 {
            return Err(bad(name, 0.0, "resolution must be at least 1"));
        }
    }
    let cells: f64 = counts.iter().map(|&(_, n)| n as f64 + 1.0).product::<f64>() * 6.0;
    if cells > MAX_GENERATED {
        let &(name, n) = counts.iter().max_by_key(|(_, n)| *n).expect("non-empty");
        return Err(bad(
            name,
            n as f64,
            "the mesh would have more than 2³² − 1 cells; use fewer cells",
        ));
    }
    Ok(())
}

fn check_extent<const D: usize>(
    min: &SVector<f64, D>,
    max: &SVector<f64, D>,
) -> Result<(), FemError> {
    for a in 0..D {
        if !(max[a] > min[a]) || !min[a].is_finite() || !max[a].is_finite() {
            return Err(bad(
                "max - min",
                max[a] - min[a],
                "extent must be positive and finite on every axis",
            ));
        }
    }
    Ok(())
}

/// Rectangle `[min, max]` with `nx × ny` cells, each split into two triangles with alternating
/// diagonals (so the mesh has no preferred direction).
pub fn rectangle(
    min: Vector2<f64>,
    max: Vector2<f64>,
    nx: usize,
    ny: usize,
) -> Result<Mesh<2>, FemError> {
    check_counts(&[("nx", nx), ("ny", ny)])?;
    check_extent(&min, &max)?;
    let mut v = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            v.push(Vector2::new(
                min.x + (max.x - min.x) * i as f64 / nx as f64,
                min.y + (max.y - min.y) * j as f64 / ny as f64,
            ));
        }
    }
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut cells = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let quad = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
            cells.extend(split_quad(quad, (i + j) % 2 == 0));
        }
    }
    Mesh::new(v, cells)
}

/// The two triangles of a quadrilateral `[a, b, c, d]` (in order around it), split along
/// `a`–`c` or, with `along_ac` false, along `b`–`d` (alternating the diagonal cell by cell
/// keeps a structured mesh free of a preferred direction).
fn split_quad([a, b, c, d]: [usize; 4], along_ac: bool) -> [[usize; 4]; 2] {
    if along_ac {
        [[a, b, c, usize::MAX], [a, c, d, usize::MAX]]
    } else {
        [[a, b, d, usize::MAX], [b, c, d, usize::MAX]]
    }
}

/// Box `[min, max]` with `nx × ny × nz` cells, each split into 6 tetrahedra along its main
/// diagonal (Freudenthal–Kuhn; conforming across cells).
pub fn cuboid(
    min: Vector3<f64>,
    max: Vector3<f64>,
    nx: usize,
    ny: usize,
    nz: usize,
) -> Result<Mesh<3>, FemError> {
    check_counts(&[("nx", nx), ("ny", ny), ("nz", nz)])?;
    check_extent(&min, &max)?;
    let n = [nx, ny, nz];
    let mut v = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                let t = [i, j, k];
                v.push(Vector3::from_fn(|a, _| {
                    min[a] + (max[a] - min[a]) * t[a] as f64 / n[a] as f64
                }));
            }
        }
    }
    let id = |i: usize, j: usize, k: usize| (k * (ny + 1) + j) * (nx + 1) + i;
    const PERMS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut cells = Vec::with_capacity(6 * nx * ny * nz);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                for p in PERMS {
                    let mut c = [i, j, k];
                    let mut tet = [id(i, j, k), 0, 0, 0];
                    for (s, &axis) in p.iter().enumerate() {
                        c[axis] += 1;
                        tet[s + 1] = id(c[0], c[1], c[2]);
                    }
                    cells.push(tet);
                }
            }
        }
    }
    Mesh::new_oriented(v, cells)
}

/// Disk of radius `radius` around `center` with `rings` concentric rings; ring `k` has `6k`
/// vertices, so triangles are nearly equilateral with edge ≈ `radius / rings`.
pub fn disk(center: Vector2<f64>, radius: f64, rings: usize) -> Result<Mesh<2>, FemError> {
    check_counts(&[("rings", rings)])?;
    // 1 + 3r(r + 1) vertices and 6r² triangles.
    if 6.0 * (rings as f64).powi(2) > MAX_GENERATED {
        return Err(bad(
            "rings",
            rings as f64,
            "the mesh would have more than 2³² − 1 cells; use fewer rings",
        ));
    }
    if !(radius > 0.0 && radius.is_finite()) {
        return Err(bad("radius", radius, "must be positive and finite"));
    }
    let mut v = vec![center];
    let mut start = vec![0usize];
    for k in 1..=rings {
        start.push(v.len());
        let r = radius * k as f64 / rings as f64;
        let m = 6 * k;
        for i in 0..m {
            let t = std::f64::consts::TAU * i as f64 / m as f64;
            v.push(center + Vector2::new(r * t.cos(), r * t.sin()));
        }
    }
    let mut cells = Vec::new();
    for k in 1..=rings {
        let (n_in, n_out) = (if k == 1 { 1 } else { 6 * (k - 1) }, 6 * k);
        let inner = |i: usize| start[k - 1] + i % n_in;
        let outer = |j: usize| start[k] + j % n_out;
        let (mut i, mut j) = (0usize, 0usize);
        // The centre (k = 1) is a single vertex shared by all 6 triangles: only the outer ring
        // advances.
        while j < n_out || (k > 1 && i < n_in) {
            // Advance along whichever ring's next vertex comes first in angle.
            let next_in = if k == 1 {
                f64::INFINITY
            } else {
                (i + 1) as f64 / n_in as f64
            };
            let next_out = (j + 1) as f64 / n_out as f64;
            if j < n_out && (next_out <= next_in || i >= n_in) {
                cells.push([inner(i), outer(j), outer(j + 1), usize::MAX]);
                j += 1;
            } else {
                cells.push([inner(i), outer(j), inner(i + 1), usize::MAX]);
                i += 1;
            }
        }
    }
    Mesh::new_oriented(v, cells)
}

/// Annulus `r_in ≤ |x − center| ≤ r_out`, `n_r` cells across and `n_theta` around.
pub fn ring(
    center: Vector2<f64>,
    r_in: f64,
    r_out: f64,
    n_r: usize,
    n_theta: usize,
) -> Result<Mesh<2>, FemError> {
    polar(
        center,
        r_in,
        r_out,
        n_r,
        n_theta,
        std::f64::consts::TAU,
        true,
    )
}

/// Upper half annulus (`0 ≤ θ ≤ π`), `n_r` cells across and `n_theta` along.
pub fn semicircular_ring(
    center: Vector2<f64>,
    r_in: f64,
    r_out: f64,
    n_r: usize,
    n_theta: usize,
) -> Result<Mesh<2>, FemError> {
    polar(
        center,
        r_in,
        r_out,
        n_r,
        n_theta,
        std::f64::consts::PI,
        false,
    )
}

fn polar(
    center: Vector2<f64>,
    r_in: f64,
    r_out: f64,
    n_r: usize,
    n_theta: usize,
    span: f64,
    periodic: bool,
) -> Result<Mesh<2>, FemError> {
    check_counts(&[("n_r", n_r), ("n_theta", n_theta)])?;
    if !(r_in > 0.0 && r_in.is_finite()) {
        return Err(bad("r_in", r_in, "inner radius must be positive"));
    }
    if !(r_out > r_in && r_out.is_finite()) {
        return Err(bad(
            "r_out",
            r_out,
            "outer radius must exceed the inner radius",
        ));
    }
    if periodic && n_theta < 3 {
        return Err(bad(
            "n_theta",
            n_theta as f64,
            "a closed ring needs at least 3 cells around",
        ));
    }
    let cols = if periodic { n_theta } else { n_theta + 1 };
    let mut v = Vec::with_capacity((n_r + 1) * cols);
    for i in 0..=n_r {
        let r = r_in + (r_out - r_in) * i as f64 / n_r as f64;
        for m in 0..cols {
            let t = span * m as f64 / n_theta as f64;
            v.push(center + Vector2::new(r * t.cos(), r * t.sin()));
        }
    }
    let id = |i: usize, m: usize| i * cols + m % cols;
    let mut cells = Vec::with_capacity(2 * n_r * n_theta);
    for i in 0..n_r {
        for m in 0..n_theta {
            let quad = [id(i, m), id(i + 1, m), id(i + 1, m + 1), id(i, m + 1)];
            cells.extend(split_quad(quad, (i + m) % 2 == 0));
        }
    }
    Mesh::new_oriented(v, cells)
}

/// The band between the graph `y = f(x)`, `x ∈ [x0, x1]`, and its offset by `thickness`
/// (negative: below the curve), with `nx × ny` cells.
pub fn curve_strip(
    f: impl Fn(f64) -> f64,
    x0: f64,
    x1: f64,
    thickness: f64,
    nx: usize,
    ny: usize,
) -> Result<Mesh<2>, FemError> {
    check_counts(&[("nx", nx), ("ny", ny)])?;
    if !(x1 > x0) {
        return Err(bad(
            "x1 - x0",
            x1 - x0,
            "the curve's x range must be positive",
        ));
    }
    if !(thickness != 0.0 && thickness.is_finite()) {
        return Err(bad("thickness", thickness, "must be non-zero and finite"));
    }
    let mut v = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            let x = x0 + (x1 - x0) * i as f64 / nx as f64;
            v.push(Vector2::new(x, f(x) + thickness * j as f64 / ny as f64));
        }
    }
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut cells = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let quad = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
            cells.extend(split_quad(quad, (i + j) % 2 == 0));
        }
    }
    Mesh::new_oriented(v, cells)
}
