//! What a scene will cost, estimated from its numbers before anything is built: particles, grid
//! nodes, FEM vertices and elements, unknowns, steps, memory and frame output. Counts are
//! computed in floating point, so a scene asking for 10²⁰ cells is refused instead of
//! overflowing or allocating until the machine runs out of memory.
//!
//! [`World::build`](crate::World::build) refuses a scene whose estimate exceeds its
//! [`Limits`] (the error names the field that sets the size, the estimate, the limit and how to
//! raise it); `femp check` prints the estimate. Mesh files are read (bounded, regular files
//! only) to count their vertices.
//!
//! The memory model is linear in the counts, with per-item costs measured on the `femp` binary
//! (peak resident memory of two-step runs, block-on-plate scenes from 10³ to 1.6·10⁵ particles
//! and up to 1.6·10⁴ FEM vertices, 2D and 3D; `docs/scenes.md`, "Limits"): it is meant to be
//! within a factor of about two, enough to refuse what cannot run rather than to plan a
//! machine.

use std::path::Path;

use femp_fem::Mesh;

use super::mesh::fem_mesh;
use super::{BodySpec, FemBody, MeshSpec, Method, MpmBody, Scene, ShapeSpec, VertexSelector};
use crate::error::SimError;

/// How large a scene may be.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Largest estimated memory (bytes).
    pub memory_bytes: f64,
    /// Most time steps.
    pub steps: f64,
}

/// The default step limit: 10⁸ (days of computing at the cheapest step femp takes).
pub const DEFAULT_STEP_LIMIT: f64 = 1e8;

impl Default for Limits {
    /// 80 % of this machine's memory (16 GiB where it cannot be read) and
    /// [`DEFAULT_STEP_LIMIT`] steps.
    fn default() -> Self {
        Self {
            memory_bytes: 0.8 * physical_memory().unwrap_or(20.0 * GIB),
            steps: DEFAULT_STEP_LIMIT,
        }
    }
}

impl Limits {
    /// No limit at all.
    pub fn none() -> Self {
        Self {
            memory_bytes: f64::INFINITY,
            steps: f64::INFINITY,
        }
    }
}

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// Total physical memory (bytes), from `/proc/meminfo` (Linux).
pub fn physical_memory() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024.0)
}

/// A size in bytes for people: `1.3 TB`, `512 MB`.
pub fn human_bytes(b: f64) -> String {
    const UNITS: [&str; 7] = ["B", "kB", "MB", "GB", "TB", "PB", "EB"];
    if !b.is_finite() {
        return "unlimited".into();
    }
    let mut v = b;
    let mut u = 0;
    while v >= 1000.0 && u + 1 < UNITS.len() {
        v /= 1000.0;
        u += 1;
    }
    if u == UNITS.len() - 1 && v >= 1000.0 {
        return format!("{b:.1e} B");
    }
    if v >= 100.0 || u == 0 {
        format!("{v:.0} {}", UNITS[u])
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

/// What one body costs.
#[derive(Clone, Debug)]
pub struct BodyCost {
    /// Its path in the scene (`bodies[2]`).
    pub field: String,
    /// Its name.
    pub name: String,
    /// The scene field that sets its resolution (`mpm.grid_spacing`, `bodies[2].mesh.cells`).
    pub resolution: String,
    /// Particles (MPM) or vertices (FEM).
    pub points: f64,
    /// Grid nodes (MPM; 0 for FEM).
    pub grid_nodes: f64,
    /// Elements (FEM; 0 for MPM).
    pub elements: f64,
    /// Estimated memory (bytes).
    pub memory_bytes: f64,
}

/// The estimated cost of a scene.
#[derive(Clone, Debug, Default)]
pub struct Estimate {
    /// MPM particles.
    pub particles: f64,
    /// Active MPM grid nodes (an upper estimate: bodies' nodes are added as if apart).
    pub grid_nodes: f64,
    /// FEM vertices.
    pub fem_vertices: f64,
    /// FEM elements.
    pub fem_elements: f64,
    /// Unknowns of one implicit step (D per grid node and per FEM vertex that is not fully
    /// prescribed; augury: D per FEM vertex).
    pub dofs: f64,
    /// Time steps.
    pub steps: f64,
    /// Frames written (without `--no-frames`).
    pub frames: f64,
    /// Peak memory (bytes).
    pub memory_bytes: f64,
    /// Bytes of one frame (all bodies).
    pub frame_bytes: f64,
    /// Per body.
    pub bodies: Vec<BodyCost>,
}

impl Estimate {
    /// Disk space of the frames of a whole run (bytes).
    pub fn output_bytes(&self) -> f64 {
        self.frames * self.frame_bytes
    }

    /// One line: counts, memory, steps and output.
    pub fn describe(&self) -> String {
        let n = |x: f64| {
            if x < 1e6 {
                format!("{x:.0}")
            } else {
                format!("{x:.2e}")
            }
        };
        format!(
            "estimated {} particles on {} grid nodes, {} FEM vertices in {} elements, {} unknowns; \
             {} steps; memory about {}; frames {} × {} = {}",
            n(self.particles),
            n(self.grid_nodes),
            n(self.fem_vertices),
            n(self.fem_elements),
            n(self.dofs),
            n(self.steps),
            human_bytes(self.memory_bytes),
            n(self.frames),
            human_bytes(self.frame_bytes),
            human_bytes(self.output_bytes()),
        )
    }
}

/// Memory costs per item (bytes), measured (module doc).
struct Costs {
    base: f64,
    particle: f64,
    grid_node: f64,
    fem_vertex: f64,
}

fn costs(d: usize, method: Method) -> Costs {
    match (method, d) {
        (Method::Bfemp, 2) => Costs {
            base: 16e6,
            particle: 500.0,
            grid_node: 13e3,
            fem_vertex: 7e3,
        },
        (Method::Bfemp, _) => Costs {
            base: 32e6,
            particle: 600.0,
            grid_node: 140e3,
            fem_vertex: 36e3,
        },
        (Method::Augury, 2) => Costs {
            base: 8e6,
            particle: 0.0,
            grid_node: 0.0,
            fem_vertex: 2.5e3,
        },
        (Method::Augury, _) => Costs {
            base: 8e6,
            particle: 0.0,
            grid_node: 0.0,
            fem_vertex: 5e3,
        },
    }
}

/// Particles and grid nodes of an MPM shape at grid spacing `h` with `per_axis` particles per
/// cell axis. Mesh shapes are read (bounded).
fn mpm_counts(
    shape: &ShapeSpec,
    d: usize,
    h: f64,
    per_axis: f64,
    base_dir: &Path,
    field: &str,
) -> Result<(f64, f64), SimError> {
    let s = h / per_axis;
    let df = d as i32;
    let pi = std::f64::consts::PI;
    // Nodes touched by the stencils of a region: its cells and a layer around it.
    let around = |volume: f64, surface: f64| volume / h.powi(df) + 2.0 * surface / h.powi(df - 1);
    Ok(match shape {
        ShapeSpec::Box { min, max, .. } => {
            let ext: Vec<f64> = min.iter().zip(max).map(|(a, b)| b - a).collect();
            let particles = ext.iter().map(|e| (e / s).round().max(1.0)).product();
            let nodes = ext.iter().map(|e| e / h + 3.0).product();
            (particles, nodes)
        }
        ShapeSpec::Disk { radius: r, .. } => {
            let (vol, surf) = if d == 2 {
                (pi * r * r, 2.0 * pi * r)
            } else {
                (4.0 / 3.0 * pi * r.powi(3), 4.0 * pi * r * r)
            };
            (vol / s.powi(df), around(vol, surf))
        }
        ShapeSpec::Ring { r_in, r_out, .. } => {
            let vol = pi * (r_out * r_out - r_in * r_in);
            (vol / (s * s), around(vol, 2.0 * pi * (r_in + r_out)))
        }
        ShapeSpec::SemicircularRing { r_in, r_out, .. } => {
            let vol = 0.5 * pi * (r_out * r_out - r_in * r_in);
            let surf = pi * (r_in + r_out) + 2.0 * (r_out - r_in);
            (vol / (s * s), around(vol, surf))
        }
        ShapeSpec::Mesh(never) => match *never {},
        ShapeSpec::File(f) => {
            let (vol, lo, hi) = match d {
                2 => mesh_extent::<2>(base_dir, &f.path, f.reorient, field)?,
                _ => mesh_extent::<3>(base_dir, &f.path, f.reorient, field)?,
            };
            let nodes = lo.iter().zip(&hi).map(|(a, b)| (b - a) / h + 3.0).product();
            (vol / s.powi(df), nodes)
        }
    })
}

fn mesh_extent<const D: usize>(
    base_dir: &Path,
    file: &str,
    reorient: bool,
    field: &str,
) -> Result<(f64, Vec<f64>, Vec<f64>), SimError> {
    let mesh: Mesh<D> = femp_fem::mesh::gmsh::read_msh_with(
        &base_dir.join(file),
        femp_fem::mesh::gmsh::ReadOptions { reorient },
    )
    .map_err(|e| SimError::Build {
        context: format!("{field}.file"),
        message: e.to_string(),
    })?;
    let (lo, hi) = mesh.bounding_box();
    Ok((
        mesh.volume(),
        lo.iter().copied().collect(),
        hi.iter().copied().collect(),
    ))
}

/// Vertices and elements of a FEM mesh spec, from the generators' formulas (files are read).
fn fem_counts(
    mesh: &MeshSpec,
    d: usize,
    base_dir: &Path,
    field: &str,
) -> Result<(f64, f64), SimError> {
    let c = |v: &[usize]| -> Vec<f64> { v.iter().map(|&n| n as f64).collect() };
    Ok(match mesh {
        MeshSpec::Rectangle { cells, .. } | MeshSpec::CosineStrip { cells, .. } => {
            let n = c(cells);
            ((n[0] + 1.0) * (n[1] + 1.0), 2.0 * n[0] * n[1])
        }
        MeshSpec::Cuboid { cells, .. } => {
            let n = c(cells);
            (
                (n[0] + 1.0) * (n[1] + 1.0) * (n[2] + 1.0),
                6.0 * n[0] * n[1] * n[2],
            )
        }
        MeshSpec::Disk { rings, .. } => {
            let r = *rings as f64;
            (1.0 + 3.0 * r * (r + 1.0), 6.0 * r * r)
        }
        MeshSpec::Ring { cells, .. } => {
            let n = c(cells);
            ((n[0] + 1.0) * n[1], 2.0 * n[0] * n[1])
        }
        MeshSpec::SemicircularRing { cells, .. } => {
            let n = c(cells);
            ((n[0] + 1.0) * (n[1] + 1.0), 2.0 * n[0] * n[1])
        }
        MeshSpec::File(_) => {
            let counts = |v: usize, e: usize| (v as f64, e as f64);
            match d {
                2 => {
                    let m = fem_mesh::<2>(mesh, base_dir, field)?;
                    counts(m.num_vertices(), m.num_cells())
                }
                _ => {
                    let m = fem_mesh::<3>(mesh, base_dir, field)?;
                    counts(m.num_vertices(), m.num_cells())
                }
            }
        }
    })
}

/// The field that sets a FEM mesh's resolution.
fn mesh_field(mesh: &MeshSpec) -> &'static str {
    match mesh {
        MeshSpec::Disk { .. } => "mesh.disk.rings",
        MeshSpec::File(_) => "mesh.file.path",
        MeshSpec::Rectangle { .. } => "mesh.rectangle.cells",
        MeshSpec::Cuboid { .. } => "mesh.cuboid.cells",
        MeshSpec::Ring { .. } => "mesh.ring.cells",
        MeshSpec::SemicircularRing { .. } => "mesh.semicircular_ring.cells",
        MeshSpec::CosineStrip { .. } => "mesh.cosine_strip.cells",
    }
}

/// Estimate what a (validated) scene costs.
pub fn estimate(scene: &Scene) -> Result<Estimate, SimError> {
    let spec = scene.spec();
    let d = spec.dimension;
    let cost = costs(d, spec.method);
    let mut e = Estimate {
        memory_bytes: cost.base,
        ..Default::default()
    };
    for (i, b) in spec.bodies.iter().enumerate() {
        let field = format!("bodies[{i}]");
        match b {
            BodySpec::Mpm(MpmBody {
                name,
                shape,
                particles_per_cell,
                ..
            }) => {
                let Some(m) = &spec.mpm else { continue };
                let ppc = particles_per_cell.unwrap_or(if d == 2 { 4 } else { 8 });
                let per_axis = (ppc as f64).powf(1.0 / d as f64).round();
                let (points, nodes) = mpm_counts(
                    shape,
                    d,
                    m.grid_spacing,
                    per_axis,
                    &scene.base_dir,
                    &format!("{field}.shape"),
                )?;
                let memory_bytes = points * cost.particle + nodes * cost.grid_node;
                e.particles += points;
                e.grid_nodes += nodes;
                e.dofs += d as f64 * nodes;
                e.memory_bytes += memory_bytes;
                // Position, velocity, det F, von Mises, body: float64 in binary VTU.
                e.frame_bytes += points * 8.0 * (2.0 * d as f64 + 3.0);
                e.bodies.push(BodyCost {
                    field,
                    name: name.clone(),
                    resolution: if particles_per_cell.is_some() {
                        format!("mpm.grid_spacing and bodies[{i}].particles_per_cell")
                    } else {
                        "mpm.grid_spacing".into()
                    },
                    points,
                    grid_nodes: nodes,
                    elements: 0.0,
                    memory_bytes,
                });
            }
            BodySpec::Fem(FemBody {
                name,
                mesh,
                prescribed,
                ..
            }) => {
                let (vertices, elements) =
                    fem_counts(mesh, d, &scene.base_dir, &format!("{field}.mesh"))?;
                let all_fixed = prescribed
                    .iter()
                    .any(|p| matches!(p.vertices, VertexSelector::All));
                let memory_bytes = vertices * cost.fem_vertex;
                e.fem_vertices += vertices;
                e.fem_elements += elements;
                if !all_fixed || spec.method == Method::Augury {
                    e.dofs += d as f64 * vertices;
                }
                e.memory_bytes += memory_bytes;
                // Points, displacement, velocity; connectivity, offsets, types, two cell fields.
                e.frame_bytes += vertices * 8.0 * (3.0 * d as f64)
                    + elements * (8.0 * (d as f64 + 1.0) + 8.0 + 1.0 + 16.0);
                e.bodies.push(BodyCost {
                    resolution: format!("{field}.{}", mesh_field(mesh)),
                    field,
                    name: name.clone(),
                    points: vertices,
                    grid_nodes: 0.0,
                    elements,
                    memory_bytes,
                });
            }
        }
    }
    e.steps = ((spec.time.duration / spec.time.dt) - 1e-9).ceil().max(1.0);
    e.frames = 1.0
        + spec
            .time
            .frame_interval
            .map_or(e.steps, |f| (spec.time.duration / f).floor().min(e.steps));
    Ok(e)
}

/// Refuse an estimate over the limits, naming the field that sets the size.
pub fn check(e: &Estimate, limits: &Limits) -> Result<(), SimError> {
    if !(e.steps <= limits.steps) {
        return Err(SimError::TooLarge {
            field: "time.dt".into(),
            message: format!(
                "time.duration / time.dt = {:.3e} steps, more than the limit of {:.3e}; use a \
                 larger time step or a shorter duration, or raise the limit (femp: \
                 --step-limit)",
                e.steps, limits.steps
            ),
        });
    }
    if !(e.memory_bytes <= limits.memory_bytes) {
        let worst = e
            .bodies
            .iter()
            .max_by(|a, b| a.memory_bytes.total_cmp(&b.memory_bytes));
        let (field, what) = match worst {
            Some(b) if b.grid_nodes > 0.0 => (
                b.resolution.clone(),
                format!(
                    "body `{}` ({}) alone has about {:.3e} particles on {:.3e} grid nodes ({})",
                    b.name,
                    b.field,
                    b.points,
                    b.grid_nodes,
                    human_bytes(b.memory_bytes)
                ),
            ),
            Some(b) => (
                b.resolution.clone(),
                format!(
                    "body `{}` ({}) alone has about {:.3e} vertices in {:.3e} elements ({})",
                    b.name,
                    b.field,
                    b.points,
                    b.elements,
                    human_bytes(b.memory_bytes)
                ),
            ),
            None => ("bodies".into(), String::new()),
        };
        return Err(SimError::TooLarge {
            field,
            message: format!(
                "the scene needs an estimated {} of memory, more than the limit of {}: {what}; \
                 coarsen it, or raise the limit (femp: --memory-limit GIB)",
                human_bytes(e.memory_bytes),
                human_bytes(limits.memory_bytes),
            ),
        });
    }
    Ok(())
}
