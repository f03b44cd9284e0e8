//! The integration tests of `femp-augury`, one module per topic, in one test binary: every
//! separate binary would link the crate and instantiate its generic code again, which
//! was a third of the release test build (`cargo test --workspace --release`).

mod affine;
mod blocks;
mod conservation;
mod ramp;
mod two_particle;
