//! The incremental potential of one BFEMP step (eq. 38) as a [`femp_solver::Objective`]:
//!
//! `E(x) = ½‖x − x̂‖²_M + w (Ψ_FEM + Ψ_MPM + B + D − Σ m g·x) + penalties`, `w = 2αβΔt²`,
//!
//! over the DOFs `x = (grid node positions, FEM vertex positions)`. MPM particles are not
//! unknowns: `x_q = x_qⁿ + Σ_i w_iq u_i` and `F_q = (I + Σ_i u_i ∇w_iqᵀ) F_qⁿ` with
//! `u_i = x_i − X_i` (eqs. 25, 29), so every particle term reaches the grid by the chain rule.
//! The feasible step is the minimum of CCD (particles and FEM vertices against FEM boundaries),
//! det F > 0 of FEM elements, and det F > 0 of MPM particles.
//!
//! One type per term, each with its energy, gradient, Hessian and step bound, over one
//! [`Configuration`](config::Configuration) of the bodies at the current `x`:
//! [`Inertia`](inertia::Inertia) (inertia, gravity, slip penalties),
//! [`ParticleElasticity`](particles::ParticleElasticity) (MPM, on the grid),
//! [`ElementElasticity`](elements::ElementElasticity) (FEM, femp-fem's own derivatives) and
//! [`Contact`](contact::Contact) (barrier and lagged friction of every pair, with the term
//! derivatives the gradient and the Hessian at one state share).

use femp_solver::{Objective, StepBound, StepLimit, Triplets};
use nalgebra::SVector;
use std::time::Instant;

use crate::bodies::{Bodies, FemBody, Mpm};

mod config;
mod contact;
mod elements;
mod inertia;
pub(crate) mod particles;

use config::Configuration;
pub(crate) use config::Dofs;
use contact::Contact;
use elements::ElementElasticity;
pub(crate) use inertia::Inertia;
pub use inertia::Penalty;
use particles::ParticleElasticity;

/// Wall-clock seconds spent in the parts of the objective, accumulated over a step.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
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

/// One step's objective: the sum of its terms over one configuration. Built by the stepper;
/// borrows the world's state.
pub struct StepObjective<'a, const D: usize> {
    mpm: Option<&'a Mpm<D>>,
    fem: &'a [FemBody<D>],
    /// DOF values at the start of the step (grid node positions, FEM xⁿ).
    x_start: &'a [f64],
    dofs: Dofs,
    /// The integrator's weight `w` of every potential but inertia.
    w: f64,
    cfg: Configuration<D>,
    inertia: Inertia<'a, D>,
    particles: ParticleElasticity<'a, D>,
    elements: ElementElasticity<'a, D>,
    contact: Contact<'a, D>,
    /// Grid increments and particle displacements along a direction ([`Objective::max_step`]).
    motion: (Vec<SVector<f64, D>>, Vec<SVector<f64, D>>),
    /// The gradient computes the barrier's exact Hessian for the cache (the solver asks for
    /// [`Objective::exact_hessian`] first: `HessianStrategy::ExactWhenDefinite`).
    pub(crate) prefer_exact: bool,
    /// Newton's convergence test measures an increment on the particles and FEM vertices
    /// ([`ParticleElasticity::increment_size`]) instead of on the unknowns
    /// (`solver.newton_test`).
    pub(crate) point_test: bool,
    /// Newton directions that carry friction terms through their stick zone are solved again
    /// with those terms modelled as stuck ([`Objective::begin_model`]).
    pub(crate) stick_model: bool,
    /// Where the time went.
    pub(crate) timing: ObjectiveTiming,
    /// Number of active contact terms and smallest contact distance at the last gradient.
    pub(crate) last_contacts: (usize, f64),
    /// Whether the elastic terms (and their det F > 0 bounds) are part of the objective; not
    /// in the predictor projection of contact-stabilised Newmark ([`Self::contact_only`]).
    elastic: bool,
    /// The friction lag: where the operator was last evaluated, how often, and whether (and
    /// until when) Newton iterations may update it ([`Objective::update_lagged`]).
    pub(crate) lag: FrictionLag<D>,
}

/// Where and how often a step's lagged friction operator was evaluated, and the policy that
/// lets the Newton iterations re-evaluate it (`solver.friction_update_below`).
#[derive(Clone, Debug, Default)]
pub(crate) struct FrictionLag<const D: usize> {
    /// The DOF values the operator was last evaluated at.
    pub at: Vec<f64>,
    /// The points it depends on there: every particle, then every FEM body's vertices.
    pub points: Vec<SVector<f64, D>>,
    /// Evaluations so far.
    pub count: usize,
    /// Friction terms of the last evaluation.
    pub terms: usize,
    /// Newton iterations may re-evaluate the operator while `count` is below this …
    pub limit: usize,
    /// … and the last iteration's increment ‖p‖∞/Δt (m/s) is below this (0: never).
    pub below: f64,
    /// In a later solve of the friction loop (`solver.friction_update_later`): the increment
    /// the last update inside Newton followed, which the next must be below 0.9 of (∞ at the
    /// solve's start); `None` outside such solves.
    pub later: Option<f64>,
    /// Updates inside Newton stopped contracting in this step: later solves keep their lag.
    pub stalled: bool,
}

impl<const D: usize> FrictionLag<D> {
    /// The ratio of successive increments below which updates inside Newton go on.
    const CONTRACTION: f64 = 0.9;

    /// A later solve of the friction loop begins: its Newton iterations may update the
    /// operator while that contracts, unless updates stalled earlier in the step.
    pub fn begin_later_solve(&mut self) {
        self.later = (!self.stalled).then_some(f64::INFINITY);
    }

    /// Whether a Newton iteration whose last increment was `residual` (m/s) updates the
    /// operator: `friction_update_below`'s rule, or in a later solve while each increment
    /// after an update is below [`Self::CONTRACTION`] of the one before it.
    fn updates_at(&mut self, residual: f64) -> bool {
        if self.count == 0 || self.count >= self.limit {
            return false;
        }
        if let Some(last) = self.later {
            if residual < Self::CONTRACTION * last {
                self.later = Some(residual);
                return true;
            }
            self.later = None;
            self.stalled = true;
            return false;
        }
        residual < self.below
    }
}

impl<'a, const D: usize> StepObjective<'a, D> {
    /// The potential of a step of length `dt` over `bodies`, with their unknowns laid out by
    /// `dofs`, the quadratic terms `inertia`, the step's start `x_start` (where the line
    /// search's feasible paths begin) and the integrator weight `w`.
    pub(crate) fn new(
        bodies: &'a Bodies<D>,
        dt: f64,
        dofs: Dofs,
        inertia: Inertia<'a, D>,
        x_start: &'a [f64],
        w: f64,
    ) -> Self {
        let (mpm, fem) = (bodies.mpm.as_ref(), &bodies.fem[..]);
        Self {
            mpm,
            fem,
            x_start,
            dofs,
            w,
            cfg: Configuration::new(fem),
            inertia,
            particles: ParticleElasticity::new(mpm),
            elements: ElementElasticity::new(fem),
            contact: Contact::new(mpm, fem, &bodies.pairs, dt),
            motion: (Vec::new(), Vec::new()),
            prefer_exact: false,
            point_test: false,
            stick_model: false,
            timing: ObjectiveTiming::default(),
            last_contacts: (0, f64::INFINITY),
            elastic: true,
            lag: FrictionLag::default(),
        }
    }

    /// The objective without its elastic terms: `½‖x − x̂‖²_M + w B(x)` (with the gravity and
    /// penalties it was built with), the mass-norm projection of `x̂` onto the configurations
    /// the barrier admits (contact-stabilised Newmark's predictor step). Its feasible step is
    /// CCD's alone: nothing deforms elastically in it, so nothing can invert.
    pub(crate) fn contact_only(mut self) -> Self {
        self.elastic = false;
        self
    }

    /// Write the contact terms' gradient `w ∇(B + D)` at `x` into `g` (all DOFs).
    pub(crate) fn contact_gradient(&mut self, x: &[f64], g: &mut [f64]) {
        self.unpack(x);
        g.iter_mut().for_each(|v| *v = 0.0);
        let clock = Instant::now();
        self.contact
            .add_gradient(&self.cfg, &self.dofs, self.w, self.prefer_exact, g);
        self.timing.contact_s += clock.elapsed().as_secs_f64();
    }

    /// Move the configuration to `x` (once per `x`).
    fn unpack(&mut self, x: &[f64]) {
        let clock = Instant::now();
        if self
            .cfg
            .update(x, self.x_start, self.mpm, self.fem, &self.dofs)
        {
            self.timing.unpack_s += clock.elapsed().as_secs_f64();
        }
    }

    /// Recompute the lagged friction operator at `x` (Algorithm 1, lines 5 and 9).
    pub(crate) fn lag_friction(&mut self, x: &[f64]) {
        self.unpack(x);
        self.cfg.touch();
        self.lag.terms = self.contact.lag_friction(&self.cfg);
        self.lag.count += 1;
        self.lag.at.clear();
        self.lag.at.extend_from_slice(x);
        self.lag.points.clear();
        self.lag.points.extend_from_slice(&self.cfg.xq);
        for b in &self.cfg.fem_x {
            self.lag.points.extend_from_slice(b);
        }
    }

    /// How far the points the friction operator depends on (particles, FEM vertices) are at
    /// `x` from where it was last evaluated: the largest distance. Measured on the points,
    /// not on the unknowns: a grid node a particle barely touches (masses down to 1e-13 of
    /// the others') can swing between lagged solves without moving any particle — the
    /// operator, a function of the points, is then the same.
    pub(crate) fn lag_distance(&mut self, x: &[f64]) -> f64 {
        self.unpack(x);
        let now = self.cfg.xq.iter().chain(self.cfg.fem_x.iter().flatten());
        now.zip(&self.lag.points)
            .map(|(a, b)| (a - b).amax())
            .fold(0.0, f64::max)
    }

    /// The points' fixed-point residual at `x`: each particle's and FEM vertex's position minus
    /// where the friction operator last saw it, coordinates in a row, into `out`.
    pub(crate) fn lag_residual(&mut self, x: &[f64], out: &mut Vec<f64>) {
        self.unpack(x);
        let now = self.cfg.xq.iter().chain(self.cfg.fem_x.iter().flatten());
        out.clear();
        for (a, b) in now.zip(&self.lag.points) {
            out.extend((a - b).iter());
        }
    }

    /// The contact force of every pair at `x` ([`Contact::pair_forces`]).
    pub(crate) fn pair_forces(
        &mut self,
        x: &[f64],
        on_particles: &mut [SVector<f64, D>],
        on_vertices: &mut [Vec<SVector<f64, D>>],
    ) -> Vec<[SVector<f64, D>; 2]> {
        self.unpack(x);
        self.contact
            .pair_forces(&self.cfg, on_particles, on_vertices)
    }

    /// Number of active contact terms and smallest contact distance over all pairs at `x`.
    pub(crate) fn contact_summary(&mut self, x: &[f64]) -> (usize, f64) {
        self.unpack(x);
        self.contact.summary(&self.cfg)
    }

    /// The Hessian with PSD-projected element, particle and barrier terms, or (`exact`) the
    /// exact one. Friction's lagged operator is PSD by construction and the same in both.
    fn build_hessian(&mut self, x: &[f64], h: &mut Triplets, exact: bool) {
        self.unpack(x);
        let (w, dofs, cfg) = (self.w, &self.dofs, &self.cfg);
        self.inertia.hessian(h);
        // The particles' blocks (parallel, into the grid Hessian) alongside the elements'
        // triplets (into `h`) and the contact derivatives.
        let (particles, elements, contact) =
            (&mut self.particles, &mut self.elements, &mut self.contact);
        let elastic = self.elastic;
        let (mpm_s, (fem_s, contact_s)) = rayon::join(
            || {
                let clock = Instant::now();
                if elastic {
                    particles.hessian(cfg, dofs, w, exact);
                } else {
                    particles.clear_hessian(dofs);
                }
                clock.elapsed().as_secs_f64()
            },
            || {
                let mut clock = Instant::now();
                if elastic {
                    elements.hessian(cfg, dofs, w, exact, h);
                }
                let fem_s = lap(&mut clock);
                contact.prepare_hessian(cfg, dofs, w, exact);
                (fem_s, lap(&mut clock))
            },
        );
        self.timing.mpm_s += mpm_s;
        self.timing.fem_s += fem_s;
        self.timing.contact_s += contact_s;
        // The contact terms' blocks (particle–particle ones into the grid Hessian).
        let mut clock = Instant::now();
        self.contact
            .scatter_hessian(&self.dofs, w, h, &mut self.particles.gh);
        self.timing.contact_s += lap(&mut clock);
        self.particles.emit(h);
        self.timing.emit_s += lap(&mut clock);
    }

    fn energy_impl(&mut self, x: &[f64]) -> f64 {
        self.unpack(x);
        let w = self.w;
        let e = self.inertia.energy(x, w);
        // MPM elasticity (parallel) alongside the elements' and the contact terms' energies.
        let (cfg, particles, elements, contact) = (
            &self.cfg,
            &self.particles,
            &self.elements,
            &mut self.contact,
        );
        if !self.elastic {
            return e + contact.add_energy(cfg, w, 0.0);
        }
        let (el, rest) = rayon::join(
            || particles.energy(cfg),
            || {
                let e = elements.add_energy(cfg, w, 0.0);
                if e.is_finite() {
                    contact.add_energy(cfg, w, e)
                } else {
                    e
                }
            },
        );
        if !el.is_finite() {
            return f64::INFINITY;
        }
        e + w * el + rest
    }
}

impl<const D: usize> Objective for StepObjective<'_, D> {
    fn num_dofs(&self) -> usize {
        self.dofs.n
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
        let (w, dofs, cfg) = (self.w, &self.dofs, &self.cfg);
        self.inertia.set_gradient(x, w, g);
        if self.elastic {
            self.particles.add_gradient(cfg, dofs, w, g);
            self.timing.mpm_s += lap(&mut clock);
            self.elements.add_gradient(cfg, dofs, w, g);
            self.timing.fem_s += lap(&mut clock);
        }
        self.last_contacts = self
            .contact
            .add_gradient(cfg, dofs, w, self.prefer_exact, g);
        self.timing.contact_s += lap(&mut clock);
    }

    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        self.build_hessian(x, h, false);
    }

    fn exact_hessian(&mut self, x: &[f64], h: &mut Triplets) -> bool {
        self.build_hessian(x, h, true);
        true
    }

    fn hessian_terms_unchanged(&mut self) -> bool {
        self.contact.hessian_terms_unchanged()
    }

    fn increment_size(&mut self, _x: &[f64], p: &[f64]) -> Option<f64> {
        if !self.point_test {
            return None;
        }
        let n = self.dofs.n_grid * D;
        let particles = self.particles.increment_size(&p[..n]);
        Some(p[n..].iter().fold(particles, |m, v| m.max(v.abs())))
    }

    fn update_lagged(&mut self, x: &[f64], residual: f64) -> bool {
        if self.lag.at == x || !self.lag.updates_at(residual) {
            return false;
        }
        self.lag_friction(x);
        true
    }

    fn begin_model(&mut self, x: &[f64], p: &[f64]) -> bool {
        if !self.stick_model {
            return false;
        }
        self.unpack(x);
        let clock = Instant::now();
        let (pg, dq) = &mut self.motion;
        let stuck = self.particles.motion(p, &self.dofs, pg, dq)
            && self.contact.begin_stick_model(&self.cfg, &self.dofs, p, dq) > 0;
        self.timing.contact_s += clock.elapsed().as_secs_f64();
        stuck
    }

    fn end_model(&mut self) {
        self.contact.end_stick_model();
    }

    fn max_step(&mut self, x: &[f64], p: &[f64]) -> StepBound {
        self.unpack(x);
        let clock = Instant::now();
        // Particle displacements along p (for CCD) and grid increments (for det F); if they
        // cannot be interpolated (a non-finite direction), no step is known to be safe.
        let (pg, dq) = &mut self.motion;
        let interpolated = self.particles.motion(p, &self.dofs, pg, dq);
        let setup_s = clock.elapsed().as_secs_f64();
        // The particles' det F bound (parallel) alongside the elements' and CCD (sequential).
        let (cfg, dofs, particles, elements, contact) = (
            &self.cfg,
            &self.dofs,
            &self.particles,
            &mut self.elements,
            &mut self.contact,
        );
        let ((mpm_alpha, mpm_s), (fem_alpha, fem_s, ccd_alpha, ccd_s)) = rayon::join(
            || {
                let t = Instant::now();
                (particles.det_bound(cfg, pg), t.elapsed().as_secs_f64())
            },
            || {
                let t = Instant::now();
                let fem = elements.det_bound(cfg, dofs, p);
                let fem_s = t.elapsed().as_secs_f64();
                let ccd = contact.ccd_bound(cfg, dofs, p, dq);
                (fem, fem_s, ccd, t.elapsed().as_secs_f64() - fem_s)
            },
        );
        self.timing.inversion_s += setup_s + mpm_s + fem_s;
        self.timing.ccd_s += ccd_s;
        let (mpm_alpha, fem_alpha) = if self.elastic {
            (mpm_alpha, fem_alpha)
        } else {
            (f64::INFINITY, f64::INFINITY)
        };
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

#[cfg(test)]
mod tests;
