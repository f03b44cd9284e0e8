//! A FEM body's mesh from its spec: the generators (rectangle, cuboid, disk, rings, cosine strip)
//! and Gmsh files — what the scene's size estimate and the world's builder both read.

use std::path::Path;

use femp_fem::Mesh;
use femp_fem::mesh::{generate, gmsh};
use nalgebra::{SVector, Vector2, Vector3};

use super::MeshSpec;
use crate::error::SimError;

/// Build a FEM mesh from its spec (before the transform).
pub fn fem_mesh<const D: usize>(
    spec: &MeshSpec,
    base_dir: &Path,
    field: &str,
) -> Result<Mesh<D>, SimError> {
    let err = |e: femp_fem::FemError| SimError::Build {
        context: field.to_string(),
        message: e.to_string(),
    };
    let to_d = |m2: Result<Mesh<2>, femp_fem::FemError>| -> Result<Mesh<D>, SimError> {
        let m2 = m2.map_err(err)?;
        let verts: Vec<SVector<f64, D>> = m2
            .vertices()
            .iter()
            .map(|p| SVector::from_fn(|a, _| p[a]))
            .collect();
        Mesh::new(verts, m2.cells().to_vec()).map_err(err)
    };
    let to_d3 = |m3: Result<Mesh<3>, femp_fem::FemError>| -> Result<Mesh<D>, SimError> {
        let m3 = m3.map_err(err)?;
        let verts: Vec<SVector<f64, D>> = m3
            .vertices()
            .iter()
            .map(|p| SVector::from_fn(|a, _| p[a]))
            .collect();
        Mesh::new(verts, m3.cells().to_vec()).map_err(err)
    };
    let v2 = |a: &[f64]| Vector2::new(a[0], a[1]);
    match spec {
        MeshSpec::Rectangle { min, max, cells } => {
            to_d(generate::rectangle(v2(min), v2(max), cells[0], cells[1]))
        }
        MeshSpec::Cuboid { min, max, cells } => to_d3(generate::cuboid(
            Vector3::new(min[0], min[1], min[2]),
            Vector3::new(max[0], max[1], max[2]),
            cells[0],
            cells[1],
            cells[2],
        )),
        MeshSpec::Disk {
            center,
            radius,
            rings,
        } => to_d(generate::disk(v2(center), *radius, *rings)),
        MeshSpec::Ring {
            center,
            r_in,
            r_out,
            cells,
        } => to_d(generate::ring(
            v2(center),
            *r_in,
            *r_out,
            cells[0],
            cells[1],
        )),
        MeshSpec::SemicircularRing {
            center,
            r_in,
            r_out,
            cells,
        } => to_d(generate::semicircular_ring(
            v2(center),
            *r_in,
            *r_out,
            cells[0],
            cells[1],
        )),
        MeshSpec::CosineStrip {
            amplitude,
            wavelength,
            offset,
            x0,
            x1,
            thickness,
            cells,
        } => {
            let (a, w, o) = (*amplitude, *wavelength, *offset);
            to_d(generate::curve_strip(
                move |x| o + a * (std::f64::consts::TAU * x / w).cos(),
                *x0,
                *x1,
                *thickness,
                cells[0],
                cells[1],
            ))
        }
        MeshSpec::File(f) => gmsh::read_msh_with::<D>(
            &base_dir.join(&f.path),
            gmsh::ReadOptions {
                reorient: f.reorient,
            },
        )
        .map_err(err),
    }
}
