//! The error type of `femp-contact`.

/// Bad input and contact failures. Penetrations are reported with the particle and facet.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ContactError {
    /// A parameter out of range (`dhat`, `kappa`, `mu`, `eps_v`, `dt`).
    #[error("{what} = {value}: {requirement}")]
    BadParameter {
        /// Parameter name.
        what: &'static str,
        /// Rejected value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// A boundary facet is malformed.
    #[error("boundary facet {facet} {reason}")]
    BadFacet {
        /// Facet index.
        facet: usize,
        /// What is wrong.
        reason: String,
    },
    /// A particle touches or crossed the boundary.
    #[error(
        "particle {particle} is at distance {distance:e} from boundary facet {facet} (penetration)"
    )]
    Penetration {
        /// Particle index.
        particle: usize,
        /// Facet index.
        facet: usize,
        /// Its distance (0 when touching).
        distance: f64,
    },
    /// A position is NaN or infinite.
    #[error("{what} {index} is not finite")]
    NonFinite {
        /// Which array.
        what: &'static str,
        /// Index in it.
        index: usize,
    },
    /// Two arrays that must match in length do not.
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
