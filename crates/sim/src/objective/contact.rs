//! Barrier contact `w Σ_k B_k` and lagged friction `w Σ_k D_k` of every pair (points — MPM
//! particles or a FEM body's boundary vertices — against a FEM body's facets): terms,
//! derivatives scattered to the DOFs the points depend on, and the CCD step bound.

use std::borrow::Cow;

use femp_contact::broad_phase::{self, Candidates};
use femp_contact::ccd::{self, CcdOptions};
use femp_contact::friction::{self, FrictionParams, FrictionTerm};
use femp_contact::{ContactTerm, TermDerivatives};
use femp_solver::Triplets;
use nalgebra::{SMatrix, SVector};

use super::config::{Configuration, Dofs, block};
use super::particles::GridHessian;
use crate::bodies::{FemBody, Mpm, Pair, Points};

/// The contact term: the pairs, their lagged friction operators, and the buffers and derivative
/// cache the evaluations share.
pub(super) struct Contact<'a, const D: usize> {
    mpm: Option<&'a Mpm<D>>,
    fem: &'a [FemBody<D>],
    pairs: &'a [Pair<D>],
    /// Per pair, its friction at the step's Δt.
    friction_params: Vec<FrictionParams>,
    /// Friction terms lagged per pair (empty when μ = 0).
    friction: Vec<Vec<FrictionTerm<D>>>,
    cands: Candidates,
    /// The active terms of the last pair collected ([`Contact::collect`]).
    terms: Vec<ContactTerm>,
    /// Displacements over the step of a pair's points and facet body, for friction
    /// ([`Contact::fill_displacements`]).
    disp: (Vec<SVector<f64, D>>, Vec<SVector<f64, D>>),
    /// The contact terms' derivatives at one state, shared by the gradient and the Hessian.
    derivatives: ContactDerivatives<D>,
    /// A scratch gradient for a Hessian that computes the derivatives first.
    scratch: Vec<f64>,
    /// Which barrier terms were active at the last gradient and at the last Hessian
    /// ([`terms_key`]), for [`Contact::hessian_terms_unchanged`].
    grad_terms: u64,
    hess_terms: Option<u64>,
    /// Buffers of the CCD bound.
    ccd: CcdScratch<D>,
    /// Per pair, the friction terms a Newton direction carries through their stick zone
    /// ([`Contact::begin_stick_model`]); modelled as stuck while `model` is on.
    stuck: Vec<Vec<bool>>,
    model: bool,
}

/// Buffers of [`Contact::ccd_bound`], kept across Newton iterations: per pair the moving
/// points' and facets' increments and end positions and the swept broad phase's candidates.
#[derive(Default)]
struct CcdScratch<const D: usize> {
    dx: Vec<SVector<f64, D>>,
    bdx: Vec<SVector<f64, D>>,
    x1: Vec<SVector<f64, D>>,
    b1: Vec<SVector<f64, D>>,
    cands: Candidates,
}

impl<'a, const D: usize> Contact<'a, D> {
    /// The contact term of `pairs` in a step of length `dt`.
    pub fn new(
        mpm: Option<&'a Mpm<D>>,
        fem: &'a [FemBody<D>],
        pairs: &'a [Pair<D>],
        dt: f64,
    ) -> Self {
        Self {
            mpm,
            fem,
            pairs,
            friction_params: pairs.iter().map(|p| p.friction.at(dt)).collect(),
            friction: vec![Vec::new(); pairs.len()],
            cands: Candidates::default(),
            terms: Vec::new(),
            disp: (Vec::new(), Vec::new()),
            derivatives: ContactDerivatives {
                per_pair: (0..pairs.len()).map(|_| [Vec::new(), Vec::new()]).collect(),
                computed_at: None,
                summary: (0, f64::INFINITY),
            },
            scratch: Vec::new(),
            grad_terms: 0,
            hess_terms: None,
            ccd: CcdScratch::default(),
            stuck: vec![Vec::new(); pairs.len()],
            model: false,
        }
    }

    /// Displacements over the step of pair `k`'s points and of its facets' body (for
    /// friction), into the reused `self.disp`.
    fn fill_displacements(&mut self, cfg: &Configuration<D>, k: usize) {
        let pair = &self.pairs[k];
        let (dp, db) = &mut self.disp;
        dp.clear();
        match &pair.points {
            Points::Mpm { range } => {
                let m = self.mpm.expect("MPM pair without MPM state");
                dp.extend((range.0..range.1).map(|p| cfg.xq[p] - m.x[p]));
            }
            Points::Fem { body } => {
                let b = &self.fem[*body];
                dp.extend(
                    b.boundary
                        .vertices()
                        .iter()
                        .map(|&v| cfg.fem_x[*body][v] - b.x[v]),
                );
            }
        }
        let f = &self.fem[pair.facets_of];
        db.clear();
        db.extend(
            cfg.fem_x[pair.facets_of]
                .iter()
                .zip(&f.x)
                .map(|(now, start)| now - start),
        );
    }

    /// Active contact terms of pair `k` at `cfg` (into `self.terms`).
    fn collect(
        &mut self,
        cfg: &Configuration<D>,
        k: usize,
    ) -> Result<(), femp_contact::ContactError> {
        let pair = &self.pairs[k];
        let pts = points_of(&cfg.xq, self.fem, &cfg.fem_x, pair);
        let w = weights_of(self.mpm, self.fem, pair);
        let bx = &cfg.fem_x[pair.facets_of];
        let facets = &self.fem[pair.facets_of].facets;
        pair.collect_terms(
            &pts,
            w,
            (bx, facets),
            pair.potential.barrier.dhat,
            (&mut self.cands, &mut self.terms),
        )
    }

    /// Add `w (B_k + D_k)` of every pair to `e`; `+∞` if a contact is infeasible.
    pub fn add_energy(&mut self, cfg: &Configuration<D>, w: f64, mut e: f64) -> f64 {
        for k in 0..self.pairs.len() {
            if self.collect(cfg, k).is_err() {
                return f64::INFINITY;
            }
            e += w * self.pairs[k].potential.energy(&self.terms);
            if !self.friction[k].is_empty() {
                self.fill_displacements(cfg, k);
                let (dp, db) = &self.disp;
                e += w * friction::energy(&self.friction_params[k], &self.friction[k], dp, db);
            }
        }
        e
    }

    /// Add the contact (barrier and lagged friction) gradient at `cfg` into `g`, keeping the
    /// term derivatives (the barrier's Hessian `exact` or projected) for a Hessian at the same
    /// state — or scattering the ones a Hessian at this state computed. Returns the number of
    /// active terms and the smallest contact distance.
    pub fn add_gradient(
        &mut self,
        cfg: &Configuration<D>,
        dofs: &Dofs,
        w: f64,
        exact: bool,
        g: &mut [f64],
    ) -> (usize, f64) {
        let summary = if self.derivatives.serves_gradient(cfg.generation) {
            // The Hessian at this x computed the contact derivatives (either kind: their
            // gradients are the same): scatter them in the same order.
            for (k, [bar, fric]) in self.derivatives.per_pair.iter().enumerate() {
                self.scatter(k, bar, dofs, w, Some(g), None);
                self.scatter(k, fric, dofs, w, Some(g), None);
            }
            self.derivatives.summary
        } else {
            self.compute(cfg, dofs, w, exact, g)
        };
        self.grad_terms = terms_key(&self.derivatives.per_pair);
        summary
    }

    /// Compute the term derivatives at `cfg` into the cache and scatter their gradient into
    /// `g`.
    fn compute(
        &mut self,
        cfg: &Configuration<D>,
        dofs: &Dofs,
        w: f64,
        exact: bool,
        g: &mut [f64],
    ) -> (usize, f64) {
        let mut count = 0;
        let mut dmin = f64::INFINITY;
        let mut cache = std::mem::take(&mut self.derivatives.per_pair);
        for k in 0..self.pairs.len() {
            let [bar, fric] = &mut cache[k];
            bar.clear();
            fric.clear();
            if self.collect(cfg, k).is_err() {
                continue;
            }
            count += self.terms.len();
            for t in &self.terms {
                dmin = dmin.min(t.sq_dist.sqrt());
            }
            let pair = &self.pairs[k];
            let pts = points_of(&cfg.xq, self.fem, &cfg.fem_x, pair);
            if exact {
                pair.potential.exact_derivatives(
                    &self.terms,
                    &pts,
                    &cfg.fem_x[pair.facets_of],
                    bar,
                );
            } else {
                pair.potential
                    .derivatives(&self.terms, &pts, &cfg.fem_x[pair.facets_of], bar);
            }
            self.scatter(k, bar, dofs, w, Some(g), None);
            if !self.friction[k].is_empty() {
                self.fill_displacements(cfg, k);
                let (dp, db) = &self.disp;
                let stuck: &[bool] = if self.model { &self.stuck[k] } else { &[] };
                friction::model_derivatives(
                    &self.friction_params[k],
                    &self.friction[k],
                    dp,
                    db,
                    stuck,
                    fric,
                );
                self.scatter(k, fric, dofs, w, Some(g), None);
            }
        }
        self.derivatives = ContactDerivatives {
            per_pair: cache,
            computed_at: Some(State {
                generation: cfg.generation,
                exact,
            }),
            summary: (count, dmin),
        };
        (count, dmin)
    }

    /// Make sure the cached term derivatives are those of a Hessian (`exact` or projected) at
    /// `cfg`: unless the gradient at this state computed them, compute them (the gradient at
    /// this state then reuses them).
    pub fn prepare_hessian(&mut self, cfg: &Configuration<D>, dofs: &Dofs, w: f64, exact: bool) {
        if self.derivatives.serves_hessian(cfg.generation, exact) {
            return;
        }
        // No gradient at this x and friction operator yet (the Newton solver asks for the
        // Hessian first), or it kept the other kind of barrier Hessian.
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.clear();
        scratch.resize(dofs.n, 0.0);
        self.compute(cfg, dofs, w, exact, &mut scratch);
        self.scratch = scratch;
    }

    /// Scatter the cached term derivatives' Hessian blocks: into `h`, and those between grid
    /// nodes (particle points) into the grid Hessian `gh`.
    pub fn scatter_hessian(
        &mut self,
        dofs: &Dofs,
        w: f64,
        h: &mut Triplets,
        gh: &mut GridHessian<D>,
    ) {
        for (k, [bar, fric]) in self.derivatives.per_pair.iter().enumerate() {
            self.scatter(k, bar, dofs, w, None, Some((&mut *h, &mut *gh)));
            self.scatter(k, fric, dofs, w, None, Some((&mut *h, &mut *gh)));
        }
        self.hess_terms = Some(terms_key(&self.derivatives.per_pair));
    }

    /// Whether the last Hessian had the same active barrier terms as the last gradient.
    pub fn hessian_terms_unchanged(&self) -> bool {
        self.hess_terms == Some(self.grad_terms)
    }

    /// Recompute the lagged friction operator at `cfg` (Algorithm 1, lines 5 and 9).
    /// Returns the number of friction terms.
    pub fn lag_friction(&mut self, cfg: &Configuration<D>) -> usize {
        // The friction Hessian changes with the operator: no reuse of a matrix built before.
        self.hess_terms = None;
        for k in 0..self.pairs.len() {
            if self.pairs[k].friction.mu == 0.0 {
                self.friction[k].clear();
                continue;
            }
            if self.collect(cfg, k).is_err() {
                self.friction[k].clear();
                continue;
            }
            let pair = &self.pairs[k];
            let pts = points_of(&cfg.xq, self.fem, &cfg.fem_x, pair);
            self.friction[k] = friction::lag(
                &pair.potential,
                &self.terms,
                &pts,
                &cfg.fem_x[pair.facets_of],
            );
        }
        self.friction.iter().map(Vec::len).sum()
    }

    /// The DOF blocks a pair's local point `k` depends on: calls `f(dof_base, weight, entry)`
    /// for each (grid nodes of its stencil with non-zero weight for MPM, `entry` the stencil
    /// entry; its one vertex for FEM, `entry` 0).
    fn point_dofs(
        &self,
        dofs: &Dofs,
        pair: &Pair<D>,
        k: usize,
        mut f: impl FnMut(usize, f64, usize),
    ) {
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
                f(dofs.fem_offset[*body] + v * D, 1.0, 0);
            }
        }
    }

    /// Add term derivatives (per-point blocks) into gradient and/or Hessian (blocks between
    /// grid nodes into the grid Hessian).
    fn scatter(
        &self,
        pair_k: usize,
        ders: &[TermDerivatives<D>],
        dofs: &Dofs,
        w: f64,
        g: Option<&mut [f64]>,
        h: Option<(&mut Triplets, &mut GridHessian<D>)>,
    ) {
        let pair = &self.pairs[pair_k];
        let boff = dofs.fem_offset[pair.facets_of];
        if let Some(g) = g {
            for d in ders {
                let gq = d.grad[0] * w;
                self.point_dofs(dofs, pair, d.particle as usize, |base, wt, _| {
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
        if let Some((h, gh)) = h {
            let mpm_points = matches!(pair.points, Points::Mpm { .. });
            let mut pdofs: Vec<(usize, f64, usize)> = Vec::with_capacity(27);
            let nn = self.mpm.map_or(0, |m| m.stencils.stencil_len());
            for d in ders {
                // Point's DOF blocks with weights.
                pdofs.clear();
                self.point_dofs(dofs, pair, d.particle as usize, |b, wt, e| {
                    pdofs.push((b, wt, e))
                });
                let hqq = d.hess[0][0] * w;
                if mpm_points {
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

    /// The contact force of every pair at `cfg`, summed over the pair's points:
    /// `[barrier, friction]` on the points' body (`−∂B/∂x_points`, `−∂D/∂x_points`, friction
    /// with the operator the last solve used); the facets' body feels the opposite (both
    /// potentials are invariant to a common translation). N in 3D, N/m in 2D. The force on
    /// every particle and FEM vertex (barrier and friction, all pairs) is added into
    /// `on_particles` and `on_vertices[body]`.
    pub fn pair_forces(
        &mut self,
        cfg: &Configuration<D>,
        on_particles: &mut [SVector<f64, D>],
        on_vertices: &mut [Vec<SVector<f64, D>>],
    ) -> Vec<[SVector<f64, D>; 2]> {
        let mut out = Vec::with_capacity(self.pairs.len());
        let mut derivs = Vec::new();
        for k in 0..self.pairs.len() {
            let mut f = [SVector::zeros(); 2];
            if self.collect(cfg, k).is_ok() {
                for part in 0..2 {
                    let pair = &self.pairs[k];
                    if part == 0 {
                        let pts = points_of(&cfg.xq, self.fem, &cfg.fem_x, pair);
                        pair.potential.derivatives(
                            &self.terms,
                            &pts,
                            &cfg.fem_x[pair.facets_of],
                            &mut derivs,
                        );
                    } else if self.friction[k].is_empty() {
                        continue;
                    } else {
                        self.fill_displacements(cfg, k);
                        let (dp, db) = &self.disp;
                        friction::derivatives(
                            &self.friction_params[k],
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

    /// Number of active terms and smallest contact distance over all pairs at `cfg` (0 where
    /// a contact is infeasible).
    pub fn summary(&mut self, cfg: &Configuration<D>) -> (usize, f64) {
        let mut n = 0;
        let mut dmin = f64::INFINITY;
        for k in 0..self.pairs.len() {
            if self.collect(cfg, k).is_ok() {
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

    /// Model the friction terms that the direction `p` (particles moving by `dq`) carries
    /// through their stick zone as stuck, until [`Contact::end_stick_model`]
    /// ([`friction::carried_through_stick`]); returns how many.
    pub fn begin_stick_model(
        &mut self,
        cfg: &Configuration<D>,
        dofs: &Dofs,
        p: &[f64],
        dq: &[SVector<f64, D>],
    ) -> usize {
        let mut count = 0;
        for k in 0..self.pairs.len() {
            if self.friction[k].is_empty() {
                self.stuck[k].clear();
                continue;
            }
            self.fill_displacements(cfg, k);
            let pair = &self.pairs[k];
            let sc = &mut self.ccd;
            let dx = direction_motion((&mut sc.dx, &mut sc.bdx), self.fem, pair, dofs, p, dq);
            count += friction::carried_through_stick(
                &self.friction_params[k],
                &self.friction[k],
                (&self.disp.0, &self.disp.1),
                (dx, &sc.bdx),
                &mut self.stuck[k],
            );
        }
        if count > 0 {
            self.model = true;
            self.invalidate_derivatives();
        }
        count
    }

    /// Back to the true friction terms after [`Contact::begin_stick_model`].
    pub fn end_stick_model(&mut self) {
        if std::mem::take(&mut self.model) {
            self.invalidate_derivatives();
        }
    }

    /// Forget the cached term derivatives and the last Hessian's terms (the model changed).
    fn invalidate_derivatives(&mut self) {
        self.derivatives.computed_at = None;
        self.hess_terms = None;
    }

    /// The largest step fraction (≤ 1) along `p` before a point of any pair meets a facet
    /// (CCD), the particles moving by `dq`.
    pub fn ccd_bound(
        &mut self,
        cfg: &Configuration<D>,
        dofs: &Dofs,
        p: &[f64],
        dq: &[SVector<f64, D>],
    ) -> f64 {
        let mut best = 1.0f64;
        let sc = &mut self.ccd;
        // CCD of every pair along the full step.
        for pair in self.pairs {
            let x0 = points_of(&cfg.xq, self.fem, &cfg.fem_x, pair);
            let dx = direction_motion((&mut sc.dx, &mut sc.bdx), self.fem, pair, dofs, p, dq);
            let fb = pair.facets_of;
            let bx = &cfg.fem_x[fb];
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

/// A pair's motion along the direction `p`: its points' increments (the particles' `dq`, or
/// its FEM boundary vertices' blocks of `p`, gathered into `dx`) and its facet body's vertex
/// increments (into `bdx`).
fn direction_motion<'s, const D: usize>(
    (dx, bdx): (&'s mut Vec<SVector<f64, D>>, &mut Vec<SVector<f64, D>>),
    fem: &[FemBody<D>],
    pair: &Pair<D>,
    dofs: &Dofs,
    p: &[f64],
    dq: &'s [SVector<f64, D>],
) -> &'s [SVector<f64, D>] {
    let fb = pair.facets_of;
    let off = dofs.fem_offset[fb];
    bdx.clear();
    bdx.extend((0..fem[fb].x.len()).map(|v| block(&p[off..], v)));
    match &pair.points {
        Points::Mpm { range } => &dq[range.0..range.1],
        Points::Fem { body } => {
            let off = dofs.fem_offset[*body];
            dx.clear();
            dx.extend(
                fem[*body]
                    .boundary
                    .vertices()
                    .iter()
                    .map(|&v| block(&p[off..], v)),
            );
            dx
        }
    }
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

/// Positions of a pair's points at a configuration: the particles' slice itself (no copy —
/// this runs at every energy, gradient and CCD evaluation), or the FEM boundary vertices
/// gathered.
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
