//! Where a world is in time.

/// Simulated time, steps taken and the time step: what a step advances besides the bodies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clock {
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken.
    pub step: usize,
    /// Time step Δt (s).
    pub dt: f64,
}
