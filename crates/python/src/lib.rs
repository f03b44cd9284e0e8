//! Python bindings of femp (the `femp._femp` extension module; the `femp` Python package in
//! `python/femp` wraps it). Scenes load and edit as JSON, runs write the same outputs as the
//! `femp` program, worlds step from Python with their state as numpy arrays, and the contact
//! and transfer building blocks are callable one at a time. See `docs/python.md`.
//!
//! Every long call releases the GIL and runs on a worker thread while the calling thread polls
//! for Python signals: Ctrl-C stops a run or a step (between Newton iterations) and raises
//! `KeyboardInterrupt`.

mod mesh_contact;

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use femp::SimError;
use femp::run::{RunOptions, RunResult};
use femp::scene::Scene;
use femp_contact::ccd::CcdOptions;
use femp_contact::single::{self, Hessian};
use femp_contact::{ContactError, LogBarrier};
use femp_kernels::{Grid, Kernel, Stencils};
use nalgebra::{SMatrix, SVector, Vector3};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

create_exception!(
    _femp,
    FempError,
    PyException,
    "Base class of femp's errors."
);
create_exception!(
    _femp,
    SceneError,
    FempError,
    "A scene that is malformed, non-physical, too large or starts with bodies overlapping: the message names the field."
);
create_exception!(
    _femp,
    SimulationError,
    FempError,
    "A run or step that failed part-way (Newton not converging, a blow-up): outputs written so far stay."
);
create_exception!(
    _femp,
    StateError,
    FempError,
    "A state, force, target or parameter set on a World that it refuses (a wrong shape, a non-finite value, a body put into another, an inverted element, a vertex the scene moves): the World is unchanged."
);
create_exception!(
    _femp,
    CheckpointError,
    FempError,
    "A checkpoint that cannot be written, read or resumed from: none there, a damaged file, another scene's or other bodies' state, a World steered from outside (the message says which)."
);
create_exception!(
    _femp,
    OutputError,
    FempError,
    "An output directory that is busy (another run holds it) or holds an earlier run's outputs."
);

/// femp's error as the matching Python exception.
fn py_err(e: SimError) -> PyErr {
    let msg = e.to_string();
    match e {
        SimError::Io { .. } => PyOSError::new_err(msg),
        SimError::SceneFormat { .. }
        | SimError::Invalid { .. }
        | SimError::Overlap { .. }
        | SimError::TooLarge { .. } => SceneError::new_err(msg),
        SimError::Interrupted { .. } => PyKeyboardInterrupt::new_err(msg),
        SimError::State { .. } => StateError::new_err(msg),
        SimError::Checkpoint { .. } => CheckpointError::new_err(python_options(&msg)),
        SimError::OutputBusy { .. }
        | SimError::StaleOutput { .. }
        | SimError::OutputLink { .. } => OutputError::new_err(python_options(&msg)),
        _ => SimulationError::new_err(msg),
    }
}

/// A message that names the program's options, with them named as the Python calls take them.
fn python_options(msg: &str) -> String {
    msg.replace("--overwrite", "overwrite=True")
        .replace("--checkpoint", "checkpoint=True")
        .replace("--pictures", "pictures=True")
        .replace("another --out", "another output directory")
        .replace("inside --out", "inside the output directory")
        .replace("in --out", "in the output directory")
}

fn contact_err(e: ContactError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// Run `f` on a worker thread with the GIL released, while the calling thread waits for its
/// result and, every 20 ms without one, polls for Python signals: a signal (Ctrl-C) sets the
/// interrupt flag `f` was given, waits for `f` to stop and re-raises the signal's exception.
/// The result is taken as soon as it is ready (no polling delay on short calls).
fn interruptible<T: Send>(
    py: Python<'_>,
    f: impl FnOnce(Arc<AtomicBool>) -> T + Send,
) -> PyResult<T> {
    use std::sync::mpsc::{RecvTimeoutError, channel};
    let flag = Arc::new(AtomicBool::new(false));
    std::thread::scope(|s| {
        let (tx, rx) = channel();
        let worker = {
            let flag = flag.clone();
            s.spawn(move || {
                // The receiver outlives the worker (the scope joins it): a send cannot fail.
                let _ = tx.send(f(flag));
            })
        };
        let mut rx = rx;
        loop {
            // The receiver is moved into the GIL-free closure and back (it is Send, not Sync).
            let (got, back) = py.detach(move || (rx.recv_timeout(Duration::from_millis(20)), rx));
            rx = back;
            match got {
                Ok(v) => {
                    let _ = py.detach(|| worker.join());
                    return Ok(v);
                }
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(e) = py.check_signals() {
                        flag.store(true, Ordering::SeqCst);
                        let _ = py.detach(|| worker.join());
                        return Err(e);
                    }
                }
                Err(RecvTimeoutError::Disconnected) => {
                    let _ = py.detach(|| worker.join());
                    return Err(SimulationError::new_err(
                        "femp panicked (a bug: please report it)",
                    ));
                }
            }
        }
    })
}

// ---------------------------------------------------------------------------------------------
// Scenes and runs

/// A validated scene: parsed from JSON, with the directory its relative mesh paths resolve
/// against. Edit it as a dict (`femp.Scene.to_dict` / `femp.Scene.from_dict` in the Python
/// package) and validate again.
#[pyclass(name = "Scene", module = "femp", frozen)]
#[derive(Clone)]
struct PyScene {
    scene: Scene,
}

#[pymethods]
impl PyScene {
    /// Read, parse and validate a scene file.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        py.detach(|| femp::scene::load(&path))
            .map(|scene| Self { scene })
            .map_err(py_err)
    }

    /// Parse and validate scene JSON text; relative mesh paths resolve against `base_dir`;
    /// `name` is used when the text has no `name` field.
    #[staticmethod]
    #[pyo3(signature = (text, base_dir = PathBuf::from("."), name = "scene"))]
    fn from_json(text: &str, base_dir: PathBuf, name: &str) -> PyResult<Self> {
        femp::scene::parse(text, "<python>", base_dir, name)
            .map(|scene| Self { scene })
            .map_err(py_err)
    }

    /// The JSON text the scene was parsed from.
    fn to_json(&self) -> String {
        self.scene.source.clone().unwrap_or_default()
    }

    /// The scene's name (its `name` field, the file stem, or the `name` argument).
    #[getter]
    fn name(&self) -> String {
        self.scene.name.clone()
    }

    /// 2 or 3.
    #[getter]
    fn dimension(&self) -> usize {
        self.scene.spec().dimension
    }

    /// The directory relative mesh paths resolve against.
    #[getter]
    fn base_dir(&self) -> PathBuf {
        self.scene.base_dir.clone()
    }

    /// What `femp check` prints: the size estimate (particles, nodes, DOFs, memory, steps).
    fn estimate(&self) -> PyResult<String> {
        femp::scene::size::estimate(&self.scene)
            .map(|e| e.describe())
            .map_err(py_err)
    }

    fn __repr__(&self) -> String {
        format!(
            "femp.Scene(name={:?}, dimension={})",
            self.scene.name,
            self.scene.spec().dimension
        )
    }
}

/// Run a scene to its end (or `max_steps`), writing frames, `metrics.csv` and `summary.json`
/// into `out` exactly as `femp run` does. Returns `(summary_json, columns, rows)`: the summary
/// as JSON text, metrics.csv's column names, and one row of values per measured step (the
/// values themselves: metrics.csv holds them rounded to its precision).
#[pyfunction]
#[pyo3(signature = (scene, out, max_steps = None, frames = true, overwrite = false, progress = false, metrics_every = 1, checkpoint = false, resume = false))]
#[allow(clippy::too_many_arguments)]
fn run(
    py: Python<'_>,
    scene: &PyScene,
    out: PathBuf,
    max_steps: Option<usize>,
    frames: bool,
    overwrite: bool,
    progress: bool,
    metrics_every: usize,
    checkpoint: bool,
    resume: bool,
) -> PyResult<(String, Vec<String>, Vec<Vec<f64>>)> {
    if metrics_every == 0 {
        return Err(pyo3::exceptions::PyValueError::new_err(
            "femp.run: metrics_every must be at least 1 (a metrics row every N steps)",
        ));
    }
    let scene = scene.scene.clone();
    let dim = scene.spec().dimension;
    let result: Result<RunResult, SimError> = interruptible(py, |flag| {
        let opts = RunOptions {
            progress,
            max_steps,
            no_frames: !frames,
            interrupt: Some(flag),
            overwrite,
            metrics_every,
            checkpoint,
            resume,
            command: vec!["python: femp.run".into()],
            ..Default::default()
        };
        femp::run::run(scene, &out, &opts)
    })?;
    let r = result.map_err(py_err)?;
    let summary = serde_json::to_string(&r.summary)
        .map_err(|e| SimulationError::new_err(format!("summary: {e}")))?;
    let names: Vec<&str> = r.force_bodies.iter().map(String::as_str).collect();
    let (header, rows) = match dim {
        2 => table::<2>(&names, &r),
        _ => table::<3>(&names, &r),
    };
    Ok((summary, header, rows))
}

/// The metrics of a run as its column names and rows of numbers — the values themselves, not
/// their CSV text (counts exact, reals whole).
fn table<const D: usize>(forces_of: &[&str], r: &RunResult) -> (Vec<String>, Vec<Vec<f64>>) {
    let method = r.summary.method;
    let names = femp::metrics::column_names::<D>(forces_of, method);
    let rows = r
        .metrics
        .iter()
        .map(|m| m.cells::<D>().into_iter().map(|c| c.value()).collect())
        .collect();
    (names, rows)
}

// ---------------------------------------------------------------------------------------------
// Worlds stepped from Python

enum AnyWorld {
    D2(Box<femp::World<2>>),
    D3(Box<femp::World<3>>),
}

macro_rules! with_world {
    ($w:expr, $v:ident => $body:expr) => {
        match $w {
            AnyWorld::D2($v) => $body,
            AnyWorld::D3($v) => $body,
        }
    };
}

/// A simulation state that steps on demand: `step()` advances one time step (BFEMP or augury,
/// as the scene says); positions, velocities and forces read out as numpy arrays (copies) and
/// are set, with forces and prescribed vertex positions for the next step, through the
/// setters; `record()` writes what `femp run` writes for the steps that follow.
#[pyclass(name = "World", module = "femp")]
struct PyWorld {
    /// The world and what goes with it, shared with the worker thread that steps it.
    state: Arc<Mutex<WorldState>>,
    /// The thread that steps this World, made at the first step and kept: one long-lived
    /// worker per World, so a loop of single steps pays no thread start (nor loses the
    /// thread's caches) per call.
    worker: Option<Worker>,
}

/// A World's state.
struct WorldState {
    world: AnyWorld,
    /// The last step's report (its solver columns and contact forces go into `metrics()`).
    last: Option<femp::StepReport>,
    /// The recording in progress (`record()` .. `stop_recording()`).
    recorder: Option<femp::run::Recorder>,
}

/// A job for a World's worker thread.
type Job = Box<dyn FnOnce() + Send>;

/// A World's worker thread: runs the jobs it is sent, in order, until the World is dropped.
struct Worker {
    jobs: Option<std::sync::mpsc::Sender<Job>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Worker {
    fn spawn() -> PyResult<Self> {
        let (tx, rx) = std::sync::mpsc::channel::<Job>();
        let thread = std::thread::Builder::new()
            .name("femp-world".into())
            .spawn(move || {
                for job in rx {
                    job();
                }
            })
            .map_err(|e| SimulationError::new_err(format!("could not start a thread: {e}")))?;
        Ok(Self {
            jobs: Some(tx),
            thread: Some(thread),
        })
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        // Closing the channel ends the thread's loop; no job is running (the World waits for
        // each).
        drop(self.jobs.take());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The rows of an (n, D) array, or what is wrong with its shape.
pub(crate) fn array_rows<const D: usize>(
    a: &PyReadonlyArray2<'_, f64>,
) -> Result<Vec<SVector<f64, D>>, String> {
    let a = a.as_array();
    if a.ncols() != D {
        return Err(format!(
            "shape ({}, {}), expected (n, {D})",
            a.nrows(),
            a.ncols()
        ));
    }
    Ok((0..a.nrows())
        .map(|i| SVector::from_fn(|k, _| a[(i, k)]))
        .collect())
}

/// The rows of an (n, D) array set on a World (a wrong shape is a `StateError` on `what`).
fn rows<const D: usize>(
    a: &PyReadonlyArray2<'_, f64>,
    what: &str,
) -> PyResult<Vec<SVector<f64, D>>> {
    array_rows(a).map_err(|m| StateError::new_err(format!("{what}: {m}")))
}

fn vectors<const D: usize>(v: &[SVector<f64, D>]) -> Array2<f64> {
    Array2::from_shape_fn((v.len(), D), |(i, a)| v[i][a])
}

fn matrices<const D: usize>(v: &[SMatrix<f64, D, D>]) -> Array3<f64> {
    Array3::from_shape_fn((v.len(), D, D), |(i, a, b)| v[i][(a, b)])
}

fn report_dict<'py>(py: Python<'py>, r: &femp::StepReport) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("newton_iterations", r.newton_iterations)?;
    d.set_item("friction_iterations", r.friction_iterations)?;
    d.set_item("augury_iterations", r.augury_iterations)?;
    d.set_item("friction_converged", r.friction_converged)?;
    d.set_item("contact_terms", r.contact_terms)?;
    d.set_item("min_distance", r.min_distance)?;
    Ok(d)
}

/// Set the particles' positions and/or velocities: both or neither.
fn set_particles_d<const D: usize>(
    w: &mut femp::World<D>,
    x: Option<&PyReadonlyArray2<'_, f64>>,
    v: Option<&PyReadonlyArray2<'_, f64>>,
) -> PyResult<()> {
    let x = x.map(|a| rows::<D>(a, "particles.x")).transpose()?;
    let v = v.map(|a| rows::<D>(a, "particles.v")).transpose()?;
    let old_v = w.bodies.mpm.as_ref().map(|m| m.v.clone());
    if let Some(v) = v {
        w.set_particle_velocities(&v).map_err(py_err)?;
    }
    if let Some(x) = x
        && let Err(e) = w.set_particle_positions(&x)
    {
        if let (Some(m), Some(old)) = (w.bodies.mpm.as_mut(), old_v) {
            m.v = old;
        }
        return Err(py_err(e));
    }
    Ok(())
}

/// Set FEM body `name`'s positions and/or velocities: both or neither.
fn set_fem_d<const D: usize>(
    w: &mut femp::World<D>,
    name: &str,
    x: Option<&PyReadonlyArray2<'_, f64>>,
    v: Option<&PyReadonlyArray2<'_, f64>>,
) -> PyResult<()> {
    let x = x
        .map(|a| rows::<D>(a, &format!("fem[{name}].x")))
        .transpose()?;
    let v = v
        .map(|a| rows::<D>(a, &format!("fem[{name}].v")))
        .transpose()?;
    let b = w.fem_index(name).map_err(py_err)?;
    let old_v = w.bodies.fem[b].v.clone();
    if let Some(v) = v {
        w.set_fem_velocities(name, &v).map_err(py_err)?;
    }
    if let Some(x) = x
        && let Err(e) = w.set_fem_positions(name, &x)
    {
        // Back to the velocities it had (accepted before, so accepted again).
        let _ = w.set_fem_velocities(name, &old_v);
        return Err(py_err(e));
    }
    Ok(())
}

/// `n` steps of `w`, each recorded by `rec` if recording: the last step's report.
fn steps<const D: usize>(
    w: &mut femp::World<D>,
    n: usize,
    mut rec: Option<&mut femp::run::Recorder>,
) -> Result<Option<femp::StepReport>, SimError> {
    let mut last = None;
    for _ in 0..n {
        if w.interrupted() {
            return Err(SimError::Interrupted {
                step: w.clock.step,
                time: w.clock.time,
            });
        }
        let t0 = std::time::Instant::now();
        let r = w.step()?;
        if let Some(rec) = rec.as_deref_mut() {
            rec.record(w, &r, t0, &mut |_, _| {})?;
        }
        last = Some(r);
    }
    Ok(last)
}

/// The state behind `m`, even if a panicking step poisoned the lock (the panic was reported
/// as a bug already).
fn lock(m: &Mutex<WorldState>) -> std::sync::MutexGuard<'_, WorldState> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl PyWorld {
    fn st(&self) -> std::sync::MutexGuard<'_, WorldState> {
        lock(&self.state)
    }

    /// Run `f` on this World's worker thread (started at the first call) with the GIL
    /// released, as [`interruptible`] does on a thread of its own: Ctrl-C sets the flag `f`
    /// was given, waits for `f` to stop and raises `KeyboardInterrupt`.
    fn on_worker<T: Send + 'static>(
        &mut self,
        py: Python<'_>,
        f: impl FnOnce(Arc<AtomicBool>) -> T + Send + 'static,
    ) -> PyResult<T> {
        use std::sync::mpsc::{RecvTimeoutError, channel};
        let flag = Arc::new(AtomicBool::new(false));
        let (tx, rx) = channel();
        let job: Job = {
            let flag = flag.clone();
            Box::new(move || {
                // The World waits for this result; a send fails only if it stopped waiting.
                let _ = tx.send(f(flag));
            })
        };
        // A worker whose thread died (a panic in an earlier job) is replaced.
        let mut job = Some(job);
        for _ in 0..2 {
            if self.worker.is_none() {
                self.worker = Some(Worker::spawn()?);
            }
            let sender = self.worker.as_ref().and_then(|w| w.jobs.as_ref());
            match sender.map(|t| t.send(job.take().expect("not yet sent"))) {
                Some(Ok(())) => break,
                Some(Err(back)) => {
                    job = Some(back.0);
                    self.worker = None;
                }
                None => self.worker = None,
            }
        }
        if job.is_some() {
            return Err(SimulationError::new_err(
                "femp could not hand the step to its worker thread (a bug: please report it)",
            ));
        }
        let mut rx = rx;
        loop {
            // The receiver is moved into the GIL-free closure and back (it is Send, not Sync).
            let (got, back) = py.detach(move || (rx.recv_timeout(Duration::from_millis(20)), rx));
            rx = back;
            match got {
                Ok(v) => return Ok(v),
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(e) = py.check_signals() {
                        flag.store(true, Ordering::SeqCst);
                        let _ = py.detach(move || rx.recv().is_ok());
                        return Err(e);
                    }
                }
                Err(RecvTimeoutError::Disconnected) => {
                    self.worker = None;
                    return Err(SimulationError::new_err(
                        "femp panicked (a bug: please report it)",
                    ));
                }
            }
        }
    }

    fn particles_d<'py, const D: usize>(
        py: Python<'py>,
        w: &femp::World<D>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let Some(m) = &w.bodies.mpm else {
            d.set_item("x", Array2::<f64>::zeros((0, D)).into_pyarray(py))?;
            d.set_item("body_names", Vec::<String>::new())?;
            return Ok(d);
        };
        d.set_item("x", vectors(&m.x).into_pyarray(py))?;
        d.set_item("v", vectors(&m.v).into_pyarray(py))?;
        d.set_item("mass", Array1::from(m.mass.clone()).into_pyarray(py))?;
        d.set_item(
            "rest_volume",
            Array1::from(m.volume.clone()).into_pyarray(py),
        )?;
        d.set_item("volume", Array1::from(m.current_volume()).into_pyarray(py))?;
        d.set_item("F", matrices(&m.f).into_pyarray(py))?;
        d.set_item("B", matrices(&m.b).into_pyarray(py))?;
        let (_, stress) = m.stresses();
        d.set_item("stress", matrices(&stress).into_pyarray(py))?;
        d.set_item("contact_force", vectors(&m.contact_force).into_pyarray(py))?;
        let body: Vec<i64> = m.body.iter().map(|&b| i64::from(b)).collect();
        d.set_item("body", Array1::from(body).into_pyarray(py))?;
        d.set_item(
            "body_names",
            m.bodies.iter().map(|b| b.name.clone()).collect::<Vec<_>>(),
        )?;
        Ok(d)
    }

    fn fem_d<'py, const D: usize>(
        py: Python<'py>,
        w: &femp::World<D>,
        name: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let Some(b) = w.bodies.fem.iter().find(|b| b.name == name) else {
            let known: Vec<&str> = w.bodies.fem.iter().map(|b| b.name.as_str()).collect();
            return Err(PyValueError::new_err(format!(
                "no FEM body `{name}` (the scene's FEM bodies: {known:?})"
            )));
        };
        let d = PyDict::new(py);
        d.set_item("x", vectors(&b.x).into_pyarray(py))?;
        d.set_item("v", vectors(&b.v).into_pyarray(py))?;
        d.set_item("rest", vectors(b.mesh.vertices()).into_pyarray(py))?;
        d.set_item("initial", vectors(&b.initial).into_pyarray(py))?;
        d.set_item("mass", Array1::from(b.mass.clone()).into_pyarray(py))?;
        let cells = b.mesh.cells();
        let elements = Array2::from_shape_fn((cells.len(), D + 1), |(e, k)| cells[e][k] as i64);
        d.set_item("elements", elements.into_pyarray(py))?;
        let facets = Array2::from_shape_fn((b.facets.len(), D), |(f, k)| i64::from(b.facets[f][k]));
        d.set_item("facets", facets.into_pyarray(py))?;
        d.set_item(
            "stress",
            matrices(&b.elastic.cauchy_stress(&b.x)).into_pyarray(py),
        )?;
        d.set_item("contact_force", vectors(&b.contact_force).into_pyarray(py))?;
        Ok(d)
    }

    fn metrics_d<'py, const D: usize>(
        py: Python<'py>,
        w: &femp::World<D>,
        last: Option<&femp::StepReport>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let names = w.force_bodies();
        let mut m = w.measure();
        if let Some(r) = last {
            m.record_step(r);
        }
        (m.contact_forces, m.friction_forces) =
            w.body_forces(last.map_or(&[][..], |r| &r.pair_forces[..]));
        let d = PyDict::new(py);
        let columns = femp::metrics::column_names::<D>(&names, m.method);
        for (k, c) in columns.iter().zip(m.cells::<D>()) {
            match c {
                femp::metrics::Cell::Count(n) => d.set_item(k, n)?,
                femp::metrics::Cell::Real(v, _) => d.set_item(k, v)?,
            }
        }
        Ok(d)
    }
}

#[pymethods]
impl PyWorld {
    /// Build the world of a scene (particles sampled, meshes read, contact pairs set up).
    #[new]
    fn new(py: Python<'_>, scene: &PyScene) -> PyResult<Self> {
        let scene = scene.scene.clone();
        let world = py
            .detach(|| match scene.spec().dimension {
                2 => femp::World::<2>::build(scene).map(|w| AnyWorld::D2(Box::new(w))),
                _ => femp::World::<3>::build(scene).map(|w| AnyWorld::D3(Box::new(w))),
            })
            .map_err(py_err)?;
        Ok(Self {
            state: Arc::new(Mutex::new(WorldState {
                world,
                last: None,
                recorder: None,
            })),
            worker: None,
        })
    }

    /// Advance `n` time steps (default 1); returns the last step's solver report
    /// (`newton_iterations`, `friction_iterations`, `augury_iterations`, `friction_converged`,
    /// `contact_terms`, `min_distance`). A failed step raises `SimulationError`; Ctrl-C, `KeyboardInterrupt`.
    #[pyo3(signature = (n = 1))]
    fn step<'py>(&mut self, py: Python<'py>, n: usize) -> PyResult<Bound<'py, PyDict>> {
        let state = self.state.clone();
        let stepped = self.on_worker(py, move |flag| {
            let mut s = lock(&state);
            let WorldState {
                world, recorder, ..
            } = &mut *s;
            with_world!(world, w => {
                w.set_interrupt(Some(flag));
                let r = steps(w, n, recorder.as_mut());
                w.set_interrupt(None);
                r
            })
        });
        let mut s = self.st();
        // A step (or a recorded write) that failed ends the recording with the summary saying
        // why, as a failed `femp run` does; so does Ctrl-C (`interrupted`).
        let report = match stepped {
            Ok(Ok(r)) => r,
            Ok(Err(e)) => {
                let e = match s.recorder.take() {
                    Some(rec) => with_world!(&s.world, w => rec.fail(w, e)),
                    None => e,
                };
                return Err(py_err(e));
            }
            Err(interrupt) => {
                if let Some(rec) = s.recorder.take() {
                    let _ = with_world!(&s.world, w => {
                        let (step, time) = (w.clock.step, w.clock.time);
                        rec.fail(w, SimError::Interrupted { step, time })
                    });
                }
                return Err(interrupt);
            }
        };
        match report {
            Some(r) => {
                let d = report_dict(py, &r);
                s.last = Some(r);
                d
            }
            None => Ok(PyDict::new(py)),
        }
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        let s = self.st();
        with_world!(&s.world, w => w.clock.time)
    }

    /// Steps taken.
    #[getter]
    fn steps(&self) -> usize {
        let s = self.st();
        with_world!(&s.world, w => w.clock.step)
    }

    /// The time step (s).
    #[getter]
    fn dt(&self) -> f64 {
        let s = self.st();
        with_world!(&s.world, w => w.clock.dt)
    }

    /// 2 or 3.
    #[getter]
    fn dimension(&self) -> usize {
        let s = self.st();
        match s.world {
            AnyWorld::D2(_) => 2,
            AnyWorld::D3(_) => 3,
        }
    }

    /// Names of the FEM bodies.
    #[getter]
    fn fem_bodies(&self) -> Vec<String> {
        let s = self.st();
        with_world!(&s.world, w => w.bodies.fem.iter().map(|b| b.name.clone()).collect())
    }

    /// Names of the MPM bodies (`particles()["body"]` indexes this list).
    #[getter]
    fn mpm_bodies(&self) -> Vec<String> {
        let s = self.st();
        with_world!(&s.world, w => w.bodies.mpm.as_ref().map_or_else(Vec::new, |m| {
            m.bodies.iter().map(|b| b.name.clone()).collect()
        }))
    }

    /// All particles: `x`, `v` (n×D), `mass`, `volume` (current), `rest_volume` (n), `F`, `B`,
    /// `stress` (Cauchy; n×D×D), `contact_force` (n×D, the last step's), `body` (n, an index
    /// into `body_names`).
    fn particles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.st();
        with_world!(&s.world, w => Self::particles_d(py, w))
    }

    /// One FEM body: `x`, `v`, `rest` (mesh vertices), `initial` (after the scene's transform),
    /// `mass` (lumped), `elements` (cells × (D+1) vertex indices), `facets` (boundary facets ×
    /// D), `stress` (Cauchy per element), `contact_force` (per vertex, the last step's).
    fn fem<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
        let s = self.st();
        with_world!(&s.world, w => Self::fem_d(py, w, name))
    }

    /// The current metrics as a dict keyed by `metrics.csv`'s columns: energies, momenta, and
    /// the last step's solver columns and per-body contact forces (`wall_s` is 0 here).
    fn metrics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.st();
        let last = s.last.as_ref();
        with_world!(&s.world, w => Self::metrics_d(py, w, last))
    }

    /// Warnings about what the scene asks for and femp does not fully model.
    fn warnings(&self) -> Vec<String> {
        let s = self.st();
        with_world!(&s.world, w => w.warnings())
    }

    /// Set the particles' positions `x` and/or velocities `v` (n×D, every particle). Refused
    /// (`StateError`, the World unchanged) for a wrong shape, a non-finite value, or a particle
    /// put into or onto a FEM body.
    #[pyo3(signature = (x = None, v = None))]
    fn set_particles(
        &mut self,
        x: Option<PyReadonlyArray2<'_, f64>>,
        v: Option<PyReadonlyArray2<'_, f64>>,
    ) -> PyResult<()> {
        let mut s = self.st();
        with_world!(&mut s.world, w => set_particles_d(w, x.as_ref(), v.as_ref()))
    }

    /// Set FEM body `name`'s vertex positions `x` and/or velocities `v` (vertices×D). Refused
    /// for a wrong shape, a non-finite value, an inverted element, the body put into or onto
    /// another, or a change to a vertex the scene prescribes.
    #[pyo3(signature = (name, x = None, v = None))]
    fn set_fem(
        &mut self,
        name: &str,
        x: Option<PyReadonlyArray2<'_, f64>>,
        v: Option<PyReadonlyArray2<'_, f64>>,
    ) -> PyResult<()> {
        let mut s = self.st();
        with_world!(&mut s.world, w => set_fem_d(w, name, x.as_ref(), v.as_ref()))
    }

    /// The force on each particle (n×D, N; N/m in 2D) during the next step.
    fn apply_particle_forces(&mut self, f: PyReadonlyArray2<'_, f64>) -> PyResult<()> {
        let mut s = self.st();
        with_world!(&mut s.world, w => {
            let f = rows(&f, "particles.force")?;
            w.apply_particle_forces(&f).map_err(py_err)
        })
    }

    /// The force on each vertex of FEM body `name` (vertices×D) during the next step.
    fn apply_fem_forces(&mut self, name: &str, f: PyReadonlyArray2<'_, f64>) -> PyResult<()> {
        let mut s = self.st();
        with_world!(&mut s.world, w => {
            let f = rows(&f, &format!("fem[{name}].force"))?;
            w.apply_fem_forces(name, &f).map_err(py_err)
        })
    }

    /// Move `vertices` of FEM body `name` to `positions` (len(vertices)×D) by the end of the
    /// next step, each on a straight line.
    fn prescribe(
        &mut self,
        name: &str,
        vertices: Vec<usize>,
        positions: PyReadonlyArray2<'_, f64>,
    ) -> PyResult<()> {
        let mut s = self.st();
        with_world!(&mut s.world, w => {
            let p = rows(&positions, &format!("fem[{name}].prescribe"))?;
            w.prescribe(name, &vertices, &p).map_err(py_err)
        })
    }

    /// Set the friction coefficient of every contact pair, or of the pairs between the two
    /// bodies `between`; the number of pairs changed.
    #[pyo3(signature = (mu, between = None))]
    fn set_friction(&mut self, mu: f64, between: Option<(String, String)>) -> PyResult<usize> {
        let mut s = self.st();
        let between = between.as_ref().map(|(a, b)| (a.as_str(), b.as_str()));
        with_world!(&mut s.world, w => w.set_friction(mu, between).map_err(py_err))
    }

    /// Set Young's modulus `E` and Poisson's ratio `nu` of body `name` (MPM or FEM; BFEMP) from
    /// the next step on.
    #[pyo3(signature = (name, E, nu))]
    #[allow(non_snake_case)]
    fn set_material(&mut self, name: &str, E: f64, nu: f64) -> PyResult<()> {
        let mut s = self.st();
        with_world!(&mut s.world, w => w.set_material(name, E, nu).map_err(py_err))
    }

    /// Start recording into `out` what `femp run` writes: the scene's copy, summary.json, the
    /// initial metrics row and frame now, then every step's row and frames at the scene's frame
    /// interval (`frames=False`: none), pictures with `pictures=True`.
    ///
    /// `checkpoint=True` also writes `checkpoint.femp` at every frame time (BFEMP, a World not
    /// steered from outside); `resume=True` puts the World where the checkpoint in `out` was
    /// taken and continues that recording (`femp run --resume`).
    #[pyo3(signature = (out, frames = true, overwrite = false, metrics_every = 1, pictures = false, checkpoint = false, resume = false))]
    #[allow(clippy::too_many_arguments)]
    fn record(
        &mut self,
        py: Python<'_>,
        out: PathBuf,
        frames: bool,
        overwrite: bool,
        metrics_every: usize,
        pictures: bool,
        checkpoint: bool,
        resume: bool,
    ) -> PyResult<()> {
        let mut s = self.st();
        if s.recorder.is_some() {
            return Err(PyValueError::new_err(
                "World.record: already recording; stop_recording() first",
            ));
        }
        if metrics_every == 0 {
            return Err(PyValueError::new_err(
                "World.record: metrics_every must be at least 1 (a metrics row every N steps)",
            ));
        }
        let opts = RunOptions {
            no_frames: !frames,
            overwrite,
            metrics_every,
            pictures: pictures.then(femp::render::PictureOptions::default),
            checkpoint,
            resume,
            command: vec!["python: femp.World.record".into()],
            ..Default::default()
        };
        let world = &mut s.world;
        let rec = py
            .detach(|| {
                with_world!(world, w => if resume {
                    femp::run::Recorder::resume(w, &out, &opts)
                } else {
                    femp::run::Recorder::start(w, &out, &opts)
                })
            })
            .map_err(py_err)?;
        s.recorder = Some(rec);
        Ok(())
    }

    /// Write the World's state to the file `path` (`femp::checkpoint`'s format): every later
    /// step depends on nothing else, so `restore` of it into a World of the same scene
    /// steps on bit for bit. A BFEMP World not steered from outside.
    fn checkpoint(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let s = self.st();
        let world = &s.world;
        py.detach(|| {
            with_world!(world, w => femp::checkpoint::Checkpoint::for_world(w)
                .and_then(|c| c.write(&path)))
        })
        .map_err(py_err)
    }

    /// Put the World where the state in the file `path` was taken (a World of the same scene;
    /// only `time.duration` may differ). Refused, the World unchanged, for another scene's or
    /// other bodies' state or a damaged file.
    fn restore(&mut self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let mut s = self.st();
        if s.recorder.is_some() {
            return Err(PyValueError::new_err(
                "World.restore: recording; stop_recording() first (a recording continues \
                 from a checkpoint with record(out, resume=True))",
            ));
        }
        let WorldState { world, last, .. } = &mut *s;
        py.detach(|| {
            let c = femp::checkpoint::Checkpoint::read(&path)?;
            with_world!(world, w => w.restore(&c.world))
        })
        .map_err(py_err)?;
        *last = None;
        Ok(())
    }

    /// Write a frame of the World as it is now into the recording.
    fn write_frame(&mut self) -> PyResult<()> {
        let mut s = self.st();
        let WorldState {
            world, recorder, ..
        } = &mut *s;
        let Some(rec) = recorder.as_mut() else {
            return Err(PyValueError::new_err(
                "World.write_frame: not recording: call record(out) first",
            ));
        };
        with_world!(world, w => rec.write_frame(w)).map_err(py_err)
    }

    /// End the recording: summary.json `completed`, or with `error` (what stopped the Python
    /// code driving the World) `failed` (`interrupted`) with it. `(summary_json, columns,
    /// rows)` as `run` returns them.
    #[pyo3(signature = (error = None, interrupted = false))]
    fn stop_recording(
        &mut self,
        py: Python<'_>,
        error: Option<String>,
        interrupted: bool,
    ) -> PyResult<(String, Vec<String>, Vec<Vec<f64>>)> {
        let mut s = self.st();
        let Some(rec) = s.recorder.take() else {
            return Err(PyValueError::new_err("World.stop_recording: not recording"));
        };
        let world = &s.world;
        let (step, time) = with_world!(world, w => (w.clock.step, w.clock.time));
        let r = py.detach(|| {
            with_world!(world, w => match error {
                None if !interrupted => rec.finish(w),
                None => Err(rec.fail(w, SimError::Interrupted { step, time })),
                Some(_) if interrupted => Err(rec.fail(w, SimError::Interrupted { step, time })),
                Some(message) => Err(rec.fail(w, SimError::Stopped { step, time, message })),
            })
        });
        let r = match r {
            Ok(r) => r,
            // The recording ended as the caller said: what it wrote is on disk.
            Err(SimError::Stopped { .. } | SimError::Interrupted { .. }) => {
                return Ok((String::new(), Vec::new(), Vec::new()));
            }
            Err(e) => return Err(py_err(e)),
        };
        let summary = serde_json::to_string(&r.summary)
            .map_err(|e| SimulationError::new_err(format!("summary: {e}")))?;
        let names: Vec<&str> = r.force_bodies.iter().map(String::as_str).collect();
        let (header, rows) = match s.world {
            AnyWorld::D2(_) => table::<2>(&names, &r),
            AnyWorld::D3(_) => table::<3>(&names, &r),
        };
        Ok((summary, header, rows))
    }

    /// Whether a recording is in progress.
    #[getter]
    fn recording(&self) -> bool {
        let s = self.st();
        s.recorder.is_some()
    }

    fn __repr__(&self) -> String {
        let dimension = self.dimension();
        let s = self.st();
        with_world!(&s.world, w => format!(
            "femp.World(dimension={dimension}, steps={}, time={:.6e})",
            w.clock.step,
            w.clock.time
        ))
    }
}

// ---------------------------------------------------------------------------------------------
// Single contacts, barrier and CCD

fn point<const D: usize>(a: &PyReadonlyArray1<'_, f64>, what: &str) -> PyResult<SVector<f64, D>> {
    let a = a.as_array();
    if a.len() != D {
        return Err(PyValueError::new_err(format!(
            "{what}: expected {D} coordinates, got {}",
            a.len()
        )));
    }
    Ok(SVector::from_fn(|i, _| a[i]))
}

fn hessian_kind(s: &str) -> PyResult<Hessian> {
    match s {
        "projected" => Ok(Hessian::Projected),
        "exact" => Ok(Hessian::Exact),
        _ => Err(PyValueError::new_err(format!(
            "hessian = {s:?}: expected \"projected\" or \"exact\""
        ))),
    }
}

fn contact_dict<'py, const D: usize, const N: usize>(
    py: Python<'py>,
    c: &single::Contact<D, N>,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("distance", c.distance)?;
    d.set_item("value", c.value)?;
    d.set_item("gradient", vectors(&c.gradient).into_pyarray(py))?;
    let h = Array2::from_shape_fn((N * D, N * D), |(r, col)| {
        c.hessian[r / D][col / D][(r % D, col % D)]
    });
    d.set_item("hessian", h.into_pyarray(py))?;
    Ok(d)
}

/// The barrier potential `w b(d)` of point `p` against edge `e0 e1` (2D or 3D), with its
/// gradient (3×D, rows p, e0, e1) and Hessian (3D×3D); `None` when `d ≥ dhat`. The barrier acts
/// on `d`, not `d²` as the IPC Toolkit's does (docs/contact.md).
#[pyfunction]
#[pyo3(signature = (p, e0, e1, dhat, kappa, weight = 1.0, hessian = "projected"))]
fn point_edge_potential<'py>(
    py: Python<'py>,
    p: PyReadonlyArray1<'py, f64>,
    e0: PyReadonlyArray1<'py, f64>,
    e1: PyReadonlyArray1<'py, f64>,
    dhat: f64,
    kappa: f64,
    weight: f64,
    hessian: &str,
) -> PyResult<Option<Bound<'py, PyDict>>> {
    let b = LogBarrier::new(dhat, kappa).map_err(contact_err)?;
    let h = hessian_kind(hessian)?;
    fn edge<'py, const D: usize>(
        py: Python<'py>,
        b: &LogBarrier,
        weight: f64,
        pts: [&PyReadonlyArray1<'py, f64>; 3],
        h: Hessian,
    ) -> PyResult<Option<Bound<'py, PyDict>>> {
        single::point_edge::<D>(
            b,
            weight,
            &point(pts[0], "p")?,
            &point(pts[1], "e0")?,
            &point(pts[2], "e1")?,
            h,
        )
        .map_err(contact_err)?
        .map(|c| contact_dict(py, &c))
        .transpose()
    }
    match p.as_array().len() {
        2 => edge::<2>(py, &b, weight, [&p, &e0, &e1], h),
        3 => edge::<3>(py, &b, weight, [&p, &e0, &e1], h),
        n => Err(PyValueError::new_err(format!(
            "p: expected 2 or 3 coordinates, got {n}"
        ))),
    }
}

/// The barrier potential of point `p` against triangle `t0 t1 t2` (3D): as
/// [`point_edge_potential`], gradient 4×3, Hessian 12×12.
#[pyfunction]
#[pyo3(signature = (p, t0, t1, t2, dhat, kappa, weight = 1.0, hessian = "projected"))]
fn point_triangle_potential<'py>(
    py: Python<'py>,
    p: PyReadonlyArray1<'py, f64>,
    t0: PyReadonlyArray1<'py, f64>,
    t1: PyReadonlyArray1<'py, f64>,
    t2: PyReadonlyArray1<'py, f64>,
    dhat: f64,
    kappa: f64,
    weight: f64,
    hessian: &str,
) -> PyResult<Option<Bound<'py, PyDict>>> {
    let b = LogBarrier::new(dhat, kappa).map_err(contact_err)?;
    single::point_triangle(
        &b,
        weight,
        &point::<3>(&p, "p")?,
        &point::<3>(&t0, "t0")?,
        &point::<3>(&t1, "t1")?,
        &point::<3>(&t2, "t2")?,
        hessian_kind(hessian)?,
    )
    .map_err(contact_err)?
    .map(|c| contact_dict(py, &c))
    .transpose()
}

/// `(b(d), b'(d), b''(d))` of the log barrier `b(d) = −κ (d/d̂ − 1)² ln(d/d̂)` (BFEMP eq. 27);
/// zero at `d ≥ d̂`.
#[pyfunction]
fn barrier(d: f64, dhat: f64, kappa: f64) -> PyResult<(f64, f64, f64)> {
    let b = LogBarrier::new(dhat, kappa).map_err(contact_err)?;
    if !(d > 0.0) {
        return Err(PyValueError::new_err(format!(
            "d = {d}: the barrier is defined for d > 0"
        )));
    }
    Ok((b.value(d), b.first(d), b.second(d)))
}

/// Squared distance from point `p` to edge `e0 e1` (2D or 3D) or, with `t2`, to the triangle
/// `e0 e1 t2` (3D).
#[pyfunction]
#[pyo3(signature = (p, e0, e1, t2 = None))]
fn sq_distance(
    p: PyReadonlyArray1<'_, f64>,
    e0: PyReadonlyArray1<'_, f64>,
    e1: PyReadonlyArray1<'_, f64>,
    t2: Option<PyReadonlyArray1<'_, f64>>,
) -> PyResult<f64> {
    use femp_contact::distance::{point_edge, point_triangle};
    match (p.as_array().len(), t2) {
        (3, Some(t2)) => Ok(point_triangle::sq_dist(
            &point::<3>(&p, "p")?,
            &point::<3>(&e0, "t0")?,
            &point::<3>(&e1, "t1")?,
            &point::<3>(&t2, "t2")?,
        )),
        (2, None) => Ok(point_edge::sq_dist(
            &point::<2>(&p, "p")?,
            &point::<2>(&e0, "e0")?,
            &point::<2>(&e1, "e1")?,
        )),
        (3, None) => Ok(point_edge::sq_dist(
            &point::<3>(&p, "p")?,
            &point::<3>(&e0, "e0")?,
            &point::<3>(&e1, "e1")?,
        )),
        (n, _) => Err(PyValueError::new_err(format!(
            "p: expected 2 coordinates (edge) or 3 (edge or triangle), got {n}"
        ))),
    }
}

/// A closest feature's name, the squared distance, its gradient and Hessian.
type DistanceDerivatives<'py> = (
    &'static str,
    f64,
    Bound<'py, numpy::PyArray2<f64>>,
    Bound<'py, numpy::PyArray2<f64>>,
);

/// The squared distance from point `p` to the edge `a b` (2D or 3D) or the triangle `a b c`
/// (3D), with its closest feature and its gradient and exact Hessian over the whole stencil
/// (`p`, then the edge's or triangle's vertices): `(feature, s, gradient (N×D), hessian
/// (ND×ND))`, the feature `"v0"`, `"v1"`, `"v2"` (a vertex), `"edge"` (the edge's interior),
/// `"e01"`, `"e12"`, `"e20"` (a triangle edge's interior) or `"face"`.
#[pyfunction]
#[pyo3(signature = (p, a, b, c = None))]
#[allow(clippy::type_complexity)]
fn sq_distance_derivatives<'py>(
    py: Python<'py>,
    p: PyReadonlyArray1<'py, f64>,
    a: PyReadonlyArray1<'py, f64>,
    b: PyReadonlyArray1<'py, f64>,
    c: Option<PyReadonlyArray1<'py, f64>>,
) -> PyResult<DistanceDerivatives<'py>> {
    use femp_contact::distance::point_edge::{self, PointEdgeRegion};
    use femp_contact::distance::point_triangle::{self, PointTriangleRegion};
    use femp_contact::{ContactPotential, Feature};
    fn stencil<'py, const D: usize>(
        py: Python<'py>,
        p: &SVector<f64, D>,
        verts: &[SVector<f64, D>],
        (name, feature): (&'static str, Feature),
    ) -> DistanceDerivatives<'py> {
        let (s, g, h) = ContactPotential::<D>::feature_sq_dist(p, feature, verts);
        let (fv, k) = feature.vertices();
        // Stencil point i of the feature (0: p) → its place among (p, a, b[, c]).
        let place = |i: usize| if i == 0 { 0 } else { 1 + fv[i - 1] as usize };
        let n = 1 + verts.len();
        let mut grad = Array2::<f64>::zeros((n, D));
        let mut hess = Array2::<f64>::zeros((n * D, n * D));
        for i in 0..=k {
            for r in 0..D {
                grad[(place(i), r)] = g[i][r];
            }
            for j in 0..=k {
                for r in 0..D {
                    for q in 0..D {
                        hess[(place(i) * D + r, place(j) * D + q)] = h[i][j][(r, q)];
                    }
                }
            }
        }
        (name, s, grad.into_pyarray(py), hess.into_pyarray(py))
    }
    match (p.as_array().len(), c) {
        (3, Some(c)) => {
            let v = |x: &PyReadonlyArray1<'py, f64>, w: &str| point::<3>(x, w);
            let (p, t) = (v(&p, "p")?, [v(&a, "a")?, v(&b, "b")?, v(&c, "c")?]);
            use PointTriangleRegion::*;
            let f = match point_triangle::region(&p, &t[0], &t[1], &t[2]) {
                V0 => ("v0", Feature::Vertex(0)),
                V1 => ("v1", Feature::Vertex(1)),
                V2 => ("v2", Feature::Vertex(2)),
                E01 => ("e01", Feature::Edge(0, 1)),
                E12 => ("e12", Feature::Edge(1, 2)),
                E20 => ("e20", Feature::Edge(2, 0)),
                Face => ("face", Feature::Face(0, 1, 2)),
            };
            Ok(stencil::<3>(py, &p, &t, f))
        }
        (d @ (2 | 3), None) => {
            fn edge<'py, const D: usize>(
                py: Python<'py>,
                pts: [&PyReadonlyArray1<'py, f64>; 3],
            ) -> PyResult<DistanceDerivatives<'py>> {
                let p = point::<D>(pts[0], "p")?;
                let e = [point::<D>(pts[1], "a")?, point::<D>(pts[2], "b")?];
                let f = match point_edge::region(&p, &e[0], &e[1]) {
                    PointEdgeRegion::V0 => ("v0", Feature::Vertex(0)),
                    PointEdgeRegion::V1 => ("v1", Feature::Vertex(1)),
                    PointEdgeRegion::Interior => ("edge", Feature::Edge(0, 1)),
                };
                Ok(stencil::<D>(py, &p, &e, f))
            }
            if d == 2 {
                edge::<2>(py, [&p, &a, &b])
            } else {
                edge::<3>(py, [&p, &a, &b])
            }
        }
        (n, _) => Err(PyValueError::new_err(format!(
            "p: expected 2 coordinates (edge) or 3 (edge or triangle), got {n}"
        ))),
    }
}

/// Conservative time of impact in `[0, 1]` of a point moving linearly from `start[0]` to
/// `end[0]` against an edge (2 more rows, 2D or 3D) or triangle (3 more rows, 3D) moving
/// linearly from `start[1:]` to `end[1:]`; `None` when they do not come within the CCD's
/// separation (additive CCD, docs/contact.md). Returns `(toi, iterations)`.
#[pyfunction]
#[pyo3(signature = (start, end, max_iterations = 800))]
fn ccd_toi(
    start: PyReadonlyArray2<'_, f64>,
    end: PyReadonlyArray2<'_, f64>,
    max_iterations: usize,
) -> PyResult<(Option<f64>, usize)> {
    let (a, b) = (start.as_array(), end.as_array());
    if a.shape() != b.shape() {
        return Err(PyValueError::new_err(format!(
            "start and end: shapes {:?} and {:?} differ",
            a.shape(),
            b.shape()
        )));
    }
    for (name, m) in [("start", &a), ("end", &b)] {
        if let Some(row) = (0..m.nrows()).find(|&i| m.row(i).iter().any(|v| !v.is_finite())) {
            let what = if row == 0 {
                "the point".to_string()
            } else {
                format!("vertex {} of the primitive", row - 1)
            };
            return Err(PyValueError::new_err(format!(
                "{name}[{row}] ({what}): non-finite coordinate {:?}",
                m.row(row).to_vec()
            )));
        }
    }
    let opts = CcdOptions {
        max_iterations: max_iterations.max(1),
        ..Default::default()
    };
    fn rows<const D: usize>(a: &numpy::ndarray::ArrayView2<'_, f64>) -> Vec<SVector<f64, D>> {
        (0..a.nrows())
            .map(|i| SVector::from_fn(|k, _| a[(i, k)]))
            .collect()
    }
    let r = match a.shape() {
        [3, 2] => {
            let (s, e) = (rows::<2>(&a), rows::<2>(&b));
            femp_contact::ccd::point_edge(&s[0], &s[1], &s[2], &e[0], &e[1], &e[2], &opts)
        }
        [3, 3] => {
            let (s, e) = (rows::<3>(&a), rows::<3>(&b));
            femp_contact::ccd::point_edge(&s[0], &s[1], &s[2], &e[0], &e[1], &e[2], &opts)
        }
        [4, 3] => {
            let (s, e) = (rows::<3>(&a), rows::<3>(&b));
            let v = |x: &SVector<f64, 3>| Vector3::new(x[0], x[1], x[2]);
            femp_contact::ccd::point_triangle(
                &v(&s[0]),
                &v(&s[1]),
                &v(&s[2]),
                &v(&s[3]),
                &v(&e[0]),
                &v(&e[1]),
                &v(&e[2]),
                &v(&e[3]),
                &opts,
            )
        }
        s => {
            return Err(PyValueError::new_err(format!(
                "start/end: shape {s:?}; expected (3, 2) or (3, 3) for point–edge, (4, 3) for point–triangle"
            )));
        }
    };
    Ok((r.toi, r.iterations))
}

// ---------------------------------------------------------------------------------------------
// Transfers

enum AnyStencils {
    D2(Box<Stencils<2>>),
    D3(Box<Stencils<3>>),
}

/// APIC/PIC transfers between particles at fixed positions and the quadratic B-spline grid
/// nodes they touch (BFEMP Tables 1–3; augury eqs. 10–20). Grid arrays are indexed like
/// `nodes` (integer node indices, nodes × D).
#[pyclass(name = "Transfer", module = "femp")]
struct PyTransfer {
    stencils: AnyStencils,
    particles: usize,
}

fn vec_rows<const D: usize>(
    a: &PyReadonlyArray2<'_, f64>,
    n: usize,
    what: &str,
) -> PyResult<Vec<SVector<f64, D>>> {
    let a = a.as_array();
    if a.shape() != [n, D] {
        return Err(PyValueError::new_err(format!(
            "{what}: shape {:?}, expected ({n}, {D})",
            a.shape()
        )));
    }
    Ok((0..n).map(|i| SVector::from_fn(|k, _| a[(i, k)])).collect())
}

fn mat_rows<const D: usize>(
    a: &PyReadonlyArray3<'_, f64>,
    n: usize,
    what: &str,
) -> PyResult<Vec<SMatrix<f64, D, D>>> {
    let a = a.as_array();
    if a.shape() != [n, D, D] {
        return Err(PyValueError::new_err(format!(
            "{what}: shape {:?}, expected ({n}, {D}, {D})",
            a.shape()
        )));
    }
    Ok((0..n)
        .map(|i| SMatrix::from_fn(|r, c| a[(i, r, c)]))
        .collect())
}

/// `(grid_mass, grid_momentum)`.
type GridArrays<'py> = (
    Bound<'py, numpy::PyArray1<f64>>,
    Bound<'py, numpy::PyArray2<f64>>,
);
/// `(v, B)` per particle.
type ParticleArrays<'py> = (
    Bound<'py, numpy::PyArray2<f64>>,
    Bound<'py, numpy::PyArray3<f64>>,
);

fn kernel_err(e: femp_kernels::KernelError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

impl PyTransfer {
    fn p2g_d<'py, const D: usize>(
        py: Python<'py>,
        st: &Stencils<D>,
        mass: &PyReadonlyArray1<'py, f64>,
        v: &PyReadonlyArray2<'py, f64>,
        b: Option<&PyReadonlyArray3<'py, f64>>,
    ) -> PyResult<GridArrays<'py>> {
        let n = st.num_particles();
        let m = mass.as_array().to_vec();
        let v = vec_rows::<D>(v, n, "v")?;
        let mut gm = vec![0.0; st.num_nodes()];
        let mut gp = vec![SVector::<f64, D>::zeros(); st.num_nodes()];
        match b {
            Some(b) => {
                let b = mat_rows::<D>(b, n, "B")?;
                femp_kernels::transfer::p2g_apic(st, &m, &v, &b, &mut gm, &mut gp)
            }
            None => femp_kernels::transfer::p2g_pic(st, &m, &v, &mut gm, &mut gp),
        }
        .map_err(kernel_err)?;
        Ok((
            Array1::from(gm).into_pyarray(py),
            vectors(&gp).into_pyarray(py),
        ))
    }

    fn g2p_d<'py, const D: usize>(
        py: Python<'py>,
        st: &Stencils<D>,
        grid_v: &PyReadonlyArray2<'py, f64>,
    ) -> PyResult<ParticleArrays<'py>> {
        let n = st.num_particles();
        let gv = vec_rows::<D>(grid_v, st.num_nodes(), "grid_velocity")?;
        let mut v = vec![SVector::<f64, D>::zeros(); n];
        let mut b = vec![SMatrix::<f64, D, D>::zeros(); n];
        femp_kernels::transfer::g2p_apic(st, &gv, None, &mut v, &mut b).map_err(kernel_err)?;
        Ok((vectors(&v).into_pyarray(py), matrices(&b).into_pyarray(py)))
    }
}

#[pymethods]
impl PyTransfer {
    /// Stencils of the particles `x` (n×D, D = 2 or 3) on the grid of spacing `h` with a node
    /// at `origin` (default the coordinate origin); `kernel` is `"quadratic"` (3 nodes per axis,
    /// BFEMP) or `"quadratic4"` (the augury paper's 4-node variant).
    #[new]
    #[pyo3(signature = (x, h, origin = None, kernel = "quadratic"))]
    fn new(
        x: PyReadonlyArray2<'_, f64>,
        h: f64,
        origin: Option<PyReadonlyArray1<'_, f64>>,
        kernel: &str,
    ) -> PyResult<Self> {
        let kernel = match kernel {
            "quadratic" => Kernel::Quadratic,
            "quadratic4" => Kernel::Quadratic4,
            k => {
                return Err(PyValueError::new_err(format!(
                    "kernel = {k:?}: expected \"quadratic\" or \"quadratic4\""
                )));
            }
        };
        let n = x.as_array().nrows();
        let stencils = match x.as_array().ncols() {
            2 => {
                let o = origin
                    .as_ref()
                    .map_or(Ok(SVector::zeros()), |o| point::<2>(o, "origin"))?;
                let g = Grid::<2>::new(h, o, kernel).map_err(kernel_err)?;
                AnyStencils::D2(Box::new(
                    g.stencils(&vec_rows::<2>(&x, n, "x")?)
                        .map_err(kernel_err)?,
                ))
            }
            3 => {
                let o = origin
                    .as_ref()
                    .map_or(Ok(SVector::zeros()), |o| point::<3>(o, "origin"))?;
                let g = Grid::<3>::new(h, o, kernel).map_err(kernel_err)?;
                AnyStencils::D3(Box::new(
                    g.stencils(&vec_rows::<3>(&x, n, "x")?)
                        .map_err(kernel_err)?,
                ))
            }
            c => {
                return Err(PyValueError::new_err(format!(
                    "x: {c} columns, expected 2 or 3"
                )));
            }
        };
        Ok(Self {
            stencils,
            particles: n,
        })
    }

    /// Number of particles.
    #[getter]
    fn num_particles(&self) -> usize {
        self.particles
    }

    /// Integer indices of the grid nodes the particles touch (nodes × D), in the order of every
    /// grid array here.
    #[getter]
    fn nodes<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<i64>> {
        fn idx<const D: usize>(st: &Stencils<D>) -> Array2<i64> {
            let n = st.node_indices();
            Array2::from_shape_fn((n.len(), D), |(i, a)| n[i][a])
        }
        match &self.stencils {
            AnyStencils::D2(s) => idx(s),
            AnyStencils::D3(s) => idx(s),
        }
        .into_pyarray(py)
    }

    /// Positions of the nodes (nodes × D).
    #[getter]
    fn node_positions<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<f64>> {
        fn pos<const D: usize>(st: &Stencils<D>) -> Array2<f64> {
            Array2::from_shape_fn((st.num_nodes(), D), |(i, a)| st.node_position(i)[a])
        }
        match &self.stencils {
            AnyStencils::D2(s) => pos(s),
            AnyStencils::D3(s) => pos(s),
        }
        .into_pyarray(py)
    }

    /// Particles to grid: `(grid_mass, grid_momentum)` from `mass` (n), `v` (n×D) and, for APIC,
    /// `B` (n×D×D; PIC without it). Mass, linear and (APIC) angular momentum are conserved.
    #[pyo3(signature = (mass, v, B = None))]
    #[allow(non_snake_case)]
    fn p2g<'py>(
        &self,
        py: Python<'py>,
        mass: PyReadonlyArray1<'py, f64>,
        v: PyReadonlyArray2<'py, f64>,
        B: Option<PyReadonlyArray3<'py, f64>>,
    ) -> PyResult<GridArrays<'py>> {
        match &self.stencils {
            AnyStencils::D2(s) => Self::p2g_d::<2>(py, s, &mass, &v, B.as_ref()),
            AnyStencils::D3(s) => Self::p2g_d::<3>(py, s, &mass, &v, B.as_ref()),
        }
    }

    /// Grid to particles (APIC): `(v, B)` from the node velocities (nodes × D).
    fn g2p<'py>(
        &self,
        py: Python<'py>,
        grid_velocity: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<ParticleArrays<'py>> {
        match &self.stencils {
            AnyStencils::D2(s) => Self::g2p_d::<2>(py, s, &grid_velocity),
            AnyStencils::D3(s) => Self::g2p_d::<3>(py, s, &grid_velocity),
        }
    }
}

/// The `femp._femp` extension module.
#[pymodule]
fn _femp(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("FempError", py.get_type::<FempError>())?;
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("SimulationError", py.get_type::<SimulationError>())?;
    m.add("OutputError", py.get_type::<OutputError>())?;
    m.add("StateError", py.get_type::<StateError>())?;
    m.add("CheckpointError", py.get_type::<CheckpointError>())?;
    m.add_class::<PyScene>()?;
    m.add_class::<PyWorld>()?;
    m.add_class::<PyTransfer>()?;
    m.add_class::<mesh_contact::PyContactMesh>()?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(point_edge_potential, m)?)?;
    m.add_function(wrap_pyfunction!(point_triangle_potential, m)?)?;
    m.add_function(wrap_pyfunction!(barrier, m)?)?;
    m.add_function(wrap_pyfunction!(sq_distance, m)?)?;
    m.add_function(wrap_pyfunction!(sq_distance_derivatives, m)?)?;
    m.add_function(wrap_pyfunction!(ccd_toi, m)?)?;
    Ok(())
}
