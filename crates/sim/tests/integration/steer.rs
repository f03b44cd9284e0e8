//! Steering a world from outside ([`femp::steer`]): external forces give exactly the
//! acceleration and impulse they should in both methods, prescribed vertices are where they
//! were sent while the barrier keeps the particles out, states that would put a body into
//! another or invert an element are refused with the world unchanged — and a world stepped by
//! hand and recorded with [`femp::run::Recorder`] writes the same files as `femp run`.

use std::path::Path;

use femp::run::{Recorder, RunOptions};
use femp::scene::{self, Scene};
use femp::{SimError, World};
use nalgebra::Vector2;
use serde_json::{Value, json};

fn parse(v: &Value) -> Scene {
    scene::parse(&v.to_string(), "steer.json", Path::new(".").into(), "steer").unwrap()
}

/// An MPM block and a free FEM block side by side, far apart, no gravity; optionally a fixed
/// plate under the MPM block.
fn two_blocks(plate: bool) -> Value {
    let mut bodies = vec![
        json!({ "kind": "mpm", "name": "block",
                "shape": { "box": { "min": [-0.2, 0.02], "max": [0.2, 0.22] } },
                "material": { "E": 1e5, "nu": 0.3, "rho": 1000 } }),
        json!({ "kind": "fem", "name": "pusher",
                "mesh": { "rectangle": { "min": [-0.6, 0.03], "max": [-0.4, 0.2], "cells": [2, 2] } },
                "material": { "E": 1e6, "nu": 0.3, "rho": 1000 } }),
    ];
    if plate {
        bodies.push(json!({ "kind": "fem", "name": "plate",
            "mesh": { "rectangle": { "min": [-1, -0.1], "max": [1, 0], "cells": [20, 1] } },
            "material": { "E": 1e7, "nu": 0.3, "rho": 1000 },
            "prescribed": [ { "vertices": "all", "motion": [] } ] }));
    }
    json!({
        "dimension": 2,
        "time": { "dt": 0.01, "duration": 0.2 },
        "solver": { "tolerance": 1e-6 },
        "mpm": { "grid_spacing": 0.05 },
        "bodies": bodies,
        "contact": { "dhat": 0.005, "kappa": 1e5 }
    })
}

fn pusher(w: &World<2>) -> usize {
    w.fem_index("pusher").unwrap()
}

/// A force proportional to mass is a uniform acceleration: every particle and vertex, started
/// at rest with nothing touching, moves at exactly `n Δt a` after `n` steps — in BFEMP through
/// the grid (`f_i = Σ_p w_ip f_p` over `m_i = Σ_p w_ip m_p`) as on the FEM vertices. Without
/// forces set again, the next step adds nothing.
#[test]
fn forces_proportional_to_mass_accelerate_uniformly_in_bfemp() {
    let mut w = World::<2>::build(parse(&two_blocks(false))).unwrap();
    let (ap, af) = (Vector2::new(1.0, 0.5), Vector2::new(-2.0, 1.0));
    let k = pusher(&w);
    let n = 4;
    for _ in 0..n {
        let fp: Vec<_> = w
            .bodies
            .mpm
            .as_ref()
            .unwrap()
            .mass
            .iter()
            .map(|m| ap * *m)
            .collect();
        let ff: Vec<_> = w.bodies.fem[k].mass.iter().map(|m| af * *m).collect();
        w.apply_particle_forces(&fp).unwrap();
        w.apply_fem_forces("pusher", &ff).unwrap();
        w.step().unwrap();
        assert!(w.bodies.loads.is_empty(), "forces act for one step");
    }
    let t = n as f64 * w.clock.dt;
    let m = w.bodies.mpm.as_ref().unwrap();
    for v in &m.v {
        assert!((v - ap * t).norm() < 1e-9 * t, "particle v {v:?}");
    }
    for v in &w.bodies.fem[k].v {
        assert!((v - af * t).norm() < 1e-9 * t, "vertex v {v:?}");
    }
    // No force this step: the velocities stay.
    w.step().unwrap();
    let m = w.bodies.mpm.as_ref().unwrap();
    assert!(m.v.iter().all(|v| (v - ap * t).norm() < 1e-9 * t));
    assert!(
        w.driven(),
        "a steered world does not warn about its energy rising"
    );
}

/// One force on one particle and one on one vertex: the total momentum grows by their impulse
/// `n Δt f` (the grid spreads a particle's force with weights that sum to 1; elastic forces
/// cancel), to the Newton tolerance.
#[test]
fn a_point_force_adds_its_impulse_to_the_momentum() {
    let mut w = World::<2>::build(parse(&two_blocks(false))).unwrap();
    let k = pusher(&w);
    let np = w.bodies.mpm.as_ref().unwrap().x.len();
    let nv = w.bodies.fem[k].x.len();
    let (f1, f2) = (Vector2::new(3.0, -1.0), Vector2::new(0.0, 2.0));
    let n = 3;
    for _ in 0..n {
        let mut fp = vec![Vector2::zeros(); np];
        fp[np / 2] = f1;
        let mut ff = vec![Vector2::zeros(); nv];
        ff[nv - 1] = f2;
        w.apply_particle_forces(&fp).unwrap();
        w.apply_fem_forces("pusher", &ff).unwrap();
        w.step().unwrap();
    }
    let p = w.measure().momentum;
    let expect = (f1 + f2) * (n as f64 * w.clock.dt);
    for a in 0..2 {
        assert!(
            (p[a] - expect[a]).abs() < 1e-6 * expect.norm(),
            "momentum {p:?}, impulse {expect:?}"
        );
    }
}

/// Augury: a mass-proportional force accelerates free FEM blocks uniformly (velocity Verlet
/// with the force in the accelerations), exactly.
#[test]
fn forces_proportional_to_mass_accelerate_uniformly_in_augury() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/augury_blocks.json");
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
    for b in v["bodies"].as_array_mut().unwrap() {
        b.as_object_mut().unwrap().remove("velocity");
    }
    let mut w = World::<2>::build(parse(&v)).unwrap();
    let a = Vector2::new(0.5, -0.25);
    let n = 10;
    for _ in 0..n {
        for name in ["a", "b"] {
            let k = w.fem_index(name).unwrap();
            let f: Vec<_> = w.bodies.fem[k].mass.iter().map(|m| a * *m).collect();
            w.apply_fem_forces(name, &f).unwrap();
        }
        w.step().unwrap();
    }
    let t = n as f64 * w.clock.dt;
    for b in &w.bodies.fem {
        for v in &b.v {
            assert!((v - a * t).norm() < 1e-12, "{}: v {v:?}", b.name);
        }
    }
}

/// A controller drives the pusher's left side into the MPM block resting on a fixed plate:
/// after every step the driven vertices are exactly at their targets, no particle is inside a
/// body, the block is pushed along +x and the contact force on it points along +x.
#[test]
fn prescribed_vertices_push_a_block_without_penetration() {
    let mut w = World::<2>::build(parse(&two_blocks(true))).unwrap();
    let k = pusher(&w);
    let left: Vec<usize> = (0..w.bodies.fem[k].x.len())
        .filter(|&v| w.bodies.fem[k].x[v][0] < -0.6 + 1e-9)
        .collect();
    assert_eq!(left.len(), 3);
    let x_block0 = w
        .bodies
        .mpm
        .as_ref()
        .unwrap()
        .x
        .iter()
        .map(|x| x[0])
        .sum::<f64>();
    for _ in 0..20 {
        let targets: Vec<_> = left
            .iter()
            .map(|&v| w.bodies.fem[k].x[v] + Vector2::new(0.015, 0.0))
            .collect();
        w.prescribe("pusher", &left, &targets).unwrap();
        w.step().unwrap();
        for (&v, t) in left.iter().zip(&targets) {
            assert!((w.bodies.fem[k].x[v] - t).norm() < 1e-12, "vertex {v}");
        }
        assert_eq!(w.measure().penetrations, 0);
    }
    let m = w.bodies.mpm.as_ref().unwrap();
    let x_block = m.x.iter().map(|x| x[0]).sum::<f64>();
    assert!(
        x_block > x_block0 + 1e-3 * m.x.len() as f64,
        "the block was pushed"
    );
    let push: f64 = m.contact_force.iter().map(|f| f[0]).sum();
    assert!(push > 0.0, "contact force on the block {push}");
}

fn refused(r: Result<impl std::fmt::Debug, SimError>, what: &str, why: &str) {
    match r {
        Err(SimError::State { what: w, message }) => {
            assert_eq!(w, what, "{message}");
            assert!(message.contains(why), "{what}: {message}");
        }
        other => panic!("{what}: expected a State error containing {why:?}, got {other:?}"),
    }
}

/// States and targets the world cannot take are refused by name, and the world is unchanged.
#[test]
fn bad_states_are_refused_and_change_nothing() {
    let mut w = World::<2>::build(parse(&two_blocks(true))).unwrap();
    let k = pusher(&w);
    let x0 = w.bodies.mpm.as_ref().unwrap().x.clone();
    let fx0 = w.bodies.fem[k].x.clone();
    // A particle into the plate.
    let mut x = x0.clone();
    x[0] = Vector2::new(0.0, -0.05);
    refused(
        w.set_particle_positions(&x),
        "particles.x",
        "into (or onto) `plate`",
    );
    assert_eq!(w.bodies.mpm.as_ref().unwrap().x, x0);
    // Wrong length, non-finite.
    refused(
        w.set_particle_velocities(&x0[1..]),
        "particles.v",
        "expected",
    );
    let mut bad = x0.clone();
    bad[3][1] = f64::NAN;
    refused(
        w.set_particle_positions(&bad),
        "particles.x",
        "row 3 is not finite",
    );
    // The pusher into the block, and inverted.
    let into: Vec<_> = fx0.iter().map(|x| x + Vector2::new(0.45, 0.0)).collect();
    refused(
        w.set_fem_positions("pusher", &into),
        "fem[pusher].x",
        "into (or onto)",
    );
    let mut flipped = fx0.clone();
    flipped[0] = fx0[fx0.len() - 1] + Vector2::new(0.1, 0.1);
    refused(
        w.set_fem_positions("pusher", &flipped),
        "fem[pusher].x",
        "inverted",
    );
    assert_eq!(w.bodies.fem[k].x, fx0);
    // The plate is the scene's to move; an unknown body; a vertex twice or out of range.
    let plate = w.fem_index("plate").unwrap();
    let px = w.bodies.fem[plate].x[0];
    refused(
        w.prescribe("plate", &[0], &[px]),
        "fem[plate].prescribe",
        "prescribed",
    );
    refused(
        w.set_fem_velocities(
            "plate",
            &vec![Vector2::new(1.0, 0.0); w.bodies.fem[plate].x.len()],
        ),
        "fem[plate].v",
        "prescribed",
    );
    refused(
        w.apply_fem_forces("ghost", &[]),
        "fem[ghost]",
        "no FEM body of that name",
    );
    refused(
        w.prescribe("pusher", &[1, 1], &[fx0[1], fx0[1]]),
        "fem[pusher].prescribe",
        "listed twice",
    );
    refused(
        w.prescribe("pusher", &[99], &[fx0[1]]),
        "fem[pusher].prescribe",
        "out of range",
    );
    refused(w.set_friction(-0.1, None), "contact.friction", "≥ 0");
    refused(
        w.set_friction(0.3, Some(("block", "nobody"))),
        "contact.friction",
        "no contact pair",
    );
    assert!(w.bodies.loads.is_empty());
    assert!(!w.driven(), "nothing was set");
    // A good state is taken.
    let moved: Vec<_> = x0.iter().map(|x| x + Vector2::new(0.0, 0.01)).collect();
    w.set_particle_positions(&moved).unwrap();
    assert_eq!(w.bodies.mpm.as_ref().unwrap().x, moved);
    w.step().unwrap();
}

/// A material set between steps is the one the energy and the next step use: at the same
/// deformed positions, twice Young's modulus (ν kept) is twice the elastic energy, for the MPM
/// block and the FEM pusher alike; bad values and unknown bodies are refused.
#[test]
fn material_set_between_steps_scales_the_elastic_energy() {
    let mut v = two_blocks(false);
    v["bodies"][0]["velocity"] = json!([0, -0.5]);
    v["bodies"][1]["velocity"] = json!([0.3, 0]);
    v["bodies"][1]["prescribed"] =
        json!([{ "vertices": { "below": { "axis": 0, "value": -0.599 } }, "motion": [] }]);
    let mut w = World::<2>::build(parse(&v)).unwrap();
    for _ in 0..3 {
        w.step().unwrap();
    }
    let elastic = |w: &World<2>| {
        let m = w.bodies.mpm.as_ref().unwrap();
        let mpm: f64 = (0..m.x.len())
            .map(|p| {
                use femp_fem::Hyperelastic;
                m.bodies[0].material.energy_density(&m.f[p]) * m.volume[p]
            })
            .sum();
        let b = &w.bodies.fem[pusher(w)];
        (mpm, b.elastic.energy(&b.x).unwrap())
    };
    let (mpm0, fem0) = elastic(&w);
    assert!(mpm0 > 0.0 && fem0 > 0.0, "deformed: {mpm0}, {fem0}");
    w.set_material("block", 2e5, 0.3).unwrap();
    w.set_material("pusher", 2e6, 0.3).unwrap();
    let (mpm1, fem1) = elastic(&w);
    assert!((mpm1 / mpm0 - 2.0).abs() < 1e-12, "{mpm1} / {mpm0}");
    assert!((fem1 / fem0 - 2.0).abs() < 1e-12, "{fem1} / {fem0}");
    refused(
        w.set_material("block", 1e5, 0.5),
        "bodies[block].material",
        "nu",
    );
    refused(
        w.set_material("ghost", 1e5, 0.3),
        "bodies[ghost].material",
        "no body",
    );
    w.step().unwrap();
}

/// A block sliding on the plate slows down once μ is raised between steps.
#[test]
fn friction_set_between_steps_slows_a_sliding_block() {
    let run = |mu: f64| {
        let mut v = two_blocks(true);
        v["gravity"] = json!([0, -9.81]);
        v["bodies"][0]["velocity"] = json!([0.5, 0]);
        let mut w = World::<2>::build(parse(&v)).unwrap();
        for _ in 0..3 {
            w.step().unwrap();
        }
        assert_eq!(w.set_friction(mu, Some(("plate", "block"))).unwrap(), 1);
        for _ in 0..5 {
            w.step().unwrap();
        }
        w.measure().momentum[0]
    };
    let (free, rough) = (run(0.0), run(0.5));
    assert!(rough < 0.9 * free, "μ = 0.5: {rough}, μ = 0: {free}");
}

/// Every file of `dir` (relative path → bytes).
fn files(dir: &Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// metrics.csv without its `wall_s` column.
fn without_wall(csv: &[u8]) -> Vec<Vec<String>> {
    let text = String::from_utf8(csv.to_vec()).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let wall = header.iter().position(|c| *c == "wall_s").unwrap();
    std::iter::once(header.iter().map(|s| s.to_string()).collect())
        .chain(lines.map(|l| {
            l.split(',')
                .enumerate()
                .filter(|(i, _)| *i != wall)
                .map(|(_, s)| s.to_string())
                .collect()
        }))
        .collect()
}

/// A world stepped by hand and recorded writes what `femp run` writes for the same scene and
/// steps: every frame and the PVD byte for byte, metrics.csv but for its wall-clock column,
/// the scene copy, and a summary with the same counts.
#[test]
fn a_recorded_world_writes_what_a_run_writes() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/block_on_plate.json");
    let scene = scene::load(&p).unwrap();
    let opts = RunOptions {
        max_steps: Some(12),
        ..Default::default()
    };
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let ran = femp::run::run(scene.clone(), a.path(), &opts).unwrap();
    let mut w = World::<2>::build(scene).unwrap();
    let mut rec = Recorder::start(&w, b.path(), &opts).unwrap();
    for _ in 0..rec.total_steps() {
        let t0 = std::time::Instant::now();
        let r = w.step().unwrap();
        rec.record(&w, &r, t0, &mut |_, _| {}).unwrap();
    }
    let recorded = rec.finish(&w).unwrap();
    let (fa, fb) = (files(a.path()), files(b.path()));
    assert_eq!(
        fa.keys().collect::<Vec<_>>(),
        fb.keys().collect::<Vec<_>>(),
        "the same files"
    );
    assert!(fa.keys().filter(|k| k.ends_with(".vtu")).count() >= 3);
    for (name, bytes) in &fa {
        match name.as_str() {
            "metrics.csv" => assert_eq!(without_wall(bytes), without_wall(&fb[name])),
            "summary.json" => {}
            _ => assert!(bytes == &fb[name], "{name} differs"),
        }
    }
    let (sa, sb) = (&ran.summary, &recorded.summary);
    assert_eq!(sb.status, "completed");
    assert_eq!(
        (
            sa.steps,
            sa.frames,
            sa.newton_iterations,
            sa.max_penetrations
        ),
        (
            sb.steps,
            sb.frames,
            sb.newton_iterations,
            sb.max_penetrations
        )
    );
    assert_eq!(ran.metrics.len(), recorded.metrics.len());
}
