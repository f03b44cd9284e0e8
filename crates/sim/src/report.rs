//! What a time step did, for either method: iterations, contact, solver statistics, timings
//! and contact forces.

use femp_solver::SolveStats;

/// The unknown that carried a Newton iteration's largest increment
/// ([`StepReport::largest_increments`]), with its mass in the step's inertia.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Unknown {
    /// A grid node's velocity component (`axis`), `node` in the step's active-node order.
    GridNode {
        /// The node's index among the step's active nodes.
        node: usize,
        /// The component.
        axis: usize,
        /// The node's mass (kg; kg/m in 2D).
        mass: f64,
    },
    /// A FEM vertex's component (`body` among the scene's FEM bodies, in scene order).
    FemVertex {
        /// The FEM body.
        body: usize,
        /// The vertex.
        vertex: usize,
        /// The component.
        axis: usize,
        /// The vertex's lumped mass.
        mass: f64,
    },
}

/// What a step did.
#[derive(Clone, Debug)]
pub struct StepReport {
    /// Newton iterations over all friction iterations (0 for augury).
    pub newton_iterations: usize,
    /// Friction (lagging) iterations (1 when there is no friction; 0 for augury).
    pub friction_iterations: usize,
    /// Friction operators lagged at an extrapolated point (`solver.friction_extrapolation`).
    pub extrapolated_lags: usize,
    /// Friction operators lagged short of the solve's point: half way once the loop stopped
    /// contracting (`solver.friction_relaxation`), or by Aitken's factor ω < 1
    /// (`solver.friction_aitken`).
    pub relaxed_lags: usize,
    /// Iterations of the augury contact step (its velocity corrections; 0 for BFEMP).
    pub augury_iterations: usize,
    /// Whether the friction iteration converged (always true without friction).
    pub friction_converged: bool,
    /// The step's first solve failed and the step was solved again from its start: the
    /// failures and what solved it — direct solves after an inexact linear solve
    /// (`solver.linear` `"pcg"` or `"last_factor_cg"`), or the other Hessian strategy
    /// (`solver.retry_other_projection`).
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
    /// The straight paths of the step's points against the bodies they can touch
    /// ([`crate::sweep`]).
    pub swept: crate::sweep::SweptReport,
    /// Substeps the step was solved in (1 unless a point's straight path passed through a
    /// body: [`crate::World::step`]).
    pub substeps: usize,
    /// With [`crate::World::record_newton_iterations`]: per record of `stats.trace`, the
    /// unknown its largest increment sat on (empty otherwise).
    pub largest_increments: Vec<Unknown>,
}

impl StepReport {
    /// Add the work of another solve of (part of) this step: iterations, solver statistics,
    /// timings, and whether friction converged and a solve was retried.
    pub(crate) fn add_work(&mut self, o: &StepReport) {
        self.newton_iterations += o.newton_iterations;
        self.friction_iterations += o.friction_iterations;
        self.extrapolated_lags += o.extrapolated_lags;
        self.relaxed_lags += o.relaxed_lags;
        self.augury_iterations += o.augury_iterations;
        self.friction_converged &= o.friction_converged;
        if self.retried.is_none() {
            self.retried.clone_from(&o.retried);
        }
        self.stats += &o.stats;
        self.largest_increments
            .extend_from_slice(&o.largest_increments);
        self.transfers_s += o.transfers_s;
        self.setup_s += o.setup_s;
        self.objective.add(&o.objective);
    }

    /// Take the end-of-step state of `last` (its contact terms, smallest distance, forces and
    /// straight-path report).
    pub(crate) fn take_state(&mut self, last: StepReport) {
        self.contact_terms = last.contact_terms;
        self.min_distance = last.min_distance;
        self.pair_forces = last.pair_forces;
        self.swept = last.swept;
    }
}

impl Default for StepReport {
    fn default() -> Self {
        Self {
            newton_iterations: 0,
            friction_iterations: 0,
            extrapolated_lags: 0,
            relaxed_lags: 0,
            augury_iterations: 0,
            friction_converged: true,
            retried: None,
            contact_terms: 0,
            min_distance: f64::INFINITY,
            stats: SolveStats::default(),
            transfers_s: 0.0,
            setup_s: 0.0,
            objective: Default::default(),
            pair_forces: Vec::new(),
            swept: Default::default(),
            substeps: 1,
            largest_increments: Vec::new(),
        }
    }
}
