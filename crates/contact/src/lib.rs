//! # femp-contact
//!
//! Contact between particles (MPM material points, or FEM boundary vertices) and the boundary
//! of a mesh — segments in 2D, triangles in 3D — as BFEMP needs it (§4–5, eqs. 26–38):
//!
//! * [`distance`] — squared point–point, point–edge (2D/3D) and point–triangle (3D) distances
//!   with gradients and Hessians by explicit closest-feature region;
//! * [`LogBarrier`] — `b(d) = −κ (d/d̂ − 1)² ln(d/d̂)` (eq. 27) and its derivatives;
//! * [`ContactPotential`] — the particle–boundary potential with the duplicate-removal terms
//!   of eqs. 31–32: active terms, energy, gradients and PSD-projected Hessians per stencil
//!   (returned as per-point blocks so MPM can chain them to grid nodes, eq. 29);
//! * [`friction`] — lagged smoothed Coulomb friction (eqs. 34–37) with the units derivation;
//! * [`ccd`] — conservative continuous collision detection and the line search's largest
//!   feasible step;
//! * [`broad_phase`] — candidate particle–facet pairs, now and over a step;
//! * [`single`] — one point against one edge or triangle in one call (potential, gradient,
//!   exact or projected Hessian), for users with their own contact set. The barrier acts on the
//!   distance `d` (eq. 27), not on `d²` as the IPC Toolkit's does: κ and d̂ do not carry over
//!   unchanged.
//!
//! ```
//! use femp_contact::{BoundaryTopology, ContactPotential, LogBarrier, broad_phase, particle_weight};
//! use nalgebra::Vector2;
//!
//! // A floor segment from (-1, 0) to (1, 0) and one particle 1 mm above it.
//! let boundary = vec![Vector2::new(-1.0, 0.0), Vector2::new(1.0, 0.0)];
//! let topo = BoundaryTopology::<2>::new(&[[0, 1, 0]], 2).unwrap();
//! let pot = ContactPotential::new(LogBarrier::new(0.01, 1e4).unwrap(), topo);
//! let particles = vec![Vector2::new(0.2, 0.001)];
//! let weights = vec![particle_weight::<2>(1e-4)];
//! let mut cands = broad_phase::Candidates::default();
//! broad_phase::candidates_within(&particles, &boundary, pot.topology.facets(), 0.01, &mut cands);
//! let mut terms = Vec::new();
//! pot.collect_terms(&particles, &weights, &boundary, &cands, &mut terms).unwrap();
//! assert_eq!(terms.len(), 1);
//! assert!(pot.energy(&terms) > 0.0);
//! ```

mod barrier;

/// Terms per chunk of the energies' parallel sums: each chunk is summed in order and the chunk
/// sums in order, so an energy has the same bits on any number of threads.
pub(crate) const SUM_CHUNK: usize = 1024;
pub mod assembly;
pub mod broad_phase;
pub mod ccd;
pub mod distance;
mod error;
pub mod friction;
pub mod intersect;
mod potential;
pub mod single;

pub use barrier::LogBarrier;
pub use error::ContactError;
pub use potential::{
    BarrierHessian, BoundaryTopology, ContactPotential, ContactTerm, Feature, TermDerivatives,
    particle_weight, project_psd,
};

pub(crate) fn check_len(
    what: &'static str,
    expected: usize,
    got: usize,
) -> Result<(), ContactError> {
    if expected == got {
        Ok(())
    } else {
        Err(ContactError::LengthMismatch {
            what,
            expected,
            got,
        })
    }
}
