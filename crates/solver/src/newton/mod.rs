//! Projected Newton with a feasibility-filtered backtracking line search (BFEMP Algorithm 2).
//!
//! Each iteration: `begin_iteration` (the objective updates its active sets), gradient `g`,
//! PSD Hessian `H` (triplets → CSC, symbolic factorisation reused while the pattern holds),
//! `p = −H⁻¹g` on the free DOFs (`p = 0` on fixed ones), the largest feasible step `α_max`
//! from the objective (CCD, det F), then `α = min(1, 0.9 α_max)` halved until
//! `E(x + αp) ≤ E(x) + c α gᵀp` (Armijo, `c = 1e-4` by default; non-finite energies count as
//! failures). The solve stops when `‖p‖_∞ / Δt < ε_d` (BFEMP §5: the Newton increment in
//! velocity units; or the objective's own size of `p`, `Objective::increment_size`). Before
//! every iteration but the first an objective may update its lagged terms
//! (`Objective::update_lagged`; the energy is then re-evaluated).
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
//! In the code, a solve is a [`Newton`] (here: buffers and the factorisation, kept across
//! solves) and a `SolveState` (`state.rs`: energy, statistics and one policy per strategy, in
//! `policy.rs`: `ExactPolicy` for [`HessianStrategy::ExactWhenDefinite`], `CgPolicy` for
//! [`LinearSolver::Pcg`] and its forcing, `HessianReuse` for
//! [`NewtonParams::reuse_hessian_below`], `Stagnation` for round-off stops). What a solve is
//! given — the [`Objective`] trait, the strategies, [`NewtonParams`] — is in `params.rs`, its
//! [`SolveStats`] in `stats.rs`. An iteration runs `matrix_and_gradient`, `solve_with_cg` or
//! `solve_with_cholesky`, `direction`, the stationarity tests and `line_search`
//! (`line_search.rs`), in that order; every phase that can end the solve returns a `Failure`,
//! to which `SolveState::finish` attaches the statistics.

mod line_search;
mod params;
mod policy;
mod state;
mod stats;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering as AtomicOrdering};
use std::time::Instant;

use crate::linear::{Cholesky, LinearError, Ordering, Precision, Threads};
use crate::pcg::Pcg;
use crate::{SolveError, Triplets, UpperCsc};

pub use params::{
    Forcing, HessianStrategy, LinearSolver, NewtonParams, Objective, ROUNDOFF, StepBound, StepLimit,
};
pub use stats::{IterationRecord, SolveStats};

use params::Problem;
use policy::forcing_term;
use state::{Direction, Failure, LineSearch, Matrix, Progress, SolveState, Solved};

/// A projected-Newton solver. Keep it across solves: the symbolic factorisation and all
/// buffers are reused while the Hessian's pattern is unchanged.
pub struct Newton {
    lin: Linear,
    triplets: Triplets,
    ordering: Ordering,
    threads: Threads,
    precision: Precision,
    free: Vec<u32>,
    free_dofs: Vec<usize>,
    g: Vec<f64>,
    p: Vec<f64>,
    rhs: Vec<f64>,
    trial: Vec<f64>,
    /// The gradient at `trial`, for a step taken on the gradient's word.
    g_trial: Vec<f64>,
    /// The direction times [`NewtonParams::max_expansion`], for the expanded step's bound.
    long_p: Vec<f64>,
    pcg: Pcg,
    sol: Vec<f64>,
    /// Set from elsewhere to stop the solve before its next iteration.
    interrupt: Option<Arc<AtomicBool>>,
    /// Whether solves record every iteration in [`SolveStats::trace`].
    record: bool,
    /// A factorisation of this solve's matrix size is held ([`LinearSolver::LastFactorCg`]
    /// and [`LinearSolver::Auto`] may precondition with it).
    factor_ready: bool,
    /// The true gradient and the first direction's free part, kept while a piecewise model's
    /// direction is solved ([`Objective::begin_model`]).
    model_keep: (Vec<f64>, Vec<f64>),
    /// [`Newton::keep_last_factor`] was called for the next solve.
    keep_factor: bool,
}

/// A factorisation's symbolic analysis, by what it was made from: the upper-triangular
/// pattern (`col_ptr`, `row_idx`, as [`UpperCsc`] stores it) and the original DOF of each row
/// (empty: the identity). See [`Newton::analysed_pattern`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AnalysedPattern {
    /// The original DOF of each row.
    pub dof_of: Vec<usize>,
    /// Column pointers.
    pub col_ptr: Vec<usize>,
    /// Row indices.
    pub row_idx: Vec<usize>,
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
    /// The original DOF of each row of that analysis (nested dissection orders nodes).
    analysed_dof_of: Vec<usize>,
    analysed_in_solve: bool,
    /// Seconds building the CSC matrix (counted as assembly).
    csc_s: f64,
    /// Whether a build changed the pattern since `assemble` last made sure it is analysed.
    unanalysed: bool,
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
                analysed_dof_of: Vec::new(),
                analysed_in_solve: false,
                csc_s: 0.0,
                unanalysed: false,
            },
            triplets: Triplets::default(),
            ordering: Ordering::Auto,
            threads: Threads::Auto,
            precision: Precision::Double,
            free: Vec::new(),
            free_dofs: Vec::new(),
            g: Vec::new(),
            p: Vec::new(),
            rhs: Vec::new(),
            trial: Vec::new(),
            g_trial: Vec::new(),
            long_p: Vec::new(),
            pcg: Pcg::new(),
            sol: Vec::new(),
            interrupt: None,
            record: false,
            factor_ready: false,
            model_keep: (Vec::new(), Vec::new()),
            keep_factor: false,
        }
    }

    /// A flag that, once set (e.g. by a signal handler), stops every solve before its next
    /// iteration with [`SolveError::Interrupted`]: a solve that never converges can still be
    /// stopped. `None` removes it.
    pub fn set_interrupt(&mut self, flag: Option<Arc<AtomicBool>>) {
        self.interrupt = flag;
    }

    /// The next solve has the unknowns of the last one (the friction loop's next solve within
    /// a step): with [`LinearSolver::LastFactorCg`] (and [`LinearSolver::Auto`] on a large
    /// factor) its first iteration may solve by CG preconditioned with the last factorisation
    /// instead of factorising — if its fixed DOFs are those of the last solve. Applies to the
    /// next solve only.
    pub fn keep_last_factor(&mut self) {
        self.keep_factor = true;
    }

    /// The sparsity pattern the factorisation was last analysed for (`None` before the first
    /// analysis). A later solve whose matrix pattern it contains factorises with it — explicit
    /// zeros, the same elimination order — so the bits of every later factorisation depend on
    /// it: a checkpoint that keeps it lets a solver built afresh
    /// ([`Newton::restore_analysis`]) continue exactly as this one would.
    pub fn analysed_pattern(&self) -> Option<AnalysedPattern> {
        self.lin.chol.is_analyzed().then(|| AnalysedPattern {
            dof_of: self.lin.analysed_dof_of.clone(),
            col_ptr: self.lin.analysed_col_ptr.clone(),
            row_idx: self.lin.analysed_row_idx.clone(),
        })
    }

    /// Analyse `pattern` (from [`Newton::analysed_pattern`]) with the ordering, threads and
    /// precision of `params`, as if the last solve had: the next solves reuse it as they would
    /// have reused the original. A malformed pattern is [`SolveError::BadProblem`] saying
    /// what is wrong with it.
    pub fn restore_analysis(
        &mut self,
        params: &NewtonParams,
        pattern: &AnalysedPattern,
    ) -> Result<(), SolveError> {
        let n = pattern.col_ptr.len().saturating_sub(1);
        if !(pattern.dof_of.is_empty() || pattern.dof_of.len() == n) {
            return Err(SolveError::BadProblem(format!(
                "an analysed pattern of {n} rows with {} row DOFs",
                pattern.dof_of.len()
            )));
        }
        let csc = UpperCsc::from_pattern(n, &pattern.col_ptr, &pattern.row_idx)
            .map_err(|e| SolveError::BadProblem(format!("analysed pattern: {e}")))?;
        self.lin.chol = Cholesky::with_precision(params.ordering, params.threads, params.precision);
        self.ordering = params.ordering;
        self.threads = params.threads;
        self.precision = params.precision;
        self.lin.chol.set_dof_map(&pattern.dof_of);
        self.lin
            .chol
            .analyze(&csc)
            .map_err(|e| SolveError::BadProblem(format!("analysed pattern: {e}")))?;
        self.lin.analysed_col_ptr.clone_from(&pattern.col_ptr);
        self.lin.analysed_row_idx.clone_from(&pattern.row_idx);
        self.lin.analysed_dof_of.clone_from(&pattern.dof_of);
        self.lin.analysed_in_solve = false;
        self.factor_ready = false;
        Ok(())
    }

    /// Whether the solves that follow record each Newton iteration ([`IterationRecord`]) in
    /// their [`SolveStats::trace`] — for diagnosing where a solve's iterations go. Off by
    /// default; on, it costs a pass over the increment per iteration.
    pub fn record_iterations(&mut self, on: bool) {
        self.record = on;
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
        if params.ordering != self.ordering
            || params.threads != self.threads
            || params.precision != self.precision
        {
            self.lin.chol =
                Cholesky::with_precision(params.ordering, params.threads, params.precision);
            self.ordering = params.ordering;
            self.threads = params.threads;
            self.precision = params.precision;
        }
        let n = fixed.len();
        // The last factor stays usable as a preconditioner only for the same free DOFs.
        let mut k = 0;
        let same_unknowns = self.free.len() == n
            && fixed.iter().zip(&self.free).all(|(&f, &v)| {
                if f {
                    v == u32::MAX
                } else {
                    k += 1;
                    v == k - 1
                }
            });
        let keep = std::mem::take(&mut self.keep_factor) && same_unknowns;
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
        self.factor_ready &= keep;
        let nf = self.free_dofs.len();
        self.g.resize(n, 0.0);
        self.p.resize(n, 0.0);
        self.rhs.resize(nf, 0.0);
        self.sol.resize(nf, 0.0);
        self.trial.resize(n, 0.0);
        self.g_trial.resize(n, 0.0);
        self.long_p.resize(n, 0.0);
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
        for k in 0..problem.params.max_iterations {
            if self
                .interrupt
                .as_ref()
                .is_some_and(|f| f.load(AtomicOrdering::Relaxed))
            {
                return Err(Failure::Interrupted);
            }
            if k > 0 && obj.update_lagged(x, state.stats.final_residual) {
                state.stats.lagged_updates += 1;
                state.e = obj.energy(x);
                if !state.e.is_finite() {
                    return Err(Failure::NonFinite("energy after updating lagged terms"));
                }
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
        // Reused Hessians and taken model directions before this iteration (for its record).
        let counts_before = (
            state.stats.reused_hessians,
            state.stats.model_directions_taken,
        );
        let matrix = self.matrix_and_gradient(state, obj, x, problem, cg.is_some(), false)?;
        let mut solved = match cg {
            Some(cg) => self.solve_with_cg(state, obj, x, problem, matrix, cg)?,
            None => self.solve_with_cholesky(state, obj, x, problem, matrix)?,
        };
        let mut direction = self.direction(problem.fixed)?;
        // (Whether or not its direction is taken, the matrix held is then the model's.)
        let modelled = obj.begin_model(x, &self.p);
        if modelled && let Some(model) = self.model_direction(state, obj, x, problem)? {
            (solved, direction) = model;
        }
        let Direction { pmax, gp } = direction;
        state.stats.final_residual = obj.increment_size(x, &self.p).unwrap_or(pmax) / params.dt;
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
            state.stats.ended_at_roundoff = true;
            self.record(state, (solved.exact, counts_before, gp, params.dt), None);
            return Ok(Progress::Done);
        }

        let backtracks = state.stats.backtracks;
        // Within a few thousand ulps of the energy, a predicted decrease is round-off.
        let resolved = -gp > 1e4 * ROUNDOFF * scale;
        // Only a projected Hessian's step may expand: an exact one's is the minimiser of its
        // own quadratic model (a kink that model misses is the piecewise model's business).
        let may_expand = !solved.exact && !modelled && resolved;
        let search = self.line_search(state, obj, x, problem, (pmax, gp), may_expand);
        let halvings = state.stats.backtracks - backtracks;
        self.record(
            state,
            (solved.exact, counts_before, gp, params.dt),
            Some((&search, halvings)),
        );
        let within_roundoff = at_targets && !resolved;
        // A backtracked step that leaves the energy exactly unchanged was accepted only
        // because Armijo's bound rounds to `e` (α·gᵀp vanishes next to it): no progress.
        // With a predicted decrease within round-off the iterate is stationary to working
        // precision — stop instead of repeating the zero step until the iteration limit.
        // (Full steps with an unchanged energy are normal near a minimum, where the energy
        // change is below round-off but x still improves.)
        if search.accepted == Some(state.e) && search.alpha < 1.0 && within_roundoff {
            state.stats.roundoff_stops += 1;
            state.stats.ended_at_roundoff = true;
            return Ok(Progress::Done);
        }
        // (A model's matrix is not the Hessian the next iteration would reuse.)
        state.reuse.after_line_search(
            search.accepted.is_some() && search.alpha == 1.0 && !modelled,
            solved.exact,
        );
        match search.accepted {
            Some(et) => {
                x.copy_from_slice(&self.trial);
                if search.alpha >= 1.0 {
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
                state.stats.ended_at_roundoff = true;
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

    /// The direction solved again with the objective's piecewise model
    /// ([`Objective::begin_model`], already begun; ended here): a fresh matrix (no reuse, no
    /// CG preconditioned with a factor of the true Hessian, which the model's stiff blocks
    /// would defeat) and the model's gradient. `Some` with the model's direction if it descends
    /// the true energy (`gᵀp < 0` with the true gradient, which `g` holds again on return);
    /// `None`, the first direction restored, if not, or if the model's matrix could not be
    /// solved.
    fn model_direction(
        &mut self,
        state: &mut SolveState,
        obj: &mut impl Objective,
        x: &[f64],
        problem: &Problem,
    ) -> Result<Option<(Solved, Direction)>, Failure> {
        state.stats.model_directions += 1;
        // The true gradient and the first direction, kept for after the model.
        let (g_true, first_rhs) = (&mut self.model_keep.0, &mut self.model_keep.1);
        g_true.clone_from(&self.g);
        first_rhs.clone_from(&self.rhs);
        let cg = state.cg.active(problem.params.linear);
        let solved = self
            .matrix_and_gradient(state, obj, x, problem, cg.is_some(), true)
            .and_then(|matrix| match cg {
                Some(cg) => self.solve_with_cg(state, obj, x, problem, matrix, cg),
                None => self.solve_with_cholesky(state, obj, x, problem, matrix),
            });
        obj.end_model();
        std::mem::swap(&mut self.g, &mut self.model_keep.0);
        match solved {
            Ok(solved) => {
                let direction = self.direction(problem.fixed)?;
                if direction.gp < 0.0 {
                    state.stats.model_directions_taken += 1;
                    return Ok(Some((solved, direction)));
                }
            }
            // The model's matrix could not be solved: Newton's direction stands, and no factor
            // of this iteration is held.
            Err(_) => self.factor_ready = false,
        }
        self.rhs.clone_from(&self.model_keep.1);
        self.direction(problem.fixed).map(|_| None)
    }

    /// With [`Newton::record_iterations`], the iteration's [`IterationRecord`] (`search`:
    /// the line search and its halvings; `None` if the iteration stopped before one).
    fn record(
        &self,
        state: &mut SolveState,
        (exact, (reused_before, taken_before), gp, dt): (bool, (usize, usize), f64, f64),
        search: Option<(&LineSearch, usize)>,
    ) {
        if !self.record {
            return;
        }
        let (largest, size) = self.p.iter().enumerate().fold((0, 0.0), |(i, m), (j, v)| {
            if v.abs() > m { (j, v.abs()) } else { (i, m) }
        });
        let (bound, alpha, backtracks, change) = match search {
            Some((s, halvings)) => (
                (s.bound.alpha, s.bound.limit),
                if s.accepted.is_some() { s.alpha } else { 0.0 },
                halvings,
                s.accepted.map_or(f64::NAN, |e| e - state.e),
            ),
            None => ((f64::NAN, None), 0.0, 0, f64::NAN),
        };
        state.stats.trace.push(IterationRecord {
            iteration: state.stats.iterations,
            increment: state.stats.final_residual,
            largest: (largest, size / dt),
            exact,
            reused: state.stats.reused_hessians > reused_before,
            modelled: state.stats.model_directions_taken > taken_before,
            predicted: gp,
            bound,
            alpha,
            backtracks,
            change,
        });
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
        fresh: bool,
    ) -> Result<Matrix, Failure> {
        let t = Instant::now();
        if !fresh {
            obj.begin_iteration(x);
        }
        let nf = self.free_dofs.len();
        // Reuse the last matrix? The gradient comes first, then the objective says whether
        // the Hessian's terms are still those of that matrix.
        let mut have_gradient = false;
        let mut reuse = None;
        if let Some(held_exact) = state
            .reuse
            .candidate(state.stats.final_residual, problem, x)
            .filter(|_| !fresh)
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
        // CG preconditioned with the last factor, once this solve has a factor: for a
        // projected Hessian, and for an exact one, which CG rejects if it meets non-positive
        // curvature (then its factorisation decides).
        let last_factor = match problem.params.linear {
            linear @ (LinearSolver::LastFactorCg {
                rtol,
                max_iterations,
            }
            | LinearSolver::Auto {
                rtol,
                max_iterations,
            }) if reuse.is_none()
                && !cg
                && !fresh
                && self.factor_ready
                && nf > 0
                && (matches!(linear, LinearSolver::LastFactorCg { .. })
                    || self.lin.chol.is_large()) =>
            {
                Some((rtol, max_iterations))
            }
            _ => None,
        };
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
            let only_build = cg || last_factor.is_some();
            let mut factor = move || {
                if only_build {
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
        if factorized && !cg && last_factor.is_none() {
            self.factor_ready = true;
        }
        Ok(Matrix {
            exact,
            factorized,
            last_factor,
        })
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
            ..
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
            self.solve_factorised()?;
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
        let Matrix {
            exact,
            factorized,
            last_factor,
        } = matrix;
        let mut factorized = factorized;
        if let Some((rtol, max_iterations)) = last_factor {
            self.prescribed_part(problem.fixed, problem.target, x);
            if self.last_factor_cg(state, rtol, max_iterations) {
                // CG met only positive curvature: a descent direction of the exact model too.
                if exact {
                    state.exact.accepted(&mut state.stats);
                }
                return Ok(Solved {
                    exact,
                    loose: false,
                });
            }
            // Factorise this matrix (its pattern analysed first) and solve directly; `rhs`
            // still holds the right-hand side. An exact one may turn out indefinite: then the
            // projected one is factorised below.
            state.stats.pcg_fallbacks += 1;
            self.lin.ensure_analysed().map_err(Failure::Linear)?;
            factorized = if exact {
                self.lin.chol.try_factorize(&mut self.lin.csc)
            } else {
                self.lin.chol.factorize(&mut self.lin.csc).map(|()| true)
            }
            .map_err(Failure::Linear)?;
        } else if factorized {
            self.prescribed_part(problem.fixed, problem.target, x);
        }
        // (A single-precision factor's refined solve may still find the matrix indefinite.)
        if factorized && self.solve_factorised()? {
            self.factor_ready = true;
            if exact {
                state.exact.accepted(&mut state.stats);
            }
            return Ok(Solved {
                exact,
                loose: false,
            });
        }
        // The exact Hessian is indefinite (a projected one is factorised with shifts, or its
        // failure returned): the projected one, factorised with diagonal shifts.
        self.factor_ready = false;
        if exact {
            state.exact.rejected(&mut state.stats);
        }
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
        self.factor_ready = true;
        self.prescribed_part(problem.fixed, problem.target, x);
        self.solve_factorised()?;
        Ok(Solved {
            exact: false,
            loose: false,
        })
    }

    /// `rhs` solved in place with the matrix just factorised (allowed diagonal shifts, or
    /// tried without): a triangular solve, or a single-precision factor's solve refined to
    /// double precision ([`Cholesky::solve_refined`]). `false` if the refinement found a
    /// tried matrix not positive definite after all (`rhs` unchanged).
    fn solve_factorised(&mut self) -> Result<bool, Failure> {
        if self.free_dofs.is_empty() {
            return Ok(true);
        }
        let Linear { chol, csc, .. } = &mut self.lin;
        chol.solve_refined(csc, &mut self.rhs, &mut self.pcg, &mut self.sol)
            .map_err(Failure::Linear)
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

    /// [`LinearSolver::LastFactorCg`]: `rhs` solved with the built matrix by CG preconditioned
    /// with the last factorisation ([`Pcg::solve_preconditioned`]); the solution replaces
    /// `rhs` if CG converged (`false`, `rhs` unchanged, if not). Needing more than half of
    /// `max_iterations` marks the factor stale: the next iteration factorises.
    fn last_factor_cg(&mut self, state: &mut SolveState, rtol: f64, max_iterations: usize) -> bool {
        let t = Instant::now();
        let Linear { chol, csc, .. } = &mut self.lin;
        let outcome = self.pcg.solve_preconditioned(
            csc,
            &self.rhs,
            &mut self.sol,
            (rtol, max_iterations),
            &mut |z| chol.solve_in_place(z),
        );
        let converged = outcome.converged();
        if converged {
            self.rhs.copy_from_slice(&self.sol);
        }
        if 2 * outcome.iterations() > max_iterations || !converged {
            self.factor_ready = false;
        }
        state.stats.pcg_iterations += outcome.iterations();
        state.stats.pcg_s += t.elapsed().as_secs_f64();
        converged
    }

    /// Statistics of the linear algebra since this solver was created.
    pub fn linear_stats(&self) -> crate::linear::LinearStats {
        self.lin.chol.stats
    }
}

impl Linear {
    /// The Hessian triplets into the free-DOF CSC (no analysis); whether the pattern changed.
    fn build(&mut self, triplets: &Triplets, free: &[u32], nf: usize) -> bool {
        let t = Instant::now();
        let changed = self.csc.assemble(triplets, free, nf);
        self.csc_s += t.elapsed().as_secs_f64();
        self.unanalysed |= changed;
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
            self.analysed_dof_of.clear();
            self.analysed_dof_of.extend_from_slice(self.chol.dof_map());
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
        self.build(triplets, free, nf);
        // The pattern may have changed in a build that was not factorised (a CG iteration)
        // even if this one equals it.
        if std::mem::take(&mut self.unanalysed) || !self.chol.is_analyzed() {
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
