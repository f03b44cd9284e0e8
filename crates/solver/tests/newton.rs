//! Projected Newton on problems with known answers, the feasibility filter, Dirichlet DOFs,
//! the time integrators against their closed-form discrete solutions, and failing solves.

use femp_solver::{
    Cholesky, Forcing, HessianStrategy, Integrator, LinearSolver, Newton, NewtonParams, Objective,
    Ordering, Pcg, Precision, SolveError, SolveStats, StepBound, StepLimit, Threads, Triplets,
};
use nalgebra::{DMatrix, DVector};

/// `E = ½ xᵀAx − bᵀx`.
struct Quadratic {
    a: DMatrix<f64>,
    b: DVector<f64>,
}

impl Objective for Quadratic {
    fn num_dofs(&self) -> usize {
        self.b.len()
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        let x = DVector::from_column_slice(x);
        0.5 * x.dot(&(&self.a * &x)) - self.b.dot(&x)
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        let r = &self.a * DVector::from_column_slice(x) - &self.b;
        g.copy_from_slice(r.as_slice());
    }
    fn hessian(&mut self, _x: &[f64], h: &mut Triplets) {
        for i in 0..self.b.len() {
            for j in 0..self.b.len() {
                if self.a[(i, j)] != 0.0 {
                    h.push(i, j, self.a[(i, j)]);
                }
            }
        }
    }
}

fn spd(n: usize, seed: u64) -> DMatrix<f64> {
    let mut s = seed;
    let mut rnd = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let x = DMatrix::from_fn(n, n, |_, _| rnd());
    x.transpose() * x + DMatrix::identity(n, n)
}

#[test]
fn quadratic_converges_in_one_newton_step() {
    for (n, ord) in [
        (5, Ordering::Amd),
        (40, Ordering::NestedDissection { block: 2 }),
        (40, Ordering::Auto),
    ] {
        let a = spd(n, n as u64);
        let b = DVector::from_fn(n, |i, _| (i as f64).sin());
        let exact = a.clone().cholesky().unwrap().solve(&b);
        let mut obj = Quadratic { a, b };
        let mut x = vec![0.0; n];
        let params = NewtonParams {
            tolerance: 1e-10,
            ordering: ord,
            ..Default::default()
        };
        // One iteration takes the full step to the minimiser …
        let mut x1 = x.clone();
        let err = Newton::new()
            .minimize(
                &mut obj,
                &mut x1,
                &vec![false; n],
                &NewtonParams {
                    max_iterations: 1,
                    ..params
                },
            )
            .unwrap_err();
        assert!(matches!(err, SolveError::IterationLimit { .. }));
        assert!((DVector::from_column_slice(&x1) - &exact).amax() < 1e-10 * exact.amax());
        // … and the second finds a zero increment.
        let stats = Newton::new()
            .minimize(&mut obj, &mut x, &vec![false; n], &params)
            .unwrap();
        assert_eq!(stats.iterations, 2);
        assert_eq!(stats.backtracks, 0);
        assert_eq!(
            stats.symbolic_analyses, 1,
            "the pattern did not change: one symbolic analysis"
        );
        assert!((DVector::from_column_slice(&x) - &exact).amax() < 1e-10 * exact.amax());
    }
}

/// A chain of point masses joined by springs of rest length L, the top one fixed, hanging under
/// gravity in 2D. Springs are nonlinear in the positions (`½k(|Δx| − L)²`); each spring's
/// Hessian is projected to PSD in closed form.
struct Chain {
    n: usize,
    k: f64,
    rest: f64,
    m: Vec<f64>,
    g: f64,
}

impl Chain {
    /// `n` masses (0.05 + 0.01 j kg) joined by springs k = 250 N/m, L = 0.1 m, under g = 9.81.
    fn hanging(n: usize) -> Self {
        Chain {
            n,
            k: 250.0,
            rest: 0.1,
            m: (0..n).map(|j| 0.05 + 0.01 * j as f64).collect(),
            g: 9.81,
        }
    }

    fn spring(&self, x: &[f64], j: usize) -> ([f64; 2], f64) {
        let d = [x[2 * j] - x[2 * j - 2], x[2 * j + 1] - x[2 * j - 1]];
        (d, (d[0] * d[0] + d[1] * d[1]).sqrt())
    }
}

impl Chain {
    /// The spring's Hessian block `k (û ûᵀ + c (I − û ûᵀ))`, with `c = 1 − L/l` (exact; negative
    /// for a compressed spring) or `max(0, c)` (its PSD part).
    fn spring_hessian(&self, x: &[f64], h: &mut Triplets, exact: bool) {
        for j in 1..self.n {
            let (d, l) = self.spring(x, j);
            let u = [d[0] / l, d[1] / l];
            let c = if exact {
                1.0 - self.rest / l
            } else {
                (1.0 - self.rest / l).max(0.0)
            };
            let mut kb = [[0.0; 2]; 2];
            for a in 0..2 {
                for b in 0..2 {
                    let id = if a == b { 1.0 } else { 0.0 };
                    kb[a][b] = self.k * (u[a] * u[b] + c * (id - u[a] * u[b]));
                }
            }
            for (p, q, s) in [
                (j, j, 1.0),
                (j - 1, j - 1, 1.0),
                (j, j - 1, -1.0),
                (j - 1, j, -1.0),
            ] {
                for a in 0..2 {
                    for b in 0..2 {
                        h.push(2 * p + a, 2 * q + b, s * kb[a][b]);
                    }
                }
            }
        }
    }
}

impl Objective for Chain {
    fn num_dofs(&self) -> usize {
        2 * self.n
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        let mut e = 0.0;
        for j in 1..self.n {
            let (_, l) = self.spring(x, j);
            e += 0.5 * self.k * (l - self.rest).powi(2);
        }
        for j in 0..self.n {
            e += self.m[j] * self.g * x[2 * j + 1];
        }
        e
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        g.iter_mut().for_each(|v| *v = 0.0);
        for j in 1..self.n {
            let (d, l) = self.spring(x, j);
            let f = self.k * (l - self.rest) / l;
            for a in 0..2 {
                g[2 * j + a] += f * d[a];
                g[2 * j - 2 + a] -= f * d[a];
            }
        }
        for j in 0..self.n {
            g[2 * j + 1] += self.m[j] * self.g;
        }
    }
    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        // K = k (û ûᵀ + max(0, 1 − L/l)(I − û ûᵀ)): the PSD part of the spring Hessian.
        self.spring_hessian(x, h, false);
    }
    fn exact_hessian(&mut self, x: &[f64], h: &mut Triplets) -> bool {
        self.spring_hessian(x, h, true);
        true
    }
}

/// One implicit time step of the chain: `½ (m/Δt²) |x − x̂|² + E_chain(x)`.
struct ChainStep {
    chain: Chain,
    inertia: f64,
    x_hat: Vec<f64>,
}

impl Objective for ChainStep {
    fn num_dofs(&self) -> usize {
        self.chain.num_dofs()
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        let d2: f64 = x
            .iter()
            .zip(&self.x_hat)
            .map(|(a, b)| (a - b).powi(2))
            .sum();
        0.5 * self.inertia * d2 + self.chain.energy(x)
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        self.chain.gradient(x, g);
        for (k, gk) in g.iter_mut().enumerate() {
            *gk += self.inertia * (x[k] - self.x_hat[k]);
        }
    }
    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        h.extend((0..x.len()).map(|k| (k, k, self.inertia)));
        self.chain.hessian(x, h);
    }
    fn exact_hessian(&mut self, x: &[f64], h: &mut Triplets) -> bool {
        h.extend((0..x.len()).map(|k| (k, k, self.inertia)));
        self.chain.exact_hessian(x, h)
    }
}

/// A chain crumpled to a tenth of its rest length, every spring compressed: the projection
/// drops their (negative) transverse stiffness.
/// A solve to `‖p‖∞ < 1e-12` with the given Hessian strategy (which must succeed).
fn solve_tight(
    obj: &mut impl Objective,
    x: &mut [f64],
    fixed: &[bool],
    hessian: HessianStrategy,
) -> SolveStats {
    solve_with(obj, x, fixed, hessian, LinearSolver::Cholesky)
}

fn crumpled_chain(n: usize) -> (Chain, Vec<f64>, Vec<bool>) {
    let chain = Chain::hanging(n);
    let x: Vec<f64> = (0..n)
        .flat_map(|j| [0.01 * j as f64, 0.002 * (j % 2) as f64])
        .collect();
    let mut fixed = vec![false; 2 * n];
    fixed[0] = true;
    fixed[1] = true;
    (chain, x, fixed)
}

/// With a mass term that outweighs the compressed springs' negative stiffness the assembled
/// exact Hessian is positive definite: `ExactWhenDefinite` uses it in every iteration and
/// reaches the same minimiser as projected Newton in fewer iterations (Newton's quadratic
/// convergence, which the projection's extra curvature spoils). A wrong exact Hessian would not
/// converge this fast, or to the same point.
#[test]
fn exact_hessian_when_definite_converges_faster_to_the_same_step() {
    let n = 20;
    let solve = |hessian: HessianStrategy| {
        let (chain, x0, fixed) = crumpled_chain(n);
        let mut obj = ChainStep {
            chain,
            inertia: 2.0e4,
            x_hat: x0.iter().map(|v| v * 1.5).collect(),
        };
        let mut x = x0.clone();
        let stats = solve_tight(&mut obj, &mut x, &fixed, hessian);
        (x, stats)
    };
    let (xp, sp) = solve(HessianStrategy::Projected);
    let (xe, se) = solve(HessianStrategy::ExactWhenDefinite);
    assert_eq!(sp.exact_iterations, 0);
    assert_eq!(se.exact_rejections, 0, "{se:?}");
    assert_eq!(se.exact_iterations, se.iterations, "{se:?}");
    assert_eq!(se.regularizations, 0);
    for (a, b) in xp.iter().zip(&xe) {
        assert!((a - b).abs() < 1e-9, "{a} vs {b}");
    }
    // Measured: 5 against 15.
    assert!(
        2 * se.iterations <= sp.iterations,
        "exact {} vs projected {} iterations",
        se.iterations,
        sp.iterations
    );
}

/// Without a mass term the crumpled chain's exact Hessian is indefinite: the tries are rejected
/// (without diagonal shifts) and those iterations use the projected Hessian, with tries backing
/// off; once the chain hangs in tension the exact Hessian is positive definite and used again.
/// The solve reaches the static equilibrium.
#[test]
fn indefinite_exact_hessian_falls_back_to_the_projected_one() {
    let n = 12;
    let (mut chain, mut x, fixed) = crumpled_chain(n);
    let stats = solve_tight(
        &mut chain,
        &mut x,
        &fixed,
        HessianStrategy::ExactWhenDefinite,
    );
    assert!(stats.exact_rejections >= 1, "{stats:?}");
    assert!(stats.exact_iterations >= 1, "{stats:?}");
    // Back-off: after k rejections in a row the next try waits 2^(k−1) − 1 iterations, so some
    // iterations do not try (measured: 11 iterations, 3 rejected tries, 4 exact).
    let tries = stats.exact_rejections + stats.exact_iterations;
    assert!(tries < stats.iterations, "{stats:?}");
    assert_hangs_in_equilibrium(&chain, &x);
}

/// A solve to `‖p‖∞ < 1e-12` with the given Hessian strategy and linear solver.
fn solve_with(
    obj: &mut impl Objective,
    x: &mut [f64],
    fixed: &[bool],
    hessian: HessianStrategy,
    linear: LinearSolver,
) -> SolveStats {
    Newton::new()
        .minimize(
            obj,
            x,
            fixed,
            &NewtonParams {
                tolerance: 1e-12,
                hessian,
                linear,
                ..Default::default()
            },
        )
        .unwrap()
}

/// A mass-dominated implicit step (the crumpled chain with a large inertia term): CG
/// directions reach the Cholesky solve's minimiser with the same Newton iteration count, for
/// projected and exact Hessians, without one factorisation or analysis; every exact Hessian is
/// positive definite, and CG uses them all.
#[test]
fn pcg_directions_reach_the_cholesky_step() {
    let n = 20;
    for hessian in [
        HessianStrategy::Projected,
        HessianStrategy::ExactWhenDefinite,
    ] {
        let solve = |linear: LinearSolver| {
            let (chain, x0, fixed) = crumpled_chain(n);
            let mut obj = ChainStep {
                chain,
                inertia: 2.0e4,
                x_hat: x0.iter().map(|v| v * 1.5).collect(),
            };
            let mut x = x0.clone();
            let stats = solve_with(&mut obj, &mut x, &fixed, hessian, linear);
            (x, stats)
        };
        let (xc, sc) = solve(LinearSolver::Cholesky);
        let (xg, sg) = solve(LinearSolver::Pcg {
            rtol: 1e-10,
            max_iterations: 500,
            forcing: Forcing::Fixed,
        });
        for (a, b) in xc.iter().zip(&xg) {
            assert!((a - b).abs() < 1e-10, "{hessian:?}: {a} vs {b}");
        }
        assert_eq!(
            sg.iterations, sc.iterations,
            "{hessian:?}: {sg:?} vs {sc:?}"
        );
        assert_eq!(sg.exact_iterations, sc.exact_iterations, "{hessian:?}");
        assert!(sg.pcg_iterations >= sg.iterations, "{sg:?}");
        assert_eq!(sg.pcg_fallbacks, 0, "{sg:?}");
        assert_eq!((sg.symbolic_analyses, sg.numeric_s), (0, 0.0), "{sg:?}");
        assert_eq!((sc.pcg_iterations, sc.pcg_fallbacks), (0, 0), "{sc:?}");
    }
}

/// Without a mass term the crumpled chain's exact Hessian is indefinite: CG meets non-positive
/// curvature (or does not converge) and the exact Hessian is rejected; with too few CG
/// iterations allowed on the projected one, Cholesky delivers the direction. The solve reaches
/// the static equilibrium either way.
#[test]
fn pcg_rejects_indefinite_hessians_and_falls_back_to_cholesky() {
    let n = 12;
    let (mut chain, mut x, fixed) = crumpled_chain(n);
    let stats = solve_with(
        &mut chain,
        &mut x,
        &fixed,
        HessianStrategy::ExactWhenDefinite,
        LinearSolver::Pcg {
            rtol: 1e-10,
            max_iterations: 1000,
            forcing: Forcing::Fixed,
        },
    );
    assert!(stats.exact_rejections >= 1, "{stats:?}");
    assert!(stats.exact_iterations >= 1, "{stats:?}");
    assert_hangs_in_equilibrium(&chain, &x);

    let (mut chain, mut x, fixed) = crumpled_chain(n);
    let stats = solve_with(
        &mut chain,
        &mut x,
        &fixed,
        HessianStrategy::Projected,
        LinearSolver::Pcg {
            rtol: 1e-10,
            max_iterations: 2,
            forcing: Forcing::Fixed,
        },
    );
    // A 22-unknown chain without mass: two CG iterations do not reach 1e-10; after the first
    // fallback the solve stays with Cholesky.
    assert_eq!(stats.pcg_fallbacks, 1, "{stats:?}");
    assert_eq!(stats.pcg_iterations, 2, "{stats:?}");
    assert!(stats.iterations > 1, "{stats:?}");
    assert!(
        stats.symbolic_analyses >= 1 && stats.numeric_s > 0.0,
        "{stats:?}"
    );
    assert_hangs_in_equilibrium(&chain, &x);
}

/// An objective that counts its Hessian assemblies and answers
/// [`Objective::hessian_terms_unchanged`] with `unchanged`.
struct Counting<O> {
    inner: O,
    hessians: usize,
    unchanged: bool,
}

impl<O: Objective> Objective for Counting<O> {
    fn num_dofs(&self) -> usize {
        self.inner.num_dofs()
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        self.inner.energy(x)
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        self.inner.gradient(x, g)
    }
    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        self.hessians += 1;
        self.inner.hessian(x, h)
    }
    fn exact_hessian(&mut self, x: &[f64], h: &mut Triplets) -> bool {
        self.hessians += 1;
        self.inner.exact_hessian(x, h)
    }
    fn hessian_terms_unchanged(&mut self) -> bool {
        self.unchanged
    }
}

/// One implicit step of the crumpled chain (`inertia` the mass term), solved to `‖p‖∞ < 1e-12`
/// with Hessian reuse below `reuse` and the objective answering `unchanged`.
fn chain_step_solve(
    inertia: f64,
    hessian: HessianStrategy,
    linear: LinearSolver,
    reuse: f64,
    unchanged: bool,
) -> (Vec<f64>, SolveStats, usize, usize) {
    let (chain, x0, fixed) = crumpled_chain(20);
    let mut obj = Counting {
        inner: ChainStep {
            chain,
            inertia,
            x_hat: x0.iter().map(|v| v * 1.5).collect(),
        },
        hessians: 0,
        unchanged,
    };
    let mut x = x0.clone();
    let mut newton = Newton::new();
    let stats = newton
        .minimize(
            &mut obj,
            &mut x,
            &fixed,
            &NewtonParams {
                tolerance: 1e-12,
                hessian,
                linear,
                reuse_hessian_below: reuse,
                ..Default::default()
            },
        )
        .unwrap();
    (x, stats, obj.hessians, newton.linear_stats().numeric_count)
}

/// Reusing the last Hessian once the increments are small (a Shamanskii step): the same
/// minimiser to the tolerance, with Cholesky and CG, projected and exact Hessians, and one
/// Hessian assembly fewer per reusing iteration, at most one iteration more than Newton with a
/// fresh Hessian every time (the reuse keeps the convergence superlinear). A reused matrix that
/// were not the last one, or a convergence test on a stale direction, would miss the minimiser.
#[test]
fn reused_hessians_reach_the_same_step_with_fewer_assemblies() {
    let pcg = LinearSolver::Pcg {
        rtol: 1e-12,
        max_iterations: 500,
        forcing: Forcing::Fixed,
    };
    for linear in [LinearSolver::Cholesky, pcg] {
        for hessian in [
            HessianStrategy::Projected,
            HessianStrategy::ExactWhenDefinite,
        ] {
            let (xf, sf, hf, _) = chain_step_solve(2.0e4, hessian, linear, 0.0, true);
            let (xr, sr, hr, _) = chain_step_solve(2.0e4, hessian, linear, 1e-3, true);
            let what = format!("{linear:?} {hessian:?}: {sr:?} vs {sf:?}");
            for (a, b) in xf.iter().zip(&xr) {
                assert!((a - b).abs() < 1e-10, "{what}: {a} vs {b}");
            }
            assert_eq!((sf.reused_hessians, hf), (0, sf.iterations), "{what}");
            assert!(sr.reused_hessians >= 1, "{what}");
            assert_eq!(hr, sr.iterations - sr.reused_hessians, "{what}");
            assert!(hr < hf, "{what}");
            assert!(sr.iterations <= sf.iterations + 1, "{what}");
        }
    }
}

/// The objective decides: when its Hessian terms changed (e.g. a contact appeared) the matrix
/// is assembled anew whatever the increment.
#[test]
fn hessian_is_not_reused_when_its_terms_changed() {
    let (_, stats, hessians, _) = chain_step_solve(
        2.0e4,
        HessianStrategy::Projected,
        LinearSolver::Cholesky,
        1e-3,
        false,
    );
    assert_eq!(stats.reused_hessians, 0, "{stats:?}");
    assert_eq!(hessians, stats.iterations, "{stats:?}");
}

/// Eisenstat–Walker forcing: CG asks for less accuracy far from the minimiser and reaches the
/// same step with fewer matrix products in total; a loose direction small enough to end the
/// solve is solved again to `rtol`, so the convergence test means the same.
#[test]
fn adaptive_forcing_reaches_the_same_step_with_fewer_cg_products() {
    let solve = |forcing: Forcing| {
        chain_step_solve(
            2.0e4,
            HessianStrategy::ExactWhenDefinite,
            LinearSolver::Pcg {
                rtol: 1e-12,
                max_iterations: 500,
                forcing,
            },
            0.0,
            false,
        )
    };
    let (xf, sf, _, _) = solve(Forcing::Fixed);
    let (xa, sa, _, _) = solve(Forcing::Adaptive { max: 1e-2 });
    for (a, b) in xf.iter().zip(&xa) {
        assert!((a - b).abs() < 1e-10, "{a} vs {b}");
    }
    assert_eq!((sf.pcg_fallbacks, sa.pcg_fallbacks), (0, 0));
    // Measured: 38 against 53 products, 6 against 5 Newton iterations; the last loose
    // direction passed the convergence test and was solved again to `rtol`.
    assert!(
        sa.pcg_iterations < sf.pcg_iterations,
        "adaptive {sa:?} vs fixed {sf:?}"
    );
    assert!(
        sa.iterations <= sf.iterations + 1,
        "adaptive {sa:?} vs fixed {sf:?}"
    );
    assert_eq!((sf.pcg_tightened, sa.pcg_tightened), (0, 1), "{sa:?}");
}

#[test]
fn mass_spring_chain_reaches_its_static_equilibrium() {
    let n = 30;
    let mut chain = Chain::hanging(n);
    // Start stretched out sideways (far from equilibrium).
    let mut x: Vec<f64> = (0..n).flat_map(|j| [0.1 * j as f64, 0.0]).collect();
    let mut fixed = vec![false; 2 * n];
    fixed[0] = true;
    fixed[1] = true;
    let stats = solve_tight(&mut chain, &mut x, &fixed, HessianStrategy::Projected);
    assert_hangs_in_equilibrium(&chain, &x);
    assert_eq!((x[0], x[1]), (0.0, 0.0), "the fixed DOFs moved");
    assert!(stats.iterations > 2 && stats.iterations < 100, "{stats:?}");
}

/// Analytic static equilibrium of a hanging chain (top mass fixed at the origin): spring j
/// carries the weight below it, T_j = g Σ_{i ≥ j} m_i, so its length is L + T_j/k and the chain
/// hangs straight down.
fn assert_hangs_in_equilibrium(chain: &Chain, x: &[f64]) {
    let mut y = 0.0;
    for j in 1..chain.n {
        let t: f64 = chain.m[j..].iter().sum::<f64>() * chain.g;
        y -= chain.rest + t / chain.k;
        assert!(x[2 * j].abs() < 1e-9, "mass {j} x = {}", x[2 * j]);
        assert!(
            (x[2 * j + 1] - y).abs() < 1e-9,
            "mass {j}: y = {} vs {y}",
            x[2 * j + 1]
        );
    }
}

/// A particle falling onto a wall at x = 0 with a log barrier, one huge time step
/// (backward Euler, Δt = 1 s, v₀ = −100 m/s). The unsigned distance |x| makes the far side look
/// feasible: an unfiltered Newton step jumps through the wall; with the feasible-step bound it
/// never does.
struct Falling {
    m: f64,
    x_hat: f64,
    w: f64,
    kappa: f64,
    dhat: f64,
    filter: bool,
    min_x_evaluated: f64,
}

impl Falling {
    fn b(&self, d: f64) -> (f64, f64, f64) {
        if d >= self.dhat {
            return (0.0, 0.0, 0.0);
        }
        let r = d / self.dhat;
        let k = self.kappa;
        (
            -k * (r - 1.0).powi(2) * r.ln(),
            -k * (2.0 * (r - 1.0) * r.ln() / self.dhat + (r - 1.0).powi(2) / d),
            -k * (2.0 * r.ln() / (self.dhat * self.dhat) + 4.0 * (r - 1.0) / (self.dhat * d)
                - (r - 1.0).powi(2) / (d * d)),
        )
    }
}

impl Objective for Falling {
    fn num_dofs(&self) -> usize {
        1
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        self.min_x_evaluated = self.min_x_evaluated.min(x[0]);
        let d = x[0].abs();
        if d == 0.0 {
            return f64::INFINITY;
        }
        0.5 * self.m * (x[0] - self.x_hat).powi(2) + self.w * (self.m * 9.81 * x[0] + self.b(d).0)
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        let d = x[0].abs();
        g[0] =
            self.m * (x[0] - self.x_hat) + self.w * (self.m * 9.81 + self.b(d).1 * x[0].signum());
    }
    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        h.push(0, 0, self.m + self.w * self.b(x[0].abs()).2.max(0.0));
    }
    fn max_step(&mut self, x: &[f64], p: &[f64]) -> StepBound {
        if self.filter && p[0] < 0.0 && x[0] + p[0] <= 0.0 {
            // 1D "CCD": the step reaches the wall at α = x/(−p).
            StepBound {
                alpha: x[0] / -p[0],
                limit: Some(StepLimit::Ccd),
            }
        } else {
            StepBound::UNLIMITED
        }
    }
}

#[test]
fn barrier_with_feasibility_filter_never_crosses_at_huge_time_steps() {
    let dt = 1.0;
    let (x0, v0) = (1.0, -100.0);
    let make = |filter| Falling {
        m: 1.0,
        x_hat: x0 + dt * v0,
        w: Integrator::BackwardEuler.weight(dt),
        kappa: 1e3,
        dhat: 0.01,
        filter,
        min_x_evaluated: f64::INFINITY,
    };
    let params = NewtonParams {
        tolerance: 1e-9,
        dt,
        ..Default::default()
    };
    let mut filtered = make(true);
    let mut x = [x0];
    let stats = Newton::new()
        .minimize(&mut filtered, &mut x, &[false], &params)
        .unwrap();
    assert!(
        filtered.min_x_evaluated > 0.0,
        "an evaluated point crossed the wall: {}",
        filtered.min_x_evaluated
    );
    assert!(x[0] > 0.0 && x[0] < 0.01, "x = {}", x[0]);
    assert!(stats.limited_by_ccd > 0);
    // At rest on the wall the barrier balances the inertia of the step and gravity.
    let mut g = [0.0];
    filtered.gradient(&x, &mut g);
    assert!(g[0].abs() < 1e-6 * 100.0, "gradient {}", g[0]);

    // Without the filter the first Newton step jumps through the wall and the solve ends on the
    // wrong side.
    let mut unfiltered = make(false);
    let mut y = [x0];
    let _ = Newton::new().minimize(&mut unfiltered, &mut y, &[false], &params);
    assert!(unfiltered.min_x_evaluated < 0.0);
    assert!(y[0] < 0.0, "unfiltered run ended at {}", y[0]);
}

#[test]
fn dirichlet_dofs_keep_their_prescribed_values_exactly() {
    let n = 12;
    let mut obj = Quadratic {
        a: spd(n, 3),
        b: DVector::from_fn(n, |i, _| 1.0 + i as f64),
    };
    let mut x = vec![0.0; n];
    let mut fixed = vec![false; n];
    for (d, v) in [(0, 0.123456789), (5, -2.5), (11, 1e-7)] {
        fixed[d] = true;
        x[d] = v;
    }
    solve_tight(&mut obj, &mut x, &fixed, HessianStrategy::Projected);
    assert_eq!((x[0], x[5], x[11]), (0.123456789, -2.5, 1e-7));
    // The free DOFs satisfy the reduced equations.
    let mut g = vec![0.0; n];
    obj.gradient(&x, &mut g);
    for d in 0..n {
        if !fixed[d] {
            assert!(g[d].abs() < 1e-9, "free DOF {d}: residual {}", g[d]);
        }
    }
}

/// One step of a linear oscillator `m ẍ = −k x` in incremental-potential form.
struct Oscillator {
    m: f64,
    k: f64,
    x_hat: f64,
    w: f64,
}

impl Objective for Oscillator {
    fn num_dofs(&self) -> usize {
        1
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        0.5 * self.m * (x[0] - self.x_hat).powi(2) + self.w * 0.5 * self.k * x[0] * x[0]
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        g[0] = self.m * (x[0] - self.x_hat) + self.w * self.k * x[0];
    }
    fn hessian(&mut self, _x: &[f64], h: &mut Triplets) {
        h.push(0, 0, self.m + self.w * self.k);
    }
}

fn integrate(scheme: Integrator, steps: usize, dt: f64) -> Vec<(f64, f64)> {
    let (m, k) = (2.0, 50.0);
    let (mut x, mut v, mut a) = ([1.0], [0.0], [-k / m * 1.0]);
    if scheme == Integrator::BackwardEuler {
        a = [0.0];
    }
    let mut newton = Newton::new();
    let mut out = vec![(x[0], v[0])];
    let mut x_hat = [0.0];
    for _ in 0..steps {
        scheme.predictor(dt, &x, &v, &a, &mut x_hat);
        let mut obj = Oscillator {
            m,
            k,
            x_hat: x_hat[0],
            w: scheme.weight(dt),
        };
        let mut xn = x;
        newton
            .minimize(
                &mut obj,
                &mut xn,
                &[false],
                &NewtonParams {
                    tolerance: 1e-13,
                    dt,
                    ..Default::default()
                },
            )
            .unwrap();
        scheme.update(dt, &xn, &x_hat, &mut v, &mut a);
        x = xn;
        out.push((x[0], v[0]));
    }
    out
}

#[test]
fn integrators_match_their_closed_form_discrete_solutions() {
    let (m, k, dt, steps) = (2.0f64, 50.0f64, 0.05f64, 400);
    let w2 = k / m;
    let energy = |(x, v): (f64, f64)| 0.5 * m * v * v + 0.5 * k * x * x;
    // Newmark (average acceleration): the amplification matrix of
    // x' = x + Δt v + Δt²/4 (a + a'), v' = v + Δt/2 (a + a'), a = −ω² x.
    let c = 1.0 + w2 * dt * dt / 4.0;
    let nm = nalgebra::Matrix2::new(
        (1.0 - w2 * dt * dt / 4.0) / c,
        dt / c,
        -w2 * dt / c,
        (1.0 - w2 * dt * dt / 4.0) / c,
    );
    // Backward Euler: x' = (x + Δt v)/(1 + ω²Δt²), v' = (x' − x)/Δt.
    let d = 1.0 + w2 * dt * dt;
    let be = nalgebra::Matrix2::new(1.0 / d, dt / d, -w2 * dt / d, 1.0 / d);
    for (scheme, amp) in [(Integrator::Newmark, nm), (Integrator::BackwardEuler, be)] {
        let traj = integrate(scheme, steps, dt);
        let mut s = nalgebra::Vector2::new(1.0, 0.0);
        for (i, &(x, v)) in traj.iter().enumerate() {
            assert!(
                (x - s[0]).abs() < 1e-9 && (v - s[1]).abs() < 1e-8,
                "{scheme:?} step {i}: ({x}, {v}) vs ({}, {})",
                s[0],
                s[1]
            );
            s = amp * s;
        }
        let (e0, e1) = (energy(traj[0]), energy(*traj.last().unwrap()));
        match scheme {
            // Exactly conservative for linear problems (a Cayley transform): to solver tolerance.
            Integrator::Newmark => assert!(
                (e1 - e0).abs() < 1e-9 * e0,
                "Newmark energy drift {}",
                (e1 - e0) / e0
            ),
            // Dissipative: the energy decays like (1 + ω²Δt²)^(−n) for the oscillation.
            Integrator::BackwardEuler => assert!(e1 < 0.2 * e0, "backward Euler kept {}", e1 / e0),
        }
    }
}

/// Objectives that make the solve fail: NaN beyond a point the minimum lies behind, and an
/// energy unbounded below.
struct NanWall;
impl Objective for NanWall {
    fn num_dofs(&self) -> usize {
        1
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        if x[0] > 1.0 {
            f64::NAN
        } else {
            (x[0] - 3.0).powi(2)
        }
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        g[0] = 2.0 * (x[0] - 3.0);
    }
    fn hessian(&mut self, _x: &[f64], h: &mut Triplets) {
        h.push(0, 0, 2.0);
    }
}

struct Unbounded;
impl Objective for Unbounded {
    fn num_dofs(&self) -> usize {
        2
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        -x[0] - 2.0 * x[1]
    }
    fn gradient(&mut self, _x: &[f64], g: &mut [f64]) {
        g[0] = -1.0;
        g[1] = -2.0;
    }
    fn hessian(&mut self, _x: &[f64], h: &mut Triplets) {
        h.push(0, 0, 1.0);
        h.push(1, 1, 1.0);
    }
}

#[test]
fn failing_solves_return_errors_with_statistics() {
    let mut x = [0.5];
    let err = Newton::new()
        .minimize(&mut NanWall, &mut x, &[false], &NewtonParams::default())
        .unwrap_err();
    let stats = err.stats().unwrap();
    assert!(
        matches!(
            err,
            SolveError::LineSearchStalled { .. } | SolveError::IterationLimit { .. }
        ),
        "{err}"
    );
    assert!(stats.iterations >= 1 && stats.backtracks > 0);
    assert!(x[0] <= 1.0, "accepted a NaN point: {}", x[0]);
    assert!(err.to_string().contains("Newton"), "{err}");

    let mut x = [0.0, 0.0];
    let err = Newton::new()
        .minimize(
            &mut Unbounded,
            &mut x,
            &[false, false],
            &NewtonParams {
                max_iterations: 25,
                ..Default::default()
            },
        )
        .unwrap_err();
    match &err {
        SolveError::IterationLimit { stats } => {
            assert_eq!(stats.iterations, 25);
            assert!(stats.final_energy < -50.0);
        }
        other => panic!("expected the iteration limit, got {other}"),
    }
    assert!(
        err.to_string()
            .starts_with("Newton did not converge in 25 iterations")
    );

    // A non-finite starting energy and an inconsistent problem are reported, not panicked on.
    let mut x = [2.0];
    assert!(matches!(
        Newton::new()
            .minimize(&mut NanWall, &mut x, &[false], &NewtonParams::default())
            .unwrap_err(),
        SolveError::NonFinite { .. }
    ));
    assert!(matches!(
        Newton::new()
            .minimize(
                &mut NanWall,
                &mut [0.0, 0.0],
                &[false],
                &NewtonParams::default()
            )
            .unwrap_err(),
        SolveError::BadProblem(_)
    ));
}

/// A PSD but singular Hessian (a DOF with no stiffness and no mass) is factorised after a
/// diagonal shift, counted in the statistics.
struct Singular;
impl Objective for Singular {
    fn num_dofs(&self) -> usize {
        2
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        (x[0] - 1.0).powi(2)
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        g[0] = 2.0 * (x[0] - 1.0);
        g[1] = 0.0;
    }
    fn hessian(&mut self, _x: &[f64], h: &mut Triplets) {
        h.push(0, 0, 2.0);
        h.push(1, 1, 0.0);
    }
}

#[test]
fn singular_psd_hessians_are_regularised_and_counted() {
    let mut x = [0.0, 5.0];
    let stats = Newton::new()
        .minimize(
            &mut Singular,
            &mut x,
            &[false, false],
            &NewtonParams {
                threads: Threads::Seq,
                ..Default::default()
            },
        )
        .unwrap();
    assert!((x[0] - 1.0).abs() < 1e-9);
    assert_eq!(x[1], 5.0);
    assert!(stats.regularizations > 0);
}

/// Dirichlet DOFs driven to targets inside the Newton steps: `E = ½(x₁ − x₀)² + ½x₁²` with
/// `x₀` prescribed to move from 0 to 2 gives `x₁ = 1`, and `x₀` lands exactly on its target.
struct Coupled;
impl Objective for Coupled {
    fn num_dofs(&self) -> usize {
        2
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        0.5 * (x[1] - x[0]).powi(2) + 0.5 * x[1] * x[1]
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        g[0] = x[0] - x[1];
        g[1] = 2.0 * x[1] - x[0];
    }
    fn hessian(&mut self, _x: &[f64], h: &mut Triplets) {
        h.extend([(0, 0, 1.0), (0, 1, -1.0), (1, 0, -1.0), (1, 1, 2.0)]);
    }
    fn max_step(&mut self, x: &[f64], p: &[f64]) -> StepBound {
        // Something (say, a collision that later resolves) limits the very first step.
        if x[0] == 0.0 && p[0] > 0.0 {
            StepBound {
                alpha: 0.25,
                limit: Some(StepLimit::Ccd),
            }
        } else {
            StepBound::UNLIMITED
        }
    }
}

#[test]
fn prescribed_dofs_reach_their_targets_through_the_line_search() {
    let mut x = [0.0, 0.0];
    let stats = Newton::new()
        .minimize_to(
            &mut Coupled,
            &mut x,
            &[true, false],
            &[2.0, 0.0],
            &NewtonParams {
                tolerance: 1e-12,
                ..Default::default()
            },
        )
        .unwrap();
    assert_eq!(x[0], 2.0);
    assert!((x[1] - 1.0).abs() < 1e-12);
    // The first step was cut by the bound, so reaching the target took more than one step.
    assert!(
        stats.limited_by_ccd >= 1 && stats.iterations >= 3,
        "{stats:?}"
    );
}

/// [`Quadratic`] pushing only the upper triangle of its Hessian (what the `Objective::hessian`
/// contract allows, and what femp's grid Hessian does).
struct UpperOnly(Quadratic);

impl Objective for UpperOnly {
    fn num_dofs(&self) -> usize {
        self.0.num_dofs()
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        self.0.energy(x)
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        self.0.gradient(x, g)
    }
    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        let mut full = Triplets::default();
        self.0.hessian(x, &mut full);
        h.extend(full.iter().filter(|&(r, c, _)| r <= c));
    }
}

/// Moving prescribed DOFs on either side of free ones in the numbering: one Newton iteration
/// lands on the constrained minimiser, whether the Hessian comes in both triangles or only the
/// upper one — the prescribed motion's pull `−H_fd p_d` on a free DOF numbered after a fixed
/// one is then in the triplets only as (fixed, free) and must be mirrored.
#[test]
fn moving_prescribed_dofs_couple_through_an_upper_triangle_hessian() {
    let n = 12;
    let a = spd(n, 7);
    let b = DVector::from_fn(n, |i, _| (0.3 * i as f64).cos());
    let fixed: Vec<bool> = (0..n).map(|i| i % 4 == 1).collect();
    let target: Vec<f64> = (0..n)
        .map(|i| if fixed[i] { 0.5 + 0.1 * i as f64 } else { 0.0 })
        .collect();
    // The constrained minimiser: A_ff x_f = b_f − A_fd t_d.
    let free: Vec<usize> = (0..n).filter(|&i| !fixed[i]).collect();
    let afd = DMatrix::from_fn(free.len(), free.len(), |r, c| a[(free[r], free[c])]);
    let rhs = DVector::from_fn(free.len(), |r, _| {
        b[free[r]]
            - (0..n)
                .filter(|&d| fixed[d])
                .map(|d| a[(free[r], d)] * target[d])
                .sum::<f64>()
    });
    let xf = afd.cholesky().unwrap().solve(&rhs);
    let mut exact = target.clone();
    for (r, &d) in free.iter().enumerate() {
        exact[d] = xf[r];
    }
    let params = NewtonParams {
        tolerance: 1e-10,
        max_iterations: 1,
        ..Default::default()
    };
    // One iteration from zero; it ends at the iteration limit (convergence needs a second).
    fn one_step(
        obj: &mut impl Objective,
        fixed: &[bool],
        target: &[f64],
        params: &NewtonParams,
    ) -> Vec<f64> {
        let mut x = vec![0.0; fixed.len()];
        let err = Newton::new()
            .minimize_to(obj, &mut x, fixed, target, params)
            .unwrap_err();
        assert!(matches!(err, SolveError::IterationLimit { .. }), "{err}");
        x
    }
    let quadratic = || Quadratic {
        a: a.clone(),
        b: b.clone(),
    };
    let full = one_step(&mut quadratic(), &fixed, &target, &params);
    let upper = one_step(&mut UpperOnly(quadratic()), &fixed, &target, &params);
    let scale = exact.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for d in 0..n {
        assert!(
            (full[d] - exact[d]).abs() < 1e-10 * scale,
            "full, DOF {d}: {} vs {}",
            full[d],
            exact[d]
        );
        assert!(
            (upper[d] - exact[d]).abs() < 1e-10 * scale,
            "upper, DOF {d}: {} vs {}",
            upper[d],
            exact[d]
        );
    }
}

/// `E = 1 + ½ x₀² + ½ ε x₁²` whose `x₁` gradient carries a deterministic "round-off" term of
/// size `η`, as a grid node with a tiny mass does: `p₁ ≈ η/ε` never shrinks, yet no energy
/// change can be resolved.
struct NearNullMode {
    eps: f64,
    eta: f64,
    calls: u64,
}

impl Objective for NearNullMode {
    fn num_dofs(&self) -> usize {
        2
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        1.0 + 0.5 * x[0] * x[0] + 0.5 * self.eps * x[1] * x[1]
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        self.calls += 1;
        let noise = if self.calls.is_multiple_of(2) {
            1.0
        } else {
            -1.0
        };
        g[0] = x[0];
        g[1] = self.eps * x[1] + noise * self.eta;
    }
    fn hessian(&mut self, _x: &[f64], h: &mut Triplets) {
        h.push(0, 0, 1.0);
        h.push(1, 1, self.eps);
    }
}

#[test]
fn a_search_direction_lost_in_round_off_ends_the_solve_as_stationary() {
    let params = NewtonParams {
        tolerance: 1e-6,
        dt: 1.0,
        ..Default::default()
    };
    // p₁ = ∓η/ε = 10⁻² each iteration, −gᵀp ≈ η²/ε = 10⁻²⁴ ≪ 10⁻¹⁵ |E|.
    let mut obj = NearNullMode {
        eps: 1e-20,
        eta: 1e-22,
        calls: 0,
    };
    let mut x = vec![0.3, 0.0];
    let mut newton = Newton::new();
    newton.record_iterations(true);
    let stats = newton
        .minimize(&mut obj, &mut x, &[false, false], &params)
        .unwrap();
    assert_eq!(stats.roundoff_stops, 1, "{stats:?}");
    assert!(x[0].abs() < 1e-12, "x₀ = {}", x[0]);
    assert!(stats.iterations < 10, "{stats:?}");
    // The stopping iteration is recorded too, without a step (it ended before a line search).
    assert_eq!(stats.trace.len(), stats.iterations, "{stats:?}");
    let last = stats.trace.last().unwrap();
    assert!(
        last.bound.0.is_nan() && last.alpha == 0.0 && last.change.is_nan(),
        "{last:?}"
    );

    // The same mode with a resolvable energy (η/ε large but −gᵀp well above round-off) is
    // not cut short: it fails with the iteration limit instead.
    let mut obj = NearNullMode {
        eps: 1e-4,
        eta: 1e-6,
        calls: 0,
    };
    let mut x = vec![0.3, 0.0];
    let err = Newton::new()
        .minimize(
            &mut obj,
            &mut x,
            &[false, false],
            &NewtonParams {
                max_iterations: 20,
                ..params
            },
        )
        .unwrap_err();
    assert!(matches!(err, SolveError::IterationLimit { .. }), "{err:?}");
}

/// An energy flat to round-off around the iterate (the change of a small step is below one ulp
/// of it), a gradient whose predicted decrease is above the "flat" threshold but within a few
/// thousand ulps, and a step bound that forces α < 1: Armijo accepts the backtracked step only
/// because its bound rounds to E, and nothing changes.
struct FlatWithBound;

impl Objective for FlatWithBound {
    fn num_dofs(&self) -> usize {
        1
    }
    fn energy(&mut self, _x: &[f64]) -> f64 {
        1.0
    }
    fn gradient(&mut self, _x: &[f64], g: &mut [f64]) {
        g[0] = -1e-11;
    }
    fn hessian(&mut self, _x: &[f64], h: &mut Triplets) {
        h.push(0, 0, 1e-9);
    }
    fn max_step(&mut self, _x: &[f64], _p: &[f64]) -> StepBound {
        StepBound {
            alpha: 1e-6,
            limit: Some(StepLimit::Other),
        }
    }
}

#[test]
fn a_backtracked_step_that_leaves_the_energy_unchanged_ends_the_solve_as_stationary() {
    // p = 10⁻² every iteration, −gᵀp = 10⁻¹³: above 10⁻¹⁵ |E| (not "flat"), below 10⁻¹¹ |E|.
    // Before, each iteration accepted α ≈ 10⁻⁶ with E unchanged and ‖p‖ never shrank: the
    // solve ran into the iteration limit.
    let params = NewtonParams {
        tolerance: 1e-6,
        dt: 1.0,
        max_iterations: 50,
        ..Default::default()
    };
    let mut x = vec![0.0];
    let stats = Newton::new()
        .minimize(&mut FlatWithBound, &mut x, &[false], &params)
        .unwrap();
    assert_eq!(stats.roundoff_stops, 1, "{stats:?}");
    assert_eq!(stats.iterations, 1, "{stats:?}");
}

/// `E = Σ ¼(xᵢ − i)⁴ + ½(xᵢ − i)²` whose Hessian *pattern* changes between calls, like a
/// contact pair that is active in one Newton iteration and not the next: every other call adds
/// a (zero-valued) coupling of the first and last DOF, every third one of the second and the
/// second-to-last.
struct Toggling {
    n: usize,
    calls: usize,
}

impl Objective for Toggling {
    fn num_dofs(&self) -> usize {
        self.n
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        x.iter()
            .enumerate()
            .map(|(i, &v)| {
                let r = v - i as f64;
                0.25 * r.powi(4) + 0.5 * r * r
            })
            .sum()
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        for (i, &v) in x.iter().enumerate() {
            let r = v - i as f64;
            g[i] = r.powi(3) + r;
        }
    }
    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        for (i, &v) in x.iter().enumerate() {
            let r = v - i as f64;
            h.push(i, i, 3.0 * r * r + 1.0);
        }
        self.calls += 1;
        let n = self.n;
        if self.calls.is_multiple_of(2) {
            h.push(0, n - 1, 0.0);
            h.push(n - 1, 0, 0.0);
        }
        if self.calls.is_multiple_of(3) {
            h.push(1, n - 2, 0.0);
            h.push(n - 2, 1, 0.0);
        }
    }
}

/// A pattern that changes between the iterations of a solve is analysed at most once per new
/// coupling (the analysis covers the union of the patterns met so far), and a later solve whose
/// pattern the analysed one contains needs none — with the same minimiser.
#[test]
fn patterns_that_come_and_go_within_a_solve_share_one_analysis() {
    let n = 12;
    let mut obj = Toggling { n, calls: 0 };
    let mut newton = Newton::new();
    let params = NewtonParams {
        tolerance: 1e-12,
        ..Default::default()
    };
    let mut x = vec![5.0; n];
    let stats = newton
        .minimize(&mut obj, &mut x, &vec![false; n], &params)
        .unwrap();
    assert!(stats.iterations >= 6, "{} iterations", stats.iterations);
    // Calls 1 (diagonal), 2 (+ first coupling: union), 3 (+ second: union); from then on every
    // pattern is contained in the union of all three.
    assert_eq!(stats.symbolic_analyses, 3);
    for (i, v) in x.iter().enumerate() {
        assert!((v - i as f64).abs() < 1e-10, "x[{i}] = {v}");
    }
    // A second solve: every pattern is contained in the last analysis.
    let mut y = vec![-3.0; n];
    let stats = newton
        .minimize(&mut obj, &mut y, &vec![false; n], &params)
        .unwrap();
    assert!(stats.iterations >= 4);
    assert_eq!(stats.symbolic_analyses, 0);
    for (i, v) in y.iter().enumerate() {
        assert!((v - i as f64).abs() < 1e-10, "y[{i}] = {v}");
    }
}

/// A quadratic whose energy comes out `noise` too high everywhere but at the start `x0`, as
/// round-off does when the energy is a sum of terms far larger than the change a converging
/// Newton step makes (a spinning FEM ring's step stalled so: femp's scene, docs/solver.md).
/// The gradient is exact; the Hessian is `hess_scale` times the true one.
struct RoundedQuadratic {
    q: Quadratic,
    x0: Vec<f64>,
    noise: f64,
    hess_scale: f64,
}

impl Objective for RoundedQuadratic {
    fn num_dofs(&self) -> usize {
        self.q.num_dofs()
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        self.q.energy(x)
            + if x == self.x0.as_slice() {
                0.0
            } else {
                self.noise
            }
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        self.q.gradient(x, g);
    }
    fn hessian(&mut self, _x: &[f64], h: &mut Triplets) {
        let n = self.q.b.len();
        for i in 0..n {
            for j in i..n {
                h.push(i, j, self.hess_scale * self.q.a[(i, j)]);
            }
        }
    }
}

/// No step length lowers an energy that cannot resolve the decrease: the full Newton step is
/// taken on the gradient's word when its energy rises by less than 10× the predicted decrease
/// and the gradient at least halves there — and only then (a larger rise, or a direction from
/// a wrong Hessian that leaves the gradient large, still stalls).
#[test]
fn a_step_below_the_energys_round_off_is_taken_when_the_gradient_confirms_it() {
    let n = 6;
    let a = spd(n, 5);
    let b = DVector::from_fn(n, |i, _| (i as f64).cos());
    let exact = a.clone().cholesky().unwrap().solve(&b);
    let delta = DVector::from_fn(n, |i, _| 1e-3 * (1.0 + i as f64).sin());
    let x0: Vec<f64> = (&exact + &delta).as_slice().to_vec();
    let decrease = delta.dot(&(&a * &delta)); // −gᵀp of the exact Newton step
    let params = NewtonParams {
        tolerance: 1e-8,
        ..Default::default()
    };
    let solve = |noise: f64, hess_scale: f64| {
        let mut obj = RoundedQuadratic {
            q: Quadratic {
                a: a.clone(),
                b: b.clone(),
            },
            x0: x0.clone(),
            noise,
            hess_scale,
        };
        let mut x = x0.clone();
        let r = Newton::new().minimize(&mut obj, &mut x, &vec![false; n], &params);
        (r, x)
    };

    let (r, x) = solve(2.0 * decrease, 1.0);
    let stats = r.expect("the full step is confirmed by the gradient");
    assert_eq!(stats.gradient_steps, 1);
    assert!((DVector::from_column_slice(&x) - &exact).amax() < 1e-10 * exact.amax());

    let (r, _) = solve(20.0 * decrease, 1.0);
    assert!(
        matches!(r, Err(SolveError::LineSearchStalled { .. })),
        "a rise of 20× the predicted decrease is not round-off: {r:?}"
    );
    // Ten times the Hessian: p = −δ/10, the gradient keeps 90 % of its norm.
    let (r, _) = solve(0.2 * decrease, 10.0);
    assert!(
        matches!(r, Err(SolveError::LineSearchStalled { .. })),
        "a step the gradient does not confirm is not taken: {r:?}"
    );
}

/// `E = e^{−x}`: Newton steps by exactly 1 forever (`p = −E'/E'' = 1`), the energy falling every
/// time — a solve that never converges. It sets `flag` when its `at`-th iteration begins, as a
/// signal handler would in the middle of a step.
struct Runaway {
    flag: std::sync::Arc<std::sync::atomic::AtomicBool>,
    at: usize,
    iterations: usize,
}

impl Objective for Runaway {
    fn num_dofs(&self) -> usize {
        1
    }
    fn begin_iteration(&mut self, _x: &[f64]) {
        self.iterations += 1;
        if self.iterations == self.at {
            self.flag.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        (-x[0]).exp()
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        g[0] = -(-x[0]).exp();
    }
    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        h.push(0, 0, (-x[0]).exp());
    }
}

#[test]
fn an_interrupt_stops_a_solve_that_never_converges_between_iterations() {
    let params = NewtonParams {
        tolerance: 1e-6,
        max_iterations: 10_000,
        ..Default::default()
    };
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let mut obj = Runaway {
        flag: flag.clone(),
        at: 5,
        iterations: 0,
    };
    let mut newton = Newton::new();
    newton.set_interrupt(Some(flag.clone()));
    let mut x = vec![0.0];
    match newton.minimize(&mut obj, &mut x, &[false], &params) {
        Err(SolveError::Interrupted { stats }) => {
            // The flag went up during iteration 5; iteration 6 never started.
            assert_eq!(stats.iterations, 5);
            assert!((x[0] - 5.0).abs() < 1e-9, "x = {}", x[0]);
        }
        other => panic!("expected an interrupt, got {other:?}"),
    }
    // Without the flag the same solve runs into its iteration limit.
    let mut obj = Runaway {
        flag: std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false)),
        at: 5,
        iterations: 0,
    };
    let mut newton = Newton::new();
    let mut x = vec![0.0];
    let params = NewtonParams {
        max_iterations: 20,
        ..params
    };
    assert!(matches!(
        newton.minimize(&mut obj, &mut x, &[false], &params),
        Err(SolveError::IterationLimit { .. })
    ));
    // A flag set before the solve stops it before any iteration.
    let mut newton = Newton::new();
    newton.set_interrupt(Some(flag));
    let mut x = vec![0.0];
    assert!(matches!(
        newton.minimize(&mut obj, &mut x, &[false], &params),
        Err(SolveError::Interrupted { stats }) if stats.iterations == 0
    ));
}

#[path = "../benches/common/matrices.rs"]
mod matrices;

/// `Threads::Auto` factorises large matrices on rayon's threads in a fixed number of tasks: the
/// same bits on any number of threads, so a run's results do not depend on the machine's core
/// count. (`Threads::Rayon`, split by the pool's size, differs in the last bits between 2 and 3
/// threads — the reason `Auto` does not use it.)
#[test]
fn cholesky_gives_the_same_bits_on_any_number_of_threads() {
    // 3D elasticity, 3·16³ ≈ 12 000 unknowns: a factor with millions of entries and many
    // supernodes to share out (below `Auto`'s size rule, so the test asks for its split).
    let case = matrices::grid3(16);
    let on = |n: usize, threads: Threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
            .install(|| solved_bits(&case.csc, Ordering::Amd, threads))
    };
    let auto = Threads::Tasks(femp_solver::FACTOR_TASKS);
    let one = on(1, auto);
    for n in [2, 3, 4] {
        assert_eq!(one, on(n, auto), "{auto:?} on {n} threads");
    }
    // The check can fail: split by the pool's size, the bits change.
    assert_ne!(on(2, Threads::Rayon), on(3, Threads::Rayon));
}

/// The fixed right-hand side `b` the solve tests use.
fn fixed_rhs(n: usize) -> Vec<f64> {
    (0..n).map(|i| ((i * 7919) % 101) as f64 - 50.0).collect()
}

/// The bits of `a x = b` solved by a factorisation with `ordering` and `threads` (a fixed `b`).
fn solved_bits(a: &femp_solver::UpperCsc, ordering: Ordering, threads: Threads) -> Vec<u64> {
    let mut ch = femp_solver::Cholesky::new(ordering, threads);
    let mut a = a.clone();
    ch.analyze(&a).unwrap();
    ch.factorize(&mut a).unwrap();
    let mut x = fixed_rhs(a.n());
    ch.solve_in_place(&mut x);
    x.iter().map(|v| v.to_bits()).collect()
}

/// `a x = b` for the fixed `b` of [`solved_bits`], by a factorisation in `precision` and
/// [`Cholesky::solve_refined`] (or, `refine` false, one plain solve with the factor); the
/// solution and the solver's statistics. `None` if `a` was tried (`try_only`) and found not
/// positive definite.
fn solve_in(
    a: &femp_solver::UpperCsc,
    precision: Precision,
    try_only: bool,
    refine: bool,
) -> Option<(Vec<f64>, femp_solver::LinearStats)> {
    let mut ch = Cholesky::with_precision(Ordering::Amd, Threads::Seq, precision);
    let mut a = a.clone();
    ch.analyze(&a).unwrap();
    if try_only {
        if !ch.try_factorize(&mut a).unwrap() {
            return None;
        }
    } else {
        ch.factorize(&mut a).unwrap();
    }
    let mut x = fixed_rhs(a.n());
    if refine {
        let mut sol = vec![0.0; a.n()];
        if !ch
            .solve_refined(&mut a, &mut x, &mut Pcg::new(), &mut sol)
            .unwrap()
        {
            return None;
        }
    } else {
        ch.solve_in_place(&mut x);
    }
    Some((x, ch.stats))
}

fn relative_difference(a: &[f64], b: &[f64]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let n: f64 = b.iter().map(|y| y * y).sum();
    (d / n).sqrt()
}

/// [`Precision::Mixed`] on 3D elasticity (≈ 3 000 unknowns), and on the same matrix with its
/// unknowns scaled over eight orders of magnitude (as grid nodes of 10⁻⁵ the heaviest's mass
/// beside stiff FEM vertices): the single-precision factor alone solves to single precision
/// only (it is single: 10⁻⁹ < error), refined by a few CG iterations the solution is the
/// double-precision factor's to 10⁻⁹, without a double-precision factorisation.
#[test]
fn mixed_precision_solves_to_double_precision_with_a_single_precision_factor() {
    let case = matrices::grid3(10);
    let mut scaled = case.csc.clone();
    let (cp, ri) = (scaled.col_ptr().to_vec(), scaled.row_idx().to_vec());
    let s = |i: usize| 10f64.powf(4.0 * ((i * 37 % 17) as f64 / 8.0 - 1.0));
    for c in 0..scaled.n() {
        for k in cp[c]..cp[c + 1] {
            scaled.values_mut()[k] *= s(ri[k]) * s(c);
        }
    }
    for a in [&case.csc, &scaled] {
        let (xd, _) = solve_in(a, Precision::Double, false, true).unwrap();
        let (xs, plain) = solve_in(a, Precision::Mixed, false, false).unwrap();
        let single_error = relative_difference(&xs, &xd);
        assert!(
            single_error > 1e-9 && single_error < 1e-2,
            "{single_error:e}"
        );
        assert_eq!(plain.double_fallbacks, 0);
        let (xm, stats) = solve_in(a, Precision::Mixed, false, true).unwrap();
        let error = relative_difference(&xm, &xd);
        assert!(error < 1e-9, "{error:e}: {stats:?}");
        assert!((1..=6).contains(&stats.refine_iterations), "{stats:?}");
        assert_eq!(stats.double_fallbacks, 0, "{stats:?}");
        assert_eq!(stats.numeric_count, 1, "{stats:?}");
    }
}

/// Matrices single precision cannot solve are factorised again in double precision, and the
/// mixed solve then gives exactly the double-precision solve's bits: 2×2 blocks
/// `[[1, 1 − ε], [1 − ε, 1]]` (eigenvalues 2 − ε and ε) with ε = 10⁻⁹, which single precision
/// rounds to singular blocks (its factorisation fails); and with ε spread over
/// 3.5·10⁻⁸–2·10⁻⁷, whose single-precision pivots are off by up to half — CG refines those
/// solves (measured: 16 iterations), so the fallback is shown with a budget of 8. An indefinite
/// matrix tried without shifts is rejected in mixed precision as in double (after the
/// double-precision try), and a shifted factorisation fails alike.
#[test]
fn mixed_precision_falls_back_to_double_precision_where_single_cannot_solve() {
    let blocks = |eps: &dyn Fn(usize) -> f64| {
        let n = 2000;
        let mut t = Triplets::default();
        for b in 0..n / 2 {
            let (i, j) = (2 * b, 2 * b + 1);
            t.push(i, i, 1.0);
            t.push(j, j, 1.0);
            t.push(i, j, 1.0 - eps(b));
            t.push(j, i, 1.0 - eps(b));
        }
        let free: Vec<u32> = (0..n as u32).collect();
        let mut a = femp_solver::UpperCsc::default();
        a.assemble(&t, &free, n);
        a
    };
    let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    let singular = blocks(&|_| 1e-9);
    let (xd, _) = solve_in(&singular, Precision::Double, false, true).unwrap();
    let (xm, stats) = solve_in(&singular, Precision::Mixed, false, true).unwrap();
    assert_eq!(
        (
            stats.double_fallbacks,
            stats.numeric_count,
            stats.refine_iterations
        ),
        (1, 2, 0),
        "{stats:?}"
    );
    assert_eq!(bits(&xm), bits(&xd));

    let spread = blocks(&|b| 3.5e-8 * 10f64.powf(0.75 * ((b * 7919) % 1000) as f64 / 1000.0));
    let (xd, _) = solve_in(&spread, Precision::Double, false, true).unwrap();
    let (xm, stats) = solve_in(&spread, Precision::Mixed, false, true).unwrap();
    assert!(relative_difference(&xm, &xd) < 1e-9);
    assert!(
        stats.refine_iterations > 8 && stats.double_fallbacks == 0,
        "{stats:?}"
    );
    let mut ch = Cholesky::with_precision(Ordering::Amd, Threads::Seq, Precision::Mixed);
    ch.set_refinement(femp_solver::REFINE_RTOL, 8);
    let mut a = spread.clone();
    ch.analyze(&a).unwrap();
    ch.factorize(&mut a).unwrap();
    let mut x = fixed_rhs(a.n());
    let mut sol = vec![0.0; a.n()];
    assert!(
        ch.solve_refined(&mut a, &mut x, &mut Pcg::new(), &mut sol)
            .unwrap()
    );
    assert_eq!(
        (ch.stats.refine_iterations, ch.stats.double_fallbacks),
        (8, 1),
        "{:?}",
        ch.stats
    );
    assert_eq!(bits(&x), bits(&xd));

    // 3D elasticity with one diagonal entry made negative: indefinite.
    let mut bad = matrices::grid3(6).csc;
    let k = bad.diagonal_index(40).unwrap();
    bad.values_mut()[k] = -bad.values()[k];
    assert!(solve_in(&bad, Precision::Double, true, true).is_none());
    let mut ch = Cholesky::with_precision(Ordering::Amd, Threads::Seq, Precision::Mixed);
    let mut a = bad.clone();
    ch.analyze(&a).unwrap();
    assert!(!ch.try_factorize(&mut a).unwrap());
    assert_eq!(ch.stats.double_fallbacks, 1, "{:?}", ch.stats);
    // Both fail with the same diagonal shifts.
    let shifted = |precision| {
        let mut ch = Cholesky::with_precision(Ordering::Amd, Threads::Seq, precision);
        let mut a = bad.clone();
        ch.analyze(&a).unwrap();
        ch.factorize(&mut a).unwrap_err()
    };
    assert_eq!(shifted(Precision::Mixed), shifted(Precision::Double));
}

/// Newton with [`Precision::Mixed`] on the crumpled chain's implicit step — Cholesky and the
/// last factor as CG's preconditioner, projected and exact Hessians — and on the chain without
/// a mass term (indefinite exact Hessians, rejected): the double-precision solve's minimiser to
/// 10⁻¹⁰ and its iteration and rejection counts, every solve refined.
#[test]
fn mixed_precision_newton_takes_the_double_precision_steps() {
    let solve = |inertia: Option<f64>, hessian, linear, precision| {
        let (chain, x0, fixed) = crumpled_chain(if inertia.is_some() { 20 } else { 12 });
        let params = NewtonParams {
            tolerance: 1e-12,
            hessian,
            linear,
            precision,
            ..Default::default()
        };
        let mut x = x0.clone();
        let stats = match inertia {
            Some(inertia) => Newton::new().minimize(
                &mut ChainStep {
                    chain,
                    inertia,
                    x_hat: x0.iter().map(|v| v * 1.5).collect(),
                },
                &mut x,
                &fixed,
                &params,
            ),
            None => {
                let mut chain = chain;
                let stats = Newton::new().minimize(&mut chain, &mut x, &fixed, &params);
                assert_hangs_in_equilibrium(&chain, &x);
                stats
            }
        }
        .unwrap();
        (x, stats)
    };
    let last_factor = LinearSolver::LastFactorCg {
        rtol: 1e-10,
        max_iterations: 40,
    };
    for (inertia, hessian, linear) in [
        (
            Some(2.0e2),
            HessianStrategy::Projected,
            LinearSolver::Cholesky,
        ),
        (
            Some(2.0e4),
            HessianStrategy::ExactWhenDefinite,
            LinearSolver::Cholesky,
        ),
        (Some(2.0e2), HessianStrategy::Projected, last_factor),
        (
            None,
            HessianStrategy::ExactWhenDefinite,
            LinearSolver::Cholesky,
        ),
    ] {
        let (xd, sd) = solve(inertia, hessian, linear, Precision::Double);
        let (xm, sm) = solve(inertia, hessian, linear, Precision::Mixed);
        for (a, b) in xd.iter().zip(&xm) {
            assert!((a - b).abs() < 1e-10, "{a} vs {b}");
        }
        assert_eq!(sm.iterations, sd.iterations, "{sm:?} vs {sd:?}");
        assert_eq!(sm.exact_rejections, sd.exact_rejections, "{sm:?} vs {sd:?}");
        assert_eq!(sd.refine_iterations, 0);
        assert!(sm.refine_iterations > 0, "{sm:?}");
        if inertia.is_none() {
            assert!(sm.exact_rejections > 0, "{sm:?}");
        }
    }
}

fn record(iteration: usize) -> femp_solver::IterationRecord {
    femp_solver::IterationRecord {
        iteration,
        increment: 1.0,
        largest: (0, 1.0),
        exact: false,
        reused: false,
        modelled: false,
        predicted: -1.0,
        bound: (1.0, None),
        alpha: 1.0,
        backtracks: 0,
        change: -0.5,
    }
}

/// Statistics of consecutive solves add up field by field (the last solve's residual and energy
/// are kept). Every field is named, so a new one must be added here — and to `AddAssign`.
#[test]
fn solve_statistics_add_up() {
    let stats = |k: usize| femp_solver::SolveStats {
        iterations: k,
        backtracks: k,
        limited_by_ccd: k,
        limited_by_det_f: k,
        limited_by_other: k,
        final_residual: k as f64,
        final_energy: k as f64,
        regularizations: k,
        exact_iterations: k,
        reused_hessians: k,
        exact_rejections: k,
        roundoff_stops: k,
        ended_at_roundoff: k.is_multiple_of(2),
        gradient_steps: k,
        lagged_updates: k,
        model_directions: k,
        model_directions_taken: k,
        expanded_steps: k,
        expansion_trials: k,
        symbolic_analyses: k,
        pcg_iterations: k,
        pcg_fallbacks: k,
        pcg_tightened: k,
        pcg_s: k as f64,
        refine_iterations: k,
        double_fallbacks: k,
        assembly_s: k as f64,
        symbolic_s: k as f64,
        numeric_s: k as f64,
        solve_s: k as f64,
        line_search_s: k as f64,
        trace: (1..=k).map(record).collect(),
    };
    let mut acc = stats(1);
    acc += &stats(2);
    let mut expect = stats(3);
    (expect.final_residual, expect.final_energy) = (2.0, 2.0);
    expect.ended_at_roundoff = true;
    // The records are appended: the second solve's start again at iteration 1.
    expect.trace = vec![record(1), record(1), record(2)];
    assert_eq!(acc, expect);
}

/// `E(x) = ½‖x − c(y)‖²` with a lagged parameter `y` and `c(y) = a + B y` (‖B‖ < 1): solved
/// with `y` fixed the minimiser is `c(y)`; the fixed point `x = c(x)` is `(I − B)⁻¹ a`.
/// [`Objective::update_lagged`] sets `y = x` once the last increment is below `below`.
struct Lagged {
    a: DVector<f64>,
    b: DMatrix<f64>,
    y: DVector<f64>,
    below: f64,
    updates: usize,
}

impl Lagged {
    fn c(&self) -> DVector<f64> {
        &self.a + &self.b * &self.y
    }
}

impl Objective for Lagged {
    fn num_dofs(&self) -> usize {
        self.a.len()
    }
    fn update_lagged(&mut self, x: &[f64], residual: f64) -> bool {
        if residual < self.below {
            self.y = DVector::from_column_slice(x);
            self.updates += 1;
            return true;
        }
        false
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        0.5 * (DVector::from_column_slice(x) - self.c()).norm_squared()
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        g.copy_from_slice((DVector::from_column_slice(x) - self.c()).as_slice());
    }
    fn hessian(&mut self, _x: &[f64], h: &mut Triplets) {
        for i in 0..self.a.len() {
            h.push(i, i, 1.0);
        }
    }
}

/// Lagged terms updated inside the Newton iterations: the solve ends at the fixed point of the
/// lag (not at the minimiser for the first `y`), every update is counted, and the energy is
/// re-evaluated after one — a line search against the stale energy would accept no step once
/// `c(y)` jumps (the new objective is larger at `x` than the old one was).
#[test]
fn lagged_terms_updated_in_the_iterations_reach_their_fixed_point() {
    let n = 6;
    let a = DVector::from_fn(n, |i, _| 1.0 + i as f64);
    let b = DMatrix::from_fn(n, n, |i, j| if i == j { 0.5 } else { 0.05 });
    let fixed_point = (DMatrix::identity(n, n) - &b)
        .lu()
        .solve(&a)
        .expect("I − B is invertible");
    let params = NewtonParams {
        tolerance: 1e-9,
        dt: 1.0,
        ..Default::default()
    };
    // Without updates: the minimiser for y = 0, in two iterations (a quadratic).
    let mut frozen = Lagged {
        a: a.clone(),
        b: b.clone(),
        y: DVector::zeros(n),
        below: 0.0,
        updates: 0,
    };
    let mut x = vec![0.0; n];
    let stats = Newton::new()
        .minimize(&mut frozen, &mut x, &vec![false; n], &params)
        .unwrap();
    assert_eq!((stats.iterations, stats.lagged_updates), (2, 0));
    assert!((DVector::from_column_slice(&x) - &a).amax() < 1e-12);
    // With updates: each iteration is one step of the fixed-point map (contraction 0.75).
    let mut lagged = Lagged {
        below: f64::INFINITY,
        ..frozen
    };
    lagged.y = DVector::zeros(n);
    let mut x = vec![0.0; n];
    let stats = Newton::new()
        .minimize(&mut lagged, &mut x, &vec![false; n], &params)
        .unwrap();
    let err = (DVector::from_column_slice(&x) - &fixed_point).amax();
    assert!(err < 1e-8, "{err:e} from the fixed point");
    assert_eq!(stats.lagged_updates, lagged.updates);
    assert_eq!(stats.lagged_updates, stats.iterations - 1);
    assert!(stats.iterations > 20, "{stats:?}");
}

/// `E = √(1 + x₀²) + ½x₁²`: Newton's step on the first term overshoots (from `x₀ = 2`, `p₀ =
/// −x₀(1 + x₀²) = −10`), and a bound limits the first step to half of it.
struct Overshoot;
impl Objective for Overshoot {
    fn num_dofs(&self) -> usize {
        2
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        (1.0 + x[0] * x[0]).sqrt() + 0.5 * x[1] * x[1]
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        g[0] = x[0] / (1.0 + x[0] * x[0]).sqrt();
        g[1] = x[1];
    }
    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        h.extend([(0, 0, (1.0 + x[0] * x[0]).powf(-1.5)), (1, 1, 1.0)]);
    }
    fn max_step(&mut self, x: &[f64], _p: &[f64]) -> StepBound {
        if x[0] == 2.0 {
            StepBound {
                alpha: 0.5,
                limit: Some(StepLimit::Ccd),
            }
        } else {
            StepBound::UNLIMITED
        }
    }
}

#[test]
fn recorded_iterations_say_what_each_newton_iteration_did() {
    let params = NewtonParams {
        tolerance: 1e-10,
        dt: 0.5,
        ..Default::default()
    };
    let x0 = [2.0, 1.0];
    let mut plain = x0;
    let quiet = Newton::new()
        .minimize(&mut Overshoot, &mut plain, &[false; 2], &params)
        .unwrap();
    assert!(quiet.trace.is_empty(), "recorded without being asked");

    let mut newton = Newton::new();
    newton.record_iterations(true);
    let mut x = x0;
    let stats = newton
        .minimize(&mut Overshoot, &mut x, &[false; 2], &params)
        .unwrap();
    // Recording changes nothing about the solve.
    assert_eq!(x, plain);
    assert_eq!(stats.iterations, quiet.iterations);
    assert_eq!(stats.trace.len(), stats.iterations);
    for (i, r) in stats.trace.iter().enumerate() {
        assert_eq!(r.iteration, i + 1);
        // The default test measures ‖p‖∞ / Δt: the largest increment itself.
        assert_eq!(r.increment, r.largest.1, "{r:?}");
        assert!(!r.exact && !r.reused);
        if i + 1 < stats.iterations {
            assert!(r.alpha > 0.0 && r.alpha <= 1.0 && r.change <= 0.0, "{r:?}");
        }
    }
    // The last iteration passed the test; a step below round-off is not taken (α = 0, no
    // energy change) or is.
    let last = stats.trace.last().unwrap();
    assert!(last.increment < params.tolerance, "{last:?}");
    assert!(
        (last.alpha == 0.0 && last.change.is_nan()) || last.change <= 0.0,
        "{last:?}"
    );
    // The first iteration: p = (−10, −1), bounded at half of it by CCD, cut to 0.9 · 0.5 =
    // 0.45 (x₀ = −2.5: the energy rises) and once more to 0.225 (x₀ = −0.25).
    let first = stats.trace[0];
    assert_eq!(first.largest.0, 0);
    assert!((first.largest.1 - 10.0 / 0.5).abs() < 1e-12, "{first:?}");
    assert_eq!(first.bound, (0.5, Some(StepLimit::Ccd)));
    assert_eq!((first.alpha, first.backtracks), (0.225, 1));
    let predicted = -10.0 * 2.0 / 5f64.sqrt() - 1.0;
    assert!((first.predicted - predicted).abs() < 1e-12, "{first:?}");
    let e = |x: [f64; 2]| Overshoot.energy(&x);
    let after = [2.0 - 0.225 * 10.0, 1.0 - 0.225];
    assert!(
        (first.change - (e(after) - e(x0))).abs() < 1e-12,
        "{first:?}"
    );
    // The energy changes add up to the solve's.
    let total: f64 = stats
        .trace
        .iter()
        .filter(|r| r.alpha > 0.0)
        .map(|r| r.change)
        .sum();
    assert!((total - (e(x) - e(x0))).abs() < 1e-12);
    assert_eq!(last.bound, (1.0, None));
}

/// The crumpled chain's implicit step (inertia `inertia`) solved with Cholesky and with
/// [`LinearSolver::LastFactorCg`] (CG to 1e-10 within 40 products): the same minimiser to
/// 1e-10 and the same Newton iteration count, Cholesky factorising once an iteration. The CG
/// solve's statistics and factorisations, and Cholesky's factorisations.
fn last_factor_cg_against_cholesky(
    inertia: f64,
    hessian: HessianStrategy,
) -> (SolveStats, usize, usize) {
    let solve = |linear: LinearSolver| {
        let (x, stats, _, factorisations) = chain_step_solve(inertia, hessian, linear, 0.0, true);
        (x, stats, factorisations)
    };
    let (xc, sc, fc) = solve(LinearSolver::Cholesky);
    let (xg, sg, fg) = solve(LinearSolver::LastFactorCg {
        rtol: 1e-10,
        max_iterations: 40,
    });
    assert!(sc.iterations >= 3, "{sc:?}");
    for (a, b) in xc.iter().zip(&xg) {
        assert!((a - b).abs() < 1e-10, "{a} vs {b}");
    }
    assert_eq!(sg.iterations, sc.iterations, "{sg:?} vs {sc:?}");
    assert_eq!(fc, sc.iterations);
    (sg, fg, fc)
}

/// [`LinearSolver::LastFactorCg`] with exact Hessians (`ExactWhenDefinite`): on the
/// mass-dominated step every exact Hessian is positive definite and the later iterations solve
/// them by CG preconditioned with the first factor — the Cholesky solve's minimiser and
/// iteration count, every iteration exact, fewer factorisations. Without a mass term the exact
/// Hessian is indefinite: CG meets non-positive curvature or fails, the factorisation then
/// rejects it, the projected Hessian is used, and the solve still reaches the equilibrium with
/// exact Hessians once the chain hangs in tension.
#[test]
fn last_factor_cg_solves_exact_hessians_and_leaves_indefinite_ones_to_the_factorisation() {
    let (sg, fg, fc) = last_factor_cg_against_cholesky(2.0e4, HessianStrategy::ExactWhenDefinite);
    assert_eq!(sg.exact_iterations, sg.iterations, "{sg:?}");
    assert_eq!(sg.exact_rejections, 0, "{sg:?}");
    assert!(fg < fc && sg.pcg_iterations > 0, "{fg} of {fc}: {sg:?}");

    let n = 12;
    let (mut chain, mut x, fixed) = crumpled_chain(n);
    let mut newton = Newton::new();
    let stats = newton
        .minimize(
            &mut chain,
            &mut x,
            &fixed,
            &NewtonParams {
                tolerance: 1e-12,
                hessian: HessianStrategy::ExactWhenDefinite,
                linear: LinearSolver::LastFactorCg {
                    rtol: 1e-10,
                    max_iterations: 40,
                },
                ..Default::default()
            },
        )
        .unwrap();
    assert!(stats.exact_rejections >= 1, "{stats:?}");
    assert!(stats.exact_iterations >= 1, "{stats:?}");
    assert!(
        stats.pcg_fallbacks >= 1 && stats.pcg_iterations > 0,
        "{stats:?}"
    );
    assert_hangs_in_equilibrium(&chain, &x);
}

/// [`LinearSolver::LastFactorCg`] on the crumpled chain's implicit step (projected Hessians):
/// the first iteration factorises, the later ones solve their own Hessians by CG preconditioned
/// with that factor — the same minimiser and Newton iteration count as Cholesky, with fewer
/// factorisations. With one CG product allowed, CG cannot get there: every such direction is
/// factorised and solved directly (counted as a fallback), and the solve is Cholesky's.
#[test]
fn last_factor_cg_reaches_the_cholesky_step_with_fewer_factorisations() {
    let solve = |linear: LinearSolver| {
        let (x, stats, _, factorisations) =
            chain_step_solve(2.0e2, HessianStrategy::Projected, linear, 0.0, true);
        (x, stats, factorisations)
    };
    let (xc, _, fc) = solve(LinearSolver::Cholesky);
    let (sg, fg, _) = last_factor_cg_against_cholesky(2.0e2, HessianStrategy::Projected);
    // The first iteration's factorisation, fallbacks and refreshes after long CG solves: here
    // a tenth of Cholesky's.
    assert!(
        10 * fg <= fc && fg > sg.pcg_fallbacks && sg.pcg_iterations > 0,
        "{fg} of {fc}: {sg:?}"
    );

    let (x1, s1, f1) = solve(LinearSolver::LastFactorCg {
        rtol: 1e-14,
        max_iterations: 1,
    });
    for (a, b) in xc.iter().zip(&x1) {
        assert!((a - b).abs() < 1e-10, "{a} vs {b}");
    }
    assert_eq!(f1, fc, "{s1:?}");
    assert_eq!(s1.pcg_fallbacks, s1.iterations - 1, "{s1:?}");

    // Every DOF prescribed and on its way (no free unknown to solve for): the solve moves
    // them to their targets through the feasibility bound, with no CG.
    let mut x = [0.0, 0.0];
    let stats = Newton::new()
        .minimize_to(
            &mut Coupled,
            &mut x,
            &[true, true],
            &[2.0, 1.0],
            &NewtonParams {
                tolerance: 1e-12,
                linear: LinearSolver::LastFactorCg {
                    rtol: 1e-3,
                    max_iterations: 16,
                },
                ..Default::default()
            },
        )
        .unwrap();
    assert_eq!(x, [2.0, 1.0]);
    assert!(
        stats.iterations >= 2 && stats.pcg_iterations == 0,
        "{stats:?}"
    );
}

/// Nested-dissection orderings made on several threads at once are the ones made alone. METIS
/// draws from GKlib's random generator, one static state per process that every call re-seeds:
/// two calls at once (two `World`s stepping on two threads — `validate --jobs 2` lanes, Python
/// worlds) would interleave their draws and get other orderings, and so other bits.
#[test]
fn nested_dissection_is_the_same_made_on_several_threads_at_once() {
    let case = matrices::grid3(12);
    let solve = || {
        solved_bits(
            &case.csc,
            Ordering::NestedDissection { block: 3 },
            Threads::Seq,
        )
    };
    let alone = solve();
    let at_once: Vec<Vec<Vec<u64>>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..8)
            .map(|_| s.spawn(|| (0..6).map(|_| solve()).collect::<Vec<_>>()))
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let differing = at_once.iter().flatten().filter(|x| **x != alone).count();
    assert_eq!(
        differing, 0,
        "{differing} of 48 solves differ from the one made alone"
    );
}

/// `E = ½ xᵀAx − bᵀx + Σ xᵢ⁴/4` for `A` given by upper-triangle triplets: Newton takes a few
/// iterations, each with its own Hessian `A + diag(3xᵢ²)` on one pattern.
struct QuarticOn {
    a: Triplets,
    n: usize,
}

impl QuarticOn {
    fn b(d: usize) -> f64 {
        ((d * 7919) % 13) as f64 / 4.0 - 1.0
    }
}

impl Objective for QuarticOn {
    fn num_dofs(&self) -> usize {
        self.n
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        let quadratic: f64 = self
            .a
            .iter()
            .map(|(r, c, v)| {
                if r == c {
                    0.5 * v * x[r] * x[r]
                } else {
                    v * x[r] * x[c]
                }
            })
            .sum();
        quadratic
            + x.iter()
                .enumerate()
                .map(|(d, xd)| xd.powi(4) / 4.0 - Self::b(d) * xd)
                .sum::<f64>()
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        for (d, gd) in g.iter_mut().enumerate() {
            *gd = x[d].powi(3) - Self::b(d);
        }
        for (r, c, v) in self.a.iter() {
            g[r] += v * x[c];
            if r != c {
                g[c] += v * x[r];
            }
        }
    }
    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        h.append(&self.a);
        for (d, xd) in x.iter().enumerate() {
            h.push(d, d, 3.0 * xd * xd);
        }
    }
}

/// `Precision::Auto` and `LinearSolver::Auto` follow `large_factor`: on a small matrix they are
/// double-precision factorisations of every Hessian — bit for bit `Double` and `Cholesky` —,
/// on one the size of block_on_plate_3d's (8 000 nodes of the B-spline's 5³ stencil, 24 000
/// unknowns: a factor of more than 2·10⁷ entries) the factorisations are single precision,
/// refined to double, and after a solve's first factorisation Newton's directions come from CG
/// preconditioned with the last factor, to the same minimiser.
#[test]
fn auto_settings_take_single_precision_and_the_last_factor_only_for_large_factors() {
    let small = matrices::grid3(8);
    let auto = solve_in(&small.csc, Precision::Auto, false, true).unwrap();
    let double = solve_in(&small.csc, Precision::Double, false, true).unwrap();
    let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&auto.0), bits(&double.0));
    assert_eq!((auto.1.refine_iterations, auto.1.numeric_count), (0, 1));

    let minimise = |a: &Triplets, n: usize, linear: LinearSolver, precision: Precision| {
        let mut x = vec![0.0; n];
        let params = NewtonParams {
            linear,
            precision,
            tolerance: 1e-9,
            ..Default::default()
        };
        let stats = Newton::new()
            .minimize(
                &mut QuarticOn { a: a.clone(), n },
                &mut x,
                &vec![false; n],
                &params,
            )
            .unwrap();
        (x, stats)
    };
    let auto_linear = LinearSolver::Auto {
        rtol: 1e-3,
        max_iterations: 16,
    };
    let mut small_t = Triplets::default();
    for (r, c, v) in small.triplets.iter().filter(|&(r, c, _)| r <= c) {
        small_t.push(r, c, v);
    }
    let n = small.csc.n();
    let (xa, sa) = minimise(&small_t, n, auto_linear, Precision::Auto);
    let (xc, sc) = minimise(&small_t, n, LinearSolver::Cholesky, Precision::Double);
    assert_eq!(bits(&xa), bits(&xc));
    assert_eq!(
        (sa.iterations, sa.pcg_iterations, sa.refine_iterations),
        (sc.iterations, 0, 0),
        "{sa:?}"
    );
    assert!(sa.iterations >= 3, "{sa:?}");

    let large = matrices::bspline3(20);
    let (a, n) = (&large.csc, large.csc.n());
    let mut ch = Cholesky::with_precision(Ordering::Auto, Threads::Auto, Precision::Auto);
    ch.analyze(a).unwrap();
    assert!(ch.is_large() && ch.is_mixed(), "{:?}", ch.stats);
    let mut ch_small = Cholesky::with_precision(Ordering::Auto, Threads::Auto, Precision::Auto);
    ch_small.analyze(&small.csc).unwrap();
    assert!(!ch_small.is_large() && !ch_small.is_mixed());

    let (x, stats) = minimise(&large.triplets, n, auto_linear, Precision::Auto);
    assert!(
        stats.pcg_iterations > 0 && stats.refine_iterations > 0 && stats.iterations >= 3,
        "{stats:?}"
    );
    let mut g = vec![0.0; n];
    QuarticOn {
        a: large.triplets,
        n,
    }
    .gradient(&x, &mut g);
    let residual = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(residual < 1e-7, "{residual:e}: {stats:?}");
}

/// A chain of `n` unit masses on a line with springs between neighbours and smoothed Coulomb
/// friction on each (`μλ f₀(|x_i − x⁰_i|)`, the mollifier of BFEMP eq. 36 with threshold
/// `eps`), pulled towards `x̂`: where the pull on a mass stays below `μλ` it sticks at `x⁰`,
/// within `eps`. With `model`, [`Objective::begin_model`] models the terms a direction carries
/// through their stick zone (sliding, past `x⁰` at the step's end) as stuck — the zone's
/// quadratic `μλ u²/eps` — as femp's step does (`femp_contact::friction`); `ascend` negates the
/// model's whole gradient, so its direction climbs the energy and must be refused.
struct FrictionalChain {
    x0: Vec<f64>,
    x_hat: Vec<f64>,
    k: f64,
    mu_lambda: f64,
    eps: f64,
    model: bool,
    ascend: bool,
    stuck: Vec<bool>,
    modelling: bool,
}

impl FrictionalChain {
    fn new(n: usize, model: bool) -> Self {
        Self {
            x0: (0..n).map(|i| i as f64).collect(),
            // Pulls of 0.5 ± 0.8: some masses slide, the others stick.
            x_hat: (0..n)
                .map(|i| i as f64 + 0.5 + 0.8 * (i as f64).sin())
                .collect(),
            k: 0.5,
            mu_lambda: 1.0,
            eps: 1e-5,
            model,
            ascend: false,
            stuck: vec![false; n],
            modelling: false,
        }
    }

    /// `(f₀, f₁ = f₀', f₁')` at `|u|`.
    fn f(&self, u: f64) -> (f64, f64, f64) {
        let (y, e) = (u.abs(), self.eps);
        if y >= e {
            (y, 1.0, 0.0)
        } else {
            (
                -y * y * y / (3.0 * e * e) + y * y / e + e / 3.0,
                -y * y / (e * e) + 2.0 * y / e,
                -2.0 * y / (e * e) + 2.0 / e,
            )
        }
    }

    /// Friction's gradient and curvature at mass `i` (the model's if it is modelled stuck).
    fn friction(&self, i: usize, u: f64) -> (f64, f64) {
        if self.modelling && self.stuck[i] {
            let c = 2.0 * self.mu_lambda / self.eps;
            return (c * u, c);
        }
        let (_, f1, f1p) = self.f(u);
        (self.mu_lambda * f1 * u.signum(), self.mu_lambda * f1p)
    }
}

impl Objective for FrictionalChain {
    fn num_dofs(&self) -> usize {
        self.x0.len()
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        let n = x.len();
        let mut e = 0.0;
        for i in 0..n {
            e += 0.5 * (x[i] - self.x_hat[i]).powi(2);
            e += self.mu_lambda * self.f(x[i] - self.x0[i]).0;
            if i + 1 < n {
                e += 0.5 * self.k * (x[i + 1] - x[i] - 1.0).powi(2);
            }
        }
        e
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        let n = x.len();
        for i in 0..n {
            g[i] = x[i] - self.x_hat[i] + self.friction(i, x[i] - self.x0[i]).0;
        }
        for i in 0..n - 1 {
            let s = self.k * (x[i + 1] - x[i] - 1.0);
            g[i] -= s;
            g[i + 1] += s;
        }
        if self.modelling && self.ascend {
            g.iter_mut().for_each(|v| *v = -*v);
        }
    }
    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        let n = x.len();
        for i in 0..n {
            h.push(i, i, 1.0 + self.friction(i, x[i] - self.x0[i]).1);
        }
        for i in 0..n - 1 {
            h.push(i, i, self.k);
            h.push(i + 1, i + 1, self.k);
            h.push(i, i + 1, -self.k);
        }
    }
    fn begin_model(&mut self, x: &[f64], p: &[f64]) -> bool {
        if !self.model {
            return false;
        }
        for i in 0..x.len() {
            let u = x[i] - self.x0[i];
            self.stuck[i] = u.abs() >= self.eps && u * (u + p[i]) < 0.0;
        }
        self.modelling = self.stuck.iter().any(|&s| s);
        self.modelling
    }
    fn end_model(&mut self) {
        self.modelling = false;
    }
}

/// From the frictionless solution (every mass at its pull's `x̂`), plain Newton creeps back to
/// the masses' stick zones over cut steps: the friction's Taylor model has no curvature along
/// a slip, so each direction overshoots the kink at `x⁰`. With the stick model the solve lands
/// there at once and reaches the same minimiser in far fewer iterations; a model direction
/// that does not descend is refused (the plain solve, bit for bit).
#[test]
fn stick_model_directions_reach_the_same_minimiser_in_fewer_iterations() {
    let n = 20;
    let solve = |obj: &mut FrictionalChain| {
        let mut x = obj.x_hat.clone();
        let mut newton = Newton::new();
        newton.record_iterations(true);
        let stats = newton
            .minimize(
                obj,
                &mut x,
                &vec![false; n],
                &NewtonParams {
                    tolerance: 1e-10,
                    ..Default::default()
                },
            )
            .unwrap();
        (x, stats)
    };
    let (x_plain, plain) = solve(&mut FrictionalChain::new(n, false));
    let (x_model, model) = solve(&mut FrictionalChain::new(n, true));
    // The same minimiser: masses that stick are within eps of x⁰, and the rest agree.
    let sticking = (0..n)
        .filter(|&i| (x_plain[i] - i as f64).abs() < 1e-5)
        .count();
    assert!(sticking >= n / 4 && sticking < n, "{sticking} of {n} stick");
    for i in 0..n {
        assert!(
            (x_plain[i] - x_model[i]).abs() < 1e-9,
            "mass {i}: {} against {}",
            x_plain[i],
            x_model[i]
        );
    }
    assert_eq!(plain.model_directions, 0);
    assert!(model.model_directions_taken >= 1);
    // The trace marks the iterations that took the model's direction.
    let marked = model.trace.iter().filter(|r| r.modelled).count();
    assert_eq!(marked, model.model_directions_taken);
    assert!(
        4 * model.iterations <= plain.iterations,
        "{} iterations with the model against {}",
        model.iterations,
        plain.iterations
    );
    // A model whose direction climbs: tried, refused, and the solve is the plain one.
    let mut ascending = FrictionalChain::new(n, true);
    ascending.ascend = true;
    let (x_refused, refused) = solve(&mut ascending);
    assert!(refused.model_directions >= 1);
    assert_eq!(refused.model_directions_taken, 0);
    assert_eq!(refused.iterations, plain.iterations);
    assert_eq!(x_refused, x_plain);
}

/// [`Newton::keep_last_factor`]: a second solve of the same unknowns (the crumpled chain's
/// step, its predictor moved a little: a friction loop's next solve) preconditions its first
/// iteration with the first solve's last factor instead of factorising — the same minimiser to
/// 1e-10 as a solve that factorises, with no factorisation at all here. Other fixed DOFs, or
/// no call, and it factorises as before; the call holds for one solve only.
#[test]
fn a_kept_factor_preconditions_the_next_solve_of_the_same_unknowns() {
    let linear = LinearSolver::LastFactorCg {
        rtol: 1e-10,
        max_iterations: 40,
    };
    let params = NewtonParams {
        tolerance: 1e-12,
        hessian: HessianStrategy::Projected,
        linear,
        ..Default::default()
    };
    // Solves after the first (`keep` says, per solve, whether the factor is kept for it);
    // returns the last solution and each later solve's numeric factorisations.
    let run = |keep: &[bool], fix_another: bool| {
        let (chain, x0, fixed) = crumpled_chain(20);
        let mut obj = ChainStep {
            chain,
            inertia: 2.0e2,
            x_hat: x0.iter().map(|v| v * 1.5).collect(),
        };
        let mut x = x0.clone();
        let mut newton = Newton::new();
        newton.minimize(&mut obj, &mut x, &fixed, &params).unwrap();
        let mut fixed2 = fixed.clone();
        if fix_another {
            fixed2[2] = true;
            fixed2[3] = true;
        }
        let mut counts = Vec::new();
        for &k in keep {
            obj.x_hat.iter_mut().for_each(|v| *v *= 1.001);
            if k {
                newton.keep_last_factor();
            }
            let before = newton.linear_stats().numeric_count;
            newton.minimize(&mut obj, &mut x, &fixed2, &params).unwrap();
            counts.push(newton.linear_stats().numeric_count - before);
        }
        (x, counts)
    };
    let (x_fresh, fresh) = run(&[false], false);
    let (x_kept, kept) = run(&[true], false);
    assert!(fresh[0] >= 1);
    assert_eq!(
        kept[0], 0,
        "the kept factor must precondition the next solve"
    );
    for (a, b) in x_fresh.iter().zip(&x_kept) {
        assert!((a - b).abs() < 1e-10, "{a} vs {b}");
    }
    // One solve only: the one after factorises again.
    let (_, counts) = run(&[true, false], false);
    assert!(counts[0] == 0 && counts[1] >= 1, "{counts:?}");
    // Other unknowns: the kept factor is not used.
    let (_, other) = run(&[true], true);
    assert!(other[0] >= 1);
}

/// `E = √(1 + (x₀ − 10)²) + ½(x₁ − x₀/2)²`, nearly linear in `x₀` far from 10, whose "projected"
/// Hessian keeps a curvature `extra` in `x₀` that the energy does not have — the situation of a
/// projected Newton solve whose clipped negative eigenvalues leave positive curvature along the
/// direction it moves in (measured on the §6.7 twist: 30 iterations in a row of equal increments,
/// each decreasing the energy by its first-order prediction `gᵀp`). An optional wall at
/// `x₀ = wall` is known only to `max_step` (the energy goes on beyond it, so a step past the
/// wall would not be caught by the energy); `evaluated` is the largest `x₀` the energy was
/// evaluated at.
struct Overcurved {
    extra: f64,
    wall: Option<f64>,
    evaluated: f64,
}

impl Overcurved {
    fn new(wall: Option<f64>) -> Self {
        Self {
            extra: 1.0,
            wall,
            evaluated: f64::NEG_INFINITY,
        }
    }
}

impl Objective for Overcurved {
    fn num_dofs(&self) -> usize {
        2
    }
    fn energy(&mut self, x: &[f64]) -> f64 {
        self.evaluated = self.evaluated.max(x[0]);
        (1.0 + (x[0] - 10.0).powi(2)).sqrt() + 0.5 * (x[1] - 0.5 * x[0]).powi(2)
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        let r = x[1] - 0.5 * x[0];
        g[0] = (x[0] - 10.0) / (1.0 + (x[0] - 10.0).powi(2)).sqrt() - 0.5 * r;
        g[1] = r;
    }
    fn hessian(&mut self, x: &[f64], h: &mut Triplets) {
        let s = (1.0 + (x[0] - 10.0).powi(2)).powf(-1.5);
        h.push(0, 0, s + 0.25 + self.extra);
        h.push(0, 1, -0.5);
        h.push(1, 1, 1.0);
    }
    /// The true Hessian (positive definite everywhere: its determinant is `s > 0`).
    fn exact_hessian(&mut self, x: &[f64], h: &mut Triplets) -> bool {
        let s = (1.0 + (x[0] - 10.0).powi(2)).powf(-1.5);
        h.push(0, 0, s + 0.25);
        h.push(0, 1, -0.5);
        h.push(1, 1, 1.0);
        true
    }
    fn max_step(&mut self, x: &[f64], p: &[f64]) -> StepBound {
        match self.wall {
            Some(w) if x[0] + p[0] > w => StepBound {
                alpha: (w - x[0]) / p[0],
                limit: Some(StepLimit::Other),
            },
            _ => StepBound::UNLIMITED,
        }
    }
}

/// [`NewtonParams::max_expansion`]: where the energy along the direction is much flatter than
/// the projected Hessian says, the line search doubles the full step while the energy falls —
/// the same minimiser in a fraction of the iterations, every step decreasing the energy; the
/// trace shows steps longer than 1. Off (`1`), no step is longer than Newton's; nor is an exact
/// Hessian's step ([`HessianStrategy::ExactWhenDefinite`]), the minimiser of its own model.
#[test]
fn expanding_steps_cross_flat_stretches_in_fewer_iterations() {
    let solve = |max_expansion: f64, hessian: HessianStrategy| {
        let mut obj = Overcurved::new(None);
        let mut x = vec![-50.0, 0.0];
        let mut newton = Newton::new();
        newton.record_iterations(true);
        let params = NewtonParams {
            tolerance: 1e-9,
            max_iterations: 500,
            max_expansion,
            hessian,
            ..Default::default()
        };
        let stats = newton
            .minimize(&mut obj, &mut x, &[false; 2], &params)
            .unwrap();
        (x, stats)
    };
    let (x_plain, plain) = solve(1.0, HessianStrategy::Projected);
    let (x_long, long) = solve(64.0, HessianStrategy::Projected);
    let (x_exact, exact) = solve(64.0, HessianStrategy::ExactWhenDefinite);
    assert_eq!(exact.exact_iterations, exact.iterations);
    assert_eq!(exact.expanded_steps, 0);
    assert_eq!(exact.expansion_trials, 0);
    for x in [&x_plain, &x_long, &x_exact] {
        assert!(
            (x[0] - 10.0).abs() < 1e-8 && (x[1] - 5.0).abs() < 1e-8,
            "{x:?}"
        );
    }
    assert_eq!(plain.expanded_steps, 0);
    assert!(plain.trace.iter().all(|r| r.alpha <= 1.0));
    assert!(long.expanded_steps >= 1 && long.expansion_trials >= long.expanded_steps);
    let expanded = long.trace.iter().filter(|r| r.alpha > 1.0).count();
    assert_eq!(expanded, long.expanded_steps);
    assert!(
        long.trace.iter().all(|r| r.change <= 0.0),
        "{:?}",
        long.trace
    );
    assert!(
        4 * long.iterations <= plain.iterations,
        "{} iterations expanding against {}",
        long.iterations,
        plain.iterations
    );
}

/// An expanded step stays within the feasible fraction of the objective's bound along the
/// longest step: with a wall at `x₀ = −20` that only `max_step` knows of, no energy is ever
/// evaluated past it, although an unbounded expansion would have taken the iterate there in
/// one step (and the energy beyond is lower).
#[test]
fn expanding_steps_stay_within_the_feasible_bound() {
    let wall = -20.0;
    let mut obj = Overcurved::new(Some(wall));
    let mut x = vec![-50.0, 0.0];
    let params = NewtonParams {
        tolerance: 1e-9,
        max_iterations: 30,
        max_expansion: 64.0,
        ..Default::default()
    };
    // The minimiser is behind the wall: the solve creeps up to it and stops at the limit.
    let stats = match Newton::new().minimize(&mut obj, &mut x, &[false; 2], &params) {
        Err(SolveError::IterationLimit { stats } | SolveError::LineSearchStalled { stats }) => {
            *stats
        }
        other => panic!("{other:?}"),
    };
    assert!(stats.expanded_steps >= 1, "{stats:?}");
    assert!(
        obj.evaluated < wall,
        "energy evaluated at x₀ = {}",
        obj.evaluated
    );
    assert!(x[0] > wall - 0.1, "x₀ = {} stayed far from the wall", x[0]);
}

/// A solver keeps its last symbolic analysis across solves: a later matrix whose pattern it
/// contains is factorised with it (explicit zeros, that elimination order), so the bits of later
/// solves depend on what came before. [`Newton::analysed_pattern`] and
/// [`Newton::restore_analysis`] carry that over to a solver built afresh (a resumed run): it
/// then solves bit for bit as the original — where a fresh solver without it does not.
#[test]
fn a_restored_analysis_solves_as_the_solver_it_came_from() {
    let case = matrices::grid3(6);
    let n = case.csc.n();
    let upper = |keep: &dyn Fn(usize, usize) -> bool| {
        let mut t = Triplets::default();
        for (r, c, v) in case.triplets.iter().filter(|&(r, c, _)| r <= c) {
            if r == c || keep(r, c) {
                t.push(r, c, v);
            }
        }
        t
    };
    // Problem B couples fewer unknowns than A: its pattern is contained in A's.
    let wide = upper(&|_, _| true);
    let narrow = upper(&|r, c| (r * 31 + c * 17) % 5 != 0);
    // Some unknowns fixed, so the rows are not the original DOFs (nested dissection groups
    // them into nodes by the original numbering).
    let fixed: Vec<bool> = (0..n).map(|d| d % 11 == 3).collect();
    let params = NewtonParams {
        ordering: Ordering::NestedDissection { block: 3 },
        threads: Threads::Seq,
        tolerance: 1e-9,
        ..Default::default()
    };
    let solve = |newton: &mut Newton, a: &Triplets| {
        let mut x = vec![0.0; n];
        let stats = newton
            .minimize(&mut QuarticOn { a: a.clone(), n }, &mut x, &fixed, &params)
            .unwrap();
        (
            x.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            stats.iterations,
            stats.symbolic_analyses,
        )
    };
    let mut original = Newton::new();
    assert!(original.analysed_pattern().is_none());
    solve(&mut original, &wide);
    let kept = original.analysed_pattern().expect("analysed");
    let (x_original, its, symbolic) = solve(&mut original, &narrow);
    assert_eq!(symbolic, 0, "the narrow solve reuses the wide analysis");
    assert!(its >= 3);

    let mut resumed = Newton::new();
    resumed.restore_analysis(&params, &kept).unwrap();
    assert_eq!(resumed.analysed_pattern().as_ref(), Some(&kept));
    let (x_resumed, its_resumed, symbolic_resumed) = solve(&mut resumed, &narrow);
    assert_eq!((its_resumed, symbolic_resumed), (its, 0));
    assert!(x_resumed == x_original, "the resumed solver's bits differ");

    // The check can fail: analysed for its own pattern, the narrow problem's bits differ.
    let (x_fresh, _, symbolic_fresh) = solve(&mut Newton::new(), &narrow);
    assert_eq!(symbolic_fresh, 1);
    assert!(
        x_fresh != x_original,
        "the analysis made no difference to the bits"
    );

    // A malformed pattern is an error, not a panic.
    let mut broken = kept.clone();
    broken.row_idx.swap(0, 1);
    broken.col_ptr[1] = 2;
    let err = Newton::new()
        .restore_analysis(&params, &broken)
        .unwrap_err();
    assert!(err.to_string().contains("analysed pattern"), "{err}");
    let mut short = kept.clone();
    short.dof_of.pop();
    assert!(Newton::new().restore_analysis(&params, &short).is_err());
}
