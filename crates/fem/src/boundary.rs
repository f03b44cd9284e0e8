//! The boundary of a simplex mesh: outward-oriented facets (edges in 2D, triangles in 3D),
//! incidence counts for the BFEMP contact potential (eqs. 31–32), and area-weighted outward
//! vertex normals (augury §2.3).
//!
//! * A facet is on the boundary when exactly one cell has it. Its vertex order makes the normal
//!   point out of the body: in 2D the edge `(a, b)` has outward normal `(b − a)` rotated by −90°
//!   (`(d_y, −d_x)`); in 3D the triangle `(a, b, c)` has outward normal `(b − a) × (c − a)`.
//! * η counts: per boundary vertex, the number of boundary facets containing it (2D `η_k`);
//!   in 3D also per boundary edge, the number of boundary triangles containing it (`η_e`).
//!   On a closed (manifold) boundary every η is 2.

use std::collections::HashMap;

use nalgebra::SVector;

use crate::Mesh;

/// Boundary of a mesh. See the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct Boundary<const D: usize> {
    facets: Vec<[usize; 3]>,
    vertices: Vec<usize>,
    vertex_facets: Vec<u32>,
    edges: Vec<[usize; 2]>,
    edge_facets: Vec<u32>,
}

/// Faces of a positively oriented tetrahedron `(0, 1, 2, 3)` with outward orientation.
const TET_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

impl<const D: usize> Boundary<D> {
    /// Extract the boundary of `mesh`.
    pub fn of(mesh: &Mesh<D>) -> Self {
        let mut count: HashMap<[usize; 3], (u32, [usize; 3])> = HashMap::new();
        for e in 0..mesh.num_cells() {
            let c = mesh.cell(e);
            if D == 2 {
                for k in 0..3 {
                    let (a, b) = (c[k], c[(k + 1) % 3]);
                    let key = [a.min(b), a.max(b), usize::MAX];
                    let entry = count.entry(key).or_insert((0, [a, b, usize::MAX]));
                    entry.0 += 1;
                }
            } else {
                for f in TET_FACES {
                    let tri = [c[f[0]], c[f[1]], c[f[2]]];
                    let mut key = tri;
                    key.sort_unstable();
                    let entry = count.entry(key).or_insert((0, tri));
                    entry.0 += 1;
                }
            }
        }
        let mut facets: Vec<[usize; 3]> = count
            .into_values()
            .filter(|(n, _)| *n == 1)
            .map(|(_, f)| f)
            .collect();
        facets.sort_unstable();
        let mut vcount: HashMap<usize, u32> = HashMap::new();
        let mut ecount: HashMap<[usize; 2], u32> = HashMap::new();
        for f in &facets {
            for &v in &f[..D] {
                *vcount.entry(v).or_insert(0) += 1;
            }
            if D == 3 {
                for k in 0..3 {
                    let (a, b) = (f[k], f[(k + 1) % 3]);
                    *ecount.entry([a.min(b), a.max(b)]).or_insert(0) += 1;
                }
            }
        }
        let mut vertices: Vec<usize> = vcount.keys().copied().collect();
        vertices.sort_unstable();
        let vertex_facets = vertices.iter().map(|v| vcount[v]).collect();
        let mut edges: Vec<[usize; 2]> = ecount.keys().copied().collect();
        edges.sort_unstable();
        let edge_facets = edges.iter().map(|e| ecount[e]).collect();
        Self {
            facets,
            vertices,
            vertex_facets,
            edges,
            edge_facets,
        }
    }

    /// Outward-oriented boundary facets; the first `D` entries of each are mesh vertex indices.
    pub fn facets(&self) -> &[[usize; 3]] {
        &self.facets
    }

    /// Boundary vertices (mesh indices), sorted.
    pub fn vertices(&self) -> &[usize] {
        &self.vertices
    }

    /// Per boundary vertex (same order as [`Self::vertices`]): the number of boundary facets
    /// containing it (`η_k` in 2D).
    pub fn vertex_facet_counts(&self) -> &[u32] {
        &self.vertex_facets
    }

    /// 3D: boundary edges (sorted vertex pairs), sorted; empty in 2D.
    pub fn edges(&self) -> &[[usize; 2]] {
        &self.edges
    }

    /// 3D: per boundary edge, the number of boundary triangles containing it (`η_e`).
    pub fn edge_facet_counts(&self) -> &[u32] {
        &self.edge_facets
    }

    /// Whether the boundary is a closed manifold (every η equal to 2).
    pub fn is_closed(&self) -> bool {
        if D == 2 {
            self.vertex_facets.iter().all(|&n| n == 2)
        } else {
            self.edge_facets.iter().all(|&n| n == 2)
        }
    }

    /// Outward normal of facet `f` scaled by its measure (length in 2D, area in 3D).
    pub fn facet_normal(&self, f: usize, x: &[SVector<f64, D>]) -> SVector<f64, D> {
        let v = &self.facets[f];
        let mut n = SVector::<f64, D>::zeros();
        if D == 2 {
            let d = x[v[1]] - x[v[0]];
            n[0] = d[1];
            n[1] = -d[0];
        } else {
            let (a, b) = (x[v[1]] - x[v[0]], x[v[2]] - x[v[0]]);
            n[0] = 0.5 * (a[1] * b[D - 1] - a[D - 1] * b[1]);
            n[1] = 0.5 * (a[D - 1] * b[0] - a[0] * b[D - 1]);
            n[D - 1] = 0.5 * (a[0] * b[1] - a[1] * b[0]);
        }
        n
    }

    /// Area-weighted outward unit normal of every boundary vertex at positions `x` (same order
    /// as [`Self::vertices`]): the normalised sum of the measure-scaled normals of its facets.
    pub fn vertex_normals(&self, x: &[SVector<f64, D>]) -> Vec<SVector<f64, D>> {
        let index: HashMap<usize, usize> = self
            .vertices
            .iter()
            .enumerate()
            .map(|(i, &v)| (v, i))
            .collect();
        let mut n = vec![SVector::<f64, D>::zeros(); self.vertices.len()];
        for f in 0..self.facets.len() {
            let nf = self.facet_normal(f, x);
            for &v in &self.facets[f][..D] {
                n[index[&v]] += nf;
            }
        }
        for v in n.iter_mut() {
            let l = v.norm();
            if l > 0.0 {
                *v /= l;
            }
        }
        n
    }
}
