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
use femp_fem::{Hyperelastic, Tangent, Triplet, chain_gradient, chain_hessian};
use femp_kernels::transfer;
use femp_solver::{Objective, StepBound, StepLimit, Triplets};
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use crate::world::{FemBody, Mpm, Pair, Points};

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

/// Grid-node Hessian blocks stored by node and neighbour offset (`δ ∈ [−2, 2]^D` for the
/// 3-node kernel): every particle's stencil couples only such pairs.
pub struct GridHessian<const D: usize> {
    slots: usize,
    blocks: Vec<SMatrix<f64, D, D>>,
    nbr: Vec<u32>,
}

impl<const D: usize> GridHessian<D> {
    fn new() -> Self {
        Self {
            slots: 5usize.pow(D as u32),
            blocks: Vec::new(),
            nbr: Vec::new(),
        }
    }

    fn reset(&mut self, n: usize) {
        self.blocks.clear();
        self.blocks.resize(n * self.slots, SMatrix::zeros());
        self.nbr.clear();
        self.nbr.resize(n * self.slots, u32::MAX);
    }

    #[inline]
    fn add(&mut self, i: usize, j: usize, ci: &[i64; D], cj: &[i64; D], b: &SMatrix<f64, D, D>) {
        let mut enc = 0usize;
        let mut mul = 1usize;
        for a in 0..D {
            enc += ((cj[a] - ci[a] + 2) as usize) * mul;
            mul *= 5;
        }
        let k = i * self.slots + enc;
        self.blocks[k] += b;
        self.nbr[k] = j as u32;
    }

    fn emit(&self, h: &mut Triplets) {
        for (k, &j) in self.nbr.iter().enumerate() {
            if j != u32::MAX {
                let i = k / self.slots;
                let b = &self.blocks[k];
                for r in 0..D {
                    for c in 0..D {
                        h.push(i * D + r, j as usize * D + c, b[(r, c)]);
                    }
                }
            }
        }
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
    fem_x: Vec<Vec<SVector<f64, D>>>,
    gh: GridHessian<D>,
    cands: Candidates,
    terms: Vec<ContactTerm>,
    ders: Vec<TermDerivatives<D>>,
    fem_trip: Vec<Triplet>,
    /// Number of active contact terms and smallest contact distance at the last gradient.
    pub(crate) last_contacts: (usize, f64),
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
            fem_x: fem.iter().map(|b| b.x.clone()).collect(),
            gh: GridHessian::new(),
            cands: Candidates::default(),
            terms: Vec::new(),
            ders: Vec::new(),
            fem_trip: Vec::new(),
            last_contacts: (0, f64::INFINITY),
        }
    }

    #[inline]
    fn v(x: &[f64], k: usize) -> SVector<f64, D> {
        SVector::from_column_slice(&x[k * D..k * D + D])
    }

    /// Update the scratch state (grid displacements, particle positions and F, FEM positions).
    fn unpack(&mut self, x: &[f64]) {
        if let Some(m) = self.mpm {
            self.u.resize(self.n_grid, SVector::zeros());
            for i in 0..self.n_grid {
                self.u[i] = Self::v(x, i) - Self::v(self.x_start, i);
            }
            let st = &m.stencils;
            let u = &self.u;
            self.xq.resize(m.x.len(), SVector::zeros());
            self.fq.resize(m.x.len(), SMatrix::zeros());
            self.xq
                .par_iter_mut()
                .zip(self.fq.par_iter_mut())
                .enumerate()
                .with_min_len(512)
                .for_each(|(p, (xq, fq))| {
                    let ps = st.particle(p);
                    let mut dx = SVector::<f64, D>::zeros();
                    let mut du = SMatrix::<f64, D, D>::zeros();
                    ps.for_each(|i, w, g| {
                        dx += u[i] * w;
                        du += u[i] * g.transpose();
                    });
                    *xq = m.x[p] + dx;
                    *fq = (SMatrix::identity() + du) * m.f[p];
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

    /// Positions of a pair's points at the unpacked state.
    fn points(&self, pair: &Pair<D>) -> Vec<SVector<f64, D>> {
        match &pair.points {
            Points::Mpm { range } => self.xq[range.0..range.1].to_vec(),
            Points::Fem { body } => self.fem[*body]
                .boundary
                .vertices()
                .iter()
                .map(|&v| self.fem_x[*body][v])
                .collect(),
        }
    }

    fn weights(&self, pair: &Pair<D>) -> Vec<f64> {
        match &pair.points {
            Points::Mpm { range } => self
                .mpm
                .map(|m| m.weight[range.0..range.1].to_vec())
                .unwrap_or_default(),
            Points::Fem { body } => self.fem[*body].vertex_weight.clone(),
        }
    }

    /// Displacements over the step of a pair's points and boundary (for friction).
    fn displacements(&self, pair: &Pair<D>) -> (Vec<SVector<f64, D>>, Vec<SVector<f64, D>>) {
        let dp = match &pair.points {
            Points::Mpm { range } => {
                let m = self.mpm.expect("MPM pair without MPM state");
                (range.0..range.1).map(|p| self.xq[p] - m.x[p]).collect()
            }
            Points::Fem { body } => {
                let b = &self.fem[*body];
                b.boundary
                    .vertices()
                    .iter()
                    .map(|&v| self.fem_x[*body][v] - b.x[v])
                    .collect()
            }
        };
        let f = &self.fem[pair.facets_of];
        let db = (0..f.x.len())
            .map(|v| self.fem_x[pair.facets_of][v] - f.x[v])
            .collect();
        (dp, db)
    }

    /// Active contact terms of a pair at the unpacked state (into `self.terms`).
    fn collect(&mut self, k: usize) -> Result<(), femp_contact::ContactError> {
        let pair = &self.pairs[k];
        let pts = self.points(pair);
        let w = self.weights(pair);
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
            .collect_terms(&pts, &w, bx, &self.cands, &mut self.terms)
    }

    /// Recompute the lagged friction operator at `x` (Algorithm 1, lines 5 and 9).
    pub(crate) fn lag_friction(&mut self, x: &[f64]) {
        self.unpack(x);
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

    /// DOF index of a pair's local point `k`'s stencil: calls `f(dof_base, weight)` for each
    /// DOF block the point's position depends on (grid nodes for MPM, one vertex for FEM).
    fn point_dofs(&self, pair: &Pair<D>, k: usize, mut f: impl FnMut(usize, f64)) {
        match &pair.points {
            Points::Mpm { range } => {
                let m = self.mpm.expect("MPM pair");
                m.stencils.particle(range.0 + k).for_each(|i, w, _| {
                    if w != 0.0 {
                        f(i * D, w)
                    }
                });
            }
            Points::Fem { body } => {
                let v = self.fem[*body].boundary.vertices()[k];
                f(self.fem_offset[*body] + v * D, 1.0);
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
                self.point_dofs(pair, d.particle as usize, |base, wt| {
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
            for d in ders {
                // Point's DOF blocks with weights.
                let mut pdofs: Vec<(usize, f64)> = Vec::with_capacity(27);
                self.point_dofs(pair, d.particle as usize, |b, wt| pdofs.push((b, wt)));
                let hqq = d.hess[0][0] * w;
                if mpm_points {
                    let st = &self.mpm.expect("MPM pair").stencils;
                    for &(ba, wa) in &pdofs {
                        let (ia, ca) = (ba / D, st.node_index(ba / D));
                        for &(bb, wb) in &pdofs {
                            let ib = bb / D;
                            self.gh
                                .add(ia, ib, &ca, &st.node_index(ib), &(hqq * (wa * wb)));
                        }
                    }
                } else {
                    for &(ba, wa) in &pdofs {
                        for &(bb, wb) in &pdofs {
                            push_block(h, ba, bb, &(hqq * (wa * wb)));
                        }
                    }
                }
                for s in 1..d.n {
                    let bs = boff + d.vertices[s - 1] as usize * D;
                    for &(ba, wa) in &pdofs {
                        push_block(h, ba, bs, &(d.hess[0][s] * (w * wa)));
                        push_block(h, bs, ba, &(d.hess[s][0] * (w * wa)));
                    }
                    for t in 1..d.n {
                        let bt = boff + d.vertices[t - 1] as usize * D;
                        push_block(h, bs, bt, &(d.hess[s][t] * w));
                    }
                }
            }
        }
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
}

#[inline]
fn push_block<const D: usize>(h: &mut Triplets, r: usize, c: usize, b: &SMatrix<f64, D, D>) {
    for i in 0..D {
        for j in 0..D {
            h.push(r + i, c + j, b[(i, j)]);
        }
    }
}

impl<const D: usize> Objective for StepObjective<'_, D> {
    fn num_dofs(&self) -> usize {
        self.n_dofs
    }

    fn energy(&mut self, x: &[f64]) -> f64 {
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
        // MPM elasticity.
        if let Some(m) = self.mpm {
            let fq = &self.fq;
            let el: f64 = (0..m.x.len())
                .into_par_iter()
                .with_min_len(1024)
                .map(|p| m.volume[p] * m.bodies[m.body[p] as usize].material.energy_density(&fq[p]))
                .sum();
            if !el.is_finite() {
                return f64::INFINITY;
            }
            e += w * el;
        }
        // FEM elasticity.
        for (b, body) in self.fem.iter().enumerate() {
            if body.fully_prescribed {
                continue;
            }
            match body.elastic.energy(&self.fem_x[b]) {
                Ok(v) if v.is_finite() => e += w * v,
                _ => return f64::INFINITY,
            }
        }
        // Contact and friction.
        for k in 0..self.pairs.len() {
            if self.collect(k).is_err() {
                return f64::INFINITY;
            }
            e += w * self.pairs[k].potential.energy(&self.terms);
            if !self.friction[k].is_empty() {
                let (dp, db) = self.displacements(&self.pairs[k]);
                e += w * friction::energy(&self.pairs[k].friction, &self.friction[k], &dp, &db);
            }
        }
        e
    }

    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        self.unpack(x);
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
            let st = &m.stencils;
            // Per-particle node forces, then a serial scatter (no races).
            for p in 0..m.x.len() {
                let f = &self.fq[p];
                let pk = m.bodies[m.body[p] as usize].material.first_piola(f) * (w * m.volume[p]);
                let ft = m.f[p].transpose();
                st.particle(p).for_each(|i, _, grad| {
                    let gi = pk * (ft * grad);
                    for a in 0..D {
                        g[i * D + a] += gi[a];
                    }
                });
            }
        }
        for b in 0..self.fem.len() {
            if self.fem[b].fully_prescribed {
                continue;
            }
            let off = self.fem_offset[b];
            let n = self.fem[b].x.len();
            let mut gb = vec![SVector::<f64, D>::zeros(); n];
            // ElasticBody::add_gradient needs &mut for its force buffer; compute through the
            // chain rule here instead (same formula), element by element.
            let body = &self.fem[b];
            for (e, c) in body.elastic.cells().iter().enumerate() {
                let el = &body.elastic.elements()[e];
                let xe: [SVector<f64, D>; 4] = std::array::from_fn(|k| {
                    if k <= D {
                        self.fem_x[b][c[k]]
                    } else {
                        SVector::zeros()
                    }
                });
                let pmat = body.material.first_piola(&el.deformation_gradient(&xe));
                let mut fe = [SVector::<f64, D>::zeros(); 4];
                chain_gradient(&pmat, el.gradients(), el.volume * w, &mut fe[..D + 1]);
                for k in 0..=D {
                    gb[c[k]] += fe[k];
                }
            }
            for v in 0..n {
                for a in 0..D {
                    g[off + v * D + a] += gb[v][a];
                }
            }
        }
        let mut count = 0;
        let mut dmin = f64::INFINITY;
        for k in 0..self.pairs.len() {
            if self.collect(k).is_err() {
                continue;
            }
            count += self.terms.len();
            for t in &self.terms {
                dmin = dmin.min(t.sq_dist.sqrt());
            }
            let pair = &self.pairs[k];
            let pts = self.points(pair);
            let mut ders = std::mem::take(&mut self.ders);
            pair.potential
                .derivatives(&self.terms, &pts, &self.fem_x[pair.facets_of], &mut ders);
            self.scatter(k, &ders, Some(g), None);
            if !self.friction[k].is_empty() {
                let (dp, db) = self.displacements(&self.pairs[k]);
                friction::derivatives(
                    &self.pairs[k].friction,
                    &self.friction[k],
                    &dp,
                    &db,
                    &mut ders,
                );
                self.scatter(k, &ders, Some(g), None);
            }
            self.ders = ders;
        }
        self.last_contacts = (count, dmin);
    }

    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        self.unpack(x);
        let w = self.w;
        for d in 0..self.n_dofs {
            h.push(d, d, self.mass[d]);
        }
        for p in self.penalties {
            for a in 0..D {
                for b in 0..D {
                    h.push(p.node * D + a, p.node * D + b, p.k * p.n[a] * p.n[b]);
                }
            }
        }
        self.gh.reset(self.n_grid);
        if let Some(m) = self.mpm {
            let st = &m.stencils;
            let nn = st.stencil_len();
            let mut gvec = vec![SVector::<f64, D>::zeros(); nn];
            let mut ids = vec![0usize; nn];
            let mut blocks = vec![SMatrix::<f64, D, D>::zeros(); nn * nn];
            for p in 0..m.x.len() {
                let t: Tangent<D> = m.bodies[m.body[p] as usize]
                    .material
                    .tangent_psd(&self.fq[p]);
                let ft = m.f[p].transpose();
                let mut k = 0;
                st.particle(p).for_each(|i, _, grad| {
                    ids[k] = i;
                    gvec[k] = ft * grad;
                    k += 1;
                });
                chain_hessian(&t, &gvec, w * m.volume[p], &mut blocks);
                for a in 0..nn {
                    let ca = st.node_index(ids[a]);
                    for b in 0..nn {
                        self.gh.add(
                            ids[a],
                            ids[b],
                            &ca,
                            &st.node_index(ids[b]),
                            &blocks[a * nn + b],
                        );
                    }
                }
            }
        }
        for b in 0..self.fem.len() {
            if self.fem[b].fully_prescribed {
                continue;
            }
            let mut trip = std::mem::take(&mut self.fem_trip);
            if self.fem[b]
                .elastic
                .hessian_triplets(&self.fem_x[b], w, self.fem_offset[b], &mut trip)
                .is_ok()
            {
                h.reserve(trip.len());
                for t in &trip {
                    h.push(t.row, t.col, t.value);
                }
            }
            self.fem_trip = trip;
        }
        for k in 0..self.pairs.len() {
            if self.collect(k).is_err() {
                continue;
            }
            let pair = &self.pairs[k];
            let pts = self.points(pair);
            let mut ders = std::mem::take(&mut self.ders);
            pair.potential
                .derivatives(&self.terms, &pts, &self.fem_x[pair.facets_of], &mut ders);
            self.scatter(k, &ders, None, Some(h));
            if !self.friction[k].is_empty() {
                let (dp, db) = self.displacements(&self.pairs[k]);
                friction::derivatives(
                    &self.pairs[k].friction,
                    &self.friction[k],
                    &dp,
                    &db,
                    &mut ders,
                );
                self.scatter(k, &ders, None, Some(h));
            }
            self.ders = ders;
        }
        self.gh.emit(h);
    }

    fn max_step(&mut self, x: &[f64], p: &[f64]) -> StepBound {
        self.unpack(x);
        let mut best = StepBound::UNLIMITED;
        let mut take = |alpha: f64, limit: StepLimit| {
            if alpha < best.alpha {
                best = StepBound {
                    alpha: alpha.max(0.0),
                    limit: Some(limit),
                };
            }
        };
        // Particle displacements along p, and det F of particles.
        let mut dq: Vec<SVector<f64, D>> = Vec::new();
        if let Some(m) = self.mpm {
            let pg: Vec<SVector<f64, D>> = (0..self.n_grid).map(|i| Self::v(p, i)).collect();
            dq = vec![SVector::zeros(); m.x.len()];
            let _ = transfer::interpolate(&m.stencils, &pg, &mut dq);
            let st = &m.stencils;
            let u = &self.u;
            let alpha = (0..m.x.len())
                .into_par_iter()
                .with_min_len(512)
                .map(|q| {
                    let mut g0 = SMatrix::<f64, D, D>::identity();
                    let mut g1 = SMatrix::<f64, D, D>::zeros();
                    st.particle(q).for_each(|i, _, grad| {
                        g0 += u[i] * grad.transpose();
                        g1 += pg[i] * grad.transpose();
                    });
                    first_det_root(&g0, &g1).unwrap_or(1.0)
                })
                .reduce(|| 1.0, f64::min);
            take(alpha, StepLimit::DetF);
        }
        // FEM det F.
        for (b, body) in self.fem.iter().enumerate() {
            if body.fully_prescribed {
                continue;
            }
            let off = self.fem_offset[b];
            let pb: Vec<SVector<f64, D>> = (0..body.x.len())
                .map(|v| SVector::from_column_slice(&p[off + v * D..off + v * D + D]))
                .collect();
            if let Ok(a) = body.elastic.max_inversion_free_step(&self.fem_x[b], &pb) {
                take(a, StepLimit::DetF);
            }
        }
        // CCD of every pair along the full step.
        for pair in self.pairs {
            let x0 = self.points(pair);
            let dx: Vec<SVector<f64, D>> = match &pair.points {
                Points::Mpm { range } => dq[range.0..range.1].to_vec(),
                Points::Fem { body } => {
                    let off = self.fem_offset[*body];
                    self.fem[*body]
                        .boundary
                        .vertices()
                        .iter()
                        .map(|&v| SVector::from_column_slice(&p[off + v * D..off + v * D + D]))
                        .collect()
                }
            };
            let fb = pair.facets_of;
            let off = self.fem_offset[fb];
            let bx = &self.fem_x[fb];
            let bdx: Vec<SVector<f64, D>> = (0..bx.len())
                .map(|v| SVector::from_column_slice(&p[off + v * D..off + v * D + D]))
                .collect();
            let x1: Vec<_> = x0.iter().zip(&dx).map(|(a, b)| a + b).collect();
            let b1: Vec<_> = bx.iter().zip(&bdx).map(|(a, b)| a + b).collect();
            let mut cands = Candidates::default();
            broad_phase::candidates_swept(&x0, &x1, bx, &b1, &self.fem[fb].facets, 0.0, &mut cands);
            let (alpha, _) = ccd::max_step(
                &x0,
                &dx,
                bx,
                &bdx,
                &self.fem[fb].facets,
                &cands,
                &CcdOptions::default(),
            );
            take(alpha, StepLimit::Ccd);
        }
        best
    }
}
