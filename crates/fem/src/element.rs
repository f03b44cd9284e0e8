//! Linear simplex elements: rest shape, deformation gradient (BFEMP eq. 24), lumped masses.
//!
//! With rest vertices `X_0..X_D`, `B = [X_1 − X_0, …, X_D − X_0]` and current vertices `x_i`,
//! `F = T B⁻¹` with `T = [x_1 − x_0, …]`. Written as `F = Σ_i x_i g_iᵀ`, `g_k` (k ≥ 1) is row
//! `k − 1` of `B⁻¹` and `g_0 = −Σ_k g_k`; `∂F_ab/∂x_i,c = δ_ac g_i[b]`, constant per element —
//! the linear map [`crate::chain_gradient`] and [`crate::chain_hessian`] chain through.

use nalgebra::{SMatrix, SVector};

use crate::{FemError, Mesh, linalg, material::check_density};

/// Rest-shape data of one element.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Element<const D: usize> {
    /// The vectors `g_i` of `F = Σ_i x_i g_iᵀ` (first `D + 1` used).
    pub g: [SVector<f64, D>; 4],
    /// Rest volume (area in 2D).
    pub volume: f64,
}

impl<const D: usize> Element<D> {
    /// From the `D + 1` rest positions; `index` names the element in errors. Degenerate or
    /// inverted rest shapes are errors with the signed volume.
    pub fn new(rest: &[SVector<f64, D>], index: usize) -> Result<Self, FemError> {
        let b = SMatrix::<f64, D, D>::from_fn(|r, k| rest[k + 1][r] - rest[0][r]);
        let detb = linalg::det(&b);
        let volume = detb / if D == 2 { 2.0 } else { 6.0 };
        let mut l: f64 = 0.0;
        for i in 0..=D {
            for j in i + 1..=D {
                l = l.max((rest[i] - rest[j]).norm());
            }
        }
        if !(volume.abs() > crate::mesh::DEGENERATE * l.powi(D as i32)) {
            return Err(FemError::DegenerateCell {
                cell: index,
                volume,
                reason: "has (near) zero rest volume",
            });
        }
        if volume < 0.0 {
            return Err(FemError::InvertedCell {
                cell: index,
                volume,
            });
        }
        let binv = linalg::inverse(&b).ok_or(FemError::DegenerateCell {
            cell: index,
            volume,
            reason: "has a singular rest shape",
        })?;
        let mut g = [SVector::<f64, D>::zeros(); 4];
        for k in 0..D {
            g[k + 1] = binv.row(k).transpose();
            g[0] -= g[k + 1];
        }
        Ok(Self { g, volume })
    }

    /// The `D + 1` vectors `g_i`.
    #[inline]
    pub fn gradients(&self) -> &[SVector<f64, D>] {
        &self.g[..D + 1]
    }

    /// `F = Σ_k (x_k − x_0) g_kᵀ` for the element's current vertex positions.
    #[inline]
    pub fn deformation_gradient(&self, x: &[SVector<f64, D>]) -> SMatrix<f64, D, D> {
        let mut f = SMatrix::<f64, D, D>::zeros();
        for k in 1..=D {
            f += (x[k] - x[0]) * self.g[k].transpose();
        }
        f
    }

    /// `T(x) = [x_1 − x_0, …, x_D − x_0]` (so `F = T B⁻¹` and `det F ∝ det T`).
    #[inline]
    pub fn edge_matrix(x: &[SVector<f64, D>]) -> SMatrix<f64, D, D> {
        SMatrix::from_fn(|r, k| x[k + 1][r] - x[0][r])
    }
}

/// Lumped vertex masses `m_i = Σ_{e ∋ i} ρ V_e / (D + 1)` for density `rho` (kg/m³ in 3D,
/// kg/m² in 2D).
pub fn lumped_masses<const D: usize>(mesh: &Mesh<D>, rho: f64) -> Result<Vec<f64>, FemError> {
    let rho = check_density(rho)?;
    let mut m = vec![0.0; mesh.num_vertices()];
    for e in 0..mesh.num_cells() {
        let share = rho * mesh.cell_volume(e) / (D + 1) as f64;
        for &v in mesh.cell(e) {
            m[v] += share;
        }
    }
    Ok(m)
}
