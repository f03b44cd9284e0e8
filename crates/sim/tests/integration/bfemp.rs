//! BFEMP end to end on small scenes: a block falling on a plate at large time steps, momentum
//! conservation through an MPM–FEM collision, friction on a slope (sticking and sliding) in 2D
//! and 3D. Every step of every scene is checked for penetrations.

use std::path::Path;

use femp::run::{RunOptions, RunResult, run};
use femp::scene;

/// Run a scene without frames in a temporary directory.
fn try_run_scene(json: &str) -> Result<RunResult, femp::SimError> {
    let s = scene::parse(json, "test.json", Path::new(".").to_path_buf(), "test").unwrap();
    let dir = tempfile::tempdir().unwrap();
    run(
        s,
        dir.path(),
        &RunOptions {
            no_frames: true,
            ..Default::default()
        },
    )
}

/// Run a scene that must complete, checking every step for penetrations.
pub(crate) fn run_scene(json: &str) -> RunResult {
    let r = try_run_scene(json).unwrap();
    for m in &r.metrics {
        assert_eq!(m.penetrations, 0, "penetration at step {}", m.step);
    }
    r
}

fn block_on_plate(dt: f64, duration: f64) -> String {
    block_on_plate_with(dt, duration, "projected")
}

/// With the barrier Hessian `hessian` (`projected` or `gauss_newton`).
fn block_on_plate_with(dt: f64, duration: f64, hessian: &str) -> String {
    format!(
        r#"{{
  "dimension": 2, "gravity": [0, -9.81],
  "time": {{ "dt": {dt}, "duration": {duration} }},
  "solver": {{ "tolerance": 1e-5 }},
  "mpm": {{ "grid_spacing": 0.05 }},
  "bodies": [
    {{ "kind": "mpm", "name": "block", "shape": {{ "box": {{ "min": [-0.2, 0.05], "max": [0.2, 0.25] }} }},
      "material": {{ "E": 1e5, "nu": 0.3, "rho": 1000 }} }},
    {{ "kind": "fem", "name": "plate", "mesh": {{ "rectangle": {{ "min": [-1, -0.1], "max": [1, 0], "cells": [20, 1] }} }},
      "material": {{ "E": 1e7, "nu": 0.3, "rho": 1000 }}, "prescribed": [ {{ "vertices": "all", "motion": [] }} ] }}
  ],
  "contact": {{ "dhat": 0.005, "kappa": 1e5, "hessian": "{hessian}" }}
}}"#
    )
}

/// An MPM block dropped on a fixed FEM plate comes to rest above it, without any particle ever
/// entering the plate — at Δt = 1e-2 and at Δt = 1e-1 (where one step moves the block further
/// than the gap) — with either barrier Hessian.
#[test]
fn block_falls_on_plate_and_rests_at_large_time_steps() {
    for (dt, hessian) in [
        (1e-2, "projected"),
        (1e-1, "projected"),
        (1e-2, "gauss_newton"),
        (1e-1, "gauss_newton"),
    ] {
        let r = run_scene(&block_on_plate_with(dt, 1.5, hessian));
        let last = r.metrics.last().unwrap();
        let mass = 0.4 * 0.2 * 1000.0;
        // At rest: tiny speed, in contact (within d̂), the weight carried by the barrier.
        let speed = last.momentum[1].abs() / mass;
        assert!(
            speed < 0.05,
            "dt {dt}, {hessian}: still moving at {speed} m/s"
        );
        assert!(
            last.min_distance > 0.0 && last.min_distance < 0.005,
            "dt {dt}, {hessian}: min distance {}",
            last.min_distance
        );
        assert!(last.barrier_energy > 0.0);
        assert_eq!(r.summary.max_penetrations, 0);
    }
}

/// `solver.projection: "when_indefinite"`: the block comes to the same rest as with projected
/// Newton (the same minimisers, to the Newton tolerance), never entering the plate, and the
/// metrics count the iterations that used the exact Hessian; with the default none do.
#[test]
fn exact_hessian_when_definite_gives_the_same_steps() {
    let scene = |projection: &str| {
        block_on_plate(1e-2, 0.6).replace(
            r#""solver": { "tolerance": 1e-5 }"#,
            &format!(r#""solver": {{ "tolerance": 1e-5, "projection": "{projection}" }}"#),
        )
    };
    let p = run_scene(&scene("always"));
    let e = run_scene(&scene("when_indefinite"));
    assert_eq!(p.metrics.len(), e.metrics.len());
    assert!(p.metrics.iter().all(|m| m.exact_hessians == 0));
    let exact: usize = e.metrics.iter().map(|m| m.exact_hessians).sum();
    let newton: usize = e.metrics.iter().map(|m| m.newton_iterations).sum();
    assert!(exact > newton / 2, "{exact} of {newton} iterations exact");
    assert_eq!(e.summary.exact_hessian_iterations, exact);
    let mass = 0.4 * 0.2 * 1000.0;
    for (a, b) in p.metrics.iter().zip(&e.metrics) {
        // Both solves stop at ‖p‖∞/Δt < 1e-5 m/s: momenta agree to a few times that.
        let dv = (a.momentum[1] - b.momentum[1]).abs() / mass;
        assert!(dv < 1e-4, "step {}: velocities differ by {dv} m/s", a.step);
    }
    let last = e.metrics.last().unwrap();
    assert!(last.min_distance > 0.0 && last.min_distance < 0.005);
    assert_eq!(e.summary.max_penetrations, 0);
}

/// `World::contact_forces` is the reaction force: once the block rests on the plate, the
/// barrier force on its particles carries its weight.
#[test]
fn contact_force_carries_the_weight_at_rest() {
    let s = scene::parse(
        &block_on_plate(1e-2, 1.5),
        "test.json",
        Path::new(".").to_path_buf(),
        "test",
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut last = None;
    femp::run::run_with::<2>(
        s,
        dir.path(),
        &RunOptions {
            no_frames: true,
            ..Default::default()
        },
        |w, _| last = Some(w.contact_forces()),
    )
    .unwrap();
    let forces = last.unwrap();
    assert_eq!(forces.len(), 1);
    let f = &forces[0];
    assert_eq!(f.names, ("block".to_string(), "plate".to_string()));
    let weight = 0.4 * 0.2 * 1000.0 * 9.81;
    assert!(
        (f.on_points[1] - weight).abs() < 0.02 * weight && f.on_points[0].abs() < 0.02 * weight,
        "contact force {:?} vs weight {weight} N/m ({} terms)",
        f.on_points,
        f.terms
    );
}

/// A free MPM disk and a free FEM disk collide head-on without gravity: linear momentum is
/// conserved through the contact to the solver tolerance (the barrier is translation
/// invariant and the transfers conserve momentum), and they bounce apart.
/// A free MPM disk and a free FEM disk collide (no gravity): linear momentum is conserved to
/// the Newton tolerance through the collision — with Cholesky directions, and with CG ones
/// (`solver.linear: "pcg"`, exact Hessians when definite), which give the same steps.
#[test]
fn mpm_fem_collision_conserves_linear_momentum() {
    let scene = |solver: &str| {
        format!(
            r#"{{
  "dimension": 2,
  "time": {{ "dt": 0.002, "duration": 0.12 }},
  "solver": {{ "tolerance": 1e-9, "max_newton_iterations": 200{solver} }},
  "mpm": {{ "grid_spacing": 0.05 }},
  "bodies": [
    {{ "kind": "mpm", "name": "left", "shape": {{ "disk": {{ "center": [-0.32, 0.0], "radius": 0.3 }} }},
      "material": {{ "E": 1e6, "nu": 0.3, "rho": 1000 }}, "velocity": [2.0, 0.1] }},
    {{ "kind": "fem", "name": "right", "mesh": {{ "disk": {{ "center": [0.32, 0.05], "radius": 0.3, "rings": 6 }} }},
      "material": {{ "E": 1e6, "nu": 0.3, "rho": 1000 }}, "velocity": [-2.0, 0.0] }}
  ],
  "contact": {{ "dhat": 0.005, "kappa": 1e6 }}
}}"#
        )
    };
    let direct = run_scene(&scene(""));
    let cg = run_scene(&scene(
        r#", "linear": "pcg", "projection": "when_indefinite""#,
    ));
    // CG with Eisenstat–Walker forcing and Hessian reuse near convergence.
    let lean = run_scene(&scene(
        r#", "linear": "pcg", "projection": "when_indefinite", "pcg_rtol_max": 1e-2, "reuse_hessian_below": 1e-3"#,
    ));
    assert!(lean.summary.reused_hessians > 0, "{:?}", lean.summary);
    let reused: usize = lean.metrics.iter().map(|m| m.reused_hessians).sum();
    assert_eq!(reused, lean.summary.reused_hessians);
    assert_eq!(cg.summary.reused_hessians, 0);
    assert!(
        lean.summary.pcg_iterations < cg.summary.pcg_iterations,
        "{:?} vs {:?}",
        lean.summary,
        cg.summary
    );
    assert_eq!(direct.summary.pcg_iterations, 0);
    assert!(direct.metrics.iter().all(|m| m.pcg_iterations == 0));
    assert!(
        cg.summary.pcg_iterations >= cg.summary.newton_iterations,
        "{:?}",
        cg.summary
    );
    // The per-step column adds up to the run's total, and every step that iterated used CG.
    let per_step: usize = cg.metrics.iter().map(|m| m.pcg_iterations).sum();
    assert_eq!(per_step, cg.summary.pcg_iterations);
    assert!(
        cg.metrics
            .iter()
            .all(|m| (m.newton_iterations == 0) == (m.pcg_iterations == 0))
    );
    for r in [&direct, &cg, &lean] {
        let p0 = r.metrics[0].momentum;
        let scale = r.metrics[0].kinetic_energy.sqrt() * 30.0; // ~ Σ m |v|
        let mut touched = false;
        for m in &r.metrics {
            touched |= m.barrier_energy > 0.0;
            for a in 0..2 {
                assert!(
                    (m.momentum[a] - p0[a]).abs() <= 1e-6 * scale,
                    "step {}: momentum {:?} vs {:?}",
                    m.step,
                    m.momentum,
                    p0
                );
            }
        }
        assert!(touched, "the disks never came into contact");
    }
    // The same steps: all solves stop at ‖p‖∞/Δt < 1e-9 m/s.
    assert_eq!(direct.metrics.len(), cg.metrics.len());
    assert_eq!(direct.metrics.len(), lean.metrics.len());
    for (a, b) in direct
        .metrics
        .iter()
        .zip(&cg.metrics)
        .chain(direct.metrics.iter().zip(&lean.metrics))
    {
        let de = (a.kinetic_energy - b.kinetic_energy).abs() / a.kinetic_energy;
        assert!(
            de < 1e-6,
            "step {}: kinetic energies differ by {de:e}",
            a.step
        );
        assert!(
            (a.barrier_energy - b.barrier_energy).abs() <= 1e-6 * a.kinetic_energy,
            "step {}: barrier energies {} vs {}",
            a.step,
            a.barrier_energy,
            b.barrier_energy
        );
    }
}

/// A stiff MPM block on a fixed FEM slope of tan θ = 0.2 with friction `mu` (§6.4), with more
/// `solver` fields in `extra` (empty or starting with a comma).
fn slope_with(mu: f64, dim: usize, extra: &str) -> String {
    let theta = -(0.2f64).atan().to_degrees();
    if dim == 2 {
        format!(
            r#"{{
  "dimension": 2, "gravity": [0, -9.81],
  "time": {{ "dt": 0.005, "duration": 0.3 }},
  "solver": {{ "tolerance": 1e-6{extra} }},
  "mpm": {{ "grid_spacing": 0.01 }},
  "bodies": [
    {{ "kind": "mpm", "name": "block",
      "shape": {{ "box": {{ "min": [-0.05, 0.0005], "max": [0.05, 0.0205], "transform": {{ "rotate_deg": {theta} }} }} }},
      "material": {{ "E": 1e8, "nu": 0.2, "rho": 100 }} }},
    {{ "kind": "fem", "name": "slope", "mesh": {{ "rectangle": {{ "min": [-1, -0.1], "max": [1, 0], "cells": [40, 2] }} }},
      "transform": {{ "rotate_deg": {theta} }},
      "material": {{ "E": 1e9, "nu": 0.3, "rho": 1000 }}, "prescribed": [ {{ "vertices": "all", "motion": [] }} ] }}
  ],
  "contact": {{ "dhat": 0.001, "kappa": 1e6, "friction": {mu}, "eps_v": 1e-5 }}
}}"#
        )
    } else {
        format!(
            r#"{{
  "dimension": 3, "gravity": [0, -9.81, 0],
  "time": {{ "dt": 0.005, "duration": 0.15 }},
  "solver": {{ "tolerance": 1e-6{extra} }},
  "mpm": {{ "grid_spacing": 0.02 }},
  "bodies": [
    {{ "kind": "mpm", "name": "block",
      "shape": {{ "box": {{ "min": [-0.04, 0.0005, -0.04], "max": [0.04, 0.0405, 0.04], "transform": {{ "rotate_deg": {theta}, "axis": [0, 0, 1] }} }} }},
      "material": {{ "E": 1e8, "nu": 0.2, "rho": 100 }} }},
    {{ "kind": "fem", "name": "slope", "mesh": {{ "cuboid": {{ "min": [-0.6, -0.05, -0.2], "max": [0.6, 0, 0.2], "cells": [12, 1, 4] }} }},
      "transform": {{ "rotate_deg": {theta}, "axis": [0, 0, 1] }},
      "material": {{ "E": 1e9, "nu": 0.3, "rho": 1000 }}, "prescribed": [ {{ "vertices": "all", "motion": [] }} ] }}
  ],
  "contact": {{ "dhat": 0.001, "kappa": 1e6, "friction": {mu}, "eps_v": 1e-5 }}
}}"#
        )
    }
}

/// Along-slope speed of the block's centre of mass after it lands, and the time it landed.
fn slope_velocity(r: &RunResult, mass: f64) -> Vec<(f64, f64)> {
    let th = 0.2f64.atan();
    let dir = [th.cos(), -th.sin()];
    r.metrics
        .iter()
        .map(|m| {
            (
                m.t,
                (m.momentum[0] * dir[0] + m.momentum[1] * dir[1]) / mass,
            )
        })
        .collect()
}

fn check_slope(dim: usize) {
    check_slope_with(dim, "");
}

fn check_slope_with(dim: usize, extra: &str) {
    let g = 9.81;
    let th = 0.2f64.atan();
    let mass = if dim == 2 {
        0.1 * 0.02 * 100.0
    } else {
        0.08 * 0.04 * 0.08 * 100.0
    };
    // Slides: a = g (sin θ − μ cos θ).
    for mu in [0.0, 0.1] {
        let r = run_scene(&slope_with(mu, dim, extra));
        let v = slope_velocity(&r, mass);
        let a = g * (th.sin() - mu * th.cos());
        // Fit the acceleration over the second half (after landing).
        let n = v.len();
        let (t0, v0) = v[n / 2];
        let (t1, v1) = v[n - 1];
        let fitted = (v1 - v0) / (t1 - t0);
        assert!(
            (fitted - a).abs() <= 2e-3 * a,
            "{dim}D μ = {mu}: acceleration {fitted} vs {a}"
        );
    }
    // Sticks: μ ≥ tan θ = 0.2 → (mollified) static friction holds the block.
    let r = run_scene(&slope_with(0.25, dim, extra));
    let v = slope_velocity(&r, mass);
    let vmax = v[v.len() / 2..]
        .iter()
        .map(|x| x.1.abs())
        .fold(0.0, f64::max);
    assert!(vmax < 1e-3, "{dim}D μ = 0.25: block slides at {vmax} m/s");
}

#[test]
fn slope_2d_sticks_and_slides() {
    check_slope(2);
}

#[test]
fn slope_3d_sticks_and_slides() {
    check_slope(3);
}

/// The same accelerations with the friction operator updated inside Newton's iterations and
/// Newton's test measured on the particles (`solver.friction_update_below`, `newton_test`).
#[test]
fn slope_sticks_and_slides_with_friction_updated_in_newton_and_the_point_test() {
    let extra = r#", "friction_update_below": 1e-4, "newton_test": "points""#;
    check_slope_with(2, extra);
    check_slope_with(3, extra);
}

/// The same accelerations with inexact friction solves while the operator moves
/// (`solver.friction_forcing`): the loop still ends at the fully implicit fixed point.
#[test]
fn slope_sticks_and_slides_with_inexact_friction_solves() {
    let extra = r#", "friction_forcing": 0.1"#;
    check_slope_with(2, extra);
    check_slope_with(3, extra);
}

/// The same accelerations with later Newton iterations solved by CG preconditioned with the
/// last factorisation (`solver.linear: "last_factor_cg"`).
#[test]
fn slope_sticks_and_slides_with_directions_from_the_last_factor() {
    let extra = r#", "linear": "last_factor_cg""#;
    check_slope_with(2, extra);
    check_slope_with(3, extra);
}

/// The same accelerations with single-precision factorisations refined to double precision
/// (`solver.factor_precision: "mixed"`), alone and as the last factor preconditioning CG.
#[test]
fn slope_sticks_and_slides_with_single_precision_factors() {
    for extra in [
        r#", "factor_precision": "mixed""#,
        r#", "factor_precision": "mixed", "linear": "last_factor_cg""#,
    ] {
        check_slope_with(2, extra);
        check_slope_with(3, extra);
    }
}

/// A 2D MPM block thrown down and sideways onto a fixed FEM plate with friction μ = 0.5, for
/// `duration` s, with the given `solver` fields.
fn sliding_block_2d(duration: f64, solver: &str) -> String {
    format!(
        r#"{{ "dimension": 2, "gravity": [0, -9.81],
          "time": {{ "dt": 0.01, "duration": {duration} }},
          "solver": {{ {solver} }},
          "mpm": {{ "grid_spacing": 0.05 }},
          "bodies": [
            {{ "kind": "mpm", "name": "block", "shape": {{ "box": {{ "min": [-0.2, 0.004], "max": [0.2, 0.204] }} }},
              "material": {{ "E": 1e5, "nu": 0.3, "rho": 1000 }}, "velocity": [1.0, -0.5] }},
            {{ "kind": "fem", "name": "plate",
              "mesh": {{ "rectangle": {{ "min": [-2, -0.1], "max": [2, 0], "cells": [40, 1] }} }},
              "material": {{ "E": 1e7, "nu": 0.3, "rho": 1000 }},
              "prescribed": [ {{ "vertices": "all", "motion": [] }} ] }} ],
          "contact": {{ "dhat": 0.005, "kappa": 1e5, "friction": 0.5 }} }}"#
    )
}

/// The contact forces in `metrics.csv` are the forces that change the bodies' momenta: with
/// backward Euler a body's momentum changes over a step by `Δt (F_contact + M g)` (the elastic
/// forces cancel, the transfers conserve momentum), so the reported force is checked against
/// the impulse of every step — of a 2D block sliding and sticking on a plate with friction, and
/// of a 3D one. The friction part opposes the sliding, and the plate feels the opposite force.
#[test]
fn contact_forces_in_the_metrics_are_the_impulse_of_every_step() {
    for (d, json) in [
        (
            2,
            sliding_block_2d(0.3, r#""tolerance": 1e-9, "max_friction_iterations": 50"#),
        ),
        (
            3,
            r#"{ "dimension": 3, "gravity": [0, -9.81, 0],
              "time": { "dt": 0.01, "duration": 0.1 },
              "solver": { "tolerance": 1e-9, "max_friction_iterations": 50 },
              "mpm": { "grid_spacing": 0.1 },
              "bodies": [
                { "kind": "mpm", "name": "block", "shape": { "box": { "min": [-0.2, 0.004, -0.2], "max": [0.2, 0.204, 0.2] } },
                  "material": { "E": 1e5, "nu": 0.3, "rho": 1000 }, "velocity": [1.0, -0.5, 0.3] },
                { "kind": "fem", "name": "plate",
                  "mesh": { "cuboid": { "min": [-1, -0.1, -1], "max": [1, 0, 1], "cells": [4, 1, 4] } },
                  "material": { "E": 1e7, "nu": 0.3, "rho": 1000 },
                  "prescribed": [ { "vertices": "all", "motion": [] } ] } ],
              "contact": { "dhat": 0.005, "kappa": 1e5, "friction": 0.5 } }"#
                .to_string(),
        ),
    ] {
        let json = &json;
        let r = run_scene(json);
        let (dt, g) = (0.01, [0.0, -9.81, 0.0]);
        // The plate is prescribed at rest: the momentum in the metrics is the block's.
        let mass: f64 = {
            let s = scene::parse(json, "m.json", ".".into(), "m").unwrap();
            match d {
                2 => femp::World::<2>::build(s)
                    .unwrap()
                    .bodies.mpm
                    .unwrap()
                    .mass
                    .iter()
                    .sum(),
                _ => femp::World::<3>::build(s)
                    .unwrap()
                    .bodies.mpm
                    .unwrap()
                    .mass
                    .iter()
                    .sum(),
            }
        };
        let mut contact_steps = 0;
        let mut friction_seen = 0.0f64;
        for k in 1..r.metrics.len() {
            let (m0, m1) = (&r.metrics[k - 1], &r.metrics[k]);
            let f = m1.contact_forces[0];
            let fr = m1.friction_forces[0];
            for a in 0..d {
                let impulse = m1.momentum[a] - m0.momentum[a];
                let expected = dt * (f[a] + mass * g[a]);
                assert!(
                    (impulse - expected).abs() <= 1e-6 * dt * mass * 9.81,
                    "{d}D step {k}, axis {a}: Δp = {impulse:e}, Δt (F + Mg) = {expected:e}"
                );
                // Action and reaction.
                assert_eq!(m1.contact_forces[1][a], -f[a]);
                assert_eq!(m1.friction_forces[1][a], -fr[a]);
            }
            if f[1] > 0.0 {
                contact_steps += 1;
                // Coulomb: the friction force is at most μ times the normal force.
                let tangential = (fr[0] * fr[0] + fr[2] * fr[2]).sqrt();
                assert!(
                    tangential <= 0.5 * f[1] * (1.0 + 1e-6),
                    "{d}D step {k}: friction {fr:?} against normal {}",
                    f[1]
                );
                // While the block slides, friction opposes its motion.
                if m1.momentum[0] / mass > 0.05 {
                    assert!(fr[0] < 0.0, "{d}D step {k}: friction {fr:?}");
                }
                friction_seen = friction_seen.max(tangential);
            }
        }
        assert!(contact_steps >= 3, "{d}D: {contact_steps} steps in contact");
        assert!(friction_seen > 0.1 * mass, "{d}D: friction {friction_seen}");
    }
}

/// The per-particle and per-vertex contact forces of the frames add up to the per-body forces of
/// the metrics, step by step: the block's particles to the block's force, the plate's vertices
/// to the plate's.
#[test]
fn per_point_contact_forces_add_up_to_the_body_forces() {
    let json = &sliding_block_2d(0.1, r#""tolerance": 1e-7"#);
    let s = scene::parse(json, "p.json", ".".into(), "p").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut checked = 0;
    femp::run::run_with::<2>(
        s,
        dir.path(),
        &RunOptions {
            no_frames: true,
            ..Default::default()
        },
        |w, m| {
            let particles: nalgebra::Vector2<f64> =
                w.bodies.mpm.as_ref().unwrap().contact_force.iter().sum();
            let plate: nalgebra::Vector2<f64> = w.bodies.fem[0].contact_force.iter().sum();
            for a in 0..2 {
                let scale = m.contact_forces[0][a].abs().max(1e-9);
                assert!((particles[a] - m.contact_forces[0][a]).abs() <= 1e-9 * scale);
                assert!((plate[a] - m.contact_forces[1][a]).abs() <= 1e-9 * scale);
            }
            if m.contact_forces[0][1] > 0.0 {
                checked += 1;
            }
        },
    )
    .unwrap();
    assert!(checked >= 3, "{checked} steps in contact");
}

/// 3D FEM–FEM contact has no edge–edge terms: the world says so (check, run, summary.json),
/// and says nothing for MPM–FEM contact in 3D.
#[test]
fn three_d_fem_fem_contact_is_flagged_as_vertex_facet_only() {
    let body = |name: &str, y0: f64, y1: f64| {
        format!(
            r#"{{ "kind": "fem", "name": "{name}",
                  "mesh": {{ "cuboid": {{ "min": [0, {y0}, 0], "max": [1, {y1}, 1], "cells": [1, 1, 1] }} }},
                  "material": {{ "E": 1e6, "nu": 0.3, "rho": 1000 }} }}"#
        )
    };
    let scene = |bodies: String| {
        format!(
            r#"{{ "dimension": 3, "time": {{ "dt": 0.01, "duration": 0.01 }}, "mpm": {{ "grid_spacing": 0.5 }},
                 "bodies": [ {bodies} ], "contact": {{ "dhat": 0.01, "kappa": 1e5 }} }}"#
        )
    };
    let fem_fem = scene(format!("{}, {}", body("a", 0.0, 1.0), body("b", 1.1, 2.0)));
    let w = femp::World::<3>::build(scene::parse(&fem_fem, "s.json", ".".into(), "s").unwrap())
        .unwrap()
        .warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains("edge–edge") && w[0].contains("`a`"),
        "{}",
        w[0]
    );
    let mpm_fem = scene(format!(
        r#"{}, {{ "kind": "mpm", "name": "m", "shape": {{ "box": {{ "min": [0, 1.1, 0], "max": [1, 2, 1] }} }},
                  "material": {{ "E": 1e6, "nu": 0.3, "rho": 1000 }} }}"#,
        body("a", 0.0, 1.0)
    ));
    let w = femp::World::<3>::build(scene::parse(&mpm_fem, "s.json", ".".into(), "s").unwrap())
        .unwrap()
        .warnings();
    assert!(w.is_empty(), "{w:?}");
}

/// The quick validation tier's §6.2 scene (an MPM box pressed down onto a prescribed sine-wave
/// FEM strip, dragged sideways) with projected Newton limited to 30 iterations: while the strip
/// drags the box, some steps need 36–48 projected iterations (linear convergence) but at most
/// 20 with the exact Hessian. With `solver.retry_other_projection` (the default) those steps
/// are solved again with the exact Hessian where it is definite and the run goes on; without it
/// the run stops at the first. Those steps are projected Newton creeping with full steps along
/// directions the energy is flatter along than the projected Hessian says: with
/// `solver.line_search_expansion` (`expansion` > 1) they take 30 or fewer.
fn sine_strip(retry: bool, expansion: f64) -> String {
    format!(
        r#"{{
  "dimension": 2, "gravity": [0.0, -9.81],
  "time": {{ "dt": 0.004, "duration": 0.76 }},
  "solver": {{ "tolerance": 1e-4, "max_newton_iterations": 30, "projection": "always",
              "retry_other_projection": {retry}, "line_search_expansion": {expansion} }},
  "mpm": {{ "grid_spacing": 0.05 }},
  "bodies": [
    {{ "kind": "mpm", "name": "box", "shape": {{ "box": {{ "min": [0.0, 0.0], "max": [1.0, 1.0] }} }},
      "particles_per_cell": 4, "material": {{ "E": 1e6, "nu": 0.2, "rho": 1000 }} }},
    {{ "kind": "fem", "name": "sine",
      "mesh": {{ "cosine_strip": {{ "x0": -0.6, "x1": 1.6, "offset": 1.2, "amplitude": 0.025,
                                   "wavelength": 0.1, "thickness": 0.1, "cells": [440, 2] }} }},
      "material": {{ "E": 1e8, "nu": 0.3, "rho": 1000 }},
      "prescribed": [ {{ "vertices": "all", "motion": [
        {{ "until": 0.6, "velocity": [0.0, -1.0] }},
        {{ "until": 1.1, "velocity": [-1.0, 0.0] }},
        {{ "until": 1.8, "velocity": [0.0, 1.0] }} ] }} ] }}
  ],
  "contact": {{ "dhat": 0.001, "kappa": 1e4 }},
  "boundaries": [ {{ "shape": {{ "half_plane": {{ "point": [0.0, 0.0], "normal": [0.0, 1.0] }} }},
                    "condition": "no_slip" }} ]
}}"#
    )
}

#[test]
fn a_step_whose_solve_fails_is_solved_again_with_the_other_projection() {
    let r = run_scene(&sine_strip(true, 1.0));
    assert_eq!(r.summary.steps, 190);
    assert!(r.summary.retried_steps >= 1, "{:?}", r.summary);
    // The failed attempt's 30 iterations count in a retried step's row, with the retry's own
    // (which used exact Hessians).
    let retried = r
        .metrics
        .iter()
        .filter(|m| m.newton_iterations > 30)
        .count();
    assert_eq!(retried, r.summary.retried_steps);
    assert!(
        r.metrics
            .iter()
            .any(|m| m.newton_iterations > 30 && m.exact_hessians > 0)
    );
    assert!(
        r.summary
            .warnings
            .iter()
            .any(|w| w.contains("retry_other_projection")),
        "{:?}",
        r.summary.warnings
    );
    // Without the retry the same step stops the run, naming the failure.
    let err = try_run_scene(&sine_strip(false, 1.0))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("failed: Newton did not converge in 30 iterations"),
        "{err}"
    );
}

/// `solver.line_search_expansion` (the default 64) on the strip above: projected Newton alone,
/// 30 iterations a solve and no retry, runs all 190 steps — the steps that needed 36–48 creep
/// no more — with 0 penetrations, and fewer Newton iterations than the run that retried.
#[test]
fn expanding_steps_let_projected_newton_drag_the_box_within_30_iterations() {
    let r = run_scene(&sine_strip(false, 64.0));
    assert_eq!(r.summary.steps, 190);
    assert_eq!(r.summary.retried_steps, 0);
    assert!(r.summary.expanded_steps > 0, "{:?}", r.summary);
    assert_eq!(r.summary.max_penetrations, 0);
    assert!(r.metrics.iter().all(|m| m.newton_iterations <= 30));
    let retrying = run_scene(&sine_strip(true, 1.0));
    assert!(
        r.summary.newton_iterations < retrying.summary.newton_iterations,
        "{} Newton iterations expanding against {} retrying",
        r.summary.newton_iterations,
        retrying.summary.newton_iterations
    );
}

/// Two elastic boxes, one MPM and one FEM, meeting head-on at 1 m/s (the `compare` experiment's
/// impact scene at h = 1/32, backward Euler here), frictionless, with the last factorisation as
/// CG's preconditioner at a loose `rtol`. Over the first 80 steps Newton on these CG directions
/// needs up to 30 iterations a step (step 43, as the boxes press together) where direct solves
/// need at most 15.
fn loose_cg_impact(max_newton: usize, duration: f64) -> String {
    format!(
        r#"{{
  "dimension": 2,
  "time": {{ "dt": 0.0025, "duration": {duration}, "integrator": "backward_euler" }},
  "solver": {{ "tolerance": 1e-5, "max_newton_iterations": {max_newton},
              "linear": "last_factor_cg", "factor_cg_rtol": 0.3,
              "retry_other_projection": false }},
  "mpm": {{ "grid_spacing": 0.03125 }},
  "bodies": [
    {{ "kind": "mpm", "name": "a", "shape": {{ "box": {{ "min": [-1.05, 0.0], "max": [-0.05, 0.5] }} }},
      "particles_per_cell": 4, "velocity": [0.5, 0.0],
      "material": {{ "model": "linear", "E": 1e5, "nu": 0.0, "rho": 1000 }} }},
    {{ "kind": "fem", "name": "b",
      "mesh": {{ "rectangle": {{ "min": [0.05, 0.0], "max": [1.05, 0.5], "cells": [32, 16] }} }},
      "velocity": [-0.5, 0.0],
      "material": {{ "model": "linear", "E": 1e5, "nu": 0.0, "rho": 1000 }} }}
  ],
  "contact": {{ "dhat": 0.001, "kappa": 1e6 }}
}}"#
    )
}

/// A solve with CG directions (`solver.linear: "last_factor_cg"`) that fails is solved again
/// from the step's start with direct solves, before and independently of
/// `solver.retry_other_projection` (off here): the run goes through, the retried steps counted
/// and their failed attempts' iterations in their rows.
#[test]
fn a_step_whose_cg_solve_fails_is_solved_again_with_direct_solves() {
    let r = run_scene(&loose_cg_impact(20, 0.125));
    assert_eq!(r.summary.steps, 50);
    assert!(r.summary.retried_steps >= 1, "{:?}", r.summary);
    let retried = r
        .metrics
        .iter()
        .filter(|m| m.newton_iterations > 20)
        .count();
    assert_eq!(retried, r.summary.retried_steps);
    assert!(
        r.summary
            .warnings
            .iter()
            .any(|w| w.contains("direct solves")),
        "{:?}",
        r.summary.warnings
    );
    assert_eq!(r.summary.max_penetrations, 0);
    // When the direct solves fail too, the run stops with both errors, the retry's first.
    let err = try_run_scene(&loose_cg_impact(8, 0.125))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("), retried with direct solves after: step")
            && err
                .matches("failed: Newton did not converge in 8 iterations")
                .count()
                == 2,
        "{err}"
    );
    // `"auto"` solves this small system's directions directly (its factor is far from large):
    // a failed step is not solved again the same way.
    let auto = loose_cg_impact(8, 0.125).replace(r#""last_factor_cg""#, r#""auto""#);
    assert!(auto.contains(r#""linear": "auto""#));
    let err = try_run_scene(&auto).unwrap_err().to_string();
    assert!(
        !err.contains("retried")
            && err
                .matches("failed: Newton did not converge in 8 iterations")
                .count()
                == 1,
        "{err}"
    );
}

/// `World::record_newton_iterations`: every Newton iteration of a step is recorded, with the
/// unknown its largest increment sat on — grid nodes with their mass, FEM vertices with their
/// body's lumped mass — and recording stops when asked.
#[test]
fn recorded_newton_iterations_name_the_unknown_of_the_largest_increment() {
    // The plate is free here, so both kinds of unknown move; Newton's test on the unknowns.
    let json = block_on_plate(0.01, 1.0)
        .replace(
            r#", "prescribed": [ { "vertices": "all", "motion": [] } ]"#,
            "",
        )
        .replace(
            r#""tolerance": 1e-5 }"#,
            r#""tolerance": 1e-5, "newton_test": "nodes" }"#,
        );
    assert!(!json.contains("prescribed") && json.contains(r#""nodes""#));
    let s = scene::parse(&json, "t.json", ".".into(), "t").unwrap();
    let mut w = femp::World::<2>::build(s).unwrap();
    assert!(w.record_newton_iterations(true));
    let (mut grid, mut fem) = (0, 0);
    for _ in 0..5 {
        let r = w.step().unwrap();
        assert_eq!(r.stats.trace.len(), r.newton_iterations);
        assert_eq!(r.largest_increments.len(), r.newton_iterations);
        assert_eq!(r.stats.trace[0].iteration, 1);
        for (rec, on) in r.stats.trace.iter().zip(&r.largest_increments) {
            // The test on the unknowns is the largest increment itself.
            assert_eq!(rec.increment, rec.largest.1, "{rec:?}");
            match *on {
                femp::Unknown::GridNode { axis, mass, .. } => {
                    assert!(axis < 2 && mass > 0.0, "{on:?}");
                    grid += 1;
                }
                femp::Unknown::FemVertex {
                    body,
                    vertex,
                    axis,
                    mass,
                } => {
                    assert_eq!((body, axis < 2), (0, true));
                    assert_eq!(mass, w.bodies.fem[0].mass[vertex], "{on:?}");
                    fem += 1;
                }
            }
        }
    }
    assert!(grid > 0 && fem > 0, "grid {grid}, fem {fem}");
    w.record_newton_iterations(false);
    let r = w.step().unwrap();
    assert!(r.stats.trace.is_empty() && r.largest_increments.is_empty());
}
