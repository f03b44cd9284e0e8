//! FEM elasticity `w Σ_b Ψ_b(x_b)` of the free bodies through femp-fem's own energy, gradient
//! and Hessian, and the elements' det F > 0 step bound.

use femp_fem::Triplet;
use femp_solver::Triplets;
use nalgebra::SVector;

use super::config::{Configuration, Dofs, block};
use crate::bodies::FemBody;

/// The FEM bodies' elastic energy and its derivatives, with the buffers they reuse.
pub(super) struct ElementElasticity<'a, const D: usize> {
    pub fem: &'a [FemBody<D>],
    /// A body's Hessian triplets.
    trip: Vec<Triplet>,
    /// Per-element forces and per-vertex gradient of a body (`ElasticBody::add_gradient_with`).
    forces: Vec<[SVector<f64, D>; 4]>,
    grad: Vec<SVector<f64, D>>,
    /// A body's part of a step direction.
    dir: Vec<SVector<f64, D>>,
}

impl<'a, const D: usize> ElementElasticity<'a, D> {
    pub fn new(fem: &'a [FemBody<D>]) -> Self {
        Self {
            fem,
            trip: Vec::new(),
            forces: Vec::new(),
            grad: Vec::new(),
            dir: Vec::new(),
        }
    }

    /// Add `w Ψ_b` of every free body to `e`; `+∞` if an element is inverted.
    pub fn add_energy(&self, cfg: &Configuration<D>, w: f64, mut e: f64) -> f64 {
        for (b, body) in self.fem.iter().enumerate() {
            if body.fully_prescribed {
                continue;
            }
            match body.elastic.energy(&cfg.fem_x[b]) {
                Ok(v) if v.is_finite() => e += w * v,
                _ => return f64::INFINITY,
            }
        }
        e
    }

    /// Add the gradient into `g`.
    pub fn add_gradient(&mut self, cfg: &Configuration<D>, dofs: &Dofs, w: f64, g: &mut [f64]) {
        for (b, body) in self.fem.iter().enumerate() {
            if body.fully_prescribed {
                continue;
            }
            let off = dofs.fem_offset[b];
            let n = body.x.len();
            self.grad.clear();
            self.grad.resize(n, SVector::zeros());
            body.elastic
                .add_gradient_with(&cfg.fem_x[b], w, &mut self.forces, &mut self.grad)
                .expect("a FEM body's positions match its mesh");
            for v in 0..n {
                for a in 0..D {
                    g[off + v * D + a] += self.grad[v][a];
                }
            }
        }
    }

    /// Append the Hessian's upper triangle (PSD-projected per element, or `exact`) to `h`.
    pub fn hessian(
        &mut self,
        cfg: &Configuration<D>,
        dofs: &Dofs,
        w: f64,
        exact: bool,
        h: &mut Triplets,
    ) {
        for (b, body) in self.fem.iter().enumerate() {
            if body.fully_prescribed {
                continue;
            }
            let trip = &mut self.trip;
            let el = &body.elastic;
            let built = if exact {
                el.exact_hessian_triplets(&cfg.fem_x[b], w, dofs.fem_offset[b], trip)
            } else {
                el.hessian_triplets(&cfg.fem_x[b], w, dofs.fem_offset[b], trip)
            };
            if built.is_ok() {
                // The upper triangle only: the solver drops the rest (as for the grid's).
                h.reserve(trip.len() / 2 + trip.len() / 8);
                for t in trip.iter().filter(|t| t.row <= t.col) {
                    h.push(t.row, t.col, t.value);
                }
            }
        }
    }

    /// The largest step fraction (≤ 1) along `p` before an element of a free body inverts.
    pub fn det_bound(&mut self, cfg: &Configuration<D>, dofs: &Dofs, p: &[f64]) -> f64 {
        let mut best = 1.0f64;
        for (b, body) in self.fem.iter().enumerate() {
            if body.fully_prescribed {
                continue;
            }
            let off = dofs.fem_offset[b];
            self.dir.clear();
            self.dir
                .extend((0..body.x.len()).map(|v| block(&p[off..], v)));
            // An error (a non-finite direction) leaves no step known to be inversion-free.
            let a = body
                .elastic
                .max_inversion_free_step(&cfg.fem_x[b], &self.dir)
                .unwrap_or(0.0);
            best = best.min(a);
        }
        best
    }
}
