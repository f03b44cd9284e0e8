//! Jacobi-preconditioned CG on elasticity-like SPD matrices (the Cholesky benchmark's set,
//! 10⁴–10⁵ unknowns): the symmetric product on one and two threads, and a solve to
//! `rtol = 1e-6` (its iteration count printed once).
//!
//! Run: `cargo bench -p femp-solver --bench pcg`.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use femp_solver::Pcg;

#[path = "common/matrices.rs"]
mod matrices;

fn benches(c: &mut Criterion) {
    for case in [
        matrices::grid2(71),
        matrices::grid2(224),
        matrices::grid3(15),
    ] {
        let mut group = c.benchmark_group(format!("pcg_{}", case.name));
        group.sample_size(20);
        let a = &case.csc;
        let n = a.n();
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.1).sin()).collect();
        let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).cos()).collect();
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut y = vec![0.0; n];
            let mut parts = Vec::new();
            group.bench_function(
                BenchmarkId::new("product", format!("{threads}t")),
                |bench| pool.install(|| bench.iter(|| a.mul_symmetric(&x, &mut y, &mut parts))),
            );
            let mut pcg = Pcg::new();
            let mut sol = vec![0.0; n];
            let out = pool.install(|| pcg.solve(a, &b, &mut sol, 1e-6, 10_000));
            eprintln!(
                "{} ({threads}t): n = {n}, nnz(upper) = {}, CG to 1e-6: {out:?}",
                case.name,
                a.nnz()
            );
            group.bench_function(
                BenchmarkId::new("solve_1e-6", format!("{threads}t")),
                |bench| pool.install(|| bench.iter(|| pcg.solve(a, &b, &mut sol, 1e-6, 10_000))),
            );
        }
        group.finish();
    }
}

criterion_group!(pcg, benches);
criterion_main!(pcg);
