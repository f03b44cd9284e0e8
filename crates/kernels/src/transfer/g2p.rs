//! Grid-to-particle transfers: PIC, APIC, FLIP, and advection of positions and deformation
//! gradients.
//!
//! * [`interpolate`] / [`g2p_pic`]: `v_p = Σ_i w_ip v_i` (BFEMP Table 2; augury eq. 12/19).
//!   BFEMP's friction uses exactly this (grid velocity interpolated at the particle, §4.3).
//! * [`g2p_apic`]: `v_p` as above and
//!   `B_p = ½ Σ_i w_ip [ṽ_i (d_i + e_i)ᵀ + (d_i − e_i) ṽ_iᵀ]` with `d_i = x_iⁿ − x_pⁿ` and
//!   `e_i = x̃_i − x_p^{n+1}` (BFEMP Table 1). Without grid motion (`e = d`) this is augury
//!   eq. 20, `B_p = Σ_i w_ip v_i (x_i − x_p)ᵀ`. With grid displacements `u_i = x̃_i − x_i` and
//!   `ū = Σ_i w_ip u_i` it expands to `Σ_i w_ip v_i d_iᵀ + ½ Σ_i w_ip (v_i u_iᵀ − u_i v_iᵀ)
//!   − ½ (v_p ūᵀ − ū v_pᵀ)`, the form computed here; it makes the particles' angular momentum
//!   at their new positions equal the grid's, `Σ_i m_i x̃_i × v_i`, exactly.
//! * [`g2p_flip`]: `v_p ← (1 − α) Σ w v_i + α (v_p + Σ w (v_i − v_iⁿ))`, α = 1 pure FLIP
//!   (BFEMP Table 3).
//! * [`advect`]: `x_p ← x_p + Σ_i w_ip u_i` (= `Σ_i w_ip x̃_i` by linear completeness) and
//!   `F_p ← (I + Σ_i u_i ∇w_ipᵀ) F_p` (= `Σ_i x̃_i ∇w_ipᵀ F_p`, eq. 25).
//!
//! Grid inputs have length `stencils.num_nodes()`, particle outputs `num_particles()`.

use nalgebra::{SMatrix, SVector};

use super::check;
use super::window::{GatherOp, Layout, ParticleOut, Weights, gather};
use crate::error::check_len;
use crate::{Kernel, KernelError, Stencils};

macro_rules! dispatch {
    ($st:expr, $f:ident :: <$d:ident> ( $($arg:expr),* )) => {
        match $st.grid().kernel() {
            Kernel::Quadratic => $f::<$d, 3>($($arg),*),
            Kernel::Quadratic4 => $f::<$d, 4>($($arg),*),
        }
    };
}

/// Interpolate a grid vector field at the particles: `out_p = Σ_i w_ip q_i`.
pub fn interpolate<const D: usize>(
    st: &Stencils<D>,
    grid_q: &[SVector<f64, D>],
    out: &mut [SVector<f64, D>],
) -> Result<(), KernelError> {
    check_len("grid field", st.num_nodes(), grid_q.len())?;
    check_len("particle output", st.num_particles(), out.len())?;
    dispatch!(st, interp::<D>(st, grid_q, out));
    Ok(())
}

fn interp<const D: usize, const N: usize>(
    st: &Stencils<D>,
    grid_q: &[SVector<f64, D>],
    out: &mut [SVector<f64, D>],
) {
    struct Op<'a, const D: usize> {
        grid: &'a [SVector<f64, D>],
        out: ParticleOut<'a, SVector<f64, D>>,
    }
    impl<const D: usize> GatherOp<D> for Op<'_, D> {
        type Node = SVector<f64, D>;
        fn zero(&self) -> Self::Node {
            SVector::zeros()
        }
        #[inline(always)]
        fn fetch(&self, i: usize) -> Self::Node {
            self.grid[i]
        }
        #[inline(always)]
        fn particle<const N: usize>(
            &self,
            p: usize,
            _: &[f64; D],
            w: &Weights<D>,
            layout: &Layout<'_, D>,
            win: &[Self::Node],
        ) {
            let mut v = SVector::<f64, D>::zeros();
            w.for_each::<N>(&layout.stride, |o, wk, _| v += win[o] * wk);
            // SAFETY: `p` is the particle this call was given; no other task writes it (`gather`).
            unsafe { *self.out.at(p) = v };
        }
        #[inline(always)]
        fn prefetch(&self, p: usize) {
            self.out.prefetch(p);
        }
    }
    gather::<D, N, _>(
        st,
        &Op {
            grid: grid_q,
            out: ParticleOut::new(out),
        },
    );
}

/// PIC grid-to-particle: `v_p = Σ_i w_ip v_i`.
pub fn g2p_pic<const D: usize>(
    st: &Stencils<D>,
    grid_velocity: &[SVector<f64, D>],
    velocity: &mut [SVector<f64, D>],
) -> Result<(), KernelError> {
    interpolate(st, grid_velocity, velocity)
}

/// APIC grid-to-particle: new `v_p` and `B_p`. Pass the grid displacements of the step
/// (`u_i = x̃_i − x_i`) when the grid moved (implicit MPM, BFEMP Table 1), or `None` for the
/// static form (augury eq. 19–20).
pub fn g2p_apic<const D: usize>(
    st: &Stencils<D>,
    grid_velocity: &[SVector<f64, D>],
    grid_displacement: Option<&[SVector<f64, D>]>,
    velocity: &mut [SVector<f64, D>],
    b: &mut [SMatrix<f64, D, D>],
) -> Result<(), KernelError> {
    let n = st.num_particles();
    check_len("grid velocities", st.num_nodes(), grid_velocity.len())?;
    check_len("particle velocities", n, velocity.len())?;
    check_len("particle APIC matrices B", n, b.len())?;
    match grid_displacement {
        None => dispatch!(st, apic_static::<D>(st, grid_velocity, velocity, b)),
        Some(u) => {
            check_len("grid displacements", st.num_nodes(), u.len())?;
            dispatch!(st, apic_moving::<D>(st, grid_velocity, u, velocity, b))
        }
    }
    Ok(())
}

fn apic_static<const D: usize, const N: usize>(
    st: &Stencils<D>,
    grid_v: &[SVector<f64, D>],
    velocity: &mut [SVector<f64, D>],
    b: &mut [SMatrix<f64, D, D>],
) {
    struct Op<'a, const D: usize> {
        grid_v: &'a [SVector<f64, D>],
        h: f64,
        v: ParticleOut<'a, SVector<f64, D>>,
        b: ParticleOut<'a, SMatrix<f64, D, D>>,
    }
    impl<const D: usize> GatherOp<D> for Op<'_, D> {
        type Node = SVector<f64, D>;
        fn zero(&self) -> Self::Node {
            SVector::zeros()
        }
        #[inline(always)]
        fn fetch(&self, i: usize) -> Self::Node {
            self.grid_v[i]
        }
        #[inline(always)]
        fn particle<const N: usize>(
            &self,
            p: usize,
            frac: &[f64; D],
            w: &Weights<D>,
            layout: &Layout<'_, D>,
            win: &[Self::Node],
        ) {
            // v = Σ w v_i;  S = Σ w v_i kᵀ;  B = Σ w v_i (h (k − f))ᵀ = h (S − v fᵀ).
            let (v, sm) = w.moments::<N>(&layout.stride, win);
            let f = SVector::<f64, D>::from_column_slice(frac);
            // SAFETY: `p` is the particle this call was given; no other task writes it (`gather`).
            unsafe {
                *self.v.at(p) = v;
                *self.b.at(p) = (sm - v * f.transpose()) * self.h;
            }
        }
        #[inline(always)]
        fn prefetch(&self, p: usize) {
            self.v.prefetch(p);
            self.b.prefetch(p);
        }
    }
    gather::<D, N, _>(
        st,
        &Op {
            grid_v,
            h: st.grid().h(),
            v: ParticleOut::new(velocity),
            b: ParticleOut::new(b),
        },
    );
}

fn apic_moving<const D: usize, const N: usize>(
    st: &Stencils<D>,
    grid_v: &[SVector<f64, D>],
    grid_u: &[SVector<f64, D>],
    velocity: &mut [SVector<f64, D>],
    b: &mut [SMatrix<f64, D, D>],
) {
    struct Op<'a, const D: usize> {
        grid_v: &'a [SVector<f64, D>],
        grid_u: &'a [SVector<f64, D>],
        h: f64,
        v: ParticleOut<'a, SVector<f64, D>>,
        b: ParticleOut<'a, SMatrix<f64, D, D>>,
    }
    impl<const D: usize> GatherOp<D> for Op<'_, D> {
        type Node = (SVector<f64, D>, SVector<f64, D>);
        fn zero(&self) -> Self::Node {
            (SVector::zeros(), SVector::zeros())
        }
        #[inline(always)]
        fn fetch(&self, i: usize) -> Self::Node {
            (self.grid_v[i], self.grid_u[i])
        }
        #[inline(always)]
        fn particle<const N: usize>(
            &self,
            p: usize,
            frac: &[f64; D],
            w: &Weights<D>,
            layout: &Layout<'_, D>,
            win: &[Self::Node],
        ) {
            let mut v = SVector::<f64, D>::zeros();
            let mut ubar = SVector::<f64, D>::zeros();
            let mut sm = SMatrix::<f64, D, D>::zeros();
            let mut q = SMatrix::<f64, D, D>::zeros();
            w.for_each::<N>(&layout.stride, |o, wk, k| {
                let (vi, ui) = win[o];
                let wv = vi * wk;
                v += wv;
                ubar += ui * wk;
                sm += wv * k.transpose();
                q += wv * ui.transpose();
            });
            let f = SVector::<f64, D>::from_column_slice(frac);
            let vu = v * ubar.transpose();
            // SAFETY: `p` is the particle this call was given; no other task writes it (`gather`).
            unsafe {
                *self.v.at(p) = v;
                *self.b.at(p) = (sm - v * f.transpose()) * self.h + (q - q.transpose()) * 0.5
                    - (vu - vu.transpose()) * 0.5;
            }
        }
        #[inline(always)]
        fn prefetch(&self, p: usize) {
            self.v.prefetch(p);
            self.b.prefetch(p);
        }
    }
    gather::<D, N, _>(
        st,
        &Op {
            grid_v,
            grid_u,
            h: st.grid().h(),
            v: ParticleOut::new(velocity),
            b: ParticleOut::new(b),
        },
    );
}

/// FLIP grid-to-particle with a PIC/FLIP blend: `v_p ← (1 − α) Σ w v_i + α (v_p + Σ w (v_i −
/// v_iⁿ))`, `α ∈ [0, 1]` (1 = pure FLIP, BFEMP Table 3; 0 = PIC).
pub fn g2p_flip<const D: usize>(
    st: &Stencils<D>,
    grid_velocity: &[SVector<f64, D>],
    grid_velocity_old: &[SVector<f64, D>],
    flip_ratio: f64,
    velocity: &mut [SVector<f64, D>],
) -> Result<(), KernelError> {
    if !(0.0..=1.0).contains(&flip_ratio) {
        return Err(KernelError::BadParameter {
            what: "FLIP ratio",
            value: flip_ratio,
            valid: "0 ≤ α ≤ 1",
        });
    }
    let n = st.num_particles();
    check_len("grid velocities", st.num_nodes(), grid_velocity.len())?;
    check_len(
        "old grid velocities",
        st.num_nodes(),
        grid_velocity_old.len(),
    )?;
    check::vectors("particle velocities", velocity, n)?;
    dispatch!(
        st,
        flip::<D>(st, grid_velocity, grid_velocity_old, flip_ratio, velocity)
    );
    Ok(())
}

fn flip<const D: usize, const N: usize>(
    st: &Stencils<D>,
    grid_v: &[SVector<f64, D>],
    grid_v_old: &[SVector<f64, D>],
    alpha: f64,
    velocity: &mut [SVector<f64, D>],
) {
    struct Op<'a, const D: usize> {
        grid_v: &'a [SVector<f64, D>],
        grid_v_old: &'a [SVector<f64, D>],
        alpha: f64,
        v: ParticleOut<'a, SVector<f64, D>>,
    }
    impl<const D: usize> GatherOp<D> for Op<'_, D> {
        type Node = (SVector<f64, D>, SVector<f64, D>);
        fn zero(&self) -> Self::Node {
            (SVector::zeros(), SVector::zeros())
        }
        #[inline(always)]
        fn fetch(&self, i: usize) -> Self::Node {
            (self.grid_v[i], self.grid_v_old[i])
        }
        #[inline(always)]
        fn particle<const N: usize>(
            &self,
            p: usize,
            _: &[f64; D],
            w: &Weights<D>,
            layout: &Layout<'_, D>,
            win: &[Self::Node],
        ) {
            let mut vnew = SVector::<f64, D>::zeros();
            let mut vold = SVector::<f64, D>::zeros();
            w.for_each::<N>(&layout.stride, |o, wk, _| {
                let (a, b) = win[o];
                vnew += a * wk;
                vold += b * wk;
            });
            // SAFETY: `p` is the particle this call was given; no other task writes it (`gather`).
            let vp = unsafe { self.v.at(p) };
            *vp = vnew + (*vp - vold) * self.alpha;
        }
        #[inline(always)]
        fn prefetch(&self, p: usize) {
            self.v.prefetch(p);
        }
    }
    gather::<D, N, _>(
        st,
        &Op {
            grid_v,
            grid_v_old,
            alpha,
            v: ParticleOut::new(velocity),
        },
    );
}

/// Move particles with the grid: `x_p ← x_p + Σ_i w_ip u_i` and, if given,
/// `F_p ← (I + Σ_i u_i ∇w_ipᵀ) F_p` (eq. 25), for grid displacements `u_i = x̃_i − x_i`.
pub fn advect<const D: usize>(
    st: &Stencils<D>,
    grid_displacement: &[SVector<f64, D>],
    position: &mut [SVector<f64, D>],
    deformation_gradient: Option<&mut [SMatrix<f64, D, D>]>,
) -> Result<(), KernelError> {
    let n = st.num_particles();
    check_len(
        "grid displacements",
        st.num_nodes(),
        grid_displacement.len(),
    )?;
    check_len("particle positions", n, position.len())?;
    if let Some(f) = &deformation_gradient {
        check_len("particle deformation gradients", n, f.len())?;
    }
    dispatch!(
        st,
        advect_inner::<D>(st, grid_displacement, position, deformation_gradient)
    );
    Ok(())
}

fn advect_inner<const D: usize, const N: usize>(
    st: &Stencils<D>,
    grid_u: &[SVector<f64, D>],
    position: &mut [SVector<f64, D>],
    deformation_gradient: Option<&mut [SMatrix<f64, D, D>]>,
) {
    struct Op<'a, const D: usize> {
        grid_u: &'a [SVector<f64, D>],
        x: ParticleOut<'a, SVector<f64, D>>,
        f: Option<ParticleOut<'a, SMatrix<f64, D, D>>>,
    }
    impl<const D: usize> GatherOp<D> for Op<'_, D> {
        type Node = SVector<f64, D>;
        fn zero(&self) -> Self::Node {
            SVector::zeros()
        }
        #[inline(always)]
        fn fetch(&self, i: usize) -> Self::Node {
            self.grid_u[i]
        }
        #[inline(always)]
        fn particle<const N: usize>(
            &self,
            p: usize,
            _: &[f64; D],
            w: &Weights<D>,
            layout: &Layout<'_, D>,
            win: &[Self::Node],
        ) {
            let mut dx = SVector::<f64, D>::zeros();
            let mut du = SMatrix::<f64, D, D>::zeros();
            for k in 0..N.pow(D as u32) {
                let ui = win[layout.offsets[k]];
                dx += ui * w.w(&layout.axes[k]);
                if self.f.is_some() {
                    du += ui * w.grad(&layout.axes[k]).transpose();
                }
            }
            // SAFETY: `p` is the particle this call was given; no other task writes it (`gather`).
            unsafe { *self.x.at(p) += dx };
            if let Some(fo) = &self.f {
                // SAFETY: `p` is the particle this call was given; no other task writes it (`gather`).
                let f = unsafe { fo.at(p) };
                *f = (SMatrix::<f64, D, D>::identity() + du) * *f;
            }
        }
        #[inline(always)]
        fn prefetch(&self, p: usize) {
            self.x.prefetch(p);
            if let Some(f) = &self.f {
                f.prefetch(p);
            }
        }
    }
    gather::<D, N, _>(
        st,
        &Op {
            grid_u,
            x: ParticleOut::new(position),
            f: deformation_gradient.map(ParticleOut::new),
        },
    );
}
