//! Particle–grid transfers over slices of particle data (PIC, APIC, FLIP; BFEMP Tables 1–3,
//! augury eqs. 10–20). See [`p2g`] and [`g2p`] for the formulas.

mod check;
pub mod g2p;
pub mod p2g;
mod window;

pub use g2p::{advect, g2p_apic, g2p_flip, g2p_pic, interpolate};
pub use p2g::{normalise, p2g_apic, p2g_pic, p2g_vector};

use nalgebra::{SMatrix, Vector3};

/// `ε : Bᵀ`, the angular momentum an APIC matrix `B_p` carries per unit mass (z only in 2D):
/// a particle's angular momentum is `m_p (x_p × v_p + ε : B_pᵀ)`, the quantity APIC transfers
/// conserve.
pub fn apic_spin<const D: usize>(b: &SMatrix<f64, D, D>) -> Vector3<f64> {
    if D == 2 {
        Vector3::new(0.0, 0.0, b[(1, 0)] - b[(0, 1)])
    } else {
        Vector3::new(
            b[(D - 1, 1)] - b[(1, D - 1)],
            b[(0, D - 1)] - b[(D - 1, 0)],
            b[(1, 0)] - b[(0, 1)],
        )
    }
}
