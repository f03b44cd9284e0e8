//! Inertia, gravity, external forces and the slip penalties:
//! `½‖x − x̂‖²_M − w Σ (m g + f)·x + Σ ½ k (n·x_i − c)²`.

use femp_solver::Triplets;
use nalgebra::SVector;

use super::config::block;

/// A penalty `½ k (n·x_i − c)²` on one grid node (slip level sets with oblique normals).
#[derive(Clone, Copy, Debug)]
pub struct Penalty<const D: usize> {
    /// Grid node.
    pub node: usize,
    /// Unit normal.
    pub n: SVector<f64, D>,
    /// Target of `n·x_i`.
    pub target: f64,
    /// Stiffness.
    pub k: f64,
}

impl<const D: usize> Penalty<D> {
    /// The penalty's gradient `k (n·x_i − c) n` on its node, at the DOF vector `x`.
    pub fn gradient(&self, x: &[f64]) -> SVector<f64, D> {
        let r = self.n.dot(&block(x, self.node)) - self.target;
        SVector::from_fn(|a, _| self.k * r * self.n[a])
    }
}

/// The quadratic terms of the step: inertia about the predictor `x̂`, gravity, external
/// forces, penalties.
pub(crate) struct Inertia<'a, const D: usize> {
    /// Mass per DOF (the diagonal of `M`).
    pub mass: &'a [f64],
    pub x_hat: &'a [f64],
    pub gravity: SVector<f64, D>,
    /// External force per DOF ([`crate::steer`]), or empty for none.
    pub force: &'a [f64],
    pub penalties: &'a [Penalty<D>],
}

impl<const D: usize> Inertia<'_, D> {
    /// The energy at `x` (gravity times the integrator weight `w`).
    pub fn energy(&self, x: &[f64], w: f64) -> f64 {
        let mut e = 0.0;
        for d in 0..self.mass.len() {
            let r = x[d] - self.x_hat[d];
            e += 0.5 * self.mass[d] * r * r - w * self.mass[d] * self.gravity[d % D] * x[d];
        }
        for (f, x) in self.force.iter().zip(x) {
            e -= w * f * x;
        }
        for p in self.penalties {
            let r = p.n.dot(&block(x, p.node)) - p.target;
            e += 0.5 * p.k * r * r;
        }
        e
    }

    /// Write (not add) the gradient at `x` into `g`.
    pub fn set_gradient(&self, x: &[f64], w: f64, g: &mut [f64]) {
        for d in 0..self.mass.len() {
            g[d] = self.mass[d] * (x[d] - self.x_hat[d]) - w * self.mass[d] * self.gravity[d % D];
        }
        for (g, f) in g.iter_mut().zip(self.force) {
            *g -= w * f;
        }
        for p in self.penalties {
            let gp = p.gradient(x);
            for a in 0..D {
                g[p.node * D + a] += gp[a];
            }
        }
    }

    /// Append the Hessian (the masses and the penalties' `k n nᵀ`, upper triangle) to `h`.
    pub fn hessian(&self, h: &mut Triplets) {
        for d in 0..self.mass.len() {
            h.push(d, d, self.mass[d]);
        }
        for p in self.penalties {
            for a in 0..D {
                for b in a..D {
                    h.push(p.node * D + a, p.node * D + b, p.k * p.n[a] * p.n[b]);
                }
            }
        }
    }
}
