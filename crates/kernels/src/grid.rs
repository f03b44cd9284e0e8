//! The background grid: spacing, origin and kernel. Node `i ∈ ℤ^D` sits at `origin + i h`.
//!
//! A [`Grid`] holds no node data. Which nodes exist is decided per step by the particles: see
//! [`crate::Stencils`], built with [`Grid::stencils`], which numbers the *active* nodes (those
//! some particle's stencil touches) compactly. Memory therefore grows with the active nodes,
//! never with the bounding box of the bodies.

use nalgebra::SVector;

use crate::{Kernel, KernelError, Stencils};

/// A uniform background grid of B-spline nodes in `D` dimensions (2 or 3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid<const D: usize> {
    h: f64,
    origin: SVector<f64, D>,
    kernel: Kernel,
}

impl<const D: usize> Grid<D> {
    /// Largest node index magnitude per axis the grid addresses. Positions further than this
    /// (in cells) from the origin are rejected with [`KernelError::OutOfRange`]. The limit comes
    /// from packing block coordinates into 64-bit sort keys; it is ±2²⁹ cells in 2D and ±2¹⁹ in
    /// 3D (with h = 1 mm: ±537 km and ±524 m).
    pub const MAX_CELLS: i64 = if D == 2 { 1 << 29 } else { 1 << 19 };

    /// A grid with spacing `h`, node 0 at `origin`, and the given kernel.
    pub fn new(h: f64, origin: SVector<f64, D>, kernel: Kernel) -> Result<Self, KernelError> {
        const { assert!(D == 2 || D == 3, "femp-kernels supports D = 2 and D = 3") };
        if !(h > 0.0 && h.is_finite()) {
            return Err(KernelError::BadSpacing { h });
        }
        if let Some(axis) = (0..D).find(|&a| !origin[a].is_finite()) {
            return Err(KernelError::BadOrigin {
                axis,
                value: origin[axis],
            });
        }
        Ok(Self { h, origin, kernel })
    }

    /// Grid spacing.
    #[inline]
    pub fn h(&self) -> f64 {
        self.h
    }

    /// Position of node 0.
    #[inline]
    pub fn origin(&self) -> &SVector<f64, D> {
        &self.origin
    }

    /// The interpolation kernel.
    #[inline]
    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    /// `D_p` of the kernel on this grid (the scalar `c h²`; the tensor is that times `I`).
    #[inline]
    pub fn d_p(&self) -> f64 {
        self.kernel.d_p(self.h)
    }

    /// World position of the node with integer index `index`.
    #[inline]
    pub fn node_position(&self, index: &[i64; D]) -> SVector<f64, D> {
        SVector::from_fn(|a, _| self.origin[a] + index[a] as f64 * self.h)
    }

    /// Build the stencils of a set of particles (and the active-node numbering they imply).
    pub fn stencils(&self, positions: &[SVector<f64, D>]) -> Result<Stencils<D>, KernelError> {
        let mut s = Stencils::empty(*self);
        s.rebuild(positions)?;
        Ok(s)
    }
}
