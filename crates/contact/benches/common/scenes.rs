//! The deterministic benchmark scenes (shared by the bench and the profiling example; mirrored
//! by `fixtures/ipctk/bench_ipctk.py`).
#![allow(missing_docs)]

use nalgebra::{SVector, Vector2, Vector3};

/// Boundary vertices, facets, particles.
pub type Scene<const D: usize> = (Vec<SVector<f64, D>>, Vec<[u32; 3]>, Vec<SVector<f64, D>>);

pub const DHAT: f64 = 1e-3;
pub const N_PARTICLES: usize = 100_000;
/// Length of the 2D polyline.
pub const LENGTH2: f64 = 200.0;

/// Fractional part of k·φ (a low-discrepancy sequence in [0, 1)).
fn golden(k: usize, a: f64) -> f64 {
    (k as f64 * a).fract()
}

fn height2(x: f64) -> f64 {
    0.5 * (0.3 * x).sin()
}

fn height3(x: f64, y: f64) -> f64 {
    0.02 * (6.0 * x).sin() * (5.0 * y).cos()
}

/// 2D: polyline y = h(x) on [0, 200] with 10 000 edges (0.02 long); 100 000 particles above
/// it, 0.002 apart (more than d̂, so particles never interact with each other), at heights in
/// (0.05, 0.95) d̂.
pub fn scene2() -> Scene<2> {
    let ne = 10_000;
    let v: Vec<_> = (0..=ne)
        .map(|i| {
            let x = LENGTH2 * i as f64 / ne as f64;
            Vector2::new(x, height2(x))
        })
        .collect();
    let f: Vec<[u32; 3]> = (0..ne as u32).map(|i| [i, i + 1, 0]).collect();
    let p: Vec<_> = (0..N_PARTICLES)
        .map(|k| {
            let x = LENGTH2 * (k as f64 + 0.5) / N_PARTICLES as f64;
            let off = (0.05 + 0.9 * golden(k, 0.754_877_666_246_693)) * DHAT;
            Vector2::new(x, height2(x) + off)
        })
        .collect();
    (v, f, p)
}

/// 3D: height field z = h(x, y) on [0, 1]² with a 71 × 71 vertex grid (9 800 triangles);
/// 316² = 99 856 particles on a regular grid above it (0.0032 apart), at heights in
/// (0.05, 0.95) d̂ (vertical offset).
pub fn scene3() -> Scene<3> {
    let n = 70;
    let mut v = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (i as f64 / n as f64, j as f64 / n as f64);
            v.push(Vector3::new(x, y, height3(x, y)));
        }
    }
    let id = |i: usize, j: usize| (j * (n + 1) + i) as u32;
    let mut f = Vec::new();
    for j in 0..n {
        for i in 0..n {
            f.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            f.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    let m = 316;
    let p: Vec<_> = (0..m * m)
        .map(|k| {
            let x = ((k % m) as f64 + 0.5) / m as f64;
            let y = ((k / m) as f64 + 0.5) / m as f64;
            let off = (0.05 + 0.9 * golden(k, 0.618_033_988_749_895)) * DHAT;
            Vector3::new(x, y, height3(x, y) + off)
        })
        .collect();
    (v, f, p)
}
