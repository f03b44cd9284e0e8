//! Simplex meshes: vertices and cells (triangles in 2D, tetrahedra in 3D).
//!
//! * [`Mesh::new`] validates connectivity (indices in range, no repeated vertex, finite
//!   coordinates) and orientation (every cell positively oriented and non-degenerate; the error
//!   names the cell and its signed volume).
//! * [`generate`] builds the shapes the papers' scenes use.
//! * [`gmsh`] reads Gmsh `.msh` (ASCII 2.2; ASCII and binary 4.1 through `mshio`) and writes
//!   ASCII 2.2 and 4.1.
//! * [`vtk`] writes (and reads back) VTK XML unstructured grids and ParaView `.pvd` series.

pub mod generate;
pub mod gmsh;
pub mod vtk;

use nalgebra::SVector;

use crate::{FemError, linalg};

/// A mesh of linear simplices in `D` dimensions.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh<const D: usize> {
    vertices: Vec<SVector<f64, D>>,
    /// Cell vertex indices; the first `D + 1` entries are used.
    cells: Vec<[usize; 4]>,
}

/// Relative threshold below which a cell's volume counts as degenerate:
/// `|V| ≤ DEGENERATE · ℓ^D` with `ℓ` its longest edge.
pub const DEGENERATE: f64 = 1e-12;

impl<const D: usize> Mesh<D> {
    /// A validated mesh. Cells list `D + 1` vertex indices each (the rest of the array is
    /// ignored) and must be positively oriented.
    pub fn new(vertices: Vec<SVector<f64, D>>, cells: Vec<[usize; 4]>) -> Result<Self, FemError> {
        const { assert!(D == 2 || D == 3, "femp-fem supports D = 2 and D = 3") };
        let mesh = Self { vertices, cells };
        mesh.validate()?;
        Ok(mesh)
    }

    /// Like [`Mesh::new`] but cells with negative orientation are reordered (two vertices
    /// swapped) instead of rejected. Degenerate cells are still an error.
    pub fn new_oriented(
        vertices: Vec<SVector<f64, D>>,
        mut cells: Vec<[usize; 4]>,
    ) -> Result<Self, FemError> {
        let probe = Self {
            vertices,
            cells: Vec::new(),
        };
        probe.check_indices(&cells)?;
        for c in cells.iter_mut() {
            if probe.signed_volume_of(c) < 0.0 {
                c.swap(0, 1);
            }
        }
        Self::new(probe.vertices, cells)
    }

    fn check_indices(&self, cells: &[[usize; 4]]) -> Result<(), FemError> {
        if let Some(v) = self
            .vertices
            .iter()
            .position(|x| x.iter().any(|c| !c.is_finite()))
        {
            return Err(FemError::BadVertex {
                vertex: v,
                reason: "coordinate is not finite",
            });
        }
        let n = self.vertices.len();
        for (e, c) in cells.iter().enumerate() {
            let c = &c[..D + 1];
            if let Some(&v) = c.iter().find(|&&v| v >= n) {
                return Err(FemError::DanglingVertex {
                    cell: e,
                    vertex: v,
                    num_vertices: n,
                });
            }
            for i in 0..=D {
                for j in i + 1..=D {
                    if c[i] == c[j] {
                        return Err(FemError::DegenerateCell {
                            cell: e,
                            volume: 0.0,
                            reason: "repeats a vertex",
                        });
                    }
                }
            }
        }
        Ok(())
    }

    fn validate(&self) -> Result<(), FemError> {
        self.check_indices(&self.cells)?;
        for (e, c) in self.cells.iter().enumerate() {
            let vol = self.signed_volume_of(c);
            let l = self.longest_edge_of(c);
            if vol.abs() <= DEGENERATE * l.powi(D as i32) {
                return Err(FemError::DegenerateCell {
                    cell: e,
                    volume: vol,
                    reason: "has (near) zero volume",
                });
            }
            if vol < 0.0 {
                return Err(FemError::InvertedCell {
                    cell: e,
                    volume: vol,
                });
            }
        }
        Ok(())
    }

    fn signed_volume_of(&self, c: &[usize; 4]) -> f64 {
        let x0 = self.vertices[c[0]];
        let b = nalgebra::SMatrix::<f64, D, D>::from_fn(|r, k| self.vertices[c[k + 1]][r] - x0[r]);
        linalg::det(&b) / if D == 2 { 2.0 } else { 6.0 }
    }

    fn longest_edge_of(&self, c: &[usize; 4]) -> f64 {
        let mut l: f64 = 0.0;
        for i in 0..=D {
            for j in i + 1..=D {
                l = l.max((self.vertices[c[i]] - self.vertices[c[j]]).norm());
            }
        }
        l
    }

    /// Vertex positions.
    #[inline]
    pub fn vertices(&self) -> &[SVector<f64, D>] {
        &self.vertices
    }

    /// Number of vertices.
    #[inline]
    pub fn num_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Number of cells.
    #[inline]
    pub fn num_cells(&self) -> usize {
        self.cells.len()
    }

    /// The `D + 1` vertex indices of cell `e`.
    #[inline]
    pub fn cell(&self, e: usize) -> &[usize] {
        &self.cells[e][..D + 1]
    }

    /// All cells as fixed arrays (first `D + 1` entries used).
    #[inline]
    pub fn cells(&self) -> &[[usize; 4]] {
        &self.cells
    }

    /// Signed volume (area in 2D) of cell `e`.
    pub fn cell_volume(&self, e: usize) -> f64 {
        self.signed_volume_of(&self.cells[e])
    }

    /// Total volume (area in 2D).
    pub fn volume(&self) -> f64 {
        (0..self.num_cells()).map(|e| self.cell_volume(e)).sum()
    }

    /// Shortest edge length over all cells.
    pub fn min_edge_length(&self) -> f64 {
        let mut l = f64::INFINITY;
        for c in &self.cells {
            for i in 0..=D {
                for j in i + 1..=D {
                    l = l.min((self.vertices[c[i]] - self.vertices[c[j]]).norm());
                }
            }
        }
        l
    }

    /// Axis-aligned bounding box `(min, max)`.
    pub fn bounding_box(&self) -> (SVector<f64, D>, SVector<f64, D>) {
        let mut lo = SVector::<f64, D>::repeat(f64::INFINITY);
        let mut hi = SVector::<f64, D>::repeat(f64::NEG_INFINITY);
        for x in &self.vertices {
            lo = lo.inf(x);
            hi = hi.sup(x);
        }
        (lo, hi)
    }

    /// The mesh with every vertex mapped by `f`. Fails if the map inverts or degenerates a cell
    /// (a reflection, say).
    pub fn mapped(
        &self,
        f: impl Fn(&SVector<f64, D>) -> SVector<f64, D>,
    ) -> Result<Self, FemError> {
        Self::new(self.vertices.iter().map(f).collect(), self.cells.clone())
    }

    /// The mesh translated by `t`.
    pub fn translated(&self, t: &SVector<f64, D>) -> Self {
        Self {
            vertices: self.vertices.iter().map(|x| x + t).collect(),
            cells: self.cells.clone(),
        }
    }
}
