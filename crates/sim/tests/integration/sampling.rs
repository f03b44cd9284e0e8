//! Particle sampling of round shapes: `"polar"` fills a disk or ring with concentric circles
//! whose particle areas add up to the exact area and whose outermost circle is round (unlike the
//! lattice's staircase); it is 2D only.

use std::path::Path;

use femp::{World, scene};
use serde_json::{Value, json};

fn scene_with(shape: Value, dim: usize) -> Result<World<2>, String> {
    let v = json!({
        "dimension": dim,
        "time": { "dt": 0.01, "duration": 0.1 },
        "mpm": { "grid_spacing": 0.05 },
        "bodies": [ { "kind": "mpm", "name": "d", "shape": shape, "particles_per_cell": 9,
                      "material": { "E": 1e6, "nu": 0.3, "rho": 1000 } } ]
    });
    let s = scene::parse(&v.to_string(), "t.json", Path::new(".").to_path_buf(), "t")
        .map_err(|e| e.to_string())?;
    World::<2>::build(s).map_err(|e| e.to_string())
}

#[test]
fn polar_disk_has_the_exact_area_and_a_round_boundary() {
    let w = scene_with(
        json!({ "disk": { "center": [0.3, -0.2], "radius": 1.0, "sampling": "polar" } }),
        2,
    )
    .unwrap();
    let m = w.bodies.mpm.as_ref().unwrap();
    let area: f64 = m.volume.iter().sum();
    assert!((area - std::f64::consts::PI).abs() < 1e-12, "area {area}");
    // Spacing h/3; 60 rings of width 1/60; the outer one at 1 − 1/120.
    let r = |x: &nalgebra::Vector2<f64>| ((x[0] - 0.3).powi(2) + (x[1] + 0.2).powi(2)).sqrt();
    let r_max = m.x.iter().map(r).fold(0.0, f64::max);
    assert!((r_max - (1.0 - 1.0 / 120.0)).abs() < 1e-12, "{r_max}");
    let outer = m.x.iter().filter(|x| (r(x) - r_max).abs() < 1e-12).count();
    // round(2π r / Δr) particles on the outer circle.
    let expected = (std::f64::consts::TAU * r_max * 60.0).round() as usize;
    assert_eq!(outer, expected);
    // A lattice disk of the same spacing has a flat bottom row far wider than one spacing.
    let l = scene_with(
        json!({ "disk": { "center": [0.0, 0.0], "radius": 1.0 } }),
        2,
    )
    .unwrap();
    let lm = l.bodies.mpm.as_ref().unwrap();
    let y_min = lm.x.iter().map(|x| x[1]).fold(f64::INFINITY, f64::min);
    let row = lm.x.iter().filter(|x| (x[1] - y_min).abs() < 1e-12).count();
    assert!(row > 5, "lattice bottom row has {row} particles");
}

#[test]
fn polar_ring_has_the_exact_area() {
    let w = scene_with(
        json!({ "ring": { "center": [0, 0], "r_in": 0.5, "r_out": 0.8, "sampling": "polar" } }),
        2,
    )
    .unwrap();
    let area: f64 = w.bodies.mpm.as_ref().unwrap().volume.iter().sum();
    let exact = std::f64::consts::PI * (0.8f64.powi(2) - 0.5f64.powi(2));
    assert!((area - exact).abs() < 1e-12 * exact, "{area} vs {exact}");
}

#[test]
fn polar_sampling_is_2d_only() {
    let v = json!({
        "dimension": 3,
        "time": { "dt": 0.01, "duration": 0.1 },
        "mpm": { "grid_spacing": 0.05 },
        "bodies": [ { "kind": "mpm", "name": "d",
                      "shape": { "disk": { "center": [0, 0, 0], "radius": 0.2, "sampling": "polar" } },
                      "material": { "E": 1e6, "nu": 0.3, "rho": 1000 } } ]
    });
    let e = scene::parse(&v.to_string(), "t.json", Path::new(".").to_path_buf(), "t")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bodies[0].shape.sampling") && e.contains("2D"),
        "{e}"
    );
}
