//! Time APIC P2G / normalise / G2P and the stencil build separately, for profiling:
//! `cargo run --release -p femp-kernels --example profile_transfers -- 2 1000000 [sorted]`.

use femp_kernels::{Grid, Kernel, transfer};
use nalgebra::{SMatrix, SVector};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use std::time::Instant;

fn run<const D: usize>(n: usize, sorted: bool) {
    let h = 0.01;
    let ppc = if D == 2 { 4.0 } else { 8.0 };
    let side = (n as f64 / ppc).powf(1.0 / D as f64) * h;
    let mut rng = StdRng::seed_from_u64(1);
    let mut x: Vec<SVector<f64, D>> = (0..n)
        .map(|_| SVector::from_fn(|_, _| rng.random_range(0.0..side)))
        .collect();
    let grid = Grid::<D>::new(h, SVector::zeros(), Kernel::Quadratic).unwrap();
    if sorted {
        let st = grid.stencils(&x).unwrap();
        x = st.order().iter().map(|&p| x[p as usize]).collect();
    }
    // Random values, as in the bench (all-zero vectors would map to the kernel's shared zero
    // page and never miss the cache).
    let m: Vec<f64> = (0..n).map(|_| rng.random_range(0.5..1.5)).collect();
    let v: Vec<SVector<f64, D>> = (0..n)
        .map(|_| SVector::from_fn(|_, _| rng.random_range(-1.0..1.0)))
        .collect();
    let b: Vec<SMatrix<f64, D, D>> = (0..n)
        .map(|_| SMatrix::from_fn(|_, _| rng.random_range(-0.01..0.01)))
        .collect();
    let mut st = grid.stencils(&x).unwrap();
    let nn = st.num_nodes();
    let mut gm = vec![0.0; nn];
    let mut gv = vec![SVector::<f64, D>::zeros(); nn];
    let mut v2 = v.clone();
    let mut b2 = b.clone();
    let reps = std::env::var("REPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or((2_000_000 / n).max(3));
    let (mut t_build, mut t_p2g, mut t_norm, mut t_g2p) = (0.0, 0.0, 0.0, 0.0);
    for _ in 0..reps {
        let t = Instant::now();
        st.rebuild(&x).unwrap();
        t_build += t.elapsed().as_secs_f64();
        let t = Instant::now();
        transfer::p2g_apic(&st, &m, &v, &b, &mut gm, &mut gv).unwrap();
        t_p2g += t.elapsed().as_secs_f64();
        let t = Instant::now();
        transfer::normalise(&gm, &mut gv).unwrap();
        t_norm += t.elapsed().as_secs_f64();
        let t = Instant::now();
        transfer::g2p_apic(&st, &gv, None, &mut v2, &mut b2).unwrap();
        t_g2p += t.elapsed().as_secs_f64();
    }
    let r = reps as f64;
    let per = |t: f64| t / r * 1e3;
    println!(
        "D={D} n={n} sorted={sorted} threads={} nodes={nn} groups={}: build {:.2} ms, p2g {:.2} ms, normalise {:.2} ms, g2p {:.2} ms; transfer {:.2} M/s, step {:.2} M/s",
        rayon::current_num_threads(),
        st.num_groups(),
        per(t_build),
        per(t_p2g),
        per(t_norm),
        per(t_g2p),
        n as f64 / ((t_p2g + t_norm + t_g2p) / r) / 1e6,
        n as f64 / ((t_build + t_p2g + t_norm + t_g2p) / r) / 1e6,
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let d: usize = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(2);
    let n: usize = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(1_000_000);
    let sorted = args.get(3).is_some_and(|s| s == "sorted");
    if d == 2 {
        run::<2>(n, sorted)
    } else {
        run::<3>(n, sorted)
    }
}
