//! The scene the speed of augury contact is measured on, against the search-based penalty
//! baseline: two thin plates facing each other half a mesh size apart, every vertex a boundary
//! vertex (so contact is as large a part of a step as it can be), in 2D or 3D, at any number of
//! boundary nodes. Used by `cargo bench -p femp-augury --bench step` and the validation suite's
//! `augury_speed` experiment; [`time_step`] times one step from a fixed state, so every timed
//! step is the same step.

use femp_fem::mesh::generate::{cuboid, rectangle};
use femp_fem::{Material, Mesh, NeoHookean};
use femp_kernels::Kernel;
use nalgebra::{SVector, Vector2, Vector3};

use crate::explicit::{
    ExplicitBody, ExplicitParams, ExplicitState, ExplicitSystem, PenaltyContact, StepTiming,
};
use crate::{AuguryContact, AuguryError, AuguryParams, ContactModel, Transfer, TransferKind};

/// Young's modulus of the plates (Pa); Poisson's ratio 0.3, density 1000 kg/m³.
pub const YOUNG: f64 = 1e6;

/// How the plates of [`facing_plates`] touch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlatesContact {
    /// APIC augury contact: one friction iteration (μ = 0.3), grid spacing twice the mesh
    /// size, τ = Δt.
    Augury,
    /// The node-to-surface penalty baseline ([`PenaltyContact`]): stiffness E, band one mesh
    /// size.
    Penalty,
}

/// Two plates facing each other with about `boundary_nodes` vertices in all, every one on the
/// boundary — 2D: strips of `n × 1` squares (`2(n + 1)` vertices each); 3D: plates of
/// `k × 1 × k` cubes (`2(k + 1)²` vertices each) — the upper one 1.5 mesh sizes above the
/// lower (a gap of half a mesh size), at rest, no gravity, Δt a quarter of the explicit
/// stability estimate. Returns the system after its first step (so the accelerations are set)
/// and its number of boundary nodes.
pub fn facing_plates<const D: usize>(
    boundary_nodes: usize,
    contact: PlatesContact,
) -> Result<(ExplicitSystem<D>, usize), AuguryError> {
    assert!(D == 2 || D == 3, "2D or 3D");
    let (bodies, h) = plates::<D>(boundary_nodes)?;
    let nb: usize = bodies.iter().map(|b| b.boundary.len()).sum();
    let (mu, lambda) = (YOUNG / 2.6, YOUNG * 0.3 / (1.3 * 0.4));
    let probe = ExplicitSystem::new(
        bodies,
        ExplicitParams {
            dt: 1.0,
            gravity: SVector::zeros(),
        },
        None,
    );
    // A quarter of the stability estimate, so that round-off cannot grow over many steps.
    let dt = probe.stable_dt(&[(mu, lambda, 1000.0); 2], 0.25);
    let params = ExplicitParams {
        dt,
        gravity: SVector::zeros(),
    };
    let mut sys = match contact {
        PlatesContact::Augury => {
            let t = Transfer::<D>::new(2.0 * h, Kernel::Quadratic, TransferKind::Apic)?;
            let aug = AuguryContact::new(
                t,
                AuguryParams {
                    tau: dt,
                    iterations: 1,
                    model: ContactModel::Friction(0.3),
                },
            )?;
            ExplicitSystem::new(probe.bodies, params, Some(aug))
        }
        PlatesContact::Penalty => {
            let mut s = ExplicitSystem::new(probe.bodies, params, None);
            s.penalty = Some(PenaltyContact::new(YOUNG, h)?);
            s
        }
    };
    sys.step()?;
    Ok((sys, nb))
}

fn plates<const D: usize>(
    boundary_nodes: usize,
) -> Result<(Vec<ExplicitBody<D>>, f64), AuguryError> {
    let fem = |e: femp_fem::FemError| AuguryError::Fem(e.to_string());
    let (lower, upper, h) = if D == 2 {
        let n = (boundary_nodes / 4).max(2);
        let h = 1.0 / n as f64;
        let strip = |y0: f64| {
            rectangle(Vector2::new(0.0, y0), Vector2::new(1.0, y0 + h), n, 1)
                .map_err(fem)
                .and_then(lift::<2, D>)
        };
        (strip(0.0)?, strip(1.5 * h)?, h)
    } else {
        let k = (((boundary_nodes / 4) as f64).sqrt() as usize).max(2);
        let h = 1.0 / k as f64;
        let plate = |y0: f64| {
            cuboid(
                Vector3::new(0.0, y0, 0.0),
                Vector3::new(1.0, y0 + h, 1.0),
                k,
                1,
                k,
            )
            .map_err(fem)
            .and_then(lift::<3, D>)
        };
        (plate(0.0)?, plate(1.5 * h)?, h)
    };
    let mat = Material::NeoHookean(NeoHookean::from_young_poisson(YOUNG, 0.3).map_err(fem)?);
    Ok((
        vec![
            ExplicitBody::new("lower", &lower, mat, 1000.0)?,
            ExplicitBody::new("upper", &upper, mat, 1000.0)?,
        ],
        h,
    ))
}

/// A mesh generated in `A` dimensions as a `Mesh<D>` (`A = D`: the same mesh).
fn lift<const A: usize, const D: usize>(m: Mesh<A>) -> Result<Mesh<D>, AuguryError> {
    let v = m
        .vertices()
        .iter()
        .map(|p| SVector::<f64, D>::from_fn(|a, _| p[a]))
        .collect();
    Mesh::new(v, m.cells().to_vec()).map_err(|e| AuguryError::Fem(e.to_string()))
}

/// One step of `sys` from `state` (restored first, not timed): where its time went. Every call
/// times the same step, so repeated calls can be compared and a fixed state cannot drift.
pub fn time_step<const D: usize>(
    sys: &mut ExplicitSystem<D>,
    state: &ExplicitState<D>,
) -> Result<StepTiming, AuguryError> {
    sys.set_state(state);
    sys.step()?;
    Ok(sys.timing)
}
