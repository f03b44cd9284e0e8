//! Errors of a solve, each with the statistics gathered so far.

use crate::SolveStats;
use crate::linear::LinearError;

/// Why a solve failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// The problem description is inconsistent.
    #[error("bad problem: {0}")]
    BadProblem(String),
    /// The line search could not decrease the energy with a step above the floor.
    #[error("line search stalled after {} Newton iterations (‖p‖∞/Δt = {:e}, energy {:e})", stats.iterations, stats.final_residual, stats.final_energy)]
    LineSearchStalled {
        /// Statistics up to the failure.
        stats: Box<SolveStats>,
    },
    /// The iteration limit was reached before the tolerance.
    #[error("Newton did not converge in {} iterations (‖p‖∞/Δt = {:e})", stats.iterations, stats.final_residual)]
    IterationLimit {
        /// Statistics up to the failure.
        stats: Box<SolveStats>,
    },
    /// An energy, gradient or direction is NaN or infinite.
    #[error("non-finite {what} after {} Newton iterations", stats.iterations)]
    NonFinite {
        /// What was non-finite.
        what: &'static str,
        /// Statistics up to the failure.
        stats: Box<SolveStats>,
    },
    /// The solve was stopped from outside ([`crate::Newton::set_interrupt`]) before an
    /// iteration.
    #[error("interrupted after {} Newton iterations", stats.iterations)]
    Interrupted {
        /// Statistics up to the interruption.
        stats: Box<SolveStats>,
    },
    /// The linear solve failed.
    #[error("linear solve failed after {} Newton iterations: {source}", stats.iterations)]
    Linear {
        /// The cause.
        source: LinearError,
        /// Statistics up to the failure.
        stats: Box<SolveStats>,
    },
}

impl SolveError {
    /// The statistics gathered before the failure (if the solve started).
    pub fn stats(&self) -> Option<&SolveStats> {
        match self {
            SolveError::BadProblem(_) => None,
            SolveError::LineSearchStalled { stats }
            | SolveError::IterationLimit { stats }
            | SolveError::Interrupted { stats }
            | SolveError::NonFinite { stats, .. }
            | SolveError::Linear { stats, .. } => Some(stats),
        }
    }
}
