//! The material tangent `∂P/∂F` and the chain rule from `F` to the vertices (or grid nodes) that
//! define it.
//!
//! # Convention
//! `F` is flattened row-major: entry `(a, b)` of `F` is component `a·D + b`. A [`Tangent`]
//! holds the `D²×D²` matrix `A[(a·D + b, c·D + d)] = ∂P_ab / ∂F_cd` in the top-left block of a
//! 9×9 matrix (so one type serves D = 2 and 3).
//!
//! # Linear deformation maps
//! Both a linear FEM element and an MPM particle have a deformation gradient that is linear in
//! some positions `x_i`: `F = Σ_i x_i g_iᵀ` with fixed vectors `g_i` (element: the rows of
//! `B_e⁻¹` and minus their sum, eq. 24; particle: `F_pⁿᵀ ∇w_ip`, eq. 25). For an energy
//! `V ψ(F)` the gradient and Hessian with respect to the `x_i` are
//!
//! ```text
//! ∂/∂x_i = V P g_i                    H_ij[a][c] = V Σ_bd A[(a·D+b, c·D+d)] g_i[b] g_j[d]
//! ```
//!
//! ([`chain_gradient`], [`chain_hessian`]). If `A` is positive semi-definite, so is `H` — which is
//! why projecting the small `D²×D²` tangent is enough to make an element's or a particle's
//! Hessian PSD (BFEMP §5, "cheap PSD projection").

use nalgebra::{SMatrix, SVector};

use crate::linalg;

/// `∂P/∂F` as a `D²×D²` matrix (see the module documentation for the layout).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tangent<const D: usize>(pub SMatrix<f64, 9, 9>);

impl<const D: usize> Default for Tangent<D> {
    fn default() -> Self {
        Self::zeros()
    }
}

impl<const D: usize> Tangent<D> {
    /// The zero tangent.
    #[inline]
    pub fn zeros() -> Self {
        Self(SMatrix::zeros())
    }

    /// `∂P_ab / ∂F_cd`.
    #[inline]
    pub fn get(&self, a: usize, b: usize, c: usize, d: usize) -> f64 {
        self.0[(a * D + b, c * D + d)]
    }

    /// Add `v` to `∂P_ab / ∂F_cd`.
    #[inline]
    pub fn add(&mut self, a: usize, b: usize, c: usize, d: usize, v: f64) {
        self.0[(a * D + b, c * D + d)] += v;
    }

    /// `A : dF`, the change of `P` for a change `dF` of `F`.
    pub fn contract(&self, df: &SMatrix<f64, D, D>) -> SMatrix<f64, D, D> {
        SMatrix::from_fn(|a, b| {
            let mut s = 0.0;
            for c in 0..D {
                for d in 0..D {
                    s += self.get(a, b, c, d) * df[(c, d)];
                }
            }
            s
        })
    }

    /// Add `s · vec(Q) vec(Q)ᵀ` (a rank-one term, used to rebuild a tangent from its modes).
    #[inline]
    pub fn add_outer(&mut self, q: &SMatrix<f64, D, D>, s: f64) {
        for a in 0..D {
            for b in 0..D {
                let qab = q[(a, b)] * s;
                for c in 0..D {
                    for d in 0..D {
                        self.0[(a * D + b, c * D + d)] += qab * q[(c, d)];
                    }
                }
            }
        }
    }

    /// Project onto the positive semi-definite cone by a symmetric eigen-decomposition of the
    /// `D²×D²` block (negative eigenvalues set to zero). Material-independent; the analytic
    /// projections of the materials are faster and agree with this one (tested).
    pub fn project_psd_eigen(&self) -> Self {
        let mut m = self.0;
        linalg::project_psd_block(&mut m, D * D);
        Self(m)
    }

    /// Smallest eigenvalue of the (symmetrised) `D²×D²` block.
    pub fn min_eigenvalue(&self) -> f64 {
        let mut m = self.0;
        m = (m + m.transpose()) * 0.5;
        linalg::min_eigenvalue_block(&m, D * D)
    }

    /// Largest absolute entry (for scaled tolerances).
    pub fn amax(&self) -> f64 {
        self.0.amax()
    }
}

/// Gradient of `scale · ψ(F)` with respect to the `x_i` of `F = Σ_i x_i g_iᵀ`:
/// `out[i] = scale · P g_i`.
#[inline]
pub fn chain_gradient<const D: usize>(
    p: &SMatrix<f64, D, D>,
    g: &[SVector<f64, D>],
    scale: f64,
    out: &mut [SVector<f64, D>],
) {
    for (o, gi) in out.iter_mut().zip(g) {
        *o = (p * gi) * scale;
    }
}

/// The blocks `H_ij`, `i ≤ j`, of `scale · ψ(F)` with respect to the `x_i` of
/// `F = Σ_i x_i g_iᵀ`, handed to `f(i, j, H_ij)` (the tangent is symmetric, so `H_ji = H_ijᵀ`).
#[inline]
fn chain_hessian_upper_blocks<const D: usize>(
    t: &Tangent<D>,
    g: &[SVector<f64, D>],
    scale: f64,
    mut f: impl FnMut(usize, usize, SMatrix<f64, D, D>),
) {
    // T_j[(a·D + b), c] = Σ_d A[(a·D + b, c·D + d)] g_j[d], then H_ij[a][c] = Σ_b g_i[b] T_j.
    let mut tj = [[0.0f64; 3]; 9];
    for (j, gj) in g.iter().enumerate() {
        for ab in 0..D * D {
            for c in 0..D {
                let mut s = 0.0;
                for d in 0..D {
                    s += t.0[(ab, c * D + d)] * gj[d];
                }
                tj[ab][c] = s * scale;
            }
        }
        for (i, gi) in g.iter().enumerate().take(j + 1) {
            let mut h = SMatrix::<f64, D, D>::zeros();
            for a in 0..D {
                for c in 0..D {
                    let mut s = 0.0;
                    for b in 0..D {
                        s += gi[b] * tj[a * D + b][c];
                    }
                    h[(a, c)] = s;
                }
            }
            f(i, j, h);
        }
    }
}

/// Like [`chain_hessian`], but **adds** the blocks `i ≤ j` into `out` (the upper block
/// triangle; `H_ji = H_ijᵀ` is left to the caller) — for summing the Hessians of many
/// particles that share one stencil (same `n` nodes) before scattering them once.
pub fn chain_hessian_add_upper<const D: usize>(
    t: &Tangent<D>,
    g: &[SVector<f64, D>],
    scale: f64,
    out: &mut [SMatrix<f64, D, D>],
) {
    let n = g.len();
    debug_assert!(out.len() >= n * n);
    chain_hessian_upper_blocks(t, g, scale, |i, j, h| out[i * n + j] += h);
}

/// Hessian blocks of `scale · ψ(F)` with respect to the `x_i` of `F = Σ_i x_i g_iᵀ`, row-major
/// `n×n` blocks (`out[i·n + j]` is `∂²/∂x_i∂x_j`, a `D×D` matrix), `n = g.len()`. The tangent
/// must be symmetric (it is the Hessian of `ψ`), which makes `H_ji = H_ijᵀ`.
pub fn chain_hessian<const D: usize>(
    t: &Tangent<D>,
    g: &[SVector<f64, D>],
    scale: f64,
    out: &mut [SMatrix<f64, D, D>],
) {
    let n = g.len();
    debug_assert!(out.len() >= n * n);
    chain_hessian_upper_blocks(t, g, scale, |i, j, h| {
        out[i * n + j] = h;
        out[j * n + i] = h.transpose();
    });
}
