//! The per-strategy policies of a solve: when to try the exact Hessian, whether CG is in use
//! and its forcing term, when to reuse the last matrix, and stagnation at round-off.

use super::params::{Forcing, LinearSolver, Problem, STAGNATION_ITERATIONS};
use super::stats::SolveStats;

/// [`HessianStrategy::ExactWhenDefinite`]: whether an iteration tries the exact Hessian. After
/// a first rejection the next iteration tries again, then the policy backs off (waits 1, 3,
/// 7, … iterations): a solve whose exact Hessian stays indefinite wastes O(log iterations)
/// tries. An objective without an exact Hessian is not asked again in the solve.
pub(super) struct ExactPolicy {
    pub(super) wanted: bool,
    pub(super) rejected_in_a_row: u32,
    /// Iterations to wait before the next try.
    pub(super) wait: u64,
}

impl ExactPolicy {
    /// Whether this iteration (which assembles a Hessian) tries the exact one.
    pub(super) fn try_now(&mut self) -> bool {
        let try_exact = self.wanted && self.wait == 0;
        self.wait = self.wait.saturating_sub(1);
        try_exact
    }

    /// The objective has no exact Hessian.
    pub(super) fn unavailable(&mut self) {
        self.wait = u64::MAX;
    }

    /// The exact Hessian was used.
    pub(super) fn accepted(&mut self, stats: &mut SolveStats) {
        stats.exact_iterations += 1;
        self.rejected_in_a_row = 0;
    }

    /// The exact Hessian was found indefinite (or CG could not solve with it).
    pub(super) fn rejected(&mut self, stats: &mut SolveStats) {
        stats.exact_rejections += 1;
        self.rejected_in_a_row += 1;
        self.wait = (1u64 << (self.rejected_in_a_row - 1).min(20)) - 1;
    }
}

/// [`LinearSolver::Pcg`]: whether CG is still in use in this solve, and the Eisenstat–Walker
/// state ([`Forcing::Adaptive`]).
pub(super) struct CgPolicy {
    /// CG gave up on a projected Hessian in this solve: the rest of it uses Cholesky.
    pub(super) gave_up: bool,
    /// The last free gradient norm and forcing term.
    pub(super) last_forcing: (f64, f64),
}

impl CgPolicy {
    /// CG's `(rtol, max_iterations, forcing)` if this iteration solves with it.
    pub(super) fn active(&self, linear: LinearSolver) -> Option<(f64, usize, Forcing)> {
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
pub(super) struct HessianReuse {
    pub(super) below: f64,
    /// `Some(exact)` when the matrix the last iteration solved with may be reused.
    pub(super) held: Option<bool>,
}

impl HessianReuse {
    /// The held matrix's `exact` flag if the iteration at `x`, after an increment
    /// `residual`, may reuse it (subject to the objective's word).
    pub(super) fn candidate(&self, residual: f64, problem: &Problem, x: &[f64]) -> Option<bool> {
        self.held
            .filter(|_| residual < self.below && problem.at_targets(x))
    }

    /// After the line search: hold the matrix if the full step was taken.
    pub(super) fn after_line_search(&mut self, full_step: bool, exact: bool) {
        self.held = (self.below > 0.0 && full_step).then_some(exact);
    }
}

/// Stagnation at round-off: consecutive round-off-flat iterations whose ‖p‖ does not halve.
pub(super) struct Stagnation {
    /// ‖p‖_∞ of the flat iterations in a row.
    pub(super) history: Vec<f64>,
}

impl Stagnation {
    /// Record an iteration (flat and not converged, with largest increment `pmax`); whether
    /// [`STAGNATION_ITERATIONS`] flat ones in a row have not halved ‖p‖.
    pub(super) fn stalled(&mut self, flat: bool, pmax: f64) -> bool {
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
pub(super) fn forcing_term(gnorm: f64, last: &mut (f64, f64), rtol: f64, max: f64) -> f64 {
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
