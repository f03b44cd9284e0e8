//! Sparse Cholesky on elasticity-like SPD matrices (2D: 2 DOFs/node, 3D: 3 DOFs/node,
//! 10⁴–4·10⁵ unknowns): symbolic analysis (AMD vs. METIS nested dissection), numeric
//! factorisation (1 thread, the pool's threads, and `Threads::Auto`'s fixed 8-task split) and
//! solve, timed separately. Prints the factor fill once. Then single against double precision
//! factorisations and solves on the B-spline pattern of femp's 3D MPM matrices
//! (`precision_bspline3d_24k`; `--bench cholesky -- precision` runs only those).
//! Also the assembly of the matrix from its triplets: a full build (counting sort and merge)
//! and a build that reuses the previous one's structure (values scattered into place).
//!
//! Run: `cargo bench -p femp-solver --bench cholesky`. The same matrices through CHOLMOD:
//! `cargo run --release -p femp-solver --example write_matrices -- DIR` then
//! `fixtures/cholmod/run.sh DIR`.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use femp_solver::{Cholesky, FACTOR_TASKS, Ordering, Precision, Threads, UpperCsc};

#[path = "common/matrices.rs"]
mod matrices;

fn benches(c: &mut Criterion) {
    for case in matrices::all() {
        let mut group = c.benchmark_group(format!("cholesky_{}", case.name));
        group.sample_size(10);
        let n = case.csc.n();
        group.bench_function("assemble_full", |b| {
            b.iter(|| {
                let mut a = UpperCsc::default();
                a.assemble(&case.triplets, &case.free, n)
            })
        });
        let mut a = UpperCsc::default();
        a.assemble(&case.triplets, &case.free, n);
        group.bench_function("assemble_reused", |b| {
            b.iter(|| a.assemble(&case.triplets, &case.free, n))
        });
        for (oname, ord) in [
            ("amd", Ordering::Amd),
            ("nd", Ordering::NestedDissection { block: case.block }),
        ] {
            let mut probe = Cholesky::new(ord, Threads::Seq);
            probe.analyze(&case.csc).unwrap();
            eprintln!(
                "{} {oname}: n = {}, nnz(A upper) = {}, nnz(L) = {}",
                case.name,
                case.csc.n(),
                case.csc.nnz(),
                probe.stats.factor_nnz
            );
            group.bench_function(BenchmarkId::new("symbolic", oname), |b| {
                b.iter(|| {
                    let mut ch = Cholesky::new(ord, Threads::Seq);
                    ch.analyze(&case.csc).unwrap();
                })
            });
            // `tasks8`: the split `Threads::Auto` uses for large factors (a fixed task count, so
            // the same bits on any number of threads), on the machine's threads.
            for (tname, threads) in [
                ("1t", Threads::Seq),
                ("2t", Threads::Rayon),
                ("tasks8", Threads::Tasks(femp_solver::FACTOR_TASKS)),
            ] {
                let mut ch = Cholesky::new(ord, threads);
                ch.analyze(&case.csc).unwrap();
                let mut a = case.csc.clone();
                group.bench_function(BenchmarkId::new(format!("numeric_{tname}"), oname), |b| {
                    b.iter(|| ch.factorize(&mut a).unwrap())
                });
                if tname == "1t" {
                    let mut rhs = vec![1.0; case.csc.n()];
                    group.bench_function(BenchmarkId::new("solve_1t", oname), |b| {
                        b.iter(|| {
                            rhs.iter_mut().for_each(|v| *v = 1.0);
                            ch.solve_in_place(&mut rhs)
                        })
                    });
                }
            }
        }
        group.finish();
    }
}

/// Single against double precision on the B-spline pattern of femp's 3D MPM Newton matrices, at
/// block_on_plate_3d's size (where `Precision::Auto` takes single precision): the numeric
/// factorisation, and the triangular solve each CG iteration with the last factor makes —
/// sequential, and in `Threads::Auto`'s fixed split (what femp uses for this size).
fn precision(c: &mut Criterion) {
    let case = matrices::bspline3(20);
    let n = case.csc.n();
    let mut group = c.benchmark_group(format!("precision_{}", case.name));
    group.sample_size(10);
    for (pname, precision) in [("double", Precision::Double), ("single", Precision::Mixed)] {
        for (tname, threads) in [
            ("1t", Threads::Seq),
            ("tasks8", Threads::Tasks(FACTOR_TASKS)),
        ] {
            let mut ch = Cholesky::with_precision(
                Ordering::NestedDissection { block: 3 },
                threads,
                precision,
            );
            ch.analyze(&case.csc).unwrap();
            let mut a = case.csc.clone();
            group.bench_function(BenchmarkId::new(format!("numeric_{pname}"), tname), |b| {
                b.iter(|| ch.factorize(&mut a).unwrap())
            });
            let mut rhs = vec![1.0; n];
            group.bench_function(BenchmarkId::new(format!("solve_{pname}"), tname), |b| {
                b.iter(|| {
                    rhs.fill(1.0);
                    ch.solve_in_place(&mut rhs)
                })
            });
        }
    }
    group.finish();
}

criterion_group!(cholesky, benches, precision);
criterion_main!(cholesky);
