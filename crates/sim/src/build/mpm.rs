//! An MPM body's particles from its scene spec, on the grid all MPM bodies share.

use std::path::Path;

use femp_contact::particle_weight;
use femp_fem::Material;
use femp_kernels::{Grid, Kernel};
use nalgebra::{SMatrix, SVector};

use super::{rigid_velocity, sample_shape};
use crate::bodies::{Mpm, MpmBody, Transfer};
use crate::error::{SimError, invalid};
use crate::motion::angular_components;
use crate::scene::spec::{MpmBody as MpmBodySpec, MpmSpec, TransferSpec};

/// The MPM state of the scene's `mpm` section: its grid and transfer, no particles yet.
pub(crate) fn empty<const D: usize>(m: &MpmSpec) -> Result<Mpm<D>, SimError> {
    let grid = Grid::new(m.grid_spacing, SVector::zeros(), Kernel::Quadratic)
        .map_err(|e| invalid("mpm.grid_spacing", e.to_string()))?;
    let stencils = grid
        .stencils(&[])
        .map_err(|e| invalid("mpm.grid_spacing", e.to_string()))?;
    Ok(Mpm {
        stencils,
        grid,
        transfer: match m.transfer {
            TransferSpec::Apic => Transfer::Apic,
            TransferSpec::Pic => Transfer::Pic,
            TransferSpec::Flip => Transfer::Flip(m.flip_ratio),
        },
        x: Vec::new(),
        v: Vec::new(),
        b: Vec::new(),
        f: Vec::new(),
        a: Vec::new(),
        mass: Vec::new(),
        volume: Vec::new(),
        weight: Vec::new(),
        body: Vec::new(),
        bodies: Vec::new(),
        contact_force: Vec::new(),
    })
}

/// Sample `body` of material `material_m` (field path `f`, files relative to `base_dir`) into
/// `state`'s particles at rest shape, with its rigid initial velocity; its index among
/// `state`'s bodies.
pub(crate) fn add_body<const D: usize>(
    state: &mut Mpm<D>,
    (body, material_m): (&MpmBodySpec, Material),
    grid_spacing: f64,
    base_dir: &Path,
    f: &str,
) -> Result<usize, SimError> {
    let MpmBodySpec {
        name,
        shape,
        particles_per_cell,
        material,
        velocity,
        angular_velocity,
    } = body;
    let ppc = particles_per_cell.unwrap_or(if D == 2 { 4 } else { 8 });
    let per_axis = (ppc as f64).powf(1.0 / D as f64).round() as usize;
    let samples = sample_shape::<D>(
        shape,
        grid_spacing,
        per_axis,
        base_dir,
        &format!("{f}.shape"),
    )?;
    let start = state.x.len();
    let n = samples.x.len();
    let total_mass: f64 = samples.volume.iter().sum::<f64>() * material.rho;
    let com: SVector<f64, D> = samples
        .x
        .iter()
        .zip(&samples.volume)
        .map(|(x, v)| x * (v * material.rho))
        .sum::<SVector<f64, D>>()
        / total_mass;
    let v0 = velocity
        .as_deref()
        .map_or_else(SVector::zeros, SVector::from_column_slice);
    let w = angular_components(angular_velocity, D);
    let dp = grid_spacing * grid_spacing * 0.25;
    let l = {
        // Velocity gradient of the rigid rotation, for B = L D_p.
        let mut l = SMatrix::<f64, D, D>::zeros();
        for a in 0..D {
            let mut ea = SVector::<f64, D>::zeros();
            ea[a] = 1.0;
            let col = rigid_velocity(&SVector::zeros(), &w, &ea, &SVector::zeros());
            l.set_column(a, &col);
        }
        l
    };
    for k in 0..n {
        let x = samples.x[k];
        state.x.push(x);
        state.v.push(rigid_velocity(&v0, &w, &x, &com));
        state.b.push(l * dp);
        state.f.push(SMatrix::identity());
        state.a.push(SVector::zeros());
        state.mass.push(samples.volume[k] * material.rho);
        state.volume.push(samples.volume[k]);
        state.weight.push(particle_weight::<D>(samples.volume[k]));
        state.body.push(state.bodies.len() as u16);
        state.contact_force.push(SVector::zeros());
    }
    let k = state.bodies.len();
    state.bodies.push(MpmBody {
        name: name.clone(),
        material: material_m,
        range: (start, start + n),
    });
    Ok(k)
}
