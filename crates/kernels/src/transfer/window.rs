//! The two loops every transfer is built from: scatter particles into grid nodes (P2G) and
//! gather grid nodes into particles (G2P), one group window at a time.

use nalgebra::SVector;
use rayon::prelude::*;

use crate::par::DisjointSlice;
use crate::spline::{quadratic3, quadratic4};
use crate::stencil::{NO_NODE, PREFETCH, Stencils};

/// Weights of one particle's stencil, per axis (`w`, `dw`); node weights are products.
pub(crate) struct Weights<const D: usize> {
    /// Per-axis weights and derivatives (with respect to x).
    pub axis: [([f64; 4], [f64; 4]); D],
}

impl<const D: usize> Weights<D> {
    #[inline(always)]
    pub(crate) fn new<const N: usize>(frac: &[f64; D], inv_h: f64) -> Self {
        let axis: [([f64; 4], [f64; 4]); D] = std::array::from_fn(|a| {
            if N == 3 {
                quadratic3(frac[a], inv_h)
            } else {
                quadratic4(frac[a], inv_h)
            }
        });
        Self { axis }
    }

    /// Visit the `N^D` stencil nodes as nested loops (last axis fastest, the same order as the
    /// flat tables): `f(window offset, weight, per-axis offsets as a vector)`.
    #[inline(always)]
    pub(crate) fn for_each<const N: usize>(
        &self,
        stride: &[usize; D],
        mut f: impl FnMut(usize, f64, &SVector<f64, D>),
    ) {
        let mut k = SVector::<f64, D>::zeros();
        if D == 2 {
            for i in 0..N {
                let wi = self.axis[0].0[i];
                k[0] = i as f64;
                for j in 0..N {
                    k[1] = j as f64;
                    f(i * stride[0] + j, wi * self.axis[1].0[j], &k);
                }
            }
        } else {
            for i in 0..N {
                let wi = self.axis[0].0[i];
                k[0] = i as f64;
                for j in 0..N {
                    let wij = wi * self.axis[1].0[j];
                    k[1] = j as f64;
                    let oij = i * stride[0] + j * stride[1];
                    for l in 0..N {
                        k[2] = l as f64;
                        f(oij + l, wij * self.axis[2].0[l], &k);
                    }
                }
            }
        }
    }

    /// Like [`Self::for_each`] but hands `f` the affine value `a0 + A k` instead of `k`,
    /// computed incrementally (one vector add per node instead of a matrix–vector product).
    #[inline(always)]
    pub(crate) fn for_each_affine<const N: usize>(
        &self,
        stride: &[usize; D],
        a0: &SVector<f64, D>,
        a: &nalgebra::SMatrix<f64, D, D>,
        mut f: impl FnMut(usize, f64, &SVector<f64, D>),
    ) {
        let c0 = a.column(0).into_owned();
        let c1 = a.column(1).into_owned();
        if D == 2 {
            let mut vi = *a0;
            for i in 0..N {
                let wi = self.axis[0].0[i];
                let mut vij = vi;
                for j in 0..N {
                    f(i * stride[0] + j, wi * self.axis[1].0[j], &vij);
                    vij += c1;
                }
                vi += c0;
            }
        } else {
            let c2 = a.column(2).into_owned();
            let mut vi = *a0;
            for i in 0..N {
                let wi = self.axis[0].0[i];
                let mut vij = vi;
                for j in 0..N {
                    let wij = wi * self.axis[1].0[j];
                    let oij = i * stride[0] + j * stride[1];
                    let mut vijl = vij;
                    for l in 0..N {
                        f(oij + l, wij * self.axis[2].0[l], &vijl);
                        vijl += c2;
                    }
                    vij += c1;
                }
                vi += c0;
            }
        }
    }

    /// The zeroth and first moments of a window field over the stencil:
    /// `(Σ w q_i, [Σ w k_a q_i]_a)` with `k` the node's per-axis offsets, factored axis by axis.
    #[inline(always)]
    pub(crate) fn moments<const N: usize>(
        &self,
        stride: &[usize; D],
        win: &[SVector<f64, D>],
    ) -> (SVector<f64, D>, nalgebra::SMatrix<f64, D, D>) {
        let mut m0 = SVector::<f64, D>::zeros();
        let mut m1 = nalgebra::SMatrix::<f64, D, D>::zeros();
        if D == 2 {
            for i in 0..N {
                let wi = self.axis[0].0[i];
                let row = &win[i * stride[0]..];
                let mut t0 = SVector::<f64, D>::zeros();
                let mut t1 = SVector::<f64, D>::zeros();
                for j in 0..N {
                    let wq = row[j] * self.axis[1].0[j];
                    t0 += wq;
                    t1 += wq * j as f64;
                }
                m0 += t0 * wi;
                let mut c0 = m1.column_mut(0);
                c0 += t0 * (wi * i as f64);
                let mut c1 = m1.column_mut(1);
                c1 += t1 * wi;
            }
        } else {
            for i in 0..N {
                let wi = self.axis[0].0[i];
                let mut u0 = SVector::<f64, D>::zeros();
                let mut u1 = SVector::<f64, D>::zeros();
                let mut u2 = SVector::<f64, D>::zeros();
                for j in 0..N {
                    let wj = self.axis[1].0[j];
                    let row = &win[i * stride[0] + j * stride[1]..];
                    let mut t0 = SVector::<f64, D>::zeros();
                    let mut t1 = SVector::<f64, D>::zeros();
                    for l in 0..N {
                        let wq = row[l] * self.axis[2].0[l];
                        t0 += wq;
                        t1 += wq * l as f64;
                    }
                    u0 += t0 * wj;
                    u1 += t0 * (wj * j as f64);
                    u2 += t1 * wj;
                }
                m0 += u0 * wi;
                let mut c0 = m1.column_mut(0);
                c0 += u0 * (wi * i as f64);
                let mut c1 = m1.column_mut(1);
                c1 += u1 * wi;
                let mut c2 = m1.column_mut(2);
                c2 += u2 * wi;
            }
        }
        (m0, m1)
    }

    /// Weight of the stencil node with per-axis offsets `k`.
    #[inline(always)]
    pub(crate) fn w(&self, k: &[u8; D]) -> f64 {
        let mut w = self.axis[0].0[k[0] as usize];
        for a in 1..D {
            w *= self.axis[a].0[k[a] as usize];
        }
        w
    }

    /// Gradient of the weight of the stencil node with per-axis offsets `k`.
    #[inline(always)]
    pub(crate) fn grad(&self, k: &[u8; D]) -> SVector<f64, D> {
        SVector::from_fn(|c, _| {
            let mut g = 1.0;
            for a in 0..D {
                let ka = k[a] as usize;
                g *= if a == c {
                    self.axis[a].1[ka]
                } else {
                    self.axis[a].0[ka]
                };
            }
            g
        })
    }
}

/// The stencil layout shared by all particles: for each of the `N^D` nodes, its index offset in
/// the group window, its per-axis offsets, and those as a vector (in cells).
pub(crate) struct Layout<'a, const D: usize> {
    pub stride: [usize; D],
    pub offsets: &'a [usize],
    pub axes: &'a [[u8; D]],
}

impl<'a, const D: usize> Layout<'a, D> {
    fn new<const N: usize>(st: &'a Stencils<D>) -> Self {
        let nn = N.pow(D as u32);
        Self {
            stride: st.stride,
            offsets: &st.offsets[..nn],
            axes: &st.offsets_axes[..nn],
        }
    }
}

/// A particle-to-grid operation: what one particle adds to its stencil's nodes (accumulated in
/// a group-local window), and how a finished window entry goes into the grid arrays.
pub(crate) trait ScatterOp<const D: usize>: Sync {
    /// What a window node accumulates.
    type Acc: Copy + Send + Sync;
    /// The additive identity.
    fn zero(&self) -> Self::Acc;
    /// Add particle `p` (fractional position `frac`) into `win`, indexed from its stencil base.
    fn particle<const N: usize>(
        &self,
        p: usize,
        frac: &[f64; D],
        w: &Weights<D>,
        layout: &Layout<'_, D>,
        win: &mut [Self::Acc],
    );
    /// Add a window entry into grid node `node`.
    fn flush(&self, node: usize, acc: &Self::Acc);
    /// Start loading particle `p`'s data (it will be visited soon).
    fn prefetch(&self, p: usize);
}

/// P2G driver: for every group, accumulate its particles into a window buffer, then flush the
/// window into the grid. Colours run one after the other so that concurrent flushes never
/// touch the same node.
pub(crate) fn scatter<const D: usize, const N: usize, Op: ScatterOp<D>>(st: &Stencils<D>, op: &Op) {
    let wl = st.window_len();
    let inv_h = 1.0 / st.grid.h();
    let layout = Layout::new::<N>(st);
    let zero = op.zero();
    for c in 0..(1usize << D) {
        let groups = &st.colour_order[st.colour_start[c]..st.colour_start[c + 1]];
        groups.par_iter().with_min_len(8).for_each_init(
            || vec![zero; wl],
            |buf, &gi| {
                let gi = gi as usize;
                buf.fill(zero);
                let g = &st.groups[gi];
                let (start, end) = (g.start as usize, g.end as usize);
                // Ask for every particle's data of the group first: with particles stored in
                // random order each read misses the cache, and issuing them all at once lets
                // the misses overlap (19 % less P2G time than prefetching 16 ahead, 1 thread,
                // 10⁶ particles; no change when particles are sorted).
                for &p in &st.order[start..end] {
                    op.prefetch(p as usize);
                }
                for s in start..end {
                    let p = st.order[s] as usize;
                    let frac = &st.slot_frac[s];
                    let w = Weights::<D>::new::<N>(frac, inv_h);
                    let base = st.slot_base[s] as usize;
                    op.particle::<N>(p, frac, &w, &layout, &mut buf[base..]);
                }
                let ids = &st.window_ids[gi * wl..(gi + 1) * wl];
                for (acc, &id) in buf.iter().zip(ids) {
                    if id != NO_NODE {
                        op.flush(id as usize, acc);
                    }
                }
            },
        );
    }
}

/// A grid-to-particle operation: what a window node holds, and what one particle computes from
/// its stencil's nodes.
pub(crate) trait GatherOp<const D: usize>: Sync {
    /// What a window node holds.
    type Node: Copy + Send + Sync;
    /// Value for window nodes no particle touches (never read with a non-zero weight).
    fn zero(&self) -> Self::Node;
    /// Read grid node `node`.
    fn fetch(&self, node: usize) -> Self::Node;
    /// Compute particle `p`'s outputs from `win` (indexed from its stencil base).
    fn particle<const N: usize>(
        &self,
        p: usize,
        frac: &[f64; D],
        w: &Weights<D>,
        layout: &Layout<'_, D>,
        win: &[Self::Node],
    );
    /// Start loading particle `p`'s data (it will be visited soon).
    fn prefetch(&self, p: usize);
}

/// G2P driver: every group gathers its window, then computes each of its particles. Groups run
/// in parallel; an op writes particle `p`'s outputs only.
pub(crate) fn gather<const D: usize, const N: usize, Op: GatherOp<D>>(st: &Stencils<D>, op: &Op) {
    let wl = st.window_len();
    let inv_h = 1.0 / st.grid.h();
    let layout = Layout::new::<N>(st);
    let zero = op.zero();
    (0..st.groups.len())
        .into_par_iter()
        .with_min_len(8)
        .for_each_init(
            || vec![zero; wl],
            |buf, gi| {
                let ids = &st.window_ids[gi * wl..(gi + 1) * wl];
                for (b, &id) in buf.iter_mut().zip(ids) {
                    *b = if id != NO_NODE {
                        op.fetch(id as usize)
                    } else {
                        zero
                    };
                }
                let g = &st.groups[gi];
                let end = g.end as usize;
                for s in g.start as usize..end {
                    if s + PREFETCH < end {
                        op.prefetch(st.order[s + PREFETCH] as usize);
                    }
                    let p = st.order[s] as usize;
                    let frac = &st.slot_frac[s];
                    let w = Weights::<D>::new::<N>(frac, inv_h);
                    let base = st.slot_base[s] as usize;
                    op.particle::<N>(p, frac, &w, &layout, &buf[base..]);
                }
            },
        );
}

/// Write access to per-particle outputs from the parallel G2P loop.
pub(crate) struct ParticleOut<'a, T>(DisjointSlice<'a, T>);

impl<'a, T> ParticleOut<'a, T> {
    pub(crate) fn new(s: &'a mut [T]) -> Self {
        Self(DisjointSlice::new(s))
    }

    /// Hint that element `p` will be written soon.
    #[inline(always)]
    pub(crate) fn prefetch(&self, p: usize) {
        self.0.prefetch(p);
    }

    /// Element `p`.
    ///
    /// # Safety
    ///
    /// No other reference to element `p` may be live: callers inside [`gather`]'s `body` pass
    /// only the particle index they were given, which no other task receives (`order` is a
    /// permutation and groups partition the slots).
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    pub(crate) unsafe fn at(&self, p: usize) -> &mut T {
        // SAFETY: the caller guarantees exclusive access to element `p`.
        unsafe { self.0.get(p) }
    }
}

/// Write access to grid arrays from the coloured flush of [`scatter`].
pub(crate) struct NodeOut<'a, T>(DisjointSlice<'a, T>);

impl<'a, T> NodeOut<'a, T> {
    pub(crate) fn new(s: &'a mut [T]) -> Self {
        Self(DisjointSlice::new(s))
    }

    /// Node `i`.
    ///
    /// # Safety
    ///
    /// No other reference to node `i` may be live: callers inside [`scatter`]'s flush pass only
    /// nodes of their own group's window — within one colour, group windows are disjoint
    /// (G ≥ N − 1 and same-colour groups are ≥ 2 blocks apart on some axis), and colours are
    /// separated by the end of a parallel loop.
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    pub(crate) unsafe fn at(&self, i: usize) -> &mut T {
        // SAFETY: the caller guarantees exclusive access to node `i`.
        unsafe { self.0.get(i) }
    }
}
