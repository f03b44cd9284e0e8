//! Run output: ParaView frames (`.vtu` + `.pvd`), `metrics.csv` (one row per step, flushed as
//! written) and `summary.json`.

use std::fs::File;
use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

use femp_fem::mesh::vtk::{Encoding, Field, Pvd, Vtu};
use nalgebra::SVector;
use serde::{Deserialize, Serialize};

use crate::error::SimError;
use crate::io::metrics::{Metrics, csv_header};
use crate::world::World;

/// Final state of a run, written to `summary.json`.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Summary {
    /// Scene name.
    pub scene: String,
    /// femp's version.
    pub femp_version: String,
    /// The commit femp was built from (`git describe --always`; `unknown` outside a checkout;
    /// uncommitted changes are not recorded).
    pub commit: String,
    /// The command line of the run (`femp run …`; empty for library runs that do not give one).
    pub command: Vec<String>,
    /// The scene as it was read, copied into the output directory ([`SCENE_COPY`]); `None` for
    /// scenes built in code without their text.
    pub scene_copy: Option<String>,
    /// The MPM bodies' names, in the order of the `body` index of the particle frames.
    pub mpm_bodies: Vec<String>,
    /// 2 or 3.
    pub dimension: usize,
    /// The method that advanced the bodies (`"bfemp"` or `"augury"` in summary.json).
    pub method: crate::scene::Method,
    /// Augury scenes: background grid spacing (m), explicit stability estimate (s) and number
    /// of boundary particles.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub augury: Option<AugurySummary>,
    /// `running` (while it runs), `completed`, `failed` or `interrupted`.
    pub status: String,
    /// Why it failed.
    pub error: Option<String>,
    /// Steps completed.
    pub steps: usize,
    /// The steps after which this run was resumed from a checkpoint (`femp run --resume`), in
    /// order; empty for a run that went from start to end in one go. The totals count every
    /// step once; `wall_s` adds up the wall time of every part.
    #[serde(default)]
    pub resumed_at: Vec<usize>,
    /// Simulated time reached (s).
    pub simulated_time: f64,
    /// Wall-clock time (s).
    pub wall_s: f64,
    /// Frames written.
    pub frames: usize,
    /// Newton iterations in total.
    pub newton_iterations: usize,
    /// Friction iterations in total (BFEMP).
    pub friction_iterations: usize,
    /// Newton iterations whose direction was solved again with friction terms modelled as
    /// stuck (`solver.friction_stick_model`; femp-solver `SolveStats::model_directions`),
    /// each at the cost of a second assembly and factorisation.
    pub stick_model_directions: usize,
    /// Newton iterations whose line search took a step longer than the Newton step
    /// (`solver.line_search_expansion`; femp-solver `SolveStats::expanded_steps`).
    pub expanded_steps: usize,
    /// Iterations of the augury contact steps in total (augury).
    pub augury_iterations: usize,
    /// Newton iterations that used the exact Hessian (`solver.projection: "when_indefinite"`).
    pub exact_hessian_iterations: usize,
    /// Exact Hessians found indefinite (those iterations used the projected one).
    pub exact_hessian_rejections: usize,
    /// Newton iterations that reused the previous iteration's Hessian
    /// (`solver.reuse_hessian_below`).
    pub reused_hessians: usize,
    /// Full Newton steps taken on the gradient's word where the energy could not resolve
    /// their decrease (femp-solver `SolveStats::gradient_steps`).
    pub gradient_steps: usize,
    /// Conjugate-gradient iterations (`solver.linear: "pcg"`).
    pub pcg_iterations: usize,
    /// Newton directions CG did not deliver and Cholesky did (`solver.linear: "pcg"`).
    pub pcg_fallbacks: usize,
    /// CG iterations refining single-precision solves to double precision
    /// (`solver.factor_precision: "mixed"`).
    pub refine_iterations: usize,
    /// Matrices factorised again in double precision (`solver.factor_precision: "mixed"`).
    pub double_fallbacks: usize,
    /// Steps whose friction iteration hit its limit.
    pub friction_unconverged_steps: usize,
    /// Steps whose first solve failed and that were solved again from their start, with
    /// direct solves after an inexact linear solve or with the other Hessian strategy
    /// (`solver.retry_other_projection`).
    pub retried_steps: usize,
    /// Largest penetration count in any step (BFEMP: must be 0).
    pub max_penetrations: usize,
    /// Steps after which some point was inside another body (BFEMP: must be 0; augury: how
    /// often the correction let bodies overlap).
    pub penetrating_steps: usize,
    /// The deepest any point was inside another body at the end of a step (m), and which.
    pub max_penetration_depth: f64,
    /// See `max_penetration_depth` (in words; `null` if no point ever was inside).
    pub deepest_penetration: Option<String>,
    /// Steps in which a point's straight path over the step went inside a body it can touch
    /// (`swept_entered` in metrics.csv; BFEMP: 0 in every shipped scene).
    pub swept_steps: usize,
    /// The deepest any point's straight path went inside a body over a step (m).
    pub max_swept_depth: f64,
    /// Steps in which a point's straight path passed through a body (in by one facet, out by
    /// one facing away from it): augury steps whose correction let a vertex through (BFEMP
    /// solves such a step in substeps instead, so 0).
    pub passed_through_steps: usize,
    /// BFEMP steps solved again in substeps because a straight path passed through a body at
    /// the scene's Δt, and the most substeps one took.
    pub substepped_steps: usize,
    /// See `substepped_steps`.
    pub max_substeps: usize,
    /// The most the total energy (kinetic, elastic, barrier, gravity) rose above its initial
    /// value at any step, as a fraction of the energy in play — the kinetic + elastic + barrier
    /// energy at the start, or the gravitational energy released so far, whichever is larger
    /// (not the total itself, whose size depends on where gravity's potential is zero); 0 if
    /// it never rose.
    pub energy_rise: f64,
    /// The step at which `energy_rise` was reached.
    pub energy_rise_step: usize,
    /// The total energy at the start and at `energy_rise_step` (J; J/m in 2D).
    pub initial_energy: f64,
    /// See `initial_energy`.
    pub peak_energy: f64,
    /// What a user should know about a run that completed (also printed on stderr): bodies
    /// that overlapped, friction iterations that hit their limit.
    pub warnings: Vec<String>,
    /// Number of particles.
    pub particles: usize,
    /// Number of FEM vertices.
    pub fem_vertices: usize,
    /// Where the wall-clock time went.
    pub timing: RunTiming,
}

/// What an augury run was set up with.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct AugurySummary {
    /// Background grid spacing (m).
    pub grid_spacing: f64,
    /// Explicit stability estimate `min h_e / c_p` (s); Δt above it is likely to blow up.
    pub stable_dt: f64,
    /// Boundary vertices taking part in the contact correction.
    pub boundary_particles: usize,
}

/// Where a run's wall-clock time went (seconds, summed over steps). The objective's parts
/// (`objective`) overlap the solver's `assembly_s` (gradient and Hessian) and `line_search_s`
/// (energies, CCD, det F bounds).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct RunTiming {
    /// Stencil rebuild, particle-to-grid and grid-to-particle transfers, advection.
    pub transfers_s: f64,
    /// DOF layout, predictor, boundary conditions, initial guess.
    pub setup_s: f64,
    /// Newton: gradient and Hessian evaluation and the sparse matrix build.
    pub assembly_s: f64,
    /// Newton: symbolic analysis (ordering) of changed sparsity patterns.
    pub symbolic_s: f64,
    /// Newton: numeric Cholesky factorisation.
    pub numeric_s: f64,
    /// Newton: triangular solves.
    pub solve_s: f64,
    /// Newton: conjugate gradients (`solver.linear: "pcg"`).
    pub pcg_s: f64,
    /// Newton: the filtered line search.
    pub line_search_s: f64,
    /// The objective's parts.
    pub objective: crate::objective::ObjectiveTiming,
    /// Per-step measurements (energies, momenta, penetration check).
    pub measure_s: f64,
    /// Writing frames, metrics and progress.
    pub output_s: f64,
}

/// How a run treats its output directory.
#[derive(Clone, Copy, Debug, Default)]
pub struct OutputOptions {
    /// Replace the outputs of an earlier run found in the directory (otherwise they are an
    /// error: stale frames mixed with new ones would be read as one run).
    pub overwrite: bool,
}

/// The copy of the scene file a run writes into its directory.
pub const SCENE_COPY: &str = "scene_copy.json";

pub use crate::error::LOCK_FILE;

/// Writes a run's files as it goes, every one of them inside its directory:
///
/// * the directory is locked for the run ([`LOCK_FILE`], an advisory lock the system releases
///   when the process ends, however it ends): a second run into it is refused;
/// * outputs of an earlier run (summary, metrics, `.pvd` collections, frames, pictures) are
///   refused, or removed first with [`OutputOptions::overwrite`];
/// * frames and `.pvd` collections are written to a temporary name and renamed, so none is ever
///   half-written;
/// * `metrics.csv` gets whole rows only: a row that cannot be written completely (full disk)
///   is cut off again;
/// * `summary.json` is replaced atomically, or — when even that fails, as on a full disk —
///   overwritten in place.
pub struct Output {
    dir: PathBuf,
    metrics: File,
    /// Bytes of `metrics.csv` that hold whole rows.
    metrics_len: u64,
    pvds: Vec<(String, Pvd)>,
    frames: usize,
    /// The simulated time of each frame written.
    frame_times: Vec<f64>,
    /// Encoding of frames.
    pub encoding: Encoding,
    /// Held for the run: the lock lives as long as the open file.
    _lock: File,
    removed: Vec<PathBuf>,
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> SimError + '_ {
    move |source| SimError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Lock `dir` for one run: fails if another run holds it.
fn lock(dir: &Path) -> Result<File, SimError> {
    let path = dir.join(LOCK_FILE);
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&path)
        .map_err(io(&path))?;
    match file.try_lock() {
        Ok(()) => {}
        Err(std::fs::TryLockError::WouldBlock) => {
            return Err(SimError::OutputBusy {
                dir: dir.to_path_buf(),
            });
        }
        Err(std::fs::TryLockError::Error(e)) => return Err(io(&path)(e)),
    }
    // Who holds it, for a curious user (the lock itself is the flock, not this text).
    let mut f = &file;
    let _ = f
        .set_len(0)
        .and_then(|_| writeln!(f, "{}", std::process::id()));
    Ok(file)
}

/// The name of each frame series a run of `world` writes (`NAME.pvd`, `frames/NAME_k.vtu`):
/// `particles` if it has MPM bodies, then each FEM body's name.
fn series_names<const D: usize>(world: &World<D>) -> Vec<String> {
    world
        .bodies
        .mpm
        .iter()
        .map(|_| "particles".to_string())
        .chain(world.bodies.fem.iter().map(|b| b.name.clone()))
        .collect()
}

/// Refuse symbolic links where a run writes inside `dir`: its lock, `summary.json`,
/// `metrics.csv`, the scene copy, the `.pvd` collections, the `frames/` and `pictures/`
/// directories and any `.vtu`, `.png` or `.gif` in them (with their temporaries). A link there
/// would send a run's writes outside `--out` — through it, with or without `--overwrite`.
/// (`--out` itself may be a link: that is where the user asked the files to go.)
fn refuse_links<const D: usize>(dir: &Path, world: &World<D>) -> Result<(), SimError> {
    let is_link = |p: &Path| std::fs::symlink_metadata(p).is_ok_and(|m| m.file_type().is_symlink());
    let mut names: Vec<String> = [
        LOCK_FILE,
        "summary.json",
        "summary.json.tmp",
        "metrics.csv",
        "metrics.csv.tmp",
        "frames",
        "pictures",
        crate::io::checkpoint::CHECKPOINT,
        "checkpoint.femp.tmp",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    names.push(SCENE_COPY.to_string());
    names.push(format!("{SCENE_COPY}.tmp"));
    names.push(
        std::path::Path::new(SCENE_COPY)
            .with_extension("json.tmp")
            .display()
            .to_string(),
    );
    for b in series_names(world) {
        names.push(format!("{b}.pvd"));
        names.push(format!("{b}.pvd.tmp"));
    }
    let mut links: Vec<PathBuf> = names
        .iter()
        .map(|n| dir.join(n))
        .filter(|p| is_link(p))
        .collect();
    for sub in ["frames", "pictures"] {
        if let Ok(entries) = std::fs::read_dir(dir.join(sub)) {
            links.extend(
                entries
                    .filter_map(Result::ok)
                    .filter(|e| e.file_type().is_ok_and(|t| t.is_symlink()))
                    .map(|e| e.path()),
            );
        }
    }
    match links.first() {
        None => Ok(()),
        Some(first) => Err(SimError::OutputLink {
            path: first.clone(),
            count: links.len(),
        }),
    }
}

/// The files an earlier femp run left in `dir`: `summary.json`, `metrics.csv`, [`SCENE_COPY`],
/// `checkpoint.femp`, `*.pvd`,
/// `frames/*.vtu`, `pictures/key_*.png` and `pictures/animation.gif` (and their temporaries).
/// Nothing else in the directory is femp's.
pub fn earlier_outputs(dir: &Path) -> Vec<PathBuf> {
    let list = |d: &Path, keep: &dyn Fn(&str) -> bool| -> Vec<PathBuf> {
        let Ok(entries) = std::fs::read_dir(d) else {
            return Vec::new();
        };
        let mut v: Vec<PathBuf> = entries
            .filter_map(Result::ok)
            .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
            .filter(|e| e.file_name().to_str().is_some_and(keep))
            .map(|e| e.path())
            .collect();
        v.sort();
        v
    };
    let mut out = list(dir, &|n| {
        matches!(
            n,
            "summary.json"
                | "summary.json.tmp"
                | "metrics.csv"
                | "metrics.csv.tmp"
                | "checkpoint.femp"
                | "checkpoint.femp.tmp"
        ) || n.starts_with(SCENE_COPY)
            || n.ends_with(".pvd")
            || n.ends_with(".pvd.tmp")
    });
    out.extend(list(&dir.join("frames"), &|n| {
        n.ends_with(".vtu") || n.ends_with(".vtu.tmp")
    }));
    out.extend(list(&dir.join("pictures"), &|n| {
        (n.starts_with("key_") && n.ends_with(".png")) || n == "animation.gif"
    }));
    out
}

/// A short account of a list of earlier outputs: `summary.json, metrics.csv, 2 .pvd files,
/// 82 frames (frames/), 7 pictures (pictures/)`.
pub fn describe_outputs(dir: &Path, files: &[PathBuf]) -> String {
    let (frames, pictures) = (dir.join("frames"), dir.join("pictures"));
    let mut named = Vec::new();
    let (mut pvd, mut nf, mut np) = (0, 0, 0);
    for f in files {
        let parent = f.parent().unwrap_or(dir);
        if parent == frames {
            nf += 1;
        } else if parent == pictures {
            np += 1;
        } else if f.extension().is_some_and(|e| e == "pvd") {
            pvd += 1;
        } else if let Some(n) = f.file_name() {
            named.push(n.to_string_lossy().into_owned());
        }
    }
    if pvd > 0 {
        named.push(format!(
            "{pvd} .pvd file{}",
            if pvd == 1 { "" } else { "s" }
        ));
    }
    if nf > 0 {
        named.push(format!(
            "{nf} frame file{} (frames/)",
            if nf == 1 { "" } else { "s" }
        ));
    }
    if np > 0 {
        named.push(format!(
            "{np} picture{} (pictures/)",
            if np == 1 { "" } else { "s" }
        ));
    }
    named.join(", ")
}

impl Output {
    /// Create and lock `dir` (and `dir/frames`), deal with an earlier run's outputs (refused,
    /// or removed with `opts.overwrite`) and start `metrics.csv`.
    pub fn create<const D: usize>(
        dir: &Path,
        world: &World<D>,
        opts: OutputOptions,
    ) -> Result<Self, SimError> {
        std::fs::create_dir_all(dir).map_err(io(dir))?;
        refuse_links(dir, world)?;
        let lock = lock(dir)?;
        let earlier = earlier_outputs(dir);
        if !earlier.is_empty() {
            if !opts.overwrite {
                return Err(SimError::StaleOutput {
                    dir: dir.to_path_buf(),
                    found: describe_outputs(dir, &earlier),
                });
            }
            for f in &earlier {
                std::fs::remove_file(f).map_err(io(f))?;
            }
        }
        std::fs::create_dir_all(dir.join("frames")).map_err(io(dir))?;
        let mpath = dir.join("metrics.csv");
        let mut metrics = File::create(&mpath).map_err(io(&mpath))?;
        let header = format!(
            "{}\n",
            csv_header::<D>(&world.force_bodies(), world.stepper.method())
        );
        metrics.write_all(header.as_bytes()).map_err(io(&mpath))?;
        // Body names are validated as safe file names (scene::validate): the files stay in `dir`.
        let pvds = series_names(world)
            .into_iter()
            .map(|n| {
                let pvd = Pvd::new(&dir.join(format!("{n}.pvd")));
                (n, pvd)
            })
            .collect();
        Ok(Self {
            dir: dir.to_path_buf(),
            metrics,
            metrics_len: header.len() as u64,
            pvds,
            frames: 0,
            frame_times: Vec::new(),
            encoding: Encoding::Binary,
            _lock: lock,
            removed: earlier,
        })
    }

    /// Reopen `dir` to continue the run whose checkpoint was taken after step `step`, when it
    /// had written the frames at `frame_times`: locked as [`Output::create`] locks it;
    /// `metrics.csv` cut back to its rows up to that step (its columns must be this world's);
    /// later frames removed; the `.pvd` collections rewritten for the frames kept (which must
    /// all be there).
    pub fn reopen<const D: usize>(
        dir: &Path,
        world: &World<D>,
        step: usize,
        frame_times: &[f64],
    ) -> Result<Self, SimError> {
        refuse_links(dir, world)?;
        let lock = lock(dir)?;
        let mpath = dir.join("metrics.csv");
        let text = std::fs::read_to_string(&mpath).map_err(io(&mpath))?;
        let header = csv_header::<D>(&world.force_bodies(), world.stepper.method());
        let mut lines = text.split_inclusive('\n');
        if lines.next().map(str::trim_end) != Some(header.as_str()) {
            return Err(SimError::Checkpoint {
                what: mpath.display().to_string(),
                message: "its columns are not this scene's: not the run the checkpoint continues"
                    .into(),
            });
        }
        let mut kept = format!("{header}\n");
        for line in lines.filter(|l| l.ends_with('\n')) {
            match line.split(',').next().and_then(|f| f.parse::<usize>().ok()) {
                Some(k) if k <= step => kept.push_str(line),
                _ => break,
            }
        }
        write_whole(&mpath, kept.as_bytes()).map_err(io(&mpath))?;
        let metrics = std::fs::OpenOptions::new()
            .append(true)
            .open(&mpath)
            .map_err(io(&mpath))?;
        let names = series_names(world);
        let frames = dir.join("frames");
        std::fs::create_dir_all(&frames).map_err(io(&frames))?;
        remove_frames_from(&frames, &names, frame_times.len())?;
        let mut pvds = Vec::new();
        for name in &names {
            let mut pvd = Pvd::new(&dir.join(format!("{name}.pvd")));
            let paths: Vec<PathBuf> = (0..frame_times.len())
                .map(|k| frames.join(format!("{name}_{k:06}.vtu")))
                .collect();
            if let Some(missing) = paths.iter().find(|p| !p.is_file()) {
                return Err(SimError::Checkpoint {
                    what: missing.display().to_string(),
                    message: "a frame the checkpoint's run wrote is missing".into(),
                });
            }
            if !paths.is_empty() {
                pvd.add_all(
                    frame_times
                        .iter()
                        .copied()
                        .zip(paths.iter().map(PathBuf::as_path)),
                    0,
                )
                .map_err(|e| SimError::Build {
                    context: "writing frames".into(),
                    message: e.to_string(),
                })?;
            }
            pvds.push((name.clone(), pvd));
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            metrics,
            metrics_len: kept.len() as u64,
            pvds,
            frames: frame_times.len(),
            frame_times: frame_times.to_vec(),
            encoding: Encoding::Binary,
            _lock: lock,
            removed: Vec::new(),
        })
    }

    /// The outputs of an earlier run that [`Output::create`] removed (with `overwrite`).
    pub fn removed(&self) -> &[PathBuf] {
        &self.removed
    }

    /// The output directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Append one metrics row. The row is written whole or not at all: if the write fails
    /// part-way, the file is cut back to its last whole row before the error is returned.
    pub fn metrics_row<const D: usize>(&mut self, m: &Metrics) -> Result<(), SimError> {
        let mut row = m.csv_row::<D>();
        row.push('\n');
        match self.metrics.write_all(row.as_bytes()) {
            Ok(()) => {
                self.metrics_len += row.len() as u64;
                Ok(())
            }
            Err(e) => {
                let _ = self.metrics.set_len(self.metrics_len);
                let _ = self
                    .metrics
                    .seek(std::io::SeekFrom::Start(self.metrics_len));
                Err(io(&self.dir.join("metrics.csv"))(e))
            }
        }
    }

    /// Number of frames written.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Write a frame of every body at the world's current time.
    pub fn frame<const D: usize>(&mut self, world: &World<D>) -> Result<(), SimError> {
        let k = self.frames;
        let mut part = 0;
        let fem_err = |e: femp_fem::FemError| match e {
            femp_fem::FemError::Io { path, source } => SimError::Io { path, source },
            e => SimError::Build {
                context: "writing frames".into(),
                message: e.to_string(),
            },
        };
        if let Some(m) = &world.bodies.mpm {
            let path = self
                .dir
                .join("frames")
                .join(format!("particles_{k:06}.vtu"));
            let det: Vec<f64> = m.f.iter().map(femp_fem::linalg::det).collect();
            let (vm, stress) = m.stresses();
            let volume = m.current_volume();
            Vtu::points(&m.x)
                .with_point_field(Field::vector("velocity", &m.v))
                .with_point_field(Field::scalar("det_F", det))
                .with_point_field(Field::scalar("von_mises", vm))
                .with_point_field(Field::tensor("stress", &stress))
                .with_point_field(Field::vector("contact_force", &m.contact_force))
                .with_point_field(Field::scalar("mass", m.mass.clone()))
                .with_point_field(Field::scalar("volume", volume))
                .with_point_field(Field::scalar("rest_volume", m.volume.clone()))
                .with_point_field(Field::scalar(
                    "body",
                    m.body.iter().map(|&b| b as f64).collect(),
                ))
                .write(&path, self.encoding)
                .map_err(fem_err)?;
            self.pvds[part]
                .1
                .add(world.clock.time, &path, 0)
                .map_err(fem_err)?;
            part += 1;
        }
        for b in &world.bodies.fem {
            let path = self
                .dir
                .join("frames")
                .join(format!("{}_{k:06}.vtu", b.name));
            let disp: Vec<SVector<f64, D>> =
                b.x.iter().zip(&b.initial).map(|(x, x0)| x - x0).collect();
            Vtu::from_mesh(&b.mesh, &b.x)
                .with_point_field(Field::vector("displacement", &disp))
                .with_point_field(Field::vector("velocity", &b.v))
                .with_point_field(Field::vector("contact_force", &b.contact_force))
                .with_cell_field(Field::scalar("von_mises", b.elastic.von_mises(&b.x)))
                .with_cell_field(Field::tensor("stress", &b.elastic.cauchy_stress(&b.x)))
                .with_cell_field(Field::scalar("det_F", b.elastic.det_f(&b.x)))
                .write(&path, self.encoding)
                .map_err(fem_err)?;
            self.pvds[part]
                .1
                .add(world.clock.time, &path, 0)
                .map_err(fem_err)?;
            part += 1;
        }
        self.frames += 1;
        self.frame_times.push(world.clock.time);
        Ok(())
    }

    /// The simulated time of each frame written (in a resumed run, the earlier ones too).
    pub fn frame_times(&self) -> &[f64] {
        &self.frame_times
    }

    /// Copy the scene's text into the directory ([`SCENE_COPY`]), written whole.
    pub fn scene_copy(&self, text: &str) -> Result<(), SimError> {
        let path = self.dir.join(SCENE_COPY);
        write_replacing(&path, text.as_bytes()).map_err(io(&path))
    }

    /// Write `summary.json`: to a temporary file renamed over it (readers never see half a
    /// summary); if that fails — a full disk has no room for the temporary — the summary is
    /// overwritten in place, padded with spaces to the old length so no stale text follows it.
    pub fn summary(&self, s: &Summary) -> Result<(), SimError> {
        let path = self.dir.join("summary.json");
        let text = serde_json::to_string_pretty(s).map_err(|e| SimError::Build {
            context: "summary.json".into(),
            message: e.to_string(),
        })?;
        write_replacing(&path, text.as_bytes()).map_err(io(&path))
    }
}

/// Remove the frames `{name}_{k}.vtu` (and their temporaries) with `k ≥ keep` from `frames`.
fn remove_frames_from(frames: &Path, names: &[String], keep: usize) -> Result<(), SimError> {
    let entries = std::fs::read_dir(frames).map_err(io(frames))?;
    for e in entries.filter_map(Result::ok) {
        let file = e.file_name();
        let Some(n) = file.to_str() else { continue };
        let stem = n
            .strip_suffix(".vtu")
            .or_else(|| n.strip_suffix(".vtu.tmp"));
        let Some((name, k)) = stem.and_then(|s| s.rsplit_once('_')) else {
            continue;
        };
        if names.iter().any(|b| b == name) && k.parse::<usize>().is_ok_and(|k| k >= keep) {
            std::fs::remove_file(e.path()).map_err(io(&e.path()))?;
        }
    }
    Ok(())
}

/// Write `path` whole: to a temporary file renamed over it.
fn write_whole(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = path.with_extension("csv.tmp");
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)
}

/// Replace `path` by `bytes` atomically (temporary file + rename) or, when that fails, in
/// place: written over the old contents from the start, padded with spaces to the old length
/// (JSON allows trailing whitespace). The in-place write needs no new disk blocks when the new
/// text is no longer than the old, which is what lets a run record its failure on a full disk.
pub fn write_replacing(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = path.with_extension("json.tmp");
    let atomic = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    let Err(first) = atomic else {
        return Ok(());
    };
    let _ = std::fs::remove_file(&tmp);
    let in_place = || -> std::io::Result<()> {
        let mut f = std::fs::OpenOptions::new().write(true).open(path)?;
        let old = f.metadata()?.len() as usize;
        f.write_all(bytes)?;
        if old > bytes.len() {
            let mut pad = vec![b' '; old - bytes.len()];
            if let Some(last) = pad.last_mut() {
                *last = b'\n';
            }
            f.write_all(&pad)?;
        }
        Ok(())
    };
    in_place().map_err(|_| first)
}
