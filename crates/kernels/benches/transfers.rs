//! APIC P2G + grid normalisation + G2P, 10⁴–10⁶ random particles, 2D and 3D, 1 and 2 threads.
//!
//! Two measurements per size:
//! * `transfer` — P2G, normalisation and G2P with the stencils already built (the work a
//!   dense-grid MPM kernel does per step, e.g. Taichi's reference);
//! * `step` — the same plus rebuilding the stencils and active-node numbering from the
//!   positions (what a step really costs here: particles move every step).
//!
//! Particles are uniform random in a box holding 4 particles per cell in 2D and 8 in 3D. Each
//! case runs with the particle arrays in random memory order (`random`) and in the spatial order
//! of [`Stencils::order`] (`sorted`, what a simulator that reorders its particles sees).
//! Throughput is particles per second.
//!
//! Run: `cargo bench -p femp-kernels --bench transfers` (add `-- --quick` for a fast pass).

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use femp_kernels::{Grid, Kernel, Stencils, transfer};
use nalgebra::{SMatrix, SVector};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use std::hint::black_box;

struct Particles<const D: usize> {
    x: Vec<SVector<f64, D>>,
    m: Vec<f64>,
    v: Vec<SVector<f64, D>>,
    b: Vec<SMatrix<f64, D, D>>,
}

fn particles<const D: usize>(n: usize, h: f64, seed: u64) -> Particles<D> {
    let ppc = if D == 2 { 4.0 } else { 8.0 };
    let cells = n as f64 / ppc;
    let side = cells.powf(1.0 / D as f64) * h;
    let mut rng = StdRng::seed_from_u64(seed);
    let x = (0..n)
        .map(|_| SVector::from_fn(|_, _| rng.random_range(0.0..side)))
        .collect();
    let m = (0..n).map(|_| rng.random_range(0.5..1.5)).collect();
    let v = (0..n)
        .map(|_| SVector::from_fn(|_, _| rng.random_range(-1.0..1.0)))
        .collect();
    let b = (0..n)
        .map(|_| SMatrix::from_fn(|_, _| rng.random_range(-0.01..0.01)))
        .collect();
    Particles { x, m, v, b }
}

struct Work<const D: usize> {
    st: Stencils<D>,
    gm: Vec<f64>,
    gv: Vec<SVector<f64, D>>,
    v: Vec<SVector<f64, D>>,
    b: Vec<SMatrix<f64, D, D>>,
}

impl<const D: usize> Work<D> {
    fn new(grid: &Grid<D>, p: &Particles<D>) -> Self {
        let st = grid.stencils(&p.x).unwrap();
        let nn = st.num_nodes();
        Self {
            st,
            gm: vec![0.0; nn],
            gv: vec![SVector::zeros(); nn],
            v: p.v.clone(),
            b: p.b.clone(),
        }
    }

    fn transfer(&mut self, p: &Particles<D>) {
        transfer::p2g_apic(&self.st, &p.m, &p.v, &p.b, &mut self.gm, &mut self.gv).unwrap();
        transfer::normalise(&self.gm, &mut self.gv).unwrap();
        transfer::g2p_apic(&self.st, &self.gv, None, &mut self.v, &mut self.b).unwrap();
    }

    fn step(&mut self, p: &Particles<D>) {
        self.st.rebuild(&p.x).unwrap();
        let nn = self.st.num_nodes();
        self.gm.resize(nn, 0.0);
        self.gv.resize(nn, SVector::zeros());
        self.transfer(p);
    }
}

fn bench_dim<const D: usize>(c: &mut Criterion) {
    let h = 0.01;
    let grid = Grid::<D>::new(h, SVector::zeros(), Kernel::Quadratic).unwrap();
    for what in ["transfer", "step"] {
        let mut group = c.benchmark_group(format!("apic_{what}_{D}d"));
        group.sample_size(10);
        for &n in &[10_000usize, 100_000, 1_000_000] {
            for order in ["random", "sorted"] {
                let mut p = particles::<D>(n, h, 42);
                if order == "sorted" {
                    let st = grid.stencils(&p.x).unwrap();
                    let perm = st.order();
                    p = Particles {
                        x: perm.iter().map(|&i| p.x[i as usize]).collect(),
                        m: perm.iter().map(|&i| p.m[i as usize]).collect(),
                        v: perm.iter().map(|&i| p.v[i as usize]).collect(),
                        b: perm.iter().map(|&i| p.b[i as usize]).collect(),
                    };
                }
                group.throughput(Throughput::Elements(n as u64));
                for threads in [1usize, 2] {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    let mut work = pool.install(|| Work::new(&grid, &p));
                    group.bench_with_input(
                        BenchmarkId::new(format!("{threads}t/{order}"), n),
                        &n,
                        |bench, _| {
                            bench.iter(|| {
                                pool.install(|| {
                                    if what == "step" {
                                        work.step(&p)
                                    } else {
                                        work.transfer(&p)
                                    }
                                });
                                black_box(&work.v);
                            })
                        },
                    );
                }
            }
        }
        group.finish();
    }
}

fn benches(c: &mut Criterion) {
    bench_dim::<2>(c);
    bench_dim::<3>(c);
}

criterion_group!(transfers, benches);
criterion_main!(transfers);
