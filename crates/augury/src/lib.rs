//! # femp-augury
//!
//! Explicit finite-element dynamics whose boundary nodes interact **only through grid
//! transfers** — the APIC augury contact of the augury paper (the paper whose abstract begins
//! "An efficient and momentum conserving algorithm for enforcing contact between solid bodies
//! is proposed"; the project README says how it is cited), §2: no geometric search, exact
//! linear momentum, and exact angular momentum with APIC.
//!
//! * [`Transfer`] — the operator `H` (particle-to-grid then grid-to-particle, PIC or APIC) on
//!   generalised velocity fields `V = {v, B}` of boundary particles, and `G = H − I`.
//! * [`AuguryContact`] — the contact acceleration correction `Â = (Ĥ − I) V̄ / τ` (eq. 29) with
//!   the separation (eq. 38) or Coulomb friction (eqs. 42–46) iterations (eq. 36–37).
//! * [`explicit`] — explicit central-difference FEM dynamics (eq. 32) of several bodies whose
//!   boundary vertices are the augury particles.
//! * [`explicit::PenaltyContact`] — the search-based baseline: node-to-surface penalty contact
//!   with femp-contact's broad phase, for the efficiency comparison.
//! * [`speed`] — the facing-plates scene augury contact is timed on against the baseline.
//! * [`two_particle`] — the 1D two-particle analysis of §3.1 (eqs. 47–50) as an ODE.
//!
//! Momentum conservation is structural: every term of the correction is `G` applied to some
//! field, and `G` maps every field to one with zero net linear momentum (PIC) and zero net
//! angular momentum (APIC), so the sum has none either — property-tested in
//! `tests/integration/conservation.rs`.

mod contact;
mod error;
pub mod explicit;
mod operator;
pub mod scenes;
pub mod speed;
pub mod two_particle;

pub use contact::{AuguryContact, AuguryParams, ContactModel, CorrectionTiming, undesirable_part};
pub use error::AuguryError;
pub use operator::{Transfer, TransferKind, angular_momentum, linear_momentum};
