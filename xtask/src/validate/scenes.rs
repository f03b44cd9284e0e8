//! Building blocks of the experiments' scenes, as typed `femp::scene` values: field names and
//! types are checked by the compiler, and every scene still goes through `femp`'s own parser
//! and validation on its way to a run (`Ctx::scene`).

use anyhow::{Context, Result};
use femp::scene::{
    AuguryContactSpec, AugurySpec, BodySpec, BoundaryCondition, BoundaryShape, BoundarySpec,
    ContactSpec, FemBody, MaterialSpec, MeshSpec, ModelSpec, MotionSegment, MpmBody, MpmSpec,
    PenaltySpec, PrescribedSpec, SceneSpec, ShapeSpec, VertexSelector,
};

/// The name a scene file gives a setting (`TransferSpec::Apic` → `apic`), for run labels: one
/// spelling, the format's.
pub fn name_of(setting: &impl serde::Serialize) -> String {
    match serde_json::to_value(setting) {
        Ok(serde_json::Value::String(s)) => s,
        other => format!("{other:?}"),
    }
}

/// An MPM body filling `shape` with `ppc` particles per cell.
pub fn mpm(name: &str, shape: ShapeSpec, ppc: usize, material: MaterialSpec) -> MpmBody {
    MpmBody {
        particles_per_cell: Some(ppc),
        ..MpmBody::new(name, shape, material)
    }
}

/// An axis-aligned box of particles.
pub fn particle_box(min: &[f64], max: &[f64]) -> ShapeSpec {
    ShapeSpec::Box {
        min: min.to_vec(),
        max: max.to_vec(),
        transform: None,
    }
}

/// A structured rectangle mesh of `cells` cells.
pub fn rectangle(min: [f64; 2], max: [f64; 2], cells: [usize; 2]) -> MeshSpec {
    MeshSpec::Rectangle {
        min: min.to_vec(),
        max: max.to_vec(),
        cells: cells.to_vec(),
    }
}

/// A small-strain linear elastic material.
pub fn linear(e: f64, nu: f64, rho: f64) -> MaterialSpec {
    MaterialSpec {
        model: ModelSpec::Linear,
        ..MaterialSpec::new(e, nu, rho)
    }
}

/// `body` with every vertex moved by `motion` (none: held where it is).
pub fn prescribed(mut body: FemBody, motion: Vec<MotionSegment>) -> FemBody {
    body.prescribed = vec![PrescribedSpec {
        vertices: VertexSelector::All,
        motion,
    }];
    body
}

/// Moving at `velocity` until `until`.
pub fn moving(until: f64, velocity: &[f64]) -> MotionSegment {
    MotionSegment {
        velocity: Some(velocity.to_vec()),
        ..MotionSegment::until(until)
    }
}

/// A level-set half-space: solid behind the plane through `point` with `normal`.
pub fn half_plane(point: &[f64], normal: &[f64], condition: BoundaryCondition) -> BoundarySpec {
    BoundarySpec {
        shape: BoundaryShape::HalfPlane {
            point: point.to_vec(),
            normal: normal.to_vec(),
        },
        condition,
        motion: Vec::new(),
    }
}

/// Bodies of a scene.
pub fn bodies(
    mpm: impl IntoIterator<Item = MpmBody>,
    fem: impl IntoIterator<Item = FemBody>,
) -> Vec<BodySpec> {
    mpm.into_iter()
        .map(BodySpec::Mpm)
        .chain(fem.into_iter().map(BodySpec::Fem))
        .collect()
}

/// The search-based penalty baseline instead of augury contact: `stiffness` per unit
/// penetration, vertices up to `band` behind a facet pushed out.
pub fn penalty(stiffness: f64, band: f64) -> AugurySpec {
    AugurySpec {
        contact: AuguryContactSpec::Penalty,
        penalty: Some(PenaltySpec { stiffness, band }),
        ..AugurySpec::default()
    }
}

/// Set the cell counts of `body`'s box mesh.
pub fn cuboid_cells(body: &mut FemBody, n: [usize; 3]) -> Result<()> {
    match &mut body.mesh {
        MeshSpec::Cuboid { cells, .. } => {
            *cells = n.to_vec();
            Ok(())
        }
        other => anyhow::bail!("`{}` is not a cuboid mesh: {other:?}", body.name),
    }
}

/// The MPM body named `name` in `spec`.
pub fn mpm_body<'s>(spec: &'s mut SceneSpec, name: &str) -> Result<&'s mut MpmBody> {
    spec.bodies
        .iter_mut()
        .find_map(|b| match b {
            BodySpec::Mpm(b) if b.name == name => Some(b),
            _ => None,
        })
        .with_context(|| format!("the scene has no MPM body `{name}`"))
}

/// The FEM body named `name` in `spec`.
pub fn fem_body<'s>(spec: &'s mut SceneSpec, name: &str) -> Result<&'s mut FemBody> {
    spec.bodies
        .iter_mut()
        .find_map(|b| match b {
            BodySpec::Fem(b) if b.name == name => Some(b),
            _ => None,
        })
        .with_context(|| format!("the scene has no FEM body `{name}`"))
}

/// The contact settings of `spec`.
pub fn contact(spec: &mut SceneSpec) -> Result<&mut ContactSpec> {
    spec.contact
        .as_mut()
        .context("the scene has no `contact` settings")
}

/// The MPM grid settings of `spec`.
pub fn mpm_grid(spec: &mut SceneSpec) -> Result<&mut MpmSpec> {
    spec.mpm.as_mut().context("the scene has no `mpm` settings")
}
