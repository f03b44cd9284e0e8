//! Elastic assembly throughput (energy + gradient + PSD Hessian triplets), elements per second,
//! 2D and 3D, 1 and 2 threads; the PSD projection of one tangent, analytic vs eigen; and the
//! MPM particle Hessian kernel (`chain_hessian_add_upper` over a quadratic B-spline stencil of
//! 3^D nodes, the exact tangent per particle, as in the BFEMP grid Hessian).
//!
//! Run: `cargo bench -p femp-fem --bench assembly` (only the particle kernel:
//! `cargo bench -p femp-fem --bench assembly -- particle_hessian`).

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use femp_fem::mesh::generate;
use femp_fem::{ElasticBody, Hyperelastic, Mesh, NeoHookean, Triplet, chain_hessian_add_upper};
use nalgebra::{SMatrix, SVector, Vector2, Vector3};
use std::hint::black_box;

fn deformed<const D: usize>(mesh: &Mesh<D>) -> Vec<SVector<f64, D>> {
    mesh.vertices()
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let s = (i as f64 * 0.618).sin();
            v * 1.02 + SVector::<f64, D>::repeat(0.01 * s)
        })
        .collect()
}

fn bench_mesh<const D: usize>(c: &mut Criterion, name: &str, mesh: &Mesh<D>) {
    let mat = NeoHookean::from_young_poisson(1e6, 0.3).unwrap();
    let x = deformed(mesh);
    let mut group = c.benchmark_group(format!("assembly_{name}"));
    group.sample_size(10);
    group.throughput(Throughput::Elements(mesh.num_cells() as u64));
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut body = ElasticBody::new(mesh, mat).unwrap();
        let mut g = vec![SVector::<f64, D>::zeros(); x.len()];
        let mut trip: Vec<Triplet> = Vec::new();
        group.bench_with_input(
            BenchmarkId::new("energy+gradient+hessian", threads),
            &threads,
            |b, _| {
                b.iter(|| {
                    pool.install(|| {
                        let e = body.energy(&x).unwrap();
                        g.iter_mut().for_each(|v| *v = SVector::zeros());
                        body.add_gradient(&x, 1.0, &mut g).unwrap();
                        body.hessian_triplets(&x, 1.0, 0, &mut trip).unwrap();
                        black_box((e, &g, &trip));
                    })
                })
            },
        );
        // The exact (unprojected) Hessian alone, against the projected one alone: what an
        // exact-when-definite Newton iteration saves or adds per assembly.
        for (label, exact) in [("hessian", false), ("exact_hessian", true)] {
            group.bench_with_input(BenchmarkId::new(label, threads), &threads, |b, _| {
                b.iter(|| {
                    pool.install(|| {
                        if exact {
                            body.exact_hessian_triplets(&x, 1.0, 0, &mut trip).unwrap();
                        } else {
                            body.hessian_triplets(&x, 1.0, 0, &mut trip).unwrap();
                        }
                        black_box(&trip);
                    })
                })
            });
        }
    }
    group.finish();
}

fn projection<const D: usize>(c: &mut Criterion) {
    let mat = NeoHookean::from_young_poisson(1e6, 0.3).unwrap();
    // A compressed, sheared F with negative tangent eigenvalues.
    let mut f = SMatrix::<f64, D, D>::identity() * 0.7;
    f[(0, 1)] = 0.3;
    f[(D - 1, 0)] = -0.2;
    let mut group = c.benchmark_group(format!("tangent_psd_{D}d"));
    group.bench_function("analytic", |b| {
        b.iter(|| black_box(mat.tangent_psd(black_box(&f))))
    });
    group.bench_function("eigen", |b| {
        b.iter(|| black_box(Hyperelastic::<D>::tangent(&mat, black_box(&f)).project_psd_eigen()))
    });
    group.finish();
}

/// 1 000 particles of one stencil: per particle its exact tangent and its `3^D × 3^D` blocks
/// added into one accumulator (what the grid Hessian does per cell).
fn particle_chain<const D: usize>(c: &mut Criterion) {
    const PARTICLES: usize = 1000;
    let mat = NeoHookean::from_young_poisson(1e8, 0.2).unwrap();
    let nn = 3usize.pow(D as u32);
    let fs: Vec<SMatrix<f64, D, D>> = (0..PARTICLES)
        .map(|p| {
            SMatrix::<f64, D, D>::from_fn(|a, b| {
                let s = ((p * 7 + a * 3 + b) as f64 * 0.618).sin();
                f64::from(u8::from(a == b)) + 0.05 * s
            })
        })
        .collect();
    let grads: Vec<Vec<SVector<f64, D>>> = (0..PARTICLES)
        .map(|p| {
            (0..nn)
                .map(|k| SVector::<f64, D>::from_fn(|a, _| ((p + 11 * k + a) as f64).cos()))
                .collect()
        })
        .collect();
    let mut acc = vec![SMatrix::<f64, D, D>::zeros(); nn * nn];
    let mut group = c.benchmark_group(format!("particle_hessian_{D}d"));
    group.throughput(Throughput::Elements(PARTICLES as u64));
    group.bench_function("tangent_and_chain", |b| {
        b.iter(|| {
            for (f, g) in fs.iter().zip(&grads) {
                let t = Hyperelastic::<D>::tangent(&mat, f);
                chain_hessian_add_upper(&t, g, 1e-3, &mut acc);
            }
            black_box(&acc);
        })
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    let m2 = generate::rectangle(Vector2::zeros(), Vector2::new(2.0, 2.0), 200, 200).unwrap();
    bench_mesh(c, "2d_80k_triangles", &m2);
    let m3 = generate::cuboid(Vector3::zeros(), Vector3::new(1.0, 1.0, 1.0), 20, 20, 20).unwrap();
    bench_mesh(c, "3d_48k_tetrahedra", &m3);
    projection::<2>(c);
    projection::<3>(c);
    particle_chain::<2>(c);
    particle_chain::<3>(c);
}

criterion_group!(assembly, benches);
criterion_main!(assembly);
