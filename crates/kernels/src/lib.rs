//! # femp-kernels
//!
//! Quadratic B-spline kernels on a sparse background grid, and the particle–grid transfers of
//! MPM and of APIC augury contact, in 2D and 3D from one source (`const D: usize`).
//!
//! * [`Kernel`] — the standard 3-node quadratic B-spline (BFEMP) and the 4-node variant of the
//!   augury paper's appendix B, with `D_p` (¼h²I and ½h²I).
//! * [`Grid`] — spacing, origin, kernel. [`Grid::stencils`] builds the [`Stencils`] of a set of
//!   particles: each particle's nodes, weights and weight gradients, and a compact numbering of
//!   the *active* nodes (the only grid storage there is).
//! * [`transfer`] — P2G (PIC, APIC, any vector quantity), grid normalisation, G2P (PIC, APIC
//!   static and moving-grid, FLIP), advection of positions and deformation gradients.
//! * [`ParticleStencil`] — the linear maps `u ↦ x_p(u)` and `u ↦ F_p(u)` and their Jacobians,
//!   which an implicit solver chains contact and elastic derivatives through (BFEMP eq. 29).
//!
//! Everything is parallel with rayon (use the caller's thread pool) and deterministic: results
//! do not depend on the number of threads.
//!
//! ```
//! use femp_kernels::{Grid, Kernel, transfer};
//! use nalgebra::{Matrix2, Vector2};
//!
//! let grid = Grid::<2>::new(0.1, Vector2::zeros(), Kernel::Quadratic).unwrap();
//! let x = vec![Vector2::new(0.31, 0.52), Vector2::new(0.36, 0.50)];
//! let m = vec![1.0, 2.0];
//! let v = vec![Vector2::new(1.0, 0.0), Vector2::new(-1.0, 0.5)];
//! let b = vec![Matrix2::zeros(); 2];
//! let st = grid.stencils(&x).unwrap();
//! let mut gm = vec![0.0; st.num_nodes()];
//! let mut gv = vec![Vector2::zeros(); st.num_nodes()];
//! transfer::p2g_apic(&st, &m, &v, &b, &mut gm, &mut gv).unwrap();
//! assert!((gm.iter().sum::<f64>() - 3.0).abs() < 1e-12);
//! transfer::normalise(&gm, &mut gv).unwrap();
//! let (mut v2, mut b2) = (v.clone(), b.clone());
//! transfer::g2p_apic(&st, &gv, None, &mut v2, &mut b2).unwrap();
//! ```

mod error;
mod grid;
mod par;
mod sort;
pub mod spline;
pub mod stencil;
pub mod transfer;

pub use error::KernelError;
pub use grid::Grid;
pub use spline::{AxisWeights, Kernel};
pub use stencil::{NodeRows, ParticleStencil, StencilValues, Stencils};
