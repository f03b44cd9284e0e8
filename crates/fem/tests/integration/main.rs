//! The integration tests of `femp-fem`, one module per topic, in one test binary: every
//! separate binary would link the crate and instantiate its generic code again, which
//! was a third of the release test build (`cargo test --workspace --release`).

mod elasticity;
mod energy_roundoff;
mod linalg;
mod materials;
mod mesh;
