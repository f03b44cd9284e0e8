//! Explicit FEM dynamics with augury contact: central-difference Newmark (eq. 32) with
//! femp-fem's elastic forces and lumped masses, gravity, fixed vertices, and the contact
//! correction applied to the boundary vertices of all bodies together (they are the augury
//! "particles", each with an APIC matrix `B_p`).

use femp_fem::{Boundary, ElasticBody, Material, Mesh, lumped_masses};
use std::time::Instant;

use nalgebra::{SMatrix, SVector, Vector3};
use rayon::prelude::*;

use crate::contact::AuguryContact;
use crate::error::AuguryError;
use crate::operator::TransferKind;

/// One FEM body of an explicit system.
pub struct ExplicitBody<const D: usize> {
    /// Name (for messages).
    pub name: String,
    /// Elastic energy and forces.
    pub elastic: ElasticBody<D, Material>,
    /// Current positions.
    pub x: Vec<SVector<f64, D>>,
    /// Velocities at the current time.
    pub v: Vec<SVector<f64, D>>,
    /// Accelerations at the current time (mechanical + contact).
    pub a: Vec<SVector<f64, D>>,
    /// Lumped masses.
    pub mass: Vec<f64>,
    /// Vertices that do not move.
    pub fixed: Vec<bool>,
    /// Boundary vertices (the contact particles), in order.
    pub boundary: Vec<usize>,
    /// Contact force on each vertex at the current time (N; N/m in 2D): `m_p Â_p` of the augury
    /// correction and the penalty baseline's forces. On a fixed vertex it is the force the
    /// correction asked for and the prescription overrode — with [`Obstacles::Kinematic`], the
    /// reaction a fixed plate feels.
    pub contact_force: Vec<SVector<f64, D>>,
    /// An external force on each vertex (N; N/m in 2D), or empty for none: it enters the
    /// accelerations as gravity does, `a = g + (f − ∇Ψ)/m`, when they are next evaluated.
    pub external: Vec<SVector<f64, D>>,
    /// The boundary (facets, normals).
    surface: Boundary<D>,
    /// The facets of each boundary vertex (CSR by position in `boundary`, facets ascending).
    adjacent: Vec<u32>,
    adjacent_start: Vec<u32>,
    facet_normals: Vec<SVector<f64, D>>,
    force: Vec<SVector<f64, D>>,
}

impl<const D: usize> ExplicitBody<D> {
    /// A body at rest in its rest shape.
    pub fn new(
        name: &str,
        mesh: &Mesh<D>,
        material: Material,
        density: f64,
    ) -> Result<Self, AuguryError> {
        let fem = |e: femp_fem::FemError| AuguryError::Fem(e.to_string());
        let elastic = ElasticBody::new(mesh, material).map_err(fem)?;
        let mass = lumped_masses(mesh, density).map_err(fem)?;
        let b = Boundary::of(mesh);
        let n = mesh.num_vertices();
        let mut slot = vec![usize::MAX; n];
        for (k, &v) in b.vertices().iter().enumerate() {
            slot[v] = k;
        }
        let mut adjacent_start = vec![0u32; b.vertices().len() + 1];
        for fv in b.facets() {
            for &v in &fv[..D] {
                adjacent_start[slot[v] + 1] += 1;
            }
        }
        for k in 0..b.vertices().len() {
            adjacent_start[k + 1] += adjacent_start[k];
        }
        let mut fill: Vec<u32> = adjacent_start[..b.vertices().len()].to_vec();
        let mut adjacent = vec![0u32; *adjacent_start.last().unwrap_or(&0) as usize];
        for (f, fv) in b.facets().iter().enumerate() {
            for &v in &fv[..D] {
                adjacent[fill[slot[v]] as usize] = f as u32;
                fill[slot[v]] += 1;
            }
        }
        Ok(Self {
            name: name.to_string(),
            elastic,
            x: mesh.vertices().to_vec(),
            v: vec![SVector::zeros(); n],
            a: vec![SVector::zeros(); n],
            mass,
            fixed: vec![false; n],
            boundary: b.vertices().to_vec(),
            surface: b,
            adjacent,
            adjacent_start,
            facet_normals: Vec::new(),
            force: vec![SVector::zeros(); n],
            contact_force: vec![SVector::zeros(); n],
            external: Vec::new(),
        })
    }

    /// Set a rigid initial velocity `v0 + ω × (x − c)` (ω a scalar about z in 2D: pass
    /// `[0, 0, ω]`) about the centre of mass.
    pub fn set_rigid_velocity(&mut self, v0: SVector<f64, D>, omega: Vector3<f64>) {
        let c = self.centre_of_mass();
        for (x, v) in self.x.iter().zip(self.v.iter_mut()) {
            let r = x - c;
            let r3 = Vector3::new(r[0], r[1], if D == 3 { r[D - 1] } else { 0.0 });
            let w = omega.cross(&r3);
            *v = v0 + SVector::<f64, D>::from_fn(|a, _| if a < 2 { w[a] } else { w[2] });
        }
    }

    /// The velocity gradient `L` of a rigid rotation ω (for the initial `B_p = L D_p`).
    pub fn rotation_gradient(omega: Vector3<f64>) -> SMatrix<f64, D, D> {
        // 2D: the upper-left block of the 3D cross-product matrix of (0, 0, ω).
        let w = omega.cross_matrix();
        SMatrix::<f64, D, D>::from_fn(|r, c| w[(r, c)])
    }

    /// Centre of mass.
    pub fn centre_of_mass(&self) -> SVector<f64, D> {
        let m: f64 = self.mass.iter().sum();
        self.x
            .iter()
            .zip(&self.mass)
            .map(|(x, mm)| x * *mm)
            .sum::<SVector<f64, D>>()
            / m
    }

    /// Total mass.
    pub fn total_mass(&self) -> f64 {
        self.mass.iter().sum()
    }

    /// Smallest element altitude (the length scale of the stable time step).
    pub fn min_altitude(&self) -> f64 {
        let cells = self.elastic.cells();
        let mut h = f64::INFINITY;
        for (e, el) in self.elastic.elements().iter().enumerate() {
            let c = &cells[e];
            // Altitude to each facet: D·V / |facet|; the largest facet gives the smallest.
            let mut max_face = 0.0f64;
            for skip in 0..=D {
                let verts: Vec<SVector<f64, D>> = (0..=D)
                    .filter(|&k| k != skip)
                    .map(|k| self.x[c[k]])
                    .collect();
                let face = if D == 2 {
                    (verts[1] - verts[0]).norm()
                } else {
                    let (a, b) = (verts[1] - verts[0], verts[2] - verts[0]);
                    let a3 = Vector3::new(a[0], a[1], a[D - 1]);
                    let b3 = Vector3::new(b[0], b[1], b[D - 1]);
                    0.5 * a3.cross(&b3).norm()
                };
                max_face = max_face.max(face);
            }
            h = h.min(D as f64 * el.volume / max_face);
        }
        h
    }
}

/// The search-based baseline: explicit node-to-surface penalty contact. Every boundary vertex
/// of every body is tested against the boundary facets of every other body found by
/// femp-contact's broad phase within `band`; a vertex behind its nearest facet (signed gap
/// `g < 0` along the facet's outward normal, `|g| < band`) gets the force `−k g n` and the facet's
/// vertices the opposite force split by barycentric weights (so linear momentum is conserved).
pub struct PenaltyContact<const D: usize> {
    /// Stiffness `k` (force per unit penetration).
    pub stiffness: f64,
    /// Search band (penetration depth beyond which a pair is ignored, and broad-phase distance).
    pub band: f64,
    candidates: femp_contact::broad_phase::Candidates,
    facets: Vec<[u32; 3]>,
    points: Vec<usize>,
    positions: Vec<SVector<f64, D>>,
    /// Per vertex of the current body pair: its facet, barycentric weights and force.
    #[allow(clippy::type_complexity)]
    hits: Vec<Option<(u32, [f64; 3], SVector<f64, D>)>>,
    /// Active vertex–facet pairs in the last evaluation.
    pub active: usize,
}

impl<const D: usize> PenaltyContact<D> {
    /// A penalty contact with stiffness `k` and search band.
    pub fn new(stiffness: f64, band: f64) -> Result<Self, AuguryError> {
        for (name, value) in [("penalty stiffness", stiffness), ("penalty band", band)] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(AuguryError::BadParameter {
                    name,
                    value,
                    requirement: "must be positive and finite",
                });
            }
        }
        Ok(Self {
            stiffness,
            band,
            candidates: Default::default(),
            facets: Vec::new(),
            points: Vec::new(),
            positions: Vec::new(),
            hits: Vec::new(),
            active: 0,
        })
    }
}

/// Closest point of facet `f` to `p`, with the barycentric weights of the facet's vertices —
/// in plain double precision (a penalty force needs no exact predicates; the region tests of
/// Ericson, *Real-Time Collision Detection* §5.1.5, for triangles). A triangle without area
/// (which a valid mesh does not have) falls back to femp-contact's robust closest point.
fn closest_on_facet<const D: usize>(
    p: &SVector<f64, D>,
    f: &[usize; 3],
    x: &[SVector<f64, D>],
) -> (SVector<f64, D>, [f64; 3]) {
    if D == 2 {
        let (a, b) = (x[f[0]], x[f[1]]);
        let e = b - a;
        let t = ((p - a).dot(&e) / e.norm_squared()).clamp(0.0, 1.0);
        return (a + e * t, [1.0 - t, t, 0.0]);
    }
    let l = |q: &SVector<f64, D>| Vector3::new(q[0], q[1], q[D - 1]);
    let (p3, a, b, c) = (l(p), l(&x[f[0]]), l(&x[f[1]]), l(&x[f[2]]));
    let w = closest_weights(&p3, &a, &b, &c).unwrap_or_else(|| {
        use femp_contact::distance::point_triangle;
        let q = point_triangle::closest_point(&p3, &a, &b, &c);
        let (u, v) = point_triangle::barycentric(&q, &a, &b, &c).unwrap_or((0.0, 0.0));
        [1.0 - u - v, u, v]
    });
    let q = a * w[0] + b * w[1] + c * w[2];
    (SVector::<f64, D>::from_fn(|i, _| q[i.min(2)]), w)
}

/// Barycentric weights of the point of triangle `abc` closest to `p` (Voronoi regions of the
/// vertices, then the edges, then the face); `None` for a triangle without area.
fn closest_weights(
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> Option<[f64; 3]> {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return Some([1.0, 0.0, 0.0]);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return Some([0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let t = d1 / (d1 - d3);
        return Some([1.0 - t, t, 0.0]);
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return Some([0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let t = d2 / (d2 - d6);
        return Some([1.0 - t, 0.0, t]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return Some([0.0, 1.0 - t, t]);
    }
    let sum = va + vb + vc;
    if !(sum > 0.0 && sum.is_finite()) {
        return None;
    }
    let (v, w) = (vb / sum, vc / sum);
    Some([1.0 - v - w, v, w])
}

/// Mass factor of the vertices of fully prescribed bodies under [`Obstacles::Kinematic`].
pub const KINEMATIC_MASS: f64 = 1e8;

/// How a body whose every vertex is fixed or prescribed (a plate, a wall, a rigid ramp) enters
/// the augury correction. The correction cannot change such a body's motion either way; the
/// choice is what its particles weigh on the grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Obstacles {
    /// With their lumped masses, like any other particle (the paper's formulation). A body
    /// pressed against the obstacle keeps, each step, the share of its approach velocity the
    /// obstacle's particles would have taken, and sinks in under sustained load (measured:
    /// a disk pressed between plates passes 70–140 vertices into them).
    #[default]
    Lumped,
    /// As infinitely heavy: mass × [`KINEMATIC_MASS`] (the limit to 1e-8), their `B_p` that of
    /// a translation (0). Normal contact is then held (the pressed disk: no vertex inside, the
    /// plate's reaction equal to the load), but tangential motion along the obstacle is lost:
    /// the iterations cannot hand the undone tangential change to the obstacle, and a block
    /// sliding frictionlessly down a rigid ramp sticks (measured, `docs/augury.md`).
    Kinematic,
}

/// Wall time of the phases of the last [`ExplicitSystem::step`] (s). Two clock reads per phase:
/// about 50 ns a step, so they are always taken.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepTiming {
    /// Elastic forces of every body (`∇Ψ`).
    pub elastic_s: f64,
    /// Contact: the augury correction (normals, gathering the boundary particles, the
    /// transfers and iterations, scattering the result) and the penalty baseline's search and
    /// forces.
    pub contact_s: f64,
    /// The whole step (the above, the time integration and any prescribed motion).
    pub step_s: f64,
}

/// A saved state of an [`ExplicitSystem`] ([`ExplicitSystem::state`],
/// [`ExplicitSystem::set_state`]).
#[derive(Clone, Debug)]
pub struct ExplicitState<const D: usize> {
    #[allow(clippy::type_complexity)]
    bodies: Vec<(
        Vec<SVector<f64, D>>,
        Vec<SVector<f64, D>>,
        Vec<SVector<f64, D>>,
    )>,
    b: Vec<SMatrix<f64, D, D>>,
    bdot: Vec<SMatrix<f64, D, D>>,
    time: f64,
    started: bool,
}

/// Parameters of the explicit system.
pub struct ExplicitParams<const D: usize> {
    /// Time step Δt.
    pub dt: f64,
    /// Gravity.
    pub gravity: SVector<f64, D>,
}

/// Several bodies stepped together, touching only through the augury correction.
pub struct ExplicitSystem<const D: usize> {
    /// The bodies.
    pub bodies: Vec<ExplicitBody<D>>,
    /// Parameters.
    pub params: ExplicitParams<D>,
    /// Simulated time.
    pub time: f64,
    /// The contact correction (None: bodies pass through each other).
    pub contact: Option<AuguryContact<D>>,
    /// The search-based penalty baseline (used instead of, or besides, augury contact).
    pub penalty: Option<PenaltyContact<D>>,
    /// How fully prescribed bodies enter the augury correction (default
    /// [`Obstacles::Lumped`]).
    pub obstacles: Obstacles,
    /// `B_p` of every boundary particle (bodies concatenated in order).
    pub b: Vec<SMatrix<f64, D, D>>,
    /// Contact rate of `B_p` (its acceleration).
    pub bdot: Vec<SMatrix<f64, D, D>>,
    /// Where the last step's time went.
    pub timing: StepTiming,
    // Particle buffers.
    px: Vec<SVector<f64, D>>,
    pm: Vec<f64>,
    pn: Vec<SVector<f64, D>>,
    pv: Vec<SVector<f64, D>>,
    pa: Vec<SVector<f64, D>>,
    started: bool,
}

impl<const D: usize> ExplicitSystem<D> {
    /// A system of `bodies`; `B_p` starts at zero (set [`Self::b`] for affine initial fields).
    pub fn new(
        bodies: Vec<ExplicitBody<D>>,
        params: ExplicitParams<D>,
        contact: Option<AuguryContact<D>>,
    ) -> Self {
        let n: usize = bodies.iter().map(|b| b.boundary.len()).sum();
        Self {
            bodies,
            params,
            time: 0.0,
            contact,
            penalty: None,
            obstacles: Obstacles::Lumped,
            b: vec![SMatrix::zeros(); n],
            bdot: vec![SMatrix::zeros(); n],
            timing: StepTiming::default(),
            px: Vec::with_capacity(n),
            pm: Vec::with_capacity(n),
            pn: Vec::with_capacity(n),
            pv: Vec::with_capacity(n),
            pa: Vec::with_capacity(n),
            started: false,
        }
    }

    /// Number of contact particles.
    pub fn num_particles(&self) -> usize {
        self.b.len()
    }

    /// The largest stable time step of central differences for the stiffest body, times
    /// `safety`: `safety · min_e h_e / c_p` with `c_p = √((λ + 2μ)/ρ)`; `lame` and `density`
    /// per body.
    pub fn stable_dt(&self, lame_and_density: &[(f64, f64, f64)], safety: f64) -> f64 {
        self.bodies
            .iter()
            .zip(lame_and_density)
            .map(|(b, &(mu, lambda, rho))| b.min_altitude() / ((lambda + 2.0 * mu) / rho).sqrt())
            .fold(f64::INFINITY, f64::min)
            * safety
    }

    /// Mechanical accelerations `−M⁻¹ ∇Ψ + g` into each body's `a` (fixed vertices: 0).
    fn mechanical(&mut self) -> Result<(), AuguryError> {
        let g = self.params.gravity;
        let clock = Instant::now();
        for b in &mut self.bodies {
            b.force.iter_mut().for_each(|f| *f = SVector::zeros());
            b.contact_force
                .iter_mut()
                .for_each(|f| *f = SVector::zeros());
            b.elastic
                .add_gradient(&b.x, 1.0, &mut b.force)
                .map_err(|e| AuguryError::Fem(format!("body `{}`: {e}", b.name)))?;
        }
        self.timing.elastic_s = clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        self.penalty_forces();
        self.timing.contact_s = clock.elapsed().as_secs_f64();
        for b in &mut self.bodies {
            for k in 0..b.x.len() {
                b.a[k] = if b.fixed[k] {
                    SVector::zeros()
                } else {
                    match b.external.get(k) {
                        Some(f) => g + (f - b.force[k]) / b.mass[k],
                        None => g - b.force[k] / b.mass[k],
                    }
                };
            }
        }
        Ok(())
    }

    /// Positions or velocities were set from outside: the accelerations (elastic, gravity,
    /// external, contact) are evaluated again, at the new state, before the next step.
    pub fn state_changed(&mut self) {
        self.started = false;
    }

    /// Penalty forces of the baseline, added to each body's `force` (which holds `∇Ψ`, so a
    /// physical force `F` is added as `−F`).
    pub fn penalty_forces(&mut self) -> usize {
        let Some(pen) = self.penalty.as_mut() else {
            return 0;
        };
        pen.active = 0;
        let nb = self.bodies.len();
        for ib in 0..nb {
            for jb in 0..nb {
                if ib == jb {
                    continue;
                }
                // Vertices of body `ib` against facets of body `jb`.
                pen.facets.clear();
                pen.facets.extend(
                    self.bodies[jb]
                        .surface
                        .facets()
                        .iter()
                        .map(|f| [f[0] as u32, f[1] as u32, f[2] as u32]),
                );
                pen.points.clear();
                pen.points.extend_from_slice(&self.bodies[ib].boundary);
                pen.positions.clear();
                pen.positions
                    .extend(pen.points.iter().map(|&v| self.bodies[ib].x[v]));
                femp_contact::broad_phase::candidates_within(
                    &pen.positions,
                    &self.bodies[jb].x,
                    &pen.facets,
                    pen.band,
                    &mut pen.candidates,
                );
                // The nearest candidate facet of each vertex, in parallel; the forces are then
                // added in vertex order (the same sums on any number of threads).
                let (xj, surface) = (&self.bodies[jb].x, &self.bodies[jb].surface);
                let (positions, candidates) = (&pen.positions, &pen.candidates);
                let (stiffness, band) = (pen.stiffness, pen.band);
                pen.hits.resize(positions.len(), None);
                pen.hits
                    .par_iter_mut()
                    .enumerate()
                    .with_min_len(512)
                    .for_each(|(q, hit)| {
                        *hit = None;
                        let p = &positions[q];
                        let mut best: Option<(f64, usize, SVector<f64, D>, [f64; 3])> = None;
                        for &f in candidates.of(q) {
                            let (c, w) = closest_on_facet(p, &surface.facets()[f as usize], xj);
                            let d = (p - c).norm_squared();
                            if best.as_ref().is_none_or(|b| d < b.0) {
                                best = Some((d, f as usize, c, w));
                            }
                        }
                        let Some((_, f, c, w)) = best else { return };
                        let n = surface.facet_normal(f, xj);
                        let len = n.norm();
                        if len == 0.0 {
                            return;
                        }
                        let n = n / len;
                        let g = (p - c).dot(&n);
                        if g >= 0.0 || g < -band {
                            return;
                        }
                        *hit = Some((f as u32, w, n * (-stiffness * g)));
                    });
                for (q, hit) in pen.hits.iter().enumerate() {
                    let Some((f, w, force)) = *hit else { continue };
                    pen.active += 1;
                    let fv = self.bodies[jb].surface.facets()[f as usize];
                    let v = pen.points[q];
                    self.bodies[ib].force[v] -= force;
                    self.bodies[ib].contact_force[v] += force;
                    for k in 0..D {
                        self.bodies[jb].force[fv[k]] += force * w[k];
                        self.bodies[jb].contact_force[fv[k]] -= force * w[k];
                    }
                }
            }
        }
        pen.active
    }

    /// Add the augury correction for the predicted field `V̄ = V + τ A` (eq. 27), with `V` the
    /// current velocities — the half-step velocities `V^{n+1/2}` of eq. 32 — and `B`.
    ///
    /// Why the half-step velocity and not the full-step estimate `v^{n+1/2} + ½Δt a`: over one
    /// step the velocity receives `Δt·a`; the correction removes `(I − H)` of `V + τa`. With
    /// `V = v^{n+1/2}` and τ = Δt the non-smooth part of `V + Δt·a` is removed exactly; with the
    /// full-step estimate it would remove `1.5 Δt·a` and reverse the elastic forces on the
    /// boundary — an instability we measured (velocities grow ×1.5 per step).
    fn contact(&mut self) -> Result<usize, AuguryError> {
        let clock = Instant::now();
        let iterations = self.augury_correction();
        self.timing.contact_s += clock.elapsed().as_secs_f64();
        iterations
    }

    fn augury_correction(&mut self) -> Result<usize, AuguryError> {
        let Some(aug) = self.contact.as_mut() else {
            return Ok(0);
        };
        let tau = aug.params().tau;
        let apic = aug.transfer().kind() == TransferKind::Apic;
        let n: usize = self.bodies.iter().map(|b| b.boundary.len()).sum();
        self.px.resize(n, SVector::zeros());
        self.pm.resize(n, 0.0);
        self.pn.resize(n, SVector::zeros());
        self.pv.resize(n, SVector::zeros());
        let mut start = 0;
        for b in &mut self.bodies {
            let kinematic = self.obstacles == Obstacles::Kinematic && b.fixed.iter().all(|&f| f);
            let end = start + b.boundary.len();
            // Area-weighted vertex normals: each facet's normal, then per boundary vertex the
            // sum over its facets in facet order (the same sums as adding every facet's normal
            // to its vertices in turn), normalised.
            let (surface, x) = (&b.surface, &b.x);
            b.facet_normals
                .resize(surface.facets().len(), SVector::zeros());
            b.facet_normals
                .par_iter_mut()
                .enumerate()
                .with_min_len(4096)
                .for_each(|(f, n)| *n = surface.facet_normal(f, x));
            let (fnormals, adj, adj_start) = (&b.facet_normals, &b.adjacent, &b.adjacent_start);
            let (mass, v, a) = (&b.mass, &b.v, &b.a);
            (
                &mut self.px[start..end],
                &mut self.pm[start..end],
                &mut self.pn[start..end],
                &mut self.pv[start..end],
                &b.boundary[..],
            )
                .into_par_iter()
                .enumerate()
                .with_min_len(4096)
                .for_each(|(k, (px, pm, pn, pv, &vtx))| {
                    let mut sum = SVector::<f64, D>::zeros();
                    for &f in &adj[adj_start[k] as usize..adj_start[k + 1] as usize] {
                        sum += fnormals[f as usize];
                    }
                    let l = sum.norm();
                    *pn = if l > 0.0 { sum / l } else { sum };
                    *px = x[vtx];
                    // `Obstacles::Kinematic`: the infinite-mass limit. Only for fully
                    // prescribed bodies: the fixed vertices of a partly prescribed one (the
                    // anchored bottom of a ramp) lie inside it, often within a grid cell of its
                    // free surface, and as infinitely heavy particles would impose rest on the
                    // nodes that surface uses.
                    *pm = if kinematic {
                        mass[vtx] * KINEMATIC_MASS
                    } else {
                        mass[vtx]
                    };
                    *pv = v[vtx] + a[vtx] * tau;
                });
            start = end;
        }
        if !apic {
            self.b.iter_mut().for_each(|b| *b = SMatrix::zeros());
        }
        // B̄ = B + τ·0 (no mechanical B rate).
        self.pa.resize(self.px.len(), SVector::zeros());
        let iters = aug.correction(
            &self.px,
            &self.pm,
            &self.pn,
            &self.pv,
            &self.b,
            &mut self.pa,
            &mut self.bdot,
        )?;
        let mut k = 0;
        for b in &mut self.bodies {
            let kinematic = self.obstacles == Obstacles::Kinematic && b.fixed.iter().all(|&f| f);
            for &v in &b.boundary {
                if !b.fixed[v] {
                    b.a[v] += self.pa[k];
                } else if kinematic {
                    // Its `B_p` stays that of a translation; accumulating contact rates, it
                    // would carry a velocity field of its own into the grid at kinematic weight.
                    self.bdot[k] = SMatrix::zeros();
                }
                b.contact_force[v] += self.pa[k] * self.pm[k];
                k += 1;
            }
        }
        Ok(iters)
    }

    /// Advance by one step of central-difference Newmark (eq. 32). Returns the number of augury
    /// iterations the correction took (0 without augury contact).
    pub fn step(&mut self) -> Result<usize, AuguryError> {
        self.step_with(|_, _, _, _| {})
    }

    /// [`Self::step`] with prescribed motion: after the position update, `prescribe(body, t, x,
    /// v)` may set the positions and velocities of the body's fixed vertices at the new time `t`
    /// (they are not integrated; forces and the contact correction then see the prescribed
    /// state, and fixed boundary vertices enter the correction with their prescribed velocity).
    pub fn step_with(
        &mut self,
        mut prescribe: impl FnMut(usize, f64, &mut [SVector<f64, D>], &mut [SVector<f64, D>]),
    ) -> Result<usize, AuguryError> {
        let dt = self.params.dt;
        let clock = Instant::now();
        if !self.started {
            self.mechanical()?;
            self.contact()?;
            self.started = true;
        }
        // Half-step velocities, then positions.
        for b in &mut self.bodies {
            for k in 0..b.x.len() {
                if b.fixed[k] {
                    continue;
                }
                b.v[k] += b.a[k] * (0.5 * dt);
                b.x[k] += b.v[k] * dt;
            }
        }
        for (b, bd) in self.b.iter_mut().zip(&self.bdot) {
            *b += bd * (0.5 * dt);
        }
        let t1 = self.time + dt;
        for (k, b) in self.bodies.iter_mut().enumerate() {
            prescribe(k, t1, &mut b.x, &mut b.v);
        }
        // New accelerations: mechanical, then the contact correction.
        self.mechanical()?;
        let iterations = self.contact()?;
        for b in &mut self.bodies {
            for k in 0..b.x.len() {
                if !b.fixed[k] {
                    b.v[k] += b.a[k] * (0.5 * dt);
                }
            }
        }
        for (b, bd) in self.b.iter_mut().zip(&self.bdot) {
            *b += bd * (0.5 * dt);
        }
        self.time = t1;
        self.timing.step_s = clock.elapsed().as_secs_f64();
        Ok(iterations)
    }

    /// The state a step starts from: every body's positions, velocities and accelerations, the
    /// particles' `B_p` and their rates, and the time.
    pub fn state(&self) -> ExplicitState<D> {
        ExplicitState {
            bodies: self
                .bodies
                .iter()
                .map(|b| (b.x.clone(), b.v.clone(), b.a.clone()))
                .collect(),
            b: self.b.clone(),
            bdot: self.bdot.clone(),
            time: self.time,
            started: self.started,
        }
    }

    /// Go back to a state taken by [`Self::state`] of this system (copies, no allocation): the
    /// next step is the one that followed it (to round-off: the same bits).
    pub fn set_state(&mut self, s: &ExplicitState<D>) {
        for (b, (x, v, a)) in self.bodies.iter_mut().zip(&s.bodies) {
            b.x.copy_from_slice(x);
            b.v.copy_from_slice(v);
            b.a.copy_from_slice(a);
        }
        self.b.copy_from_slice(&s.b);
        self.bdot.copy_from_slice(&s.bdot);
        self.time = s.time;
        self.started = s.started;
    }

    /// Total linear momentum.
    pub fn momentum(&self) -> SVector<f64, D> {
        self.bodies
            .iter()
            .flat_map(|b| b.v.iter().zip(&b.mass).map(|(v, m)| v * *m))
            .sum()
    }

    /// Total angular momentum about the origin, including the boundary particles' APIC term
    /// `Σ m_p ε : B_pᵀ` (the quantity APIC augury conserves exactly).
    pub fn angular_momentum(&self) -> Vector3<f64> {
        let mut l = Vector3::zeros();
        let mut k = 0;
        for b in &self.bodies {
            l += crate::operator::angular_momentum(&b.mass, &b.x, &b.v, None);
            for &v in &b.boundary {
                l += femp_kernels::transfer::apic_spin(&self.b[k]) * b.mass[v];
                k += 1;
            }
        }
        l
    }

    /// Kinetic energy `½ Σ m |v|²`.
    pub fn kinetic_energy(&self) -> f64 {
        self.bodies
            .iter()
            .flat_map(|b| {
                b.v.iter()
                    .zip(&b.mass)
                    .map(|(v, m)| 0.5 * m * v.norm_squared())
            })
            .sum()
    }

    /// Elastic energy.
    pub fn elastic_energy(&self) -> f64 {
        self.bodies
            .iter()
            .map(|b| b.elastic.energy(&b.x).unwrap_or(f64::INFINITY))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use femp_contact::distance::point_triangle;
    use proptest::prelude::*;

    use super::*;

    fn v(a: [f64; 3]) -> Vector3<f64> {
        Vector3::new(a[0], a[1], a[2])
    }

    /// The baseline's plain-double closest point against femp-contact's robust one: the same
    /// point to round-off of the triangle's size, weights that sum to 1 and rebuild it.
    fn agrees(p: Vector3<f64>, a: Vector3<f64>, b: Vector3<f64>, c: Vector3<f64>) {
        let w = closest_weights(&p, &a, &b, &c).expect("a triangle with area");
        assert!(
            w.iter().all(|&x| (-1e-12..=1.0 + 1e-12).contains(&x)),
            "{w:?}"
        );
        assert!((w.iter().sum::<f64>() - 1.0).abs() <= 1e-12);
        let q = a * w[0] + b * w[1] + c * w[2];
        let r = point_triangle::closest_point(&p, &a, &b, &c);
        let scale = [a, b, c, p].iter().map(|x| x.norm()).fold(1.0, f64::max);
        assert!(
            (q - r).norm() <= 1e-10 * scale,
            "{p:?} vs ({a:?}, {b:?}, {c:?}): {q:?} against {r:?}"
        );
    }

    #[test]
    fn closest_point_in_every_region_and_on_slivers() {
        let (a, b, c) = (v([0.0, 0.0, 0.0]), v([1.0, 0.0, 0.0]), v([0.0, 1.0, 0.0]));
        // The face, the three vertices, the three edges, and points on the boundaries between
        // regions.
        for p in [
            [0.2, 0.2, 0.5],
            [-1.0, -1.0, 0.3],
            [2.0, -0.5, -0.1],
            [-0.5, 2.0, 0.0],
            [0.5, -1.0, 1.0],
            [1.0, 1.0, -2.0],
            [-1.0, 0.5, 0.0],
            [0.0, 0.0, 1.0],
            [0.5, 0.5, 0.0],
            [1.0, 0.0, 3.0],
        ] {
            agrees(v(p), a, b, c);
        }
        // A needle, a sliver, far from the origin.
        let o = v([1e5, -3e5, 2e5]);
        agrees(
            o + v([0.3, 1e-3, 0.2]),
            o,
            o + v([1.0, 0.0, 0.0]),
            o + v([0.5, 1e-4, 0.0]),
        );
        agrees(
            o + v([0.5, -0.2, 0.0]),
            o,
            o + v([1.0, 0.0, 0.0]),
            o + v([2.0, 1e-6, 0.0]),
        );
    }

    #[test]
    fn triangles_without_area_still_give_the_closest_point() {
        // Two coincident vertices, and three collinear ones (the middle one last): the vertex
        // and edge regions answer, or the robust fallback does — the point on the segment.
        let x = |pts: [[f64; 3]; 3]| {
            pts.map(|p| SVector::<f64, 3>::new(p[0], p[1], p[2]))
                .to_vec()
        };
        let p = SVector::<f64, 3>::new(0.5, 1.0, 0.0);
        for xs in [
            x([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]),
            x([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.0, 0.0]]),
            x([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]),
        ] {
            let (q, w) = closest_on_facet(&p, &[0, 1, 2], &xs);
            let expect = if xs[1] == xs[0] {
                xs[0]
            } else {
                SVector::<f64, 3>::new(0.5, 0.0, 0.0)
            };
            assert!((q - expect).norm() < 1e-15, "{xs:?}: {q:?}");
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15, "{w:?}");
        }
    }

    proptest! {
        #[test]
        fn closest_point_agrees_with_the_robust_one(
            p in prop::array::uniform3(-2.0..2.0f64),
            a in prop::array::uniform3(-1.0..1.0f64),
            b in prop::array::uniform3(-1.0..1.0f64),
            c in prop::array::uniform3(-1.0..1.0f64),
        ) {
            let (a, b, c) = (v(a), v(b), v(c));
            prop_assume!((b - a).cross(&(c - a)).norm() > 1e-3);
            agrees(v(p), a, b, c);
        }
    }
}
