//! Compressible neo-Hookean (BFEMP eq. 7) with an analytic eigensystem for the PSD projection.

use nalgebra::{SMatrix, SVector};

use super::{Hyperelastic, Lame};
use crate::{FemError, Tangent, linalg};

/// `ψ(F) = μ/2 (tr(FᵀF) − D) − μ ln J + λ/2 (ln J)²`, `J = det F`.
///
/// * `P = μ F + (λ ln J − μ) F⁻ᵀ`
/// * `∂P_ab/∂F_cd = μ δ_ac δ_bd + (μ − λ ln J) F⁻ᵀ_ad F⁻ᵀ_cb + λ F⁻ᵀ_ab F⁻ᵀ_cd`
///
/// **PSD projection** ([`Hyperelastic::tangent_psd`]) uses the eigensystem of isotropic
/// energies in terms of the rotation-variant SVD `F = U diag(σ) Vᵀ` (Smith, de Goes & Kim 2019;
/// Teran et al. 2005). With `ψ̂_i = ∂ψ/∂σ_i = μ σ_i + (λ ln J − μ)/σ_i`, the `D²` eigenpairs are
///
/// * `D` *scaling* modes `U diag(z_k) Vᵀ`, `(λ_k, z_k)` the eigenpairs of the `D×D` matrix
///   `∂²ψ/∂σ_i∂σ_j = δ_ij (μ + (μ − λ ln J + λ)/σ_i²) + (1 − δ_ij) λ/(σ_i σ_j)`;
/// * per pair `i < j`, a symmetric mode `U (e_i e_jᵀ + e_j e_iᵀ) Vᵀ / √2` with eigenvalue
///   `(ψ̂_i − ψ̂_j)/(σ_i − σ_j) = μ + (μ − λ ln J)/(σ_i σ_j)` and an antisymmetric (twist) mode
///   `U (e_i e_jᵀ − e_j e_iᵀ) Vᵀ / √2` with eigenvalue
///   `(ψ̂_i + ψ̂_j)/(σ_i + σ_j) = μ + (λ ln J − μ)/(σ_i σ_j)`.
///
/// The closed forms need no division by `σ_i − σ_j`, so repeated singular values are fine.
/// Negative eigenvalues are clamped and the tangent rebuilt from the modes; a test checks this
/// equals a numerical eigen-projection of [`Hyperelastic::tangent`].
///
/// Where `J ≤ 0` the energy is `+∞` (the line-search filter keeps every iterate at `J > 0`),
/// stress and tangent are NaN, and the projected tangent falls back to `μ I`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeoHookean {
    /// Shear modulus μ.
    pub mu: f64,
    /// First Lamé parameter λ.
    pub lambda: f64,
}

impl NeoHookean {
    /// From validated Lamé parameters.
    pub fn new(lame: Lame) -> Self {
        Self {
            mu: lame.mu,
            lambda: lame.lambda,
        }
    }

    /// From Young's modulus and Poisson's ratio (validated, see [`Lame::from_young_poisson`]).
    pub fn from_young_poisson(e: f64, nu: f64) -> Result<Self, FemError> {
        Ok(Self::new(Lame::from_young_poisson(e, nu)?))
    }
}

/// `x − ln(1 + x)` to full relative precision (a series for small `|x|`, where the direct
/// difference cancels).
fn x_minus_ln_1p(x: f64) -> f64 {
    if x.abs() < 1e-2 {
        // Σ_{k≥2} (−1)^k x^k / k, truncated after k = 9 (relative error < 1e-17).
        let mut sum = 0.0;
        let mut p = x * x;
        for k in 2..=9 {
            let term = p / k as f64;
            sum += if k % 2 == 0 { term } else { -term };
            p *= x;
        }
        sum
    } else {
        x - x.ln_1p()
    }
}

impl<const D: usize> Hyperelastic<D> for NeoHookean {
    /// Evaluated in terms of `H = F − I` (exact in floating point for `F` near `I`):
    /// `ψ = μ (tr H − ln J) + ½μ‖H‖² + ½λ (ln J)²` with `J − 1 = tr H + I₂(H) + det H` and
    /// `ln J = ln_1p(J − 1)`. The textbook form `½μ(‖F‖² − D) − μ ln J + …` cancels terms of
    /// size μ at first order, leaving a round-off of ~1e-16 μ per unit volume; for stiff
    /// materials (E = 4e12 in BFEMP §6.4) that swamps the energy decrease a line search must
    /// resolve near convergence. Here the round-off scales with the strain instead.
    fn energy_density(&self, f: &SMatrix<f64, D, D>) -> f64 {
        let h = f - SMatrix::<f64, D, D>::identity();
        let tr = h.trace();
        // J − 1 − tr H: the second- and third-order invariants.
        let higher = if D == 2 {
            h[(0, 0)] * h[(1, 1)] - h[(0, 1)] * h[(1, 0)]
        } else {
            let minors = h[(0, 0)] * h[(1, 1)] - h[(0, 1)] * h[(1, 0)] + h[(0, 0)] * h[(2, 2)]
                - h[(0, 2)] * h[(2, 0)]
                + h[(1, 1)] * h[(2, 2)]
                - h[(1, 2)] * h[(2, 1)];
            minors + linalg::det(&h)
        };
        let jm1 = tr + higher;
        if jm1 <= -1.0 || !jm1.is_finite() {
            return f64::INFINITY;
        }
        let lnj = jm1.ln_1p();
        // tr H − ln J = −(J − 1 − tr H) + ((J − 1) − ln(1 + (J − 1))), both second order.
        let tr_minus_lnj = x_minus_ln_1p(jm1) - higher;
        self.mu * tr_minus_lnj + 0.5 * self.mu * h.norm_squared() + 0.5 * self.lambda * lnj * lnj
    }

    fn first_piola(&self, f: &SMatrix<f64, D, D>) -> SMatrix<f64, D, D> {
        let j = linalg::det(f);
        if j <= 0.0 {
            return SMatrix::from_element(f64::NAN);
        }
        let f_inv_t = linalg::cofactor(f) / j;
        f * self.mu + f_inv_t * (self.lambda * j.ln() - self.mu)
    }

    fn tangent(&self, f: &SMatrix<f64, D, D>) -> Tangent<D> {
        let j = linalg::det(f);
        let mut t = Tangent::zeros();
        if j <= 0.0 {
            t.0.fill(f64::NAN);
            return t;
        }
        let fit = linalg::cofactor(f) / j;
        let c1 = self.mu - self.lambda * j.ln();
        for a in 0..D {
            for b in 0..D {
                for c in 0..D {
                    for d in 0..D {
                        let mut v = c1 * fit[(a, d)] * fit[(c, b)]
                            + self.lambda * fit[(a, b)] * fit[(c, d)];
                        if a == c && b == d {
                            v += self.mu;
                        }
                        t.0[(a * D + b, c * D + d)] = v;
                    }
                }
            }
        }
        t
    }

    fn tangent_psd(&self, f: &SMatrix<f64, D, D>) -> Tangent<D> {
        let (u, s, v) = linalg::svd_rv(f);
        let j: f64 = s.iter().product();
        let mut t = Tangent::zeros();
        if j <= 0.0 || !j.is_finite() {
            for k in 0..D * D {
                t.0[(k, k)] = self.mu;
            }
            return t;
        }
        let (mu, lambda) = (self.mu, self.lambda);
        let lnj = j.ln();
        // Scaling modes.
        let hs = SMatrix::<f64, D, D>::from_fn(|i, k| {
            if i == k {
                mu + (mu - lambda * lnj + lambda) / (s[i] * s[i])
            } else {
                lambda / (s[i] * s[k])
            }
        });
        let (vals, vecs) = linalg::sym_eigen(&hs);
        let vt = v.transpose();
        for k in 0..D {
            if vals[k] > 0.0 {
                let z: SVector<f64, D> = vecs.column(k).into_owned();
                let q = u * SMatrix::<f64, D, D>::from_diagonal(&z) * vt;
                t.add_outer(&q, vals[k]);
            }
        }
        // Symmetric and twist modes for each pair.
        let r = std::f64::consts::FRAC_1_SQRT_2;
        for i in 0..D {
            for k in i + 1..D {
                let ss = s[i] * s[k];
                let sym = mu + (mu - lambda * lnj) / ss;
                let twist = mu + (lambda * lnj - mu) / ss;
                // U (e_i e_kᵀ ± e_k e_iᵀ) Vᵀ = u_i v_kᵀ ± u_k v_iᵀ.
                let ui = u.column(i);
                let uk = u.column(k);
                let vi = v.column(i);
                let vk = v.column(k);
                if sym > 0.0 {
                    let q = (ui * vk.transpose() + uk * vi.transpose()) * r;
                    t.add_outer(&q, sym);
                }
                if twist > 0.0 {
                    let q = (ui * vk.transpose() - uk * vi.transpose()) * r;
                    t.add_outer(&q, twist);
                }
            }
        }
        t
    }
}
