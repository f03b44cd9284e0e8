//! The integration tests of `femp-contact`, one module per topic, in one test binary: every
//! separate binary would link the crate and instantiate its generic code again, which
//! was a third of the release test build (`cargo test --workspace --release`).

mod adversarial;
mod broad_phase;
mod ccd;
mod derivatives;
mod potential;
mod reference;
mod single;
