//! Errors.

/// What can go wrong in augury contact.
#[derive(Debug, thiserror::Error)]
pub enum AuguryError {
    /// A parameter is out of range.
    #[error("{name} = {value}: {requirement}")]
    BadParameter {
        /// Parameter.
        name: &'static str,
        /// Value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// Slices of mismatched length.
    #[error("{what}: expected {expected} entries, got {got}")]
    Length {
        /// Which input.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// An error of femp-fem (mesh, material, forces).
    #[error("{0}")]
    Fem(String),
    /// An error of the grid and transfer kernels.
    #[error(transparent)]
    Kernel(#[from] femp_kernels::KernelError),
}

pub(crate) fn check_len(
    what: &'static str,
    expected: usize,
    got: usize,
) -> Result<(), AuguryError> {
    if expected == got {
        Ok(())
    } else {
        Err(AuguryError::Length {
            what,
            expected,
            got,
        })
    }
}
