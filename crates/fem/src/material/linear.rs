//! Small-strain linear elasticity.

use nalgebra::SMatrix;

use super::{Hyperelastic, Lame};
use crate::{FemError, Tangent};

/// `ψ(F) = μ ε:ε + λ/2 tr(ε)²` with the small strain `ε = ½(F + Fᵀ) − I`.
///
/// * `P = 2μ ε + λ tr(ε) I`
/// * `∂P_ab/∂F_cd = μ (δ_ac δ_bd + δ_ad δ_bc) + λ δ_ab δ_cd`, constant.
///
/// The tangent's eigenvalues are `2μ` (shear), `0` (rotations) and `2μ + Dλ` (volume), all
/// non-negative for any valid Lamé pair (`λ > −2μ/3`), so the PSD projection is the tangent
/// itself (tested). The energy is not invariant under finite rotations — that is the small-strain
/// model, valid for the small-deformation range of the Brazilian-disk test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearElastic {
    /// Shear modulus μ.
    pub mu: f64,
    /// First Lamé parameter λ.
    pub lambda: f64,
}

impl LinearElastic {
    /// From validated Lamé parameters.
    pub fn new(lame: Lame) -> Self {
        Self {
            mu: lame.mu,
            lambda: lame.lambda,
        }
    }

    /// From Young's modulus and Poisson's ratio (validated).
    pub fn from_young_poisson(e: f64, nu: f64) -> Result<Self, FemError> {
        Ok(Self::new(Lame::from_young_poisson(e, nu)?))
    }
}

impl<const D: usize> Hyperelastic<D> for LinearElastic {
    fn energy_density(&self, f: &SMatrix<f64, D, D>) -> f64 {
        let eps = (f + f.transpose()) * 0.5 - SMatrix::<f64, D, D>::identity();
        let tr = eps.trace();
        self.mu * eps.norm_squared() + 0.5 * self.lambda * tr * tr
    }

    fn first_piola(&self, f: &SMatrix<f64, D, D>) -> SMatrix<f64, D, D> {
        let eps = (f + f.transpose()) * 0.5 - SMatrix::<f64, D, D>::identity();
        eps * (2.0 * self.mu) + SMatrix::<f64, D, D>::identity() * (self.lambda * eps.trace())
    }

    fn tangent(&self, _f: &SMatrix<f64, D, D>) -> Tangent<D> {
        let mut t = Tangent::zeros();
        for a in 0..D {
            for b in 0..D {
                t.add(a, b, a, b, self.mu);
                t.add(a, b, b, a, self.mu);
                if a == b {
                    for c in 0..D {
                        t.add(a, a, c, c, self.lambda);
                    }
                }
            }
        }
        t
    }

    fn tangent_psd(&self, f: &SMatrix<f64, D, D>) -> Tangent<D> {
        self.tangent(f)
    }
}
