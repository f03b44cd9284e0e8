//! `"method": "augury"` scenes through femp: the same physics as femp-augury's own reference
//! scene to round-off, exact momentum in the metrics, prescribed motion, the penalty baseline,
//! a blow-up that says why, and bad input named by field.

use std::path::Path;

use femp::run::{RunOptions, run};
use femp::scene::{self, Scene};
use femp::{SimError, World};
use femp_augury::scenes::{BlocksContact, head_on_blocks};
use femp_augury::{ContactModel, TransferKind};
use serde_json::{Value, json};

fn fixture() -> Value {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/augury_blocks.json");
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn parse(v: &Value) -> Result<Scene, SimError> {
    scene::parse(
        &serde_json::to_string(v).unwrap(),
        "test.json",
        Path::new(".").to_path_buf(),
        "test",
    )
}

fn quiet(max_steps: Option<usize>) -> RunOptions {
    RunOptions {
        progress: false,
        max_steps,
        no_frames: true,
        ..Default::default()
    }
}

/// Velocity of the centre of mass of FEM body `k` along x.
fn com_vx(w: &World<2>, k: usize) -> f64 {
    let b = &w.bodies.fem[k];
    let m: f64 = b.mass.iter().sum();
    b.v.iter()
        .zip(&b.mass)
        .map(|(v, mm)| v[0] * mm)
        .sum::<f64>()
        / m
}

/// The fixture scene run by `femp` matches `femp_augury::scenes::head_on_blocks` (the same
/// blocks, grid, Δt and model built by hand) to round-off: the scene path adds nothing.
#[test]
fn scene_run_matches_the_library_reference_scene() {
    for (model, name) in [
        (ContactModel::Separation, "separation"),
        (ContactModel::Sticky, "sticky"),
    ] {
        let reference = head_on_blocks(BlocksContact::Augury(model, TransferKind::Apic), 0.0)
            .expect("reference run");
        // The reference uses half the stability estimate as Δt.
        let mut v = fixture();
        v["augury"]["model"] = json!(name);
        let probe = World::<2>::build(parse(&v).unwrap()).unwrap();
        let dt = 0.5 * probe.stepper.augury().unwrap().stable_dt;
        v["time"]["dt"] = json!(dt);
        v["time"]["duration"] = json!(dt * reference.steps as f64);
        let dir = tempfile::tempdir().unwrap();
        let mut last = None;
        let r = femp::run::run_with::<2>(parse(&v).unwrap(), dir.path(), &quiet(None), |w, _| {
            last = Some(com_vx(w, 1) - com_vx(w, 0))
        })
        .unwrap();
        assert_eq!(r.summary.steps, reference.steps, "{name}");
        let sep = last.unwrap();
        assert!(
            (sep - reference.separation_speed).abs() <= 1e-12,
            "{name}: femp {sep} vs library {}",
            reference.separation_speed
        );
    }
}

/// Linear and angular momentum (with the APIC `B_p` term) in metrics.csv stay at their initial
/// values to round-off through the collision; the blocks do not interpenetrate.
#[test]
fn metrics_show_exact_momentum_through_the_collision() {
    let mut v = fixture();
    // Off-centre impact: angular momentum is non-zero and changes hands.
    v["bodies"][1]["mesh"]["rectangle"]["min"] = json!([0.5, 0.3]);
    v["bodies"][1]["mesh"]["rectangle"]["max"] = json!([1.5, 1.3]);
    let dir = tempfile::tempdir().unwrap();
    let r = run(parse(&v).unwrap(), dir.path(), &quiet(None)).unwrap();
    assert_eq!(r.summary.method, femp::scene::Method::Augury);
    let m0 = &r.metrics[0];
    // Scales: Σ m |v| = 2 kg·m/s; positions within 2 m of the origin.
    assert!(
        m0.angular_momentum[2].abs() > 0.1,
        "{:?}",
        m0.angular_momentum
    );
    let mut touched = false;
    for m in &r.metrics {
        for a in 0..2 {
            assert!(
                (m.momentum[a] - m0.momentum[a]).abs() <= 1e-12 * 2.0,
                "step {}: p = {:?}",
                m.step,
                m.momentum
            );
        }
        assert!(
            (m.angular_momentum[2] - m0.angular_momentum[2]).abs() <= 1e-12 * 4.0,
            "step {}: L = {} vs {}",
            m.step,
            m.angular_momentum[2],
            m0.angular_momentum[2]
        );
        // Augury contact acts across about one grid spacing (0.25 m here).
        touched |= m.min_distance < 0.25 && m.kinetic_energy < 0.9 * m0.kinetic_energy;
        assert_eq!(m.penetrations, 0, "step {}", m.step);
    }
    assert!(
        touched,
        "the blocks never came close: the test saw no collision"
    );
    // The CSV holds the same rows, with the augury step's own solver columns: its
    // iterations, not BFEMP's Newton/friction/linear-solver counters.
    let csv = std::fs::read_to_string(dir.path().join("metrics.csv")).unwrap();
    assert_eq!(csv.lines().count(), r.metrics.len() + 1);
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    assert!(header.contains(&"augury_iterations"), "{header:?}");
    for bfemp_only in ["newton_iterations", "friction_iterations", "pcg_iterations"] {
        assert!(!header.contains(&bfemp_only), "{header:?}");
    }
    let col = header
        .iter()
        .position(|c| *c == "augury_iterations")
        .unwrap();
    let per_step: Vec<usize> = csv
        .lines()
        .skip(2)
        .map(|l| l.split(',').nth(col).unwrap().parse().unwrap())
        .collect();
    assert!(per_step.iter().all(|&k| k >= 1), "{per_step:?}");
    assert_eq!(per_step.iter().sum::<usize>(), r.summary.augury_iterations);
    assert_eq!(
        (r.summary.newton_iterations, r.summary.friction_iterations),
        (0, 0)
    );
}

/// A fully prescribed plate moving at 0.5 m/s pushes a free block: the plate follows its script
/// exactly and the block ends up moving with it.
#[test]
fn a_prescribed_plate_pushes_a_block() {
    let v = json!({
        "dimension": 2, "method": "augury",
        "time": { "dt": 1e-3, "duration": 1.2 },
        "augury": { "grid_spacing": 0.25, "model": "separation" },
        "bodies": [
            { "kind": "fem", "name": "plate",
              "mesh": { "rectangle": { "min": [-1.0, 0.0], "max": [-0.75, 1.0], "cells": [2, 8] } },
              "material": { "E": 1e3, "nu": 0.3, "rho": 1.0 },
              "prescribed": [ { "vertices": "all",
                                "motion": [ { "until": 10.0, "velocity": [0.5, 0.0] } ] } ] },
            { "kind": "fem", "name": "block",
              "mesh": { "rectangle": { "min": [-0.5, 0.0], "max": [0.5, 1.0], "cells": [8, 8] } },
              "material": { "E": 1e3, "nu": 0.3, "rho": 1.0 } }
        ]
    });
    let dir = tempfile::tempdir().unwrap();
    let mut world_plate_x = Vec::new();
    let mut block_v = 0.0;
    let r = femp::run::run_with::<2>(parse(&v).unwrap(), dir.path(), &quiet(None), |w, _| {
        world_plate_x.push((w.clock.time, w.bodies.fem[0].x[0][0]));
        block_v = com_vx(w, 1);
    })
    .unwrap();
    assert_eq!(r.summary.status, "completed");
    for (t, x) in &world_plate_x {
        assert!(
            (x - (-1.0 + 0.5 * t)).abs() < 1e-12,
            "plate at {x} at t = {t}"
        );
    }
    // Before contact the block is at rest; after 1.2 s the plate has travelled 0.6 m, closing
    // the 0.25 m gap, and pushes the block along.
    assert!(
        block_v > 0.3 && block_v < 0.7,
        "block moves at {block_v} m/s (plate 0.5 m/s)"
    );
}

/// The search-based penalty baseline runs from a scene too: the blocks bounce apart, linear
/// momentum is conserved, and no vertex ends up inside the other block.
#[test]
fn the_penalty_baseline_runs_from_a_scene() {
    let mut v = fixture();
    v["augury"] = json!({ "contact": "penalty", "penalty": { "stiffness": 2e3, "band": 0.0625 } });
    let dir = tempfile::tempdir().unwrap();
    let mut last = 0.0;
    let r = femp::run::run_with::<2>(parse(&v).unwrap(), dir.path(), &quiet(None), |w, _| {
        last = com_vx(w, 1) - com_vx(w, 0);
    })
    .unwrap();
    assert!(last > 0.5, "separation speed {last}");
    let m_end = r.metrics.last().unwrap();
    assert!(m_end.momentum[0].abs() < 1e-12, "{:?}", m_end.momentum);
    assert_eq!(m_end.penetrations, 0);
    assert!(r.metrics.iter().any(|m| m.contact_terms > 0));
}

/// `"obstacles"` from a scene: block A driven by gravity into block B, whose every vertex is
/// prescribed to rest (a wall). As a kinematic obstacle the wall keeps every vertex of A out;
/// with lumped masses (the default) A sinks in — half an edge deep, where the run stops
/// (`augury.penetration_limit`), unless the limit is lifted.
#[test]
fn a_prescribed_wall_holds_as_a_kinematic_obstacle() {
    let scene = |obstacles: &str| {
        let mut v = fixture();
        v["gravity"] = json!([5.0, 0.0]);
        v["time"]["duration"] = json!(2.0);
        v["augury"]["obstacles"] = json!(obstacles);
        v["bodies"][0]["velocity"] = json!([0.0, 0.0]);
        v["bodies"][1]["velocity"] = json!([0.0, 0.0]);
        v["bodies"][1]["prescribed"] = json!([{ "vertices": "all", "motion": [] }]);
        v
    };
    let dir = tempfile::tempdir().unwrap();
    let r = run(
        parse(&scene("kinematic")).unwrap(),
        dir.path(),
        &quiet(None),
    )
    .unwrap();
    assert_eq!(r.summary.max_penetrations, 0);
    let dir = tempfile::tempdir().unwrap();
    let e = run(parse(&scene("lumped")).unwrap(), dir.path(), &quiet(None))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("of `a` is") && e.contains("inside `b`") && e.contains("penetration_limit"),
        "{e}"
    );
    let mut lifted = scene("lumped");
    lifted["augury"]["penetration_limit"] = Value::Null;
    let dir = tempfile::tempdir().unwrap();
    let r = run(parse(&lifted).unwrap(), dir.path(), &quiet(None)).unwrap();
    assert!(r.summary.max_penetrations > 0);
    assert!(
        r.summary.max_penetration_depth > 0.5 * 0.125,
        "{}",
        r.summary.max_penetration_depth
    );
}

/// A time step far above the stability estimate blows up; the run stops with an error that
/// names the estimate, keeps the metrics written so far and says `failed` in the summary.
#[test]
fn an_unstable_time_step_fails_with_the_stability_estimate() {
    let mut v = fixture();
    v["time"]["dt"] = json!(0.03);
    v["time"]["duration"] = json!(30.0);
    let dir = tempfile::tempdir().unwrap();
    let err = run(parse(&v).unwrap(), dir.path(), &quiet(None)).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("exceeds the explicit stability estimate"),
        "{msg}"
    );
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["status"], "failed");
    let rows = std::fs::read_to_string(dir.path().join("metrics.csv"))
        .unwrap()
        .lines()
        .count();
    assert!(
        rows >= 2,
        "metrics up to the failure are kept ({rows} lines)"
    );
}

fn error_of(v: &Value) -> String {
    match parse(v) {
        Err(e) => e.to_string(),
        Ok(s) => World::<2>::build(s)
            .err()
            .expect("the scene must be rejected")
            .to_string(),
    }
}

#[test]
fn bad_augury_input_is_named() {
    let cases: Vec<(Value, Vec<&str>)> = vec![
        {
            let mut v = fixture();
            v["contact"] = json!({ "dhat": 0.01, "kappa": 1.0 });
            (v, vec!["contact", "augury"])
        },
        {
            let mut v = fixture();
            v["method"] = json!("bfemp");
            v["contact"] = json!({ "dhat": 0.01, "kappa": 1.0 });
            (v, vec!["augury", "bfemp"])
        },
        {
            let mut v = fixture();
            v["augury"]["grid_ratio"] = json!(2.0);
            (v, vec!["augury", "not both"])
        },
        {
            let mut v = fixture();
            v["augury"]["tau"] = json!(-1.0);
            (v, vec!["augury.tau"])
        },
        {
            let mut v = fixture();
            v["augury"]["contact"] = json!("penalty");
            (v, vec!["augury.penalty", "stiffness"])
        },
        {
            let mut v = fixture();
            v["augury"]["friction"] = json!(0.3);
            (v, vec!["augury.friction", "friction"])
        },
        {
            let mut v = fixture();
            v["augury"]["kernel"] = json!("cubic");
            (v, vec!["augury.kernel", "cubic"])
        },
        {
            let mut v = fixture();
            v["augury"]["obstacles"] = json!("heavy");
            (v, vec!["augury.obstacles", "heavy"])
        },
        {
            let mut v = fixture();
            v["augury"]["spacing"] = json!(1.0);
            (v, vec!["augury.spacing", "unknown field"])
        },
        {
            // Overlapping blocks: named, with the deepest vertex.
            let mut v = fixture();
            v["bodies"][1]["mesh"]["rectangle"]["min"] = json!([-0.7, 0.0]);
            v["bodies"][1]["mesh"]["rectangle"]["max"] = json!([0.3, 1.0]);
            (v, vec!["`a`", "`b`", "start overlapping", "inside"])
        },
        {
            let mut v = fixture();
            v["mpm"] = json!({ "grid_spacing": 0.1 });
            v["bodies"][0] = json!({ "kind": "mpm", "name": "a",
                "shape": { "box": { "min": [-1.5, 0.0], "max": [-0.5, 1.0] } },
                "material": { "E": 1e3, "nu": 0.3, "rho": 1.0 } });
            (v, vec!["method", "MPM"])
        },
    ];
    for (v, needles) in cases {
        let msg = error_of(&v);
        for n in needles {
            assert!(msg.contains(n), "message `{msg}` lacks `{n}`");
        }
    }
}

/// Bodies that start touching (a block resting on a ramp) are accepted and not counted as
/// penetrating.
#[test]
fn touching_bodies_are_accepted() {
    let mut v = fixture();
    v["bodies"][1]["mesh"]["rectangle"]["min"] = json!([-0.5, 0.0]);
    v["bodies"][1]["mesh"]["rectangle"]["max"] = json!([0.5, 1.0]);
    let s = parse(&v).unwrap();
    let w = World::<2>::build(s).unwrap();
    let m = w.measure();
    assert_eq!(m.penetrations, 0);
    assert!(m.min_distance < 1e-12, "{}", m.min_distance);
}

/// The paper's 3D blocks (§3.2, mesh h = 0.5, grid 2h, Δt = τ = 1e-4 h): with the separation iteration the APIC blocks
/// come apart after the impact; without any iteration PIC blocks stay stuck together (their
/// normal relative velocity after the impact is a small fraction of the approach speed).
/// (Without the iteration the paper's APIC blocks stick; ours are still separating at the
/// paper's 0.05 s and come back when run longer — see docs/augury.md.)
#[test]
fn blocks_3d_separate_with_the_iteration_and_pic_sticks_without() {
    let p =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/augury_blocks_3d.json");
    let base: Value = serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
    let normal_speed = |transfer: &str, model: &str, iterations: usize| {
        let mut v = base.clone();
        v["augury"] = json!({ "grid_spacing": 1.0, "transfer": transfer, "model": model,
                              "iterations": iterations });
        for b in v["bodies"].as_array_mut().unwrap() {
            b["mesh"]["cuboid"]["cells"] = json!([6, 6, 6]);
        }
        v["time"]["dt"] = json!(5e-5);
        let s = scene::parse(
            &v.to_string(),
            "blocks3d.json",
            Path::new(".").to_path_buf(),
            "blocks3d",
        )
        .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let mut rel = Vec::new();
        femp::run::run_with::<3>(s, dir.path(), &quiet(None), |w, _| {
            let ((x1, v1), (x2, v2)) = (
                w.bodies.fem[0].centre_of_mass(),
                w.bodies.fem[1].centre_of_mass(),
            );
            rel.push((v2 - v1).dot(&(x2 - x1).normalize()));
        })
        .unwrap();
        (rel[0], *rel.last().unwrap())
    };
    let (approach, after) = normal_speed("apic", "separation", 1);
    assert!(approach < -50.0, "approach {approach}");
    assert!(
        after > 0.25 * approach.abs(),
        "APIC N = 1: {approach} → {after} m/s"
    );
    let (approach, after) = normal_speed("pic", "sticky", 0);
    assert!(
        after.abs() < 0.1 * approach.abs(),
        "PIC sticky: {approach} → {after} m/s"
    );
}

/// Issue 43, "contact that never silently fails": two thin bars meeting at 300 m/s with no
/// contact handling pass through each other within one step — every end-of-step count is 0,
/// but the straight-path check sees each vertex go through. By default the run stops at that
/// step naming a vertex; with `penetration_limit: null` it goes on, counting the step in
/// `passed_through_steps` with a warning.
#[test]
fn bodies_passing_through_each_other_in_one_step_stop_the_run() {
    let mut v = fixture();
    v["augury"] = json!({ "grid_spacing": 0.25, "contact": "none" });
    v["bodies"][0]["mesh"]["rectangle"] =
        json!({ "min": [-0.6, 0.0], "max": [-0.5, 1.0], "cells": [1, 8] });
    v["bodies"][1]["mesh"]["rectangle"] =
        json!({ "min": [0.5, 0.0], "max": [0.6, 1.0], "cells": [1, 8] });
    v["bodies"][0]["velocity"] = json!([150.0, 0.0]);
    v["bodies"][1]["velocity"] = json!([-150.0, 0.0]);
    v["time"] = json!({ "dt": 4e-3, "duration": 8e-3 });
    let dir = tempfile::tempdir().unwrap();
    let e = run(parse(&v).unwrap(), dir.path(), &quiet(None))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("step 0 ")
            && e.contains("passed through another body")
            && e.contains("penetration_limit"),
        "{e}"
    );
    // The end of that step had no vertex inside: only the paths show it.
    let text = std::fs::read_to_string(dir.path().join("metrics.csv")).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let row: Vec<&str> = text.lines().nth(2).unwrap().split(',').collect();
    let col = |n: &str| row[header.iter().position(|h| *h == n).unwrap()];
    assert_eq!(col("penetrations"), "0");
    assert!(col("swept_entered").parse::<usize>().unwrap() > 10);
    v["augury"]["penetration_limit"] = Value::Null;
    let dir = tempfile::tempdir().unwrap();
    let r = run(parse(&v).unwrap(), dir.path(), &quiet(None)).unwrap();
    assert_eq!(r.summary.passed_through_steps, 1);
    assert!(
        r.summary
            .warnings
            .iter()
            .any(|w| w.contains("passed through another body"))
    );
}

/// `metrics_every`: a row after every N-th step and after the last, each the same bits as the
/// every-step run's row of that step (measuring does not touch the state); the summary's
/// totals still count every step, and the file holds exactly the sampled rows.
#[test]
fn sampled_metrics_are_the_every_step_rows_of_those_steps() {
    let v = fixture();
    let every = tempfile::tempdir().unwrap();
    let full = run(parse(&v).unwrap(), every.path(), &quiet(Some(40))).unwrap();
    let sampled_dir = tempfile::tempdir().unwrap();
    let opts = RunOptions {
        metrics_every: 7,
        ..quiet(Some(40))
    };
    let sampled = run(parse(&v).unwrap(), sampled_dir.path(), &opts).unwrap();
    let steps: Vec<usize> = sampled.metrics.iter().map(|m| m.step).collect();
    assert_eq!(steps, vec![0, 7, 14, 21, 28, 35, 40]);
    for m in &sampled.metrics {
        let f = &full.metrics[m.step];
        assert_eq!(f.step, m.step);
        // Everything but the wall time, which differs from run to run.
        let strip = |row: String| row.rsplit_once(',').map(|(a, _)| a.to_string()).unwrap();
        assert_eq!(
            strip(f.csv_row::<2>()),
            strip(m.csv_row::<2>()),
            "step {}",
            m.step
        );
    }
    assert_eq!(sampled.summary.steps, 40);
    assert_eq!(
        sampled.summary.augury_iterations,
        full.summary.augury_iterations
    );
    let csv = std::fs::read_to_string(sampled_dir.path().join("metrics.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + steps.len());
}
