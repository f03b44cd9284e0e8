//! Checkpoints: a world restored from one steps bit for bit as the world it was taken of (2D
//! with friction, contact-stabilised Newmark's second solver, the 3D twist with nested
//! dissection); `femp run --resume` ends as a run never stopped (metrics, frames, summary
//! totals), may run a scene further than it went, and refuses what it cannot continue — no
//! checkpoint, another scene, a damaged file, an augury scene — with what is wrong.

use std::path::Path;
use std::process::{Command, Output};

use femp::World;
use femp::checkpoint::Checkpoint;
use femp::scene;
use serde_json::{Value, json};

use crate::cli::scene as scene_file;

fn femp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_femp"))
        .args(args)
        .output()
        .expect("femp runs")
}

/// An MPM block thrown onto a FEM plate with friction (the plate held at its bottom), 2D.
fn block(duration: f64, integrator: &str) -> Value {
    json!({
        "dimension": 2, "gravity": [0, -9.81],
        "time": { "dt": 0.01, "duration": duration, "frame_interval": 0.02,
                  "integrator": integrator },
        "mpm": { "grid_spacing": 0.05 },
        "bodies": [
            { "kind": "mpm", "name": "block",
              "shape": { "box": { "min": [-0.2, 0.01], "max": [0.2, 0.21] } },
              "velocity": [0.8, -1.0],
              "material": { "E": 1e5, "nu": 0.3, "rho": 1000 } },
            { "kind": "fem", "name": "plate",
              "mesh": { "rectangle": { "min": [-1, -0.1], "max": [1, 0], "cells": [20, 2] } },
              "material": { "E": 1e7, "nu": 0.3, "rho": 1000 },
              "prescribed": [ { "vertices": { "below": { "axis": 1, "value": -0.099 } },
                                "motion": [] } ] }
        ],
        "contact": { "dhat": 0.005, "kappa": 1e5, "friction": 0.3 }
    })
}

/// Every number a step changes, as bits.
pub(crate) fn bits<const D: usize>(w: &World<D>) -> Vec<u64> {
    let mut out = vec![w.clock.step as u64, w.clock.time.to_bits()];
    if let Some(m) = &w.bodies.mpm {
        for q in 0..m.x.len() {
            out.extend(
                m.x[q]
                    .iter()
                    .chain(m.v[q].iter())
                    .chain(m.b[q].iter())
                    .chain(m.f[q].iter())
                    .chain(m.a[q].iter())
                    .chain(m.contact_force[q].iter())
                    .map(|v| v.to_bits()),
            );
        }
    }
    for b in &w.bodies.fem {
        out.extend(
            b.x.iter()
                .chain(&b.v)
                .chain(&b.a)
                .chain(&b.contact_force)
                .flat_map(|v| v.iter().map(|c| c.to_bits())),
        );
    }
    out
}

/// Step a world of `scene` `first` steps, take its state through a file, step on `then`
/// steps; a world built afresh from the scene and restored from the file steps the same
/// `then` steps: the same Newton iterations and the same bits after every one.
fn resumes_bit_for_bit<const D: usize>(s: &scene::Scene, first: usize, then: usize) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state.femp");
    let mut original = World::<D>::build(s.clone()).unwrap();
    for _ in 0..first {
        original.step().unwrap();
    }
    Checkpoint::for_world(&original)
        .unwrap()
        .write(&path)
        .unwrap();
    let mut resumed = World::<D>::build(s.clone()).unwrap();
    let read = Checkpoint::read(&path).unwrap();
    assert_eq!(read.step(), first);
    resumed.restore(&read.world).unwrap();
    assert!(bits(&resumed) == bits(&original), "restored state differs");
    let mut contact_steps = 0;
    for k in 0..then {
        let a = original.step().unwrap();
        let b = resumed.step().unwrap();
        assert_eq!(
            (a.newton_iterations, a.friction_iterations),
            (b.newton_iterations, b.friction_iterations),
            "{}: step {}",
            s.name,
            first + k + 1
        );
        assert!(
            bits(&resumed) == bits(&original),
            "{}: the state after step {} differs",
            s.name,
            first + k + 1
        );
        contact_steps += usize::from(a.contact_terms > 0);
    }
    assert!(
        contact_steps > 0,
        "{}: no contact after the resumption",
        s.name
    );
}

#[test]
fn a_resumed_world_steps_bit_for_bit_as_one_never_stopped() {
    for integrator in ["backward_euler", "contact_stabilized_newmark"] {
        let text = serde_json::to_string(&block(1.0, integrator)).unwrap();
        let s = scene::parse(&text, "b.json", ".".into(), integrator).unwrap();
        resumes_bit_for_bit::<2>(&s, 2, 8);
    }
    // 3D, nested dissection: the twist at h = 0.25 pressing and then turning (a checkpoint
    // taken within the press, the steps after it in contact with friction).
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/twist.json");
    let s = scene::load(&p).unwrap();
    resumes_bit_for_bit::<3>(&s, 16, 6);
}

#[test]
fn restoring_a_state_of_another_scene_is_refused_with_what_differs() {
    let text = serde_json::to_string(&block(1.0, "backward_euler")).unwrap();
    let s = scene::parse(&text, "b.json", ".".into(), "b").unwrap();
    let mut w = World::<2>::build(s).unwrap();
    w.step().unwrap();
    let state = w.state().unwrap();
    let other = |edit: &dyn Fn(&mut Value)| {
        let mut v = block(1.0, "backward_euler");
        edit(&mut v);
        let s = scene::parse(&v.to_string(), "b.json", ".".into(), "b").unwrap();
        World::<2>::build(s).unwrap()
    };
    let mut w2 = other(&|v| v["contact"]["friction"] = json!(0.5));
    let before = bits(&w2);
    let e = w2.restore(&state).unwrap_err().to_string();
    assert!(e.contains("contact.friction") && e.contains("0.3"), "{e}");
    assert!(bits(&w2) == before, "a refused state changed the world");
    let e = other(&|v| v["bodies"][1]["mesh"]["rectangle"]["cells"] = json!([21, 2]))
        .restore(&state)
        .unwrap_err()
        .to_string();
    assert!(e.contains("bodies[1].mesh.rectangle.cells"), "{e}");
    // Only the duration may differ: the run is continued further.
    let mut longer = other(&|v| v["time"]["duration"] = json!(2.0));
    longer.restore(&state).unwrap();
    assert_eq!(longer.clock.step, 1);
}

/// `metrics.csv` without its wall-time column (the only one that differs between runs).
fn rows(out: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let wall = header.iter().position(|c| *c == "wall_s").unwrap();
    lines
        .map(|l| {
            l.split(',')
                .enumerate()
                .filter(|(k, _)| *k != wall)
                .map(|(_, f)| f)
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect()
}

fn summary(out: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

fn ok(r: &Output) {
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
}

#[test]
fn a_run_resumed_from_its_checkpoint_ends_as_one_never_stopped() {
    let dir = tempfile::tempdir().unwrap();
    let full = scene_file(dir.path(), "full.json", &block(0.16, "backward_euler"));
    let short = scene_file(dir.path(), "short.json", &block(0.1, "backward_euler"));
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let run = |scene: &str, out: &Path, extra: &[&str]| {
        let mut args = vec!["run", scene, "--out", out.to_str().unwrap(), "-q"];
        args.extend_from_slice(extra);
        femp(&args)
    };
    ok(&run(&full, &a, &[]));
    // Stopped after step 7: its last checkpoint is step 6's (frames every 2 steps).
    ok(&run(&full, &b, &["--checkpoint", "--max-steps", "7"]));
    assert_eq!(summary(&b)["steps"], 7);
    assert!(b.join("frames/particles_000003.vtu").is_file());
    assert!(!b.join("frames/particles_000004.vtu").exists());
    ok(&run(
        &full,
        &b,
        &["--resume", "--checkpoint", "--max-steps", "10"],
    ));
    assert_eq!(summary(&b)["resumed_at"], json!([6]));
    // Then run further than the first scene went: the same scene but for its duration.
    ok(&run(&short, &b, &["--resume"]));
    let e = run(&full, &b, &["--resume"]);
    ok(&e);
    let (sa, sb) = (summary(&a), summary(&b));
    // (The resumption with the short scene wrote no checkpoint: the last one's history is
    // step 6's, and this one.)
    assert_eq!(sb["resumed_at"], json!([6, 10]));
    assert_eq!(sb["status"], "completed");
    for key in [
        "steps",
        "frames",
        "newton_iterations",
        "friction_iterations",
        "energy_rise",
        "max_penetrations",
        "initial_energy",
        "peak_energy",
    ] {
        assert_eq!(sa[key], sb[key], "{key}");
    }
    assert!(sa["newton_iterations"].as_u64().unwrap() > 16);
    let (ra, rb) = (rows(&a), rows(&b));
    assert_eq!(ra.len(), 17);
    assert!(ra == rb, "metrics.csv differs");
    for f in [
        "particles_000008.vtu",
        "plate_000008.vtu",
        "particles_000003.vtu",
    ] {
        let read = |d: &Path| std::fs::read(d.join("frames").join(f)).unwrap();
        assert!(read(&a) == read(&b), "{f} differs");
    }
    for pvd in ["particles.pvd", "plate.pvd"] {
        let read = |d: &Path| std::fs::read_to_string(d.join(pvd)).unwrap();
        assert_eq!(read(&a), read(&b), "{pvd}");
    }
}

#[test]
fn what_cannot_be_resumed_is_refused_with_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let p = scene_file(dir.path(), "b.json", &block(0.06, "backward_euler"));
    let out = dir.path().join("o");
    let o = out.to_str().unwrap();
    let err = |r: Output| {
        assert!(!r.status.success());
        String::from_utf8_lossy(&r.stderr).into_owned()
    };
    // Nothing to resume.
    let e = err(femp(&["run", &p, "--out", o, "--resume", "-q"]));
    assert!(e.contains("no checkpoint to resume from"), "{e}");
    ok(&femp(&["run", &p, "--out", o, "--checkpoint", "-q"]));
    let ckpt = out.join("checkpoint.femp");
    let good = std::fs::read(&ckpt).unwrap();
    // Another scene.
    let mut v = block(0.06, "backward_euler");
    v["bodies"][0]["material"]["E"] = json!(2e5);
    let q = scene_file(dir.path(), "c.json", &v);
    let e = err(femp(&["run", &q, "--out", o, "--resume", "-q"]));
    assert!(e.contains("bodies[0].material.E"), "{e}");
    // A damaged file, a truncated one, something else.
    let mut bad = good.clone();
    let k = bad.len() / 2;
    bad[k] ^= 1;
    std::fs::write(&ckpt, &bad).unwrap();
    let e = err(femp(&["run", &p, "--out", o, "--resume", "-q"]));
    assert!(e.contains("checksum"), "{e}");
    std::fs::write(&ckpt, &good[..good.len() - 100]).unwrap();
    let e = err(femp(&["run", &p, "--out", o, "--resume", "-q"]));
    assert!(e.contains("checksum"), "{e}");
    std::fs::write(&ckpt, b"{}").unwrap();
    let e = err(femp(&["run", &p, "--out", o, "--resume", "-q"]));
    assert!(e.contains("not a femp checkpoint"), "{e}");
    // Resumed and overwritten at once.
    std::fs::write(&ckpt, &good).unwrap();
    let e = err(femp(&[
        "run",
        &p,
        "--out",
        o,
        "--resume",
        "--overwrite",
        "-q",
    ]));
    assert!(e.contains("--overwrite"), "{e}");
    // An earlier run's checkpoint is one of its outputs: refused like the others.
    let e = err(femp(&["run", &p, "--out", o, "-q"]));
    assert!(e.contains("checkpoint.femp"), "{e}");
    // Augury keeps its state in its own system: no checkpoints, said before the run starts.
    let aug =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/augury_blocks.json");
    let out2 = dir.path().join("aug");
    let e = err(femp(&[
        "run",
        aug.to_str().unwrap(),
        "--out",
        out2.to_str().unwrap(),
        "--checkpoint",
        "--max-steps",
        "2",
        "-q",
    ]));
    assert!(e.contains("BFEMP"), "{e}");
    assert!(!out2.join("metrics.csv").exists());
}

/// `--resume --branch` continues a run's checkpoint under other solver settings (to compare
/// them from one state): the summary says it branched, with the first difference; without
/// `--branch` the same scene is refused, and a branch may not change anything outside
/// `solver` (and `time.duration`). With the same settings a branch ends where the run did
/// to the solver tolerance.
#[test]
fn a_branch_resumes_a_checkpoint_under_other_solver_settings_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let base = block(0.1, "backward_euler");
    let with = |edit: &dyn Fn(&mut Value)| {
        let mut v = base.clone();
        edit(&mut v);
        v
    };
    let full = scene_file(dir.path(), "full.json", &base);
    let other = scene_file(
        dir.path(),
        "other.json",
        &with(&|v| v["solver"] = json!({ "friction_anderson": 3, "tolerance": 1e-5 })),
    );
    let contact = scene_file(
        dir.path(),
        "contact.json",
        &with(&|v| v["contact"]["friction"] = json!(0.5)),
    );
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let run = |scene: &str, out: &Path, extra: &[&str]| {
        let mut args = vec![
            "run",
            scene,
            "--out",
            out.to_str().unwrap(),
            "-q",
            "--no-frames",
        ];
        args.extend_from_slice(extra);
        femp(&args)
    };
    ok(&run(&full, &a, &["--checkpoint", "--max-steps", "4"]));
    std::fs::create_dir_all(&b).unwrap();
    for f in [
        "checkpoint.femp",
        "metrics.csv",
        "summary.json",
        "scene_copy.json",
    ] {
        std::fs::copy(a.join(f), b.join(f)).unwrap();
    }
    let refused = |r: Output, what: &str| {
        assert!(!r.status.success());
        let e = String::from_utf8_lossy(&r.stderr).into_owned();
        assert!(e.contains(what), "{e}");
    };
    refused(
        run(&other, &b, &["--resume"]),
        "`solver.friction_anderson` was absent, is 3",
    );
    refused(
        run(&contact, &b, &["--resume", "--branch"]),
        "`contact.friction` was 0.3, is 0.5 (a branch may change the `solver` section",
    );
    refused(run(&other, &b, &["--branch"]), "--resume");
    ok(&run(&other, &b, &["--resume", "--branch"]));
    let s = summary(&b);
    assert_eq!(s["status"], "completed");
    assert_eq!(s["steps"], 10);
    let warnings = s["warnings"].to_string();
    assert!(
        warnings.contains("branched at step 4 under other solver settings")
            && warnings.contains("`solver.friction_anderson` was absent, is 3"),
        "{warnings}"
    );
    // The run itself, continued plainly, and a branch of it with the same settings.
    ok(&run(&full, &a, &["--resume"]));
    let c = dir.path().join("c");
    std::fs::create_dir_all(&c).unwrap();
    ok(&run(&full, &c, &["--checkpoint", "--max-steps", "4"]));
    ok(&run(&full, &c, &["--resume", "--branch"]));
    let warnings = summary(&c)["warnings"].to_string();
    assert!(warnings.contains("the same solver settings"), "{warnings}");
    let last = |d: &Path| -> Vec<f64> {
        let text = std::fs::read_to_string(d.join("metrics.csv")).unwrap();
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let row: Vec<&str> = lines.last().unwrap().split(',').collect();
        ["momentum_x", "kinetic_energy"]
            .iter()
            .map(|k| {
                row[header.iter().position(|h| h == k).unwrap()]
                    .parse()
                    .unwrap()
            })
            .collect()
    };
    let (pa, pc) = (last(&a), last(&c));
    for (x, y) in pa.iter().zip(&pc) {
        assert!(
            (x - y).abs() <= 1e-3 * x.abs().max(1e-9),
            "{pa:?} vs {pc:?}"
        );
    }
}
