//! A FEM body from its scene spec: mesh (placed by its transform), material, lumped masses,
//! rigid initial velocity, prescribed vertex sets and the boundary contact uses.

use std::path::Path;

use femp_fem::{Boundary, ElasticBody, Material, lumped_masses};
use nalgebra::SVector;

use super::{rigid_velocity, transform_fn};
use crate::bodies::FemBody;
use crate::error::{SimError, invalid};
use crate::motion::{Motion, angular_components};
use crate::scene::VertexSelector;
use crate::scene::mesh::fem_mesh;
use crate::scene::spec::FemBody as FemBodySpec;

/// The FEM body of `body` of material `mat` (field path `f`, files relative to `base_dir`).
pub(crate) fn body<const D: usize>(
    (body, mat): (&FemBodySpec, Material),
    base_dir: &Path,
    f: &str,
) -> Result<FemBody<D>, SimError> {
    let FemBodySpec {
        name,
        mesh,
        transform,
        material,
        velocity,
        angular_velocity,
        prescribed,
    } = body;
    let mut m = fem_mesh::<D>(mesh, base_dir, &format!("{f}.mesh"))?;
    if let Some(t) = transform {
        let tf = transform_fn::<D>(t);
        m = m
            .mapped(tf)
            .map_err(|e| invalid(format!("{f}.transform"), e.to_string()))?;
    }
    let elastic =
        ElasticBody::new(&m, mat).map_err(|e| invalid(format!("{f}.mesh"), e.to_string()))?;
    let masses = lumped_masses(&m, material.rho)
        .map_err(|e| invalid(format!("{f}.material.rho"), e.to_string()))?;
    let x = m.vertices().to_vec();
    let total: f64 = masses.iter().sum();
    let com: SVector<f64, D> = x
        .iter()
        .zip(&masses)
        .map(|(p, mm)| p * *mm)
        .sum::<SVector<f64, D>>()
        / total;
    let v0 = velocity
        .as_deref()
        .map_or_else(SVector::zeros, SVector::from_column_slice);
    let w = angular_components(angular_velocity, D);
    let v: Vec<_> = x.iter().map(|p| rigid_velocity(&v0, &w, p, &com)).collect();
    let mut fixed = vec![false; x.len()];
    let mut sets = Vec::new();
    for (k, p) in prescribed.iter().enumerate() {
        let pf = format!("{f}.prescribed[{k}].vertices");
        let ids: Vec<usize> = match &p.vertices {
            VertexSelector::All => (0..x.len()).collect(),
            VertexSelector::Below { axis, value } => {
                (0..x.len()).filter(|&i| x[i][*axis] < *value).collect()
            }
            VertexSelector::Above { axis, value } => {
                (0..x.len()).filter(|&i| x[i][*axis] > *value).collect()
            }
            VertexSelector::List(l) => {
                if let Some(&bad) = l.iter().find(|&&i| i >= x.len()) {
                    return Err(invalid(
                        pf,
                        format!("vertex {bad} does not exist (the mesh has {})", x.len()),
                    ));
                }
                l.clone()
            }
        };
        if ids.is_empty() {
            return Err(invalid(pf, "selects no vertex"));
        }
        let centroid = ids.iter().map(|&i| x[i]).sum::<SVector<f64, D>>() / ids.len() as f64;
        for &i in &ids {
            fixed[i] = true;
        }
        sets.push((ids, Motion::new(&p.motion, centroid)));
    }
    let fully = fixed.iter().all(|&f| f);
    let boundary = Boundary::of(&m);
    let facets: Vec<[u32; 3]> = boundary
        .facets()
        .iter()
        .map(|f| {
            [
                f[0] as u32,
                f[1] as u32,
                if D == 3 { f[2] as u32 } else { 0 },
            ]
        })
        .collect();
    // Lumped boundary measure per boundary vertex: 1/D of each incident facet.
    let mut vw = vec![0.0; m.num_vertices()];
    for fi in 0..boundary.facets().len() {
        let a = boundary.facet_normal(fi, &x).norm();
        for &vtx in &boundary.facets()[fi][..D] {
            vw[vtx] += a / D as f64;
        }
    }
    let vertex_weight = boundary.vertices().iter().map(|&i| vw[i]).collect();
    Ok(FemBody {
        name: name.clone(),
        elastic,
        material: mat,
        a: vec![SVector::zeros(); x.len()],
        v,
        initial: x.clone(),
        x,
        mass: masses,
        prescribed: sets,
        fixed,
        fully_prescribed: fully,
        boundary,
        edges: crate::overlap::boundary_edges::<D>(&facets),
        facets,
        vertex_weight,
        contact_force: vec![SVector::zeros(); m.num_vertices()],
        mesh: m,
    })
}
