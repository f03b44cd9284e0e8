//! The state of one solve and what its phases hand each other: progress, failures, the
//! iteration's matrix, the direction and the line search's outcome.

use super::params::{HessianStrategy, NewtonParams};
use super::policy::{CgPolicy, ExactPolicy, HessianReuse, Stagnation};
use super::stats::SolveStats;
use crate::SolveError;
use crate::linear::{Cholesky, LinearError};

/// How an iteration ends: the solve goes on, or ends as converged or stationary.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Progress {
    Continue,
    Done,
}

/// Why a solve failed; [`SolveState::finish`] attaches the statistics.
pub(super) enum Failure {
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
pub(super) struct Matrix {
    pub(super) exact: bool,
    pub(super) factorized: bool,
    /// Built but not factorised: CG preconditioned with the last factor solves it to this
    /// `(rtol, max_iterations)` ([`crate::LinearSolver::LastFactorCg`]).
    pub(super) last_factor: Option<(f64, usize)>,
}

/// How the direction was solved: with the exact Hessian, and only loosely (CG whose
/// tightening did not converge — such a direction cannot end the solve).
pub(super) struct Solved {
    pub(super) exact: bool,
    pub(super) loose: bool,
}

/// The direction's largest entry and `gᵀp`.
pub(super) struct Direction {
    pub(super) pmax: f64,
    pub(super) gp: f64,
}

/// The line search's outcome: the energy at the accepted point (in `trial`), the step length
/// it ended with, and whether the full step was feasible.
pub(super) struct LineSearch {
    pub(super) accepted: Option<f64>,
    pub(super) alpha: f64,
    pub(super) full_step_feasible: bool,
    /// The objective's feasible-step bound along the direction.
    pub(super) bound: crate::StepBound,
}

/// The state of one solve: the energy, the statistics and one policy per strategy.
pub(super) struct SolveState {
    pub(super) stats: SolveStats,
    /// The factorisation's counters at the start (the solve reports differences).
    pub(super) lin0: crate::linear::LinearStats,
    /// Energy at the current iterate, and at the initial guess.
    pub(super) e: f64,
    pub(super) e0: f64,
    pub(super) exact: ExactPolicy,
    pub(super) cg: CgPolicy,
    pub(super) reuse: HessianReuse,
    pub(super) stagnation: Stagnation,
}

impl SolveState {
    pub(super) fn new(params: &NewtonParams, lin0: crate::linear::LinearStats) -> Self {
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
    pub(super) fn finish(
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
        s.refine_iterations = chol.stats.refine_iterations - lin0.refine_iterations;
        s.double_fallbacks = chol.stats.double_fallbacks - lin0.double_fallbacks;
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
