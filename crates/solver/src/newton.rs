//! Projected Newton with a feasibility-filtered backtracking line search (BFEMP Algorithm 2).
//!
//! Each iteration: `begin_iteration` (the objective updates its active sets), gradient `g`,
//! PSD Hessian `H` (triplets → CSC, symbolic factorisation reused while the pattern holds),
//! `p = −H⁻¹g` on the free DOFs (`p = 0` on fixed ones), the largest feasible step `α_max`
//! from the objective (CCD, det F), then `α = min(1, 0.9 α_max)` halved until
//! `E(x + αp) ≤ E(x) + c α gᵀp` (Armijo, `c = 1e-4` by default; non-finite energies count as
//! failures). The solve stops when `‖p‖_∞ / Δt < ε_d` (BFEMP §5: the Newton increment in
//! velocity units).
//!
//! Two optional economies for the last iterations, both off by default
//! ([`NewtonParams::reuse_hessian_below`], [`Forcing::Adaptive`]): once a full step's increment
//! is small, the next iteration may solve with the previous iteration's matrix (no assembly, no
//! factorisation — a Shamanskii step); and with conjugate gradients, each direction is solved
//! only as accurately as Newton's convergence so far can use (Eisenstat–Walker forcing).
//!
//! Failures are errors carrying the statistics so far: a line search that cannot decrease the
//! energy with `α` above a floor, the iteration limit, a non-finite energy or gradient, an
//! unfactorisable Hessian.
//!
//! In the code, a solve is a [`Newton`] (buffers and the factorisation, kept across solves) and
//! a `SolveState` (energy, statistics and one policy per strategy: `ExactPolicy` for
//! [`HessianStrategy::ExactWhenDefinite`], `CgPolicy` for [`LinearSolver::Pcg`] and its forcing,
//! `HessianReuse` for [`NewtonParams::reuse_hessian_below`], `Stagnation` for round-off stops).
//! An iteration runs `matrix_and_gradient`, `solve_with_cg` or `solve_with_cholesky`,
//! `direction`, the stationarity tests and `line_search`, in that order; every phase that can
//! end the solve returns a `Failure`, to which `SolveState::finish` attaches the statistics.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering as AtomicOrdering};
use std::time::Instant;

use crate::linear::{Cholesky, LinearError, Ordering, Threads};
use crate::pcg::Pcg;
use crate::{SolveError, Triplets, UpperCsc};

/// What limited a step: the objective's answer to "how far can we go along `p`".
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StepLimit {
    /// Continuous collision detection.
    Ccd,
    /// An element or particle would invert (det F).
    DetF,
    /// Something else the objective knows about.
    Other,
}

/// The largest feasible step along a direction: every `x + s p` with `0 ≤ s < alpha` is
/// feasible. `limit` is `None` when nothing limits the step within `alpha = 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepBound {
    /// Largest feasible fraction of the step, in (0, 1].
    pub alpha: f64,
    /// What limited it.
    pub limit: Option<StepLimit>,
}

impl StepBound {
    /// No limit.
    pub const UNLIMITED: StepBound = StepBound {
        alpha: 1.0,
        limit: None,
    };
}

/// An objective a physical model implements. `x` has one entry per DOF (fixed ones included).
pub trait Objective {
    /// Number of DOFs.
    fn num_dofs(&self) -> usize;
    /// Called at the start of every Newton iteration with the current iterate (e.g. to update
    /// broad-phase candidates for the step ahead). Default: nothing.
    fn begin_iteration(&mut self, _x: &[f64]) {}
    /// `E(x)`; `+∞` or NaN for infeasible points (they make the line search backtrack).
    fn energy(&mut self, x: &[f64]) -> f64;
    /// `∇E(x)` into `g` (overwrite). In a Newton iteration it is usually called after the
    /// Hessian at the same `x` (the solver factorises the Hessian on another thread meanwhile);
    /// when the last Hessian may be reused it comes first, followed by
    /// [`Objective::hessian_terms_unchanged`]. An objective must not depend on the order.
    fn gradient(&mut self, x: &[f64], g: &mut [f64]);
    /// A positive semi-definite approximation of `∇²E(x)` as triplets, appended to `h` (cleared
    /// by the caller). Only the upper triangle counts (row ≤ column; duplicates summed):
    /// entries below the diagonal are ignored, so an objective may push both triangles — what
    /// per-element block assembly produces naturally — or only the upper one.
    fn hessian(&mut self, x: &[f64], h: &mut Triplets);
    /// The exact Hessian `∇²E(x)` (no PSD projection, possibly indefinite), in the same form
    /// and with the same sparsity pattern as [`Objective::hessian`]; `false` if the objective
    /// cannot give it (the default). Used by [`HessianStrategy::ExactWhenDefinite`].
    fn exact_hessian(&mut self, _x: &[f64], _h: &mut Triplets) -> bool {
        false
    }
    /// Whether the Hessian's terms (e.g. the active contact pairs) at the point of the last
    /// [`Objective::gradient`] call are those of the last [`Objective::hessian`] or
    /// [`Objective::exact_hessian`] call — the condition under which the solver may reuse that
    /// Hessian ([`NewtonParams::reuse_hessian_below`]). Default `false`: never reused.
    fn hessian_terms_unchanged(&mut self) -> bool {
        false
    }
    /// The largest feasible step along `p` (CCD, inversion); default: unlimited.
    fn max_step(&mut self, _x: &[f64], _p: &[f64]) -> StepBound {
        StepBound::UNLIMITED
    }
}

/// Which Hessian a Newton iteration factorises.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HessianStrategy {
    /// Always the objective's PSD approximation ([`Objective::hessian`]): projected Newton.
    /// Robust, but the curvature the projection adds (clipped negative eigenvalues of element,
    /// particle and contact terms) makes Newton converge linearly wherever it is active.
    #[default]
    Projected,
    /// The exact Hessian ([`Objective::exact_hessian`]) whenever the *assembled* matrix is
    /// positive definite — per-term indefiniteness is often outweighed by the mass term — so
    /// Newton converges quadratically there. An iteration first tries to factorise the exact
    /// Hessian without diagonal shifts; if that fails, it uses the projected one. After `k`
    /// rejections in a row the next `2^(k−1) − 1` iterations do not try (a failed try costs
    /// one assembly and one factorisation). A positive-definite Hessian gives a descent
    /// direction, so the line search (Armijo, feasibility bound) is unchanged.
    ExactWhenDefinite,
}

/// How an iteration solves `H p = −g` for its direction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum LinearSolver {
    /// Sparse Cholesky (faer) of every Hessian, the symbolic analysis reused while the pattern
    /// holds. Exact directions; the cost grows with the factor's fill.
    #[default]
    Cholesky,
    /// Jacobi-preconditioned conjugate gradients ([`crate::Pcg`]) on the assembled Hessian,
    /// from `p = 0`, until the preconditioned residual has fallen by `rtol`, at most
    /// `max_iterations` products. No factorisation and no symbolic analysis: for
    /// well-conditioned (mass-dominated) Hessians at small time steps. With
    /// [`HessianStrategy::ExactWhenDefinite`] an exact Hessian along which CG meets
    /// non-positive curvature, or on which it does not converge, is rejected like one whose
    /// factorisation fails; a projected Hessian on which CG does not converge is factorised
    /// (Cholesky), so every direction is as good as the direct solver's up to `rtol`.
    Pcg {
        /// Relative reduction of the preconditioned residual `√(rᵀD⁻¹r)`.
        rtol: f64,
        /// Matrix products before falling back to Cholesky.
        max_iterations: usize,
        /// How `rtol` is chosen per iteration.
        forcing: Forcing,
    },
}

/// How accurately conjugate gradients solve each Newton direction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Forcing {
    /// Every direction to [`LinearSolver::Pcg`]'s `rtol`.
    #[default]
    Fixed,
    /// Eisenstat–Walker (1996, choice 2, γ = 0.9, α = 2): iteration `k` asks for
    /// `η_k = 0.9 (‖g_k‖/‖g_{k−1}‖)²` (safeguarded by `0.9 η_{k−1}²` while that exceeds 0.1),
    /// clamped to `[rtol, max]`; the first iteration of a solve asks for `max`. Inexact Newton
    /// keeps its local superlinear convergence with these terms while early directions — far
    /// from the minimiser, where a precise solve buys nothing — cost fewer products.
    Adaptive {
        /// Largest relative reduction asked for (e.g. 1e-2).
        max: f64,
    },
}

/// Parameters of a solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonParams {
    /// Convergence tolerance ε_d on `‖p‖_∞ / dt` (m/s with `dt` the time step).
    pub tolerance: f64,
    /// The time step that scales `p` into a velocity (1 for a plain minimisation).
    pub dt: f64,
    /// Iteration limit.
    pub max_iterations: usize,
    /// Armijo constant `c` in `E(x + αp) ≤ E(x) + c α gᵀp`.
    pub armijo: f64,
    /// Fraction of the largest feasible step the line search starts from (0.9 in the paper).
    pub feasible_fraction: f64,
    /// The line search gives up when `α‖p‖_∞` falls below this (absolute, DOF units).
    pub min_step: f64,
    /// Fill-reducing ordering.
    pub ordering: Ordering,
    /// Threading of the factorisation.
    pub threads: Threads,
    /// Which Hessian the iterations factorise.
    pub hessian: HessianStrategy,
    /// How the Newton direction is solved for.
    pub linear: LinearSolver,
    /// Reuse the previous iteration's Hessian (its CSC matrix for CG, its factorisation for
    /// Cholesky) when that iteration took the full step, its increment `‖p‖_∞/dt` was below this
    /// (velocity units, like `tolerance`), no prescribed DOF is still on its way and the
    /// objective reports the same Hessian terms ([`Objective::hessian_terms_unchanged`]); the
    /// gradient is always new. Near the minimiser the reused matrix differs from the current
    /// Hessian by `O(‖Δx‖)`, so the direction (and the convergence test on it) is Newton's to
    /// that relative order. `0` (the default): every iteration assembles its own.
    pub reuse_hessian_below: f64,
}

impl Default for NewtonParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-6,
            dt: 1.0,
            max_iterations: 200,
            armijo: 1e-4,
            feasible_fraction: 0.9,
            min_step: 1e-14,
            ordering: Ordering::Auto,
            threads: Threads::Auto,
            hessian: HessianStrategy::Projected,
            linear: LinearSolver::Cholesky,
            reuse_hessian_below: 0.0,
        }
    }
}

/// Relative round-off of an energy evaluation: a predicted decrease `−gᵀp` below
/// `ROUNDOFF·|E|` (about five ulps) cannot be resolved by a line search.
pub const ROUNDOFF: f64 = 1e-15;

/// How far above the current energy, in units of the predicted decrease `−gᵀp`, a full
/// Newton step's energy may come out and still be taken when the gradient confirms it.
const GRADIENT_STEP_RISE: f64 = 10.0;

/// Consecutive round-off-flat iterations without ‖p‖ halving that end a solve as stationary.
const STAGNATION_ITERATIONS: usize = 4;

/// Statistics of one solve.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SolveStats {
    /// Newton iterations (factorisations of distinct Hessians).
    pub iterations: usize,
    /// Line-search halvings, in total.
    pub backtracks: usize,
    /// Iterations whose first trial step was limited by each kind of bound.
    pub limited_by_ccd: usize,
    /// … by det F.
    pub limited_by_det_f: usize,
    /// … by something else.
    pub limited_by_other: usize,
    /// `‖p‖_∞ / dt` of the last iteration.
    pub final_residual: f64,
    /// Energy at the returned point.
    pub final_energy: f64,
    /// Diagonal shifts applied to make a Hessian factorisable.
    pub regularizations: usize,
    /// Iterations that used the exact Hessian ([`HessianStrategy::ExactWhenDefinite`]).
    pub exact_iterations: usize,
    /// Iterations that reused the previous iteration's Hessian
    /// ([`NewtonParams::reuse_hessian_below`]); they assembled no Hessian.
    pub reused_hessians: usize,
    /// Exact Hessians found indefinite (those iterations used the projected one).
    pub exact_rejections: usize,
    /// Solves ended as stationary to working precision before `‖p‖_∞/Δt` reached the
    /// tolerance: the predicted decrease `−gᵀp` stayed below `ROUNDOFF·|E|` while ‖p‖ stopped
    /// shrinking, or no step decreased the energy and `−gᵀp ≤ 10⁴·ROUNDOFF·|E|`.
    pub roundoff_stops: usize,
    /// Full Newton steps taken on the gradient's word: no step length decreased the energy,
    /// but the full step was feasible, raised the energy by at most 10× (`GRADIENT_STEP_RISE`)
    /// the predicted decrease `−gᵀp` and at least halved the free gradient — the energy's
    /// evaluation cannot resolve so small a change (its summands are far larger than their
    /// sum), the gradient can.
    pub gradient_steps: usize,
    /// Symbolic analyses (sparsity pattern changes).
    pub symbolic_analyses: usize,
    /// Conjugate-gradient iterations (matrix products), with [`LinearSolver::Pcg`].
    pub pcg_iterations: usize,
    /// Directions that CG did not deliver on a projected Hessian and Cholesky did.
    pub pcg_fallbacks: usize,
    /// Loosely solved directions ([`Forcing::Adaptive`]) solved again to `rtol` because they
    /// passed the convergence test.
    pub pcg_tightened: usize,
    /// Seconds in conjugate gradients.
    pub pcg_s: f64,
    /// Seconds assembling gradient and Hessian (objective calls and CSC build). Work, not wall
    /// time: the gradient is computed while another thread builds the CSC and factorises.
    pub assembly_s: f64,
    /// Seconds in ordering and symbolic factorisation.
    pub symbolic_s: f64,
    /// Seconds in numeric factorisation.
    pub numeric_s: f64,
    /// Seconds in triangular solves.
    pub solve_s: f64,
    /// Seconds in the line search (feasible-step bound and energy evaluations).
    pub line_search_s: f64,
}

/// Statistics of consecutive solves (the friction loop's re-solves within a step, a run's
/// steps): counters and times add up; `final_residual` and `final_energy` are the last solve's.
impl std::ops::AddAssign<&SolveStats> for SolveStats {
    fn add_assign(&mut self, s: &SolveStats) {
        self.iterations += s.iterations;
        self.backtracks += s.backtracks;
        self.limited_by_ccd += s.limited_by_ccd;
        self.limited_by_det_f += s.limited_by_det_f;
        self.limited_by_other += s.limited_by_other;
        self.final_residual = s.final_residual;
        self.final_energy = s.final_energy;
        self.regularizations += s.regularizations;
        self.roundoff_stops += s.roundoff_stops;
        self.gradient_steps += s.gradient_steps;
        self.exact_iterations += s.exact_iterations;
        self.reused_hessians += s.reused_hessians;
        self.exact_rejections += s.exact_rejections;
        self.symbolic_analyses += s.symbolic_analyses;
        self.pcg_iterations += s.pcg_iterations;
        self.pcg_fallbacks += s.pcg_fallbacks;
        self.pcg_tightened += s.pcg_tightened;
        self.pcg_s += s.pcg_s;
        self.assembly_s += s.assembly_s;
        self.symbolic_s += s.symbolic_s;
        self.numeric_s += s.numeric_s;
        self.solve_s += s.solve_s;
        self.line_search_s += s.line_search_s;
    }
}

/// A projected-Newton solver. Keep it across solves: the symbolic factorisation and all
/// buffers are reused while the Hessian's pattern is unchanged.
pub struct Newton {
    lin: Linear,
    triplets: Triplets,
    ordering: Ordering,
    threads: Threads,
    free: Vec<u32>,
    free_dofs: Vec<usize>,
    g: Vec<f64>,
    p: Vec<f64>,
    rhs: Vec<f64>,
    trial: Vec<f64>,
    /// The gradient at `trial`, for a step taken on the gradient's word.
    g_trial: Vec<f64>,
    pcg: Pcg,
    sol: Vec<f64>,
    /// Set from elsewhere to stop the solve before its next iteration.
    interrupt: Option<Arc<AtomicBool>>,
}

/// The Hessian's sparse matrix and its factorisation: what a Newton iteration can hand to
/// another thread while it computes the gradient.
struct Linear {
    chol: Cholesky,
    csc: UpperCsc,
    // The pattern the factorisation was analysed for, and whether that analysis was made in
    // the current solve (whose unknowns keep their meaning, so patterns may be merged).
    analysed_col_ptr: Vec<usize>,
    analysed_row_idx: Vec<usize>,
    analysed_in_solve: bool,
    /// Seconds building the CSC matrix (counted as assembly).
    csc_s: f64,
}

impl Default for Newton {
    fn default() -> Self {
        Self::new()
    }
}

impl Newton {
    /// A solver with empty buffers.
    pub fn new() -> Self {
        Self {
            lin: Linear {
                chol: Cholesky::new(Ordering::Auto, Threads::Auto),
                csc: UpperCsc::default(),
                analysed_col_ptr: Vec::new(),
                analysed_row_idx: Vec::new(),
                analysed_in_solve: false,
                csc_s: 0.0,
            },
            triplets: Triplets::default(),
            ordering: Ordering::Auto,
            threads: Threads::Auto,
            free: Vec::new(),
            free_dofs: Vec::new(),
            g: Vec::new(),
            p: Vec::new(),
            rhs: Vec::new(),
            trial: Vec::new(),
            g_trial: Vec::new(),
            pcg: Pcg::new(),
            sol: Vec::new(),
            interrupt: None,
        }
    }

    /// A flag that, once set (e.g. by a signal handler), stops every solve before its next
    /// iteration with [`SolveError::Interrupted`]: a solve that never converges can still be
    /// stopped. `None` removes it.
    pub fn set_interrupt(&mut self, flag: Option<Arc<AtomicBool>>) {
        self.interrupt = flag;
    }

    /// Minimise `obj` from `x` (in place). `fixed[dof]` marks Dirichlet DOFs: they keep the
    /// values they have in `x` (the caller sets prescribed values before calling).
    pub fn minimize(
        &mut self,
        obj: &mut impl Objective,
        x: &mut [f64],
        fixed: &[bool],
        params: &NewtonParams,
    ) -> Result<SolveStats, SolveError> {
        let target = x.to_vec();
        self.minimize_to(obj, x, fixed, &target, params)
    }

    /// Like [`Newton::minimize`], but the Dirichlet DOFs move from their values in `x` to
    /// `target` *as part of the Newton steps*: their increment is `target − x`, the free DOFs
    /// solve `H_ff p_f = −g_f − H_fd p_d`, and the line search (with its feasibility bound)
    /// applies to the whole step. A prescribed motion that would pass through an obstacle is thus
    /// taken only as far as contact allows, and completed over the next iterations; the solve
    /// converges once every fixed DOF is at its target (set exactly) and `‖p‖_∞/Δt < ε_d`.
    /// While targets are not reached, a step is accepted if its energy is finite (the prescribed
    /// motion may do work and raise the energy); from then on the usual Armijo condition holds.
    pub fn minimize_to(
        &mut self,
        obj: &mut impl Objective,
        x: &mut [f64],
        fixed: &[bool],
        target: &[f64],
        params: &NewtonParams,
    ) -> Result<SolveStats, SolveError> {
        let n = obj.num_dofs();
        if x.len() != n || fixed.len() != n || target.len() != n {
            return Err(SolveError::BadProblem(format!(
                "{} DOFs but x has {} entries, fixed {} and target {}",
                n,
                x.len(),
                fixed.len(),
                target.len()
            )));
        }
        if !(params.dt > 0.0 && params.tolerance > 0.0) {
            return Err(SolveError::BadProblem(format!(
                "dt = {} and tolerance = {} must be positive",
                params.dt, params.tolerance
            )));
        }
        self.prepare(fixed, params);
        let problem = Problem {
            fixed,
            target,
            params,
        };
        let mut state = SolveState::new(params, self.lin.chol.stats);
        let outcome = self.iterate(&mut state, obj, x, &problem);
        state.finish(&self.lin.chol, outcome)
    }

    /// Free-DOF numbering and buffers for a solve (rebuilt per solve; the symbolic
    /// factorisation survives if the pattern of the free part is unchanged).
    fn prepare(&mut self, fixed: &[bool], params: &NewtonParams) {
        if params.ordering != self.ordering || params.threads != self.threads {
            self.lin.chol = Cholesky::new(params.ordering, params.threads);
            self.ordering = params.ordering;
            self.threads = params.threads;
        }
        let n = fixed.len();
        self.free.clear();
        self.free_dofs.clear();
        for (d, &f) in fixed.iter().enumerate() {
            if f {
                self.free.push(u32::MAX);
            } else {
                self.free.push(self.free_dofs.len() as u32);
                self.free_dofs.push(d);
            }
        }
        self.lin.chol.set_dof_map(&self.free_dofs);
        self.lin.analysed_in_solve = false;
        let nf = self.free_dofs.len();
        self.g.resize(n, 0.0);
        self.p.resize(n, 0.0);
        self.rhs.resize(nf, 0.0);
        self.sol.resize(nf, 0.0);
        self.trial.resize(n, 0.0);
        self.g_trial.resize(n, 0.0);
    }

    /// The Newton iterations from `x` until one of them ends the solve.
    fn iterate(
        &mut self,
        state: &mut SolveState,
        obj: &mut impl Objective,
        x: &mut [f64],
        problem: &Problem,
    ) -> Result<(), Failure> {
        state.e = obj.energy(x);
        state.e0 = state.e;
        if !state.e.is_finite() {
            return Err(Failure::NonFinite("energy at the initial guess"));
        }
        if self.free_dofs.is_empty() && problem.at_targets(x) {
            return Ok(());
        }
        for _ in 0..problem.params.max_iterations {
            if self
                .interrupt
                .as_ref()
                .is_some_and(|f| f.load(AtomicOrdering::Relaxed))
            {
                return Err(Failure::Interrupted);
            }
            if self.iteration(state, obj, x, problem)? == Progress::Done {
                return Ok(());
            }
        }
        Err(Failure::IterationLimit)
    }

    /// One Newton iteration: matrix and gradient, direction, stationarity test, line search,
    /// step.
    fn iteration(
        &mut self,
        state: &mut SolveState,
        obj: &mut impl Objective,
        x: &mut [f64],
        problem: &Problem,
    ) -> Result<Progress, Failure> {
        let params = problem.params;
        state.stats.iterations += 1;
        let cg = state.cg.active(params.linear);
        let matrix = self.matrix_and_gradient(state, obj, x, problem, cg.is_some())?;
        let solved = match cg {
            Some(cg) => self.solve_with_cg(state, obj, x, problem, matrix, cg)?,
            None => self.solve_with_cholesky(state, obj, x, problem, matrix)?,
        };
        let Direction { pmax, gp } = self.direction(problem.fixed)?;
        state.stats.final_residual = pmax / params.dt;
        let at_targets = problem.at_targets(x);
        let converged =
            at_targets && !solved.loose && state.stats.final_residual < params.tolerance;
        let scale = state.e.abs().max(state.e0.abs());
        // Stagnation at round-off: the predicted decrease is below the energy's round-off
        // and ‖p‖ has stopped shrinking (Newton near a minimum shrinks it quadratically).
        // The iterate is stationary to working precision although ‖p‖ is not small: p lies
        // in a direction the energy barely sees (e.g. a grid node with a tiny mass, where
        // the gradient's round-off divided by a tiny curvature dominates p).
        let flat = at_targets && -gp <= ROUNDOFF * scale;
        if state.stagnation.stalled(flat && !converged, pmax) {
            state.stats.roundoff_stops += 1;
            return Ok(Progress::Done);
        }

        let search = self.line_search(state, obj, x, problem, pmax, gp);
        // Within a few thousand ulps of the energy, a predicted decrease is round-off.
        let within_roundoff = at_targets && -gp <= 1e4 * ROUNDOFF * scale;
        // A backtracked step that leaves the energy exactly unchanged was accepted only
        // because Armijo's bound rounds to `e` (α·gᵀp vanishes next to it): no progress.
        // With a predicted decrease within round-off the iterate is stationary to working
        // precision — stop instead of repeating the zero step until the iteration limit.
        // (Full steps with an unchanged energy are normal near a minimum, where the energy
        // change is below round-off but x still improves.)
        if search.accepted == Some(state.e) && search.alpha < 1.0 && within_roundoff {
            state.stats.roundoff_stops += 1;
            return Ok(Progress::Done);
        }
        state.reuse.after_line_search(
            search.accepted.is_some() && search.alpha == 1.0,
            solved.exact,
        );
        match search.accepted {
            Some(et) => {
                x.copy_from_slice(&self.trial);
                if search.alpha == 1.0 {
                    // A full step reaches the targets exactly (no round-off drift).
                    for (d, xd) in x.iter_mut().enumerate() {
                        if problem.fixed[d] {
                            *xd = problem.target[d];
                        }
                    }
                }
                state.e = et;
            }
            None if converged => {
                // Already at the tolerance: the last increment is below round-off.
            }
            None if within_roundoff => {
                // No step decreases the energy and the predicted decrease is round-off:
                // stationary to working precision.
                state.stats.roundoff_stops += 1;
                return Ok(Progress::Done);
            }
            None => {
                let on_the_gradients_word =
                    (at_targets && !solved.loose && search.full_step_feasible)
                        .then(|| self.full_step_on_the_gradients_word(obj, x, state.e, gp))
                        .flatten();
                let Some(et) = on_the_gradients_word else {
                    return Err(Failure::LineSearchStalled);
                };
                // `trial` holds x + p.
                x.copy_from_slice(&self.trial);
                state.e = et;
                state.stats.gradient_steps += 1;
            }
        }
        Ok(if converged {
            Progress::Done
        } else {
            Progress::Continue
        })
    }

    /// The gradient into `g` and the iteration's matrix (CSC, and its factorisation on the
    /// Cholesky path) into `lin`: the last iteration's if [`HessianReuse`] allows it, else
    /// the exact Hessian if [`ExactPolicy`] tries it and the objective has one, else the
    /// projected one. A new matrix is built and factorised on another thread while this one
    /// computes the gradient.
    fn matrix_and_gradient(
        &mut self,
        state: &mut SolveState,
        obj: &mut impl Objective,
        x: &[f64],
        problem: &Problem,
        cg: bool,
    ) -> Result<Matrix, Failure> {
        let t = Instant::now();
        obj.begin_iteration(x);
        let nf = self.free_dofs.len();
        // Reuse the last matrix? The gradient comes first, then the objective says whether
        // the Hessian's terms are still those of that matrix.
        let mut have_gradient = false;
        let mut reuse = None;
        if let Some(held_exact) = state
            .reuse
            .candidate(state.stats.final_residual, problem, x)
        {
            // (Timed with the Hessian below: both are assembly.)
            self.g.fill(0.0);
            obj.gradient(x, &mut self.g);
            have_gradient = true;
            if obj.hessian_terms_unchanged() {
                reuse = Some(held_exact);
                state.stats.reused_hessians += 1;
            }
        }
        let exact = match reuse {
            Some(exact) => exact,
            None => {
                let try_exact = state.exact.try_now();
                self.triplets.clear();
                let exact = try_exact && obj.exact_hessian(x, &mut self.triplets);
                if try_exact && !exact {
                    state.exact.unavailable();
                }
                if !exact {
                    self.triplets.clear();
                    obj.hessian(x, &mut self.triplets);
                }
                exact
            }
        };
        let hessian_s = t.elapsed().as_secs_f64();
        let mut factor_result = None;
        let mut gradient_s = 0.0;
        if reuse.is_some() {
            // The matrix and factorisation in `lin` are the last iteration's.
            factor_result = Some(Ok(true));
        } else {
            // The factorisation of the exact Hessian is a try (no diagonal shifts); the
            // projected one after a rejection is factorised afterwards.
            let (lin, triplets, free) = (&mut self.lin, &self.triplets, &self.free);
            let g = &mut self.g;
            let mut factor = move || {
                if cg {
                    // CG needs the matrix only.
                    lin.build(triplets, free, nf);
                    return Ok(true);
                }
                lin.assemble(triplets, free, nf)?;
                if exact {
                    lin.chol.try_factorize(&mut lin.csc)
                } else {
                    lin.chol.factorize(&mut lin.csc).map(|()| true)
                }
            };
            let mut gradient = || {
                if have_gradient {
                    return;
                }
                let t = Instant::now();
                g.fill(0.0);
                obj.gradient(x, g);
                gradient_s = t.elapsed().as_secs_f64();
            };
            if rayon::current_num_threads() > 1 {
                rayon::in_place_scope(|scope| {
                    let out = &mut factor_result;
                    scope.spawn(move |_| *out = Some(factor()));
                    gradient();
                });
            } else {
                gradient();
                factor_result = Some(factor());
            }
        }
        // Work, not wall time: the gradient overlapped the factorisation.
        state.stats.assembly_s += hessian_s + gradient_s + std::mem::take(&mut self.lin.csc_s);
        if self.g.iter().any(|v| !v.is_finite()) {
            return Err(Failure::NonFinite("gradient"));
        }
        let factorized = factor_result
            .expect("the factorisation ran")
            .map_err(Failure::Linear)?;
        Ok(Matrix { exact, factorized })
    }

    /// The free part of the direction into `rhs` by conjugate gradients on the built matrix.
    /// An exact Hessian is rejected if CG meets non-positive curvature or does not converge
    /// (CG then runs on the projected one); a projected Hessian CG cannot do is factorised,
    /// and [`CgPolicy`] hands the rest of the solve to Cholesky.
    fn solve_with_cg(
        &mut self,
        state: &mut SolveState,
        obj: &mut impl Objective,
        x: &[f64],
        problem: &Problem,
        matrix: Matrix,
        (rtol, max_it, forcing): (f64, usize, Forcing),
    ) -> Result<Solved, Failure> {
        let (fixed, target, params) = (problem.fixed, problem.target, problem.params);
        let Matrix {
            exact,
            mut factorized,
        } = matrix;
        let nf = self.free_dofs.len();
        let eta = match forcing {
            Forcing::Fixed => rtol,
            Forcing::Adaptive { max } => {
                let gnorm = self
                    .free_dofs
                    .iter()
                    .map(|&d| self.g[d] * self.g[d])
                    .sum::<f64>()
                    .sqrt();
                forcing_term(gnorm, &mut state.cg.last_forcing, rtol, max)
            }
        };
        let mut solved = false;
        let mut loose = false;
        for attempt in 0..2 {
            if self.cg_solve(&mut state.stats, problem, x, eta, max_it) {
                self.rhs.copy_from_slice(&self.sol);
                solved = true;
            }
            if attempt == 0 && exact {
                factorized = solved;
            }
            if solved || !(attempt == 0 && exact) {
                break;
            }
            // The exact Hessian is rejected: CG on the projected one.
            state.exact.rejected(&mut state.stats);
            let t = Instant::now();
            self.triplets.clear();
            obj.hessian(x, &mut self.triplets);
            self.lin.build(&self.triplets, &self.free, nf);
            state.stats.assembly_s +=
                t.elapsed().as_secs_f64() + std::mem::take(&mut self.lin.csc_s);
        }
        // A loosely solved direction that would pass the convergence test is solved again
        // to `rtol`: CG's iterates grow in norm, so a loose one understates ‖p‖.
        if solved && eta > rtol {
            let fixed_max = (0..x.len())
                .filter(|&d| fixed[d])
                .fold(0.0f64, |m, d| m.max(self.p[d].abs()));
            let free_max = self.rhs.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            if fixed_max.max(free_max) / params.dt < params.tolerance {
                // The loose solution waits in `trial` (free until the line search).
                self.trial[..nf].copy_from_slice(&self.rhs);
                let converged = self.cg_solve(&mut state.stats, problem, x, rtol, max_it);
                state.stats.pcg_tightened += 1;
                if converged {
                    self.rhs.copy_from_slice(&self.sol);
                } else {
                    // Keep the loose direction (a descent direction all the same), but it
                    // cannot end the solve.
                    loose = true;
                    self.rhs.copy_from_slice(&self.trial[..nf]);
                }
            }
        }
        if exact && factorized {
            state.exact.accepted(&mut state.stats);
        }
        if !solved {
            // Cholesky of the (projected) matrix already built, and for the rest of the
            // solve: its Hessians are alike.
            state.stats.pcg_fallbacks += 1;
            state.cg.gave_up = true;
            self.lin
                .ensure_analysed()
                .and_then(|()| self.lin.chol.factorize(&mut self.lin.csc))
                .map_err(Failure::Linear)?;
            self.prescribed_part(fixed, target, x);
            if nf > 0 {
                self.lin.chol.solve_in_place(&mut self.rhs);
            }
        }
        Ok(Solved {
            exact: exact && factorized,
            loose,
        })
    }

    /// Conjugate gradients on the built matrix for the right-hand side of the direction
    /// ([`Newton::prescribed_part`]) to relative accuracy `eta`, the solution in `sol`;
    /// whether it converged.
    fn cg_solve(
        &mut self,
        stats: &mut SolveStats,
        problem: &Problem,
        x: &[f64],
        eta: f64,
        max_it: usize,
    ) -> bool {
        self.prescribed_part(problem.fixed, problem.target, x);
        let t = Instant::now();
        let out = self
            .pcg
            .solve(&self.lin.csc, &self.rhs, &mut self.sol, eta, max_it);
        stats.pcg_s += t.elapsed().as_secs_f64();
        stats.pcg_iterations += out.iterations();
        out.converged()
    }

    /// The free part of the direction into `rhs` by the factorisation; an exact Hessian
    /// whose factorisation failed is rejected and the projected one factorised instead.
    fn solve_with_cholesky(
        &mut self,
        state: &mut SolveState,
        obj: &mut impl Objective,
        x: &[f64],
        problem: &Problem,
        matrix: Matrix,
    ) -> Result<Solved, Failure> {
        let Matrix { exact, factorized } = matrix;
        if exact {
            if factorized {
                state.exact.accepted(&mut state.stats);
            } else {
                state.exact.rejected(&mut state.stats);
            }
        }
        if !factorized {
            let t = Instant::now();
            self.triplets.clear();
            obj.hessian(x, &mut self.triplets);
            state.stats.assembly_s += t.elapsed().as_secs_f64();
            let result = self
                .lin
                .assemble(&self.triplets, &self.free, self.free_dofs.len())
                .and_then(|()| self.lin.chol.factorize(&mut self.lin.csc));
            state.stats.assembly_s += std::mem::take(&mut self.lin.csc_s);
            result.map_err(Failure::Linear)?;
        }
        self.prescribed_part(problem.fixed, problem.target, x);
        if !self.free_dofs.is_empty() {
            self.lin.chol.solve_in_place(&mut self.rhs);
        }
        Ok(Solved {
            exact: exact && factorized,
            loose: false,
        })
    }

    /// The direction `p`: prescribed increments of the fixed DOFs (set by
    /// [`Newton::prescribed_part`]), the solve in `rhs` on free ones; its largest entry and
    /// `gᵀp`.
    fn direction(&mut self, fixed: &[bool]) -> Result<Direction, Failure> {
        let mut pmax = 0.0f64;
        let mut gp = 0.0;
        for (d, &f) in fixed.iter().enumerate() {
            if f {
                pmax = pmax.max(self.p[d].abs());
                gp += self.g[d] * self.p[d];
            }
        }
        for (k, &d) in self.free_dofs.iter().enumerate() {
            self.p[d] = self.rhs[k];
            pmax = pmax.max(self.rhs[k].abs());
            gp += self.g[d] * self.rhs[k];
        }
        if !pmax.is_finite() {
            return Err(Failure::NonFinite("Newton direction"));
        }
        Ok(Direction { pmax, gp })
    }

    /// Backtracking from the feasible fraction of the objective's step bound (or 1) until
    /// Armijo holds — or, while prescribed DOFs are still on their way, until the energy is
    /// finite; the accepted point is left in `trial`.
    fn line_search(
        &mut self,
        state: &mut SolveState,
        obj: &mut impl Objective,
        x: &[f64],
        problem: &Problem,
        pmax: f64,
        gp: f64,
    ) -> LineSearch {
        let params = problem.params;
        let stats = &mut state.stats;
        let t = Instant::now();
        let bound = obj.max_step(x, &self.p);
        let mut alpha = if bound.limit.is_some() || bound.alpha < 1.0 {
            match bound.limit {
                Some(StepLimit::Ccd) => stats.limited_by_ccd += 1,
                Some(StepLimit::DetF) => stats.limited_by_det_f += 1,
                _ => stats.limited_by_other += 1,
            }
            (params.feasible_fraction * bound.alpha).min(1.0)
        } else {
            1.0
        };
        let full_step_feasible = alpha == 1.0;
        let at_targets = problem.at_targets(x);
        let mut accepted = None;
        while alpha * pmax >= params.min_step {
            for (t, (x, p)) in self.trial.iter_mut().zip(x.iter().zip(&self.p)) {
                *t = x + alpha * p;
            }
            let et = obj.energy(&self.trial);
            // While prescribed DOFs are still on their way, the energy may rise (the motion
            // does work on the system): accept any feasible, finite step then. Afterwards,
            // Armijo.
            let ok = !at_targets || et <= state.e + params.armijo * alpha * gp;
            if et.is_finite() && ok {
                accepted = Some(et);
                break;
            }
            alpha *= 0.5;
            stats.backtracks += 1;
        }
        stats.line_search_s += t.elapsed().as_secs_f64();
        LineSearch {
            accepted,
            alpha,
            full_step_feasible,
        }
    }

    /// The energy at the full step `x + p` (left in `trial`) if it may be taken although no
    /// step length decreased the energy: that energy is finite and above `e` by no more than
    /// [`GRADIENT_STEP_RISE`] times the predicted decrease `−gᵀp` (a change the energy's
    /// evaluation does not resolve: measured on a spinning FEM ring, the energy of a
    /// converging Newton step came out 0.25–2.3× the predicted decrease *above* `e`), and the
    /// free gradient's norm there is at most half the current one (Newton's local convergence,
    /// which the gradient resolves: 2·10⁵× smaller in that case). See
    /// [`SolveStats::gradient_steps`].
    fn full_step_on_the_gradients_word<O: Objective>(
        &mut self,
        obj: &mut O,
        x: &[f64],
        e: f64,
        gp: f64,
    ) -> Option<f64> {
        for (t, (x, p)) in self.trial.iter_mut().zip(x.iter().zip(&self.p)) {
            *t = x + p;
        }
        let et = obj.energy(&self.trial);
        if !(et.is_finite() && et - e <= -GRADIENT_STEP_RISE * gp) {
            return None;
        }
        self.g_trial.iter_mut().for_each(|v| *v = 0.0);
        obj.gradient(&self.trial, &mut self.g_trial);
        let norm2 = |g: &[f64]| self.free_dofs.iter().map(|&d| g[d] * g[d]).sum::<f64>();
        (norm2(&self.g_trial) <= 0.25 * norm2(&self.g)).then_some(et)
    }

    /// `p` zero on free DOFs and the prescribed increment `target − x` on fixed ones; the
    /// right-hand side `−g_f − H_fd p_d` on the free DOFs.
    fn prescribed_part(&mut self, fixed: &[bool], target: &[f64], x: &[f64]) {
        self.p.iter_mut().for_each(|v| *v = 0.0);
        let mut moving = false;
        for d in 0..self.p.len() {
            if fixed[d] {
                self.p[d] = target[d] - x[d];
                moving |= self.p[d] != 0.0;
            }
        }
        for (k, &d) in self.free_dofs.iter().enumerate() {
            self.rhs[k] = -self.g[d];
        }
        if moving {
            // −H_fd p_d from the upper triangle (the part of the triplets that counts), each
            // off-diagonal entry standing for itself and its mirror: an objective may push only
            // the upper triangle, so a free DOF numbered after a fixed one finds their coupling
            // only as (fixed, free).
            let t = &self.triplets;
            for k in 0..t.vals.len() {
                let (r, c) = (t.rows[k] as usize, t.cols[k] as usize);
                if r >= c {
                    continue;
                }
                let (fr, fc) = (self.free[r], self.free[c]);
                if fr != u32::MAX && fixed[c] {
                    self.rhs[fr as usize] -= t.vals[k] * self.p[c];
                } else if fc != u32::MAX && fixed[r] {
                    self.rhs[fc as usize] -= t.vals[k] * self.p[r];
                }
            }
        }
    }

    /// Statistics of the linear algebra since this solver was created.
    pub fn linear_stats(&self) -> crate::linear::LinearStats {
        self.lin.chol.stats
    }
}

/// What a solve is asked: which DOFs are fixed, where they go, with which parameters.
struct Problem<'a> {
    fixed: &'a [bool],
    target: &'a [f64],
    params: &'a NewtonParams,
}

impl Problem<'_> {
    /// Whether every fixed DOF of `x` is at its target.
    fn at_targets(&self, x: &[f64]) -> bool {
        (0..x.len()).all(|d| !self.fixed[d] || x[d] == self.target[d])
    }
}

/// How an iteration ends: the solve goes on, or ends as converged or stationary.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Progress {
    Continue,
    Done,
}

/// Why a solve failed; [`SolveState::finish`] attaches the statistics.
enum Failure {
    NonFinite(&'static str),
    Linear(LinearError),
    LineSearchStalled,
    IterationLimit,
    Interrupted,
}

/// The iteration's matrix: whether it is the exact Hessian, and whether it is factorised
/// (always on the CG path, where only the matrix is built; for an exact Hessian on the
/// Cholesky path, whether the try succeeded).
#[derive(Clone, Copy)]
struct Matrix {
    exact: bool,
    factorized: bool,
}

/// How the direction was solved: with the exact Hessian, and only loosely (CG whose
/// tightening did not converge — such a direction cannot end the solve).
struct Solved {
    exact: bool,
    loose: bool,
}

/// The direction's largest entry and `gᵀp`.
struct Direction {
    pmax: f64,
    gp: f64,
}

/// The line search's outcome: the energy at the accepted point (in `trial`), the step length
/// it ended with, and whether the full step was feasible.
struct LineSearch {
    accepted: Option<f64>,
    alpha: f64,
    full_step_feasible: bool,
}

/// The state of one solve: the energy, the statistics and one policy per strategy.
struct SolveState {
    stats: SolveStats,
    /// The factorisation's counters at the start (the solve reports differences).
    lin0: crate::linear::LinearStats,
    /// Energy at the current iterate, and at the initial guess.
    e: f64,
    e0: f64,
    exact: ExactPolicy,
    cg: CgPolicy,
    reuse: HessianReuse,
    stagnation: Stagnation,
}

impl SolveState {
    fn new(params: &NewtonParams, lin0: crate::linear::LinearStats) -> Self {
        Self {
            stats: SolveStats::default(),
            lin0,
            e: 0.0,
            e0: 0.0,
            exact: ExactPolicy {
                wanted: params.hessian == HessianStrategy::ExactWhenDefinite,
                rejected_in_a_row: 0,
                wait: 0,
            },
            cg: CgPolicy {
                gave_up: false,
                last_forcing: (0.0, 0.0),
            },
            reuse: HessianReuse {
                below: params.reuse_hessian_below,
                held: None,
            },
            stagnation: Stagnation {
                history: Vec::new(),
            },
        }
    }

    /// The statistics with the final energy and the factorisation's share, as the solve's
    /// result.
    fn finish(
        mut self,
        chol: &Cholesky,
        outcome: Result<(), Failure>,
    ) -> Result<SolveStats, SolveError> {
        let (s, lin0) = (&mut self.stats, &self.lin0);
        s.final_energy = self.e;
        s.symbolic_s = chol.stats.symbolic_s - lin0.symbolic_s;
        s.numeric_s = chol.stats.numeric_s - lin0.numeric_s;
        s.solve_s = chol.stats.solve_s - lin0.solve_s;
        s.regularizations = chol.stats.regularizations - lin0.regularizations;
        s.symbolic_analyses = chol.stats.symbolic_count - lin0.symbolic_count;
        let stats = Box::new(self.stats);
        match outcome {
            Ok(()) => Ok(*stats),
            Err(Failure::NonFinite(what)) => Err(SolveError::NonFinite { what, stats }),
            Err(Failure::Linear(source)) => Err(SolveError::Linear { source, stats }),
            Err(Failure::LineSearchStalled) => Err(SolveError::LineSearchStalled { stats }),
            Err(Failure::IterationLimit) => Err(SolveError::IterationLimit { stats }),
            Err(Failure::Interrupted) => Err(SolveError::Interrupted { stats }),
        }
    }
}

/// [`HessianStrategy::ExactWhenDefinite`]: whether an iteration tries the exact Hessian. After
/// a first rejection the next iteration tries again, then the policy backs off (waits 1, 3,
/// 7, … iterations): a solve whose exact Hessian stays indefinite wastes O(log iterations)
/// tries. An objective without an exact Hessian is not asked again in the solve.
struct ExactPolicy {
    wanted: bool,
    rejected_in_a_row: u32,
    /// Iterations to wait before the next try.
    wait: u64,
}

impl ExactPolicy {
    /// Whether this iteration (which assembles a Hessian) tries the exact one.
    fn try_now(&mut self) -> bool {
        let try_exact = self.wanted && self.wait == 0;
        self.wait = self.wait.saturating_sub(1);
        try_exact
    }

    /// The objective has no exact Hessian.
    fn unavailable(&mut self) {
        self.wait = u64::MAX;
    }

    /// The exact Hessian was used.
    fn accepted(&mut self, stats: &mut SolveStats) {
        stats.exact_iterations += 1;
        self.rejected_in_a_row = 0;
    }

    /// The exact Hessian was found indefinite (or CG could not solve with it).
    fn rejected(&mut self, stats: &mut SolveStats) {
        stats.exact_rejections += 1;
        self.rejected_in_a_row += 1;
        self.wait = (1u64 << (self.rejected_in_a_row - 1).min(20)) - 1;
    }
}

/// [`LinearSolver::Pcg`]: whether CG is still in use in this solve, and the Eisenstat–Walker
/// state ([`Forcing::Adaptive`]).
struct CgPolicy {
    /// CG gave up on a projected Hessian in this solve: the rest of it uses Cholesky.
    gave_up: bool,
    /// The last free gradient norm and forcing term.
    last_forcing: (f64, f64),
}

impl CgPolicy {
    /// CG's `(rtol, max_iterations, forcing)` if this iteration solves with it.
    fn active(&self, linear: LinearSolver) -> Option<(f64, usize, Forcing)> {
        match linear {
            LinearSolver::Pcg {
                rtol,
                max_iterations,
                forcing,
            } if !self.gave_up => Some((rtol, max_iterations, forcing)),
            _ => None,
        }
    }
}

/// [`NewtonParams::reuse_hessian_below`] (a Shamanskii step): the matrix of the last
/// iteration may be solved with again after a full step with a small increment, every
/// prescribed DOF at its target and the objective's Hessian terms unchanged.
struct HessianReuse {
    below: f64,
    /// `Some(exact)` when the matrix the last iteration solved with may be reused.
    held: Option<bool>,
}

impl HessianReuse {
    /// The held matrix's `exact` flag if the iteration at `x`, after an increment
    /// `residual`, may reuse it (subject to the objective's word).
    fn candidate(&self, residual: f64, problem: &Problem, x: &[f64]) -> Option<bool> {
        self.held
            .filter(|_| residual < self.below && problem.at_targets(x))
    }

    /// After the line search: hold the matrix if the full step was taken.
    fn after_line_search(&mut self, full_step: bool, exact: bool) {
        self.held = (self.below > 0.0 && full_step).then_some(exact);
    }
}

/// Stagnation at round-off: consecutive round-off-flat iterations whose ‖p‖ does not halve.
struct Stagnation {
    /// ‖p‖_∞ of the flat iterations in a row.
    history: Vec<f64>,
}

impl Stagnation {
    /// Record an iteration (flat and not converged, with largest increment `pmax`); whether
    /// [`STAGNATION_ITERATIONS`] flat ones in a row have not halved ‖p‖.
    fn stalled(&mut self, flat: bool, pmax: f64) -> bool {
        if !flat {
            self.history.clear();
            return false;
        }
        self.history.push(pmax);
        let k = self.history.len();
        k >= STAGNATION_ITERATIONS
            && self.history[k - 1] > 0.5 * self.history[k - STAGNATION_ITERATIONS]
    }
}

/// The Eisenstat–Walker forcing term (choice 2, γ = 0.9, α = 2) for a free gradient of norm
/// `gnorm`, given the last iteration's `(gradient norm, term)` (`(0, 0)` in a solve's first
/// iteration, which gets `max`), clamped to `[rtol, max]`; updates `last`.
fn forcing_term(gnorm: f64, last: &mut (f64, f64), rtol: f64, max: f64) -> f64 {
    let (last_gnorm, last_eta) = *last;
    let mut eta = if last_gnorm > 0.0 {
        0.9 * (gnorm / last_gnorm).powi(2)
    } else {
        max
    };
    // Safeguard: do not drop much faster than the last term while that is large.
    if 0.9 * last_eta * last_eta > 0.1 {
        eta = eta.max(0.9 * last_eta * last_eta);
    }
    let eta = eta.min(max).max(rtol);
    *last = (gnorm, eta);
    eta
}

impl Linear {
    /// The Hessian triplets into the free-DOF CSC (no analysis); whether the pattern changed.
    fn build(&mut self, triplets: &Triplets, free: &[u32], nf: usize) -> bool {
        let t = Instant::now();
        let changed = self.csc.assemble(triplets, free, nf);
        self.csc_s += t.elapsed().as_secs_f64();
        changed
    }

    /// A symbolic analysis covering the built matrix's pattern, unless the current one does.
    fn ensure_analysed(&mut self) -> Result<(), LinearError> {
        let t = Instant::now();
        let covered = self.chol.is_analyzed()
            && self.csc.widen(
                &self.analysed_col_ptr,
                &self.analysed_row_idx,
                self.analysed_in_solve,
            );
        self.chol.stats.symbolic_s += t.elapsed().as_secs_f64();
        if !covered {
            self.chol.analyze(&self.csc)?;
            self.analysed_col_ptr.clone_from(&self.csc.col_ptr);
            self.analysed_row_idx.clone_from(&self.csc.row_idx);
            self.analysed_in_solve = true;
        }
        Ok(())
    }

    /// The Hessian triplets into the free-DOF CSC, and a new symbolic analysis if the sparsity
    /// pattern is not covered by the analysed one.
    fn assemble(
        &mut self,
        triplets: &Triplets,
        free: &[u32],
        nf: usize,
    ) -> Result<(), LinearError> {
        let changed = self.build(triplets, free, nf);
        if changed || !self.chol.is_analyzed() {
            // A pattern the analysed one contains is factorised with it (explicit zeros). Within
            // a solve the next analysis covers the union of the patterns met so far, so a
            // contact coupling that comes and goes over the iterations costs one analysis, not
            // one per change. Unions are only formed with an analysis made in the same solve: a
            // new solve's unknowns may mean other things, and patterns merged across solves
            // would grow without bound (a contained pattern is still reused: a correct, if
            // wider, structure).
            self.ensure_analysed()?;
        }
        Ok(())
    }
}
