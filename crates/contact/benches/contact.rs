//! Contact hot paths:
//! (a) barrier potential + gradient + PSD Hessian for 10⁵ particles near a boundary of ~10⁴
//!     edges (2D) or triangles (3D), including the broad phase, 1 and 2 threads, with the
//!     projected Hessian and (`…_gauss_newton`) the Gauss–Newton one, and (`…+coo`) with the
//!     global gradient and Hessian triplets assembled (`assembly::assemble`, what the Python
//!     package's `ContactMesh.potential` computes);
//! (b) CCD time per query on the 3,085 vertex–face queries of the Wang et al. 2021 benchmark.
//!
//! The scenes are deterministic formulas (no RNG), reproduced exactly by
//! `fixtures/ipctk/bench_ipctk.py`, which times the same work through the IPC Toolkit.
//!
//! Run: `cargo bench -p femp-contact --bench contact`.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use femp_contact::assembly::{Coo, assemble};
use femp_contact::broad_phase::{self, Candidates};
use femp_contact::ccd::{self, CcdOptions};
use femp_contact::{
    BarrierHessian, BoundaryTopology, ContactPotential, LogBarrier, particle_weight,
};
use nalgebra::Vector3;
use std::hint::black_box;

#[path = "common/scenes.rs"]
mod scenes;
use scenes::{DHAT, scene2, scene3};

/// A rayon pool of `threads` threads.
fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

fn bench_potential<const D: usize>(c: &mut Criterion, name: &str, (v, f, p): scenes::Scene<D>) {
    let pot = ContactPotential::new(
        LogBarrier::new(DHAT, 1e4).unwrap(),
        BoundaryTopology::<D>::new(&f, v.len()).unwrap(),
    );
    let w = vec![particle_weight::<D>(1e-6); p.len()];
    let mut group = c.benchmark_group(format!("barrier_{name}"));
    group.sample_size(10);
    group.throughput(Throughput::Elements(p.len() as u64));
    for (id, hessian) in [
        ("broad+energy+grad+hess", BarrierHessian::Projected),
        (
            "broad+energy+grad+hess_gauss_newton",
            BarrierHessian::GaussNewton,
        ),
    ] {
        let pot = pot.clone().with_hessian(hessian);
        for threads in [1usize, 2] {
            let pool = pool(threads);
            let (mut cands, mut terms, mut ders) = (Candidates::default(), Vec::new(), Vec::new());
            group.bench_with_input(BenchmarkId::new(id, threads), &threads, |b, _| {
                b.iter(|| {
                    pool.install(|| {
                        broad_phase::candidates_within(
                            &p,
                            &v,
                            pot.topology.facets(),
                            DHAT,
                            &mut cands,
                        );
                        pot.collect_terms(&p, &w, &v, &cands, &mut terms).unwrap();
                        let e = pot.energy(&terms);
                        pot.derivatives(&terms, &p, &v, &mut ders);
                        black_box((e, ders.len()))
                    })
                })
            });
        }
    }
    // The same, with the gradient and the Hessian's triplets over all unknowns assembled.
    for threads in [1usize, 2] {
        let pool = pool(threads);
        let (mut cands, mut terms, mut ders) = (Candidates::default(), Vec::new(), Vec::new());
        let id = "broad+energy+grad+hess+coo";
        group.bench_with_input(BenchmarkId::new(id, threads), &threads, |b, _| {
            b.iter(|| {
                pool.install(|| {
                    broad_phase::candidates_within(&p, &v, pot.topology.facets(), DHAT, &mut cands);
                    pot.collect_terms(&p, &w, &v, &cands, &mut terms).unwrap();
                    let e = pot.energy(&terms);
                    pot.derivatives(&terms, &p, &v, &mut ders);
                    let mut grad = vec![0.0; (p.len() + v.len()) * D];
                    let mut coo = Coo::default();
                    assemble(&ders, p.len(), &mut grad, Some(&mut coo)).unwrap();
                    black_box((e, grad, coo))
                })
            })
        });
    }
    group.finish();
}

fn load_vertex_face() -> Vec<[Vector3<f64>; 8]> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/ccd-sample-queries/vertex_face.txt");
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = Vec::new();
    let mut lines = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty());
    while let Some(_head) = lines.next() {
        let pts: [Vector3<f64>; 8] = std::array::from_fn(|_| {
            let v: Vec<f64> = lines
                .next()
                .unwrap()
                .split_whitespace()
                .map(|t| t.parse().unwrap())
                .collect();
            Vector3::new(v[0], v[1], v[2])
        });
        lines.next();
        out.push(pts);
    }
    out
}

fn bench_ccd(c: &mut Criterion) {
    let qs = load_vertex_face();
    let opts = CcdOptions::default();
    let mut group = c.benchmark_group("ccd_vertex_face");
    group.throughput(Throughput::Elements(qs.len() as u64));
    group.bench_function("all_3085_queries", |b| {
        b.iter(|| {
            let mut hits = 0;
            for p in &qs {
                hits += ccd::point_triangle(
                    &p[0], &p[1], &p[2], &p[3], &p[4], &p[5], &p[6], &p[7], &opts,
                )
                .toi
                .is_some() as usize;
            }
            black_box(hits)
        })
    });
    group.finish();
}

/// The broad phase alone: `candidates_within` at the barrier distance, on the whole scene and on
/// its first 1 000 particles (many facets, few particles: a fine FEM shell on a coarse MPM body).
fn bench_broad_phase<const D: usize>(c: &mut Criterion, name: &str, (v, f, p): scenes::Scene<D>) {
    let mut group = c.benchmark_group(format!("broad_phase_{name}"));
    group.sample_size(10);
    let mut cands = Candidates::default();
    for n in [p.len(), 1000] {
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(BenchmarkId::new("particles", n), &n, |b, &n| {
            b.iter(|| {
                broad_phase::candidates_within(&p[..n], &v, &f, DHAT, &mut cands);
                black_box(cands.num_pairs())
            })
        });
    }
    group.finish();
}

fn benches(c: &mut Criterion) {
    bench_broad_phase::<2>(c, "2d_10k_edges", scene2());
    bench_broad_phase::<3>(c, "3d_9800_triangles", scene3());
    bench_potential::<2>(c, "2d_100k_particles_10k_edges", scene2());
    bench_potential::<3>(c, "3d_100k_particles_9800_triangles", scene3());
    bench_ccd(c);
}

criterion_group!(contact, benches);
criterion_main!(contact);
