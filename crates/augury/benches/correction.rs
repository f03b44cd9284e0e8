//! Cost of the augury contact correction (one step's contact work) against the number of
//! boundary particles: two boxes' surfaces touching, APIC, one friction iteration, 2D and 3D.
//!
//! `cargo bench -p femp-augury --bench correction`

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use femp_augury::{AuguryContact, AuguryParams, ContactModel, Transfer, TransferKind};
use femp_kernels::Kernel;
use nalgebra::{SMatrix, SVector};

/// Positions, outward normals, velocities, and the particle spacing.
type Surfaces<const D: usize> = (
    Vec<SVector<f64, D>>,
    Vec<SVector<f64, D>>,
    Vec<SVector<f64, D>>,
    f64,
);

/// Points on the surfaces of two unit boxes side by side (gap `s/2`), spacing `s`, with outward
/// normals and velocities towards each other.
fn surfaces<const D: usize>(target: usize) -> Surfaces<D> {
    // Surface points per box ≈ 2D: 4/s; 3D: 6/s².
    let s = if D == 2 {
        8.0 / target as f64
    } else {
        (12.0 / target as f64).sqrt()
    };
    let k = (1.0 / s).round() as usize;
    let s = 1.0 / k as f64;
    let (mut x, mut n, mut v) = (Vec::new(), Vec::new(), Vec::new());
    for (shift, vel) in [(0.0, 1.0), (1.0 + 0.5 * s, -1.0)] {
        let total = (k + 1).pow(D as u32);
        for flat in 0..total {
            let mut rem = flat;
            let idx: [usize; D] = std::array::from_fn(|_| {
                let i = rem % (k + 1);
                rem /= k + 1;
                i
            });
            if !idx.iter().any(|&i| i == 0 || i == k) {
                continue;
            }
            let mut p = SVector::<f64, D>::from_fn(|a, _| idx[a] as f64 * s);
            let mut nn = SVector::<f64, D>::zeros();
            for a in 0..D {
                if idx[a] == 0 {
                    nn[a] -= 1.0;
                } else if idx[a] == k {
                    nn[a] += 1.0;
                }
            }
            p[0] += shift;
            x.push(p);
            n.push(nn.normalize());
            let mut vv = SVector::<f64, D>::zeros();
            vv[0] = vel;
            v.push(vv);
        }
    }
    (x, n, v, s)
}

fn bench_dim<const D: usize>(c: &mut Criterion) {
    let mut group = c.benchmark_group(format!("augury_correction_{D}d"));
    group.sample_size(10);
    for target in [1_000usize, 10_000, 100_000] {
        let (x, n, v, s) = surfaces::<D>(target);
        let np = x.len();
        let m = vec![1.0; np];
        let b = vec![SMatrix::<f64, D, D>::zeros(); np];
        // Grid twice the particle spacing (the paper's impact test).
        let transfer = Transfer::<D>::new(2.0 * s, Kernel::Quadratic, TransferKind::Apic).unwrap();
        let mut aug = AuguryContact::new(
            transfer,
            AuguryParams {
                tau: 1e-4,
                iterations: 1,
                model: ContactModel::Friction(0.3),
            },
        )
        .unwrap();
        let mut a = vec![SVector::<f64, D>::zeros(); np];
        let mut bd = vec![SMatrix::<f64, D, D>::zeros(); np];
        group.throughput(Throughput::Elements(np as u64));
        group.bench_with_input(BenchmarkId::from_parameter(np), &np, |bench, _| {
            bench.iter(|| {
                aug.correction(&x, &m, &n, &v, &b, &mut a, &mut bd).unwrap();
                black_box(&a);
            })
        });
    }
    group.finish();
}

fn benches(c: &mut Criterion) {
    bench_dim::<2>(c);
    bench_dim::<3>(c);
}

criterion_group!(correction, benches);
criterion_main!(correction);
