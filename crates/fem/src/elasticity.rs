//! Elastic energy of a mesh, `Ψ(x) = Σ_e V_e ψ(F_e(x))`, with its gradient and PSD-projected
//! Hessian, assembled in parallel.
//!
//! * [`ElasticBody::energy`] — parallel sum; `+∞` if any element is inverted (neo-Hookean).
//! * [`ElasticBody::add_gradient`] — element forces computed in parallel into a buffer the body
//!   owns, then summed per vertex in a fixed order (deterministic, no atomics, no allocation
//!   after the first call); [`ElasticBody::add_gradient_with`] does the same through `&self`
//!   with a buffer the caller keeps (what femp's step objective uses).
//! * [`ElasticBody::hessian_triplets`] — `(row, col, value)` entries of the PSD-projected
//!   Hessian (each element's `(D+1)² D²` entries, full blocks, both triangles), written in
//!   parallel into a caller-owned vector resized to exactly the needed length; DOF of vertex
//!   `v`, component `a` is `dof_offset + v·D + a`.
//! * [`ElasticBody::max_inversion_free_step`] — the largest `τ ∈ (0, 1]` keeping every element's
//!   `det F > 0` along `x + τ p` (see [`crate::inversion`]).
//!
//! All take a `scale` so a caller can assemble `2αβΔt² Ψ` directly.

use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use crate::error::check_len;
use crate::inversion::first_det_root;
use crate::material::{Hyperelastic, cauchy, von_mises};
use crate::{Element, FemError, Mesh, chain_gradient, chain_hessian, linalg};

/// One entry of a sparse matrix in coordinate form.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Triplet {
    /// Row index.
    pub row: usize,
    /// Column index.
    pub col: usize,
    /// Value.
    pub value: f64,
}

/// A mesh with a material: the elastic part of an FEM body.
#[derive(Clone, Debug)]
pub struct ElasticBody<const D: usize, M> {
    material: M,
    cells: Vec<[usize; 4]>,
    elements: Vec<Element<D>>,
    n_vertices: usize,
    /// Vertex → (element, local index) incidences, CSR.
    inc_start: Vec<usize>,
    inc: Vec<(u32, u8)>,
    /// Per-element forces, reused by `add_gradient`.
    forces: Vec<[SVector<f64, D>; 4]>,
}

impl<const D: usize, M: Hyperelastic<D>> ElasticBody<D, M> {
    /// Build from a mesh (its vertex positions are the rest shape) and a material.
    pub fn new(mesh: &Mesh<D>, material: M) -> Result<Self, FemError> {
        let cells = mesh.cells().to_vec();
        let mut elements = Vec::with_capacity(cells.len());
        for (e, c) in cells.iter().enumerate() {
            let rest: [SVector<f64, D>; 4] = std::array::from_fn(|k| {
                if k <= D {
                    mesh.vertices()[c[k]]
                } else {
                    SVector::zeros()
                }
            });
            elements.push(Element::new(&rest[..D + 1], e)?);
        }
        let n = mesh.num_vertices();
        let mut count = vec![0usize; n + 1];
        for c in &cells {
            for &v in &c[..D + 1] {
                count[v + 1] += 1;
            }
        }
        for v in 0..n {
            count[v + 1] += count[v];
        }
        let mut fill = count.clone();
        let mut inc = vec![(0u32, 0u8); count[n]];
        for (e, c) in cells.iter().enumerate() {
            for (k, &v) in c[..D + 1].iter().enumerate() {
                inc[fill[v]] = (e as u32, k as u8);
                fill[v] += 1;
            }
        }
        Ok(Self {
            material,
            forces: vec![[SVector::zeros(); 4]; cells.len()],
            cells,
            elements,
            n_vertices: n,
            inc_start: count,
            inc,
        })
    }

    /// The material.
    pub fn material(&self) -> &M {
        &self.material
    }

    /// Number of elements.
    pub fn num_elements(&self) -> usize {
        self.elements.len()
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.n_vertices
    }

    /// Rest-shape data of every element.
    pub fn elements(&self) -> &[Element<D>] {
        &self.elements
    }

    /// Element connectivity (first `D + 1` entries used).
    pub fn cells(&self) -> &[[usize; 4]] {
        &self.cells
    }

    #[inline]
    fn positions(&self, e: usize, x: &[SVector<f64, D>]) -> [SVector<f64, D>; 4] {
        let c = &self.cells[e];
        std::array::from_fn(|k| if k <= D { x[c[k]] } else { SVector::zeros() })
    }

    /// Deformation gradient of element `e` at positions `x`.
    #[inline]
    pub fn deformation_gradient(&self, e: usize, x: &[SVector<f64, D>]) -> SMatrix<f64, D, D> {
        self.elements[e].deformation_gradient(&self.positions(e, x))
    }

    fn check(&self, x: &[SVector<f64, D>]) -> Result<(), FemError> {
        check_len("vertex positions", self.n_vertices, x.len())
    }

    /// `Ψ(x) = Σ_e V_e ψ(F_e)`.
    pub fn energy(&self, x: &[SVector<f64, D>]) -> Result<f64, FemError> {
        self.check(x)?;
        // Fixed chunks summed in order: the same bits on any number of threads (rayon's own
        // `sum` splits by thread count and work stealing).
        const CHUNK: usize = 1024;
        let n = self.elements.len();
        Ok((0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| {
                (c * CHUNK..((c + 1) * CHUNK).min(n))
                    .map(|e| {
                        self.elements[e].volume
                            * self
                                .material
                                .energy_density(&self.deformation_gradient(e, x))
                    })
                    .sum::<f64>()
            })
            .collect::<Vec<f64>>()
            .into_iter()
            .sum())
    }

    /// `out += scale · ∂Ψ/∂x`.
    pub fn add_gradient(
        &mut self,
        x: &[SVector<f64, D>],
        scale: f64,
        out: &mut [SVector<f64, D>],
    ) -> Result<(), FemError> {
        let mut forces = std::mem::take(&mut self.forces);
        let result = self.add_gradient_with(x, scale, &mut forces, out);
        self.forces = forces;
        result
    }

    /// [`Self::add_gradient`] through a shared reference, with the per-element forces in a
    /// buffer the caller keeps (resized to the element count; reuse it across calls to
    /// allocate nothing). Elements in parallel, then each vertex sums its elements' forces in
    /// element order: the same bits on any thread count.
    pub fn add_gradient_with(
        &self,
        x: &[SVector<f64, D>],
        scale: f64,
        forces: &mut Vec<[SVector<f64, D>; 4]>,
        out: &mut [SVector<f64, D>],
    ) -> Result<(), FemError> {
        self.check(x)?;
        check_len("gradient output", self.n_vertices, out.len())?;
        forces.resize(self.cells.len(), [SVector::zeros(); 4]);
        let (cells, elements, material) = (&self.cells, &self.elements, &self.material);
        forces
            .par_iter_mut()
            .enumerate()
            .with_min_len(1024)
            .for_each(|(e, f)| {
                let c = &cells[e];
                let xe: [SVector<f64, D>; 4] =
                    std::array::from_fn(|k| if k <= D { x[c[k]] } else { SVector::zeros() });
                let el = &elements[e];
                let p = material.first_piola(&el.deformation_gradient(&xe));
                chain_gradient(&p, el.gradients(), el.volume * scale, &mut f[..D + 1]);
            });
        let (inc_start, inc, forces) = (&self.inc_start, &self.inc, &*forces);
        out.par_iter_mut()
            .enumerate()
            .with_min_len(1024)
            .for_each(|(v, o)| {
                for &(e, k) in &inc[inc_start[v]..inc_start[v + 1]] {
                    *o += forces[e as usize][k as usize];
                }
            });
        Ok(())
    }

    /// Number of triplets [`Self::hessian_triplets`] produces.
    pub fn num_hessian_triplets(&self) -> usize {
        self.elements.len() * (D + 1) * (D + 1) * D * D
    }

    /// The PSD-projected Hessian of `scale · Ψ` as triplets (see the module documentation).
    /// `out` is resized to [`Self::num_hessian_triplets`]; element `e` owns entries
    /// `e·k..(e+1)·k`, ordered by local vertex `i`, `j`, then components `a`, `c`.
    pub fn hessian_triplets(
        &self,
        x: &[SVector<f64, D>],
        scale: f64,
        dof_offset: usize,
        out: &mut Vec<Triplet>,
    ) -> Result<(), FemError> {
        self.triplets_with(x, scale, dof_offset, true, out)
    }

    /// The exact (unprojected, possibly indefinite) Hessian of `scale · Ψ`, laid out like
    /// [`Self::hessian_triplets`].
    pub fn exact_hessian_triplets(
        &self,
        x: &[SVector<f64, D>],
        scale: f64,
        dof_offset: usize,
        out: &mut Vec<Triplet>,
    ) -> Result<(), FemError> {
        self.triplets_with(x, scale, dof_offset, false, out)
    }

    fn triplets_with(
        &self,
        x: &[SVector<f64, D>],
        scale: f64,
        dof_offset: usize,
        project: bool,
        out: &mut Vec<Triplet>,
    ) -> Result<(), FemError> {
        self.check(x)?;
        let k = (D + 1) * (D + 1) * D * D;
        out.resize(self.num_hessian_triplets(), Triplet::default());
        out.par_chunks_mut(k)
            .enumerate()
            .with_min_len(256)
            .for_each(|(e, chunk)| {
                let mut blocks = [SMatrix::<f64, D, D>::zeros(); 16];
                self.element_blocks(e, x, scale, project, &mut blocks);
                let c = &self.cells[e];
                let mut t = 0;
                for i in 0..=D {
                    for j in 0..=D {
                        let h = &blocks[i * (D + 1) + j];
                        for a in 0..D {
                            for b in 0..D {
                                chunk[t] = Triplet {
                                    row: dof_offset + c[i] * D + a,
                                    col: dof_offset + c[j] * D + b,
                                    value: h[(a, b)],
                                };
                                t += 1;
                            }
                        }
                    }
                }
            });
        Ok(())
    }

    /// PSD-projected Hessian blocks of `scale · V_e ψ(F_e)` for element `e`: `(D+1)²` blocks,
    /// row-major by local vertex.
    #[inline]
    pub fn element_hessian(
        &self,
        e: usize,
        x: &[SVector<f64, D>],
        scale: f64,
        blocks: &mut [SMatrix<f64, D, D>; 16],
    ) {
        self.element_blocks(e, x, scale, true, blocks);
    }

    /// [`Self::element_hessian`], or (`project` false) the exact, unprojected blocks.
    #[inline]
    fn element_blocks(
        &self,
        e: usize,
        x: &[SVector<f64, D>],
        scale: f64,
        project: bool,
        blocks: &mut [SMatrix<f64, D, D>; 16],
    ) {
        let el = &self.elements[e];
        let f = self.deformation_gradient(e, x);
        let t = if project {
            self.material.tangent_psd(&f)
        } else {
            self.material.tangent(&f)
        };
        chain_hessian(
            &t,
            el.gradients(),
            el.volume * scale,
            &mut blocks[..(D + 1) * (D + 1)],
        );
    }

    /// The largest `τ ∈ (0, 1]` such that every element keeps `det F > 0` on `x + s p` for all
    /// `0 ≤ s < τ` (1 if none inverts). `0` if some element is already inverted at `x`.
    pub fn max_inversion_free_step(
        &self,
        x: &[SVector<f64, D>],
        p: &[SVector<f64, D>],
    ) -> Result<f64, FemError> {
        self.check(x)?;
        check_len("search direction", self.n_vertices, p.len())?;
        Ok((0..self.elements.len())
            .into_par_iter()
            .with_min_len(1024)
            .map(|e| {
                let a0 = Element::<D>::edge_matrix(&self.positions(e, x));
                let a1 = Element::<D>::edge_matrix(&self.positions(e, p));
                first_det_root(&a0, &a1).unwrap_or(1.0)
            })
            .reduce(|| 1.0, f64::min))
    }

    /// `det F` of every element.
    pub fn det_f(&self, x: &[SVector<f64, D>]) -> Vec<f64> {
        (0..self.elements.len())
            .into_par_iter()
            .map(|e| linalg::det(&self.deformation_gradient(e, x)))
            .collect()
    }

    /// Cauchy stress of every element (NaN entries for an inverted one).
    pub fn cauchy_stress(&self, x: &[SVector<f64, D>]) -> Vec<SMatrix<f64, D, D>> {
        (0..self.elements.len())
            .into_par_iter()
            .map(|e| {
                let f = self.deformation_gradient(e, x);
                cauchy(&self.material.first_piola(&f), &f)
            })
            .collect()
    }

    /// Von Mises stress of every element.
    pub fn von_mises(&self, x: &[SVector<f64, D>]) -> Vec<f64> {
        (0..self.elements.len())
            .into_par_iter()
            .map(|e| {
                let f = self.deformation_gradient(e, x);
                von_mises(&self.material.first_piola(&f), &f)
            })
            .collect()
    }
}
