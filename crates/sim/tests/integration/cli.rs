//! The `femp` program: `check` accepts good scenes and names what is wrong with bad ones,
//! `run` writes frames, metrics and a summary, and a run that fails mid-way keeps everything up
//! to its last step, says why in `summary.json` and on stderr, and exits non-zero.

use std::path::Path;
use std::process::{Command, Output};

use serde_json::{Value, json};

fn femp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_femp"))
        .args(args)
        .output()
        .expect("femp runs")
}

/// `femp check PATH`, which must succeed; its standard output.
fn check_ok(path: &str) -> String {
    let out = femp(&["check", path]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Write scene `v` as `dir/name`; its path.
pub(crate) fn scene(dir: &Path, name: &str, v: &Value) -> String {
    let p = dir.join(name);
    std::fs::write(&p, serde_json::to_string_pretty(v).unwrap()).unwrap();
    p.display().to_string()
}

/// An MPM block moving down onto a fixed FEM plate, without gravity.
fn falling_block(max_newton: usize) -> Value {
    json!({
        "dimension": 2,
        "time": { "dt": 0.01, "duration": 0.2, "frame_interval": 0.01 },
        "solver": { "tolerance": 1e-9, "max_newton_iterations": max_newton },
        "mpm": { "grid_spacing": 0.05 },
        "bodies": [
            { "kind": "mpm", "name": "block",
              "shape": { "box": { "min": [-0.2, 0.05], "max": [0.2, 0.25] } },
              "material": { "E": 1e5, "nu": 0.3, "rho": 1000 }, "velocity": [0, -1] },
            { "kind": "fem", "name": "plate",
              "mesh": { "rectangle": { "min": [-1, -0.1], "max": [1, 0], "cells": [20, 1] } },
              "material": { "E": 1e7, "nu": 0.3, "rho": 1000 },
              "prescribed": [ { "vertices": "all", "motion": [] } ] }
        ],
        "contact": { "dhat": 0.005, "kappa": 1e5 }
    })
}

#[test]
fn check_accepts_a_valid_scene_and_reports_its_size() {
    let dir = tempfile::tempdir().unwrap();
    let p = scene(dir.path(), "ok.json", &falling_block(50));
    let text = check_ok(&p);
    // 0.4 × 0.2 m at h = 0.05 with 4 particles per cell: 16 × 8 particles; the plate 21 × 2.
    assert!(
        text.contains("valid 2D scene, 128 particles, 42 FEM vertices"),
        "{text}"
    );
}

/// `check --trial N` runs N steps, writes nothing, and extrapolates to the whole run (20 steps
/// here); it says when the trial had no contact (a lower bound), and a trial step that fails is
/// an error naming the step.
#[test]
fn check_trial_extrapolates_the_wall_time_from_the_first_steps() {
    let dir = tempfile::tempdir().unwrap();
    let p = scene(dir.path(), "ok.json", &falling_block(50));
    let out = femp(&["check", "--trial", "3", &p]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("trial: 3 steps in"), "{text}");
    assert!(text.contains("all 20 steps at that rate: about"), "{text}");
    // The block starts 0.05 m above the plate at 1 m/s: no contact in the first 3 steps.
    assert!(
        text.contains("contact in 0") && text.contains("lower bound"),
        "{text}"
    );
    let entries: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(entries.len(), 1, "check wrote files");
    // All 20 steps: the block lands, so contact is seen and no lower-bound note.
    let text = check_ok_args(&["check", "--trial", "1000", &p]);
    assert!(text.contains("trial: 20 steps in"), "{text}");
    assert!(
        !text.contains("lower bound") && !text.contains("contact in 0"),
        "{text}"
    );
    // A Newton limit of 1 fails the first contact step.
    let bad = scene(dir.path(), "bad.json", &falling_block(1));
    let out = femp(&["check", "--trial", "20", &bad]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("trial step") && !err.contains("panicked"),
        "{err}"
    );
}

fn check_ok_args(args: &[&str]) -> String {
    let out = femp(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// For augury scenes `check` reports Δt and the look-ahead τ against the explicit stability
/// estimate (τ sets how strongly the correction acts, `docs/augury.md`).
#[test]
fn check_reports_the_augury_time_step_and_look_ahead() {
    let p = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/scenes/augury_blocks_3d.json"
    );
    let text = check_ok(p);
    assert!(
        text.contains("Δt = 1.000e-4 s (0.03 × the explicit stability estimate")
            && text.contains("look-ahead τ = 1.000e-4 s (0.03 × the estimate)"),
        "{text}"
    );
}

#[test]
fn check_names_the_field_of_a_bad_scene_without_a_backtrace() {
    let dir = tempfile::tempdir().unwrap();
    let mut v = falling_block(50);
    v["bodies"][1]["material"]["nu"] = json!(0.5);
    let p = scene(dir.path(), "bad.json", &v);
    let out = Command::new(env!("CARGO_BIN_EXE_femp"))
        .args(["check", &p])
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("error: bodies[1].material.nu: 0.5") && err.contains("must be < 0.5"),
        "{err}"
    );
    assert!(!err.contains("backtrace"), "{err}");
    assert_eq!(err.lines().count(), 1, "one line: {err}");
}

#[test]
fn every_subcommand_has_help() {
    for args in [&["--help"][..], &["run", "--help"], &["check", "--help"]] {
        let out = femp(args);
        assert!(out.status.success());
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(text.contains("Usage"), "{args:?}: {text}");
    }
}

#[test]
fn run_writes_frames_metrics_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let mut v = falling_block(50);
    v["time"]["duration"] = json!(0.05);
    let p = scene(dir.path(), "ok.json", &v);
    let out_dir = dir.path().join("out");
    let out = femp(&["run", &p, "--out", out_dir.to_str().unwrap(), "-q"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["status"], "completed");
    assert_eq!(summary["steps"], 5);
    assert_eq!(summary["max_penetrations"], 0);
    let metrics = std::fs::read_to_string(out_dir.join("metrics.csv")).unwrap();
    assert_eq!(
        metrics.lines().count(),
        1 + 6,
        "header, initial state, 5 steps"
    );
    let header = metrics.lines().next().unwrap();
    for col in [
        "step",
        "t",
        "dt",
        "kinetic_energy",
        "elastic_energy",
        "barrier_energy",
        "momentum_x",
        "momentum_y",
        "angular_momentum",
        "min_distance",
        "penetrations",
        "newton_iterations",
        "friction_iterations",
        "wall_s",
    ] {
        assert!(header.split(',').any(|c| c == col), "missing column {col}");
    }
    // Six particle frames (initial + 5) in the series, and the plate's frames.
    let pvd = std::fs::read_to_string(out_dir.join("particles.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 6);
    for k in 0..6 {
        let f = out_dir.join(format!("frames/particles_{k:06}.vtu"));
        assert!(f.exists(), "{}", f.display());
    }
    assert!(out_dir.join("plate.pvd").exists());
    // Provenance: version, commit, the command, the scene as read, the body index's names.
    assert_eq!(summary["femp_version"], env!("CARGO_PKG_VERSION"));
    assert!(!summary["commit"].as_str().unwrap().is_empty());
    let command: Vec<&str> = summary["command"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert_eq!(&command[1..3], &["run", p.as_str()]);
    assert_eq!(summary["scene_copy"], "scene_copy.json");
    assert_eq!(
        std::fs::read_to_string(out_dir.join("scene_copy.json")).unwrap(),
        std::fs::read_to_string(&p).unwrap()
    );
    assert_eq!(summary["mpm_bodies"], json!(["block"]));
    // Per-particle mass, volumes and Cauchy stress; per-cell stress of the plate.
    let last =
        femp_fem::mesh::vtk::Vtu::read(&out_dir.join("frames/particles_000005.vtu")).unwrap();
    let field = |name: &str| {
        last.field(name)
            .unwrap_or_else(|| panic!("no {name}"))
            .clone()
    };
    let (mass, vol, rest, det, vm, stress) = (
        field("mass"),
        field("volume"),
        field("rest_volume"),
        field("det_F"),
        field("von_mises"),
        field("stress"),
    );
    // 0.4 × 0.2 m of 1000 kg/m².
    assert!((mass.values.iter().sum::<f64>() - 80.0).abs() < 1e-9);
    assert_eq!(stress.components, 9);
    for q in 0..mass.values.len() {
        assert!((vol.values[q] - rest.values[q] * det.values[q]).abs() < 1e-15);
        let s = &stress.values[9 * q..9 * q + 9];
        // Plane: symmetric, no out-of-plane entries; its von Mises is the frame's.
        assert!((s[1] - s[3]).abs() <= 1e-9 * s[0].abs().max(1.0));
        assert!(s[2] == 0.0 && s[5] == 0.0 && s[8] == 0.0);
        let (sx, sy, sxy) = (s[0], s[4], s[1]);
        let von_mises = (sx * sx - sx * sy + sy * sy + 3.0 * sxy * sxy).sqrt();
        assert!((von_mises - vm.values[q]).abs() <= 1e-9 * vm.values[q].max(1.0));
    }
    let plate = femp_fem::mesh::vtk::Vtu::read(&out_dir.join("frames/plate_000005.vtu")).unwrap();
    assert_eq!(plate.field("stress").unwrap().components, 9);
}

#[test]
fn a_run_that_fails_mid_way_keeps_its_files_and_says_why() {
    // One Newton iteration per step suffices in free flight (the predictor is exact) but not
    // once the block reaches the barrier: the run fails at the first contact step.
    let dir = tempfile::tempdir().unwrap();
    let p = scene(dir.path(), "fail.json", &falling_block(1));
    let out_dir = dir.path().join("out");
    let out = femp(&["run", &p, "--out", out_dir.to_str().unwrap(), "-q"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("failed") && err.contains("Newton did not converge"),
        "{err}"
    );
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["status"], "failed");
    let why = summary["error"].as_str().unwrap();
    assert!(why.contains("Newton did not converge"), "{why}");
    let steps = summary["steps"].as_u64().unwrap() as usize;
    assert!((1..20).contains(&steps), "failed after {steps} steps");
    // Every completed step is in metrics.csv and has a frame.
    let metrics = std::fs::read_to_string(out_dir.join("metrics.csv")).unwrap();
    assert_eq!(metrics.lines().count(), 1 + 1 + steps);
    let pvd = std::fs::read_to_string(out_dir.join("particles.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 1 + steps);
    assert_eq!(summary["frames"].as_u64().unwrap() as usize, 1 + steps);
}
