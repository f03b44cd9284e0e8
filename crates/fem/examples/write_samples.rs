//! Write one mesh in every format femp produces (MSH 2.2, MSH 4.1, VTU ASCII and binary) into a
//! directory, for checking with other tools:
//! `cargo run -p femp-fem --example write_samples -- DIR && python3 fixtures/meshes/check_with_meshio.py DIR`.

use femp_fem::mesh::generate;
use femp_fem::mesh::gmsh::{write_msh22, write_msh41};
use femp_fem::mesh::vtk::{Encoding, Field, Vtu};
use nalgebra::{Vector2, Vector3};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "samples".into()));
    std::fs::create_dir_all(&dir)?;
    let m2 = generate::disk(Vector2::zeros(), 1.0, 6)?;
    let m3 = generate::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.5, 0.25), 4, 2, 1)?;
    write_msh22(&dir.join("disk_v22.msh"), &m2)?;
    write_msh41(&dir.join("disk_v41.msh"), &m2)?;
    write_msh22(&dir.join("box_v22.msh"), &m3)?;
    write_msh41(&dir.join("box_v41.msh"), &m3)?;
    let disp: Vec<_> = m3.vertices().iter().map(|v| v * 0.1).collect();
    for (name, enc) in [
        ("box_ascii.vtu", Encoding::Ascii),
        ("box_binary.vtu", Encoding::Binary),
    ] {
        Vtu::from_mesh(&m3, m3.vertices())
            .with_point_field(Field::vector("displacement", &disp))
            .with_cell_field(Field::scalar("det_F", vec![1.0; m3.num_cells()]))
            .write(&dir.join(name), enc)?;
    }
    println!(
        "{} vertices / {} triangles (disk), {} vertices / {} tetrahedra (box) -> {}",
        m2.num_vertices(),
        m2.num_cells(),
        m3.num_vertices(),
        m3.num_cells(),
        dir.display()
    );
    Ok(())
}
