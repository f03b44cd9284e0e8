//! # femp-solver
//!
//! Projected Newton for incremental potentials, knowing nothing physical:
//!
//! * [`Objective`] — what a model implements: energy, gradient, PSD Hessian as triplets, and
//!   the largest feasible step along a direction (the caller answers with CCD and det F).
//! * [`Newton`] — BFEMP Algorithm 2: Cholesky-solved Newton directions (faer, symbolic
//!   factorisation reused while the pattern holds, METIS nested dissection or AMD ordering,
//!   diagonal shifts on failure; with [`Precision::Mixed`] single-precision factors whose
//!   solves CG refines to double precision) or, with [`LinearSolver::Pcg`], Jacobi-preconditioned
//!   conjugate gradients ([`Pcg`]), or CG preconditioned with the last factor
//!   ([`LinearSolver::LastFactorCg`]); line search from `0.9 ×` the feasible step, Armijo
//!   backtracking, stop at `‖p‖_∞/Δt < ε_d`; statistics and timings for every solve; errors
//!   that carry them.
//! * [`Integrator`] — backward Euler and Newmark in incremental-potential form.
//! * [`Cholesky`] and [`UpperCsc`] for direct use (benchmarks, other solvers).
//!
//! ```
//! use femp_solver::{Newton, NewtonParams, Objective, Triplets};
//!
//! /// E(x) = ½ (x − 3)² + x⁴/4: one free DOF.
//! struct Quartic;
//! impl Objective for Quartic {
//!     fn num_dofs(&self) -> usize { 1 }
//!     fn energy(&mut self, x: &[f64]) -> f64 { 0.5 * (x[0] - 3.0).powi(2) + x[0].powi(4) / 4.0 }
//!     fn gradient(&mut self, x: &[f64], g: &mut [f64]) { g[0] = x[0] - 3.0 + x[0].powi(3); }
//!     fn hessian(&mut self, x: &[f64], h: &mut Triplets) { h.push(0, 0, 1.0 + 3.0 * x[0] * x[0]); }
//! }
//! let mut x = [0.0];
//! let stats = Newton::new().minimize(&mut Quartic, &mut x, &[false], &NewtonParams::default()).unwrap();
//! assert!((x[0] - 3.0 + x[0].powi(3)).abs() < 1e-9 && stats.iterations < 20);
//! ```

mod error;
mod integrator;
pub mod linear;
mod newton;
pub mod pcg;
mod sparse;

pub use error::SolveError;
pub use integrator::Integrator;
pub use linear::{
    Cholesky, FACTOR_TASKS, LinearError, LinearStats, Ordering, Precision, REFINE_ITERATIONS,
    REFINE_RTOL, Threads, large_factor,
};
pub use newton::{
    AnalysedPattern, Forcing, HessianStrategy, IterationRecord, LinearSolver, Newton, NewtonParams,
    Objective, SolveStats, StepBound, StepLimit,
};
pub use pcg::{Pcg, PcgOutcome};
pub use sparse::{Triplets, UpperCsc};
