//! The error type of `femp-kernels`: bad input, named by what and where.

/// What went wrong in a grid or transfer call. Every variant names the offending value and, for
/// particle data, the particle index, so a caller can report it without re-scanning its data.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KernelError {
    /// The grid spacing must be a positive finite number.
    #[error("grid spacing h = {h} must be positive and finite")]
    BadSpacing {
        /// The rejected spacing.
        h: f64,
    },
    /// The grid origin must be finite.
    #[error("grid origin component {axis} = {value} is not finite")]
    BadOrigin {
        /// Axis of the offending component.
        axis: usize,
        /// The rejected value.
        value: f64,
    },
    /// A particle quantity is NaN or infinite.
    #[error("particle {particle}: {quantity} is not finite ({value})")]
    NonFinite {
        /// Index of the particle in the caller's arrays.
        particle: usize,
        /// Which quantity (`"position"`, `"velocity"`, `"B"`, `"mass"`, …).
        quantity: &'static str,
        /// The first offending component.
        value: f64,
    },
    /// A particle has a negative mass.
    #[error("particle {particle}: mass {mass} is negative")]
    NegativeMass {
        /// Index of the particle.
        particle: usize,
        /// The rejected mass.
        mass: f64,
    },
    /// A particle lies outside the range of node indices the grid can address.
    #[error(
        "particle {particle}: position component {axis} = {value} is {cells:.3e} cells from the grid origin; \
         the grid addresses at most ±{limit} cells per axis (move the origin or enlarge h)"
    )]
    OutOfRange {
        /// Index of the particle.
        particle: usize,
        /// Axis of the offending coordinate.
        axis: usize,
        /// The coordinate.
        value: f64,
        /// Its distance from the origin in cells.
        cells: f64,
        /// The addressable half-range in cells.
        limit: i64,
    },
    /// Two arrays that must have the same length do not.
    #[error("{what}: expected length {expected}, got {got}")]
    LengthMismatch {
        /// Which argument.
        what: &'static str,
        /// The length it must have.
        expected: usize,
        /// The length it has.
        got: usize,
    },
    /// A parameter outside its valid range.
    #[error("{what} = {value} is out of range ({valid})")]
    BadParameter {
        /// Which parameter.
        what: &'static str,
        /// The rejected value.
        value: f64,
        /// The valid range, in words.
        valid: &'static str,
    },
}

/// Check that `got == expected`, naming the argument otherwise.
pub(crate) fn check_len(
    what: &'static str,
    expected: usize,
    got: usize,
) -> Result<(), KernelError> {
    if expected == got {
        Ok(())
    } else {
        Err(KernelError::LengthMismatch {
            what,
            expected,
            got,
        })
    }
}
