//! A fuzz harness over scenes (proptest): every committed fixture scene, mutated — values
//! replaced by extremes (0, negative, denormal, 10³⁰⁸, 2⁶⁴ − 1), fields removed, renamed or
//! retyped, array entries dropped or repeated, the text cut short or spliced with bytes, mesh
//! files corrupted — goes through what `femp check` and `femp run` do: parse, validate,
//! estimate the size, build the world and take two steps. Whatever the input: no panic, no
//! hang (a watchdog raises the interrupt flag after a few seconds; a case must end soon after),
//! and no allocation past the test binary's cap ([`CappedAlloc`], 8 GiB: an unbounded one
//! aborts the binary).
//!
//! The case count is `PROPTEST_CASES` (default 192 here; `PROPTEST_CASES=3000 cargo test
//! --release -p femp --test integration fuzz` for a longer campaign); failures are kept in
//! `fuzz.proptest-regressions` beside this file and replayed first.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use femp::scene::{self, size::Limits};
use femp::{SimError, World};
use proptest::prelude::*;
use serde_json::{Value, json};

/// The system allocator with a cap on the bytes live at once (see the test binary's
/// `#[global_allocator]`).
pub struct CappedAlloc {
    cap: usize,
    live: AtomicUsize,
}

impl CappedAlloc {
    /// An allocator that refuses to hold more than `cap` bytes.
    pub const fn new(cap: usize) -> Self {
        Self {
            cap,
            live: AtomicUsize::new(0),
        }
    }

    fn take(&self, bytes: usize) -> bool {
        let before = self.live.fetch_add(bytes, Ordering::Relaxed);
        if before.saturating_add(bytes) > self.cap {
            self.live.fetch_sub(bytes, Ordering::Relaxed);
            return false;
        }
        true
    }
}

// SAFETY: every method forwards to `System` with the caller's layout; the counter only decides
// whether to forward (refusing with a null pointer, which the `GlobalAlloc` contract allows).
unsafe impl GlobalAlloc for CappedAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !self.take(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: the caller upholds `alloc`'s contract for `layout`.
        let p = unsafe { System.alloc(layout) };
        if p.is_null() {
            self.live.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !self.take(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: as for `alloc`.
        let p = unsafe { System.alloc_zeroed(layout) };
        if p.is_null() {
            self.live.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` with `layout` (every allocation goes there).
        unsafe { System.dealloc(ptr, layout) };
        self.live.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size();
        if new_size > old && !self.take(new_size - old) {
            return std::ptr::null_mut();
        }
        // SAFETY: `ptr` and `layout` come from a `System` allocation; the caller upholds the
        // rest of `realloc`'s contract.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if p.is_null() {
            if new_size > old {
                self.live.fetch_sub(new_size - old, Ordering::Relaxed);
            }
        } else if new_size < old {
            self.live.fetch_sub(old - new_size, Ordering::Relaxed);
        }
        p
    }
}

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures")
}

/// The fixture scenes, parsed, in file-name order.
fn bases() -> &'static [(String, Value)] {
    static BASES: std::sync::OnceLock<Vec<(String, Value)>> = std::sync::OnceLock::new();
    BASES.get_or_init(|| {
        let mut v: Vec<(String, Value)> = std::fs::read_dir(fixtures().join("scenes"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "json"))
            .map(|p| {
                let text = std::fs::read_to_string(&p).unwrap();
                (
                    p.file_stem().unwrap().to_string_lossy().into_owned(),
                    serde_json::from_str(&text).unwrap(),
                )
            })
            .collect();
        v.sort_by(|a, b| a.0.cmp(&b.0));
        v
    })
}

/// Paths to every value in a JSON tree (object keys and array indices), root first.
fn paths(v: &Value) -> Vec<Vec<Value>> {
    let mut out = vec![Vec::new()];
    let mut i = 0;
    while i < out.len() {
        let path = out[i].clone();
        match at(v, &path) {
            Some(Value::Object(m)) => {
                for k in m.keys() {
                    let mut p = path.clone();
                    p.push(Value::String(k.clone()));
                    out.push(p);
                }
            }
            Some(Value::Array(a)) => {
                for k in 0..a.len() {
                    let mut p = path.clone();
                    p.push(json!(k));
                    out.push(p);
                }
            }
            _ => {}
        }
        i += 1;
    }
    out
}

fn at<'a>(v: &'a Value, path: &[Value]) -> Option<&'a Value> {
    path.iter().try_fold(v, |v, k| match k {
        Value::String(s) => v.get(s.as_str()),
        Value::Number(n) => v.get(n.as_u64()? as usize),
        _ => None,
    })
}

fn at_mut<'a>(v: &'a mut Value, path: &[Value]) -> Option<&'a mut Value> {
    path.iter().try_fold(v, |v, k| match k {
        Value::String(s) => v.get_mut(s.as_str()),
        Value::Number(n) => v.get_mut(n.as_u64()? as usize),
        _ => None,
    })
}

/// Values a mutation puts in place of another.
fn replacement(k: u32) -> Value {
    match k % 24 {
        0 => json!(0),
        1 => json!(-1),
        2 => json!(-0.0),
        3 => json!(5e-324),
        4 => json!(1e-300),
        5 => json!(1e300),
        6 => json!(f64::MAX),
        7 => json!(-f64::MAX),
        8 => json!(u64::MAX),
        9 => json!(i64::MIN),
        10 => json!(1e18),
        11 => json!(4_294_967_296u64),
        12 => json!(1e9),
        13 => json!(0.5),
        14 => json!(3),
        15 => json!(""),
        16 => json!("../escape"),
        17 => json!("particles"),
        18 => json!("all"),
        19 => json!(null),
        20 => json!([]),
        21 => json!([1e308, -1e308, 0]),
        22 => json!({}),
        _ => json!(true),
    }
}

/// One mutation of the tree: `(which value, what to do, a parameter)`.
fn mutate(v: &mut Value, target: u32, op: u32, k: u32) {
    let all = paths(v);
    let path = &all[target as usize % all.len()];
    match op % 7 {
        // Replace by an extreme or a wrong type.
        0 | 1 => {
            if let Some(x) = at_mut(v, path) {
                *x = replacement(k);
            }
        }
        // Scale a number by a large or small factor (keeps most scenes valid but huge/tiny).
        2 => {
            if let Some(x) = at_mut(v, path)
                && let Some(f) = x.as_f64()
            {
                let factor = [1e-6, 1e-3, 0.1, 10.0, 1e3, 1e6][k as usize % 6];
                *x = json!(f * factor);
            }
        }
        // Remove the value from its parent.
        3 => {
            if let Some((last, parent)) = path.split_last()
                && let Some(p) = at_mut(v, parent)
            {
                match (p, last) {
                    (Value::Object(m), Value::String(s)) => {
                        m.remove(s);
                    }
                    (Value::Array(a), Value::Number(n)) => {
                        let i = n.as_u64().unwrap_or(0) as usize;
                        if i < a.len() {
                            a.remove(i);
                        }
                    }
                    _ => {}
                }
            }
        }
        // Repeat an array entry.
        4 => {
            if let Some(Value::Array(a)) = at_mut(v, path)
                && !a.is_empty()
            {
                let e = a[k as usize % a.len()].clone();
                a.push(e);
            }
        }
        // Add an unknown field.
        5 => {
            if let Some(Value::Object(m)) = at_mut(v, path) {
                m.insert(format!("field_{}", k % 5), json!(k));
            }
        }
        // Rename a field to a near miss.
        _ => {
            if let Some((Value::String(s), parent)) = path.split_last()
                && let Some(Value::Object(m)) = at_mut(v, parent)
                && let Some(x) = m.remove(s)
            {
                m.insert(format!("{s}s"), x);
            }
        }
    }
}

/// Corrupt mesh bytes: flip a byte, overwrite a number with 2⁶⁴ − 1, cut the file short, or
/// drop a line.
pub fn corrupt(bytes: &[u8], op: u32, at: u32) -> Vec<u8> {
    let mut b = bytes.to_vec();
    if b.is_empty() {
        return b;
    }
    let i = at as usize % b.len();
    match op % 5 {
        0 => b[i] ^= 1 << (at % 8),
        1 => {
            let end = b[i..]
                .iter()
                .position(|c| !c.is_ascii_digit())
                .map_or(b.len(), |e| i + e);
            b.splice(i..end, b"18446744073709551615".iter().copied());
        }
        2 => b.truncate(i),
        3 => {
            // Repeat a line: a cell or a node written twice, or a section count that no longer
            // matches (issue 39's duplicated cells).
            let (start, end) = line_at(&b, i);
            let line: Vec<u8> = b[start..end].to_vec();
            b.splice(end..end, line);
        }
        _ => {
            let (start, end) = line_at(&b, i);
            b.drain(start..end);
        }
    }
    b
}

/// The byte range of the line holding byte `i` (with its newline).
fn line_at(b: &[u8], i: usize) -> (usize, usize) {
    let start = b[..i]
        .iter()
        .rposition(|&c| c == b'\n')
        .map_or(0, |s| s + 1);
    let end = b[i..]
        .iter()
        .position(|&c| c == b'\n')
        .map_or(b.len(), |e| i + e + 1);
    (start, end)
}

/// How long after the world is built the watchdog raises the interrupt flag.
const WATCHDOG: Duration = Duration::from_secs(2);

/// How long a case may go on once its watchdog raised the interrupt flag (the interrupt acts
/// between Newton iterations and between steps).
const GRACE: Duration = Duration::from_secs(30);

/// How long parsing, validation and building (which the interrupt does not reach) may take: far
/// above any case's seconds, even on a loaded machine — a case past it is a hang.
const BUILD: Duration = Duration::from_secs(240);

/// Scenes estimated above this are built but not stepped.
const STEP_MEMORY: f64 = 300e6;

/// Parse, validate, estimate and build the scene text, then take two steps with a watchdog that
/// raises the interrupt flag [`WATCHDOG`] after the build: an error is fine, a panic or a hang
/// is not (the build past [`BUILD`], the steps past [`GRACE`] after the flag went up; the two
/// are timed apart, so a slow build on a loaded machine is not mistaken for an ignored
/// interrupt). Returns the steps taken (0 for an error).
fn exercise(text: &str, base_dir: PathBuf) -> Result<usize, String> {
    let started = Instant::now();
    let mut timing = Timing::default();
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(
        || -> Result<usize, SimError> {
            let mut s = scene::parse(text, "fuzz.json", base_dir, "fuzz")?;
            // Small limits keep a mutated scene that is merely large from making the suite slow.
            s.limits = Limits {
                memory_bytes: 1.5e9,
                steps: 1e7,
            };
            let estimate = scene::size::estimate(&s)?;
            scene::size::check(&estimate, &s.limits)?;
            let step = estimate.memory_bytes <= STEP_MEMORY;
            // Built, not stepped, above STEP_MEMORY: steps of the large fixtures take seconds.
            match s.spec().dimension {
                2 => build_and_step::<2>(s, step, &mut timing),
                _ => build_and_step::<3>(s, step, &mut timing),
            }
        },
    ));
    let built = timing.built.unwrap_or_else(|| started.elapsed());
    if built > BUILD {
        return Err(format!("parsing and building took {built:?}"));
    }
    if let Some(late) = timing.after_interrupt
        && late > GRACE
    {
        return Err(format!(
            "went on {late:?} after the interrupt: the interrupt did not stop it"
        ));
    }
    match outcome {
        Ok(steps) => Ok(steps.unwrap_or(0)),
        Err(p) => Err(format!(
            "panicked: {}",
            p.downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default()
        )),
    }
}

/// What [`exercise`] times: from the start to the built world, and from the watchdog's
/// interrupt (if it fired) to the end of the steps.
#[derive(Default)]
struct Timing {
    built: Option<Duration>,
    after_interrupt: Option<Duration>,
}

/// Build the world and, if `step`, take two steps under the watchdog.
fn build_and_step<const D: usize>(
    s: scene::Scene,
    step: bool,
    timing: &mut Timing,
) -> Result<usize, SimError> {
    let started = Instant::now();
    let built = World::<D>::build(s);
    timing.built = Some(started.elapsed());
    let mut w = built?;
    if !step {
        return Ok(0);
    }
    let flag = Arc::new(AtomicBool::new(false));
    // The watchdog: after WATCHDOG the flag goes up, as Ctrl-C would, and says when.
    let (done, wait) = std::sync::mpsc::channel::<()>();
    let watchdog = {
        let flag = flag.clone();
        std::thread::spawn(move || {
            if wait.recv_timeout(WATCHDOG).is_err() {
                flag.store(true, Ordering::Relaxed);
                Some(Instant::now())
            } else {
                None
            }
        })
    };
    w.set_interrupt(Some(flag));
    let steps = take_steps(&mut w);
    let _ = done.send(());
    if let Ok(Some(raised)) = watchdog.join() {
        timing.after_interrupt = Some(raised.elapsed());
    }
    steps
}

fn take_steps<const D: usize>(w: &mut World<D>) -> Result<usize, SimError> {
    let _ = w.measure();
    for k in 0..2 {
        if let Err(e) = w.step() {
            return if matches!(e, SimError::Interrupted { .. }) {
                Ok(k)
            } else {
                Err(e)
            };
        }
        let _ = w.measure();
    }
    Ok(2)
}

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(192)
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: cases(),
        ..ProptestConfig::default()
    })]

    /// Mutated fixture scenes: 1–3 tree mutations, sometimes a cut or a spliced byte.
    #[test]
    fn mutated_scenes_never_panic_hang_or_exhaust_memory(
        base in 0usize..64,
        mutations in prop::collection::vec((any::<u32>(), any::<u32>(), any::<u32>()), 1..4),
        text_op in prop::option::weighted(0.15, (any::<bool>(), any::<u32>(), any::<u8>())),
    ) {
        let (name, scene) = &bases()[base % bases().len()];
        let mut v = scene.clone();
        for &(target, op, k) in &mutations {
            mutate(&mut v, target, op, k);
        }
        let mut text = serde_json::to_string(&v).unwrap();
        if let Some((cut, at, byte)) = text_op {
            let i = at as usize % (text.len() + 1);
            let mut bytes = text.into_bytes();
            if cut { bytes.truncate(i) } else { bytes.insert(i, byte) }
            text = String::from_utf8_lossy(&bytes).into_owned();
        }
        let r = exercise(&text, fixtures().join("scenes"));
        prop_assert!(r.is_ok(), "{name} mutated by {mutations:?} / {text_op:?}: {}", r.unwrap_err());
    }

    /// Scenes whose mesh file is corrupted (the §6.7 shell, MSH 4.1, and a 2D disk).
    #[test]
    fn corrupted_mesh_files_never_panic_hang_or_exhaust_memory(
        which in any::<bool>(),
        ops in prop::collection::vec((any::<u32>(), any::<u32>()), 1..4),
    ) {
        let (mesh, scene) = if which {
            ("shell.msh", "twist")
        } else {
            ("disk_0.02.msh", "brazilian_disk")
        };
        let mut bytes = std::fs::read(fixtures().join("meshes").join(mesh)).unwrap();
        for &(op, at) in &ops {
            bytes = corrupt(&bytes, op, at);
        }
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("m.msh"), &bytes).unwrap();
        let mut v = bases().iter().find(|(n, _)| n == scene).unwrap().1.clone();
        if which {
            v["bodies"][1]["mesh"]["file"]["path"] = json!("m.msh");
        } else {
            v["bodies"][0]["shape"] = json!({ "file": "m.msh" });
        }
        let r = exercise(&serde_json::to_string(&v).unwrap(), dir.path().to_path_buf());
        prop_assert!(r.is_ok(), "{mesh} corrupted by {ops:?}: {}", r.unwrap_err());
    }
}

/// A 2D FEM body for the geometric classes: a one-cell rectangle, or a sliver triangle
/// (thickness `thin` of its length) written as a mesh file into `dir`.
fn geometric_body(name: &str, kind: u32, at: [f64; 2], rot: f64, thin: f64, dir: &Path) -> Value {
    let material = json!({ "E": 1e5, "nu": 0.3, "rho": 1 });
    let transform = json!({ "rotate_deg": rot, "translate": at });
    if kind % 3 == 2 {
        // A sliver: three nearly collinear nodes (a valid triangle, relative thickness `thin`).
        let file = dir.join(format!("{name}.msh"));
        let text = format!(
            "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0.4 {thin:e} 0\n$EndNodes\n$Elements\n1\n1 2 2 0 1 1 2 3\n$EndElements\n"
        );
        std::fs::write(&file, text).unwrap();
        json!({ "kind": "fem", "name": name, "mesh": { "file": { "path": format!("{name}.msh") } },
                "transform": transform, "material": material })
    } else {
        let (w, h) = if kind.is_multiple_of(3) {
            (4.0, 0.4)
        } else {
            (1.0, 1.0)
        };
        json!({ "kind": "fem", "name": name,
                "mesh": { "rectangle": { "min": [-w / 2.0, -h / 2.0], "max": [w / 2.0, h / 2.0], "cells": [1, 1] } },
                "transform": transform, "material": material,
                "velocity": [-at[0], -at[1]] })
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: cases() / 4,
        ..ProptestConfig::default()
    })]

    /// Issue 39's geometric classes: many FEM bodies (up to 200) at random places and angles —
    /// crossing, coincident, nested or apart — bars, squares and slivers (relative thickness
    /// 1e-12 … 1e-3), in BFEMP (with an MPM disk among them) and augury scenes: refused with an
    /// error or stepped, never a panic or a hang.
    #[test]
    fn crossing_coincident_many_and_sliver_bodies_never_panic_or_hang(
        augury in any::<bool>(),
        bodies in prop::collection::vec(
            (any::<u32>(), -3.0f64..3.0, -3.0f64..3.0, 0.0f64..360.0, 3u32..13), 1..200),
        snap in any::<bool>(),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let list: Vec<Value> = bodies
            .iter()
            .enumerate()
            .map(|(k, &(kind, x, y, rot, thin))| {
                // Snapped: positions and angles on a coarse lattice, so bodies coincide exactly.
                let (x, y, rot) = if snap { (x.round(), y.round(), (rot / 90.0).round() * 90.0) } else { (x, y, rot) };
                geometric_body(&format!("b{k}"), kind, [x, y], rot, 10f64.powi(-(thin as i32)), dir.path())
            })
            .collect();
        let mut v = json!({ "dimension": 2, "time": { "dt": 1e-3, "duration": 2e-3 }, "bodies": list });
        if augury {
            v["method"] = json!("augury");
        } else {
            v["mpm"] = json!({ "grid_spacing": 0.1 });
            v["bodies"].as_array_mut().unwrap().push(json!({
                "kind": "mpm", "name": "ball", "shape": { "disk": { "center": [0, 9], "radius": 0.3 } },
                "material": { "E": 1e5, "nu": 0.3, "rho": 1 }, "velocity": [0, -100] }));
            v["contact"] = json!({ "dhat": 1e-3, "kappa": 1e5 });
        }
        let r = exercise(&serde_json::to_string(&v).unwrap(), dir.path().to_path_buf());
        prop_assert!(r.is_ok(), "{} bodies (augury {augury}): {}", bodies.len(), r.unwrap_err());
    }

    /// Symbolic links planted among a run's output names (to a file outside, or a directory):
    /// the run is refused or completes, and nothing outside `--out` is ever written.
    #[test]
    fn links_planted_in_the_output_directory_are_never_written_through(
        names in prop::collection::vec(0usize..8, 1..4),
        overwrite in any::<bool>(),
    ) {
        const NAMES: [&str; 8] = ["metrics.csv", "summary.json", "summary.json.tmp",
            "scene_copy.json", "plate.pvd", "frames", "frames/plate_000000.vtu", ".femp.lock"];
        let dir = tempfile::tempdir().unwrap();
        let outside = dir.path().join("outside");
        std::fs::create_dir_all(&outside).unwrap();
        std::fs::write(outside.join("f"), "keep").unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir_all(out.join("frames")).unwrap();
        for &k in &names {
            let p = out.join(NAMES[k]);
            if NAMES[k] == "frames" {
                if !p.is_symlink() {
                    let _ = std::fs::remove_dir_all(&p);
                    std::os::unix::fs::symlink(&outside, &p).unwrap();
                }
            } else if p.symlink_metadata().is_err() && p.parent().is_some_and(|d| !d.is_symlink()) {
                let _ = std::os::unix::fs::symlink(outside.join("f"), &p);
            }
        }
        let s = scene::parse(&crate::trust::block(0.02).to_string(), "b.json", ".".into(), "b").unwrap();
        let r = femp::run::run(s, &out, &femp::run::RunOptions { overwrite, ..Default::default() });
        prop_assert!(matches!(r, Err(SimError::OutputLink { .. })), "{:?}", r.map(|r| r.summary.status));
        prop_assert_eq!(std::fs::read_to_string(outside.join("f")).unwrap(), "keep");
        prop_assert_eq!(std::fs::read_dir(&outside).unwrap().count(), 1);
    }
}

/// File-size limits from 1 KiB to 64 KiB (SIGXFSZ, no `trap` in the shell: femp ignores it):
/// every run ends with a final summary — `completed` or `failed` — and no temporary file; below
/// the summary's own size (about 2 KiB) the run says so on stderr and exits 1 with nothing to
/// record it in.
#[test]
fn file_size_limits_end_every_run_with_a_final_summary() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("b.json");
    std::fs::write(&scene, crate::trust::block(0.3).to_string()).unwrap();
    for kib in [1u64, 2, 3, 4, 8, 16, 64] {
        let out = dir.path().join(format!("out{kib}"));
        let r = std::process::Command::new("bash")
            .arg("-c")
            .arg(format!("ulimit -f {kib}; exec \"$0\" \"$@\""))
            .arg(env!("CARGO_BIN_EXE_femp"))
            .args([
                "run",
                scene.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "-q",
            ])
            .output()
            .unwrap();
        let text = std::fs::read_to_string(out.join("summary.json")).unwrap_or_default();
        let s: Value = serde_json::from_str(&text).unwrap_or(Value::Null);
        let status = s["status"].as_str().unwrap_or("none");
        let stderr = String::from_utf8_lossy(&r.stderr);
        if status == "none" && kib < 4 {
            assert!(
                stderr.contains("summary.json: File too large") && r.status.code() == Some(1),
                "{kib} KiB: {stderr}"
            );
            continue;
        }
        assert!(
            status == "completed" || status == "failed",
            "{kib} KiB: status {status}, exit {:?}: {}",
            r.status,
            String::from_utf8_lossy(&r.stderr)
        );
        let tmp: Vec<PathBuf> = walk(&out)
            .into_iter()
            .filter(|p| p.to_string_lossy().ends_with(".tmp"))
            .collect();
        assert!(tmp.is_empty(), "{kib} KiB: {tmp:?}");
    }
}

fn walk(d: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Ok(rd) = std::fs::read_dir(d) {
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                out.extend(walk(&p));
            } else {
                out.push(p);
            }
        }
    }
    out
}

#[test]
fn the_harness_reaches_the_steps() {
    // The unmutated fixtures go all the way through (a harness that stopped at parsing would
    // show nothing about building or stepping).
    let stepped = bases()
        .iter()
        .filter(|(_, v)| {
            exercise(
                &serde_json::to_string(v).unwrap(),
                fixtures().join("scenes"),
            ) == Ok(2)
        })
        .count();
    assert!(stepped >= 8, "{stepped} fixtures took two steps");
    assert_eq!(exercise("{\"dimension\": 2", fixtures()), Ok(0));
}
