//! What a solve is given: the objective's interface, the strategies and parameters, and the
//! problem (fixed DOFs, targets).

use crate::Triplets;
use crate::linear::{Ordering, Precision, Threads};

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
    /// Called before every Newton iteration but a solve's first, with the last iteration's
    /// increment `‖p‖_∞ / dt` (velocity units, like the tolerance): an objective with lagged
    /// terms (lagged friction, say) may re-evaluate them at `x` and return `true` if it did —
    /// the solver then re-evaluates the energy at `x`, and the iteration's direction is that of
    /// the updated objective, so a solve converges only where the lagged terms are those of its
    /// own solution. Default: nothing, `false`.
    fn update_lagged(&mut self, _x: &[f64], _residual: f64) -> bool {
        false
    }
    /// The size of the Newton increment `p` at `x` for the convergence test, in the units of
    /// `p`: `None` (the default) takes `‖p‖_∞`. An objective whose unknowns are not all
    /// equally physical — background grid nodes that carry a particle's motion with a weight
    /// of 1e-13 — may measure what the increment moves instead. The solve stops when it is
    /// below `tolerance · dt`.
    fn increment_size(&mut self, _x: &[f64], _p: &[f64]) -> Option<f64> {
        None
    }
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
    /// A piecewise model for the iteration's direction. Called after the direction `p` at `x`
    /// is solved: an objective whose energy has kinks (a friction term's stick zone, say) may
    /// replace the Taylor model of the terms `p` would carry across their kink by the model of
    /// the piece the step is headed for, and return `true` if it did. Until
    /// [`Objective::end_model`], `gradient`, `hessian` and `exact_hessian` then give the
    /// model's (positive definite where the true Hessian is); the solver solves for a new
    /// direction with them and takes it if it descends the true energy. The line search, the
    /// convergence test and the next iteration use the true energy and gradient. Default:
    /// nothing, `false`.
    fn begin_model(&mut self, _x: &[f64], _p: &[f64]) -> bool {
        false
    }
    /// Back to the true derivatives after [`Objective::begin_model`] returned `true`.
    fn end_model(&mut self) {}
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
    /// Sparse Cholesky, reused as a preconditioner: a solve's first iteration factorises its
    /// Hessian; each later iteration with a projected Hessian solves its own (new) matrix by
    /// conjugate gradients preconditioned with the last factor, from `p = 0`, until the
    /// preconditioned residual `√(rᵀM⁻¹r)` has fallen by `rtol`. If CG has not got there in
    /// `max_iterations` products (or meets non-positive curvature), the matrix is factorised
    /// and solved directly; if it needed more than half of them, the next iteration
    /// factorises. The directions are Newton's to `rtol` — the iteration counts are those of
    /// [`LinearSolver::Cholesky`] — at the price of a triangular solve and a product per CG
    /// iteration instead of a factorisation: for large 3D systems, whose factorisations cost
    /// tens of triangular solves. Exact Hessians ([`HessianStrategy::ExactWhenDefinite`]) too:
    /// one on which CG meets non-positive curvature (or fails) is factorised, and rejected if
    /// that fails — CG that meets only positive curvature gives a descent direction.
    LastFactorCg {
        /// Relative reduction of the preconditioned residual.
        rtol: f64,
        /// Products before the matrix is factorised.
        max_iterations: usize,
    },
    /// [`LinearSolver::LastFactorCg`] while the analysed matrix's factor is a
    /// [`crate::large_factor`], [`LinearSolver::Cholesky`] otherwise (decided at each
    /// iteration from the current symbolic analysis, a property of the matrix alone). Measured
    /// (`docs/performance.md`): 1.3–1.5× per Newton iteration on 3D matrices with 5·10⁷ factor
    /// entries, where a factorisation costs tens of CG iterations; on small matrices a
    /// factorisation costs a few, and the exact directions keep the iteration counts.
    Auto {
        /// Relative reduction of the preconditioned residual.
        rtol: f64,
        /// Products before the matrix is factorised.
        max_iterations: usize,
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
    /// Arithmetic of the factorisation ([`crate::Precision::Mixed`]: single-precision factors,
    /// directions refined to double precision).
    pub precision: Precision,
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
    /// The longest step, in multiples of the Newton step, an expanding line search may take
    /// (`1`, the default: never beyond the Newton step). When a projected Hessian's full step
    /// (not the exact Hessian's, not a piecewise model's: [`HessianStrategy`],
    /// [`Objective::begin_model`]) is feasible, no prescribed DOF is still moving, and the step
    /// decreased the energy by at least 3/4 of the first-order prediction `−gᵀp` (the energy
    /// along `p` is much flatter than the quadratic model: a projected Hessian that keeps
    /// curvature the true energy does not have, so the solve would otherwise creep along `p`
    /// in equal steps), the search doubles the step (2, 4, … up to this factor and the
    /// feasible fraction of the objective's bound along the longest step) while the energy
    /// keeps falling and Armijo holds, and takes the lowest. Each doubling costs one energy
    /// evaluation; the bound one [`Objective::max_step`] call.
    pub max_expansion: f64,
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
            precision: Precision::Double,
            hessian: HessianStrategy::Projected,
            linear: LinearSolver::Cholesky,
            reuse_hessian_below: 0.0,
            max_expansion: 1.0,
        }
    }
}

/// Relative round-off of an energy evaluation: a predicted decrease `−gᵀp` below
/// `ROUNDOFF·|E|` (about five ulps) cannot be resolved by a line search.
pub const ROUNDOFF: f64 = 1e-15;

/// How far above the current energy, in units of the predicted decrease `−gᵀp`, a full
/// Newton step's energy may come out and still be taken when the gradient confirms it.
pub(super) const GRADIENT_STEP_RISE: f64 = 10.0;

/// A full step expands ([`NewtonParams::max_expansion`]) when its energy change is at most this
/// fraction of `gᵀp` (a decrease of at least 3/4 of the first-order prediction; on a quadratic
/// along `p`, the line minimum then lies at twice the step or beyond).
pub(super) const EXPAND_BELOW: f64 = 0.75;

/// Consecutive round-off-flat iterations without ‖p‖ halving that end a solve as stationary.
pub(super) const STAGNATION_ITERATIONS: usize = 4;

/// What a solve is asked: which DOFs are fixed, where they go, with which parameters.
pub(super) struct Problem<'a> {
    pub(super) fixed: &'a [bool],
    pub(super) target: &'a [f64],
    pub(super) params: &'a NewtonParams,
}

impl Problem<'_> {
    /// Whether every fixed DOF of `x` is at its target.
    pub(super) fn at_targets(&self, x: &[f64]) -> bool {
        (0..x.len()).all(|d| !self.fixed[d] || x[d] == self.target[d])
    }
}
