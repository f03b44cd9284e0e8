//! Benchmark matrices with the structure of femp's Hessians: the neo-Hookean stiffness of a
//! structured triangle (2D, 2 DOFs per node) or tetrahedron (3D, 3 DOFs per node) mesh, plus a
//! lumped mass diagonal — symmetric positive definite, elasticity-like stencils.
#![allow(dead_code, missing_docs)]

use femp_fem::mesh::generate;
use femp_fem::{ElasticBody, NeoHookean, Triplet};
use femp_solver::{Triplets, UpperCsc};
use nalgebra::{Vector2, Vector3};

/// An SPD matrix (upper CSC) and its DOFs per node.
pub struct Case {
    pub name: String,
    pub csc: UpperCsc,
    pub block: usize,
    /// The triplets it was assembled from (element blocks, both triangles, plus the mass
    /// diagonal) and the free-DOF map (all free).
    pub triplets: Triplets,
    pub free: Vec<u32>,
}

fn finish(name: String, trip: &[Triplet], n: usize, mass: f64, block: usize) -> Case {
    let mut t = Triplets::default();
    t.reserve(trip.len() + n);
    for e in trip {
        t.push(e.row, e.col, e.value);
    }
    for d in 0..n {
        t.push(d, d, mass);
    }
    let free: Vec<u32> = (0..n as u32).collect();
    let mut csc = UpperCsc::default();
    csc.assemble(&t, &free, n);
    Case {
        name,
        csc,
        block,
        triplets: t,
        free,
    }
}

/// 2D: an `m × m` node grid (2 m² unknowns).
pub fn grid2(m: usize) -> Case {
    let mesh = generate::rectangle(Vector2::zeros(), Vector2::new(1.0, 1.0), m - 1, m - 1).unwrap();
    let body = ElasticBody::new(&mesh, NeoHookean::from_young_poisson(1e6, 0.3).unwrap()).unwrap();
    let x: Vec<_> = mesh.vertices().iter().map(|v| v * 1.01).collect();
    let mut trip = Vec::new();
    body.hessian_triplets(&x, 1e-4, 0, &mut trip).unwrap();
    finish(
        format!("2d_{}k", 2 * m * m / 1000),
        &trip,
        2 * m * m,
        1.0 / (m * m) as f64,
        2,
    )
}

/// 3D: an `m³` node grid (3 m³ unknowns).
pub fn grid3(m: usize) -> Case {
    let mesh = generate::cuboid(
        Vector3::zeros(),
        Vector3::new(1.0, 1.0, 1.0),
        m - 1,
        m - 1,
        m - 1,
    )
    .unwrap();
    let body = ElasticBody::new(&mesh, NeoHookean::from_young_poisson(1e6, 0.3).unwrap()).unwrap();
    let x: Vec<_> = mesh.vertices().iter().map(|v| v * 1.01).collect();
    let mut trip = Vec::new();
    body.hessian_triplets(&x, 1e-4, 0, &mut trip).unwrap();
    finish(
        format!("3d_{}k", 3 * m * m * m / 1000),
        &trip,
        3 * m * m * m,
        1.0 / (m * m * m) as f64,
        3,
    )
}

/// 3D with the pattern of the MPM part of femp's 3D Newton matrices: an `m³` grid of nodes of 3
/// DOFs, each coupled with the 5³ nodes within two cells (a quadratic B-spline's reach; 375
/// entries a row inside), diagonally dominant (SPD). Its triplets are the upper triangle
/// (row ≤ col) with the diagonal. `bspline3(20)`: 24 000 unknowns, like block_on_plate_3d's
/// 26 244, and a nested-dissection factor of 4.4·10⁷ entries.
pub fn bspline3(m: usize) -> Case {
    let node = |i: usize, j: usize, k: usize| (i * m + j) * m + k;
    let n = 3 * m * m * m;
    let mut diag = vec![1.0; n];
    let mut t = Triplets::default();
    let mut couple = |t: &mut Triplets, r: usize, c: usize, v: f64| {
        t.push(r, c, v);
        diag[r] += v.abs();
        diag[c] += v.abs();
    };
    for (i, j, k) in (0..m).flat_map(|i| (0..m).flat_map(move |j| (0..m).map(move |k| (i, j, k)))) {
        let a = node(i, j, k);
        for p in 0..3 {
            for q in p + 1..3 {
                couple(&mut t, 3 * a + p, 3 * a + q, 0.3);
            }
        }
        for (di, dj, dk) in (-2i64..=2)
            .flat_map(|x| (-2i64..=2).flat_map(move |y| (-2i64..=2).map(move |z| (x, y, z))))
        {
            let (bi, bj, bk) = (i as i64 + di, j as i64 + dj, k as i64 + dk);
            if [bi, bj, bk].iter().any(|&c| c < 0 || c >= m as i64) {
                continue;
            }
            let b = node(bi as usize, bj as usize, bk as usize);
            if b <= a {
                continue;
            }
            let d2 = (di * di + dj * dj + dk * dk) as f64;
            for p in 0..3 {
                for q in 0..3 {
                    couple(
                        &mut t,
                        3 * a + p,
                        3 * b + q,
                        -1.0 / (1.0 + d2 + (p + 2 * q) as f64),
                    );
                }
            }
        }
    }
    for (d, v) in diag.into_iter().enumerate() {
        t.push(d, d, v);
    }
    let free: Vec<u32> = (0..n as u32).collect();
    let mut csc = UpperCsc::default();
    csc.assemble(&t, &free, n);
    Case {
        name: format!("bspline3d_{}k", n / 1000),
        csc,
        block: 3,
        triplets: t,
        free,
    }
}

/// The benchmark set: about 10⁴, 10⁵ and 4·10⁵ unknowns in 2D; 10⁴ and 10⁵ in 3D (the 3D
/// 4·10⁵ case is left out: its factor needs several GB and minutes per factorisation here).
pub fn all() -> Vec<Case> {
    vec![grid2(71), grid2(224), grid2(447), grid3(15), grid3(32)]
}

/// Write the upper triangle in Matrix Market coordinate form (for CHOLMOD).
pub fn write_mtx(case: &Case, path: &std::path::Path) -> std::io::Result<()> {
    use std::io::Write;
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    let a = &case.csc;
    writeln!(f, "%%MatrixMarket matrix coordinate real symmetric")?;
    writeln!(f, "{} {} {}", a.n(), a.n(), a.nnz())?;
    for c in 0..a.n() {
        for k in a.col_ptr()[c]..a.col_ptr()[c + 1] {
            // Symmetric Matrix Market stores the lower triangle: (row ≥ col).
            writeln!(f, "{} {} {:.17e}", c + 1, a.row_idx()[k] + 1, a.values()[k])?;
        }
    }
    f.flush()
}
