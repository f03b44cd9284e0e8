//! Preconditioned conjugate gradients on an [`UpperCsc`] (a symmetric matrix stored as its upper
//! triangle) — Jacobi ([`Pcg::solve`]) or a caller's operator ([`Pcg::solve_preconditioned`],
//! e.g. a factorisation of a nearby matrix): an alternative to factorising every Newton
//! Hessian when the Hessian is well conditioned — mass-dominated incremental potentials at small
//! time steps, where a handful of CG iterations cost less than one factorisation and need no
//! symbolic analysis when the sparsity pattern changes — or close to one already factorised.
//!
//! The products run on all rayon threads (columns split into chunks of equal work, each chunk
//! accumulating into its own vector; no allocation once the buffers have grown). CG stops when
//! the preconditioned residual has fallen by `rtol` relative to the right-hand side's
//! (`√(rᵀD⁻¹r) ≤ rtol·√(bᵀD⁻¹b)`), and reports non-positive curvature (`dᵀAd ≤ 0`: the matrix
//! is not positive definite) and non-positive diagonals instead of iterating on. Every iterate
//! of CG from `x₀ = 0` on a matrix that was positive along all the directions it met is a
//! descent direction for the quadratic model: `bᵀx_k = x_kᵀA x_k > 0`.

use rayon::prelude::*;

use crate::UpperCsc;

/// How a [`Pcg::solve`] ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PcgOutcome {
    /// The relative preconditioned residual reached the tolerance after `iterations`.
    Converged {
        /// CG iterations (matrix products).
        iterations: usize,
    },
    /// A search direction with `dᵀAd ≤ 0` (or non-finite): the matrix is not positive
    /// definite. `x` holds the last iterate.
    NegativeCurvature {
        /// CG iterations done.
        iterations: usize,
    },
    /// The preconditioner is unusable — a diagonal entry `≤ 0` or non-finite (Jacobi), or
    /// `bᵀM⁻¹b` negative or non-finite ([`Pcg::solve_preconditioned`]): nothing was done.
    BadDiagonal,
    /// The iteration limit was reached first.
    NotConverged {
        /// CG iterations done (= the limit).
        iterations: usize,
    },
}

impl PcgOutcome {
    /// CG iterations (matrix products) the solve made.
    pub fn iterations(&self) -> usize {
        match *self {
            Self::Converged { iterations }
            | Self::NegativeCurvature { iterations }
            | Self::NotConverged { iterations } => iterations,
            Self::BadDiagonal => 0,
        }
    }

    /// Whether the tolerance was reached.
    pub fn converged(&self) -> bool {
        matches!(self, Self::Converged { .. })
    }
}

/// Jacobi-preconditioned CG with reusable buffers.
#[derive(Debug, Default)]
pub struct Pcg {
    inv_diag: Vec<f64>,
    r: Vec<f64>,
    z: Vec<f64>,
    d: Vec<f64>,
    q: Vec<f64>,
    parts: Vec<Vec<f64>>,
    /// The matrix's row indices as `u32` (less memory traffic per product), for the pattern
    /// [`UpperCsc::pattern_id`] `pattern`.
    rows32: Vec<u32>,
    pattern: u64,
}

/// A caller's preconditioner: `z ← M⁻¹ z` in place.
type Apply<'a> = &'a mut dyn FnMut(&mut [f64]);

/// Below this many stored entries a product runs on one thread.
const PARALLEL_NNZ: usize = 20_000;

/// At most this many column chunks per product.
const MAX_CHUNKS: usize = 16;

/// Stored entries per column chunk of a parallel product. The chunk count follows from the
/// matrix alone, never from the number of threads: every entry of the product is summed in the
/// same order on any machine, so CG gives the same bits on 1, 2 or 16 threads.
const CHUNK_NNZ: usize = 100_000;

impl Pcg {
    /// Empty buffers.
    pub fn new() -> Self {
        Self::default()
    }

    /// Solve `A x = b` from `x = 0` until `√(rᵀD⁻¹r) ≤ rtol·√(bᵀD⁻¹b)` or `max_iterations`.
    pub fn solve(
        &mut self,
        a: &UpperCsc,
        b: &[f64],
        x: &mut [f64],
        rtol: f64,
        max_iterations: usize,
    ) -> PcgOutcome {
        self.inv_diag.clear();
        for j in 0..a.n() {
            let d = a.diagonal_index(j).map_or(0.0, |k| a.values()[k]);
            if !(d > 0.0 && d.is_finite()) {
                return PcgOutcome::BadDiagonal;
            }
            self.inv_diag.push(1.0 / d);
        }
        self.run(a, b, x, (rtol, max_iterations), None)
    }

    /// Solve `A x = b` from `x = 0` with the preconditioner `apply` (`z ← M⁻¹ z` in place, `M`
    /// symmetric positive definite — e.g. a factorisation of a nearby matrix) until
    /// `√(rᵀM⁻¹r) ≤ rtol·√(bᵀM⁻¹b)` or `max_iterations`.
    pub fn solve_preconditioned(
        &mut self,
        a: &UpperCsc,
        b: &[f64],
        x: &mut [f64],
        (rtol, max_iterations): (f64, usize),
        apply: Apply<'_>,
    ) -> PcgOutcome {
        self.run(a, b, x, (rtol, max_iterations), Some(apply))
    }

    /// CG from `x = 0`, preconditioned by `apply` or (`None`) by `inv_diag`.
    fn run(
        &mut self,
        a: &UpperCsc,
        b: &[f64],
        x: &mut [f64],
        (rtol, max_iterations): (f64, usize),
        mut apply: Option<Apply<'_>>,
    ) -> PcgOutcome {
        let n = a.n();
        assert_eq!(b.len(), n, "right-hand side length");
        assert_eq!(x.len(), n, "solution length");
        x.iter_mut().for_each(|v| *v = 0.0);
        self.r.clear();
        self.r.extend_from_slice(b);
        self.z.clear();
        match apply.as_mut() {
            Some(apply) => {
                self.z.extend_from_slice(b);
                apply(&mut self.z);
            }
            None => self
                .z
                .extend(self.r.iter().zip(&self.inv_diag).map(|(r, w)| r * w)),
        }
        self.d.clear();
        self.d.extend_from_slice(&self.z);
        self.q.resize(n, 0.0);
        if self.pattern != a.pattern_id() || self.rows32.len() != a.nnz() {
            self.rows32.clear();
            self.rows32.extend(a.row_idx().iter().map(|&r| r as u32));
            self.pattern = a.pattern_id();
        }
        let mat = Sym {
            n,
            col_ptr: a.col_ptr(),
            rows: &self.rows32,
            values: a.values(),
        };
        let mut rz = dot(&self.r, &self.z);
        if apply.is_some() && !(rz >= 0.0 && rz.is_finite()) {
            return PcgOutcome::BadDiagonal;
        }
        let stop = rtol * rtol * rz;
        if rz == 0.0 {
            return PcgOutcome::Converged { iterations: 0 };
        }
        for it in 1..=max_iterations {
            let chunks = mat.mul_parts(&self.d, &mut self.parts);
            let dq = gather_product(&self.parts[..chunks], &self.d, &mut self.q);
            if !(dq > 0.0 && dq.is_finite()) {
                return PcgOutcome::NegativeCurvature { iterations: it };
            }
            let alpha = rz / dq;
            let rz_new = match apply.as_mut() {
                Some(apply) => {
                    for ((x, r), (d, q)) in x
                        .iter_mut()
                        .zip(&mut self.r)
                        .zip(self.d.iter().zip(&self.q))
                    {
                        *x += alpha * d;
                        *r -= alpha * q;
                    }
                    self.z.copy_from_slice(&self.r);
                    apply(&mut self.z);
                    dot(&self.r, &self.z)
                }
                None => step(
                    alpha,
                    &self.d,
                    &self.q,
                    &self.inv_diag,
                    x,
                    &mut self.r,
                    &mut self.z,
                ),
            };
            if rz_new <= stop {
                return PcgOutcome::Converged { iterations: it };
            }
            let beta = rz_new / rz;
            for (d, z) in self.d.iter_mut().zip(&self.z) {
                *d = z + beta * *d;
            }
            rz = rz_new;
        }
        PcgOutcome::NotConverged {
            iterations: max_iterations,
        }
    }
}

/// Independent partial sums per reduction (vector lanes; a single running sum would make every
/// loop latency-bound on its additions).
const LANES: usize = 4;

fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; LANES];
    let (ac, bc) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
    let tail: f64 = ac
        .remainder()
        .iter()
        .zip(bc.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ac.zip(bc) {
        for l in 0..LANES {
            acc[l] += x[l] * y[l];
        }
    }
    acc.iter().sum::<f64>() + tail
}

/// `q = Σ parts` and `dᵀq`.
fn gather_product(parts: &[Vec<f64>], d: &[f64], q: &mut [f64]) -> f64 {
    let n = q.len();
    match parts {
        [a] => q.copy_from_slice(&a[..n]),
        [a, b] => {
            for ((q, a), b) in q.iter_mut().zip(&a[..n]).zip(&b[..n]) {
                *q = a + b;
            }
        }
        _ => {
            q.copy_from_slice(&parts[0][..n]);
            for p in &parts[1..] {
                for (q, v) in q.iter_mut().zip(&p[..n]) {
                    *q += v;
                }
            }
        }
    }
    dot(d, q)
}

/// `x += αd`, `r −= αq`, `z = D⁻¹r`; returns `rᵀz`.
fn step(
    alpha: f64,
    d: &[f64],
    q: &[f64],
    inv_diag: &[f64],
    x: &mut [f64],
    r: &mut [f64],
    z: &mut [f64],
) -> f64 {
    let n = x.len();
    let (d, q, inv_diag, r, z) = (&d[..n], &q[..n], &inv_diag[..n], &mut r[..n], &mut z[..n]);
    for (x, d) in x.iter_mut().zip(d) {
        *x += alpha * d;
    }
    for ((r, q), (z, w)) in r.iter_mut().zip(q).zip(z.iter_mut().zip(inv_diag)) {
        *r -= alpha * q;
        *z = *r * w;
    }
    dot(r, z)
}

impl UpperCsc {
    /// `y = A x` for the symmetric `A` whose upper triangle this is, on all rayon threads
    /// (see [`UpperCsc::mul_symmetric_parts`]); `parts` is scratch kept for the next call.
    pub fn mul_symmetric(&self, x: &[f64], y: &mut [f64], parts: &mut Vec<Vec<f64>>) {
        assert_eq!(y.len(), self.n, "y length");
        let chunks = self.mul_symmetric_parts(x, parts);
        for (i, v) in y.iter_mut().enumerate() {
            *v = parts[..chunks].iter().map(|p| p[i]).sum();
        }
    }

    /// `A x` as the sum of `parts[0..k]` (the returned `k`, each `n` long): columns are split
    /// into `k` chunks of about equal entry counts (one below 20 000 entries, then one per
    /// 100 000 entries, 2 to 16 — fixed by the matrix, not the thread count), each accumulating its columns' contributions into its own buffer (grown as
    /// needed, kept for the next call). Callers sum the parts where they use the product, so
    /// a product costs one fork–join and no extra pass.
    pub fn mul_symmetric_parts(&self, x: &[f64], parts: &mut Vec<Vec<f64>>) -> usize {
        Sym {
            n: self.n,
            col_ptr: &self.col_ptr,
            rows: &self.row_idx,
            values: &self.values,
        }
        .mul_parts(x, parts)
    }
}

/// A symmetric matrix by its upper triangle (CSC, rows sorted, diagonal last in a column when
/// present) with row indices of type `I`.
struct Sym<'a, I> {
    n: usize,
    col_ptr: &'a [usize],
    rows: &'a [I],
    values: &'a [f64],
}

impl<I: Copy + Sync + TryInto<usize>> Sym<'_, I> {
    fn mul_parts(&self, x: &[f64], parts: &mut Vec<Vec<f64>>) -> usize {
        let n = self.n;
        assert_eq!(x.len(), n, "x length");
        let nnz = self.values.len();
        let chunks = if nnz < PARALLEL_NNZ {
            1
        } else {
            (nnz / CHUNK_NNZ).clamp(2, MAX_CHUNKS)
        };
        if parts.len() < chunks {
            parts.resize_with(chunks, Vec::new);
        }
        // Chunk c covers columns [bounds[c], bounds[c + 1]).
        let mut bounds = [0usize; MAX_CHUNKS + 1];
        for (c, bound) in bounds.iter_mut().enumerate().take(chunks).skip(1) {
            let target = nnz * c / chunks;
            *bound = self.col_ptr.partition_point(|&p| p < target).min(n);
        }
        bounds[chunks] = n;
        let work = |c: usize, part: &mut Vec<f64>| {
            part.clear();
            part.resize(n, 0.0);
            self.mul_columns(bounds[c], bounds[c + 1], x, part);
        };
        if chunks == 1 {
            work(0, &mut parts[0]);
        } else {
            parts[..chunks]
                .par_iter_mut()
                .enumerate()
                .for_each(|(c, part)| work(c, part));
        }
        chunks
    }

    /// Columns `c0..c1` of the symmetric product, added into `y` (indexed by row).
    #[inline]
    fn mul_columns(&self, c0: usize, c1: usize, x: &[f64], y: &mut [f64]) {
        let row = |k: usize| -> usize { self.rows[k].try_into().unwrap_or(usize::MAX) };
        for j in c0..c1 {
            let (start, mut end) = (self.col_ptr[j], self.col_ptr[j + 1]);
            let xj = x[j];
            let mut s = 0.0;
            // The diagonal, if present, is the column's last entry (rows are sorted).
            if end > start && row(end - 1) == j {
                end -= 1;
                s += self.values[end] * xj;
            }
            for k in start..end {
                let (i, v) = (row(k), self.values[k]);
                s += v * x[i];
                y[i] += v * xj;
            }
            y[j] += s;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Triplets;

    /// A random SPD matrix: a 2D grid Laplacian-like stencil with random positive weights plus
    /// a random positive diagonal, as full symmetric triplets.
    fn spd(n_side: usize, seed: u64) -> (Triplets, usize) {
        let mut s = seed;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let n = n_side * n_side;
        let mut t = Triplets::default();
        for i in 0..n {
            t.push(i, i, 0.1 + rnd());
        }
        for r in 0..n_side {
            for c in 0..n_side {
                let i = r * n_side + c;
                for j in [
                    (c + 1 < n_side).then(|| i + 1),
                    (r + 1 < n_side).then(|| i + n_side),
                ]
                .into_iter()
                .flatten()
                {
                    let w = 10.0 * rnd();
                    t.push(i, i, w);
                    t.push(j, j, w);
                    t.push(i, j, -w);
                    t.push(j, i, -w);
                }
            }
        }
        (t, n)
    }

    fn dense(t: &Triplets, n: usize) -> Vec<f64> {
        let mut a = vec![0.0; n * n];
        for k in 0..t.vals.len() {
            a[t.rows[k] as usize * n + t.cols[k] as usize] += t.vals[k];
        }
        a
    }

    #[test]
    fn symmetric_product_equals_the_dense_one_on_one_and_several_threads() {
        // 150² unknowns: above the parallel threshold, so the chunked path runs too.
        for (side, seed) in [(7, 3u64), (150, 11)] {
            let (t, n) = spd(side, seed);
            let mut a = UpperCsc::default();
            a.assemble(&t, &(0..n as u32).collect::<Vec<_>>(), n);
            let x: Vec<f64> = (0..n)
                .map(|i| ((i * 37 % 101) as f64 - 50.0) / 7.0)
                .collect();
            // Reference from the triplets directly (both triangles are in them).
            let mut want = vec![0.0; n];
            for k in 0..t.vals.len() {
                want[t.rows[k] as usize] += t.vals[k] * x[t.cols[k] as usize];
            }
            for threads in [1, 2, 3] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let mut y = vec![f64::NAN; n];
                let mut parts = Vec::new();
                pool.install(|| a.mul_symmetric(&x, &mut y, &mut parts));
                for i in 0..n {
                    assert!(
                        (y[i] - want[i]).abs() <= 1e-12 * (1.0 + want[i].abs()),
                        "side {side}, {threads} threads, row {i}: {} vs {}",
                        y[i],
                        want[i]
                    );
                }
            }
        }
    }

    #[test]
    fn pcg_solves_an_spd_system_to_the_tolerance() {
        let (t, n) = spd(20, 5);
        let mut a = UpperCsc::default();
        a.assemble(&t, &(0..n as u32).collect::<Vec<_>>(), n);
        let ad = dense(&t, n);
        let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        for rtol in [1e-4, 1e-10] {
            let mut x = vec![1.0; n];
            let out = Pcg::new().solve(&a, &b, &mut x, rtol, 10 * n);
            assert!(out.converged(), "{out:?}");
            // The true residual is small relative to b (the preconditioned one is ≤ rtol).
            let res: f64 = (0..n)
                .map(|i| {
                    let ax: f64 = (0..n).map(|j| ad[i * n + j] * x[j]).sum();
                    (ax - b[i]).powi(2)
                })
                .sum::<f64>()
                .sqrt();
            let bn = b.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!(
                res <= 100.0 * rtol * bn,
                "rtol {rtol}: residual {res} vs {bn}"
            );
            // A descent direction for ½xᵀAx − bᵀx.
            assert!(b.iter().zip(&x).map(|(p, q)| p * q).sum::<f64>() > 0.0);
        }
        // A tighter tolerance needs more iterations, and the limit is honoured.
        let mut x = vec![0.0; n];
        let out = Pcg::new().solve(&a, &b, &mut x, 1e-12, 3);
        assert_eq!(out, PcgOutcome::NotConverged { iterations: 3 });
    }

    /// A caller's preconditioner: Jacobi passed as an operator gives Jacobi CG's iterates bit
    /// for bit; the exact inverse (here of a diagonal matrix) converges in one product; an
    /// operator that is not positive is refused before any product.
    #[test]
    fn a_callers_preconditioner_is_applied_as_given() {
        let (t, n) = spd(20, 5);
        let mut a = UpperCsc::default();
        a.assemble(&t, &(0..n as u32).collect::<Vec<_>>(), n);
        let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let inv: Vec<f64> = (0..n)
            .map(|j| 1.0 / a.values()[a.diagonal_index(j).unwrap()])
            .collect();
        let (mut xj, mut xp) = (vec![0.0; n], vec![0.0; n]);
        let jacobi = Pcg::new().solve(&a, &b, &mut xj, 1e-10, 10 * n);
        let mut scale = |z: &mut [f64]| z.iter_mut().zip(&inv).for_each(|(z, w)| *z *= w);
        let given = Pcg::new().solve_preconditioned(&a, &b, &mut xp, (1e-10, 10 * n), &mut scale);
        assert!(
            jacobi.converged() && given == jacobi,
            "{jacobi:?} vs {given:?}"
        );
        assert_eq!(xj, xp);

        let mut d = Triplets::default();
        for i in 0..n {
            d.push(i, i, 1.0 + i as f64);
        }
        let mut diag = UpperCsc::default();
        diag.assemble(&d, &(0..n as u32).collect::<Vec<_>>(), n);
        let mut exact = |z: &mut [f64]| {
            z.iter_mut()
                .enumerate()
                .for_each(|(i, z)| *z /= 1.0 + i as f64)
        };
        let mut x = vec![0.0; n];
        let out = Pcg::new().solve_preconditioned(&diag, &b, &mut x, (1e-12, 5), &mut exact);
        assert_eq!(out, PcgOutcome::Converged { iterations: 1 });
        let mut negative = |z: &mut [f64]| z.iter_mut().for_each(|z| *z = -*z);
        let out = Pcg::new().solve_preconditioned(&diag, &b, &mut x, (1e-12, 5), &mut negative);
        assert_eq!(out, PcgOutcome::BadDiagonal);
    }

    #[test]
    fn pcg_reports_indefinite_matrices_and_bad_diagonals() {
        // [[1, 2], [2, 1]] has eigenvalues 3 and −1; b along the −1 eigenvector.
        let mut t = Triplets::default();
        for (r, c, v) in [(0, 0, 1.0), (0, 1, 2.0), (1, 0, 2.0), (1, 1, 1.0)] {
            t.push(r, c, v);
        }
        let mut a = UpperCsc::default();
        a.assemble(&t, &[0, 1], 2);
        let mut x = vec![0.0; 2];
        let out = Pcg::new().solve(&a, &[1.0, -1.0], &mut x, 1e-10, 10);
        assert_eq!(out, PcgOutcome::NegativeCurvature { iterations: 1 });
        let mut t = Triplets::default();
        t.push(0, 0, 1.0);
        t.push(1, 1, -1.0);
        a.assemble(&t, &[0, 1], 2);
        assert_eq!(
            Pcg::new().solve(&a, &[1.0, 1.0], &mut x, 1e-10, 10),
            PcgOutcome::BadDiagonal
        );
        // A zero right-hand side converges at once to x = 0.
        let mut x = vec![5.0; 2];
        let mut t = Triplets::default();
        t.push(0, 0, 2.0);
        t.push(1, 1, 3.0);
        a.assemble(&t, &[0, 1], 2);
        assert_eq!(
            Pcg::new().solve(&a, &[0.0, 0.0], &mut x, 1e-10, 10),
            PcgOutcome::Converged { iterations: 0 }
        );
        assert_eq!(x, vec![0.0, 0.0]);
    }
}
