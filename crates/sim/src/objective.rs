//! The incremental potential of one BFEMP step (eq. 38) as a [`femp_solver::Objective`]:
//!
//! `E(x) = ½‖x − x̂‖²_M + w (Ψ_FEM + Ψ_MPM + B + D − Σ m g·x) + penalties`, `w = 2αβΔt²`,
//!
//! over the DOFs `x = (grid node positions, FEM vertex positions)`. MPM particles are not
//! unknowns: `x_q = x_qⁿ + Σ_i w_iq u_i` and `F_q = (I + Σ_i u_i ∇w_iqᵀ) F_qⁿ` with
//! `u_i = x_i − X_i` (eqs. 25, 29), so every particle term reaches the grid by the chain rule.
//! The feasible step is the minimum of CCD (particles and FEM vertices against FEM boundaries),
//! det F > 0 of FEM elements, and det F > 0 of MPM particles.

use femp_contact::broad_phase::{self, Candidates};
use femp_contact::ccd::{self, CcdOptions};
use femp_contact::friction::{self, FrictionTerm};
use femp_contact::{ContactTerm, TermDerivatives};
use femp_fem::inversion::first_det_root;
use femp_fem::{Hyperelastic, Tangent, Triplet, chain_hessian_add_upper};
use femp_kernels::transfer;
use femp_solver::{Objective, StepBound, StepLimit, Triplets};
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;
use std::borrow::Cow;
use std::time::Instant;

use crate::bodies::{FemBody, Mpm, Pair, Points};

/// A penalty `½ k (n·x_i − c)²` on one grid node (slip level sets with oblique normals).
#[derive(Clone, Copy, Debug)]
pub struct Penalty<const D: usize> {
    /// Grid node.
    pub node: usize,
    /// Unit normal.
    pub n: SVector<f64, D>,
    /// Target of `n·x_i`.
    pub target: f64,
    /// Stiffness.
    pub k: f64,
}

/// Wall-clock seconds spent in the parts of the objective, accumulated over a step.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ObjectiveTiming {
    /// Particle positions and deformation gradients from the grid DOFs (every evaluation).
    pub unpack_s: f64,
    /// Energy evaluations (line search), excluding unpacking.
    pub energy_s: f64,
    /// MPM elasticity: gradient and Hessian (tangents, chain rule, scatter to the grid).
    pub mpm_s: f64,
    /// FEM elasticity: gradient and Hessian.
    pub fem_s: f64,
    /// Contact and friction: broad phase, terms, derivatives, scatter.
    pub contact_s: f64,
    /// Grid Hessian blocks to triplets.
    pub emit_s: f64,
    /// Continuous collision detection of the line-search filter.
    pub ccd_s: f64,
    /// det F > 0 bounds of the line-search filter (particles and elements).
    pub inversion_s: f64,
}

impl ObjectiveTiming {
    /// Add another timing.
    pub fn add(&mut self, o: &Self) {
        self.unpack_s += o.unpack_s;
        self.energy_s += o.energy_s;
        self.mpm_s += o.mpm_s;
        self.fem_s += o.fem_s;
        self.contact_s += o.contact_s;
        self.emit_s += o.emit_s;
        self.ccd_s += o.ccd_s;
        self.inversion_s += o.inversion_s;
    }
}

/// Seconds since `clock`, and restart it.
#[inline]
fn lap(clock: &mut Instant) -> f64 {
    let now = Instant::now();
    let dt = now.duration_since(*clock).as_secs_f64();
    *clock = now;
    dt
}

/// One slot of a grid node's Hessian row: the block coupling it to one neighbour.
#[derive(Clone, Copy)]
struct HBlock<const D: usize> {
    m: SMatrix<f64, D, D>,
    nbr: u32,
}

/// Grid-node Hessian blocks stored by node and neighbour offset (`δ ∈ [−2, 2]^D` for the
/// 3-node kernel): every particle's stencil couples only such pairs, so a particle's `N^D × N^D`
/// blocks land in fixed slots (a table from the stencil's per-axis offsets, no look-up), and
/// particle groups fill their nodes' rows in parallel without races
/// ([`Stencils::par_scatter_rows`](femp_kernels::Stencils::par_scatter_rows)).
pub struct GridHessian<const D: usize> {
    slots: usize,
    rows: Vec<HBlock<D>>,
    /// `pair_slot[a·N^D + b]`: the slot of stencil entry `b` in the row of entry `a`.
    pair_slot: Vec<u16>,
}

impl<const D: usize> GridHessian<D> {
    fn new() -> Self {
        Self {
            slots: 0,
            rows: Vec::new(),
            pair_slot: Vec::new(),
        }
    }

    /// Clear for `n` nodes with stencils whose per-axis offsets are `axes` (`0..npa`).
    fn reset(&mut self, n: usize, axes: &[[u8; D]], npa: usize) {
        let span = 2 * npa - 1;
        self.slots = span.pow(D as u32);
        let nn = axes.len();
        self.pair_slot.clear();
        for a in 0..nn {
            for b in 0..nn {
                let mut e = 0usize;
                for k in (0..D).rev() {
                    e = e * span + (axes[b][k] as usize + npa - 1 - axes[a][k] as usize);
                }
                self.pair_slot.push(e as u16);
            }
        }
        self.rows.clear();
        self.rows.resize(
            n * self.slots,
            HBlock {
                m: SMatrix::zeros(),
                nbr: u32::MAX,
            },
        );
    }

    /// Append the stored blocks' upper triangle to `h` as triplets, node by node and slot by slot
    /// (the order a sequential loop gives), nodes in parallel. The lower triangle is left out:
    /// the solver drops it (femp-solver's `Objective::hessian` contract), and it was half of
    /// the grid's triplets to write, compare and skip in every Hessian build.
    fn emit(&self, h: &mut Triplets, counts: &mut Vec<usize>) {
        const NODES_PER_TASK: usize = 64;
        let slots = self.slots;
        let n_nodes = self.rows.len().checked_div(slots).unwrap_or(0);
        // Entries per task of consecutive nodes (`upper_columns` row by row).
        counts.clear();
        let node_entries = |i: usize| -> usize {
            self.rows[i * slots..(i + 1) * slots]
                .iter()
                .flat_map(|b| (0..D).map(move |rr| upper_columns(i, b, rr).len()))
                .sum()
        };
        counts.extend((0..n_nodes).step_by(NODES_PER_TASK).map(|first| {
            (first..(first + NODES_PER_TASK).min(n_nodes))
                .map(node_entries)
                .sum::<usize>()
        }));
        let total: usize = counts.iter().sum();
        h.append_with(total, |rows, cols, vals| {
            let mut parts = Vec::with_capacity(counts.len());
            let (mut r, mut c, mut v) = (rows, cols, vals);
            for (task, &len) in counts.iter().enumerate() {
                let (r0, r1) = r.split_at_mut(len);
                let (c0, c1) = c.split_at_mut(len);
                let (v0, v1) = v.split_at_mut(len);
                parts.push((task, r0, c0, v0));
                (r, c, v) = (r1, c1, v1);
            }
            parts.into_par_iter().for_each(|(task, r, c, v)| {
                let first = task * NODES_PER_TASK;
                let last = (first + NODES_PER_TASK).min(n_nodes);
                let mut k = 0;
                for i in first..last {
                    for b in &self.rows[i * slots..(i + 1) * slots] {
                        for rr in 0..D {
                            for cc in upper_columns(i, b, rr) {
                                r[k] = (i * D + rr) as u32;
                                c[k] = (b.nbr as usize * D + cc) as u32;
                                v[k] = b.m[(rr, cc)];
                                k += 1;
                            }
                        }
                    }
                }
            });
        });
    }
}

/// The columns of row `rr` of node `i`'s block `b` that lie in the Hessian's upper triangle
/// (the solver ignores entries below the diagonal): all of a block to a later node, those on
/// and above the diagonal of the node's own block, none of a block to an earlier node or of an
/// empty slot.
fn upper_columns<const D: usize>(i: usize, b: &HBlock<D>, rr: usize) -> std::ops::Range<usize> {
    match b.nbr as usize {
        _ if b.nbr == u32::MAX => 0..0,
        n if n < i => 0..0,
        n if n == i => rr..D,
        _ => 0..D,
    }
}

/// One step's objective. Built by the stepper; borrows the world's state.
pub struct StepObjective<'a, const D: usize> {
    pub(crate) mpm: Option<&'a Mpm<D>>,
    pub(crate) fem: &'a [FemBody<D>],
    pub(crate) pairs: &'a [Pair<D>],
    /// Friction terms lagged per pair (empty when μ = 0).
    pub(crate) friction: Vec<Vec<FrictionTerm<D>>>,
    pub(crate) n_grid: usize,
    pub(crate) fem_offset: Vec<usize>,
    pub(crate) n_dofs: usize,
    pub(crate) mass: &'a [f64],
    pub(crate) x_hat: &'a [f64],
    /// DOF values at the start of the step (grid node positions, FEM xⁿ).
    pub(crate) x_start: &'a [f64],
    pub(crate) w: f64,
    pub(crate) gravity: SVector<f64, D>,
    pub(crate) penalties: &'a [Penalty<D>],
    // Scratch (state at the last unpacked x).
    u: Vec<SVector<f64, D>>,
    xq: Vec<SVector<f64, D>>,
    fq: Vec<SMatrix<f64, D, D>>,
    /// `I + Σ_i u_i ∇w_ipᵀ` per particle (`F_p = gu_p F_pⁿ`), for the det F step bound.
    gu: Vec<SMatrix<f64, D, D>>,
    fem_x: Vec<Vec<SVector<f64, D>>>,
    gh: GridHessian<D>,
    cands: Candidates,
    terms: Vec<ContactTerm>,
    /// Displacements over the step of a pair's points and facet body, for friction
    /// ([`Self::fill_displacements`]).
    disp: (Vec<SVector<f64, D>>, Vec<SVector<f64, D>>),
    fem_trip: Vec<Triplet>,
    node_force: Vec<SVector<f64, D>>,
    /// Per-element forces and per-vertex gradient of a FEM body (femp-fem's
    /// `ElasticBody::add_gradient_with`), reused across bodies and calls.
    fem_grad: (Vec<[SVector<f64, D>; 4]>, Vec<SVector<f64, D>>),
    /// The x the scratch state was last unpacked at.
    unpacked: Vec<f64>,
    /// Incremented whenever the scratch state changes (a new x, a new friction operator).
    generation: u64,
    /// The contact terms' derivatives at one state, shared by the gradient and the Hessian.
    contact: ContactDerivatives<D>,
    /// A scratch gradient for a Hessian that computes the contact derivatives first.
    contact_scratch: Vec<f64>,
    emit_counts: Vec<usize>,
    /// The gradient computes the barrier's exact Hessian for the cache (the solver asks for
    /// [`Objective::exact_hessian`] first: `HessianStrategy::ExactWhenDefinite`).
    pub(crate) prefer_exact: bool,
    /// Where the time went.
    pub(crate) timing: ObjectiveTiming,
    /// Number of active contact terms and smallest contact distance at the last gradient.
    pub(crate) last_contacts: (usize, f64),
    /// Which barrier terms were active at the last gradient and at the last Hessian
    /// ([`terms_key`]), for [`Objective::hessian_terms_unchanged`].
    grad_terms: u64,
    hess_terms: Option<u64>,
    bound_scratch: BoundScratch<D>,
}

/// The contact terms' derivatives per pair (barrier, friction) at one state of the objective —
/// what both the gradient and the Hessian at that state scatter, so whichever of the two comes
/// first computes them and the other reuses them (Newton asks for the Hessian first, then the
/// gradient while the factorisation runs). They serve
/// * a gradient at the same state (`generation`: the same x and friction operator) whatever
///   their barrier Hessian kind — the gradients are the same;
/// * a Hessian only at the same state *and* kind (exact or the pair's projected one).
struct ContactDerivatives<const D: usize> {
    per_pair: Vec<[Vec<TermDerivatives<D>>; 2]>,
    /// The state they were computed at; `None` before the first computation.
    computed_at: Option<State>,
    /// Active terms and smallest contact distance at that state.
    summary: (usize, f64),
}

/// A state of the objective (its `generation`: x and the friction operator) and the kind of barrier Hessian
/// computed there.
#[derive(Clone, Copy, PartialEq, Eq)]
struct State {
    generation: u64,
    exact: bool,
}

impl<const D: usize> ContactDerivatives<D> {
    /// Whether a gradient at state `generation` may scatter these derivatives.
    fn serves_gradient(&self, generation: u64) -> bool {
        self.computed_at.is_some_and(|s| s.generation == generation)
    }

    /// Whether a Hessian (`exact` or projected) at state `generation` may scatter them.
    fn serves_hessian(&self, generation: u64, exact: bool) -> bool {
        self.computed_at == Some(State { generation, exact })
    }
}

/// A fingerprint of the active barrier terms (pair, particle, feature vertices, in order): equal
/// for the same contact set. The lagged friction terms are fixed within a solve.
fn terms_key<const D: usize>(cache: &[[Vec<TermDerivatives<D>>; 2]]) -> u64 {
    // FNV-1a over the terms' indices.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut mix = |v: u64| {
        h ^= v;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    };
    for (k, [bar, _]) in cache.iter().enumerate() {
        mix(k as u64 | (bar.len() as u64) << 32);
        for t in bar {
            mix(t.particle as u64 | (t.n as u64) << 32);
            for &v in &t.vertices[..t.n - 1] {
                mix(v as u64);
            }
        }
    }
    h
}

impl<'a, const D: usize> StepObjective<'a, D> {
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        mpm: Option<&'a Mpm<D>>,
        fem: &'a [FemBody<D>],
        pairs: &'a [Pair<D>],
        n_grid: usize,
        fem_offset: Vec<usize>,
        n_dofs: usize,
        mass: &'a [f64],
        x_hat: &'a [f64],
        x_start: &'a [f64],
        w: f64,
        gravity: SVector<f64, D>,
        penalties: &'a [Penalty<D>],
    ) -> Self {
        Self {
            mpm,
            fem,
            pairs,
            friction: vec![Vec::new(); pairs.len()],
            n_grid,
            fem_offset,
            n_dofs,
            mass,
            x_hat,
            x_start,
            w,
            gravity,
            penalties,
            u: Vec::new(),
            xq: Vec::new(),
            fq: Vec::new(),
            gu: Vec::new(),
            fem_x: fem.iter().map(|b| b.x.clone()).collect(),
            gh: GridHessian::new(),
            cands: Candidates::default(),
            terms: Vec::new(),
            disp: (Vec::new(), Vec::new()),
            fem_trip: Vec::new(),
            node_force: Vec::new(),
            fem_grad: (Vec::new(), Vec::new()),
            unpacked: Vec::new(),
            generation: 0,
            contact: ContactDerivatives {
                per_pair: (0..pairs.len()).map(|_| [Vec::new(), Vec::new()]).collect(),
                computed_at: None,
                summary: (0, f64::INFINITY),
            },
            contact_scratch: Vec::new(),
            emit_counts: Vec::new(),
            prefer_exact: false,
            timing: ObjectiveTiming::default(),
            last_contacts: (0, f64::INFINITY),
            grad_terms: 0,
            hess_terms: None,
            bound_scratch: BoundScratch::default(),
        }
    }

    #[inline]
    fn v(x: &[f64], k: usize) -> SVector<f64, D> {
        SVector::from_column_slice(&x[k * D..k * D + D])
    }

    /// Update the scratch state (grid displacements, particle positions and F, FEM positions).
    fn unpack(&mut self, x: &[f64]) {
        // Newton evaluates gradient, Hessian and step bound at the same x: unpack once.
        if self.unpacked == x {
            return;
        }
        let clock = Instant::now();
        self.generation += 1;
        self.unpacked.clear();
        self.unpacked.extend_from_slice(x);
        self.unpack_impl(x);
        self.timing.unpack_s += clock.elapsed().as_secs_f64();
    }

    fn unpack_impl(&mut self, x: &[f64]) {
        if let Some(m) = self.mpm {
            self.u.resize(self.n_grid, SVector::zeros());
            for i in 0..self.n_grid {
                self.u[i] = Self::v(x, i) - Self::v(self.x_start, i);
            }
            let st = &m.stencils;
            let u = &self.u;
            self.xq.resize(m.x.len(), SVector::zeros());
            self.fq.resize(m.x.len(), SMatrix::zeros());
            self.gu.resize(m.x.len(), SMatrix::zeros());
            self.xq
                .par_iter_mut()
                .zip(self.fq.par_iter_mut())
                .zip(self.gu.par_iter_mut())
                .enumerate()
                .with_min_len(512)
                .for_each(|(p, ((xq, fq), gu))| {
                    let ps = st.particle(p);
                    let mut dx = SVector::<f64, D>::zeros();
                    let mut du = SMatrix::<f64, D, D>::zeros();
                    ps.for_each(|i, w, g| {
                        dx += u[i] * w;
                        du += u[i] * g.transpose();
                    });
                    *xq = m.x[p] + dx;
                    *gu = SMatrix::identity() + du;
                    *fq = *gu * m.f[p];
                });
        }
        for (b, off) in self.fem_offset.iter().enumerate() {
            let n = self.fem[b].x.len();
            let xs = &mut self.fem_x[b];
            for v in 0..n {
                xs[v] = SVector::from_column_slice(&x[off + v * D..off + v * D + D]);
            }
        }
    }

    /// Positions of a pair's points at the unpacked state: the particles' slice itself (no
    /// copy — this runs at every energy, gradient and CCD evaluation), or the FEM boundary
    /// vertices gathered.
    fn points(&self, pair: &Pair<D>) -> Cow<'_, [SVector<f64, D>]> {
        points_of(&self.xq, self.fem, &self.fem_x, pair)
    }

    /// Displacements over the step of pair `k`'s points and of its facets' body (for
    /// friction), into the reused `self.disp`.
    fn fill_displacements(&mut self, k: usize) {
        let pair = &self.pairs[k];
        let (dp, db) = &mut self.disp;
        dp.clear();
        match &pair.points {
            Points::Mpm { range } => {
                let m = self.mpm.expect("MPM pair without MPM state");
                dp.extend((range.0..range.1).map(|p| self.xq[p] - m.x[p]));
            }
            Points::Fem { body } => {
                let b = &self.fem[*body];
                dp.extend(
                    b.boundary
                        .vertices()
                        .iter()
                        .map(|&v| self.fem_x[*body][v] - b.x[v]),
                );
            }
        }
        let f = &self.fem[pair.facets_of];
        db.clear();
        db.extend(
            self.fem_x[pair.facets_of]
                .iter()
                .zip(&f.x)
                .map(|(now, start)| now - start),
        );
    }

    /// Active contact terms of a pair at the unpacked state (into `self.terms`).
    fn collect(&mut self, k: usize) -> Result<(), femp_contact::ContactError> {
        let pair = &self.pairs[k];
        let pts = points_of(&self.xq, self.fem, &self.fem_x, pair);
        let w = weights_of(self.mpm, self.fem, pair);
        let bx = &self.fem_x[pair.facets_of];
        let facets = &self.fem[pair.facets_of].facets;
        broad_phase::candidates_within(
            &pts,
            bx,
            facets,
            pair.potential.barrier.dhat,
            &mut self.cands,
        );
        pair.potential
            .collect_terms(&pts, w, bx, &self.cands, &mut self.terms)
    }

    /// Add the contact (barrier and lagged friction) gradient at the unpacked state into `g`,
    /// keeping the term derivatives for the Hessian at the same state. Returns the number of
    /// active terms and the smallest contact distance.
    fn contact_gradient(&mut self, g: &mut [f64], exact: bool) -> (usize, f64) {
        let mut count = 0;
        let mut dmin = f64::INFINITY;
        let mut cache = std::mem::take(&mut self.contact.per_pair);
        for k in 0..self.pairs.len() {
            let [bar, fric] = &mut cache[k];
            bar.clear();
            fric.clear();
            if self.collect(k).is_err() {
                continue;
            }
            count += self.terms.len();
            for t in &self.terms {
                dmin = dmin.min(t.sq_dist.sqrt());
            }
            let pair = &self.pairs[k];
            let pts = self.points(pair);
            if exact {
                pair.potential.exact_derivatives(
                    &self.terms,
                    &pts,
                    &self.fem_x[pair.facets_of],
                    bar,
                );
            } else {
                pair.potential
                    .derivatives(&self.terms, &pts, &self.fem_x[pair.facets_of], bar);
            }
            self.scatter(k, bar, Some(g), None);
            if !self.friction[k].is_empty() {
                self.fill_displacements(k);
                let (dp, db) = &self.disp;
                friction::derivatives(&self.pairs[k].friction, &self.friction[k], dp, db, fric);
                self.scatter(k, fric, Some(g), None);
            }
        }
        self.contact = ContactDerivatives {
            per_pair: cache,
            computed_at: Some(State {
                generation: self.generation,
                exact,
            }),
            summary: (count, dmin),
        };
        (count, dmin)
    }

    /// The Hessian with PSD-projected element, particle and barrier terms, or (`exact`) the
    /// exact one. Friction's lagged operator is PSD by construction and the same in both.
    fn build_hessian(&mut self, x: &[f64], h: &mut Triplets, exact: bool) {
        self.unpack(x);
        let w = self.w;
        for d in 0..self.n_dofs {
            h.push(d, d, self.mass[d]);
        }
        for p in self.penalties {
            for a in 0..D {
                for b in a..D {
                    h.push(p.node * D + a, p.node * D + b, p.k * p.n[a] * p.n[b]);
                }
            }
        }
        // The particles' blocks (parallel, into the grid Hessian) alongside the elements'
        // triplets (into `h`) and the contact derivatives. The particle side works on `gh` and
        // `fq` taken out of `self` meanwhile; the other side uses neither.
        let mut gh = std::mem::replace(&mut self.gh, GridHessian::new());
        let fq = std::mem::take(&mut self.fq);
        let (mpm, n_grid) = (self.mpm, self.n_grid);
        let (mpm_s, ()) = rayon::join(
            || {
                let clock = Instant::now();
                if let Some(m) = mpm {
                    particle_hessians(m, &fq, n_grid, w, exact, &mut gh);
                }
                clock.elapsed().as_secs_f64()
            },
            || self.element_hessians_and_contact_derivatives(h, exact),
        );
        self.gh = gh;
        self.fq = fq;
        self.timing.mpm_s += mpm_s;
        // The contact terms' blocks (particle–particle ones into the grid Hessian).
        let mut clock = Instant::now();
        let cache = std::mem::take(&mut self.contact.per_pair);
        for (k, [bar, fric]) in cache.iter().enumerate() {
            self.scatter(k, bar, None, Some(h));
            self.scatter(k, fric, None, Some(h));
        }
        self.hess_terms = Some(terms_key(&cache));
        self.contact.per_pair = cache;
        self.timing.contact_s += lap(&mut clock);
        if self.mpm.is_some() {
            let mut counts = std::mem::take(&mut self.emit_counts);
            self.gh.emit(h, &mut counts);
            self.emit_counts = counts;
        }
        self.timing.emit_s += lap(&mut clock);
    }

    /// The elements' Hessian triplets (appended to `h`) and the contact terms' derivatives
    /// (unless the gradient at this state computed them); not the grid Hessian.
    fn element_hessians_and_contact_derivatives(&mut self, h: &mut Triplets, exact: bool) {
        let mut clock = Instant::now();
        let w = self.w;
        for b in 0..self.fem.len() {
            if self.fem[b].fully_prescribed {
                continue;
            }
            let mut trip = std::mem::take(&mut self.fem_trip);
            let el = &self.fem[b].elastic;
            let built = if exact {
                el.exact_hessian_triplets(&self.fem_x[b], w, self.fem_offset[b], &mut trip)
            } else {
                el.hessian_triplets(&self.fem_x[b], w, self.fem_offset[b], &mut trip)
            };
            if built.is_ok() {
                // The upper triangle only: the solver drops the rest (as for the grid's).
                h.reserve(trip.len() / 2 + trip.len() / 8);
                for t in trip.iter().filter(|t| t.row <= t.col) {
                    h.push(t.row, t.col, t.value);
                }
            }
            self.fem_trip = trip;
        }
        self.timing.fem_s += lap(&mut clock);
        if !self.contact.serves_hessian(self.generation, exact) {
            // No gradient at this x and friction operator yet (the Newton solver asks for the
            // Hessian first), or it kept the other kind of barrier Hessian: compute the
            // derivatives (the gradient at this x then reuses them).
            let mut scratch = std::mem::take(&mut self.contact_scratch);
            scratch.clear();
            scratch.resize(self.n_dofs, 0.0);
            self.contact_gradient(&mut scratch, exact);
            self.contact_scratch = scratch;
        }
        self.timing.contact_s += lap(&mut clock);
    }

    /// Recompute the lagged friction operator at `x` (Algorithm 1, lines 5 and 9).
    pub(crate) fn lag_friction(&mut self, x: &[f64]) {
        self.unpack(x);
        self.generation += 1;
        for k in 0..self.pairs.len() {
            if self.pairs[k].friction.mu == 0.0 {
                self.friction[k].clear();
                continue;
            }
            if self.collect(k).is_err() {
                self.friction[k].clear();
                continue;
            }
            let pair = &self.pairs[k];
            let pts = self.points(pair);
            self.friction[k] = friction::lag(
                &pair.potential,
                &self.terms,
                &pts,
                &self.fem_x[pair.facets_of],
            );
        }
    }

    /// The DOF blocks a pair's local point `k` depends on: calls `f(dof_base, weight, entry)`
    /// for each (grid nodes of its stencil with non-zero weight for MPM, `entry` the stencil
    /// entry; its one vertex for FEM, `entry` 0).
    fn point_dofs(&self, pair: &Pair<D>, k: usize, mut f: impl FnMut(usize, f64, usize)) {
        match &pair.points {
            Points::Mpm { range } => {
                let m = self.mpm.expect("MPM pair");
                let mut e = 0;
                m.stencils.particle(range.0 + k).for_each(|i, w, _| {
                    if w != 0.0 {
                        f(i * D, w, e)
                    }
                    e += 1;
                });
            }
            Points::Fem { body } => {
                let v = self.fem[*body].boundary.vertices()[k];
                f(self.fem_offset[*body] + v * D, 1.0, 0);
            }
        }
    }

    /// Add term derivatives (per-point blocks) into gradient and/or Hessian.
    fn scatter(
        &mut self,
        pair_k: usize,
        ders: &[TermDerivatives<D>],
        g: Option<&mut [f64]>,
        h: Option<&mut Triplets>,
    ) {
        let pair = &self.pairs[pair_k];
        let boff = self.fem_offset[pair.facets_of];
        let w = self.w;
        if let Some(g) = g {
            for d in ders {
                let gq = d.grad[0] * w;
                self.point_dofs(pair, d.particle as usize, |base, wt, _| {
                    for a in 0..D {
                        g[base + a] += wt * gq[a];
                    }
                });
                for s in 1..d.n {
                    let base = boff + d.vertices[s - 1] as usize * D;
                    for a in 0..D {
                        g[base + a] += w * d.grad[s][a];
                    }
                }
            }
        }
        if let Some(h) = h {
            let mpm_points = matches!(pair.points, Points::Mpm { .. });
            let mut pdofs: Vec<(usize, f64, usize)> = Vec::with_capacity(27);
            let nn = self.mpm.map_or(0, |m| m.stencils.stencil_len());
            for d in ders {
                // Point's DOF blocks with weights.
                pdofs.clear();
                self.point_dofs(pair, d.particle as usize, |b, wt, e| pdofs.push((b, wt, e)));
                let hqq = d.hess[0][0] * w;
                if mpm_points {
                    let gh = &mut self.gh;
                    for &(ba, wa, ea) in &pdofs {
                        for &(bb, wb, eb) in &pdofs {
                            let k = (ba / D) * gh.slots + gh.pair_slot[ea * nn + eb] as usize;
                            gh.rows[k].m += hqq * (wa * wb);
                            gh.rows[k].nbr = (bb / D) as u32;
                        }
                    }
                } else {
                    for &(ba, wa, _) in &pdofs {
                        for &(bb, wb, _) in &pdofs {
                            push_block(h, ba, bb, &(hqq * (wa * wb)));
                        }
                    }
                }
                for s in 1..d.n {
                    let bs = boff + d.vertices[s - 1] as usize * D;
                    for &(ba, wa, _) in &pdofs {
                        // Blocks start at multiples of D, so each lies wholly above, on or
                        // wholly below the diagonal: of the two mirrored ones, build the one
                        // above (both on it).
                        debug_assert!(ba.is_multiple_of(D) && bs.is_multiple_of(D));
                        if ba <= bs {
                            push_block(h, ba, bs, &(d.hess[0][s] * (w * wa)));
                        }
                        if bs <= ba {
                            push_block(h, bs, ba, &(d.hess[s][0] * (w * wa)));
                        }
                    }
                    for t in 1..d.n {
                        let bt = boff + d.vertices[t - 1] as usize * D;
                        push_block(h, bs, bt, &(d.hess[s][t] * w));
                    }
                }
            }
        }
    }

    /// The contact force of every pair at `x`, summed over the pair's points:
    /// `[barrier, friction]` on the points' body (`−∂B/∂x_points`, `−∂D/∂x_points`, friction
    /// with the operator the last solve used); the facets' body feels the opposite (both
    /// potentials are invariant to a common translation). N in 3D, N/m in 2D. The force on
    /// every particle and FEM vertex (barrier and friction, all pairs) is added into
    /// `on_particles` and `on_vertices[body]`.
    pub(crate) fn pair_forces(
        &mut self,
        x: &[f64],
        on_particles: &mut [SVector<f64, D>],
        on_vertices: &mut [Vec<SVector<f64, D>>],
    ) -> Vec<[SVector<f64, D>; 2]> {
        self.unpack(x);
        let mut out = Vec::with_capacity(self.pairs.len());
        let mut derivs = Vec::new();
        for k in 0..self.pairs.len() {
            let mut f = [SVector::zeros(); 2];
            if self.collect(k).is_ok() {
                for part in 0..2 {
                    let pair = &self.pairs[k];
                    if part == 0 {
                        let pts = self.points(pair);
                        pair.potential.derivatives(
                            &self.terms,
                            &pts,
                            &self.fem_x[pair.facets_of],
                            &mut derivs,
                        );
                    } else if self.friction[k].is_empty() {
                        continue;
                    } else {
                        self.fill_displacements(k);
                        let (dp, db) = &self.disp;
                        friction::derivatives(
                            &pair.friction,
                            &self.friction[k],
                            dp,
                            db,
                            &mut derivs,
                        );
                    }
                    for d in &derivs {
                        f[part] -= d.grad[0];
                        match &pair.points {
                            Points::Mpm { range } => {
                                on_particles[range.0 + d.particle as usize] -= d.grad[0];
                            }
                            Points::Fem { body } => {
                                let v = self.fem[*body].boundary.vertices()[d.particle as usize];
                                on_vertices[*body][v] -= d.grad[0];
                            }
                        }
                        for s in 1..d.n {
                            on_vertices[pair.facets_of][d.vertices[s - 1] as usize] -= d.grad[s];
                        }
                    }
                }
            }
            out.push(f);
        }
        out
    }

    /// Smallest contact distance and number of active terms over all pairs at `x`.
    pub(crate) fn contact_summary(&mut self, x: &[f64]) -> (usize, f64) {
        self.unpack(x);
        let mut n = 0;
        let mut dmin = f64::INFINITY;
        for k in 0..self.pairs.len() {
            if self.collect(k).is_ok() {
                n += self.terms.len();
                for t in &self.terms {
                    dmin = dmin.min(t.sq_dist.sqrt());
                }
            } else {
                dmin = 0.0;
            }
        }
        (n, dmin)
    }

    fn energy_impl(&mut self, x: &[f64]) -> f64 {
        self.unpack(x);
        let w = self.w;
        // Inertia and gravity.
        let mut e = 0.0;
        for d in 0..self.n_dofs {
            let r = x[d] - self.x_hat[d];
            e += 0.5 * self.mass[d] * r * r - w * self.mass[d] * self.gravity[d % D] * x[d];
        }
        for p in self.penalties {
            let r = p.n.dot(&Self::v(x, p.node)) - p.target;
            e += 0.5 * p.k * r * r;
        }
        // MPM elasticity (parallel) alongside the elements' and the contact terms' energies; the
        // particle side works on `fq` taken out of `self` meanwhile (the other side does not
        // use it).
        let fq = std::mem::take(&mut self.fq);
        let mpm = self.mpm;
        let (el, rest) = rayon::join(
            || {
                mpm.map_or(0.0, |m| {
                    // Fixed chunks summed in order: the same bits on any number of threads.
                    const CHUNK: usize = 1024;
                    let n = m.x.len();
                    (0..n.div_ceil(CHUNK))
                        .into_par_iter()
                        .map(|c| {
                            (c * CHUNK..((c + 1) * CHUNK).min(n))
                                .map(|p| {
                                    m.volume[p]
                                        * m.bodies[m.body[p] as usize]
                                            .material
                                            .energy_density(&fq[p])
                                })
                                .sum::<f64>()
                        })
                        .collect::<Vec<f64>>()
                        .into_iter()
                        .sum::<f64>()
                })
            },
            || self.element_and_contact_energy(),
        );
        self.fq = fq;
        if !el.is_finite() {
            return f64::INFINITY;
        }
        e + w * el + rest
    }

    /// The elements' elastic energy and the contact and friction energies (times the
    /// integrator weight); `+∞` if an element is inverted or a contact is infeasible.
    fn element_and_contact_energy(&mut self) -> f64 {
        let w = self.w;
        let mut e = 0.0;
        for (b, body) in self.fem.iter().enumerate() {
            if body.fully_prescribed {
                continue;
            }
            match body.elastic.energy(&self.fem_x[b]) {
                Ok(v) if v.is_finite() => e += w * v,
                _ => return f64::INFINITY,
            }
        }
        for k in 0..self.pairs.len() {
            if self.collect(k).is_err() {
                return f64::INFINITY;
            }
            e += w * self.pairs[k].potential.energy(&self.terms);
            if !self.friction[k].is_empty() {
                self.fill_displacements(k);
                let (dp, db) = &self.disp;
                e += w * friction::energy(&self.pairs[k].friction, &self.friction[k], dp, db);
            }
        }
        e
    }
}

/// See [`StepObjective::points`].
fn points_of<'s, const D: usize>(
    xq: &'s [SVector<f64, D>],
    fem: &[FemBody<D>],
    fem_x: &[Vec<SVector<f64, D>>],
    pair: &Pair<D>,
) -> Cow<'s, [SVector<f64, D>]> {
    match &pair.points {
        Points::Mpm { range } => Cow::Borrowed(&xq[range.0..range.1]),
        Points::Fem { body } => Cow::Owned(
            fem[*body]
                .boundary
                .vertices()
                .iter()
                .map(|&v| fem_x[*body][v])
                .collect(),
        ),
    }
}

/// The weights of a pair's points (borrowed, never copied).
fn weights_of<'a, const D: usize>(
    mpm: Option<&'a Mpm<D>>,
    fem: &'a [FemBody<D>],
    pair: &Pair<D>,
) -> &'a [f64] {
    match &pair.points {
        Points::Mpm { range } => mpm.map_or(&[][..], |m| &m.weight[range.0..range.1]),
        Points::Fem { body } => &fem[*body].vertex_weight,
    }
}

/// The entries of block `b` at rows `r..r+D`, columns `c..c+D` that lie on or above the
/// diagonal (the solver reads only the upper triangle; a block wholly below it adds nothing).
#[inline]
fn push_block<const D: usize>(h: &mut Triplets, r: usize, c: usize, b: &SMatrix<f64, D, D>) {
    for i in 0..D {
        for j in 0..D {
            if r + i <= c + j {
                h.push(r + i, c + j, b[(i, j)]);
            }
        }
    }
}

/// The particles' Hessian blocks `V_p Gᵀ A_p G` (`A_p` the tangent, PSD-projected unless
/// `exact`) into the grid Hessian, particle groups in parallel, each block added into its fixed
/// slot.
fn particle_hessians<const D: usize>(
    m: &Mpm<D>,
    fq: &[SMatrix<f64, D, D>],
    n_grid: usize,
    w: f64,
    exact: bool,
    gh: &mut GridHessian<D>,
) {
    let st = &m.stencils;
    gh.reset(
        n_grid,
        st.stencil_axes(),
        st.grid().kernel().nodes_per_axis(),
    );
    // Particle Hessians V_p Gᵀ A_p G (A_p the tangent, PSD-projected unless `exact`),
    // particle groups in parallel, each block added into its fixed slot.
    let nn = st.stencil_len();
    let (slots, pair_slot) = (gh.slots, &gh.pair_slot);
    st.par_scatter_rows(&mut gh.rows, slots, |particles, rows| {
        // Per group (hundreds of particles), not per particle. Particles come sorted by
        // stencil base within a group, so the blocks of all particles sharing a stencil
        // (one cell, ~particles-per-cell of them) are summed here and scattered once.
        let mut gvec = vec![SVector::<f64, D>::zeros(); nn];
        let mut ids = vec![0usize; nn];
        let mut cell_ids = vec![usize::MAX; nn];
        let mut acc = vec![SMatrix::<f64, D, D>::zeros(); nn * nn];
        let mut flush = |cell_ids: &[usize], acc: &mut [SMatrix<f64, D, D>]| {
            for a in 0..nn {
                let row = rows.row(cell_ids[a]);
                for b in 0..nn {
                    let block = if a <= b {
                        acc[a * nn + b]
                    } else {
                        acc[b * nn + a].transpose()
                    };
                    let slot = &mut row[pair_slot[a * nn + b] as usize];
                    slot.m += block;
                    slot.nbr = cell_ids[b] as u32;
                }
            }
            acc.iter_mut().for_each(|b| *b = SMatrix::zeros());
        };
        for &p in particles {
            let p = p as usize;
            let material = &m.bodies[m.body[p] as usize].material;
            let t: Tangent<D> = if exact {
                material.tangent(&fq[p])
            } else {
                material.tangent_psd(&fq[p])
            };
            let ft = m.f[p].transpose();
            let mut k = 0;
            st.particle(p).for_each(|i, _, grad| {
                ids[k] = i;
                gvec[k] = ft * grad;
                k += 1;
            });
            // The stencil is determined by its first (base) node.
            if ids[0] != cell_ids[0] {
                if cell_ids[0] != usize::MAX {
                    flush(&cell_ids, &mut acc);
                }
                cell_ids.copy_from_slice(&ids);
            }
            chain_hessian_add_upper(&t, &gvec, w * m.volume[p], &mut acc);
        }
        if cell_ids[0] != usize::MAX {
            flush(&cell_ids, &mut acc);
        }
    });
}

impl<const D: usize> Objective for StepObjective<'_, D> {
    fn num_dofs(&self) -> usize {
        self.n_dofs
    }

    fn energy(&mut self, x: &[f64]) -> f64 {
        let clock = Instant::now();
        let e = self.energy_impl(x);
        self.timing.energy_s += clock.elapsed().as_secs_f64();
        e
    }

    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        self.unpack(x);
        let mut clock = Instant::now();
        let w = self.w;
        for d in 0..self.n_dofs {
            g[d] = self.mass[d] * (x[d] - self.x_hat[d]) - w * self.mass[d] * self.gravity[d % D];
        }
        for p in self.penalties {
            let r = p.n.dot(&Self::v(x, p.node)) - p.target;
            for a in 0..D {
                g[p.node * D + a] += p.k * r * p.n[a];
            }
        }
        if let Some(m) = self.mpm {
            // Node forces Σ_p V_p P(F_p) F_pⁿᵀ ∇w_ip, particle groups in parallel.
            let st = &m.stencils;
            let fq = &self.fq;
            self.node_force.clear();
            self.node_force.resize(self.n_grid, SVector::zeros());
            st.par_scatter_rows(&mut self.node_force, 1, |particles, rows| {
                for &p in particles {
                    let p = p as usize;
                    let pk = m.bodies[m.body[p] as usize].material.first_piola(&fq[p])
                        * (w * m.volume[p]);
                    let ft = m.f[p].transpose();
                    st.particle(p).for_each(|i, _, grad| {
                        rows.row(i)[0] += pk * (ft * grad);
                    });
                }
            });
            for (i, f) in self.node_force.iter().enumerate() {
                for a in 0..D {
                    g[i * D + a] += f[a];
                }
            }
        }
        self.timing.mpm_s += lap(&mut clock);
        for b in 0..self.fem.len() {
            if self.fem[b].fully_prescribed {
                continue;
            }
            let off = self.fem_offset[b];
            let n = self.fem[b].x.len();
            let (forces, gb) = &mut self.fem_grad;
            gb.clear();
            gb.resize(n, SVector::zeros());
            self.fem[b]
                .elastic
                .add_gradient_with(&self.fem_x[b], w, forces, gb)
                .expect("a FEM body's positions match its mesh");
            for v in 0..n {
                for a in 0..D {
                    g[off + v * D + a] += gb[v][a];
                }
            }
        }
        self.timing.fem_s += lap(&mut clock);
        let (count, dmin) = if self.contact.serves_gradient(self.generation) {
            // The Hessian at this x computed the contact derivatives (either kind: their
            // gradients are the same): scatter them in the same order.
            let cache = std::mem::take(&mut self.contact.per_pair);
            for (k, [bar, fric]) in cache.iter().enumerate() {
                self.scatter(k, bar, Some(g), None);
                self.scatter(k, fric, Some(g), None);
            }
            self.contact.per_pair = cache;
            self.contact.summary
        } else {
            self.contact_gradient(g, self.prefer_exact)
        };
        self.grad_terms = terms_key(&self.contact.per_pair);
        self.timing.contact_s += lap(&mut clock);
        self.last_contacts = (count, dmin);
    }

    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        self.build_hessian(x, h, false);
    }

    fn exact_hessian(&mut self, x: &[f64], h: &mut Triplets) -> bool {
        self.build_hessian(x, h, true);
        true
    }

    fn hessian_terms_unchanged(&mut self) -> bool {
        self.hess_terms == Some(self.grad_terms)
    }

    fn max_step(&mut self, x: &[f64], p: &[f64]) -> StepBound {
        self.unpack(x);
        let clock = Instant::now();
        // Particle displacements along p (for CCD) and grid increments (for det F).
        let mut sc = std::mem::take(&mut self.bound_scratch);
        let (mut pg, mut dq) = (std::mem::take(&mut sc.pg), std::mem::take(&mut sc.dq));
        pg.clear();
        dq.clear();
        // The particles' motion along p; if it cannot be interpolated (a non-finite direction),
        // no step is known to be safe.
        let mut interpolated = true;
        if let Some(m) = self.mpm {
            pg.extend((0..self.n_grid).map(|i| Self::v(p, i)));
            dq.resize(m.x.len(), SVector::zeros());
            interpolated = transfer::interpolate(&m.stencils, &pg, &mut dq).is_ok();
        }
        let setup_s = clock.elapsed().as_secs_f64();
        // The particles' det F bound (parallel) alongside the elements' and CCD (sequential).
        let this = &*self;
        let ((mpm_alpha, mpm_s), (fem_alpha, fem_s, ccd_alpha, ccd_s)) = rayon::join(
            || {
                let t = Instant::now();
                (this.particle_det_bound(&pg), t.elapsed().as_secs_f64())
            },
            || {
                let t = Instant::now();
                let fem = this.element_det_bound(p, &mut sc.pb);
                let fem_s = t.elapsed().as_secs_f64();
                let ccd = this.ccd_bound(p, &dq, &mut sc);
                (fem, fem_s, ccd, t.elapsed().as_secs_f64() - fem_s)
            },
        );
        (sc.pg, sc.dq) = (pg, dq);
        self.bound_scratch = sc;
        self.timing.inversion_s += setup_s + mpm_s + fem_s;
        self.timing.ccd_s += ccd_s;
        let mut best = StepBound::UNLIMITED;
        for (alpha, limit) in [
            (mpm_alpha, StepLimit::DetF),
            (fem_alpha, StepLimit::DetF),
            (ccd_alpha, StepLimit::Ccd),
            (if interpolated { 1.0 } else { 0.0 }, StepLimit::Other),
        ] {
            if alpha < best.alpha {
                best = StepBound {
                    alpha: alpha.max(0.0),
                    limit: Some(limit),
                };
            }
        }
        best
    }
}

impl<const D: usize> StepObjective<'_, D> {
    /// The largest step fraction (≤ 1) along grid increments `pg` before a particle's det F
    /// reaches zero.
    fn particle_det_bound(&self, pg: &[SVector<f64, D>]) -> f64 {
        let Some(m) = self.mpm else {
            return 1.0;
        };
        let st = &m.stencils;
        let gu = &self.gu;
        (0..m.x.len())
            .into_par_iter()
            .with_min_len(512)
            .map(|q| {
                let mut g1 = SMatrix::<f64, D, D>::zeros();
                st.particle(q).for_each(|i, _, grad| {
                    g1 += pg[i] * grad.transpose();
                });
                first_det_root(&gu[q], &g1).unwrap_or(1.0)
            })
            .reduce(|| 1.0, f64::min)
    }

    /// The same for the FEM elements (free bodies) along `p`.
    fn element_det_bound(&self, p: &[f64], pb: &mut Vec<SVector<f64, D>>) -> f64 {
        let mut best = 1.0f64;
        for (b, body) in self.fem.iter().enumerate() {
            if body.fully_prescribed {
                continue;
            }
            let off = self.fem_offset[b];
            pb.clear();
            pb.extend((0..body.x.len()).map(|v| Self::v(&p[off..], v)));
            // An error (a non-finite direction) leaves no step known to be inversion-free.
            let a = body
                .elastic
                .max_inversion_free_step(&self.fem_x[b], pb)
                .unwrap_or(0.0);
            best = best.min(a);
        }
        best
    }

    /// The largest step fraction (≤ 1) before a point of any pair meets a facet (CCD), the
    /// particles moving by `dq`.
    fn ccd_bound(&self, p: &[f64], dq: &[SVector<f64, D>], sc: &mut BoundScratch<D>) -> f64 {
        let mut best = 1.0f64;
        // CCD of every pair along the full step.
        for pair in self.pairs {
            let x0 = self.points(pair);
            let dx: &[SVector<f64, D>] = match &pair.points {
                Points::Mpm { range } => &dq[range.0..range.1],
                Points::Fem { body } => {
                    let off = self.fem_offset[*body];
                    sc.dx.clear();
                    sc.dx.extend(
                        self.fem[*body]
                            .boundary
                            .vertices()
                            .iter()
                            .map(|&v| Self::v(&p[off..], v)),
                    );
                    &sc.dx
                }
            };
            let fb = pair.facets_of;
            let off = self.fem_offset[fb];
            let bx = &self.fem_x[fb];
            sc.bdx.clear();
            sc.bdx.extend((0..bx.len()).map(|v| Self::v(&p[off..], v)));
            sc.x1.clear();
            sc.x1.extend(x0.iter().zip(dx).map(|(a, b)| a + b));
            sc.b1.clear();
            sc.b1.extend(bx.iter().zip(&sc.bdx).map(|(a, b)| a + b));
            broad_phase::candidates_swept(
                &x0,
                &sc.x1,
                bx,
                &sc.b1,
                &self.fem[fb].facets,
                0.0,
                &mut sc.cands,
            );
            let (alpha, _) = ccd::max_step(
                &x0,
                dx,
                bx,
                &sc.bdx,
                &self.fem[fb].facets,
                &sc.cands,
                &CcdOptions::default(),
            );
            best = best.min(alpha);
        }
        best
    }
}

/// Buffers of [`Objective::max_step`], kept across Newton iterations: grid increments, particle
/// displacements, and per pair the moving points' and facets' increments and end positions and
/// the swept broad phase's candidates.
#[derive(Default)]
struct BoundScratch<const D: usize> {
    pg: Vec<SVector<f64, D>>,
    dq: Vec<SVector<f64, D>>,
    pb: Vec<SVector<f64, D>>,
    dx: Vec<SVector<f64, D>>,
    bdx: Vec<SVector<f64, D>>,
    x1: Vec<SVector<f64, D>>,
    b1: Vec<SVector<f64, D>>,
    cands: Candidates,
}

#[cfg(test)]
mod tests {
    //! The step objective's derivatives against central finite differences, on scenes that
    //! exercise every term: MPM and FEM elasticity, inertia, gravity, barrier contact of
    //! particles and of FEM vertices, lagged friction, and an oblique slip penalty.

    use std::path::Path;

    use femp_solver::{Objective, Triplets};

    use crate::scene;
    use crate::world::World;

    /// Pseudo-random numbers in [−1, 1] (deterministic).
    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
            })
            .collect()
    }

    fn world<const D: usize>(json: &str) -> World<D> {
        let s = scene::parse(json, "fd.json", Path::new(".").to_path_buf(), "fd").unwrap();
        World::<D>::build(s).unwrap()
    }

    /// A 2D scene: an MPM block whose lowest particles are within d̂ (5 mm) of a free FEM block, a second FEM block
    /// touching it from the side, friction on both pairs, gravity and an oblique slip wall.
    const SCENE_2D: &str = r#"{
      "dimension": 2, "gravity": [0.3, -9.81],
      "time": { "dt": 0.01, "duration": 1 },
      "mpm": { "grid_spacing": 0.1 },
      "bodies": [
        { "kind": "mpm", "name": "block", "shape": { "box": { "min": [-0.2, -0.02], "max": [0.2, 0.3] } },
          "material": { "E": 1e4, "nu": 0.3, "rho": 1000 }, "velocity": [0.5, -0.2], "angular_velocity": 1.0 },
        { "kind": "fem", "name": "base", "mesh": { "rectangle": { "min": [-0.5, -0.2], "max": [0.5, 0.0], "cells": [5, 2] } },
          "material": { "E": 1e4, "nu": 0.3, "rho": 1000 } },
        { "kind": "fem", "name": "side", "mesh": { "rectangle": { "min": [0.503, -0.2], "max": [0.7, 0.1], "cells": [2, 3] } },
          "material": { "model": "linear", "E": 2e4, "nu": 0.2, "rho": 500 } }
      ],
      "contact": { "dhat": 0.01, "kappa": 1e3, "friction": 0.4, "eps_v": 0.01 },
      "boundaries": [ { "shape": { "half_plane": { "point": [-0.6, 0], "normal": [0.8, 0.6] } }, "condition": "slip" } ]
    }"#;

    /// 3D: one particle per cell (at cell centres, 5 cm above the FEM block) within d̂ = 6 cm.
    const SCENE_3D: &str = r#"{
      "dimension": 3, "gravity": [0, 0, -9.81],
      "time": { "dt": 0.01, "duration": 1 },
      "mpm": { "grid_spacing": 0.1 },
      "bodies": [
        { "kind": "mpm", "name": "block", "shape": { "box": { "min": [-0.1, -0.1, 0.001], "max": [0.1, 0.1, 0.2] } },
          "particles_per_cell": 1,
          "material": { "E": 1e4, "nu": 0.3, "rho": 1000 }, "velocity": [0.5, 0, -0.2] },
        { "kind": "fem", "name": "base", "mesh": { "cuboid": { "min": [-0.3, -0.3, -0.1], "max": [0.3, 0.3, 0.0], "cells": [3, 3, 1] } },
          "material": { "E": 1e4, "nu": 0.3, "rho": 1000 } }
      ],
      "contact": { "dhat": 0.06, "kappa": 1e3, "friction": 0.4, "eps_v": 0.01 }
    }"#;

    /// Gradient against central differences of the energy at a perturbed feasible state,
    /// with friction lagged at the start. Returns the number of active contact terms.
    fn check_gradient<const D: usize>(json: &str, amplitude: f64) -> usize {
        let mut w = world::<D>(json);
        let setup = w.setup(w.bfemp().unwrap().integrator).unwrap();
        let mut obj = setup.objective(&w);
        obj.lag_friction(&setup.x0);
        let r = noise(setup.n_dofs, 7);
        let x: Vec<f64> = (0..setup.n_dofs)
            .map(|d| setup.x0[d] + amplitude * r[d])
            .collect();
        let e0 = obj.energy(&x);
        assert!(e0.is_finite(), "perturbed state infeasible");
        let mut g = vec![0.0; setup.n_dofs];
        obj.gradient(&x, &mut g);
        let (terms, _) = obj.last_contacts;
        let gmax = g.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let h = 1e-7;
        let mut xp = x.clone();
        let mut worst = 0.0f64;
        for d in 0..setup.n_dofs {
            xp[d] = x[d] + h;
            let ep = obj.energy(&xp);
            xp[d] = x[d] - h;
            let em = obj.energy(&xp);
            xp[d] = x[d];
            let fd = (ep - em) / (2.0 * h);
            let err = (fd - g[d]).abs() / (gmax * 1e-5 + g[d].abs().max(fd.abs()));
            worst = worst.max(err);
            assert!(
                err < 1e-4,
                "dof {d} of {}: analytic {} vs FD {fd} (|g|max {gmax:e})",
                setup.n_dofs,
                g[d]
            );
        }
        assert!(worst.is_finite());
        terms
    }

    #[test]
    fn gradient_matches_finite_differences_2d() {
        let terms = check_gradient::<2>(SCENE_2D, 1e-4);
        assert!(
            terms > 10,
            "the scene must have active contact terms ({terms})"
        );
    }

    #[test]
    fn gradient_matches_finite_differences_3d() {
        let terms = check_gradient::<3>(SCENE_3D, 1e-4);
        assert!(
            terms >= 4,
            "the scene must have active contact terms ({terms})"
        );
    }

    /// Hessian against central differences of the gradient where no PSD projection acts:
    /// inertia, stretched elasticity, gravity, penalties (bodies apart, no contact).
    fn check_hessian<const D: usize>(json: &str) {
        let mut w = world::<D>(json);
        let setup = w.setup(w.bfemp().unwrap().integrator).unwrap();
        let n = setup.n_dofs;
        let mut obj = setup.objective(&w);
        // A uniform 5 % expansion (every F ≈ 1.05 I, where the neo-Hookean tangent is positive
        // definite and its projection is the identity) plus a small random perturbation.
        let r = noise(n, 11);
        let x: Vec<f64> = (0..n).map(|d| 1.05 * setup.x0[d] + 1e-4 * r[d]).collect();
        let mut t = Triplets::default();
        obj.hessian(&x, &mut t);
        assert_eq!(obj.last_contacts.0, 0, "scene must be contact-free");
        // Without contact terms, the grid's and the elements' blocks come as their upper
        // triangle only (the solver ignores the rest; half the triplets to assemble).
        assert!(
            t.iter().all(|(r, c, _)| r <= c),
            "a triplet below the diagonal"
        );
        assert_gradient_derivative(&mut obj, &x, &dense(&t, n), 1e-6);
    }

    /// `hd` (dense, n × n) equals the central difference (step `h`) of the objective's
    /// gradient at `x`, to 1e-5 of its largest entry plus 1e-4 relative.
    fn assert_gradient_derivative<const D: usize>(
        obj: &mut super::StepObjective<'_, D>,
        x: &[f64],
        hd: &[f64],
        h: f64,
    ) {
        let n = x.len();
        let hmax = hd.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let (mut gp, mut gm) = (vec![0.0; n], vec![0.0; n]);
        let mut xp = x.to_vec();
        for c in 0..n {
            xp[c] = x[c] + h;
            gp.iter_mut().for_each(|v| *v = 0.0);
            obj.gradient(&xp, &mut gp);
            xp[c] = x[c] - h;
            gm.iter_mut().for_each(|v| *v = 0.0);
            obj.gradient(&xp, &mut gm);
            xp[c] = x[c];
            for r in 0..n {
                let fd = (gp[r] - gm[r]) / (2.0 * h);
                let an = hd[r * n + c];
                assert!(
                    (fd - an).abs() <= 1e-5 * hmax + 1e-4 * an.abs(),
                    "H[{r}][{c}]: analytic {an} vs FD {fd} (max {hmax:e})"
                );
            }
        }
    }

    #[test]
    fn hessian_matches_finite_differences_without_contact_2d() {
        check_hessian::<2>(
            &SCENE_2D
                .replace("-0.02], \"max\": [0.2, 0.3]", "0.1], \"max\": [0.2, 0.3]")
                .replace("0.503", "0.6"),
        );
    }

    #[test]
    fn hessian_matches_finite_differences_without_contact_3d() {
        check_hessian::<3>(
            &SCENE_3D
                .replace("0.001], \"max\"", "0.1], \"max\"")
                .replace("0.06", "0.01"),
        );
    }

    /// `exact_hessian` against central differences of the gradient with contact terms active
    /// (frictionless: friction's lagged operator is the same in both Hessians), and different
    /// from the projected one there; the gradient's kept contact derivatives are re-made when
    /// the other kind of Hessian is asked for (exact, projected, exact again).
    fn check_exact_hessian<const D: usize>(json: &str) {
        let mut w = world::<D>(json);
        let setup = w.setup(w.bfemp().unwrap().integrator).unwrap();
        let n = setup.n_dofs;
        let mut obj = setup.objective(&w);
        let r = noise(n, 13);
        let x: Vec<f64> = (0..n).map(|d| setup.x0[d] + 1e-4 * r[d]).collect();
        let mut g = vec![0.0; n];
        obj.prefer_exact = true;
        obj.gradient(&x, &mut g);
        assert!(obj.last_contacts.0 > 0, "the scene must have contact terms");
        let mut t = Triplets::default();
        assert!(obj.exact_hessian(&x, &mut t));
        // Contact blocks, like the grid's and the elements', come as their upper triangle.
        assert!(
            t.iter().all(|(r, c, _)| r <= c),
            "a triplet below the diagonal"
        );
        let he = dense(&t, n);
        let mut t = Triplets::default();
        obj.hessian(&x, &mut t);
        let hp = dense(&t, n);
        let mut t = Triplets::default();
        obj.exact_hessian(&x, &mut t);
        assert_eq!(dense(&t, n), he, "exact again after the projected one");
        let hmax = he.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let diff = he
            .iter()
            .zip(&hp)
            .fold(0.0f64, |a, (u, v)| a.max((u - v).abs()));
        assert!(diff > 1e-6 * hmax, "projection inactive: {diff:e}");
        assert_gradient_derivative(&mut obj, &x, &he, 1e-7);
    }

    #[test]
    fn exact_hessian_matches_finite_differences_with_contact_2d() {
        check_exact_hessian::<2>(&SCENE_2D.replace("\"friction\": 0.4", "\"friction\": 0"));
    }

    #[test]
    fn exact_hessian_matches_finite_differences_with_contact_3d() {
        check_exact_hessian::<3>(&SCENE_3D.replace("\"friction\": 0.4", "\"friction\": 0"));
    }

    /// The symmetric matrix the solver sees: the triplets' upper triangle, mirrored (entries
    /// below the diagonal are ignored by the solver, and the grid Hessian leaves them out).
    fn dense(t: &Triplets, n: usize) -> Vec<f64> {
        let mut hd = vec![0.0; n * n];
        for (r, c, v) in t.iter().filter(|&(r, c, _)| r <= c) {
            hd[r * n + c] += v;
            if r != c {
                hd[c * n + r] += v;
            }
        }
        hd
    }

    /// `hessian_terms_unchanged` (the solver's licence to reuse a Hessian) holds at the
    /// Hessian's own point and at a nearby one with the same contacts, and fails before any
    /// Hessian and once the contact set changed (the particles moved out of reach).
    #[test]
    fn hessian_terms_unchanged_tracks_the_contact_set() {
        let mut w = world::<2>(SCENE_2D);
        let setup = w.setup(w.bfemp().unwrap().integrator).unwrap();
        let n = setup.n_dofs;
        let r = noise(n, 11);
        let x: Vec<f64> = (0..n).map(|d| setup.x0[d] + 1e-4 * r[d]).collect();
        let mut obj = setup.objective(&w);
        obj.lag_friction(&setup.x0);
        let mut g = vec![0.0; n];
        obj.gradient(&x, &mut g);
        assert!(
            obj.last_contacts.0 > 10,
            "contacts: {}",
            obj.last_contacts.0
        );
        assert!(!obj.hessian_terms_unchanged(), "no Hessian yet");
        let mut t = Triplets::default();
        obj.hessian(&x, &mut t);
        obj.gradient(&x, &mut g);
        assert!(obj.hessian_terms_unchanged());
        let near: Vec<f64> = (0..n).map(|d| x[d] + 1e-9 * r[(d + 1) % n]).collect();
        obj.gradient(&near, &mut g);
        assert!(obj.hessian_terms_unchanged());
        // The grid (and so every particle) 100 m away, out of the contact distance.
        let away: Vec<f64> = (0..n)
            .map(|d| x[d] + if d < obj.n_grid * 2 { 100.0 } else { 0.0 })
            .collect();
        let near_contacts = obj.last_contacts.0;
        obj.gradient(&away, &mut g);
        // What is left: the two FEM bodies' contact with each other.
        assert!(
            obj.last_contacts.0 < near_contacts,
            "{near_contacts} → {}",
            obj.last_contacts.0
        );
        assert!(!obj.hessian_terms_unchanged());
        obj.hessian(&away, &mut t);
        obj.gradient(&away, &mut g);
        assert!(obj.hessian_terms_unchanged());
    }

    /// The Hessian built from the derivatives the gradient kept equals one computed afresh, and
    /// a new friction operator or a new x invalidates what was kept.
    /// The Newton solver asks for the Hessian before the gradient: the gradient then scatters
    /// the contact derivatives the Hessian computed — bitwise the gradient computed afresh, with
    /// the same contact count and smallest distance, for either kind of Hessian, and not after
    /// the friction operator was lagged again.
    #[test]
    fn gradient_after_the_hessian_equals_a_fresh_one() {
        let mut w = world::<2>(SCENE_2D);
        let setup = w.setup(w.bfemp().unwrap().integrator).unwrap();
        let n = setup.n_dofs;
        let r = noise(n, 7);
        let x: Vec<f64> = (0..n).map(|d| setup.x0[d] + 1e-4 * r[d]).collect();
        let fresh = |lag_at: &[f64]| {
            let mut obj = setup.objective(&w);
            obj.lag_friction(lag_at);
            let mut g = vec![0.0; n];
            obj.gradient(&x, &mut g);
            (g, obj.last_contacts)
        };
        let bits = |g: &[f64]| g.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        for exact in [false, true] {
            let mut obj = setup.objective(&w);
            obj.lag_friction(&setup.x0);
            let mut t = Triplets::default();
            if exact {
                obj.exact_hessian(&x, &mut t);
            } else {
                obj.hessian(&x, &mut t);
            }
            let mut g = vec![0.0; n];
            obj.gradient(&x, &mut g);
            let (g0, contacts) = fresh(&setup.x0);
            assert!(contacts.0 > 10, "contact terms: {}", contacts.0);
            assert_eq!(bits(&g), bits(&g0), "exact = {exact}");
            assert_eq!(obj.last_contacts.0, contacts.0);
            assert_eq!(obj.last_contacts.1.to_bits(), contacts.1.to_bits());
            // Friction lagged again at x: the cached derivatives are stale.
            obj.lag_friction(&x);
            obj.gradient(&x, &mut g);
            let (g1, _) = fresh(&x);
            assert_eq!(bits(&g), bits(&g1), "relagged, exact = {exact}");
            assert_ne!(
                bits(&g1),
                bits(&g0),
                "the friction operator must matter here"
            );
        }
    }

    #[test]
    fn hessian_from_the_gradients_contact_derivatives_equals_a_fresh_one() {
        let mut w = world::<2>(SCENE_2D);
        let setup = w.setup(w.bfemp().unwrap().integrator).unwrap();
        let n = setup.n_dofs;
        let r = noise(n, 5);
        let x: Vec<f64> = (0..n).map(|d| setup.x0[d] + 1e-4 * r[d]).collect();
        let y: Vec<f64> = (0..n).map(|d| setup.x0[d] - 2e-4 * r[d]).collect();
        let fresh = |lag_at: &[f64], at: &[f64]| {
            let mut obj = setup.objective(&w);
            obj.lag_friction(lag_at);
            let mut t = Triplets::default();
            obj.hessian(at, &mut t);
            dense(&t, n)
        };
        let same = |a: &[f64], b: &[f64], what: &str| {
            let m = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (k, (u, v)) in a.iter().zip(b).enumerate() {
                assert!((u - v).abs() <= 1e-12 * m, "{what}: entry {k}: {u} vs {v}");
            }
        };
        let mut obj = setup.objective(&w);
        obj.lag_friction(&setup.x0);
        let mut g = vec![0.0; n];
        obj.gradient(&x, &mut g);
        assert!(
            obj.last_contacts.0 > 10,
            "contact terms: {}",
            obj.last_contacts.0
        );
        let mut t = Triplets::default();
        obj.hessian(&x, &mut t);
        let cached = dense(&t, n);
        same(&cached, &fresh(&setup.x0, &x), "kept derivatives");
        // A different x after the gradient.
        t = Triplets::default();
        obj.hessian(&y, &mut t);
        same(&dense(&t, n), &fresh(&setup.x0, &y), "new x");
        // A new friction operator (lagged at the same x) between gradient and Hessian.
        obj.gradient(&x, &mut g);
        obj.lag_friction(&x);
        t = Triplets::default();
        obj.hessian(&x, &mut t);
        let relagged = dense(&t, n);
        same(&relagged, &fresh(&x, &x), "new friction operator");
        assert!(
            relagged.iter().zip(&cached).any(|(a, b)| a != b),
            "the friction operator must matter in this scene"
        );
    }
}
