//! Particle stencils and the active-node numbering of a step.
//!
//! [`Stencils`] is built once per step from the particle positions (with [`Grid::stencils`] or,
//! reusing its memory, [`Stencils::rebuild`]) and then serves every transfer of that step and,
//! in BFEMP, every Newton iteration: for each particle it knows its `N^D` grid nodes (`N = 3` or
//! 4 per axis), their weights `w_ip` and weight gradients `∇w_ip`.
//!
//! # Active nodes
//! A node is *active* when some particle's stencil contains it. Active nodes are numbered
//! `0..num_nodes()` compactly; this numbering is what grid arrays (mass, velocity, the implicit
//! solver's unknowns) are indexed by. Memory grows with the number of active nodes.
//!
//! # How it is organised (and why it is fast and race-free)
//! Particles are bucketed by **group**: the block of `G^D` cells (G = 8 in 2D, 4 in 3D) that
//! holds their stencil's base node. Each group has a dense **window** of `(G + N − 1)^D` nodes
//! that covers every stencil of its particles; the window stores the compact id of each of its
//! nodes. Transfers accumulate a group's particles into a small dense buffer the size of the
//! window (cache-resident, no indirection per particle-node) and then add the buffer into the
//! global arrays. Two groups whose coordinates have the same parity on every axis have
//! disjoint windows (because `G ≥ N − 1`), so the `2^D` parity classes ("colours") are
//! processed one after the other, each in parallel without races. Every node receives its
//! contributions in the same order whatever the number of threads: **parallel P2G is
//! bitwise identical to serial P2G.**
//!
//! Particles are visited in *slot* order (grouped); [`Stencils::order`] gives the permutation,
//! which a simulator may apply to its particle arrays to make the transfers' memory access
//! sequential.
//!
//! # Linear maps for implicit solvers (BFEMP eq. 25, 29)
//! With grid displacements `u_i = x̃_i − x_i`, a particle's position and deformation gradient
//! after the step are linear in `u`:
//! `x_p(u) = x_p + Σ_i w_ip u_i` and `F_p(u) = (I + Σ_i u_i ∇w_ipᵀ) F_pⁿ`
//! (`Σ_i x_i ∇w_ipᵀ = I` by linear completeness, so this is eq. 25). Their Jacobians are
//! `∂x_p/∂u_i = w_ip I` and `∂F_p[a][b]/∂u_i[c] = δ_ac (F_pⁿᵀ ∇w_ip)[b]`;
//! [`ParticleStencil`] exposes both.

use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;
use rustc_hash::FxHashMap;

use crate::par::DisjointSlice;
use crate::sort::radix_sort_bits;
use crate::{Grid, Kernel, KernelError};

/// Largest window (7³ nodes: 4-node kernel in 3D).
pub(crate) const MAX_WINDOW: usize = 343;
/// Largest stencil (4³ nodes).
pub(crate) const MAX_STENCIL: usize = 64;

/// log2 of the group edge in nodes.
#[inline]
pub(crate) const fn group_log(d: usize) -> u32 {
    if d == 2 { 3 } else { 2 }
}

/// One group: particles whose stencil base lies in the same `G^D` block of cells.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GroupInfo<const D: usize> {
    /// Block coordinate (base node index >> log2 G, per axis).
    pub(crate) coord: [i64; D],
    /// Slot range of its particles.
    pub(crate) start: u32,
    pub(crate) end: u32,
    /// Which of the G^D base cells are used (one bit each; G^D = 64 in 2D and 3D).
    pub(crate) mask: u64,
}

/// Scratch kept between rebuilds so a step allocates nothing once sizes settle.
#[derive(Clone, Debug, Default)]
struct Scratch<const D: usize> {
    words64: Vec<u64>,
    tmp64: Vec<u64>,
    words128: Vec<u128>,
    tmp128: Vec<u128>,
    blocks: FxHashMap<[i64; D], u32>,
    block_ids: Vec<u32>,
}

/// The stencils of all particles of one step and the compact numbering of the active nodes.
/// See the module documentation.
#[derive(Clone, Debug)]
pub struct Stencils<const D: usize> {
    pub(crate) grid: Grid<D>,
    /// Window edge in nodes, G + N − 1.
    pub(crate) win: usize,
    /// Window index strides per axis (last axis fastest).
    pub(crate) stride: [usize; D],
    /// Window index offset of each of the N^D stencil nodes, and its per-axis offsets.
    pub(crate) offsets: Vec<usize>,
    pub(crate) offsets_axes: Vec<[u8; D]>,
    /// For each window index: which of the 2^D blocks it falls in (bit a set: the upper block
    /// on axis a), its index inside that block, and its per-axis offset in the window.
    pub(crate) window_decode: Vec<(u8, u16, [u8; D])>,
    /// Window index of the base node for each of the G^D cells of a group.
    pub(crate) cell_to_win: Vec<u32>,
    // Per slot.
    pub(crate) order: Vec<u32>,
    pub(crate) slot_group: Vec<u32>,
    pub(crate) slot_base: Vec<u32>,
    pub(crate) slot_frac: Vec<[f64; D]>,
    // Per particle.
    pub(crate) slot_of: Vec<u32>,
    // Per group.
    pub(crate) groups: Vec<GroupInfo<D>>,
    pub(crate) window_ids: Vec<u32>,
    pub(crate) colour_order: Vec<u32>,
    pub(crate) colour_start: Vec<usize>,
    // Per active node.
    pub(crate) node_index: Vec<[i64; D]>,
    scratch: Scratch<D>,
}

/// Marker for a window node no particle touches.
pub(crate) const NO_NODE: u32 = u32::MAX;

impl<const D: usize> Stencils<D> {
    pub(crate) fn empty(grid: Grid<D>) -> Self {
        let n = grid.kernel().nodes_per_axis();
        let g = 1usize << group_log(D);
        let win = g + n - 1;
        let mut stride = [1usize; D];
        for a in (0..D.saturating_sub(1)).rev() {
            stride[a] = stride[a + 1] * win;
        }
        let total = n.pow(D as u32);
        let mut offsets = Vec::with_capacity(total);
        let mut offsets_axes = Vec::with_capacity(total);
        for flat in 0..total {
            let mut k = [0u8; D];
            let mut rem = flat;
            for a in (0..D).rev() {
                k[a] = (rem % n) as u8;
                rem /= n;
            }
            offsets.push((0..D).map(|a| k[a] as usize * stride[a]).sum());
            offsets_axes.push(k);
        }
        let wl = win.pow(D as u32);
        let window_decode = (0..wl)
            .map(|l| {
                let mut rem = l;
                let mut la = [0u8; D];
                for a in (0..D).rev() {
                    la[a] = (rem % win) as u8;
                    rem /= win;
                }
                let mut which = 0u8;
                let mut in_block = 0usize;
                for a in 0..D {
                    let hi = la[a] as usize >= g;
                    which |= (hi as u8) << a;
                    in_block = in_block * g + la[a] as usize - if hi { g } else { 0 };
                }
                (which, in_block as u16, la)
            })
            .collect();
        let cell_to_win = (0..g.pow(D as u32))
            .map(|c| {
                let mut rem = c;
                let mut idx = 0;
                for a in (0..D).rev() {
                    idx += (rem % g) * stride[a];
                    rem /= g;
                }
                idx as u32
            })
            .collect();
        Self {
            grid,
            win,
            stride,
            offsets,
            offsets_axes,
            window_decode,
            cell_to_win,
            order: Vec::new(),
            slot_group: Vec::new(),
            slot_base: Vec::new(),
            slot_frac: Vec::new(),
            slot_of: Vec::new(),
            groups: Vec::new(),
            window_ids: Vec::new(),
            colour_order: Vec::new(),
            colour_start: vec![0; (1 << D) + 1],
            node_index: Vec::new(),
            scratch: Scratch::default(),
        }
    }

    /// The grid these stencils live on.
    #[inline]
    pub fn grid(&self) -> &Grid<D> {
        &self.grid
    }

    /// Number of particles.
    #[inline]
    pub fn num_particles(&self) -> usize {
        self.order.len()
    }

    /// Number of active grid nodes (the length of every grid array of this step).
    #[inline]
    pub fn num_nodes(&self) -> usize {
        self.node_index.len()
    }

    /// Nodes per particle stencil (`N^D`: 9, 16, 27 or 64).
    #[inline]
    pub fn stencil_len(&self) -> usize {
        self.offsets.len()
    }

    /// Integer index of active node `node`.
    #[inline]
    pub fn node_index(&self, node: usize) -> [i64; D] {
        self.node_index[node]
    }

    /// World position of active node `node`.
    #[inline]
    pub fn node_position(&self, node: usize) -> SVector<f64, D> {
        self.grid.node_position(&self.node_index[node])
    }

    /// Integer indices of all active nodes, in compact order.
    #[inline]
    pub fn node_indices(&self) -> &[[i64; D]] {
        &self.node_index
    }

    /// The order in which transfers visit particles: `order()[slot]` is a particle index.
    /// Applying this permutation to the particle arrays makes later transfers sequential in
    /// memory.
    #[inline]
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// Number of particle groups (blocks of cells with particles).
    #[inline]
    pub fn num_groups(&self) -> usize {
        self.groups.len()
    }

    /// The stencil of particle `p` (its index in the arrays the stencils were built from).
    #[inline]
    pub fn particle(&self, p: usize) -> ParticleStencil<'_, D> {
        self.slot(self.slot_of[p] as usize)
    }

    /// Per-axis position (`0..N`) of each stencil entry inside the particle's `N^D` block, in
    /// the order [`ParticleStencil::for_each`] visits them (lexicographic, last axis fastest).
    /// Entries `a` and `b` of any particle's stencil are nodes whose integer indices differ by
    /// `stencil_axes()[b] − stencil_axes()[a]` — which lets an implicit solver address the
    /// node-pair blocks of a particle's Hessian without looking nodes up.
    #[inline]
    pub fn stencil_axes(&self) -> &[[u8; D]] {
        &self.offsets_axes
    }

    /// Race-free parallel scatter into per-node rows: `rows` holds `row_len` entries for each
    /// active node (`rows.len() == num_nodes() * row_len`), and `f(particles, rows)` is called
    /// once per particle group with the group's particle indices and a [`NodeRows`] view
    /// through which it may write the rows of the nodes of those particles' stencils. Groups
    /// whose stencils share no node run concurrently (the colouring of the transfers), so the
    /// result does not depend on the number of threads. `NodeRows::row` panics for a node
    /// outside the group's stencils.
    pub fn par_scatter_rows<T: Send>(
        &self,
        rows: &mut [T],
        row_len: usize,
        f: impl Fn(&[u32], &mut NodeRows<'_, T, D>) + Sync,
    ) {
        assert_eq!(
            rows.len(),
            self.num_nodes() * row_len,
            "rows must hold row_len entries per active node"
        );
        let shared = DisjointSlice::new(rows);
        let g = 1i64 << group_log(D);
        for c in 0..(1usize << D) {
            let groups = &self.colour_order[self.colour_start[c]..self.colour_start[c + 1]];
            groups.par_iter().with_min_len(4).for_each(|&gi| {
                let info = &self.groups[gi as usize];
                let mut view = NodeRows {
                    rows: &shared,
                    row_len,
                    node_index: &self.node_index,
                    origin: std::array::from_fn(|a| info.coord[a] * g),
                    win: self.win as i64,
                };
                f(
                    &self.order[info.start as usize..info.end as usize],
                    &mut view,
                );
            });
        }
    }

    #[inline]
    pub(crate) fn slot(&self, s: usize) -> ParticleStencil<'_, D> {
        let g = self.slot_group[s] as usize;
        let wl = self.window_len();
        ParticleStencil {
            ids: &self.window_ids[g * wl..(g + 1) * wl],
            base: self.slot_base[s] as usize,
            frac: self.slot_frac[s],
            offsets: &self.offsets,
            offsets_axes: &self.offsets_axes,
            kernel: self.grid.kernel(),
            h: self.grid.h(),
        }
    }

    #[inline]
    pub(crate) fn window_len(&self) -> usize {
        self.win.pow(D as u32)
    }

    /// Rebuild for new particle positions, reusing this value's memory. Fails (leaving the
    /// stencils empty) on a non-finite position or one outside the addressable range, naming
    /// the first offending particle.
    pub fn rebuild(&mut self, positions: &[SVector<f64, D>]) -> Result<(), KernelError> {
        let result = self.rebuild_inner(positions);
        if result.is_err() {
            self.clear();
        }
        result
    }

    fn clear(&mut self) {
        self.order.clear();
        self.slot_group.clear();
        self.slot_base.clear();
        self.slot_frac.clear();
        self.slot_of.clear();
        self.groups.clear();
        self.window_ids.clear();
        self.colour_order.clear();
        self.colour_start.iter_mut().for_each(|c| *c = 0);
        self.node_index.clear();
    }

    // Long: the hot path of every MPM step (`cargo bench -p femp-kernels --bench transfers`,
    // "step"); its five numbered phases share the key layout (`locate`, `relative`, `word_at`)
    // and the scratch buffers' borrows, which split functions would pass around as a dozen
    // arguments. Split it only with that bench run side by side.
    fn rebuild_inner(&mut self, positions: &[SVector<f64, D>]) -> Result<(), KernelError> {
        let n = positions.len();
        if n >= u32::MAX as usize {
            return Err(KernelError::BadParameter {
                what: "number of particles",
                value: n as f64,
                valid: "< 2^32 - 1",
            });
        }
        let grid = self.grid;
        let kernel = grid.kernel();
        let h = grid.h();
        let origin = *grid.origin();
        let limit = Grid::<D>::MAX_CELLS as f64;
        let glog = group_log(D);
        let gsize = 1i64 << glog;
        let gs = gsize as usize;
        let cell_bits = D as u32 * glog;
        let wl = self.window_len();
        let sc = &mut self.scratch;
        // Base node and fractional offset along one axis. Recomputed where needed rather than
        // stored: two passes over the positions cost less memory traffic than the arrays.
        let inv_h = 1.0 / h;
        let locate = move |x: f64, a: usize| -> (i64, f64) {
            let q = (x - origin[a]) * inv_h;
            let b = kernel.base(q);
            (b as i64, q - b)
        };
        // Absolute keys: per axis the group coordinate offset to be non-negative in `fb` bits,
        // axis 0 highest, then the cell within the group in the low `cell_bits`.
        let fb: u32 = if D == 2 { 27 } else { 19 };
        let goff = 1i64 << (fb - 1);
        let fmask = (1u64 << fb) - 1;

        // 1. Validate positions, write absolute keys, find the range of group coordinates.
        sc.words64.clear();
        sc.words64.resize(n, 0);
        let (ok, gmin, gmax) = positions
            .par_iter()
            .zip(sc.words64.par_iter_mut())
            .with_min_len(4096)
            .fold(
                || (true, [i64::MAX; D], [i64::MIN; D]),
                |(mut ok, mut lo, mut hi), (x, w)| {
                    let mut key = 0u64;
                    let mut cell = 0u64;
                    for a in 0..D {
                        let q = (x[a] - origin[a]) * inv_h;
                        // `!(|q| <= limit)` is also true for NaN.
                        if q.abs() <= limit {
                            let b = kernel.base(q) as i64;
                            let g = b >> glog;
                            lo[a] = lo[a].min(g);
                            hi[a] = hi[a].max(g);
                            key = (key << fb) | (g + goff) as u64;
                            cell = (cell << glog) | (b & (gsize - 1)) as u64;
                        } else {
                            ok = false;
                        }
                    }
                    *w = (key << cell_bits) | cell;
                    (ok, lo, hi)
                },
            )
            .reduce(
                || (true, [i64::MAX; D], [i64::MIN; D]),
                |(o1, l1, h1), (o2, l2, h2)| {
                    (
                        o1 && o2,
                        std::array::from_fn(|a| l1[a].min(l2[a])),
                        std::array::from_fn(|a| h1[a].max(h2[a])),
                    )
                },
            );
        if !ok {
            return Err(Self::position_error(positions, &origin, h));
        }
        let mut bits = [0u32; D];
        if n > 0 {
            for a in 0..D {
                bits[a] = 64 - ((gmax[a] - gmin[a]) as u64).leading_zeros();
            }
        }
        // Relative key layout (low to high): cell within the group (D·log2 G bits, last axis
        // fastest), then the group coordinate minus gmin per axis, last axis lowest.
        let mut shift = [0u32; D];
        shift[D - 1] = cell_bits;
        for a in (0..D - 1).rev() {
            shift[a] = shift[a + 1] + bits[a + 1];
        }
        let key_bits = cell_bits + bits.iter().sum::<u32>();
        let relative = |abs: u64| -> u64 {
            let mut k = abs & ((1u64 << cell_bits) - 1);
            for a in 0..D {
                let field = (abs >> (cell_bits + fb * (D - 1 - a) as u32)) & fmask;
                let g = field as i64 - goff;
                k |= ((g - gmin[a]) as u64) << shift[a];
            }
            k
        };

        // 2. Sort particles by (group, cell); stable, so ties keep particle order.
        let wide = key_bits > 32;
        if !wide {
            sc.words64
                .par_iter_mut()
                .enumerate()
                .with_min_len(4096)
                .for_each(|(p, w)| *w = (relative(*w) << 32) | p as u64);
            radix_sort_bits(&mut sc.words64, &mut sc.tmp64, 32, key_bits);
        } else {
            sc.words128.clear();
            sc.words128.resize(n, 0);
            sc.words128
                .par_iter_mut()
                .zip(sc.words64.par_iter())
                .enumerate()
                .with_min_len(4096)
                .for_each(|(p, (w, abs))| *w = ((relative(*abs) as u128) << 32) | p as u128);
            radix_sort_bits(&mut sc.words128, &mut sc.tmp128, 32, key_bits);
        }
        let words64 = &sc.words64;
        let words128 = &sc.words128;
        // (key, particle) of slot s.
        let word_at = |s: usize| -> (u64, usize) {
            if wide {
                let w = words128[s];
                ((w >> 32) as u64, (w & 0xffff_ffff) as usize)
            } else {
                let w = words64[s];
                (w >> 32, (w & 0xffff_ffff) as usize)
            }
        };

        // 3. Groups: runs of equal group key (the key without its cell bits).
        self.groups.clear();
        let mut s = 0;
        while s < n {
            let k = word_at(s).0 >> cell_bits;
            let start = s;
            s += 1;
            while s < n && word_at(s).0 >> cell_bits == k {
                s += 1;
            }
            let kk = k << cell_bits;
            self.groups.push(GroupInfo {
                coord: std::array::from_fn(|a| {
                    gmin[a] + ((kk >> shift[a]) & ((1u64 << bits[a]) - 1)) as i64
                }),
                start: start as u32,
                end: s as u32,
                mask: 0,
            });
        }

        // 4. Per-slot data and per-group base-cell masks (parallel over groups).
        self.order.resize(n, 0);
        self.slot_group.resize(n, 0);
        self.slot_base.resize(n, 0);
        self.slot_frac.resize(n, [0.0; D]);
        self.slot_of.resize(n, 0);
        {
            let order = DisjointSlice::new(&mut self.order);
            let slot_group = DisjointSlice::new(&mut self.slot_group);
            let slot_base = DisjointSlice::new(&mut self.slot_base);
            let slot_frac = DisjointSlice::new(&mut self.slot_frac);
            let slot_of = DisjointSlice::new(&mut self.slot_of);
            let cell_to_win = &self.cell_to_win;
            let cell_mask = (1u64 << cell_bits) - 1;
            self.groups
                .par_iter_mut()
                .enumerate()
                .with_min_len(16)
                .for_each(|(gi, g)| {
                    let mut mask = 0u64;
                    let end = g.end as usize;
                    for s in g.start as usize..end {
                        if s + PREFETCH < end {
                            prefetch(positions, word_at(s + PREFETCH).1);
                        }
                        let (key, p) = word_at(s);
                        let cell = (key & cell_mask) as usize;
                        mask |= 1u64 << cell;
                        let x = &positions[p];
                        // SAFETY: slots are partitioned among groups, and the sorted words are
                        // a permutation of the particles, so every slot and every particle is
                        // written by exactly one task.
                        unsafe {
                            *order.get(s) = p as u32;
                            *slot_group.get(s) = gi as u32;
                            *slot_base.get(s) = cell_to_win[cell];
                            *slot_frac.get(s) = std::array::from_fn(|a| locate(x[a], a).1);
                            *slot_of.get(p) = s as u32;
                        }
                    }
                    g.mask = mask;
                });
        }

        // 5. Compact ids of the active nodes (serial over groups; cost ∝ groups × window).
        let block_len = gs.pow(D as u32);
        self.window_ids.clear();
        self.window_ids.resize(self.groups.len() * wl, NO_NODE);
        self.node_index.clear();
        sc.blocks.clear();
        sc.block_ids.clear();
        let mut touched = [false; MAX_WINDOW];
        for (gi, g) in self.groups.iter().enumerate() {
            touched[..wl].fill(false);
            let mut mask = g.mask;
            while mask != 0 {
                let c = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let win_idx = self.cell_to_win[c] as usize;
                for &o in &self.offsets {
                    touched[win_idx + o] = true;
                }
            }
            let mut nb = [NO_NODE; 8];
            let ids = &mut self.window_ids[gi * wl..(gi + 1) * wl];
            for (l, t) in touched[..wl].iter().enumerate() {
                if !*t {
                    continue;
                }
                let (which, in_block, la) = self.window_decode[l];
                let which = which as usize;
                if nb[which] == NO_NODE {
                    let bc: [i64; D] =
                        std::array::from_fn(|a| g.coord[a] + ((which >> a) & 1) as i64);
                    let next = (sc.block_ids.len() / block_len) as u32;
                    let id = *sc.blocks.entry(bc).or_insert(next);
                    if id == next {
                        sc.block_ids.resize(sc.block_ids.len() + block_len, NO_NODE);
                    }
                    nb[which] = id;
                }
                let slot = &mut sc.block_ids[nb[which] as usize * block_len + in_block as usize];
                if *slot == NO_NODE {
                    *slot = self.node_index.len() as u32;
                    self.node_index
                        .push(std::array::from_fn(|a| g.coord[a] * gsize + la[a] as i64));
                }
                ids[l] = *slot;
            }
        }

        // 6. Groups by colour (parity of the block coordinate on each axis).
        let ncol = 1usize << D;
        let colour =
            |g: &GroupInfo<D>| -> usize { (0..D).map(|a| ((g.coord[a] & 1) as usize) << a).sum() };
        self.colour_start.clear();
        self.colour_start.resize(ncol + 1, 0);
        for g in &self.groups {
            self.colour_start[colour(g) + 1] += 1;
        }
        for c in 0..ncol {
            self.colour_start[c + 1] += self.colour_start[c];
        }
        self.colour_order.clear();
        self.colour_order.resize(self.groups.len(), 0);
        let mut fill = [0usize; 8];
        fill[..ncol].copy_from_slice(&self.colour_start[..ncol]);
        for (gi, g) in self.groups.iter().enumerate() {
            let c = colour(g);
            self.colour_order[fill[c]] = gi as u32;
            fill[c] += 1;
        }
        Ok(())
    }

    /// The error for the first particle whose position is not finite or out of range.
    fn position_error(
        positions: &[SVector<f64, D>],
        origin: &SVector<f64, D>,
        h: f64,
    ) -> KernelError {
        let limit = Grid::<D>::MAX_CELLS as f64;
        for (p, x) in positions.iter().enumerate() {
            for a in 0..D {
                if !x[a].is_finite() {
                    return KernelError::NonFinite {
                        particle: p,
                        quantity: "position",
                        value: x[a],
                    };
                }
                let cells = (x[a] - origin[a]) * (1.0 / h);
                if cells.is_nan() || cells.abs() > limit {
                    return KernelError::OutOfRange {
                        particle: p,
                        axis: a,
                        value: x[a],
                        cells,
                        limit: Grid::<D>::MAX_CELLS,
                    };
                }
            }
        }
        // Not reached: the caller found a bad position with the same arithmetic.
        KernelError::BadParameter {
            what: "particle positions",
            value: f64::NAN,
            valid: "finite and within the addressable range",
        }
    }
}

/// How many particles ahead the grouped loops prefetch particle data.
pub(crate) const PREFETCH: usize = 16;

/// Hint the CPU to load `data[i]` into cache (no-op off x86-64). Grouped loops visit particles
/// in spatial order, which is random in memory unless the caller keeps particles sorted; the
/// prefetch hides most of that latency.
#[inline(always)]
pub(crate) fn prefetch<T>(data: &[T], i: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(x) = data.get(i) {
        // SAFETY: prefetching is a hint with no architectural effect; the address is valid.
        unsafe {
            std::arch::x86_64::_mm_prefetch(
                (x as *const T).cast::<i8>(),
                std::arch::x86_64::_MM_HINT_T0,
            );
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (data, i);
}

/// The stencil of one particle: its `N^D` nodes with weights and weight gradients, and the
/// linear maps `u ↦ x_p(u)` and `u ↦ F_p(u)` of the module documentation.
#[derive(Clone, Copy, Debug)]
pub struct ParticleStencil<'a, const D: usize> {
    ids: &'a [u32],
    base: usize,
    frac: [f64; D],
    offsets: &'a [usize],
    offsets_axes: &'a [[u8; D]],
    kernel: Kernel,
    h: f64,
}

impl<const D: usize> ParticleStencil<'_, D> {
    /// Number of nodes (`N^D`).
    #[inline]
    pub fn len(&self) -> usize {
        self.offsets.len()
    }

    /// Always false: a stencil has at least 9 nodes.
    #[inline]
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Call `f(node, w_ip, ∇w_ip)` for every node of the stencil, in a fixed order.
    #[inline]
    pub fn for_each(&self, mut f: impl FnMut(usize, f64, SVector<f64, D>)) {
        let inv_h = 1.0 / self.h;
        let wd: [([f64; 4], [f64; 4]); D] =
            std::array::from_fn(|a| self.kernel.eval_frac(self.frac[a], inv_h));
        for (o, k) in self.offsets.iter().zip(self.offsets_axes) {
            let node = self.ids[self.base + o] as usize;
            let mut w = 1.0;
            for a in 0..D {
                w *= wd[a].0[k[a] as usize];
            }
            let grad = SVector::<f64, D>::from_fn(|c, _| {
                let mut g = 1.0;
                for a in 0..D {
                    g *= if a == c {
                        wd[a].1[k[a] as usize]
                    } else {
                        wd[a].0[k[a] as usize]
                    };
                }
                g
            });
            f(node, w, grad);
        }
    }

    /// The nodes, weights and gradients as arrays (first `len()` entries valid).
    pub fn collect(&self) -> StencilValues<D> {
        let mut out = StencilValues {
            len: 0,
            node: [0; MAX_STENCIL],
            w: [0.0; MAX_STENCIL],
            grad: [SVector::zeros(); MAX_STENCIL],
        };
        self.for_each(|node, w, g| {
            out.node[out.len] = node as u32;
            out.w[out.len] = w;
            out.grad[out.len] = g;
            out.len += 1;
        });
        out
    }

    /// Position of the node relative to the particle, `x_i − x_p`, for stencil entry `k`.
    #[inline]
    pub fn node_offset(&self, k: usize) -> SVector<f64, D> {
        let ka = &self.offsets_axes[k];
        SVector::from_fn(|a, _| (ka[a] as f64 - self.frac[a]) * self.h)
    }

    /// `x_p(u) − x_p = Σ_i w_ip u_i`: the particle's displacement for grid displacements `u`.
    pub fn displacement(&self, u: &[SVector<f64, D>]) -> SVector<f64, D> {
        let mut d = SVector::zeros();
        self.for_each(|i, w, _| d += u[i] * w);
        d
    }

    /// `Σ_i u_i ∇w_ipᵀ`: the displacement gradient of the step, so that
    /// `F_p(u) = (I + Σ_i u_i ∇w_ipᵀ) F_pⁿ` (eq. 25).
    pub fn displacement_gradient(&self, u: &[SVector<f64, D>]) -> SMatrix<f64, D, D> {
        let mut g = SMatrix::zeros();
        self.for_each(|i, _, grad| g += u[i] * grad.transpose());
        g
    }

    /// `F_p(u) = (I + Σ_i u_i ∇w_ipᵀ) F_pⁿ`.
    pub fn deformation_gradient(
        &self,
        u: &[SVector<f64, D>],
        f_n: &SMatrix<f64, D, D>,
    ) -> SMatrix<f64, D, D> {
        (SMatrix::identity() + self.displacement_gradient(u)) * f_n
    }

    /// The Jacobian of `F_p(u)` as per-node vectors `g_i = F_pⁿᵀ ∇w_ip`:
    /// `∂F_p[a][b] / ∂u_i[c] = δ_ac g_i[b]`. Calls `f(node, g_i)` for every stencil node.
    pub fn for_each_f_jacobian(
        &self,
        f_n: &SMatrix<f64, D, D>,
        mut f: impl FnMut(usize, SVector<f64, D>),
    ) {
        let ft = f_n.transpose();
        self.for_each(|i, _, grad| f(i, ft * grad));
    }
}

/// The rows a particle group may write during [`Stencils::par_scatter_rows`]: those of the
/// nodes inside the group's window (every stencil of its particles).
pub struct NodeRows<'a, T, const D: usize> {
    rows: &'a DisjointSlice<'a, T>,
    row_len: usize,
    node_index: &'a [[i64; D]],
    origin: [i64; D],
    win: i64,
}

impl<T, const D: usize> NodeRows<'_, T, D> {
    /// The row of active node `node`. Panics if the node is not in this group's window.
    #[inline]
    pub fn row(&mut self, node: usize) -> &mut [T] {
        let idx = &self.node_index[node];
        for a in 0..D {
            let l = idx[a] - self.origin[a];
            assert!(
                (0..self.win).contains(&l),
                "node {node} is outside the particle group's stencils"
            );
        }
        if self.row_len == 0 {
            return &mut [];
        }
        let start = node * self.row_len;
        // SAFETY: the node lies in this group's window, and groups running concurrently (one
        // colour) have disjoint windows, so no other task accesses these entries now; the
        // `&mut self` receiver keeps at most one row of this view alive at a time.
        unsafe { std::slice::from_raw_parts_mut(self.rows.get(start) as *mut T, self.row_len) }
    }
}

/// A particle's stencil as plain arrays (first `len` entries valid).
#[derive(Clone, Copy, Debug)]
pub struct StencilValues<const D: usize> {
    /// Number of valid entries (`N^D`).
    pub len: usize,
    /// Compact node ids.
    pub node: [u32; MAX_STENCIL],
    /// Weights `w_ip`.
    pub w: [f64; MAX_STENCIL],
    /// Weight gradients `∇w_ip`.
    pub grad: [SVector<f64, D>; MAX_STENCIL],
}
