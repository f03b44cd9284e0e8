//! Particle-to-grid transfers: mass and momentum, PIC and APIC.
//!
//! * [`p2g_pic`]: `m_i = Σ_p w_ip m_p`, `(mv)_i = Σ_p w_ip m_p v_p` (BFEMP Table 2; augury
//!   eqs. 10–11; FLIP uses the same, Table 3).
//! * [`p2g_apic`]: `(mv)_i = Σ_p w_ip m_p (v_p + B_p D_p⁻¹ (x_i − x_p))` (BFEMP Table 1;
//!   augury eq. 17), `D_p = c h² I` for both kernels ([`crate::Kernel::d_factor`]).
//! * [`p2g_vector`]: `Σ_p w_ip m_p q_p` for any other vector quantity (e.g. Newmark
//!   accelerations), to be divided by the mass like momentum.
//! * [`normalise`]: `v_i = (mv)_i / m_i`.
//!
//! The grid arrays are indexed by the compact node ids of the [`Stencils`] and must have length
//! `stencils.num_nodes()`; they are overwritten. Results do not depend on the number of threads
//! (see [`crate::stencil`]).

use std::ops::AddAssign;

use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use super::check;
use super::window::{Layout, NodeOut, ScatterOp, Weights, scatter};
use crate::error::check_len;
use crate::stencil::prefetch;
use crate::{Kernel, KernelError, Stencils};

#[derive(Clone, Copy)]
struct MassMom<const D: usize> {
    m: f64,
    mv: SVector<f64, D>,
}

impl<const D: usize> AddAssign for MassMom<D> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        self.m += o.m;
        self.mv += o.mv;
    }
}

impl<const D: usize> MassMom<D> {
    const ZERO: Self = Self {
        m: 0.0,
        mv: SVector::from_array_storage(nalgebra::ArrayStorage([[0.0; D]; 1])),
    };
}

fn prepare_grid<const D: usize>(
    st: &Stencils<D>,
    grid_mass: &mut [f64],
    grid_momentum: &mut [SVector<f64, D>],
) -> Result<(), KernelError> {
    check_len("grid masses", st.num_nodes(), grid_mass.len())?;
    check_len("grid momenta", st.num_nodes(), grid_momentum.len())?;
    grid_mass
        .par_iter_mut()
        .with_min_len(8192)
        .for_each(|m| *m = 0.0);
    grid_momentum
        .par_iter_mut()
        .with_min_len(8192)
        .for_each(|m| *m = SVector::zeros());
    Ok(())
}

/// PIC particle-to-grid: grid mass and momentum.
pub fn p2g_pic<const D: usize>(
    st: &Stencils<D>,
    mass: &[f64],
    velocity: &[SVector<f64, D>],
    grid_mass: &mut [f64],
    grid_momentum: &mut [SVector<f64, D>],
) -> Result<(), KernelError> {
    let n = st.num_particles();
    check::masses(mass, n)?;
    check::vectors("particle velocities", velocity, n)?;
    prepare_grid(st, grid_mass, grid_momentum)?;
    match st.grid().kernel() {
        Kernel::Quadratic => pic::<D, 3>(st, mass, velocity, grid_mass, grid_momentum),
        Kernel::Quadratic4 => pic::<D, 4>(st, mass, velocity, grid_mass, grid_momentum),
    }
    Ok(())
}

fn pic<const D: usize, const N: usize>(
    st: &Stencils<D>,
    mass: &[f64],
    velocity: &[SVector<f64, D>],
    grid_mass: &mut [f64],
    grid_momentum: &mut [SVector<f64, D>],
) {
    struct Op<'a, const D: usize> {
        mass: &'a [f64],
        velocity: &'a [SVector<f64, D>],
        gm: NodeOut<'a, f64>,
        gp: NodeOut<'a, SVector<f64, D>>,
    }
    impl<const D: usize> ScatterOp<D> for Op<'_, D> {
        type Acc = MassMom<D>;
        fn zero(&self) -> MassMom<D> {
            MassMom::ZERO
        }
        #[inline(always)]
        fn particle<const N: usize>(
            &self,
            p: usize,
            _: &[f64; D],
            w: &Weights<D>,
            layout: &Layout<'_, D>,
            win: &mut [MassMom<D>],
        ) {
            let m = self.mass[p];
            let mv = self.velocity[p] * m;
            w.for_each::<N>(&layout.stride, |o, wk, _| {
                win[o] += MassMom {
                    m: wk * m,
                    mv: mv * wk,
                };
            });
        }
        #[inline(always)]
        fn flush(&self, i: usize, t: &MassMom<D>) {
            // SAFETY: node `i` is in this group's window, flushed by no other task (`scatter`).
            unsafe {
                *self.gm.at(i) += t.m;
                *self.gp.at(i) += t.mv;
            }
        }
        #[inline(always)]
        fn prefetch(&self, p: usize) {
            prefetch(self.mass, p);
            prefetch(self.velocity, p);
        }
    }
    let op = Op {
        mass,
        velocity,
        gm: NodeOut::new(grid_mass),
        gp: NodeOut::new(grid_momentum),
    };
    scatter::<D, N, _>(st, &op);
}

/// APIC particle-to-grid: grid mass and momentum including the affine term
/// `B_p D_p⁻¹ (x_i − x_p)`.
pub fn p2g_apic<const D: usize>(
    st: &Stencils<D>,
    mass: &[f64],
    velocity: &[SVector<f64, D>],
    b: &[SMatrix<f64, D, D>],
    grid_mass: &mut [f64],
    grid_momentum: &mut [SVector<f64, D>],
) -> Result<(), KernelError> {
    let n = st.num_particles();
    check::masses(mass, n)?;
    check::vectors("particle velocities", velocity, n)?;
    check::matrices("particle APIC matrices B", b, n)?;
    prepare_grid(st, grid_mass, grid_momentum)?;
    match st.grid().kernel() {
        Kernel::Quadratic => apic::<D, 3>(st, mass, velocity, b, grid_mass, grid_momentum),
        Kernel::Quadratic4 => apic::<D, 4>(st, mass, velocity, b, grid_mass, grid_momentum),
    }
    Ok(())
}

fn apic<const D: usize, const N: usize>(
    st: &Stencils<D>,
    mass: &[f64],
    velocity: &[SVector<f64, D>],
    b: &[SMatrix<f64, D, D>],
    grid_mass: &mut [f64],
    grid_momentum: &mut [SVector<f64, D>],
) {
    // w m (v + B D⁻¹ (x_i − x_p)) with D = c h² I and x_i − x_p = h (k − f):
    //   = w (a0 + A k),  A = m B / (c h),  a0 = m v − A f.
    struct Op<'a, const D: usize> {
        mass: &'a [f64],
        velocity: &'a [SVector<f64, D>],
        b: &'a [SMatrix<f64, D, D>],
        scale: f64,
        gm: NodeOut<'a, f64>,
        gp: NodeOut<'a, SVector<f64, D>>,
    }
    impl<const D: usize> ScatterOp<D> for Op<'_, D> {
        type Acc = MassMom<D>;
        fn zero(&self) -> MassMom<D> {
            MassMom::ZERO
        }
        #[inline(always)]
        fn particle<const N: usize>(
            &self,
            p: usize,
            frac: &[f64; D],
            w: &Weights<D>,
            layout: &Layout<'_, D>,
            win: &mut [MassMom<D>],
        ) {
            let m = self.mass[p];
            let a = self.b[p] * (m * self.scale);
            let f = SVector::<f64, D>::from_column_slice(frac);
            let a0 = self.velocity[p] * m - a * f;
            w.for_each_affine::<N>(&layout.stride, &a0, &a, |o, wk, val| {
                win[o] += MassMom {
                    m: wk * m,
                    mv: val * wk,
                };
            });
        }
        #[inline(always)]
        fn flush(&self, i: usize, t: &MassMom<D>) {
            // SAFETY: node `i` is in this group's window, flushed by no other task (`scatter`).
            unsafe {
                *self.gm.at(i) += t.m;
                *self.gp.at(i) += t.mv;
            }
        }
        #[inline(always)]
        fn prefetch(&self, p: usize) {
            prefetch(self.mass, p);
            prefetch(self.velocity, p);
            prefetch(self.b, p);
        }
    }
    let h = st.grid().h();
    let op = Op {
        mass,
        velocity,
        b,
        scale: 1.0 / (st.grid().kernel().d_factor() * h),
        gm: NodeOut::new(grid_mass),
        gp: NodeOut::new(grid_momentum),
    };
    scatter::<D, N, _>(st, &op);
}

/// Mass-weighted particle-to-grid of another vector quantity: `out_i = Σ_p w_ip m_p q_p`.
/// Divide by the grid mass (e.g. with [`normalise`]) to get the grid field.
pub fn p2g_vector<const D: usize>(
    st: &Stencils<D>,
    mass: &[f64],
    q: &[SVector<f64, D>],
    out: &mut [SVector<f64, D>],
) -> Result<(), KernelError> {
    let n = st.num_particles();
    check::masses(mass, n)?;
    check::vectors("particle vector quantity", q, n)?;
    check_len("grid output", st.num_nodes(), out.len())?;
    out.par_iter_mut()
        .with_min_len(8192)
        .for_each(|m| *m = SVector::zeros());
    match st.grid().kernel() {
        Kernel::Quadratic => vector::<D, 3>(st, mass, q, out),
        Kernel::Quadratic4 => vector::<D, 4>(st, mass, q, out),
    }
    Ok(())
}

fn vector<const D: usize, const N: usize>(
    st: &Stencils<D>,
    mass: &[f64],
    q: &[SVector<f64, D>],
    out: &mut [SVector<f64, D>],
) {
    struct Op<'a, const D: usize> {
        mass: &'a [f64],
        q: &'a [SVector<f64, D>],
        out: NodeOut<'a, SVector<f64, D>>,
    }
    impl<const D: usize> ScatterOp<D> for Op<'_, D> {
        type Acc = SVector<f64, D>;
        fn zero(&self) -> SVector<f64, D> {
            SVector::zeros()
        }
        #[inline(always)]
        fn particle<const N: usize>(
            &self,
            p: usize,
            _: &[f64; D],
            w: &Weights<D>,
            layout: &Layout<'_, D>,
            win: &mut [SVector<f64, D>],
        ) {
            let mq = self.q[p] * self.mass[p];
            w.for_each::<N>(&layout.stride, |o, wk, _| win[o] += mq * wk);
        }
        #[inline(always)]
        fn flush(&self, i: usize, t: &SVector<f64, D>) {
            // SAFETY: node `i` is in this group's window, flushed by no other task (`scatter`).
            unsafe { *self.out.at(i) += *t };
        }
        #[inline(always)]
        fn prefetch(&self, p: usize) {
            prefetch(self.mass, p);
            prefetch(self.q, p);
        }
    }
    let op = Op {
        mass,
        q,
        out: NodeOut::new(out),
    };
    scatter::<D, N, _>(st, &op);
}

/// Divide momenta by masses in place, giving grid velocities. Nodes with zero mass (a particle
/// exactly on the edge of a stencil gives a weight of exactly zero) get zero velocity.
pub fn normalise<const D: usize>(
    grid_mass: &[f64],
    grid_momentum: &mut [SVector<f64, D>],
) -> Result<(), KernelError> {
    check_len("grid momenta", grid_mass.len(), grid_momentum.len())?;
    grid_momentum
        .par_iter_mut()
        .zip(grid_mass.par_iter())
        .with_min_len(8192)
        .for_each(|(mv, &m)| {
            if m > 0.0 {
                *mv /= m;
            } else {
                *mv = SVector::zeros();
            }
        });
    Ok(())
}
