//! The error type of `femp-fem`. Input errors name the offending cell, vertex, parameter or file
//! line; numerical failures are kept apart.

use std::path::PathBuf;

/// Errors of mesh construction, mesh I/O, materials and assembly.
#[derive(Debug, thiserror::Error)]
pub enum FemError {
    /// A material parameter is out of its physical range.
    #[error("material parameter {parameter} = {value}: {requirement}")]
    BadMaterial {
        /// Parameter name as in scenes (`E`, `nu`, `mu`, `lambda`, `rho`).
        parameter: &'static str,
        /// The rejected value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// A function argument (a mesh resolution, a radius, …) is out of range.
    #[error("{what} = {value}: {requirement}")]
    BadArgument {
        /// The argument.
        what: &'static str,
        /// The rejected value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// A vertex is unusable.
    #[error("vertex {vertex}: {reason}")]
    BadVertex {
        /// Vertex index.
        vertex: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// A cell references a vertex that does not exist.
    #[error("cell {cell} references vertex {vertex}, but the mesh has {num_vertices} vertices")]
    DanglingVertex {
        /// Cell index.
        cell: usize,
        /// The missing vertex index.
        vertex: usize,
        /// Number of vertices.
        num_vertices: usize,
    },
    /// A cell has (near) zero volume.
    #[error("cell {cell} is degenerate: it {reason} (signed volume {volume:e})")]
    DegenerateCell {
        /// Cell index.
        cell: usize,
        /// Its signed volume (area in 2D).
        volume: f64,
        /// Why it is degenerate.
        reason: &'static str,
    },
    /// A cell is inverted (negative orientation) in the rest configuration.
    #[error(
        "cell {cell} is inverted in the rest configuration (signed volume {volume:e}); \
         list its vertices counter-clockwise (2D) / positively oriented (3D), or build the mesh \
         with Mesh::new_oriented"
    )]
    InvertedCell {
        /// Cell index.
        cell: usize,
        /// Its signed volume.
        volume: f64,
    },
    /// A mesh file is malformed or unsupported.
    #[error("{}:{line}: {message}", path.display())]
    MeshFile {
        /// The file.
        path: PathBuf,
        /// 1-based line number (0 when not applicable, e.g. binary files).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Two arrays that must have the same length do not.
    #[error("{what}: expected length {expected}, got {got}")]
    LengthMismatch {
        /// Which argument.
        what: &'static str,
        /// Required length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
}

pub(crate) fn check_len(what: &'static str, expected: usize, got: usize) -> Result<(), FemError> {
    if expected == got {
        Ok(())
    } else {
        Err(FemError::LengthMismatch {
            what,
            expected,
            got,
        })
    }
}
