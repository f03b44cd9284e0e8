//! What a time step did, for either method: iterations, contact, solver statistics, timings
//! and contact forces.

use femp_solver::SolveStats;

/// What a step did.
#[derive(Clone, Debug, Default)]
pub struct StepReport {
    /// Newton iterations over all friction iterations (0 for augury).
    pub newton_iterations: usize,
    /// Friction (lagging) iterations (1 when there is no friction; 0 for augury).
    pub friction_iterations: usize,
    /// Iterations of the augury contact step (its velocity corrections; 0 for BFEMP).
    pub augury_iterations: usize,
    /// Whether the friction iteration converged (always true without friction).
    pub friction_converged: bool,
    /// The step's first solve failed with this error and the step was solved again with the
    /// other Hessian strategy (`solver.retry_other_projection`).
    pub retried: Option<String>,
    /// Active contact terms at the end of the step.
    pub contact_terms: usize,
    /// Smallest particle/vertex–boundary distance among active terms (∞ if none).
    pub min_distance: f64,
    /// Solver statistics summed over the step's solves.
    pub stats: SolveStats,
    /// Seconds in the transfers (stencils, P2G, G2P, advection).
    pub transfers_s: f64,
    /// Seconds setting up the minimisation (DOFs, predictor, boundaries, initial guess).
    pub setup_s: f64,
    /// Seconds in the objective's parts.
    pub objective: crate::objective::ObjectiveTiming,
    /// Per contact pair (`World::pairs` order) at the end of the step: `[barrier, friction]`
    /// force on the pair's points (x, y, z; z = 0 in 2D), the facets' body feeling the opposite
    /// (empty for augury).
    pub pair_forces: Vec<[[f64; 3]; 2]>,
}
