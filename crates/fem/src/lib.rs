//! # femp-fem
//!
//! Linear simplex finite elements (triangles in 2D, tetrahedra in 3D) for the FEM bodies of
//! femp, and the material models shared with MPM particles. One source for `D = 2` and `3`.
//!
//! * [`Mesh`] with [`generate`](mesh::generate)d shapes, Gmsh input ([`mesh::gmsh`]) and VTK
//!   output ([`mesh::vtk`]).
//! * [`Element`]: rest shape, `F = T B⁻¹` (BFEMP eq. 24) as the linear map `F = Σ x_i g_iᵀ`;
//!   [`lumped_masses`].
//! * [`material`]: [`NeoHookean`] (eq. 7) and [`LinearElastic`], each with `ψ`, `P`, `∂P/∂F`
//!   and a PSD projection of `∂P/∂F` ([`Hyperelastic`]); they take `F` and know nothing of
//!   meshes, so MPM particles use them too.
//! * [`chain_gradient`] / [`chain_hessian`]: from `P` and `∂P/∂F` to vertex (or grid-node)
//!   gradients and Hessian blocks, for any linear map `F = Σ x_i g_iᵀ`.
//! * [`ElasticBody`]: parallel assembly of energy, gradient and PSD Hessian triplets.
//! * [`inversion`]: the largest step keeping `det F > 0` (BFEMP §5).
//! * [`Boundary`]: outward facets, η incidence counts (eqs. 31–32), vertex normals.
//!
//! ```
//! use femp_fem::{ElasticBody, NeoHookean, mesh::generate};
//! use nalgebra::Vector2;
//!
//! let mesh = generate::rectangle(Vector2::zeros(), Vector2::new(2.0, 1.0), 4, 2).unwrap();
//! let mut body = ElasticBody::new(&mesh, NeoHookean::from_young_poisson(1e5, 0.3).unwrap()).unwrap();
//! let x: Vec<_> = mesh.vertices().iter().map(|v| v * 1.01).collect(); // 1 % stretch
//! assert!(body.energy(&x).unwrap() > 0.0);
//! let mut g = vec![Vector2::zeros(); x.len()];
//! body.add_gradient(&x, 1.0, &mut g).unwrap();
//! let net: Vector2<f64> = g.iter().sum();
//! assert!(net.norm() < 1e-9); // internal forces balance
//! ```

mod boundary;
mod elasticity;
mod element;
mod error;
pub mod inversion;
pub mod linalg;
pub mod material;
pub mod mesh;
mod tangent;

pub use boundary::Boundary;
pub use elasticity::{ElasticBody, Triplet};
pub use element::{Element, lumped_masses};
pub use error::FemError;
pub use material::{Hyperelastic, Lame, LinearElastic, Material, NeoHookean};
pub use mesh::Mesh;
pub use tangent::{Tangent, chain_gradient, chain_hessian, chain_hessian_add_upper};
