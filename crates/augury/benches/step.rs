//! Cost of one explicit step against the number of boundary nodes: APIC augury contact versus
//! the search-based penalty baseline, on two thin plates facing each other (every vertex is a
//! boundary vertex, so the contact work dominates), 2D and 3D.
//!
//! `cargo bench -p femp-augury --bench step`

use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use femp_augury::explicit::{ExplicitBody, ExplicitParams, ExplicitSystem, PenaltyContact};
use femp_augury::{AuguryContact, AuguryParams, ContactModel, Transfer, TransferKind};
use femp_fem::mesh::generate::{cuboid, rectangle};
use femp_fem::{Material, Mesh, NeoHookean};
use femp_kernels::Kernel;
use nalgebra::{SVector, Vector2, Vector3};

const E: f64 = 1e6;

fn plates<const D: usize>(boundary_nodes: usize) -> (Vec<ExplicitBody<D>>, f64) {
    let mat = Material::NeoHookean(NeoHookean::from_young_poisson(E, 0.3).unwrap());
    let (lower, upper, h): (Mesh<D>, Mesh<D>, f64) = if D == 2 {
        // Strips of n × 1 cells: 2(n + 1) vertices each.
        let n = (boundary_nodes / 4).max(2);
        let h = 1.0 / n as f64;
        let m = |y0: f64| {
            let m = rectangle(Vector2::new(0.0, y0), Vector2::new(1.0, y0 + h), n, 1).unwrap();
            let v = m
                .vertices()
                .iter()
                .map(|p| SVector::<f64, D>::from_fn(|a, _| p[a]))
                .collect();
            Mesh::new(v, m.cells().to_vec()).unwrap()
        };
        (m(0.0), m(1.5 * h), h)
    } else {
        // Plates of k × 1 × k cells: 2(k + 1)² vertices each.
        let k = (((boundary_nodes / 4) as f64).sqrt() as usize).max(2);
        let h = 1.0 / k as f64;
        let m = |y0: f64| {
            let m = cuboid(
                Vector3::new(0.0, y0, 0.0),
                Vector3::new(1.0, y0 + h, 1.0),
                k,
                1,
                k,
            )
            .unwrap();
            let v = m
                .vertices()
                .iter()
                .map(|p| SVector::<f64, D>::from_fn(|a, _| p[a]))
                .collect();
            Mesh::new(v, m.cells().to_vec()).unwrap()
        };
        (m(0.0), m(1.5 * h), h)
    };
    let a = ExplicitBody::new("lower", &lower, mat, 1000.0).unwrap();
    let b = ExplicitBody::new("upper", &upper, mat, 1000.0).unwrap();
    (vec![a, b], h)
}

fn system<const D: usize>(n: usize, augury: bool) -> (ExplicitSystem<D>, usize) {
    let (bodies, h) = plates::<D>(n);
    let nb: usize = bodies.iter().map(|b| b.boundary.len()).sum();
    // A quarter of the stability estimate, so that round-off cannot grow over many iterations.
    let (mu, lambda) = (E / 2.6, E * 0.3 / (1.3 * 0.4));
    let dt = ExplicitSystem::new(
        bodies,
        ExplicitParams {
            dt: 1.0,
            gravity: SVector::zeros(),
        },
        None,
    )
    .stable_dt(&[(mu, lambda, 1000.0); 2], 0.25);
    let (bodies, _) = plates::<D>(n);
    let params = ExplicitParams {
        dt,
        gravity: SVector::zeros(),
    };
    let sys = if augury {
        let t = Transfer::<D>::new(2.0 * h, Kernel::Quadratic, TransferKind::Apic).unwrap();
        let aug = AuguryContact::new(
            t,
            AuguryParams {
                tau: dt,
                iterations: 1,
                model: ContactModel::Friction(0.3),
            },
        )
        .unwrap();
        ExplicitSystem::new(bodies, params, Some(aug))
    } else {
        let mut s = ExplicitSystem::new(bodies, params, None);
        s.penalty = Some(PenaltyContact::new(E, h).unwrap());
        s
    };
    (sys, nb)
}

fn bench_dim<const D: usize>(c: &mut Criterion) {
    let mut group = c.benchmark_group(format!("explicit_step_{D}d"));
    group.sample_size(10);
    for n in [1_000usize, 10_000, 100_000] {
        for (name, augury) in [("augury_apic", true), ("penalty_search", false)] {
            let (mut sys, nb) = system::<D>(n, augury);
            // Every timed step starts from the same state (after one step, so that the
            // accelerations are set): left to run, the penalty baseline's plates drift over
            // thousands of benchmark iterations and the step timed is no longer this one.
            sys.step().unwrap();
            let saved: Vec<_> = sys
                .bodies
                .iter()
                .map(|b| (b.x.clone(), b.v.clone(), b.a.clone()))
                .collect();
            group.throughput(Throughput::Elements(nb as u64));
            group.bench_with_input(BenchmarkId::new(name, nb), &nb, |bench, _| {
                bench.iter_custom(|iters| {
                    let mut total = Duration::ZERO;
                    for _ in 0..iters {
                        for (b, (x, v, a)) in sys.bodies.iter_mut().zip(&saved) {
                            b.x.copy_from_slice(x);
                            b.v.copy_from_slice(v);
                            b.a.copy_from_slice(a);
                        }
                        let t = Instant::now();
                        sys.step().unwrap();
                        total += t.elapsed();
                    }
                    total
                })
            });
        }
    }
    group.finish();
}

fn benches(c: &mut Criterion) {
    bench_dim::<2>(c);
    bench_dim::<3>(c);
}

criterion_group!(step, benches);
criterion_main!(step);
