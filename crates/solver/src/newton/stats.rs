//! Statistics of a solve, and of consecutive solves.

use super::params::StepLimit;

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
    /// The (last) solve ended as stationary to working precision (a round-off stop), not at
    /// the tolerance.
    pub ended_at_roundoff: bool,
    /// Full Newton steps taken on the gradient's word: no step length decreased the energy,
    /// but the full step was feasible, raised the energy by at most 10× (`GRADIENT_STEP_RISE`)
    /// the predicted decrease `−gᵀp` and at least halved the free gradient — the energy's
    /// evaluation cannot resolve so small a change (its summands are far larger than their
    /// sum), the gradient can.
    pub gradient_steps: usize,
    /// Iterations that began by updating the objective's lagged terms
    /// ([`crate::Objective::update_lagged`]).
    pub lagged_updates: usize,
    /// Iterations whose direction was solved again with the objective's piecewise model
    /// ([`crate::Objective::begin_model`]).
    pub model_directions: usize,
    /// Of those, the iterations that took the model's direction (it descends the true energy).
    pub model_directions_taken: usize,
    /// Iterations whose line search took a step longer than the Newton step
    /// ([`crate::NewtonParams::max_expansion`]).
    pub expanded_steps: usize,
    /// Energy evaluations the expanding line search made beyond the full step.
    pub expansion_trials: usize,
    /// Symbolic analyses (sparsity pattern changes).
    pub symbolic_analyses: usize,
    /// Conjugate-gradient iterations (matrix products), with [`LinearSolver::Pcg`] or
    /// [`LinearSolver::LastFactorCg`].
    pub pcg_iterations: usize,
    /// Directions that CG did not deliver on a projected Hessian and Cholesky did.
    pub pcg_fallbacks: usize,
    /// Loosely solved directions ([`Forcing::Adaptive`]) solved again to `rtol` because they
    /// passed the convergence test.
    pub pcg_tightened: usize,
    /// Seconds in conjugate gradients.
    pub pcg_s: f64,
    /// [`crate::Precision::Mixed`]: CG iterations refining single-precision solves (their
    /// seconds are in `solve_s`).
    pub refine_iterations: usize,
    /// [`crate::Precision::Mixed`]: matrices factorised again in double precision.
    pub double_fallbacks: usize,
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
    /// One record per Newton iteration, oldest first, if the solver was asked for them
    /// ([`crate::Newton::record_iterations`]); empty otherwise. Summed statistics append the
    /// records of each solve: a solve's records start at `iteration` 1.
    pub trace: Vec<IterationRecord>,
}

/// What one Newton iteration did ([`crate::Newton::record_iterations`]): enough to see where
/// a solve's iterations go — which unknown carries the largest increment, how far the line
/// search cut the step and why, and whether the energy fell as the quadratic model predicted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IterationRecord {
    /// The iteration within its solve, from 1.
    pub iteration: usize,
    /// The convergence test's increment (velocity units, as the tolerance).
    pub increment: f64,
    /// The unknown with the largest `|p|` (free or prescribed) and that `|p| / Δt`.
    pub largest: (usize, f64),
    /// Whether the direction came from the exact (unprojected) Hessian.
    pub exact: bool,
    /// Whether the direction reused the previous iteration's matrix.
    pub reused: bool,
    /// Whether the direction was solved with the objective's piecewise model
    /// ([`crate::Objective::begin_model`]) and taken.
    pub modelled: bool,
    /// The directional derivative `gᵀp` (the quadratic model's predicted first-order change).
    pub predicted: f64,
    /// The objective's feasible-step bound along `p` and what set it (`None`: nothing within
    /// the full step); NaN if the iteration ended the solve before a line search (the
    /// increment stopped shrinking at round-off).
    pub bound: (f64, Option<StepLimit>),
    /// The step length taken (0 if the line search found none; above 1 if the step expanded,
    /// [`crate::NewtonParams::max_expansion`]).
    pub alpha: f64,
    /// Halvings in the line search.
    pub backtracks: usize,
    /// The energy change of the accepted step (NaN if none was accepted).
    pub change: f64,
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
        self.ended_at_roundoff = s.ended_at_roundoff;
        self.gradient_steps += s.gradient_steps;
        self.exact_iterations += s.exact_iterations;
        self.reused_hessians += s.reused_hessians;
        self.exact_rejections += s.exact_rejections;
        self.lagged_updates += s.lagged_updates;
        self.model_directions += s.model_directions;
        self.model_directions_taken += s.model_directions_taken;
        self.expanded_steps += s.expanded_steps;
        self.expansion_trials += s.expansion_trials;
        self.symbolic_analyses += s.symbolic_analyses;
        self.pcg_iterations += s.pcg_iterations;
        self.pcg_fallbacks += s.pcg_fallbacks;
        self.pcg_tightened += s.pcg_tightened;
        self.pcg_s += s.pcg_s;
        self.refine_iterations += s.refine_iterations;
        self.double_fallbacks += s.double_fallbacks;
        self.assembly_s += s.assembly_s;
        self.symbolic_s += s.symbolic_s;
        self.numeric_s += s.numeric_s;
        self.solve_s += s.solve_s;
        self.line_search_s += s.line_search_s;
        self.trace.extend_from_slice(&s.trace);
    }
}
