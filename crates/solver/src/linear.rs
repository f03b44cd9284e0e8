//! Sparse Cholesky through faer's low-level API, with the symbolic factorisation reused while
//! the sparsity pattern is unchanged and the numeric values and workspace reused always.
//!
//! * [`Ordering::Amd`] — faer's approximate minimum degree (its default);
//! * [`Ordering::NestedDissection`] — METIS `NodeND` (vendored METIS through `metis-sys`) on the
//!   graph of the matrix, optionally compressed to nodes of `block` DOFs (2 or 3 for vector
//!   fields), which is both faster to order and gives less fill on elasticity-like matrices;
//! * [`Ordering::Auto`] — nested dissection for large matrices, AMD for small ones.
//!
//! If the numeric factorisation meets a non-positive pivot (a PSD Hessian that is singular up to
//! round-off), the diagonal is shifted by `δ · max|diag|` and the factorisation retried, with δ
//! growing tenfold from 1e-12; every retry is counted.
//!
//! [`Precision::Mixed`] factorises in single precision — the matrix scaled to a unit diagonal,
//! `D A D` with `D = diag(A)^(-1/2)` — and [`Cholesky::solve_refined`] solves to double precision
//! by conjugate gradients on the double-precision matrix preconditioned with that factor (two or
//! three iterations on the Newton matrices of femp's 3D scenes): the dense kernels of a
//! supernodal factorisation do twice the work per instruction in single precision and its
//! triangular solves move half the bytes. A matrix the single-precision factor fails on, or
//! cannot solve to [`REFINE_RTOL`] within [`REFINE_ITERATIONS`], is factorised again in double
//! precision, so whether a matrix is positive definite is decided as in double precision.

use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use crate::UpperCsc;

/// Fill-reducing ordering.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Ordering {
    /// faer's AMD.
    Amd,
    /// METIS nested dissection on the graph of nodes of `block` DOFs.
    NestedDissection {
        /// DOFs per node (1, 2 or 3); DOF `k` belongs to node `k / block` of the *original*
        /// numbering.
        block: usize,
    },
    /// Nested dissection (per DOF) for matrices with more than 20 000 unknowns and more than 12
    /// stored entries per column (3D-like), else AMD: measured, AMD is as good or better on 2D
    /// elasticity matrices and twice worse in fill and time on 3D ones.
    #[default]
    Auto,
}

/// Arithmetic of the factorisation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Precision {
    /// Factor and solves in double precision.
    #[default]
    Double,
    /// Factor in single precision (of the matrix scaled to a unit diagonal), solves refined to
    /// double precision by CG preconditioned with it ([`Cholesky::solve_refined`]).
    Mixed,
    /// [`Precision::Mixed`] for a [`large_factor`], [`Precision::Double`] otherwise — decided
    /// at each symbolic analysis, from the matrix alone. Measured (`docs/performance.md`): 1.5×
    /// on the factorisations of 3D Newton matrices with 5·10⁷ factor entries; no gain with
    /// 6·10⁵, where the refinement's products and the double-precision re-factorisations of
    /// rejected exact Hessians eat what the factorisations save.
    Auto,
}

/// Whether a factor with `factor_nnz` entries of an `n`-unknown matrix is large and dense
/// enough for parallel factorisation ([`Threads::Auto`]), single precision
/// ([`Precision::Auto`]) and factor reuse by CG (`LinearSolver::Auto`) to pay:
/// `nnz(L) > 2·10⁷` and `nnz(L)/n > 300`.
pub fn large_factor(factor_nnz: usize, n: usize) -> bool {
    factor_nnz > 20_000_000 && factor_nnz / n.max(1) > 300
}

/// [`Precision::Mixed`]: the relative reduction of the factor-preconditioned residual
/// `√(rᵀM⁻¹r)` a refined solve reaches.
pub const REFINE_RTOL: f64 = 1e-10;

/// [`Precision::Mixed`]: CG iterations a refined solve may take before the matrix is factorised
/// in double precision.
pub const REFINE_ITERATIONS: usize = 20;

/// The tasks [`Threads::Auto`] splits a large factorisation into, on any number of threads.
pub const FACTOR_TASKS: usize = 8;

/// Held while METIS runs: GKlib's random generator is one static state per process.
static METIS: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Parallelism of the numeric factorisation and solve.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Threads {
    /// Single-threaded.
    Seq,
    /// rayon, split into as many tasks as the pool has threads: the fastest, but faer's sums
    /// then depend on the thread count (results differ in the last bits from machine to
    /// machine).
    Rayon,
    /// rayon, split into this many tasks whatever the pool's size: the same bits on any number
    /// of threads (faer's split, and with it its summation order, follows the task count).
    Tasks(usize),
    /// Rayon when the factor is large and dense enough to profit, split into a fixed
    /// [`FACTOR_TASKS`] tasks (as [`Threads::Tasks`]) whatever the pool's size, so the result has the same bits on any
    /// number of threads (faer's split, and with it its summation order, follows the task
    /// count; it is not that of the sequential factorisation). Measured (see
    /// `docs/performance.md`), 2 threads were slower than 1 on every 2D matrix and on small 3D
    /// ones, 1.4× faster on the 3D matrix with 10⁵ unknowns. Rule: [`large_factor`] (a
    /// property of the matrix alone).
    #[default]
    Auto,
}

/// Failure of the linear solve.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinearError {
    /// The symbolic analysis failed (out of memory, index overflow).
    #[error("symbolic Cholesky analysis failed: {0}")]
    Symbolic(String),
    /// The matrix stayed indefinite after the allowed diagonal shifts.
    #[error("Cholesky factorisation failed after {shifts} diagonal shifts (last δ = {delta:e})")]
    NotPositiveDefinite {
        /// Shifts tried.
        shifts: usize,
        /// Last relative shift.
        delta: f64,
    },
    /// METIS failed.
    #[error("METIS nested dissection failed with status {0}")]
    Metis(i32),
}

/// Times and counters of the linear algebra, accumulated.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LinearStats {
    /// Symbolic analyses (pattern changes).
    pub symbolic_count: usize,
    /// Numeric factorisations (including retries).
    pub numeric_count: usize,
    /// Diagonal shifts applied.
    pub regularizations: usize,
    /// Seconds in ordering + symbolic analysis.
    pub symbolic_s: f64,
    /// Seconds in numeric factorisation.
    pub numeric_s: f64,
    /// Seconds in triangular solves.
    pub solve_s: f64,
    /// Non-zeros of the last factor.
    pub factor_nnz: usize,
    /// [`Precision::Mixed`]: CG iterations refining single-precision solves.
    pub refine_iterations: usize,
    /// [`Precision::Mixed`]: matrices factorised again in double precision (the single
    /// precision factor failed, or a refined solve did not converge).
    pub double_fallbacks: usize,
}

/// One numeric factorisation into `l` of the matrix with `a`'s pattern and the values `values`
/// (in `T`'s precision), analysed as `symbolic`; whether it succeeded.
fn numeric_llt<T: faer::traits::ComplexField>(
    symbolic: &SymbolicCholesky<usize>,
    l: &mut [T],
    a: &UpperCsc,
    values: &[T],
    par: Par,
    buffer: &mut MemBuffer,
) -> bool {
    let n = a.n;
    let mat = SparseColMatRef::new(
        SymbolicSparseColMatRef::new_checked(n, n, &a.col_ptr, None, &a.row_idx),
        values,
    );
    symbolic
        .factorize_numeric_llt(
            l,
            mat,
            Side::Upper,
            LltRegularization::default(),
            par,
            MemStack::new(buffer),
            Default::default(),
        )
        .is_ok()
}

/// A reusable sparse Cholesky solver.
pub struct Cholesky {
    ordering: Ordering,
    threads: Threads,
    precision: Precision,
    /// Whether factorisations are single precision: [`Precision::Mixed`], or
    /// [`Precision::Auto`] for the analysed matrix.
    mixed: bool,
    symbolic: Option<SymbolicCholesky<usize>>,
    l_values: Vec<f64>,
    /// [`Precision::Mixed`]: the single-precision factor of `D A D`, `D` = `scale`.
    l_single: Vec<f32>,
    scale: Vec<f64>,
    /// Scratch: the scaled matrix's values, and a right-hand side, in single precision.
    scaled: Vec<f32>,
    rhs_single: Vec<f32>,
    /// Whether the last factorisation is the single-precision one.
    single: bool,
    /// The diagonal shifts the last factorisation was allowed (0: a try).
    last_max_shifts: usize,
    /// [`Cholesky::solve_refined`]'s tolerance and CG iterations.
    refinement: (f64, usize),
    buffer: MemBuffer,
    /// Original DOF of each free DOF (for node compression in nested dissection).
    dof_of: Vec<usize>,
    /// Statistics.
    pub stats: LinearStats,
}

impl Cholesky {
    /// A solver with the given ordering and threading.
    pub fn new(ordering: Ordering, threads: Threads) -> Self {
        Self::with_precision(ordering, threads, Precision::Double)
    }

    /// A solver with the given ordering, threading and arithmetic.
    pub fn with_precision(ordering: Ordering, threads: Threads, precision: Precision) -> Self {
        Self {
            ordering,
            threads,
            precision,
            mixed: precision == Precision::Mixed,
            symbolic: None,
            l_values: Vec::new(),
            l_single: Vec::new(),
            scale: Vec::new(),
            scaled: Vec::new(),
            rhs_single: Vec::new(),
            single: false,
            last_max_shifts: 0,
            refinement: (REFINE_RTOL, REFINE_ITERATIONS),
            buffer: MemBuffer::new(faer::dyn_stack::StackReq::EMPTY),
            dof_of: Vec::new(),
            stats: LinearStats::default(),
        }
    }

    /// [`Precision::Mixed`]: the relative reduction of the preconditioned residual a refined
    /// solve reaches, and the CG iterations it may take before the matrix is factorised in
    /// double precision (default [`REFINE_RTOL`], [`REFINE_ITERATIONS`]).
    pub fn set_refinement(&mut self, rtol: f64, max_iterations: usize) {
        self.refinement = (rtol, max_iterations);
    }

    /// Tell the solver which original DOF each row is (used to group DOFs into nodes for
    /// nested dissection). Defaults to the identity.
    pub fn set_dof_map(&mut self, dof_of: &[usize]) {
        self.dof_of.clear();
        self.dof_of.extend_from_slice(dof_of);
    }

    /// The original DOF of each row ([`Cholesky::set_dof_map`]; empty: the identity).
    pub fn dof_map(&self) -> &[usize] {
        &self.dof_of
    }

    fn par(&self, factor_nnz: usize, n: usize) -> Par {
        match self.threads {
            Threads::Seq => Par::Seq,
            Threads::Rayon => Par::rayon(0),
            Threads::Tasks(n) => Par::rayon(n.max(1)),
            Threads::Auto => {
                if large_factor(factor_nnz, n) {
                    Par::rayon(FACTOR_TASKS)
                } else {
                    Par::Seq
                }
            }
        }
    }

    /// Forget the symbolic analysis (the next factorisation re-analyses).
    pub fn reset(&mut self) {
        self.symbolic = None;
    }

    /// Analyse `a`'s pattern (ordering + symbolic factorisation).
    pub fn analyze(&mut self, a: &UpperCsc) -> Result<(), LinearError> {
        let t = Instant::now();
        let n = a.n;
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &a.col_ptr, None, &a.row_idx);
        let use_nd = match self.ordering {
            Ordering::Amd => None,
            Ordering::NestedDissection { block } => Some(block),
            Ordering::Auto => (n > 20_000 && a.nnz() > 12 * n).then_some(1),
        };
        let result = match use_nd {
            Some(block) => {
                let (fwd, inv) = self.nested_dissection(a, block)?;
                let perm = faer::perm::PermRef::new_checked(&fwd, &inv, n);
                factorize_symbolic_cholesky(
                    sym,
                    Side::Upper,
                    SymmetricOrdering::Custom(perm),
                    CholeskySymbolicParams::default(),
                )
            }
            None => factorize_symbolic_cholesky(
                sym,
                Side::Upper,
                SymmetricOrdering::Amd,
                CholeskySymbolicParams::default(),
            ),
        };
        let symbolic = result.map_err(|e| LinearError::Symbolic(format!("{e:?}")))?;
        self.mixed = match self.precision {
            Precision::Double => false,
            Precision::Mixed => true,
            Precision::Auto => large_factor(symbolic.len_val(), n),
        };
        if self.mixed {
            // The double-precision factor is made (and its memory taken) only if needed.
            self.l_single.resize(symbolic.len_val(), 0.0);
        } else {
            self.l_values.resize(symbolic.len_val(), 0.0);
        }
        self.single = false;
        self.stats.factor_nnz = symbolic.len_val();
        let par = self.par(symbolic.len_val(), n);
        let mut req = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, par));
        if self.mixed {
            req = req
                .or(symbolic.factorize_numeric_llt_scratch::<f32>(par, Default::default()))
                .or(symbolic.solve_in_place_scratch::<f32>(1, par));
        }
        self.buffer = MemBuffer::new(req);
        self.symbolic = Some(symbolic);
        self.stats.symbolic_count += 1;
        self.stats.symbolic_s += t.elapsed().as_secs_f64();
        Ok(())
    }

    /// Whether a symbolic analysis is available.
    pub fn is_analyzed(&self) -> bool {
        self.symbolic.is_some()
    }

    /// Whether the analysed matrix's factor is a [`large_factor`] (false before an analysis).
    pub fn is_large(&self) -> bool {
        self.symbolic
            .as_ref()
            .is_some_and(|s| large_factor(s.len_val(), s.nrows()))
    }

    /// Whether the factorisations of the analysed matrix are made in single precision
    /// ([`Precision::Mixed`], or [`Precision::Auto`] for a [`large_factor`]).
    pub fn is_mixed(&self) -> bool {
        self.mixed
    }

    /// Numeric factorisation of `a` (analysed before), shifting the diagonal on failure.
    pub fn factorize(&mut self, a: &mut UpperCsc) -> Result<(), LinearError> {
        self.factorize_shifting(a, 12)
    }

    /// One numeric factorisation of `a` (analysed before), without diagonal shifts: `Ok(true)`
    /// if `a` is positive definite to working precision, `Ok(false)` if not (the factor is then
    /// unusable). For trying an indefinite-looking matrix before falling back to a projected one.
    pub fn try_factorize(&mut self, a: &mut UpperCsc) -> Result<bool, LinearError> {
        match self.factorize_shifting(a, 0) {
            Ok(()) => Ok(true),
            Err(LinearError::NotPositiveDefinite { .. }) => Ok(false),
            Err(other) => Err(other),
        }
    }

    fn factorize_shifting(
        &mut self,
        a: &mut UpperCsc,
        max_shifts: usize,
    ) -> Result<(), LinearError> {
        self.last_max_shifts = max_shifts;
        self.single = false;
        if self.mixed {
            if self.factorize_single(a)? {
                return Ok(());
            }
            self.stats.double_fallbacks += 1;
        }
        self.factorize_double(a, max_shifts)
    }

    /// [`Precision::Mixed`]: one single-precision factorisation of `a` scaled to a unit
    /// diagonal; whether it succeeded (a non-positive or non-finite diagonal fails it).
    fn factorize_single(&mut self, a: &UpperCsc) -> Result<bool, LinearError> {
        let t = Instant::now();
        let Some(symbolic) = &self.symbolic else {
            return Err(LinearError::Symbolic(
                "factorize called before analyze".into(),
            ));
        };
        let n = a.n;
        self.scale.clear();
        for j in 0..n {
            let d = a.diagonal_index(j).map_or(0.0, |k| a.values[k]);
            if !(d > 0.0 && d.is_finite()) {
                return Ok(false);
            }
            self.scale.push(1.0 / d.sqrt());
        }
        self.scaled.clear();
        for c in 0..n {
            let sc = self.scale[c];
            for k in a.col_ptr[c]..a.col_ptr[c + 1] {
                self.scaled
                    .push((a.values[k] * self.scale[a.row_idx[k]] * sc) as f32);
            }
        }
        self.l_single.resize(symbolic.len_val(), 0.0);
        let par = self.par(symbolic.len_val(), n);
        self.stats.numeric_count += 1;
        let ok = numeric_llt(
            symbolic,
            &mut self.l_single,
            a,
            &self.scaled,
            par,
            &mut self.buffer,
        );
        self.single = ok;
        self.stats.numeric_s += t.elapsed().as_secs_f64();
        Ok(ok)
    }

    /// Double-precision factorisation of `a`, shifting its diagonal up to `max_shifts` times.
    fn factorize_double(&mut self, a: &mut UpperCsc, max_shifts: usize) -> Result<(), LinearError> {
        let t = Instant::now();
        let Some(symbolic) = &self.symbolic else {
            return Err(LinearError::Symbolic(
                "factorize called before analyze".into(),
            ));
        };
        let n = a.n;
        let max_diag = (0..n)
            .filter_map(|j| a.diagonal_index(j))
            .map(|k| a.values[k].abs())
            .fold(0.0f64, f64::max)
            .max(f64::MIN_POSITIVE);
        let par = self.par(symbolic.len_val(), n);
        self.l_values.resize(symbolic.len_val(), 0.0);
        let mut delta = 0.0;
        let mut shifts = 0;
        loop {
            self.stats.numeric_count += 1;
            let ok = numeric_llt(
                symbolic,
                &mut self.l_values,
                a,
                &a.values,
                par,
                &mut self.buffer,
            );
            if ok {
                break;
            }
            if shifts >= max_shifts {
                self.stats.numeric_s += t.elapsed().as_secs_f64();
                return Err(LinearError::NotPositiveDefinite { shifts, delta });
            }
            let new_delta = if delta == 0.0 { 1e-12 } else { delta * 10.0 };
            for j in 0..n {
                if let Some(k) = a.diagonal_index(j) {
                    a.values[k] += (new_delta - delta) * max_diag;
                }
            }
            delta = new_delta;
            shifts += 1;
            self.stats.regularizations += 1;
        }
        self.stats.numeric_s += t.elapsed().as_secs_f64();
        Ok(())
    }

    /// Solve `A x = rhs` in place with the last factorisation — with a single-precision one
    /// ([`Precision::Mixed`]) to single precision only: a preconditioner, or see
    /// [`Cholesky::solve_refined`].
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) {
        let t = Instant::now();
        let symbolic = self.symbolic.as_ref().expect("solve before factorize");
        let par = self.par(symbolic.len_val(), symbolic.nrows());
        let n = rhs.len();
        if self.single {
            let llt = faer::sparse::linalg::cholesky::LltRef::<'_, usize, f32>::new(
                symbolic,
                &self.l_single,
            );
            self.rhs_single.clear();
            self.rhs_single
                .extend(rhs.iter().zip(&self.scale).map(|(b, d)| (b * d) as f32));
            let rhs_mat = MatMut::from_column_major_slice_mut(&mut self.rhs_single, n, 1);
            llt.solve_in_place_with_conj(Conj::No, rhs_mat, par, MemStack::new(&mut self.buffer));
            for ((x, z), d) in rhs.iter_mut().zip(&self.rhs_single).zip(&self.scale) {
                *x = f64::from(*z) * d;
            }
        } else {
            let llt = faer::sparse::linalg::cholesky::LltRef::<'_, usize, f64>::new(
                symbolic,
                &self.l_values,
            );
            let rhs_mat = MatMut::from_column_major_slice_mut(rhs, n, 1);
            llt.solve_in_place_with_conj(Conj::No, rhs_mat, par, MemStack::new(&mut self.buffer));
        }
        self.stats.solve_s += t.elapsed().as_secs_f64();
    }

    /// Solve `A x = rhs` in place to double precision, `a` the matrix last factorised: with a
    /// double-precision factor a triangular solve ([`Cholesky::solve_in_place`]); with a
    /// single-precision one CG on `a` preconditioned with it, to [`REFINE_RTOL`] (`pcg`'s
    /// buffers and `sol` as workspace; [`Cholesky::set_refinement`]). If CG does not get there
    /// in [`REFINE_ITERATIONS`] (or meets non-positive curvature), `a` is factorised in double
    /// precision — with the diagonal shifts the last factorisation was allowed — and solved
    /// directly: `Ok(false)` (`rhs` unchanged) if that was a try ([`Cholesky::try_factorize`])
    /// and `a` is not positive definite.
    pub fn solve_refined(
        &mut self,
        a: &mut UpperCsc,
        rhs: &mut [f64],
        pcg: &mut crate::Pcg,
        sol: &mut [f64],
    ) -> Result<bool, LinearError> {
        if !self.single {
            self.solve_in_place(rhs);
            return Ok(true);
        }
        let outcome = pcg.solve_preconditioned(a, rhs, sol, self.refinement, &mut |z| {
            self.solve_in_place(z)
        });
        self.stats.refine_iterations += outcome.iterations();
        if outcome.converged() {
            rhs.copy_from_slice(sol);
            return Ok(true);
        }
        self.stats.double_fallbacks += 1;
        self.single = false;
        match self.factorize_double(a, self.last_max_shifts) {
            Ok(()) => {
                self.solve_in_place(rhs);
                Ok(true)
            }
            Err(LinearError::NotPositiveDefinite { .. }) if self.last_max_shifts == 0 => Ok(false),
            Err(e) => Err(e),
        }
    }

    /// METIS NodeND on the (node-compressed) graph of `a` (one call in the process at a time:
    /// [`METIS`]); returns (forward, inverse)
    /// permutations of the rows (`forward[new] = old`).
    fn nested_dissection(
        &self,
        a: &UpperCsc,
        block: usize,
    ) -> Result<(Vec<usize>, Vec<usize>), LinearError> {
        let n = a.n;
        let block = block.max(1);
        let dof = |k: usize| {
            if self.dof_of.len() == n {
                self.dof_of[k]
            } else {
                k
            }
        };
        // Node of each row, renumbered compactly.
        let mut node_of = vec![0usize; n];
        let mut node_id = std::collections::HashMap::new();
        let mut members: Vec<Vec<usize>> = Vec::new();
        for k in 0..n {
            let key = dof(k) / block;
            let id = *node_id.entry(key).or_insert_with(|| {
                members.push(Vec::new());
                members.len() - 1
            });
            node_of[k] = id;
            members[id].push(k);
        }
        let nn = members.len();
        // Symmetric node adjacency from the upper pattern.
        let mut adj: Vec<Vec<i32>> = vec![Vec::new(); nn];
        for c in 0..n {
            for &r in &a.row_idx[a.col_ptr[c]..a.col_ptr[c + 1]] {
                let (u, v) = (node_of[r], node_of[c]);
                if u != v {
                    adj[u].push(v as i32);
                    adj[v].push(u as i32);
                }
            }
        }
        let mut xadj = Vec::with_capacity(nn + 1);
        let mut adjncy = Vec::new();
        xadj.push(0i32);
        for l in adj.iter_mut() {
            l.sort_unstable();
            l.dedup();
            adjncy.extend_from_slice(l);
            xadj.push(adjncy.len() as i32);
        }
        let mut perm = vec![0i32; nn];
        let mut iperm = vec![0i32; nn];
        if nn > 1 && !adjncy.is_empty() {
            let mut nv = nn as i32;
            let mut options = [0i32; metis_sys::METIS_NOPTIONS as usize];
            // One METIS call at a time in the process: METIS draws from GKlib's random
            // generator, a static state each call re-seeds, so calls on two threads at once
            // (two worlds stepping side by side) would interleave their draws — other orderings,
            // other bits, and a data race on that state. (A poisoned lock guards nothing.)
            let _one_at_a_time = METIS.lock().unwrap_or_else(|e| e.into_inner());
            // SAFETY: plain FFI calls with correctly sized, initialised buffers: `options` has
            // METIS_NOPTIONS entries, `xadj` nn + 1, `adjncy` xadj[nn], `perm`/`iperm` nn; no
            // other METIS call runs meanwhile (the lock above).
            let status = unsafe {
                metis_sys::METIS_SetDefaultOptions(options.as_mut_ptr());
                metis_sys::METIS_NodeND(
                    &mut nv,
                    xadj.as_mut_ptr(),
                    adjncy.as_mut_ptr(),
                    std::ptr::null_mut(),
                    options.as_mut_ptr(),
                    perm.as_mut_ptr(),
                    iperm.as_mut_ptr(),
                )
            };
            if status != metis_sys::rstatus_et_METIS_OK {
                return Err(LinearError::Metis(status));
            }
        } else {
            for (i, p) in perm.iter_mut().enumerate() {
                *p = i as i32;
            }
        }
        // METIS: perm[new] = old node. Expand nodes to their rows.
        let mut fwd = Vec::with_capacity(n);
        for &node in &perm {
            fwd.extend_from_slice(&members[node as usize]);
        }
        let mut inv = vec![0usize; n];
        for (new, &old) in fwd.iter().enumerate() {
            inv[old] = new;
        }
        Ok((fwd, inv))
    }
}
