//! Hyperelastic materials shared by FEM elements and MPM particles: they take a deformation
//! gradient `F` and return the energy density `ψ(F)`, the first Piola–Kirchhoff stress
//! `P = ∂ψ/∂F`, the tangent `∂P/∂F` and a positive semi-definite projection of it.
//!
//! * [`NeoHookean`] — compressible neo-Hookean, BFEMP eq. 7:
//!   `ψ = μ/2 (tr(FᵀF) − D) − μ ln J + λ/2 (ln J)²`.
//! * [`LinearElastic`] — small-strain linear elasticity: `ψ = μ ε:ε + λ/2 tr(ε)²`,
//!   `ε = ½(F + Fᵀ) − I` (used in the Brazilian-disk test, BFEMP §6.3).
//! * [`Material`] — either, chosen at run time (scenes).
//!
//! Energies are per unit reference volume (per unit reference area in 2D, i.e. per unit
//! thickness); Lamé parameters are the 3D ones, so 2D is plane strain.

mod linear;
mod neo_hookean;

use nalgebra::SMatrix;

pub use linear::LinearElastic;
pub use neo_hookean::NeoHookean;

use crate::{FemError, Tangent};

/// A hyperelastic energy density `ψ(F)` with its first two derivatives.
pub trait Hyperelastic<const D: usize>: Send + Sync {
    /// `ψ(F)`. `+∞` where the material is undefined (neo-Hookean with `det F ≤ 0`).
    fn energy_density(&self, f: &SMatrix<f64, D, D>) -> f64;
    /// `P = ∂ψ/∂F`.
    fn first_piola(&self, f: &SMatrix<f64, D, D>) -> SMatrix<f64, D, D>;
    /// `∂P/∂F`.
    fn tangent(&self, f: &SMatrix<f64, D, D>) -> Tangent<D>;
    /// `∂P/∂F` projected onto the positive semi-definite cone (negative eigenvalues clamped).
    fn tangent_psd(&self, f: &SMatrix<f64, D, D>) -> Tangent<D>;
}

/// Lamé parameters `μ` (shear modulus) and `λ`, validated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lame {
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// First Lamé parameter λ (Pa).
    pub lambda: f64,
}

impl Lame {
    /// From Young's modulus `E > 0` and Poisson's ratio `−1 < ν < 1/2`:
    /// `μ = E / (2(1+ν))`, `λ = E ν / ((1+ν)(1−2ν))`.
    pub fn from_young_poisson(youngs_modulus: f64, poisson_ratio: f64) -> Result<Self, FemError> {
        let (e, nu) = (youngs_modulus, poisson_ratio);
        if !(e > 0.0 && e.is_finite()) {
            return Err(FemError::BadMaterial {
                parameter: "E",
                value: e,
                requirement: "Young's modulus must be positive and finite",
            });
        }
        if !(nu.is_finite() && nu < 0.5) {
            return Err(FemError::BadMaterial {
                parameter: "nu",
                value: nu,
                requirement: "Poisson's ratio must be < 0.5 (0.5 is incompressible)",
            });
        }
        if nu <= -1.0 {
            return Err(FemError::BadMaterial {
                parameter: "nu",
                value: nu,
                requirement: "Poisson's ratio must be > -1",
            });
        }
        Ok(Self {
            mu: e / (2.0 * (1.0 + nu)),
            lambda: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
        })
    }

    /// From Lamé parameters directly: `μ > 0` and `2μ + 3λ > 0` (positive bulk modulus).
    pub fn new(mu: f64, lambda: f64) -> Result<Self, FemError> {
        if !(mu > 0.0 && mu.is_finite()) {
            return Err(FemError::BadMaterial {
                parameter: "mu",
                value: mu,
                requirement: "shear modulus must be positive and finite",
            });
        }
        if !(lambda.is_finite() && 2.0 * mu + 3.0 * lambda > 0.0) {
            return Err(FemError::BadMaterial {
                parameter: "lambda",
                value: lambda,
                requirement: "bulk modulus λ + 2μ/3 must be positive",
            });
        }
        Ok(Self { mu, lambda })
    }

    /// Young's modulus.
    pub fn youngs_modulus(&self) -> f64 {
        self.mu * (3.0 * self.lambda + 2.0 * self.mu) / (self.lambda + self.mu)
    }

    /// Poisson's ratio.
    pub fn poisson_ratio(&self) -> f64 {
        self.lambda / (2.0 * (self.lambda + self.mu))
    }
}

/// Check a mass density: positive and finite (kg/m³ in 3D, kg/m² in 2D).
pub fn check_density(rho: f64) -> Result<f64, FemError> {
    if rho > 0.0 && rho.is_finite() {
        Ok(rho)
    } else {
        Err(FemError::BadMaterial {
            parameter: "rho",
            value: rho,
            requirement: "density must be positive and finite",
        })
    }
}

/// A material chosen at run time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Material {
    /// Compressible neo-Hookean (BFEMP eq. 7).
    NeoHookean(NeoHookean),
    /// Small-strain linear elasticity.
    Linear(LinearElastic),
}

impl<const D: usize> Hyperelastic<D> for Material {
    #[inline]
    fn energy_density(&self, f: &SMatrix<f64, D, D>) -> f64 {
        match self {
            Material::NeoHookean(m) => m.energy_density(f),
            Material::Linear(m) => m.energy_density(f),
        }
    }
    #[inline]
    fn first_piola(&self, f: &SMatrix<f64, D, D>) -> SMatrix<f64, D, D> {
        match self {
            Material::NeoHookean(m) => m.first_piola(f),
            Material::Linear(m) => m.first_piola(f),
        }
    }
    #[inline]
    fn tangent(&self, f: &SMatrix<f64, D, D>) -> Tangent<D> {
        match self {
            Material::NeoHookean(m) => m.tangent(f),
            Material::Linear(m) => m.tangent(f),
        }
    }
    #[inline]
    fn tangent_psd(&self, f: &SMatrix<f64, D, D>) -> Tangent<D> {
        match self {
            Material::NeoHookean(m) => m.tangent_psd(f),
            Material::Linear(m) => m.tangent_psd(f),
        }
    }
}

/// The Cauchy stress `σ = J⁻¹ P Fᵀ` (eq. 5) of a first Piola–Kirchhoff stress `P` at `F`; NaN
/// entries where `J = det F ≤ 0` (an inverted state has no Cauchy stress).
pub fn cauchy<const D: usize>(
    p: &SMatrix<f64, D, D>,
    f: &SMatrix<f64, D, D>,
) -> SMatrix<f64, D, D> {
    let j = crate::linalg::det(f);
    if j <= 0.0 || !j.is_finite() {
        return SMatrix::from_element(f64::NAN);
    }
    p * f.transpose() / j
}

/// Von Mises equivalent stress of the Cauchy stress `σ = J⁻¹ P Fᵀ` (eq. 5); in 2D the plane
/// stress components only (out-of-plane stress ignored).
pub fn von_mises<const D: usize>(p: &SMatrix<f64, D, D>, f: &SMatrix<f64, D, D>) -> f64 {
    let sigma = cauchy(p, f);
    if sigma[(0, 0)].is_nan() {
        return f64::NAN;
    }
    let tr = sigma.trace() / D as f64;
    let dev = sigma - SMatrix::<f64, D, D>::identity() * tr;
    // 3D: sqrt(3/2 s:s); 2D (plane): sqrt(σxx² − σxxσyy + σyy² + 3σxy²).
    if D == 3 {
        (1.5 * dev.component_mul(&dev).sum()).sqrt()
    } else {
        let (sx, sy, sxy) = (
            sigma[(0, 0)],
            sigma[(1, 1)],
            0.5 * (sigma[(0, 1)] + sigma[(1, 0)]),
        );
        (sx * sx - sx * sy + sy * sy + 3.0 * sxy * sxy).sqrt()
    }
}
