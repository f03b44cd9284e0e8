//! What the parser makes of a checked scene file: the typed values a world is built from, each
//! made once from its section (pair settings merged with the scene's, materials as Lamé
//! parameters, …), so that building a world cannot fail on anything the parser checked.

use femp_contact::friction::FrictionParams;
use femp_contact::{BarrierHessian, LogBarrier};
use femp_fem::Material;

use super::{FemBody, MpmBody, MpmSpec};

/// A contact pair's Coulomb friction: the coefficient μ ≥ 0 and the static-friction velocity
/// threshold ε_v > 0 (m/s). A step's friction parameters add its Δt ([`FrictionLaw::at`]): the
/// mollifier threshold is the displacement ε_v Δt.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrictionLaw {
    /// Coulomb coefficient μ.
    pub mu: f64,
    /// Static-friction velocity threshold ε_v (m/s).
    pub eps_v: f64,
}

impl FrictionLaw {
    /// The friction parameters of a step of length `dt` (s).
    pub fn at(&self, dt: f64) -> FrictionParams {
        FrictionParams {
            mu: self.mu,
            eps_v: self.eps_v,
            dt,
        }
    }
}

/// The typed parts of a scene, made by the parser from the checked sections
/// ([`super::parse`]); a [`super::Scene`] always carries the parts of its own spec.
#[derive(Clone, Debug)]
pub struct Resolved {
    /// The scene's bodies in scene order, each with its material (Lamé parameters from E and
    /// ν) and, for an MPM body, the grid.
    pub bodies: Vec<Body>,
    /// The contact laws of the body pairs that may touch (BFEMP scenes), in scene order of
    /// their first body, then of their second.
    pub pairs: Vec<PairLaw>,
}

/// A scene body with what the parser made of its sections.
#[derive(Clone, Debug)]
pub enum Body {
    /// An MPM body, its material and the scene's `mpm` section (every MPM body has one).
    Mpm {
        /// The body as written.
        spec: MpmBody,
        /// Its material.
        material: Material,
        /// The grid and transfer settings.
        grid: MpmSpec,
    },
    /// A FEM body and its material.
    Fem {
        /// The body as written.
        spec: FemBody,
        /// Its material.
        material: Material,
    },
}

/// The contact law between two scene bodies: the scene's `contact` settings with the pair's
/// own entry in `contact.pairs` (if any) over them.
#[derive(Clone, Debug, PartialEq)]
pub struct PairLaw {
    /// The two bodies' scene indices, the first smaller.
    pub bodies: [usize; 2],
    /// The barrier: d̂ and κ.
    pub barrier: LogBarrier,
    /// How the barrier's Hessian is made positive semi-definite.
    pub hessian: BarrierHessian,
    /// Friction: μ and ε_v.
    pub friction: FrictionLaw,
    /// The scene field d̂ comes from (`contact.dhat` or `contact.pairs[k].dhat`), for errors
    /// about it that need the built bodies.
    pub dhat_field: String,
}
