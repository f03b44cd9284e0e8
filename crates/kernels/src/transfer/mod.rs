//! Particle–grid transfers over slices of particle data (PIC, APIC, FLIP; BFEMP Tables 1–3,
//! augury eqs. 10–20). See [`p2g`] and [`g2p`] for the formulas.

mod check;
pub mod g2p;
pub mod p2g;
mod window;

pub use g2p::{advect, g2p_apic, g2p_flip, g2p_pic, interpolate};
pub use p2g::{normalise, p2g_apic, p2g_pic, p2g_vector};
