//! The unknowns' layout and the configuration they describe, shared by every term.

use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use crate::bodies::{FemBody, Mpm};

/// Where the bodies' unknowns sit in `x`: the grid nodes' positions first (`n_grid` nodes),
/// then each FEM body's vertices from `fem_offset[b]`.
#[derive(Clone)]
pub(crate) struct Dofs {
    pub n_grid: usize,
    pub fem_offset: Vec<usize>,
    pub n: usize,
}

/// `D` consecutive entries of `x` from block `k`.
#[inline]
pub(super) fn block<const D: usize>(x: &[f64], k: usize) -> SVector<f64, D> {
    SVector::from_column_slice(&x[k * D..k * D + D])
}

/// The bodies' configuration at the last `x` the objective saw: what every term reads.
pub(super) struct Configuration<const D: usize> {
    /// The `x` it was last updated at.
    x: Vec<f64>,
    /// Incremented whenever the objective's state changes: a new `x`
    /// ([`Configuration::update`]) or a new friction operator ([`Configuration::touch`]).
    pub generation: u64,
    /// Grid node displacements over the step, `u_i = x_i − X_i`.
    pub u: Vec<SVector<f64, D>>,
    /// Particle positions `x_q = x_qⁿ + Σ_i w_iq u_i`.
    pub xq: Vec<SVector<f64, D>>,
    /// Particle deformation gradients `F_q = gu_q F_qⁿ`.
    pub fq: Vec<SMatrix<f64, D, D>>,
    /// `I + Σ_i u_i ∇w_iqᵀ` per particle, for the det F step bound.
    pub gu: Vec<SMatrix<f64, D, D>>,
    /// Each FEM body's vertex positions.
    pub fem_x: Vec<Vec<SVector<f64, D>>>,
}

impl<const D: usize> Configuration<D> {
    /// Before any `x`: the FEM bodies where they are.
    pub fn new(fem: &[FemBody<D>]) -> Self {
        Self {
            x: Vec::new(),
            generation: 0,
            u: Vec::new(),
            xq: Vec::new(),
            fq: Vec::new(),
            gu: Vec::new(),
            fem_x: fem.iter().map(|b| b.x.clone()).collect(),
        }
    }

    /// The state changed without a new `x` (a new friction operator).
    pub fn touch(&mut self) {
        self.generation += 1;
    }

    /// Move to `x` (grid displacements from the step's start `x_start`); `false` if already
    /// there — Newton evaluates gradient, Hessian and step bound at the same `x`.
    pub fn update(
        &mut self,
        x: &[f64],
        x_start: &[f64],
        mpm: Option<&Mpm<D>>,
        fem: &[FemBody<D>],
        dofs: &Dofs,
    ) -> bool {
        if self.x == x {
            return false;
        }
        self.generation += 1;
        self.x.clear();
        self.x.extend_from_slice(x);
        if let Some(m) = mpm {
            self.u.resize(dofs.n_grid, SVector::zeros());
            for i in 0..dofs.n_grid {
                self.u[i] = block(x, i) - block(x_start, i);
            }
            let st = &m.stencils;
            let u = &self.u;
            self.xq.resize(m.x.len(), SVector::zeros());
            self.fq.resize(m.x.len(), SMatrix::zeros());
            self.gu.resize(m.x.len(), SMatrix::zeros());
            self.xq
                .par_iter_mut()
                .zip(self.fq.par_iter_mut())
                .zip(self.gu.par_iter_mut())
                .enumerate()
                .with_min_len(512)
                .for_each(|(p, ((xq, fq), gu))| {
                    let ps = st.particle(p);
                    let mut dx = SVector::<f64, D>::zeros();
                    let mut du = SMatrix::<f64, D, D>::zeros();
                    ps.for_each(|i, w, g| {
                        dx += u[i] * w;
                        du += u[i] * g.transpose();
                    });
                    *xq = m.x[p] + dx;
                    *gu = SMatrix::identity() + du;
                    *fq = *gu * m.f[p];
                });
        }
        for (b, off) in dofs.fem_offset.iter().enumerate() {
            let n = fem[b].x.len();
            let xs = &mut self.fem_x[b];
            for v in 0..n {
                xs[v] = SVector::from_column_slice(&x[off + v * D..off + v * D + D]);
            }
        }
        true
    }
}
