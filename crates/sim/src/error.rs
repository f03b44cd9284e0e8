//! Errors of scene loading and simulation runs.

use std::path::PathBuf;

/// The lock file that keeps two runs out of one output directory (`crate::io::output`).
pub const LOCK_FILE: &str = ".femp.lock";

/// Everything that can go wrong, named by what and where.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The scene is not valid JSON or does not match the format (unknown field, wrong type).
    #[error("{file}: {field}: {message}")]
    SceneFormat {
        /// Scene file.
        file: String,
        /// Field path (`bodies[1].material.nu`), or `(root)`.
        field: String,
        /// What serde reported (with line and column).
        message: String,
    },
    /// A value in the scene is out of range or inconsistent.
    #[error("{field}: {message}")]
    Invalid {
        /// Field path.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// The initial state violates the non-overlap assumption (BFEMP eq. 15).
    #[error("bodies `{a}` and `{b}` start overlapping: {detail}")]
    Overlap {
        /// First body.
        a: String,
        /// Second body.
        b: String,
        /// The worst offender.
        detail: String,
    },
    /// A time step failed (Newton, line search, friction, a blow-up).
    #[error("step {step} (t = {time:.6e} s) failed: {message}")]
    StepFailed {
        /// Step index.
        step: usize,
        /// Simulated time at the start of the step.
        time: f64,
        /// What happened.
        message: String,
    },
    /// The run was stopped from outside (Ctrl-C) after `step` steps.
    #[error("interrupted after step {step} (t = {time:.6e} s)")]
    Interrupted {
        /// Steps completed.
        step: usize,
        /// Simulated time reached.
        time: f64,
    },
    /// The code driving a world stopped its run (a Python loop that raised, say).
    #[error(
        "stopped after step {step} (t = {time:.6e} s) by the code driving the world: {message}"
    )]
    Stopped {
        /// Steps completed.
        step: usize,
        /// Simulated time reached.
        time: f64,
        /// Why.
        message: String,
    },
    /// A checkpoint that cannot be written, read or resumed from (`what`: its file, or
    /// `checkpoint`).
    #[error("{what}: {message}")]
    Checkpoint {
        /// The checkpoint file (or `checkpoint`).
        what: String,
        /// What is wrong.
        message: String,
    },
    /// Another run holds the output directory's lock.
    #[error(
        "{}: another femp run is writing into this directory (it holds {}); wait for it to end or choose another --out",
        dir.display(),
        LOCK_FILE
    )]
    OutputBusy {
        /// The output directory.
        dir: PathBuf,
    },
    /// The output directory holds an earlier run's outputs.
    #[error(
        "{}: holds the outputs of an earlier run ({found}); pass --overwrite to replace them, or choose another --out",
        dir.display()
    )]
    StaleOutput {
        /// The output directory.
        dir: PathBuf,
        /// What was found.
        found: String,
    },
    /// A symbolic link inside the output directory where the run would write.
    #[error(
        "{}: a symbolic link where the run writes ({count} in --out): femp writes regular files inside --out and does not follow links out of it; remove {}",
        path.display(),
        if *count == 1 { "it" } else { "them" }
    )]
    OutputLink {
        /// The first link.
        path: PathBuf,
        /// How many there are.
        count: usize,
    },
    /// The scene would need more than the limits allow (memory, steps).
    #[error("{field}: {message}")]
    TooLarge {
        /// The field that sets the size.
        field: String,
        /// The estimate, the limit and how to change either.
        message: String,
    },
    /// A state, load or parameter set on a world from outside ([`crate::World::set_particle_positions`]
    /// and the rest of `crate::steer`) that the world refuses: a wrong shape, a non-finite
    /// value, a body put into another, an inverted element, a vertex the scene already moves.
    /// The world is unchanged.
    #[error("{what}: {message}")]
    State {
        /// What was set (`particles.x`, `fem[plate].v`, …).
        what: String,
        /// Why it was refused.
        message: String,
    },
    /// An error from a library crate while building the world.
    #[error("{context}: {message}")]
    Build {
        /// Where.
        context: String,
        /// The library's message.
        message: String,
    },
}

/// Shorthand for an `Invalid` error.
pub(crate) fn invalid(field: impl Into<String>, message: impl Into<String>) -> SimError {
    SimError::Invalid {
        field: field.into(),
        message: message.into(),
    }
}
