//! One BFEMP time step (Algorithm 1), `Bfemp::step` over a world without its stepper (`Parts`):
//! particle-to-grid, the lagged-friction loop around the incremental-potential minimisation
//! (Algorithm 2, [`femp_solver::Newton`]), the velocity update, grid-to-particle and advection;
//! a step whose points' straight paths pass through a body solved again in substeps.

use femp_kernels::transfer;
use femp_solver::{
    Forcing, HessianStrategy, Integrator, LinearSolver, Newton, NewtonParams, Ordering, Precision,
    Threads,
};
use nalgebra::{SMatrix, SVector};

use crate::bodies::{Bodies, Transfer};
use crate::clock::Clock;
use crate::error::SimError;
use crate::objective::{Dofs, Inertia, Penalty, StepObjective};
use crate::report::{StepReport, Unknown};
use crate::scene::spec::{
    LinearSpec, NewtonTestSpec, OrderingSpec, PrecisionSpec, ProjectionSpec, SolverSpec,
};
use crate::scene::{BoundaryCondition, IntegratorSpec, Scene};

/// The state of the implicit (BFEMP) method.
pub struct Bfemp {
    /// The time integrator of the incremental potential.
    pub integrator: Integrator,
    /// Contact-stabilised Newmark: the predictor is projected onto what the barrier admits
    /// before the step, and the acceleration carried to the next step excludes contact.
    pub contact_stabilized: bool,
    /// The Newton solver (kept across steps: symbolic factorisations and buffers are reused).
    pub newton: Newton,
    /// The predictor projection's Newton solver (contact-stabilised Newmark; its own Hessian
    /// pattern, so kept apart from the step's).
    pub projection: Newton,
}

impl Bfemp {
    /// The implicit method with the scene's integrator and fresh solvers.
    pub(crate) fn new(integrator: IntegratorSpec) -> Self {
        Self {
            integrator: match integrator {
                IntegratorSpec::BackwardEuler => Integrator::BackwardEuler,
                IntegratorSpec::Newmark | IntegratorSpec::ContactStabilizedNewmark => {
                    Integrator::Newmark
                }
            },
            contact_stabilized: integrator == IntegratorSpec::ContactStabilizedNewmark,
            newton: Newton::new(),
            projection: Newton::new(),
        }
    }
}

/// A BFEMP world's state at the start of a step (`Parts::save`): the positions (also the
/// start of the step's straight paths) and what else a step changes, to solve it again in
/// substeps.
pub(crate) struct Saved<const D: usize> {
    time: f64,
    step: usize,
    at: crate::sweep::Positions<D>,
    /// MPM: v, B, F, a, contact force.
    mpm: Option<SavedMpm<D>>,
    /// Each FEM body: v, a, contact force.
    fem: Vec<[Vec<SVector<f64, D>>; 3]>,
}

/// The particles' state besides their positions.
struct SavedMpm<const D: usize> {
    v: Vec<SVector<f64, D>>,
    b: Vec<SMatrix<f64, D, D>>,
    f: Vec<SMatrix<f64, D, D>>,
    a: Vec<SVector<f64, D>>,
    contact_force: Vec<SVector<f64, D>>,
}

/// The grid of a step after particle-to-grid (empty without MPM bodies): active nodes, their
/// mass, velocity, start-of-step acceleration (Newmark) and position.
struct GridState<const D: usize> {
    n_grid: usize,
    grid_m: Vec<f64>,
    grid_v: Vec<SVector<f64, D>>,
    grid_a: Vec<SVector<f64, D>>,
    grid_x: Vec<SVector<f64, D>>,
    /// External forces on the particles spread to the nodes, `Σ_p w_ip f_p` (empty: none).
    grid_f: Vec<SVector<f64, D>>,
}

/// The unknowns of one step and what they start from (see `Parts::setup`).
pub(crate) struct StepSetup<const D: usize> {
    pub(crate) n_grid: usize,
    pub(crate) grid_v: Vec<SVector<f64, D>>,
    pub(crate) grid_x: Vec<SVector<f64, D>>,
    pub(crate) fem_offset: Vec<usize>,
    pub(crate) n_dofs: usize,
    pub(crate) mass: Vec<f64>,
    pub(crate) x0: Vec<f64>,
    pub(crate) v0: Vec<f64>,
    pub(crate) a0: Vec<f64>,
    pub(crate) fixed: Vec<bool>,
    pub(crate) target: Vec<f64>,
    pub(crate) penalties: Vec<Penalty<D>>,
    pub(crate) x_hat: Vec<f64>,
    /// External force per DOF set from outside ([`crate::steer`]), or empty for none.
    pub(crate) force: Vec<f64>,
    pub(crate) transfers_s: f64,
}

/// A world without its stepper: what a step advances.
pub(crate) struct Parts<'a, const D: usize> {
    /// The scene (the solver's settings).
    pub(crate) scene: &'a Scene,
    /// The bodies.
    pub(crate) bodies: &'a mut Bodies<D>,
    /// The clock.
    pub(crate) clock: &'a mut Clock,
}

impl Bfemp {
    /// One BFEMP step, checked along the straight paths of its points ([`crate::sweep`]): if a
    /// point's path from where it was to where the step put it passes through a body, the step
    /// is solved again from its start in substeps ([`crate::World::step`] says how).
    pub(crate) fn step<const D: usize>(
        &mut self,
        mut w: Parts<'_, D>,
    ) -> Result<StepReport, SimError> {
        // The Newton solver checks the interrupt flag before every iteration.
        let saved = w.save();
        let mut report = self.solve(&mut w)?;
        report.swept = w.bodies.sweep_pairs(&saved.at);
        if report.swept.tunnelled == 0 {
            return Ok(report);
        }
        self.substepped(&mut w, &saved, report)
    }

    /// The step from `saved` again in substeps, after `first` (the whole step's attempt) let a
    /// point pass through a body.
    fn substepped<const D: usize>(
        &mut self,
        w: &mut Parts<'_, D>,
        saved: &Saved<D>,
        first: StepReport,
    ) -> Result<StepReport, SimError> {
        let (dt, max) = (w.clock.dt, w.scene.spec().solver.max_substeps);
        let mut worst = first.swept.clone();
        let mut work = StepReport::default();
        work.add_work(&first);
        let mut n = 2;
        while n <= max {
            w.restore(saved);
            w.set_dt(dt / n as f64);
            let attempt = self.substeps(w, n, &mut work);
            w.set_dt(dt);
            match attempt? {
                Ok(mut report) => {
                    w.clock.time = saved.time + dt;
                    w.clock.step = saved.step + 1;
                    let last = std::mem::take(&mut report);
                    report = work;
                    report.take_state(last);
                    report.substeps = n;
                    return Ok(report);
                }
                Err(swept) => worst = swept,
            }
            n = if n == max { max + 1 } else { (2 * n).min(max) };
        }
        w.restore(saved);
        Err(SimError::StepFailed {
            step: saved.step,
            time: saved.time,
            message: format!(
                "a point passed through a body: {}{}; reduce time.dt (the points move too far \
                 in one step for the bodies they meet)",
                worst.describe(),
                if max > 1 {
                    format!(", even in substeps of Δt/{max} (solver.max_substeps)")
                } else {
                    " (solver.max_substeps = 1: no substeps)".to_string()
                }
            ),
        })
    }

    /// `n` steps of the current Δt, each checked along its straight paths: the last one's report
    /// with every one's work added into `work`, or the straight-path report of the first that
    /// let a point through.
    fn substeps<const D: usize>(
        &mut self,
        w: &mut Parts<'_, D>,
        n: usize,
        work: &mut StepReport,
    ) -> Result<Result<StepReport, crate::sweep::SweptReport>, SimError> {
        let mut last = StepReport::default();
        let mut swept = crate::sweep::SweptReport::default();
        for _ in 0..n {
            let before = w.bodies.positions();
            let mut r = self.solve(w)?;
            r.swept = w.bodies.sweep_pairs(&before);
            work.add_work(&r);
            if r.swept.tunnelled > 0 {
                return Ok(Err(r.swept));
            }
            swept.merge(r.swept.clone());
            last = r;
        }
        last.swept = swept;
        Ok(Ok(last))
    }

    /// One BFEMP step with the method's integrator (its straight paths not checked): steps
    /// 1–2 in `Parts::setup`, the contact-stabilised predictor's projection, the friction loop
    /// around the minimisation ([`Bfemp::minimize`]), the contact forces and the acceleration
    /// carried to the next step ([`contact_outcome`]), then steps 4–5 in `Parts::finish`.
    fn solve<const D: usize>(&mut self, w: &mut Parts<'_, D>) -> Result<StepReport, SimError> {
        let (dt, integrator) = (w.clock.dt, self.integrator);
        let clock = std::time::Instant::now();
        let mut s = w.setup(integrator)?;
        let clock_setup = clock.elapsed().as_secs_f64() - s.transfers_s;
        let clock = std::time::Instant::now();
        // 3. The friction loop around the minimisation.
        let params = newton_params::<D>(&w.scene.spec().solver, dt);
        let weight = integrator.weight(dt);
        let point_test = w.scene.spec().solver.newton_test == NewtonTestSpec::Points;
        let any_friction = w.bodies.pairs.iter().any(|p| p.friction.mu > 0.0);
        let mut report = StepReport {
            friction_converged: true,
            transfers_s: s.transfers_s,
            ..Default::default()
        };
        if self.contact_stabilized && !w.bodies.pairs.is_empty() {
            self.project_predictor(w, &mut s, &params, (weight, point_test), &mut report)?;
        }
        let mut x = s.x0.clone();
        // Start the fixed DOFs where they are; Newton moves them to their targets.
        let mut obj = s.objective(w.bodies, dt, weight);
        obj.point_test = point_test;
        obj.stick_model = w.scene.spec().solver.friction_stick_model;
        let _ = start_at_predictor(&mut obj, &s.x0, &s.fixed, &s.target, &s.x_hat, &mut x);
        report.setup_s = clock_setup + clock.elapsed().as_secs_f64();
        self.minimize(
            (w.scene, w.clock, any_friction),
            &mut obj,
            &mut x,
            &s,
            &params,
            &mut report,
        )?;
        let outcome = contact_outcome(
            &mut obj,
            w.bodies,
            &x,
            &s,
            (integrator, self.contact_stabilized, weight),
            &mut report,
        );
        report.objective.add(&obj.timing);
        drop(obj);
        report.largest_increments = report
            .stats
            .trace
            .iter()
            .map(|r| s.unknown(r.largest.0))
            .collect();
        if let Some(m) = w.bodies.mpm.as_mut() {
            m.contact_force = outcome.on_particles;
        }
        for (body, f) in w.bodies.fem.iter_mut().zip(outcome.on_vertices) {
            body.contact_force = f;
        }
        if x.iter().any(|v| !v.is_finite()) {
            return Err(SimError::StepFailed {
                step: w.clock.step,
                time: w.clock.time,
                message: "the solution contains non-finite positions".into(),
            });
        }
        w.finish(integrator, &s, &x, &outcome.carried, &mut report)?;
        Ok(report)
    }

    /// Contact-stabilised Newmark, the predictor step: `x_p = argmin ½‖x − (xⁿ + Δt vⁿ)‖²_M +
    /// w B(x)` (prescribed DOFs at their targets), and `x̂ = x_p + Δt²/4 aⁿ` (`s.x_hat` moved by
    /// `x_p` minus the free-flight predictor).
    fn project_predictor<const D: usize>(
        &mut self,
        w: &Parts<'_, D>,
        s: &mut StepSetup<D>,
        params: &NewtonParams,
        (weight, point_test): (f64, bool),
        report: &mut StepReport,
    ) -> Result<(), SimError> {
        let mut raw = vec![0.0; s.n_dofs];
        Integrator::BackwardEuler.predictor(w.clock.dt, &s.x0, &s.v0, &s.a0, &mut raw);
        let mut xp = s.x0.clone();
        let mut proj = StepObjective::new(
            w.bodies,
            w.clock.dt,
            s.dofs(),
            Inertia {
                mass: &s.mass,
                x_hat: &raw,
                gravity: SVector::zeros(),
                force: &[],
                penalties: &[],
            },
            &s.x0,
            weight,
        )
        .contact_only();
        proj.point_test = point_test;
        // Where the predictor is reached along a feasible path and no barrier term is active
        // there, it is the projection's minimiser (the objective is 0 there and nowhere
        // negative): Newmark's predictor stays as it is, bit for bit.
        let at_raw = start_at_predictor(&mut proj, &s.x0, &s.fixed, &s.target, &raw, &mut xp);
        if !at_raw || proj.contact_summary(&xp).0 > 0 {
            let stats = self
                .projection
                .minimize_to(&mut proj, &mut xp, &s.fixed, &s.target, params)
                .map_err(|e| match e {
                    femp_solver::SolveError::Interrupted { .. } => SimError::Interrupted {
                        step: w.clock.step,
                        time: w.clock.time,
                    },
                    e => SimError::StepFailed {
                        step: w.clock.step,
                        time: w.clock.time,
                        message: format!("{e} (contact-stabilised predictor)"),
                    },
                })?;
            report.newton_iterations += stats.iterations;
            report.stats += &stats;
            for d in 0..s.n_dofs {
                if !s.fixed[d] {
                    s.x_hat[d] += xp[d] - raw[d];
                }
            }
        }
        report.objective.add(&proj.timing);
        Ok(())
    }

    /// The friction loop around the minimisation of `obj` from `x` ([`friction_loop`]); if it
    /// fails and `solver.retry_other_projection` is on, solved again from the same start with
    /// the other Hessian strategy (where one stalls the other often does not), the failed
    /// attempt's work counted in the report.
    fn minimize<const D: usize>(
        &mut self,
        (scene, clock, any_friction): (&Scene, &Clock, bool),
        obj: &mut StepObjective<'_, D>,
        x: &mut Vec<f64>,
        s: &StepSetup<D>,
        params: &NewtonParams,
        report: &mut StepReport,
    ) -> Result<(), SimError> {
        let solver = &scene.spec().solver;
        let max_fric = if any_friction {
            solver.max_friction_iterations
        } else {
            1
        };
        let policy = FrictionPolicy {
            any: any_friction,
            max_solves: max_fric,
            update_below: solver.friction_update_below,
            update_later: solver.update_later(D),
            forcing: solver.forcing(D),
            extrapolate: solver.friction_extrapolation,
            relax: solver.friction_relaxation.then_some(1.0),
            aitken: solver.aitken(D),
            anderson: solver.anderson(D),
        };
        let (step, time) = (clock.step, clock.time);
        let failed = |(e, j): (femp_solver::SolveError, usize)| match e {
            femp_solver::SolveError::Interrupted { .. } => SimError::Interrupted { step, time },
            e => SimError::StepFailed {
                step,
                time,
                message: format!(
                    "{e}{}",
                    if any_friction {
                        format!(" (friction iteration {})", j + 1)
                    } else {
                        String::new()
                    }
                ),
            },
        };
        let start = x.clone();
        let mut solve = |obj: &mut StepObjective<'_, D>,
                         x: &mut Vec<f64>,
                         params: &NewtonParams,
                         report: &mut StepReport| {
            friction_loop(
                &mut self.newton,
                obj,
                x,
                &s.x0,
                (&s.fixed, &s.target),
                params,
                policy,
                report,
            )
        };
        // The attempts after a failed solve, each from the step's start: an inexact linear
        // solve (CG) is retried with direct solves and the same Hessian strategy — CG's
        // tolerance can lead Newton to a point no direction leaves (docs/performance.md,
        // `last_factor_cg`) — then, with `retry_other_projection`, the other strategy.
        let direct = NewtonParams {
            linear: LinearSolver::Cholesky,
            ..*params
        };
        let other = NewtonParams {
            hessian: match params.hessian {
                HessianStrategy::Projected => HessianStrategy::ExactWhenDefinite,
                _ => HessianStrategy::Projected,
            },
            ..direct
        };
        // (The first only if the failed attempt solved by CG: with `LinearSolver::Auto` on a
        // small matrix it was direct solves already.)
        let retries = [
            (params.linear != LinearSolver::Cholesky).then_some((direct, "direct solves", true)),
            solver.retry_other_projection.then_some((
                other,
                match other.hessian {
                    HessianStrategy::Projected => "projected Newton",
                    _ => "the exact Hessian when definite",
                },
                false,
            )),
        ];
        let mut retries = retries.iter().flatten();
        let mut attempt = (*params, "");
        // The failures so far, as one error (the latest first).
        let mut so_far: Option<SimError> = None;
        let mut solved_by_cg = false;
        loop {
            let e = match solve(obj, x, &attempt.0, report) {
                Ok(()) => {
                    if let Some(failed) = so_far {
                        report.retried = Some(format!("{failed}; solved again with {}", attempt.1));
                    }
                    return Ok(());
                }
                Err(e) if matches!(e.0, femp_solver::SolveError::Interrupted { .. }) => {
                    return Err(failed(e));
                }
                Err(e) => e,
            };
            if let Some(stats) = e.0.stats() {
                report.newton_iterations += stats.iterations;
                report.stats += stats;
                solved_by_cg = stats.pcg_iterations > 0;
            }
            let e = match (failed(e), so_far.take()) {
                (e, None) => e,
                (
                    SimError::StepFailed {
                        step,
                        time,
                        message,
                    },
                    Some(before),
                ) => SimError::StepFailed {
                    step,
                    time,
                    message: format!("{message}, retried with {} after: {before}", attempt.1),
                },
                (e, Some(_)) => e,
            };
            let Some(&(next, how, _)) = retries.find(|r| !r.2 || solved_by_cg) else {
                return Err(e);
            };
            so_far = Some(e);
            x.copy_from_slice(&start);
            report.friction_converged = true;
            attempt = (next, how);
        }
    }
}

/// What the contact terms leave at a step's solution: the contact force on each particle and
/// FEM vertex, and the acceleration carried to the next step.
struct ContactOutcome<const D: usize> {
    on_particles: Vec<SVector<f64, D>>,
    on_vertices: Vec<Vec<SVector<f64, D>>>,
    /// Per DOF (empty if the integrator carries no acceleration).
    carried: Vec<f64>,
}

/// The contact forces of `obj` at the solution `x` (per pair into the report, with the number
/// of contact terms and the smallest distance) and the acceleration carried to the next step.
fn contact_outcome<const D: usize>(
    obj: &mut StepObjective<'_, D>,
    bodies: &Bodies<D>,
    x: &[f64],
    s: &StepSetup<D>,
    (integrator, contact_stabilized, weight): (Integrator, bool, f64),
    report: &mut StepReport,
) -> ContactOutcome<D> {
    let (nterms, dmin) = obj.contact_summary(x);
    let pad = |v: &SVector<f64, D>| std::array::from_fn(|a| if a < D { v[a] } else { 0.0 });
    let mut on_particles = vec![SVector::zeros(); bodies.mpm.as_ref().map_or(0, |m| m.x.len())];
    let mut on_vertices: Vec<Vec<SVector<f64, D>>> = bodies
        .fem
        .iter()
        .map(|b| vec![SVector::zeros(); b.x.len()])
        .collect();
    report.pair_forces = obj
        .pair_forces(x, &mut on_particles, &mut on_vertices)
        .iter()
        .map(|[b, f]| [pad(b), pad(f)])
        .collect();
    report.contact_terms = nterms;
    report.min_distance = dmin;
    // The contact terms' part of the new acceleration, −M⁻¹∇(B + D)(x) (the step's
    // minimality: M(x − x̂) = −w∇(Ψ + B + D) − ∇P + w M g): what plain Newmark carries to
    // the next step besides the slip penalties' part; contact-stabilised Newmark carries
    // neither contact part.
    let (n_dofs, fixed, mass) = (s.n_dofs, &s.fixed, &s.mass);
    let needs_acc = integrator.needs_acceleration();
    let mut carried = vec![0.0; if needs_acc { n_dofs } else { 0 }];
    if needs_acc && nterms > 0 && !contact_stabilized {
        obj.contact_gradient(x, &mut carried);
        for d in 0..n_dofs {
            carried[d] = if fixed[d] || mass[d] <= 0.0 {
                0.0
            } else {
                -carried[d] / (weight * mass[d])
            };
        }
    }
    if needs_acc {
        for p in &s.penalties {
            let (d, gp) = (p.node * D, p.gradient(x));
            for a in 0..D {
                if !fixed[d + a] && mass[d + a] > 0.0 {
                    carried[d + a] -= gp[a] / (weight * mass[d + a]);
                }
            }
        }
    }
    ContactOutcome {
        on_particles,
        on_vertices,
        carried,
    }
}

/// The Newton parameters of the scene's solver settings for a step of `dt`.
pub(crate) fn newton_params<const D: usize>(solver: &SolverSpec, dt: f64) -> NewtonParams {
    NewtonParams {
        tolerance: solver.tolerance,
        dt,
        max_iterations: solver.max_newton_iterations,
        // Auto, measured (docs/performance.md, `cargo xtask bench`): nested dissection as
        // fast as AMD at the twist's 5k 3D unknowns, 1.6× faster per contact step at
        // block_on_plate_3d's 26k.
        ordering: match solver.ordering_in(D) {
            OrderingSpec::Auto | OrderingSpec::Amd => Ordering::Amd,
            OrderingSpec::NestedDissection => Ordering::NestedDissection { block: D },
        },
        threads: Threads::Auto,
        precision: match solver.factor_precision {
            PrecisionSpec::Auto => Precision::Auto,
            PrecisionSpec::Double => Precision::Double,
            PrecisionSpec::Mixed => Precision::Mixed,
        },
        hessian: match solver.projection {
            ProjectionSpec::Always => HessianStrategy::Projected,
            ProjectionSpec::WhenIndefinite => HessianStrategy::ExactWhenDefinite,
        },
        linear: match solver.linear {
            LinearSpec::Cholesky => LinearSolver::Cholesky,
            LinearSpec::Pcg => LinearSolver::Pcg {
                rtol: solver.pcg_rtol,
                max_iterations: solver.pcg_max_iterations,
                forcing: match solver.pcg_rtol_max {
                    Some(max) => Forcing::Adaptive { max },
                    None => Forcing::Fixed,
                },
            },
            LinearSpec::LastFactorCg => LinearSolver::LastFactorCg {
                rtol: solver.factor_cg_rtol,
                max_iterations: solver.factor_cg_iterations,
            },
            LinearSpec::Auto => LinearSolver::Auto {
                rtol: solver.factor_cg_rtol,
                max_iterations: solver.factor_cg_iterations,
            },
        },
        reuse_hessian_below: solver.reuse_hessian_below,
        max_expansion: solver.line_search_expansion,
        ..Default::default()
    }
}

impl<const D: usize> Parts<'_, D> {
    /// Steps 4–5 of a time step from the solution `x`: velocities and accelerations,
    /// grid-to-particle and advection (with the `carried` acceleration interpolated to the
    /// particles), the FEM vertices' new state, and the clock one step on.
    fn finish(
        &mut self,
        integrator: Integrator,
        s: &StepSetup<D>,
        x: &[f64],
        carried: &[f64],
        report: &mut StepReport,
    ) -> Result<(), SimError> {
        let (dt, n_grid) = (self.clock.dt, s.n_grid);
        let needs_acc = integrator.needs_acceleration();
        let failed = |clock: &Clock, message: String| SimError::StepFailed {
            step: clock.step,
            time: clock.time,
            message,
        };
        // 4. Velocities and accelerations.
        let mut v1 = s.v0.clone();
        let mut a1 = s.a0.clone();
        integrator.update(dt, x, &s.x_hat, &mut v1, &mut a1);

        // 5. Grid-to-particle and advection.
        let clock = std::time::Instant::now();
        if let Some(m) = self.bodies.mpm.as_mut() {
            let st = &m.stencils;
            let gv1: Vec<SVector<f64, D>> = (0..n_grid)
                .map(|i| SVector::from_column_slice(&v1[i * D..i * D + D]))
                .collect();
            let gu: Vec<SVector<f64, D>> = (0..n_grid)
                .map(|i| SVector::from_column_slice(&x[i * D..i * D + D]) - s.grid_x[i])
                .collect();
            let res = match m.transfer {
                Transfer::Apic => transfer::g2p_apic(st, &gv1, Some(&gu), &mut m.v, &mut m.b),
                Transfer::Pic => transfer::g2p_pic(st, &gv1, &mut m.v),
                Transfer::Flip(r) => transfer::g2p_flip(st, &gv1, &s.grid_v, r, &mut m.v),
            };
            res.and_then(|_| transfer::advect(st, &gu, &mut m.x, Some(&mut m.f)))
                .map_err(|e| failed(self.clock, e.to_string()))?;
            if needs_acc {
                let carried: Vec<SVector<f64, D>> = (0..n_grid)
                    .map(|i| SVector::from_column_slice(&carried[i * D..i * D + D]))
                    .collect();
                transfer::interpolate(st, &carried, &mut m.a)
                    .map_err(|e| failed(self.clock, e.to_string()))?;
            }
            if let Some(bad) =
                m.f.iter()
                    .position(|f: &SMatrix<f64, D, D>| !(femp_fem::linalg::det(f) > 0.0))
            {
                return Err(failed(
                    self.clock,
                    format!("particle {bad} inverted (det F ≤ 0)"),
                ));
            }
        }
        report.transfers_s += clock.elapsed().as_secs_f64();
        for (b, body) in self.bodies.fem.iter_mut().enumerate() {
            for vtx in 0..body.x.len() {
                let d = s.fem_offset[b] + vtx * D;
                body.x[vtx] = SVector::from_column_slice(&x[d..d + D]);
                body.v[vtx] = SVector::from_column_slice(&v1[d..d + D]);
                if needs_acc {
                    body.a[vtx] = SVector::from_column_slice(&carried[d..d + D]);
                }
            }
        }
        self.clock.time += dt;
        self.clock.step += 1;
        Ok(())
    }
}

impl<const D: usize> Parts<'_, D> {
    /// Set Δt of the steps that follow.
    fn set_dt(&mut self, dt: f64) {
        self.clock.dt = dt;
    }

    /// The state a BFEMP step changes.
    fn save(&self) -> Saved<D> {
        Saved {
            time: self.clock.time,
            step: self.clock.step,
            at: self.bodies.positions(),
            mpm: self.bodies.mpm.as_ref().map(|m| SavedMpm {
                v: m.v.clone(),
                b: m.b.clone(),
                f: m.f.clone(),
                a: m.a.clone(),
                contact_force: m.contact_force.clone(),
            }),
            fem: self
                .bodies
                .fem
                .iter()
                .map(|b| [b.v.clone(), b.a.clone(), b.contact_force.clone()])
                .collect(),
        }
    }

    /// Back to a saved state.
    fn restore(&mut self, s: &Saved<D>) {
        self.clock.time = s.time;
        self.clock.step = s.step;
        if let (Some(m), Some(saved)) = (self.bodies.mpm.as_mut(), &s.mpm) {
            m.x.clone_from(&s.at.particles);
            m.v.clone_from(&saved.v);
            m.b.clone_from(&saved.b);
            m.f.clone_from(&saved.f);
            m.a.clone_from(&saved.a);
            m.contact_force.clone_from(&saved.contact_force);
        }
        for ((body, x), [v, a, c]) in self.bodies.fem.iter_mut().zip(&s.at.fem).zip(&s.fem) {
            body.x.clone_from(x);
            body.v.clone_from(v);
            body.a.clone_from(a);
            body.contact_force.clone_from(c);
        }
    }

    /// Steps 1–2 of a time step: particle-to-grid, the DOF layout (active grid nodes, then FEM
    /// vertices), prescribed targets, level-set boundary conditions and the predictor.
    pub(crate) fn setup(&mut self, integrator: Integrator) -> Result<StepSetup<D>, SimError> {
        let dt = self.clock.dt;
        let t1 = self.clock.time + dt;
        // 1. Particle-to-grid.
        let clock = std::time::Instant::now();
        let GridState {
            n_grid,
            grid_m,
            grid_v,
            grid_a,
            grid_x,
            grid_f,
        } = self.particles_to_grid(integrator)?;
        let transfers_s = clock.elapsed().as_secs_f64();
        // 2. DOF layout: grid nodes, then FEM vertices body by body.
        let mut fem_offset = Vec::with_capacity(self.bodies.fem.len());
        let mut n_dofs = n_grid * D;
        for b in &self.bodies.fem {
            fem_offset.push(n_dofs);
            n_dofs += b.x.len() * D;
        }
        let mut mass = vec![0.0; n_dofs];
        let mut x0 = vec![0.0; n_dofs];
        let mut v0 = vec![0.0; n_dofs];
        let mut a0 = vec![0.0; n_dofs];
        let mut fixed = vec![false; n_dofs];
        let mut target = vec![0.0; n_dofs];
        let loads = &self.bodies.loads;
        let forced = !loads.particles.is_empty() || loads.fem.iter().any(|f| !f.is_empty());
        let mut force = if forced {
            vec![0.0; n_dofs]
        } else {
            Vec::new()
        };
        let max_m = grid_m.iter().copied().fold(0.0, f64::max);
        for i in 0..n_grid {
            for a in 0..D {
                let d = i * D + a;
                mass[d] = grid_m[i];
                x0[d] = grid_x[i][a];
                v0[d] = grid_v[i][a];
                a0[d] = grid_a[i][a];
                if let Some(f) = grid_f.get(i) {
                    force[d] = f[a];
                }
                // Nodes a particle touches with weight ~0 carry no mass: pin them.
                if grid_m[i] <= 1e-14 * max_m {
                    fixed[d] = true;
                    target[d] = x0[d];
                }
            }
        }
        // One gradient and one per-element force buffer serve every body.
        let mut gradient = Vec::new();
        let mut element_forces = Vec::new();
        for (b, body) in self.bodies.fem.iter().enumerate() {
            gradient.clear();
            gradient.resize(body.x.len(), SVector::<f64, D>::zeros());
            if integrator.needs_acceleration() && !body.fully_prescribed {
                body.elastic
                    .add_gradient_with(&body.x, 1.0, &mut element_forces, &mut gradient)
                    .map_err(|e| SimError::StepFailed {
                        step: self.clock.step,
                        time: self.clock.time,
                        message: format!("FEM body {}: {e}", body.name),
                    })?;
            }
            for vtx in 0..body.x.len() {
                for a in 0..D {
                    let d = fem_offset[b] + vtx * D + a;
                    mass[d] = body.mass[vtx];
                    x0[d] = body.x[vtx][a];
                    v0[d] = body.v[vtx][a];
                    let f = if forced {
                        loads.fem_force(b, vtx)[a]
                    } else {
                        0.0
                    };
                    if forced {
                        force[d] = f;
                    }
                    if integrator.needs_acceleration() && mass[d] > 0.0 {
                        a0[d] = body.a[vtx][a]
                            + self.bodies.gravity[a]
                            + (f - gradient[vtx][a]) / mass[d];
                    }
                }
            }
            for (ids, motion) in &body.prescribed {
                let tf = motion.at(t1);
                for &vtx in ids {
                    let p = tf.apply(&body.initial[vtx]);
                    for a in 0..D {
                        let d = fem_offset[b] + vtx * D + a;
                        fixed[d] = true;
                        target[d] = p[a];
                    }
                }
            }
            // Vertices prescribed from outside: on their straight line at this (sub)step's end.
            for t in loads.targets.get(b).map_or(&[][..], Vec::as_slice) {
                let p = t.at(t1);
                for a in 0..D {
                    let d = fem_offset[b] + t.vertex * D + a;
                    fixed[d] = true;
                    target[d] = p[a];
                }
            }
        }
        // Level-set boundaries on grid nodes (at the end-of-step boundary position).
        let penalties = self.level_set_conditions(&grid_x, &grid_m, &mut fixed, &mut target);
        // Predictor.
        let mut x_hat = vec![0.0; n_dofs];
        integrator.predictor(dt, &x0, &v0, &a0, &mut x_hat);

        Ok(StepSetup {
            n_grid,
            grid_v,
            grid_x,
            fem_offset,
            n_dofs,
            mass,
            x0,
            v0,
            a0,
            fixed,
            target,
            penalties,
            x_hat,
            force,
            transfers_s,
        })
    }

    /// Step 1: the particles' mass, momentum (and, for Newmark, acceleration) on this step's
    /// grid nodes, and the nodes' positions.
    fn particles_to_grid(&mut self, integrator: Integrator) -> Result<GridState<D>, SimError> {
        let mut n_grid = 0;
        let mut grid_m: Vec<f64> = Vec::new();
        let mut grid_v: Vec<SVector<f64, D>> = Vec::new();
        let mut grid_a: Vec<SVector<f64, D>> = Vec::new();
        let mut grid_x: Vec<SVector<f64, D>> = Vec::new();
        let mut grid_f: Vec<SVector<f64, D>> = Vec::new();
        let forces = &self.bodies.loads.particles;
        if let Some(m) = self.bodies.mpm.as_mut() {
            m.stencils.rebuild(&m.x).map_err(|e| SimError::StepFailed {
                step: self.clock.step,
                time: self.clock.time,
                message: e.to_string(),
            })?;
            n_grid = m.stencils.num_nodes();
            grid_m = vec![0.0; n_grid];
            grid_v = vec![SVector::zeros(); n_grid];
            let r = match m.transfer {
                Transfer::Apic => {
                    transfer::p2g_apic(&m.stencils, &m.mass, &m.v, &m.b, &mut grid_m, &mut grid_v)
                }
                _ => transfer::p2g_pic(&m.stencils, &m.mass, &m.v, &mut grid_m, &mut grid_v),
            };
            r.and_then(|_| transfer::normalise(&grid_m, &mut grid_v))
                .map_err(|e| SimError::StepFailed {
                    step: self.clock.step,
                    time: self.clock.time,
                    message: e.to_string(),
                })?;
            if !forces.is_empty() {
                grid_f = vec![SVector::zeros(); n_grid];
                transfer::p2g_vector(&m.stencils, &vec![1.0; forces.len()], forces, &mut grid_f)
                    .map_err(|e| SimError::StepFailed {
                        step: self.clock.step,
                        time: self.clock.time,
                        message: e.to_string(),
                    })?;
            }
            grid_a = vec![SVector::zeros(); n_grid];
            if integrator.needs_acceleration() {
                // Newmark's start-of-step acceleration (grid here, FEM vertices below): the
                // elastic and gravity part evaluated at the start, on this step's grid
                // (`−M⁻¹∇Ψ(xⁿ) + g`), plus what the particles and vertices carry from the last
                // step — the contact, friction and slip-penalty part (contact-stabilised
                // Newmark: the penalties' only), which cannot be evaluated at the start.
                // Carrying the elastic part through the particles and back smooths it, and
                // the trapezoidal rule then no longer balances its work: the MPM bar of the
                // impact comparison gained 1.5 % with contact-stabilised Newmark that way and
                // gains nothing this way. (Carried, it would also keep each step's Newton
                // residual; evaluated, the momentum balance is exact whatever the residual.)
                transfer::p2g_vector(&m.stencils, &m.mass, &m.a, &mut grid_a)
                    .and_then(|_| transfer::normalise(&grid_m, &mut grid_a))
                    .map_err(|e| SimError::StepFailed {
                        step: self.clock.step,
                        time: self.clock.time,
                        message: e.to_string(),
                    })?;
                let mut gradient = Vec::new();
                crate::objective::particles::start_gradient(m, &mut gradient);
                // Nodes with next to no mass are pinned (below): no division by it.
                let tiny = 1e-14 * grid_m.iter().copied().fold(0.0, f64::max);
                for (i, ((a, f), &mi)) in grid_a.iter_mut().zip(&gradient).zip(&grid_m).enumerate()
                {
                    *a += self.bodies.gravity;
                    if mi > tiny {
                        *a -= f / mi;
                        if let Some(fe) = grid_f.get(i) {
                            *a += fe / mi;
                        }
                    }
                }
            }
            grid_x = (0..n_grid).map(|i| m.stencils.node_position(i)).collect();
        }

        Ok(GridState {
            n_grid,
            grid_m,
            grid_v,
            grid_a,
            grid_x,
            grid_f,
        })
    }

    /// The level-set boundaries' conditions on the grid nodes at the end-of-step boundary
    /// position: no-slip and axis-aligned slip nodes prescribed in `fixed`/`target`, oblique
    /// slip as penalties (returned).
    fn level_set_conditions(
        &self,
        grid_x: &[SVector<f64, D>],
        grid_m: &[f64],
        fixed: &mut [bool],
        target: &mut [f64],
    ) -> Vec<Penalty<D>> {
        let dt = self.clock.dt;
        let t1 = self.clock.time + dt;
        let n_grid = grid_x.len();
        let mut penalties: Vec<Penalty<D>> = Vec::new();
        for ls in &self.bodies.boundaries {
            let vb = ls.velocity(t1 - 0.5 * dt);
            for i in 0..n_grid {
                let (phi, n) = ls.eval(&grid_x[i], t1);
                if phi > 0.0 || fixed[i * D] && fixed[i * D + D - 1] {
                    continue;
                }
                match ls.condition {
                    BoundaryCondition::NoSlip => {
                        for a in 0..D {
                            fixed[i * D + a] = true;
                            target[i * D + a] = grid_x[i][a] + dt * vb[a];
                        }
                    }
                    BoundaryCondition::Slip => {
                        let axis = (0..D).find(|&a| (n[a].abs() - 1.0).abs() < 1e-12);
                        match axis {
                            Some(a) => {
                                fixed[i * D + a] = true;
                                target[i * D + a] = grid_x[i][a] + dt * vb[a];
                            }
                            None => penalties.push(Penalty {
                                node: i,
                                n,
                                target: n.dot(&(grid_x[i] + vb * dt)),
                                k: 1e4 * grid_m[i].max(1e-300),
                            }),
                        }
                    }
                }
            }
        }
        penalties
    }
}

/// The lagged-friction loop around the minimisation (Algorithm 1) from `x`, friction lagged
/// at the step's start `x0` first; the failing solve's error and friction iteration if one
/// fails.
///
/// The fixed point is reached when a solve's solution is where its friction operator was
/// evaluated (to the Newton tolerance, in velocity units), or when neither the operator
/// solved with nor the one at the solution has a friction term (then both are the same
/// objective) — in both cases by a solve to the full tolerance. `policy.max_solves` bounds
/// the solves. With `policy.update_below > 0` the Newton iterations re-evaluate the operator
/// at their iterate once an increment is below it (m/s), so most friction iterations cost one
/// Newton iteration rather than a solve (at most half a solve's iterations update it). With
/// `policy.forcing = η > 0` a solve whose operator is still moving is inexact: it stops at
/// `max(tolerance, η × c)`, `c` the last change of the operator's point (m/s; before the first
/// solve, from the step's start to Newton's start) — the tail of quadratic convergence is
/// spent only on the last operator. A loose solve whose last increment fell below the full
/// tolerance anyway counts as a full one (no solve again just to confirm it).
pub(crate) fn friction_loop<const D: usize>(
    newton: &mut femp_solver::Newton,
    obj: &mut StepObjective<'_, D>,
    x: &mut [f64],
    x0: &[f64],
    (fixed, target): (&[bool], &[f64]),
    params: &NewtonParams,
    policy: FrictionPolicy,
    report: &mut StepReport,
) -> Result<(), (femp_solver::SolveError, usize)> {
    obj.lag = Default::default();
    // The change of the operator's point the next solve's tolerance follows (m/s).
    let mut moving = 0.0;
    if policy.any {
        // Algorithm 1 lags the friction operator at the start of the step.
        obj.lag_friction(x0);
        obj.lag.below = policy.update_below;
        if policy.forcing > 0.0 {
            moving = obj.lag_distance(x) / params.dt;
        }
    }
    obj.prefer_exact = params.hessian == HessianStrategy::ExactWhenDefinite;
    let mut solves = 0;
    // Aitken extrapolation: the change after the last solve lagged at a solve's own point.
    let mut plain_change: Option<f64> = None;
    let mut lag_point = Vec::new();
    // Relaxation: the change after the previous solve, and whether the loop has stopped
    // contracting (then every later operator is lagged half way).
    let mut last_change: Option<f64> = None;
    let mut relaxing = false;
    let mut aitken = AitkenRelaxation::default();
    let mut anderson = AndersonMixing::new(policy.anderson);
    loop {
        // Half a solve's iterations at most update the operator: the rest converge on it.
        obj.lag.limit = obj.lag.count + params.max_iterations / 2;
        solves += 1;
        if solves > 1 && policy.update_later {
            obj.lag.begin_later_solve();
        }
        let tolerance = params.tolerance.max(policy.forcing * moving);
        let solve_params = NewtonParams {
            tolerance,
            ..*params
        };
        if solves > 1 {
            // The same unknowns as the last solve: its factor may precondition this one's
            // first iteration (large 3D factors, `solver.linear: "auto"`).
            newton.keep_last_factor();
        }
        let stats = newton
            .minimize_to(obj, x, fixed, target, &solve_params)
            .map_err(|e| (e, obj.lag.count.max(1) - 1))?;
        report.friction_iterations = obj.lag.count.max(1);
        report.newton_iterations += stats.iterations;
        report.stats += &stats;
        // A solve asked for a looser tolerance whose last increment is below the full one
        // (quadratic convergence overshoots) is as converged as one asked for it.
        let exact = tolerance <= params.tolerance || stats.final_residual < params.tolerance;
        if !policy.any {
            break;
        }
        // With Aitken's or Anderson's mixing the residual it needs gives the change too (one unpacking
        // of `x`): its largest coordinate is `lag_distance`.
        let residual = if policy.anderson > 0 {
            Some(&mut anderson.current)
        } else if policy.aitken {
            Some(&mut aitken.current)
        } else {
            None
        };
        let change = match residual {
            Some(r) => {
                obj.lag_residual(x, r);
                r.iter().fold(0.0, |m: f64, d| m.max(d.abs()))
            }
            None => obj.lag_distance(x),
        } / params.dt;
        if change < params.tolerance && exact {
            break;
        }
        if solves >= policy.max_solves {
            // The last solve's friction operator stays (the forces reported with the step
            // are those of the state it solved for).
            report.friction_converged = false;
            break;
        }
        let before = obj.lag.terms;
        relaxing |= policy
            .relax
            .is_some_and(|ratio| last_change.is_some_and(|p| change >= ratio * p));
        last_change = Some(change);
        let previous = plain_change.filter(|_| policy.extrapolate && !relaxing);
        if policy.anderson > 0 {
            if anderson.next_point(x, &mut lag_point) && lag_at(obj, x, &mut lag_point) {
                report.relaxed_lags += 1;
            } else {
                anderson.restart();
                obj.lag_friction(x);
            }
        } else if policy.aitken {
            let omega = aitken.next_factor();
            let relaxed = omega < 1.0 && lag_along(obj, x, omega - 1.0, &mut lag_point);
            if relaxed {
                report.relaxed_lags += 1;
            } else {
                obj.lag_friction(x);
            }
            aitken.used(if relaxed { omega } else { 1.0 });
        } else if relaxing && relaxed_lag(obj, x, &mut lag_point) {
            report.relaxed_lags += 1;
            plain_change = None;
        } else if extrapolated_lag(obj, x, previous, change, &mut lag_point) {
            report.extrapolated_lags += 1;
            plain_change = None;
        } else {
            obj.lag_friction(x);
            plain_change = Some(change);
        }
        // A solve to the full tolerance follows once the operator has stopped moving.
        moving = if change < params.tolerance {
            0.0
        } else {
            change
        };
        if before == 0 && obj.lag.terms == 0 {
            if exact {
                break;
            }
            moving = 0.0;
        }
    }
    Ok(())
}

/// Lag the friction operator at the Aitken extrapolation of the friction loop's iterates, if
/// it applies: the last two changes `previous` and `change` of the operator's point shrank by a
/// steady ratio `r = change / previous < 0.9`, and the straight path from `x` to
/// `y = x + r/(1 − r) (x − the operator's point)` is feasible ([`lag_along`]). For a
/// linearly converging fixed-point iteration `y` is its limit to first order.
fn extrapolated_lag<const D: usize>(
    obj: &mut StepObjective<'_, D>,
    x: &[f64],
    previous: Option<f64>,
    change: f64,
    lag_point: &mut Vec<f64>,
) -> bool {
    let Some(previous) = previous else {
        return false;
    };
    let r = change / previous;
    if !(r > 0.0 && r < 0.9) {
        return false;
    }
    lag_along(obj, x, r / (1.0 - r), lag_point)
}

/// Lag the friction operator half way from its last point to the solve's `x` (the averaged
/// fixed-point iteration: the same fixed points, and it may converge where the plain one
/// cycles), if the straight path from `x` there is feasible.
fn relaxed_lag<const D: usize>(
    obj: &mut StepObjective<'_, D>,
    x: &[f64],
    lag_point: &mut Vec<f64>,
) -> bool {
    lag_along(obj, x, -0.5, lag_point)
}

/// Lag the friction operator at `y = x + factor (x − the operator's last point)` if the
/// straight path from `x` to `y` is feasible (`lag_point` reused across the loop's solves:
/// first the step `y − x`, then `y`).
fn lag_along<const D: usize>(
    obj: &mut StepObjective<'_, D>,
    x: &[f64],
    factor: f64,
    lag_point: &mut Vec<f64>,
) -> bool {
    lag_point.clear();
    lag_point.extend(
        x.iter()
            .zip(&obj.lag.at)
            .map(|(now, at)| factor * (now - at)),
    );
    lag_by(obj, x, lag_point)
}

/// Lag the friction operator at `y` (in `lag_point`) if the straight path from `x` to it is
/// feasible ([`lag_by`]).
fn lag_at<const D: usize>(
    obj: &mut StepObjective<'_, D>,
    x: &[f64],
    lag_point: &mut [f64],
) -> bool {
    for (y, a) in lag_point.iter_mut().zip(x) {
        *y -= a;
    }
    lag_by(obj, x, lag_point)
}

/// With the step `s` in `lag_point`: lag the friction operator at `x + s` (into `lag_point`)
/// if the straight path there is feasible (no crossing, no inversion), else `false`.
fn lag_by<const D: usize>(
    obj: &mut StepObjective<'_, D>,
    x: &[f64],
    lag_point: &mut [f64],
) -> bool {
    let bound = femp_solver::Objective::max_step(obj, x, lag_point);
    if bound.limit.is_some() || bound.alpha < 1.0 {
        return false;
    }
    for (y, a) in lag_point.iter_mut().zip(x) {
        *y += a;
    }
    obj.lag_friction(lag_point);
    true
}

/// How a step's lagged-friction loop runs ([`friction_loop`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct FrictionPolicy {
    /// Whether any pair has friction (without, one solve).
    pub(crate) any: bool,
    /// The most solves (`solver.max_friction_iterations`).
    pub(crate) max_solves: usize,
    /// `solver.friction_update_below` (m/s).
    pub(crate) update_below: f64,
    /// `solver.friction_update_later`: the solves after the first update the operator at
    /// their Newton iterates while that contracts.
    pub(crate) update_later: bool,
    /// `solver.friction_forcing`.
    pub(crate) forcing: f64,
    /// `solver.friction_extrapolation`.
    pub(crate) extrapolate: bool,
    /// `solver.friction_relaxation`: relax once a solve's change is at least this times the
    /// previous solve's (1 from the scene: once the loop stops contracting).
    pub(crate) relax: Option<f64>,
    /// `solver.friction_aitken`: Aitken's dynamic relaxation of every lag after the first.
    pub(crate) aitken: bool,
    /// `solver.friction_anderson`: Anderson acceleration with this many past iterates (0:
    /// off; on, it chooses the lags instead of Aitken).
    pub(crate) anderson: usize,
}

/// Anderson acceleration of a fixed-point iteration `at ↦ g(at)` (Anderson 1965; Walker & Ni
/// 2011, "type II", mixing β = 1), for the friction loop: `at` the point the operator was
/// lagged at, `g` the solve's solution, `f = P(g − at)` the residual on the points the operator
/// depends on (`P` linear: particles and vertices are linear in the unknowns). With the
/// differences `ΔG`, `ΔF` of the last `m` pairs, the next lag is at `g − ΔG γ`, `γ` the least-
/// squares minimiser of `‖f − ΔF γ‖₂` — for a linear map, where the residual vanishes on the
/// span of the last `m` steps. A mixed lag whose residual is larger than the one before it
/// empties the history (the next lag plain).
#[derive(Debug)]
pub(crate) struct AndersonMixing {
    depth: usize,
    /// The last solve's solution and residual.
    last_g: Vec<f64>,
    last_f: Vec<f64>,
    have_last: bool,
    /// Whether the last lag was mixed (not plain).
    mixed: bool,
    /// The last `depth` differences of solutions (unknowns) and residuals (points), oldest
    /// first.
    dg: std::collections::VecDeque<Vec<f64>>,
    df: std::collections::VecDeque<Vec<f64>>,
    /// The current residual, filled by the caller before [`Self::next_point`].
    pub(crate) current: Vec<f64>,
}

impl AndersonMixing {
    pub(crate) fn new(depth: usize) -> Self {
        Self {
            depth,
            last_g: Vec::new(),
            last_f: Vec::new(),
            have_last: false,
            mixed: false,
            dg: Default::default(),
            df: Default::default(),
            current: Vec::new(),
        }
    }

    /// Forget the differences (the next lag plain, the one after mixes again).
    pub(crate) fn restart(&mut self) {
        self.dg.clear();
        self.df.clear();
        self.mixed = false;
    }

    /// With `current` the residual of the solve that ended at `g`: the next lag point into
    /// `out` and `true`, or `false` where there is no history to mix (the lag is then `g`).
    pub(crate) fn next_point(&mut self, g: &[f64], out: &mut Vec<f64>) -> bool {
        if self.depth == 0 {
            return false;
        }
        let norm = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>();
        if self.have_last {
            if self.mixed && norm(&self.current) >= norm(&self.last_f) {
                // The mixed lag did worse than the plain one before it would have had to.
                self.restart();
            } else {
                let mut dg = if self.dg.len() == self.depth {
                    self.df.pop_front();
                    self.dg.pop_front().expect("a full history")
                } else {
                    Vec::new()
                };
                dg.clear();
                dg.extend(g.iter().zip(&self.last_g).map(|(a, b)| a - b));
                let df = self
                    .current
                    .iter()
                    .zip(&self.last_f)
                    .map(|(a, b)| a - b)
                    .collect();
                self.dg.push_back(dg);
                self.df.push_back(df);
            }
        }
        self.last_g.clear();
        self.last_g.extend_from_slice(g);
        self.last_f.clone_from(&self.current);
        self.have_last = true;
        let m = self.df.len();
        self.mixed = m > 0;
        if m == 0 {
            return false;
        }
        // The normal equations, solved through the SVD with small singular values cut (nearly
        // dependent columns).
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let gram = nalgebra::DMatrix::from_fn(m, m, |i, j| dot(&self.df[i], &self.df[j]));
        let rhs = nalgebra::DVector::from_fn(m, |i, _| dot(&self.df[i], &self.current));
        let svd = gram.svd(true, true);
        let cut = 1e-12 * svd.singular_values.max();
        let Ok(gamma) = svd.solve(&rhs, cut) else {
            self.restart();
            return false;
        };
        if !gamma.iter().all(|v| v.is_finite()) {
            self.restart();
            return false;
        }
        out.clear();
        out.extend_from_slice(g);
        for (j, dg) in self.dg.iter().enumerate() {
            for (o, d) in out.iter_mut().zip(dg) {
                *o -= gamma[j] * d;
            }
        }
        true
    }
}

/// Aitken's dynamic relaxation of a fixed-point iteration (Irons & Tuck 1969; as Küttler & Wall
/// 2008 use it for partitioned fluid–structure loops): with `d_k` the residual of iterate `k`
/// (the solve's points minus where its operator was evaluated) and `ω_{k−1}` the factor the
/// last lag used, the next lag is at `lag + ω_k d_k`, `ω_k = −ω_{k−1} d_{k−1}·(d_k − d_{k−1}) /
/// ‖d_k − d_{k−1}‖²`. For a residual that flips sign (a loop that oscillates, `d_k ≈ −ρ
/// d_{k−1}`) that is `ω_{k−1}/(1 + ρ)`; for one that shrinks steadily (`d_k ≈ r d_{k−1}`)
/// `ω_{k−1}/(1 − r)`. Clamped to `[OMEGA_MIN, 1]`: it damps, it never extrapolates (that is
/// `friction_extrapolation`'s, which the twist's switching contacts did not reward).
#[derive(Debug)]
pub(crate) struct AitkenRelaxation {
    /// The factor the last lag used (1 for a plain lag).
    omega: f64,
    /// The last residual and the current one (point coordinates).
    previous: Vec<f64>,
    pub(crate) current: Vec<f64>,
    /// Whether `previous` holds a residual.
    have_previous: bool,
}

impl Default for AitkenRelaxation {
    /// A loop's start: no residual yet, the first lag plain.
    fn default() -> Self {
        Self {
            omega: 1.0,
            previous: Vec::new(),
            current: Vec::new(),
            have_previous: false,
        }
    }
}

impl AitkenRelaxation {
    /// The smallest factor.
    pub(crate) const OMEGA_MIN: f64 = 1.0 / 16.0;

    /// The factor for the next lag from the residual just measured into `current`, remembering
    /// it as `previous`. The first residual of a loop gives 1.
    pub(crate) fn next_factor(&mut self) -> f64 {
        let omega = if self.have_previous {
            let (mut num, mut den) = (0.0, 0.0);
            for (p, c) in self.previous.iter().zip(&self.current) {
                let delta = c - p;
                num += p * delta;
                den += delta * delta;
            }
            if den > 0.0 && den.is_finite() && num.is_finite() {
                (-self.omega * num / den).clamp(Self::OMEGA_MIN, 1.0)
            } else {
                1.0
            }
        } else {
            1.0
        };
        std::mem::swap(&mut self.previous, &mut self.current);
        self.have_previous = true;
        omega
    }

    /// The factor the lag actually used (1 where the relaxed point was not feasible).
    pub(crate) fn used(&mut self, omega: f64) {
        self.omega = omega;
    }
}

/// Start `x` at the predictor `x_hat` (targets for prescribed DOFs) when the straight path
/// from `x0` to it is feasible (no crossing, no inversion) and its energy finite (`true`); at
/// `x0` otherwise (`false`).
pub(crate) fn start_at_predictor<const D: usize>(
    obj: &mut StepObjective<'_, D>,
    x0: &[f64],
    fixed: &[bool],
    target: &[f64],
    x_hat: &[f64],
    x: &mut [f64],
) -> bool {
    x.copy_from_slice(x0);
    let n = x0.len();
    let mut dir = vec![0.0; n];
    for d in 0..n {
        dir[d] = if fixed[d] { target[d] } else { x_hat[d] } - x0[d];
    }
    let bound = femp_solver::Objective::max_step(obj, x0, &dir);
    if bound.limit.is_none() && bound.alpha >= 1.0 {
        for d in 0..n {
            x[d] = if fixed[d] { target[d] } else { x0[d] + dir[d] };
        }
        if femp_solver::Objective::energy(obj, x).is_finite() {
            return true;
        }
        x.copy_from_slice(x0);
    }
    false
}

impl<const D: usize> StepSetup<D> {
    /// What unknown `dof` is: a grid node's or a FEM vertex's component, with its mass.
    pub(crate) fn unknown(&self, dof: usize) -> Unknown {
        let (node_or_vertex, axis) = (dof / D, dof % D);
        let mass = self.mass.get(dof).copied().unwrap_or(f64::NAN);
        match self.fem_offset.iter().rposition(|&o| o <= dof) {
            Some(body) if dof >= self.n_grid * D => Unknown::FemVertex {
                body,
                vertex: (dof - self.fem_offset[body]) / D,
                axis,
                mass,
            },
            _ => Unknown::GridNode {
                node: node_or_vertex,
                axis,
                mass,
            },
        }
    }

    /// The unknowns' layout.
    pub(crate) fn dofs(&self) -> Dofs {
        Dofs {
            n_grid: self.n_grid,
            fem_offset: self.fem_offset.clone(),
            n: self.n_dofs,
        }
    }

    /// The incremental potential of this step (of length `dt`) over `bodies`, with the
    /// integrator's weight `w` (as the step builds it).
    pub(crate) fn objective<'a>(
        &'a self,
        bodies: &'a Bodies<D>,
        dt: f64,
        w: f64,
    ) -> StepObjective<'a, D> {
        StepObjective::new(
            bodies,
            dt,
            self.dofs(),
            Inertia {
                mass: &self.mass,
                x_hat: &self.x_hat,
                gravity: bodies.gravity,
                force: &self.force,
                penalties: &self.penalties,
            },
            &self.x0,
            w,
        )
    }
}
