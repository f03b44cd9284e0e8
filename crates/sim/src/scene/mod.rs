//! Scenes: JSON files (format in `docs/scenes.md`, types in [`spec`]), loaded with field paths
//! in every error. Parsing checks every section and makes its typed parts ([`resolved`]) once:
//! a [`Scene`] is only ever a checked one.

pub mod mesh;
pub mod resolved;
pub mod size;
pub mod spec;

use std::path::{Path, PathBuf};

use femp_contact::{BarrierHessian, LogBarrier};
use femp_fem::{Lame, LinearElastic, Material, NeoHookean, material::check_density};
use resolved::{FrictionLaw, PairLaw, Resolved};
pub use spec::*;

use crate::error::{SimError, invalid};

/// A parsed and checked scene with its typed parts, and the directory relative paths resolve
/// against. Made only by [`load`], [`parse`] and [`Scene::with_spec`], so its spec has passed
/// every check and its parts are its spec's.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The parsed file.
    spec: SceneSpec,
    /// What the parser made of it.
    resolved: Resolved,
    /// Directory of the scene file.
    pub base_dir: PathBuf,
    /// Name (the `name` field or the file stem).
    pub name: String,
    /// How large the scene may be ([`size::check`], applied by `World::build`).
    pub limits: size::Limits,
    /// The text the scene was parsed from (a run copies it into its output directory).
    pub source: Option<String>,
}

impl Scene {
    /// The scene as parsed (to read; [`Scene::with_spec`] makes an edited copy).
    pub fn spec(&self) -> &SceneSpec {
        &self.spec
    }

    /// The typed parts the parser made of the spec.
    pub fn resolved(&self) -> &Resolved {
        &self.resolved
    }

    /// Time step Δt (s) the scene's steps start with.
    pub fn dt(&self) -> f64 {
        self.spec.time.dt
    }

    /// This scene with `spec` instead of its own, parsed from [`SceneSpec::to_json`] and checked
    /// as a file would be (paths against the same directory, the same limits; named `spec.name`
    /// or this scene's name).
    pub fn with_spec(&self, spec: &SceneSpec) -> Result<Scene, SimError> {
        let mut s = parse(
            &spec.to_json(),
            &format!("{} (edited)", self.name),
            self.base_dir.clone(),
            &self.name,
        )?;
        s.limits = self.limits;
        Ok(s)
    }
}

impl SceneSpec {
    /// The scene as JSON in the scene file format: [`parse`] reads it back to an equal spec. A
    /// program builds or edits scenes as these typed values (field names checked by the
    /// compiler) and runs them through this text, which is also what a run copies into its
    /// output directory.
    pub fn to_json(&self) -> String {
        // Every field is a number, string, bool, sequence or struct: nothing can fail (a
        // non-finite number is written as `null`, which `parse` then names).
        serde_json::to_string_pretty(self).expect("a scene spec is plain data")
    }
}

/// The largest scene file [`load`] reads (64 MiB; scenes are a few kB, a long vertex list a
/// few MB).
pub const MAX_SCENE_BYTES: u64 = 64 << 20;

/// Read, parse and validate a scene file (a regular file of at most [`MAX_SCENE_BYTES`]).
pub fn load(path: &Path) -> Result<Scene, SimError> {
    let bytes =
        femp_fem::mesh::gmsh::read_regular_file(path, MAX_SCENE_BYTES).map_err(|e| match e {
            femp_fem::FemError::Io { path, source } => SimError::Io { path, source },
            femp_fem::FemError::MeshFile { message, .. } => SimError::SceneFormat {
                file: path.display().to_string(),
                field: "(root)".into(),
                message,
            },
            other => SimError::SceneFormat {
                file: path.display().to_string(),
                field: "(root)".into(),
                message: other.to_string(),
            },
        })?;
    let text = String::from_utf8(bytes).map_err(|e| SimError::SceneFormat {
        file: path.display().to_string(),
        field: "(root)".into(),
        message: format!(
            "not UTF-8 text (invalid byte at offset {})",
            e.utf8_error().valid_up_to()
        ),
    })?;
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    parse(&text, &path.display().to_string(), base, &stem)
}

/// Parse and validate scene text (`file` names it in errors).
pub fn parse(
    text: &str,
    file: &str,
    base_dir: PathBuf,
    default_name: &str,
) -> Result<Scene, SimError> {
    let mut de = serde_json::Deserializer::from_str(text);
    let spec: SceneSpec = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let mut field = e.path().to_string();
        let mut message = e.into_inner().to_string();
        // A body's own deserialiser reports the path inside the body as `\u{1}path\u{1}rest`.
        if let Some(rest) = message.strip_prefix(spec::NESTED_PATH)
            && let Some((inner, rest)) = rest.split_once(spec::NESTED_PATH)
        {
            if !inner.is_empty() && inner != "." {
                field = format!("{field}.{inner}");
            }
            message = rest.to_string();
        }
        SimError::SceneFormat {
            file: file.to_string(),
            field: if field == "." { "(root)".into() } else { field },
            message,
        }
    })?;
    // Only whitespace may follow the scene object.
    de.end().map_err(|e| SimError::SceneFormat {
        file: file.to_string(),
        field: "(root)".into(),
        message: format!("text after the scene object ({e})"),
    })?;
    let resolved = resolve(&spec)?;
    check_mesh_files(&spec, &base_dir)?;
    let name = spec
        .name
        .clone()
        .unwrap_or_else(|| default_name.to_string());
    Ok(Scene {
        spec,
        resolved,
        base_dir,
        name,
        limits: size::Limits::default(),
        source: Some(text.to_string()),
    })
}

/// A mesh file's reference (field path `field`): a path naming a file.
fn mesh_file(field: &str, file: &MeshFile) -> Result<(), SimError> {
    if file.path.is_empty() {
        return Err(invalid(format!("{field}.path"), "must name a mesh file"));
    }
    Ok(())
}

/// Surface and other mesh formats femp does not read, by file extension.
const NOT_MSH: [&str; 8] = ["stl", "obj", "ply", "off", "vtk", "vtu", "inp", "mesh"];

/// Every mesh file a scene names exists and is a Gmsh `.msh` file (by its first line), checked
/// when the scene is read rather than when its world is built; a surface mesh (`.stl`, `.obj`,
/// …) is named with the command that fills it.
fn check_mesh_files(spec: &SceneSpec, base_dir: &Path) -> Result<(), SimError> {
    for (i, body) in spec.bodies.iter().enumerate() {
        let (field, file) = match body {
            BodySpec::Mpm(b) => match &b.shape {
                ShapeSpec::File(f) => (format!("bodies[{i}].shape.file.path"), f),
                _ => continue,
            },
            BodySpec::Fem(b) => match &b.mesh {
                MeshSpec::File(f) => (format!("bodies[{i}].mesh.file.path"), f),
                _ => continue,
            },
        };
        let path = base_dir.join(&file.path);
        let fill = |what: &str| {
            let stem = Path::new(&file.path).with_extension("msh");
            format!(
                "{what}: femp reads Gmsh .msh meshes of triangles (2D) or tetrahedra (3D); fill a \
                 closed surface with `python -m femp.mesh {} {} [--size h]` (or an outline with \
                 `--2d`; docs/scenes.md) and name the .msh here",
                file.path,
                stem.display()
            )
        };
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        if NOT_MSH.contains(&ext.as_str()) {
            return Err(invalid(
                field,
                fill(&format!("`{}` is a .{ext} file", file.path)),
            ));
        }
        let unreadable = |e: std::io::Error| {
            invalid(
                field.clone(),
                format!(
                    "{}: {e} (relative paths start at the scene's directory)",
                    path.display()
                ),
            )
        };
        // Only a regular file is opened (a FIFO would block the open, a device never end).
        match std::fs::metadata(&path) {
            Ok(m) if m.is_file() => {}
            Ok(_) => {
                return Err(invalid(
                    field,
                    format!("{}: not a regular file", path.display()),
                ));
            }
            Err(e) => return Err(unreadable(e)),
        }
        let first = match std::fs::File::open(&path) {
            Ok(f) => {
                let mut line = String::new();
                let _ = std::io::BufRead::read_line(
                    &mut std::io::BufReader::new(std::io::Read::take(f, 256)),
                    &mut line,
                );
                line
            }
            Err(e) => return Err(unreadable(e)),
        };
        if !first.trim_start().starts_with("$MeshFormat") {
            return Err(invalid(
                field,
                fill(&format!(
                    "`{}` is not a Gmsh .msh file (it does not start with $MeshFormat)",
                    file.path
                )),
            ));
        }
    }
    Ok(())
}

fn vec_len(field: &str, v: &[f64], d: usize) -> Result<(), SimError> {
    if v.len() != d {
        return Err(invalid(
            field,
            format!("has {} components; the scene is {d}D", v.len()),
        ));
    }
    if let Some(x) = v.iter().find(|x| !x.is_finite()) {
        return Err(invalid(field, format!("component {x} is not finite")));
    }
    Ok(())
}

/// The speed of light (m/s): a body or a boundary given a speed at or above it is a unit
/// mix-up, not a scene (a velocity of 1e30 m/s failed the first step with no field named).
pub const SPEED_OF_LIGHT: f64 = 299_792_458.0;

/// A velocity: `d` finite components, slower than light.
fn velocity(field: &str, v: &[f64], d: usize) -> Result<(), SimError> {
    vec_len(field, v, d)?;
    let speed = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !(speed < SPEED_OF_LIGHT) {
        return Err(invalid(
            field,
            format!(
                "a speed of {speed:.3e} m/s is not below the speed of light ({SPEED_OF_LIGHT:.3e} m/s): check the units"
            ),
        ));
    }
    Ok(())
}

fn positive(field: &str, x: f64) -> Result<(), SimError> {
    if x > 0.0 && x.is_finite() {
        Ok(())
    } else {
        Err(invalid(field, format!("{x} must be positive")))
    }
}

/// The material of `m` (field path `field`).
fn material(field: &str, m: &MaterialSpec) -> Result<Material, SimError> {
    let lame = Lame::from_young_poisson(m.youngs_modulus, m.nu).map_err(|e| match e {
        femp_fem::FemError::BadMaterial {
            parameter,
            value,
            requirement,
        } => invalid(
            format!("{field}.{parameter}"),
            format!("{value}: {requirement}"),
        ),
        other => invalid(field, other.to_string()),
    })?;
    check_density(m.rho).map_err(|_| {
        invalid(
            format!("{field}.rho"),
            format!("{} must be positive", m.rho),
        )
    })?;
    Ok(match m.model {
        ModelSpec::NeoHookean => Material::NeoHookean(NeoHookean::new(lame)),
        ModelSpec::Linear => Material::Linear(LinearElastic::new(lame)),
    })
}

fn angular(field: &str, a: &AngularSpec, d: usize) -> Result<(), SimError> {
    match (a, d) {
        (AngularSpec::Scalar(w), 2) if w.is_finite() => Ok(()),
        (AngularSpec::Vector(v), 3) => vec_len(field, v, 3),
        (AngularSpec::Scalar(_), _) => Err(invalid(field, "must be a 3-vector in 3D")),
        (AngularSpec::Vector(_), _) => Err(invalid(field, "must be a number (about z) in 2D")),
    }
}

fn transform(field: &str, t: &TransformSpec, d: usize) -> Result<(), SimError> {
    if !t.rotate_deg.is_finite() {
        return Err(invalid(format!("{field}.rotate_deg"), "must be finite"));
    }
    if let Some(a) = &t.axis {
        if d == 2 {
            return Err(invalid(
                format!("{field}.axis"),
                "2D rotations are about z; remove `axis`",
            ));
        }
        direction(&format!("{field}.axis"), a, 3)?;
    }
    if let Some(a) = &t.about {
        vec_len(&format!("{field}.about"), a, d)?;
    }
    if let Some(a) = &t.translate {
        vec_len(&format!("{field}.translate"), a, d)?;
    }
    Ok(())
}

fn motion(field: &str, segs: &[MotionSegment], d: usize) -> Result<(), SimError> {
    let mut last = 0.0;
    for (k, s) in segs.iter().enumerate() {
        let f = format!("{field}[{k}]");
        if !(s.until > last) {
            return Err(invalid(
                format!("{f}.until"),
                format!(
                    "{} must be after the previous segment's end ({last})",
                    s.until
                ),
            ));
        }
        last = s.until;
        if let Some(v) = &s.velocity {
            velocity(&format!("{f}.velocity"), v, d)?;
        }
        if let Some(w) = &s.angular_velocity {
            angular(&format!("{f}.angular_velocity"), w, d)?;
        }
        if let Some(c) = &s.center {
            vec_len(&format!("{f}.center"), c, d)?;
        }
    }
    Ok(())
}

fn radii(field: &str, r_in: f64, r_out: f64) -> Result<(), SimError> {
    positive(&format!("{field}.r_in"), r_in)?;
    if !(r_out > r_in && r_out.is_finite()) {
        return Err(invalid(
            format!("{field}.r_out"),
            format!("{r_out} must exceed r_in = {r_in}"),
        ));
    }
    Ok(())
}

fn cells(field: &str, c: &[usize], n: usize) -> Result<(), SimError> {
    if c.len() != n {
        return Err(invalid(
            field,
            format!("needs {n} entries, has {}", c.len()),
        ));
    }
    if c.contains(&0) {
        return Err(invalid(field, "every entry must be at least 1"));
    }
    Ok(())
}

fn box_corners(field: &str, min: &[f64], max: &[f64], d: usize) -> Result<(), SimError> {
    vec_len(&format!("{field}.min"), min, d)?;
    vec_len(&format!("{field}.max"), max, d)?;
    for a in 0..d {
        if !(max[a] > min[a]) {
            return Err(invalid(
                format!("{field}.max"),
                format!("component {a} ({}) must exceed min ({})", max[a], min[a]),
            ));
        }
    }
    Ok(())
}

/// The most CG iterations a Newton direction may take (`solver.pcg_max_iterations`): one CG
/// solve is not interruptible, so its length is bounded here.
pub const MAX_PCG_ITERATIONS: usize = 100_000;

/// The most substeps a step may be split into (`solver.max_substeps`).
pub const MAX_SUBSTEPS: usize = 1 << 20;

/// The most augury iterations per step (`augury.iterations`; the paper uses 1): a step is not
/// interruptible, so its length is bounded here.
pub const MAX_AUGURY_ITERATIONS: usize = 1000;

/// A direction given as a vector (a plane's normal, a rotation axis): finite, and long enough
/// that normalising it is exact (a denormal or huge vector would normalise to NaN or 0).
fn direction(field: &str, v: &[f64], d: usize) -> Result<(), SimError> {
    vec_len(field, v, d)?;
    let sq: f64 = v.iter().map(|x| x * x).sum();
    if !sq.is_normal() {
        return Err(invalid(
            field,
            format!(
                "{v:?} cannot be normalised (its length is {}); give a direction such as a unit vector",
                sq.sqrt()
            ),
        ));
    }
    Ok(())
}

/// The longest body name.
pub const MAX_NAME_LEN: usize = 64;

/// Body names become file names (`NAME.pvd`, `frames/NAME_000001.vtu`), so they are restricted
/// to what is safe on every file system: 1–[`MAX_NAME_LEN`] ASCII letters, digits, `_`, `-`
/// and `.`, not starting with `.` or `-`. Two names may not differ only in case (they would
/// collide on case-insensitive file systems), and `particles` is the MPM output's.
fn body_name(field: &str, name: &str, fem: bool, taken: &[&str]) -> Result<(), SimError> {
    if name.is_empty() {
        return Err(invalid(field, "must not be empty"));
    }
    if name.len() > MAX_NAME_LEN {
        return Err(invalid(
            field,
            format!("`{name}` is longer than {MAX_NAME_LEN} characters"),
        ));
    }
    if let Some(c) = name
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.')))
    {
        return Err(invalid(
            field,
            format!(
                "`{name}` contains {c:?}: body names become file names, so they may only use \
                 ASCII letters, digits, `_`, `-` and `.`"
            ),
        ));
    }
    if name.starts_with(['.', '-']) {
        return Err(invalid(
            field,
            format!("`{name}` must not start with `.` or `-` (it becomes a file name)"),
        ));
    }
    if let Some(other) = taken.iter().find(|t| t.eq_ignore_ascii_case(name)) {
        return Err(invalid(
            field,
            if *other == name {
                format!("`{name}` is used by another body")
            } else {
                format!(
                    "`{name}` and `{other}` differ only in case; their output files would \
                     collide on case-insensitive file systems"
                )
            },
        ));
    }
    if fem && name.eq_ignore_ascii_case("particles") {
        return Err(invalid(
            field,
            "`particles` names the MPM output (particles.pvd); choose another name for a FEM body",
        ));
    }
    Ok(())
}

/// The thinnest extent of an MPM shape before placement (`None` for mesh files, known only
/// once read): the grid must be at least this fine to resolve the body.
fn thinnest(shape: &ShapeSpec) -> Option<f64> {
    match shape {
        ShapeSpec::Box { min, max, .. } => Some(
            min.iter()
                .zip(max)
                .map(|(a, b)| b - a)
                .fold(f64::INFINITY, f64::min),
        ),
        ShapeSpec::Disk { radius, .. } => Some(2.0 * radius),
        ShapeSpec::Ring { r_in, r_out, .. } | ShapeSpec::SemicircularRing { r_in, r_out, .. } => {
            Some(r_out - r_in)
        }
        ShapeSpec::File(_) => None,
        ShapeSpec::Mesh(never) => match *never {},
    }
}

/// Check what every body has (field path `f`): its material, which it returns, and its initial
/// velocity and angular velocity, if given.
fn material_and_motion(
    f: &str,
    m: &MaterialSpec,
    (velocity, angular_velocity): (Option<&[f64]>, Option<&AngularSpec>),
    d: usize,
) -> Result<Material, SimError> {
    let material = material(&format!("{f}.material"), m)?;
    if let Some(v) = velocity {
        self::velocity(&format!("{f}.velocity"), v, d)?;
    }
    if let Some(w) = angular_velocity {
        angular(&format!("{f}.angular_velocity"), w, d)?;
    }
    Ok(material)
}

/// Check an MPM body (field path `f`) of a `d`-dimensional scene; its material.
fn mpm_body(f: &str, body: &MpmBody, d: usize) -> Result<Material, SimError> {
    let MpmBody {
        shape,
        particles_per_cell,
        material: m,
        velocity,
        angular_velocity,
        ..
    } = body;
    let material = material_and_motion(f, m, (velocity.as_deref(), angular_velocity.as_ref()), d)?;
    if let Some(ppc) = particles_per_cell {
        let k = (*ppc as f64).powf(1.0 / d as f64).round() as usize;
        if *ppc == 0 || k.checked_pow(d as u32) != Some(*ppc) {
            return Err(invalid(
                format!("{f}.particles_per_cell"),
                format!(
                    "{ppc} must be a perfect {} (particles are placed on a regular sub-grid)",
                    if d == 2 { "square" } else { "cube" }
                ),
            ));
        }
    }
    let sf = format!("{f}.shape");
    match shape {
        ShapeSpec::Box {
            min,
            max,
            transform: t,
        } => {
            box_corners(&sf, min, max, d)?;
            if let Some(t) = t {
                transform(&format!("{sf}.transform"), t, d)?;
            }
        }
        ShapeSpec::Disk {
            center,
            radius,
            sampling,
        } => {
            vec_len(&format!("{sf}.center"), center, d)?;
            positive(&format!("{sf}.radius"), *radius)?;
            if *sampling == Sampling::Polar && d != 2 {
                return Err(invalid(format!("{sf}.sampling"), "`polar` sampling is 2D"));
            }
        }
        ShapeSpec::Ring {
            center,
            r_in,
            r_out,
            ..
        }
        | ShapeSpec::SemicircularRing {
            center,
            r_in,
            r_out,
        } => {
            if d != 2 {
                return Err(invalid(sf, "rings are 2D shapes"));
            }
            vec_len(&format!("{sf}.center"), center, d)?;
            radii(&sf, *r_in, *r_out)?;
        }
        ShapeSpec::File(file) => mesh_file(&format!("{sf}.file"), file)?,
        ShapeSpec::Mesh(never) => match *never {},
    }
    Ok(material)
}

/// Check a FEM body (field path `f`) of a `d`-dimensional scene; its material.
fn fem_body(f: &str, body: &FemBody, d: usize) -> Result<Material, SimError> {
    let FemBody {
        mesh,
        transform: t,
        material: m,
        velocity,
        angular_velocity,
        prescribed,
        ..
    } = body;
    let material = material_and_motion(f, m, (velocity.as_deref(), angular_velocity.as_ref()), d)?;
    if let Some(t) = t {
        transform(&format!("{f}.transform"), t, d)?;
    }
    let mf = format!("{f}.mesh");
    match mesh {
        MeshSpec::Rectangle { min, max, cells: c } => {
            if d != 2 {
                return Err(invalid(mf, "`rectangle` is 2D; use `cuboid`"));
            }
            box_corners(&mf, min, max, d)?;
            cells(&format!("{mf}.cells"), c, 2)?;
        }
        MeshSpec::Cuboid { min, max, cells: c } => {
            if d != 3 {
                return Err(invalid(mf, "`cuboid` is 3D; use `rectangle`"));
            }
            box_corners(&mf, min, max, d)?;
            cells(&format!("{mf}.cells"), c, 3)?;
        }
        MeshSpec::Disk {
            center,
            radius,
            rings,
        } => {
            if d != 2 {
                return Err(invalid(mf, "`disk` meshes are 2D"));
            }
            vec_len(&format!("{mf}.center"), center, d)?;
            positive(&format!("{mf}.radius"), *radius)?;
            if *rings == 0 {
                return Err(invalid(format!("{mf}.rings"), "must be at least 1"));
            }
        }
        MeshSpec::Ring {
            center,
            r_in,
            r_out,
            cells: c,
        }
        | MeshSpec::SemicircularRing {
            center,
            r_in,
            r_out,
            cells: c,
        } => {
            if d != 2 {
                return Err(invalid(mf, "ring meshes are 2D"));
            }
            vec_len(&format!("{mf}.center"), center, d)?;
            radii(&mf, *r_in, *r_out)?;
            cells(&format!("{mf}.cells"), c, 2)?;
        }
        MeshSpec::CosineStrip {
            wavelength,
            x0,
            x1,
            thickness,
            cells: c,
            ..
        } => {
            if d != 2 {
                return Err(invalid(mf, "`cosine_strip` is 2D"));
            }
            positive(&format!("{mf}.wavelength"), *wavelength)?;
            if !(x1 > x0) {
                return Err(invalid(
                    format!("{mf}.x1"),
                    format!("{x1} must exceed x0 = {x0}"),
                ));
            }
            if !(*thickness != 0.0 && thickness.is_finite()) {
                return Err(invalid(format!("{mf}.thickness"), "must be non-zero"));
            }
            cells(&format!("{mf}.cells"), c, 2)?;
        }
        MeshSpec::File(file) => mesh_file(&format!("{mf}.file"), file)?,
    }
    for (k, p) in prescribed.iter().enumerate() {
        let pf = format!("{f}.prescribed[{k}]");
        match &p.vertices {
            VertexSelector::Below { axis, value } | VertexSelector::Above { axis, value } => {
                if *axis >= d {
                    return Err(invalid(
                        format!("{pf}.vertices"),
                        format!("axis {axis} does not exist in {d}D"),
                    ));
                }
                if !value.is_finite() {
                    return Err(invalid(
                        format!("{pf}.vertices"),
                        "threshold must be finite",
                    ));
                }
            }
            VertexSelector::List(l) if l.is_empty() => {
                return Err(invalid(format!("{pf}.vertices"), "the list is empty"));
            }
            _ => {}
        }
        motion(&format!("{pf}.motion"), &p.motion, d)?;
    }
    Ok(material)
}

/// Check the `solver` section.
fn solver(solver: &SolverSpec) -> Result<(), SimError> {
    positive("solver.tolerance", solver.tolerance)?;
    if solver.max_newton_iterations == 0 {
        return Err(invalid(
            "solver.max_newton_iterations",
            "must be at least 1",
        ));
    }
    if solver.max_friction_iterations == 0 {
        return Err(invalid(
            "solver.max_friction_iterations",
            "must be at least 1",
        ));
    }
    if !(1..=MAX_SUBSTEPS).contains(&solver.max_substeps) {
        return Err(invalid(
            "solver.max_substeps",
            format!("{} must be from 1 to {MAX_SUBSTEPS}", solver.max_substeps),
        ));
    }
    if !(solver.pcg_rtol > 0.0 && solver.pcg_rtol < 1.0) {
        return Err(invalid(
            "solver.pcg_rtol",
            format!("{} must be in (0, 1)", solver.pcg_rtol),
        ));
    }
    if !(1..=MAX_PCG_ITERATIONS).contains(&solver.pcg_max_iterations) {
        return Err(invalid(
            "solver.pcg_max_iterations",
            format!(
                "{} must be from 1 to {MAX_PCG_ITERATIONS}",
                solver.pcg_max_iterations
            ),
        ));
    }
    if !(solver.factor_cg_rtol > 0.0 && solver.factor_cg_rtol < 1.0) {
        return Err(invalid(
            "solver.factor_cg_rtol",
            format!("{} must be in (0, 1)", solver.factor_cg_rtol),
        ));
    }
    if !(1..=MAX_PCG_ITERATIONS).contains(&solver.factor_cg_iterations) {
        return Err(invalid(
            "solver.factor_cg_iterations",
            format!(
                "{} must be from 1 to {MAX_PCG_ITERATIONS}",
                solver.factor_cg_iterations
            ),
        ));
    }
    if let Some(max) = solver.pcg_rtol_max
        && !(max >= solver.pcg_rtol && max < 1.0)
    {
        return Err(invalid(
            "solver.pcg_rtol_max",
            format!("{max} must be in [pcg_rtol, 1) = [{}, 1)", solver.pcg_rtol),
        ));
    }
    for (field, v) in [
        ("solver.reuse_hessian_below", solver.reuse_hessian_below),
        ("solver.friction_update_below", solver.friction_update_below),
    ] {
        if !(v >= 0.0 && v.is_finite()) {
            return Err(invalid(field, format!("{v} must be finite and ≥ 0")));
        }
    }
    if !(solver.line_search_expansion >= 1.0 && solver.line_search_expansion <= 1e6) {
        return Err(invalid(
            "solver.line_search_expansion",
            format!(
                "{} must be from 1 (no expansion) to 1e6",
                solver.line_search_expansion
            ),
        ));
    }
    if let Some(forcing) = solver.friction_forcing
        && !(0.0..1.0).contains(&forcing)
    {
        return Err(invalid(
            "solver.friction_forcing",
            format!("{forcing} must be in [0, 1)"),
        ));
    }
    if let Some(m) = solver.friction_anderson {
        if m > SolverSpec::ANDERSON_MAX {
            return Err(invalid(
                "solver.friction_anderson",
                format!(
                    "{m} past iterates: at most {} (0 turns it off)",
                    SolverSpec::ANDERSON_MAX
                ),
            ));
        }
        if m > 0
            && (solver.friction_aitken == Some(true)
                || solver.friction_relaxation
                || solver.friction_extrapolation)
        {
            return Err(invalid(
                "solver.friction_anderson",
                "chooses where each friction operator is lagged, as friction_aitken, \
                 friction_relaxation and friction_extrapolation do: set only one of them"
                    .to_string(),
            ));
        }
    }
    if solver.friction_aitken == Some(true)
        && (solver.friction_relaxation || solver.friction_extrapolation)
    {
        return Err(invalid(
            "solver.friction_aitken",
            "chooses where each friction operator is lagged, as friction_relaxation and \
             friction_extrapolation do: set only one of them (with either, Aitken's relaxation \
             is off unless set)"
                .to_string(),
        ));
    }
    Ok(())
}

/// Check the `mpm` section of a scene with MPM bodies (present; a grid that resolves every MPM
/// body); the section.
fn mpm_section(s: &SceneSpec) -> Result<MpmSpec, SimError> {
    let Some(m) = &s.mpm else {
        return Err(invalid(
            "mpm",
            "the scene has MPM bodies but no `mpm` section (grid_spacing)",
        ));
    };
    positive("mpm.grid_spacing", m.grid_spacing)?;
    // Every MPM body at least one grid cell thick (coarser, it is a handful of particles
    // that no grid resolves).
    for (i, b) in s.bodies.iter().enumerate() {
        if let BodySpec::Mpm(body) = b
            && let Some(t) = thinnest(&body.shape)
            && t < m.grid_spacing
        {
            return Err(invalid(
                "mpm.grid_spacing",
                format!(
                    "{} is coarser than body `{}` (bodies[{i}]) is thick ({t}): the grid \
                     must resolve every MPM body with at least one cell across",
                    m.grid_spacing, body.name
                ),
            ));
        }
    }
    if !(0.0..=1.0).contains(&m.flip_ratio) {
        return Err(invalid(
            "mpm.flip_ratio",
            format!("{} must be in [0, 1]", m.flip_ratio),
        ));
    }
    Ok(m.clone())
}

/// Check the `contact` section (`None` is an error when `needed`: bodies that can touch), its
/// pairs naming bodies of `names`; the contact laws of the pairs that may touch
/// ([`pair_laws`]).
fn contact(
    contact: Option<&ContactSpec>,
    names: &[&str],
    is_mpm: &[bool],
    needed: bool,
) -> Result<Vec<PairLaw>, SimError> {
    match contact {
        Some(c) => {
            positive("contact.dhat", c.dhat)?;
            positive("contact.kappa", c.kappa)?;
            if !(c.friction >= 0.0 && c.friction.is_finite()) {
                return Err(invalid(
                    "contact.friction",
                    format!("{} must be non-negative", c.friction),
                ));
            }
            positive("contact.eps_v", c.eps_v)?;
            for (k, p) in c.pairs.iter().enumerate() {
                let pf = format!("contact.pairs[{k}]");
                for (j, b) in p.bodies.iter().enumerate() {
                    if !names.contains(&b.as_str()) {
                        return Err(invalid(
                            format!("{pf}.bodies[{j}]"),
                            format!("no body is called `{b}`"),
                        ));
                    }
                }
                if p.bodies[0] == p.bodies[1] {
                    return Err(invalid(
                        format!("{pf}.bodies"),
                        "a pair needs two different bodies",
                    ));
                }
                if let Some(x) = p.dhat {
                    positive(&format!("{pf}.dhat"), x)?;
                }
                if let Some(x) = p.kappa {
                    positive(&format!("{pf}.kappa"), x)?;
                }
                if let Some(x) = p.friction
                    && !(x >= 0.0 && x.is_finite())
                {
                    return Err(invalid(
                        format!("{pf}.friction"),
                        format!("{x} must be non-negative"),
                    ));
                }
                if let Some(x) = p.eps_v {
                    positive(&format!("{pf}.eps_v"), x)?;
                }
            }
            Ok(pair_laws(c, names, is_mpm))
        }
        None if needed => Err(invalid(
            "contact",
            "the scene has bodies that can touch but no `contact` section (dhat, kappa)",
        )),
        None => Ok(Vec::new()),
    }
}

/// The contact law of every pair of bodies that may touch (all but MPM–MPM pairs, which touch
/// through the shared grid, and pairs whose `contact.pairs` entry disables them): the section's
/// settings with the pair's own entry over them. The first entry naming a pair counts.
fn pair_laws(c: &ContactSpec, names: &[&str], is_mpm: &[bool]) -> Vec<PairLaw> {
    let hessian = match c.hessian {
        BarrierHessianSpec::GaussNewton => BarrierHessian::GaussNewton,
        BarrierHessianSpec::Projected => BarrierHessian::Projected,
    };
    let mut laws = Vec::new();
    for i in 0..names.len() {
        for j in i + 1..names.len() {
            if is_mpm[i] && is_mpm[j] {
                continue;
            }
            let over = c.pairs.iter().enumerate().find(|(_, p)| {
                (p.bodies[0] == names[i] && p.bodies[1] == names[j])
                    || (p.bodies[0] == names[j] && p.bodies[1] == names[i])
            });
            if over.is_some_and(|(_, p)| !p.enabled) {
                continue;
            }
            let pick = |own: fn(&PairSpec) -> Option<f64>, all: f64| {
                over.and_then(|(_, p)| own(p)).unwrap_or(all)
            };
            let dhat_field = match over {
                Some((k, p)) if p.dhat.is_some() => format!("contact.pairs[{k}].dhat"),
                _ => "contact.dhat".to_string(),
            };
            laws.push(PairLaw {
                bodies: [i, j],
                // Both checked positive and finite above, as `LogBarrier::new` would.
                barrier: LogBarrier {
                    dhat: pick(|p| p.dhat, c.dhat),
                    kappa: pick(|p| p.kappa, c.kappa),
                },
                hessian,
                friction: FrictionLaw {
                    mu: pick(|p| p.friction, c.friction),
                    eps_v: pick(|p| p.eps_v, c.eps_v),
                },
                dhat_field,
            });
        }
    }
    laws
}

/// Check the level-set `boundaries` (only with MPM bodies: they act on the grid).
fn boundaries(s: &SceneSpec, any_mpm: bool) -> Result<(), SimError> {
    let d = s.dimension;
    for (k, b) in s.boundaries.iter().enumerate() {
        let bf = format!("boundaries[{k}]");
        if !any_mpm {
            return Err(invalid(
                bf,
                "level-set boundaries act on the MPM grid, and the scene has no MPM body",
            ));
        }
        match &b.shape {
            BoundaryShape::HalfPlane { point, normal } => {
                vec_len(&format!("{bf}.shape.point"), point, d)?;
                direction(&format!("{bf}.shape.normal"), normal, d)?;
            }
            BoundaryShape::Cosine {
                wavelength,
                amplitude,
                offset,
                ..
            } => {
                if d != 2 {
                    return Err(invalid(format!("{bf}.shape"), "`cosine` boundaries are 2D"));
                }
                positive(&format!("{bf}.shape.wavelength"), *wavelength)?;
                if !amplitude.is_finite() || !offset.is_finite() {
                    return Err(invalid(
                        format!("{bf}.shape"),
                        "amplitude and offset must be finite",
                    ));
                }
            }
        }
        motion(&format!("{bf}.motion"), &b.motion, d)?;
        for (j, s) in b.motion.iter().enumerate() {
            if s.angular_velocity.is_some() {
                return Err(invalid(
                    format!("{bf}.motion[{j}].angular_velocity"),
                    "level-set boundaries only translate",
                ));
            }
        }
    }
    Ok(())
}

/// Check every field of a parsed scene (ranges, lengths, names, consistency), section by
/// section, and make its typed parts.
fn resolve(s: &SceneSpec) -> Result<Resolved, SimError> {
    let d = s.dimension;
    if d != 2 && d != 3 {
        return Err(invalid("dimension", format!("{d}: must be 2 or 3")));
    }
    if let Some(g) = &s.gravity {
        vec_len("gravity", g, d)?;
    }
    positive("time.dt", s.time.dt)?;
    positive("time.duration", s.time.duration)?;
    if s.time.dt > s.time.duration {
        return Err(invalid(
            "time.dt",
            format!(
                "{:e} is longer than time.duration ({:e}): the one step would end past the run's end; \
                 use a Δt no longer than the duration",
                s.time.dt, s.time.duration
            ),
        ));
    }
    if let Some(f) = s.time.frame_interval {
        positive("time.frame_interval", f)?;
    }
    solver(&s.solver)?;
    if s.bodies.is_empty() {
        return Err(invalid("bodies", "the scene has no bodies"));
    }
    let mut names: Vec<&str> = Vec::new();
    let mut is_mpm: Vec<bool> = Vec::new();
    let mut materials = Vec::with_capacity(s.bodies.len());
    // Each body is checked before the sections that refer to bodies.
    for (i, b) in s.bodies.iter().enumerate() {
        let f = format!("bodies[{i}]");
        let name = b.name();
        body_name(
            &format!("{f}.name"),
            name,
            matches!(b, BodySpec::Fem(_)),
            &names,
        )?;
        names.push(name);
        is_mpm.push(matches!(b, BodySpec::Mpm(_)));
        materials.push(match b {
            BodySpec::Mpm(body) => mpm_body(&f, body, d)?,
            BodySpec::Fem(body) => fem_body(&f, body, d)?,
        });
    }
    let any_mpm = is_mpm.contains(&true);
    let n_fem = is_mpm.iter().filter(|m| !**m).count();
    // The `mpm` section is checked (once) where the first MPM body needs it.
    let mut grid: Option<MpmSpec> = None;
    let bodies = s
        .bodies
        .iter()
        .zip(materials)
        .map(|(b, material)| {
            Ok(match b {
                BodySpec::Mpm(spec) => resolved::Body::Mpm {
                    spec: spec.clone(),
                    material,
                    grid: match &grid {
                        Some(g) => g.clone(),
                        None => grid.insert(mpm_section(s)?).clone(),
                    },
                },
                BodySpec::Fem(spec) => resolved::Body::Fem {
                    spec: spec.clone(),
                    material,
                },
            })
        })
        .collect::<Result<Vec<_>, SimError>>()?;
    let needs_contact = s.method == Method::Bfemp && ((any_mpm && n_fem > 0) || n_fem > 1);
    augury(s)?;
    let pairs = contact(s.contact.as_ref(), &names, &is_mpm, needs_contact)?;
    boundaries(s, any_mpm)?;
    if s.method == Method::Augury && any_mpm {
        return Err(invalid(
            "method",
            "`augury` simulates FEM bodies only; MPM bodies need `bfemp`",
        ));
    }
    Ok(Resolved { bodies, pairs })
}

/// The method-specific sections: `augury` only with the augury method, `contact` only with BFEMP.
fn augury(s: &SceneSpec) -> Result<(), SimError> {
    match s.method {
        Method::Bfemp => {
            if s.augury.is_some() {
                return Err(invalid(
                    "augury",
                    "settings of the `augury` method, but the scene's method is `bfemp`",
                ));
            }
            Ok(())
        }
        Method::Augury => {
            if s.contact.is_some() {
                return Err(invalid(
                    "contact",
                    "barrier contact settings belong to `bfemp`; the augury method's contact settings are in `augury`",
                ));
            }
            let Some(a) = &s.augury else {
                return Ok(());
            };
            match (a.grid_spacing, a.grid_ratio) {
                (Some(_), Some(_)) => {
                    return Err(invalid(
                        "augury",
                        "give `grid_spacing` or `grid_ratio`, not both",
                    ));
                }
                (Some(h), None) => positive("augury.grid_spacing", h)?,
                (None, Some(r)) => positive("augury.grid_ratio", r)?,
                (None, None) => {}
            }
            if let Some(t) = a.tau {
                positive("augury.tau", t)?;
            }
            if let Some(l) = a.penetration_limit {
                positive("augury.penetration_limit", l)?;
            }
            if a.iterations > MAX_AUGURY_ITERATIONS {
                return Err(invalid(
                    "augury.iterations",
                    format!("{} is more than {MAX_AUGURY_ITERATIONS}", a.iterations),
                ));
            }
            if a.iterations == 0 && a.model != AuguryModelSpec::Sticky {
                return Err(invalid(
                    "augury.iterations",
                    "must be at least 1 (or use `\"model\": \"sticky\"`)",
                ));
            }
            if !(a.friction >= 0.0 && a.friction.is_finite()) {
                return Err(invalid(
                    "augury.friction",
                    format!("{} must be non-negative", a.friction),
                ));
            }
            if a.friction > 0.0 && a.model != AuguryModelSpec::Friction {
                return Err(invalid(
                    "augury.friction",
                    "a friction coefficient needs `\"model\": \"friction\"`",
                ));
            }
            match (&a.penalty, a.contact) {
                (Some(p), AuguryContactSpec::Penalty) => {
                    positive("augury.penalty.stiffness", p.stiffness)?;
                    positive("augury.penalty.band", p.band)?;
                }
                (None, AuguryContactSpec::Penalty) => {
                    return Err(invalid(
                        "augury.penalty",
                        "`\"contact\": \"penalty\"` needs `penalty` (stiffness, band)",
                    ));
                }
                (Some(_), _) => {
                    return Err(invalid(
                        "augury.penalty",
                        "penalty settings, but `contact` is not `penalty`",
                    ));
                }
                (None, _) => {}
            }
            Ok(())
        }
    }
}
