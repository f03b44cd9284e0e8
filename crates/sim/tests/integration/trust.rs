//! Runs a user can trust however they end: signals stop a run cleanly (exit 130, summary
//! `interrupted`, every metrics row whole), a failed write is recorded, nothing is written
//! outside `--out`, an earlier run's outputs are never mixed with new ones, two runs never
//! share a directory, a closed stderr does not stop a run, and absurd arguments are refused
//! instead of panicking.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use femp::scene;
use femp::{SimError, World};
use serde_json::{Value, json};

fn femp() -> Command {
    Command::new(env!("CARGO_BIN_EXE_femp"))
}

/// `femp run SCENE --out OUT --no-frames -q EXTRA…` started in the background (stderr piped).
fn spawn_run(scene: &str, out: &Path, extra: &[&str]) -> Child {
    femp()
        .args([
            "run",
            scene,
            "--out",
            out.to_str().unwrap(),
            "--no-frames",
            "-q",
        ])
        .args(extra)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn run_femp(args: &[&str]) -> Output {
    femp().args(args).output().expect("femp runs")
}

use crate::cli::scene as scene_file;

/// An MPM block falling onto a fixed FEM plate under gravity, for `duration` seconds.
pub(crate) fn block(duration: f64) -> Value {
    json!({
        "dimension": 2, "gravity": [0, -9.81],
        "time": { "dt": 0.01, "duration": duration },
        "mpm": { "grid_spacing": 0.05 },
        "bodies": [
            { "kind": "mpm", "name": "block",
              "shape": { "box": { "min": [-0.2, 0.05], "max": [0.2, 0.25] } },
              "material": { "E": 1e5, "nu": 0.3, "rho": 1000 } },
            { "kind": "fem", "name": "plate",
              "mesh": { "rectangle": { "min": [-1, -0.1], "max": [1, 0], "cells": [20, 1] } },
              "material": { "E": 1e7, "nu": 0.3, "rho": 1000 },
              "prescribed": [ { "vertices": "all", "motion": [] } ] }
        ],
        "contact": { "dhat": 0.005, "kappa": 1e5 }
    })
}

fn summary(out: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

/// Every line of `metrics.csv` ends with a newline and has the header's number of fields; the
/// number of data rows.
fn whole_rows(out: &Path) -> usize {
    let text = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
    assert!(
        text.ends_with('\n'),
        "a partial last row: {:?}",
        text.lines().last()
    );
    let mut lines = text.lines();
    let n = lines.next().unwrap().split(',').count();
    let mut rows = 0;
    for l in lines {
        assert_eq!(l.split(',').count(), n, "row {rows}: {l}");
        rows += 1;
    }
    rows
}

/// Wait until `cond` holds (polling), at most `secs` seconds.
fn wait_for(secs: u64, mut cond: impl FnMut() -> bool) -> bool {
    let end = Instant::now() + Duration::from_secs(secs);
    while Instant::now() < end {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}

/// Wait for a child to exit (at most `secs`), killing it if it does not: a hang fails the test.
fn wait_exit(child: &mut Child, secs: u64) -> std::process::ExitStatus {
    let end = Instant::now() + Duration::from_secs(secs);
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        if Instant::now() > end {
            let _ = child.kill();
            panic!("femp did not exit within {secs} s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill")
        .args([&format!("-{sig}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
}

/// Rows in `metrics.csv` so far (0 if it does not exist yet).
fn rows_so_far(out: &Path) -> usize {
    std::fs::read_to_string(out.join("metrics.csv"))
        .map_or(0, |t| t.lines().count().saturating_sub(1))
}

#[test]
fn signals_stop_a_run_with_status_interrupted_and_whole_rows() {
    let dir = tempfile::tempdir().unwrap();
    // 100 000 steps: it runs until a signal stops it.
    let p = scene_file(dir.path(), "long.json", &block(1000.0));
    for sig in ["TERM", "HUP", "INT"] {
        let out = dir.path().join(format!("out_{sig}"));
        let mut child = spawn_run(&p, &out, &[]);
        assert!(
            wait_for(60, || rows_so_far(&out) >= 5),
            "{sig}: no progress"
        );
        signal(&child, sig);
        let status = wait_exit(&mut child, 60);
        assert_eq!(status.code(), Some(130), "SIG{sig}");
        let s = summary(&out);
        assert_eq!(s["status"], "interrupted", "SIG{sig}: {s}");
        assert!(s["error"].as_str().unwrap().contains("interrupted"), "{s}");
        let steps = s["steps"].as_u64().unwrap() as usize;
        assert!(steps >= 4, "SIG{sig}: {steps} steps");
        assert_eq!(
            whole_rows(&out),
            steps + 1,
            "SIG{sig}: initial state + every step"
        );
    }
}

#[test]
fn an_interrupt_stops_a_step_inside_its_newton_iterations() {
    // The flag is up before the step: a BFEMP step returns at its first Newton iteration (the
    // solver checks before every iteration; a step that never converges stops the same way),
    // an augury step before it starts.
    let text = serde_json::to_string(&block(1.0)).unwrap();
    let s = scene::parse(&text, "b.json", ".".into(), "b").unwrap();
    let mut w = World::<2>::build(s).unwrap();
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    w.set_interrupt(Some(flag.clone()));
    assert!(matches!(
        w.step(),
        Err(SimError::Interrupted { step: 0, .. })
    ));
    assert_eq!(w.clock.step, 0);
    flag.store(false, std::sync::atomic::Ordering::Relaxed);
    assert!(w.step().is_ok());
    assert_eq!(w.clock.step, 1);

    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/augury_blocks.json");
    let mut w = World::<2>::build(scene::load(&p).unwrap()).unwrap();
    w.set_interrupt(Some(std::sync::Arc::new(true.into())));
    assert!(matches!(
        w.step(),
        Err(SimError::Interrupted { step: 0, .. })
    ));
}

#[test]
fn a_closed_stderr_does_not_stop_a_run() {
    let dir = tempfile::tempdir().unwrap();
    let p = scene_file(dir.path(), "b.json", &block(0.2));
    let out = dir.path().join("out");
    // Progress on (not -q): the last step's progress line and the final line go to a pipe
    // whose reader is gone (`femp run … 2>&1 | head -1`).
    let mut child = femp()
        .args(["run", &p, "--out", out.to_str().unwrap(), "--no-frames"])
        .stderr(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stderr.take());
    drop(child.stdout.take());
    let status = wait_exit(&mut child, 120);
    assert_eq!(status.code(), Some(0));
    assert_eq!(summary(&out)["status"], "completed");
    // `check` with a closed stdout.
    let mut child = femp()
        .args(["check", &p])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    assert_eq!(wait_exit(&mut child, 60).code(), Some(0));
}

#[test]
fn an_earlier_runs_outputs_are_refused_or_replaced_never_mixed() {
    let dir = tempfile::tempdir().unwrap();
    let p = scene_file(dir.path(), "b.json", &block(0.1));
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    assert!(run_femp(&["run", &p, "--out", o, "-q"]).status.success());
    let frames = |out: &Path| std::fs::read_dir(out.join("frames")).unwrap().count();
    assert_eq!(
        frames(&out),
        2 * 11,
        "particles and plate, initial + 10 steps"
    );
    // Again into the same directory: refused, naming what is there; nothing touched.
    let r = run_femp(&["run", &p, "--out", o, "-q", "--max-steps", "2"]);
    assert_eq!(r.status.code(), Some(1));
    let err = String::from_utf8_lossy(&r.stderr);
    for needle in [
        "holds the outputs of an earlier run",
        "summary.json",
        "metrics.csv",
        "2 .pvd files",
        "22 frame files (frames/)",
        "--overwrite",
    ] {
        assert!(err.contains(needle), "lacks `{needle}`: {err}");
    }
    assert_eq!(summary(&out)["steps"], 10);
    assert_eq!(frames(&out), 22);
    // A user's own file in the directory is neither an earlier output nor removed.
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    // With --overwrite: the old outputs go (and the run says so), the new run's are alone.
    let r = run_femp(&["run", &p, "--out", o, "--max-steps", "2", "--overwrite"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("removed the outputs of an earlier run"),
        "{err}"
    );
    assert_eq!(summary(&out)["steps"], 2);
    assert_eq!(frames(&out), 2 * 3);
    assert_eq!(whole_rows(&out), 3);
    let pvd = std::fs::read_to_string(out.join("particles.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 3);
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine"
    );
}

#[test]
fn two_runs_never_share_an_output_directory() {
    let dir = tempfile::tempdir().unwrap();
    let p = scene_file(dir.path(), "long.json", &block(1000.0));
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    let mut first = femp()
        .args(["run", &p, "--out", o, "--no-frames", "-q"])
        .spawn()
        .unwrap();
    assert!(wait_for(60, || rows_so_far(&out) >= 2));
    // Even with --overwrite the second run may not touch the first one's files.
    let r = run_femp(&["run", &p, "--out", o, "--no-frames", "-q", "--overwrite"]);
    assert_eq!(r.status.code(), Some(1));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("another femp run is writing into this directory"),
        "{err}"
    );
    signal(&first, "TERM");
    assert_eq!(wait_exit(&mut first, 60).code(), Some(130));
    assert_eq!(summary(&out)["status"], "interrupted");
    whole_rows(&out);
    // Once the first has ended, the directory is free again.
    let r = run_femp(&[
        "run",
        &p,
        "--out",
        o,
        "--no-frames",
        "-q",
        "--overwrite",
        "--max-steps",
        "1",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
}

#[test]
fn body_names_cannot_write_outside_the_output_directory() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["../escaped", "/tmp/femp_escaped_abs", "particles"] {
        let mut v = block(0.05);
        v["bodies"][1]["name"] = json!(name);
        let p = scene_file(dir.path(), "n.json", &v);
        let out = dir.path().join("sub").join("out");
        let r = run_femp(&["run", &p, "--out", out.to_str().unwrap(), "-q"]);
        assert_eq!(r.status.code(), Some(1), "{name}");
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(err.contains("bodies[1].name"), "{name}: {err}");
        assert!(
            !out.exists(),
            "{name}: nothing is written for a rejected scene"
        );
    }
    assert!(!dir.path().join("sub").join("escaped.pvd").exists());
    assert!(!Path::new("/tmp/femp_escaped_abs.pvd").exists());
}

/// `femp ARGS` under a file-size limit of `kib` KiB (`ulimit -f`; SIGXFSZ ignored, so a write
/// past it fails with EFBIG — what a full disk does to a run, in miniature).
fn femp_with_file_limit(kib: u64, args: &[&str]) -> Output {
    Command::new("bash")
        .arg("-c")
        .arg(format!("ulimit -f {kib}; trap '' XFSZ; exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_femp"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn a_failed_write_ends_the_run_with_its_summary_saying_why() {
    let dir = tempfile::tempdir().unwrap();
    let p = scene_file(dir.path(), "b.json", &block(3.0));
    // metrics.csv outgrows 16 KiB after ~50 rows: the row that does not fit is cut off.
    let out = dir.path().join("metrics_full");
    let r = femp_with_file_limit(
        16,
        &[
            "run",
            &p,
            "--out",
            out.to_str().unwrap(),
            "--no-frames",
            "-q",
        ],
    );
    assert_eq!(
        r.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    let s = summary(&out);
    assert_eq!(s["status"], "failed");
    let why = s["error"].as_str().unwrap();
    assert!(
        why.contains("metrics.csv") && why.contains("too large"),
        "{why}"
    );
    let steps = s["steps"].as_u64().unwrap() as usize;
    assert!(steps > 10, "{steps}");
    assert_eq!(whole_rows(&out), steps + 1);
    // A frame that does not fit: no partial frame is left, and the collection lists none.
    let out = dir.path().join("frame_full");
    let r = femp_with_file_limit(4, &["run", &p, "--out", out.to_str().unwrap(), "-q"]);
    assert_eq!(r.status.code(), Some(1));
    let s = summary(&out);
    assert_eq!(s["status"], "failed");
    assert!(
        s["error"]
            .as_str()
            .unwrap()
            .contains("particles_000000.vtu"),
        "{s}"
    );
    assert_eq!(s["frames"], 0);
    let left: Vec<PathBuf> = std::fs::read_dir(out.join("frames"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert!(left.is_empty(), "{left:?}");
    assert_eq!(whole_rows(&out), 1, "the initial state");
}

#[test]
fn the_summary_is_recorded_in_place_when_it_cannot_be_replaced() {
    // A full disk has no room for a temporary copy: the summary is then written over itself.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("summary.json");
    std::fs::write(
        &path,
        format!(
            "{{\"status\": \"running\", \"pad\": \"{}\"}}",
            "x".repeat(200)
        ),
    )
    .unwrap();
    // The temporary's name taken by a directory: the atomic replacement fails.
    std::fs::create_dir(dir.path().join("summary.json.tmp")).unwrap();
    femp::output::write_replacing(&path, b"{\"status\": \"failed\"}").unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let v: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["status"], "failed");
    assert!(v.get("pad").is_none());
    // Without the obstacle it is replaced whole.
    std::fs::remove_dir(dir.path().join("summary.json.tmp")).unwrap();
    femp::output::write_replacing(&path, b"{}").unwrap();
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "{}");
}

#[test]
fn absurd_arguments_are_refused_without_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let p = scene_file(dir.path(), "b.json", &block(0.05));
    let o = dir.path().join("out");
    let o = o.to_str().unwrap();
    for args in [
        &[
            "run",
            &p,
            "--out",
            o,
            "--pictures",
            "--picture-size",
            "4294967295x64",
        ][..],
        &[
            "run",
            &p,
            "--out",
            o,
            "--pictures",
            "--gif-frames",
            "100000000",
        ],
        &["run", &p, "--out", o, "--max-steps", "-1"],
        &["run", &p, "--out", o, "--memory-limit", "-3"],
    ] {
        let r = run_femp(args);
        let code = r.status.code();
        assert!(code == Some(1) || code == Some(2), "{args:?}: {code:?}");
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    // 10¹⁸ steps: refused by the step limit, naming the field; with the limit raised and
    // --max-steps, it runs (nothing is sized by the step count).
    let mut v = block(1e16);
    v["time"]["dt"] = json!(0.01);
    let p = scene_file(dir.path(), "huge.json", &v);
    let r = run_femp(&["run", &p, "--out", o, "-q"]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stderr).contains("time.dt"));
    let r = run_femp(&[
        "run",
        &p,
        "--out",
        o,
        "-q",
        "--step-limit",
        "1e19",
        "--max-steps",
        "2",
        "--no-frames",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    // A scene a million times too large: `check` refuses it at once, with the estimate.
    let mut v = block(0.05);
    v["mpm"]["grid_spacing"] = json!(1e-7);
    let p = scene_file(dir.path(), "fine.json", &v);
    let r = run_femp(&["check", &p]);
    assert_eq!(r.status.code(), Some(1));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("mpm.grid_spacing") && err.contains("--memory-limit"),
        "{err}"
    );
}

#[test]
fn overlapping_augury_bodies_are_counted_and_warned_about() {
    // Without contact handling two blocks pass through each other: by default the run stops
    // once a vertex is half an edge deep (`augury.penetration_limit`), naming it; with the
    // limit lifted it completes and says how often, and how deep, bodies overlapped.
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/augury_blocks.json");
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
    v["augury"] = json!({ "grid_spacing": 0.25, "contact": "none" });
    let dir = tempfile::tempdir().unwrap();
    let p = scene_file(dir.path(), "stop.json", &v);
    let out = dir.path().join("stopped");
    let r = run_femp(&["run", &p, "--out", out.to_str().unwrap(), "--no-frames"]);
    assert_eq!(r.status.code(), Some(1));
    let s = summary(&out);
    assert_eq!(s["status"], "failed");
    let why = s["error"].as_str().unwrap();
    assert!(
        why.contains("inside `") && why.contains("penetration_limit"),
        "{why}"
    );
    // The stopping step's row is written: its depth is past the limit.
    let text = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = header
        .iter()
        .position(|h| *h == "penetration_depth")
        .unwrap();
    let last: f64 = text
        .lines()
        .last()
        .unwrap()
        .split(',')
        .nth(col)
        .unwrap()
        .parse()
        .unwrap();
    assert!(last > 0.5 * 0.125, "{last}");
    v["augury"]["penetration_limit"] = Value::Null;
    let p = scene_file(dir.path(), "through.json", &v);
    let out = dir.path().join("out");
    let r = run_femp(&["run", &p, "--out", out.to_str().unwrap(), "--no-frames"]);
    assert!(r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("warning: points were inside another body") && err.contains("m inside `"),
        "{err}"
    );
    let s = summary(&out);
    assert_eq!(s["status"], "completed");
    assert!(s["penetrating_steps"].as_u64().unwrap() > 10, "{s}");
    assert!(
        s["warnings"][0]
            .as_str()
            .unwrap()
            .contains("inside another body"),
        "{s}"
    );
    // With augury contact the same blocks bounce apart: no warning.
    let out = dir.path().join("out2");
    let fixture =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/augury_blocks.json");
    let r = run_femp(&[
        "run",
        fixture.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-frames",
    ]);
    assert!(r.status.success());
    assert_eq!(summary(&out)["warnings"], json!([]));
}

#[test]
fn any_number_of_threads_gives_the_same_bits() {
    // 5 000 particles with friction on a plate of 1 200 elements: the sums over particles and
    // elements are split across threads (chunks of 1 024). Summed in fixed chunks, the run is
    // the same to the bit on 1, 2 or 3 threads — rayon's own `sum` splits by thread count and
    // work stealing, and the buckling fixture differed from its fifth step.
    let mut v = block(0.15);
    v["mpm"]["grid_spacing"] = json!(0.02);
    v["bodies"][0]["shape"]["box"] = json!({ "min": [-0.5, 0.01], "max": [0.5, 0.51] });
    v["bodies"][0]["velocity"] = json!([0.5, -1.0]);
    v["bodies"][1]["mesh"]["rectangle"]["cells"] = json!([100, 6]);
    v["bodies"][1]["prescribed"] =
        json!([{ "vertices": { "below": { "axis": 1, "value": -0.099 } }, "motion": [] }]);
    v["contact"]["friction"] = json!(0.3);
    let text = serde_json::to_string(&v).unwrap();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let s = scene::parse(&text, "d.json", ".".into(), "d").unwrap();
                let mut w = World::<2>::build(s).unwrap();
                assert!(w.bodies.mpm.as_ref().unwrap().x.len() >= 5000);
                let mut energies = Vec::new();
                for _ in 0..10 {
                    let r = w.step().unwrap();
                    let m = w.measure();
                    energies
                        .push((m.kinetic_energy + m.elastic_energy + m.barrier_energy).to_bits());
                    energies.push(r.newton_iterations as u64);
                }
                (crate::checkpoint::bits(&w), energies)
            })
    };
    let one = run(1);
    for threads in [2, 3] {
        let other = run(threads);
        assert!(
            one.1 == other.1,
            "energies or iteration counts differ on {threads} threads"
        );
        assert!(one.0 == other.0, "states differ on {threads} threads");
    }
}

/// What left a run's summary at `running` (issue 39) now ends it with a final status: a
/// file-size limit (SIGXFSZ, which killed femp mid-write and left a `.vtu.tmp`), two signals
/// 50 ms apart (the second stops femp at once), and a signal while large pictures are drawn
/// (which were drawn to the end first, and left a GIF header alone).
#[test]
fn every_catchable_end_leaves_a_final_summary_and_no_temporaries() {
    let dir = tempfile::tempdir().unwrap();
    let p = scene_file(dir.path(), "b.json", &block(3.0));
    // A file-size limit without `trap '' XFSZ`: femp ignores the signal itself.
    let out = dir.path().join("xfsz");
    let r = Command::new("bash")
        .arg("-c")
        .arg("ulimit -f 4; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_femp"))
        .args(["run", &p, "--out", out.to_str().unwrap(), "-q"])
        .output()
        .unwrap();
    assert_eq!(
        r.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    let s = summary(&out);
    assert_eq!(s["status"], "failed", "{s}");
    assert!(s["error"].as_str().unwrap().contains("too large"), "{s}");
    let tmp: Vec<PathBuf> = std::fs::read_dir(out.join("frames"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .chain(std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().path()))
        .filter(|p| p.to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(tmp.is_empty(), "{tmp:?}");

    // Two SIGTERMs 50 ms apart.
    let long = scene_file(dir.path(), "long.json", &block(1000.0));
    let out = dir.path().join("twice");
    let mut child = spawn_run(&long, &out, &[]);
    assert!(wait_for(60, || rows_so_far(&out) >= 5), "no progress");
    signal(&child, "TERM");
    std::thread::sleep(Duration::from_millis(50));
    signal(&child, "TERM");
    assert_eq!(wait_exit(&mut child, 60).code(), Some(130));
    let s = summary(&out);
    assert_eq!(s["status"], "interrupted", "{s}");

    // A signal while large pictures are drawn: the run stops before drawing the next, and an
    // animation without a frame is not left behind.
    let out = dir.path().join("pictures");
    let pictures = [
        "--pictures",
        "--picture-size",
        "4096x4096",
        "--key-frames",
        "1000",
        "--gif-frames",
        "10000",
    ];
    let mut child = spawn_run(&long, &out, &pictures);
    assert!(wait_for(120, || rows_so_far(&out) >= 1), "no progress");
    signal(&child, "TERM");
    assert_eq!(wait_exit(&mut child, 120).code(), Some(130));
    let s = summary(&out);
    assert_eq!(s["status"], "interrupted", "{s}");
    let gif = out.join("pictures/animation.gif");
    if let Ok(m) = std::fs::metadata(&gif) {
        assert!(m.len() > 1000, "a GIF of {} bytes: no frame", m.len());
    }
}

/// A symbolic link planted in `--out` is not written through (issue 39): a `metrics.csv`
/// pointing outside, or a `frames/` directory link, refuses the run — with or without
/// `--overwrite` — and the file outside is untouched.
#[test]
fn writes_do_not_follow_links_planted_in_the_output_directory() {
    let dir = tempfile::tempdir().unwrap();
    let p = scene_file(dir.path(), "b.json", &block(0.05));
    let outside = dir.path().join("outside.txt");
    std::fs::write(&outside, "keep me").unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    std::os::unix::fs::symlink(&outside, out.join("metrics.csv")).unwrap();
    for extra in [&[][..], &["--overwrite"][..]] {
        let mut args = vec!["run", &p, "--out", out.to_str().unwrap(), "-q"];
        args.extend_from_slice(extra);
        let r = run_femp(&args);
        assert_eq!(r.status.code(), Some(1));
        let e = String::from_utf8_lossy(&r.stderr);
        assert!(e.contains("metrics.csv: a symbolic link"), "{e}");
        assert_eq!(std::fs::read_to_string(&outside).unwrap(), "keep me");
    }
    std::fs::remove_file(out.join("metrics.csv")).unwrap();
    let elsewhere = dir.path().join("elsewhere");
    std::fs::create_dir_all(&elsewhere).unwrap();
    std::os::unix::fs::symlink(&elsewhere, out.join("frames")).unwrap();
    let r = run_femp(&["run", &p, "--out", out.to_str().unwrap(), "-q"]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stderr).contains("frames: a symbolic link"));
    assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 0);
}
