//! The integration tests of `femp`, one module per topic, in one test binary: every
//! separate binary would link the crate and instantiate its generic code again, which
//! was a third of the release test build (`cargo test --workspace --release`).

mod augury;
mod bad_input;
mod bfemp;
mod checkpoint;
mod cli;
mod fixtures;
mod fuzz;
mod pictures;
mod resolved;
mod sampling;
mod stabilized;
mod steer;
mod trust;
mod tunnelling;

/// Every allocation of these tests counts against a cap: one that would take the live total
/// past it aborts the test binary (as an out-of-memory kill would) instead of swapping the
/// machine. The fuzz harness relies on it to show that no scene, however mutated, allocates
/// without bound.
#[global_allocator]
static ALLOC: fuzz::CappedAlloc = fuzz::CappedAlloc::new(8 << 30);
