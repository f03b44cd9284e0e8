//! Run output: ParaView frames (`.vtu` + `.pvd`), `metrics.csv` (one row per step, flushed as
//! written) and `summary.json`.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use femp_fem::Hyperelastic;
use femp_fem::material::von_mises;
use femp_fem::mesh::vtk::{Encoding, Field, Pvd, Vtu};
use nalgebra::SVector;
use serde::Serialize;

use crate::error::SimError;
use crate::metrics::{Metrics, csv_header};
use crate::world::World;

/// Final state of a run, written to `summary.json`.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Summary {
    /// Scene name.
    pub scene: String,
    /// 2 or 3.
    pub dimension: usize,
    /// `bfemp` or `augury`.
    pub method: String,
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
    /// Simulated time reached (s).
    pub simulated_time: f64,
    /// Wall-clock time (s).
    pub wall_s: f64,
    /// Frames written.
    pub frames: usize,
    /// Newton iterations in total.
    pub newton_iterations: usize,
    /// Friction iterations in total.
    pub friction_iterations: usize,
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
    /// Steps whose friction iteration hit its limit.
    pub friction_unconverged_steps: usize,
    /// Largest penetration count in any step (BFEMP: must be 0).
    pub max_penetrations: usize,
    /// Number of particles.
    pub particles: usize,
    /// Number of FEM vertices.
    pub fem_vertices: usize,
    /// Where the wall-clock time went.
    pub timing: RunTiming,
}

/// What an augury run was set up with.
#[derive(Clone, Debug, Default, Serialize)]
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
#[derive(Clone, Debug, Default, Serialize)]
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

/// Writes a run's files as it goes.
pub struct Output {
    dir: PathBuf,
    metrics: BufWriter<File>,
    pvds: Vec<(String, Pvd)>,
    frames: usize,
    /// Encoding of frames.
    pub encoding: Encoding,
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> SimError + '_ {
    move |source| SimError::Io {
        path: path.to_path_buf(),
        source,
    }
}

impl Output {
    /// Create `dir` (and `dir/frames`) and start `metrics.csv`.
    pub fn create<const D: usize>(dir: &Path, world: &World<D>) -> Result<Self, SimError> {
        std::fs::create_dir_all(dir.join("frames")).map_err(io(dir))?;
        let mpath = dir.join("metrics.csv");
        let mut metrics = BufWriter::new(File::create(&mpath).map_err(io(&mpath))?);
        writeln!(metrics, "{}", csv_header::<D>()).map_err(io(&mpath))?;
        metrics.flush().map_err(io(&mpath))?;
        let mut pvds = Vec::new();
        if world.mpm.is_some() {
            pvds.push((
                "particles".to_string(),
                Pvd::new(&dir.join("particles.pvd")),
            ));
        }
        for b in &world.fem {
            pvds.push((
                b.name.clone(),
                Pvd::new(&dir.join(format!("{}.pvd", b.name))),
            ));
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            metrics,
            pvds,
            frames: 0,
            encoding: Encoding::Binary,
        })
    }

    /// Append one metrics row and flush it.
    pub fn metrics_row<const D: usize>(&mut self, m: &Metrics) -> Result<(), SimError> {
        let path = self.dir.join("metrics.csv");
        writeln!(self.metrics, "{}", m.csv_row::<D>()).map_err(io(&path))?;
        self.metrics.flush().map_err(io(&path))
    }

    /// Number of frames written.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Write a frame of every body at the world's current time.
    pub fn frame<const D: usize>(&mut self, world: &World<D>) -> Result<(), SimError> {
        let k = self.frames;
        let mut part = 0;
        let fem_err = |e: femp_fem::FemError| SimError::Build {
            context: "writing frames".into(),
            message: e.to_string(),
        };
        if let Some(m) = &world.mpm {
            let path = self
                .dir
                .join("frames")
                .join(format!("particles_{k:06}.vtu"));
            let det: Vec<f64> = m.f.iter().map(femp_fem::linalg::det).collect();
            let vm: Vec<f64> = (0..m.x.len())
                .map(|p| {
                    let mat = &m.bodies[m.body[p] as usize].material;
                    von_mises(&mat.first_piola(&m.f[p]), &m.f[p])
                })
                .collect();
            Vtu::points(&m.x)
                .with_point_field(Field::vector("velocity", &m.v))
                .with_point_field(Field::scalar("det_F", det))
                .with_point_field(Field::scalar("von_mises", vm))
                .with_point_field(Field::scalar(
                    "body",
                    m.body.iter().map(|&b| b as f64).collect(),
                ))
                .write(&path, self.encoding)
                .map_err(fem_err)?;
            self.pvds[part]
                .1
                .add(world.time, &path, 0)
                .map_err(fem_err)?;
            part += 1;
        }
        for b in &world.fem {
            let path = self
                .dir
                .join("frames")
                .join(format!("{}_{k:06}.vtu", b.name));
            let disp: Vec<SVector<f64, D>> =
                b.x.iter().zip(&b.initial).map(|(x, x0)| x - x0).collect();
            Vtu::from_mesh(&b.mesh, &b.x)
                .with_point_field(Field::vector("displacement", &disp))
                .with_point_field(Field::vector("velocity", &b.v))
                .with_cell_field(Field::scalar("von_mises", b.elastic.von_mises(&b.x)))
                .with_cell_field(Field::scalar("det_F", b.elastic.det_f(&b.x)))
                .write(&path, self.encoding)
                .map_err(fem_err)?;
            self.pvds[part]
                .1
                .add(world.time, &path, 0)
                .map_err(fem_err)?;
            part += 1;
        }
        self.frames += 1;
        Ok(())
    }

    /// Write `summary.json`.
    pub fn summary(&self, s: &Summary) -> Result<(), SimError> {
        let path = self.dir.join("summary.json");
        let text = serde_json::to_string_pretty(s).map_err(|e| SimError::Build {
            context: "summary.json".into(),
            message: e.to_string(),
        })?;
        std::fs::write(&path, text).map_err(io(&path))
    }
}
