//! # femp
//!
//! Elastic solids that touch: material-point (MPM) and finite-element (FEM) bodies in frictional
//! contact, simulated with **BFEMP** — implicit MPM–FEM coupling through barrier particle–mesh
//! contact (the unknowns are MPM grid-node and FEM vertex positions; one step minimises the
//! incremental potential of eq. 38 by projected Newton with a CCD- and det F-filtered line
//! search, so no particle ever enters a FEM body) — or, for scenes with `"method": "augury"`,
//! FEM bodies stepped explicitly and touching through APIC augury contact (femp-augury).
//!
//! * [`scene`] — the JSON scene format (`docs/scenes.md`), loading with field paths in errors.
//! * [`World`] — the state built from a scene; [`World::step`] is one BFEMP step (Algorithm 1)
//!   or one explicit augury step; [`World::contact_forces`] gives the barrier (reaction) forces.
//! * [`run`](run::run) — a whole run with output (`.vtu`/`.pvd` frames, `metrics.csv`,
//!   `summary.json`) and progress.
//!   [`run::Recorder`] writes the same outputs for a world stepped by any other loop.
//! * [`steer`] — a world steered between steps: positions and velocities set (checked as a
//!   scene's initial state is), external forces and prescribed FEM vertex positions for the next
//!   step, friction and materials changed.
//!
//! Inside: a [`World`] is its bodies ([`world::Bodies`], in `bodies`: MPM particles and grid, FEM
//! bodies, contact pairs, level sets, point-in-body queries), its [`world::Clock`] and its
//! [`world::Stepper`] — one per method, chosen when the world is built (`stepper`): BFEMP's
//! integrator and Newton solvers (the step in `step`, its incremental potential in
//! `objective`), or the augury system (`augury`). Both steps return a [`StepReport`]. Above the
//! simulation, the `io` layer — [`metrics`], [`output`], [`render`] — measures and writes what a
//! run shows; [`run`](run::run) drives it, and nothing below imports it.
//!
//! ```no_run
//! let scene = femp::scene::load(std::path::Path::new("fixtures/scenes/block_on_plate.json"))?;
//! let result = femp::run::run(scene, std::path::Path::new("out"), &Default::default())?;
//! assert_eq!(result.summary.max_penetrations, 0);
//! # Ok::<(), femp::SimError>(())
//! ```

mod augury;
mod bodies;
mod build;
mod clock;
mod error;
mod io;
pub mod motion;
mod objective;
mod overlap;
mod report;
pub mod run;
pub mod scene;
pub mod state;
pub mod steer;
mod step;
mod stepper;
pub mod sweep;
pub mod world;

pub use error::SimError;
/// The solver's per-iteration record and step limits, as [`StepReport`] carries them.
pub use femp_solver::{IterationRecord, StepLimit};
pub use io::{checkpoint, metrics, output, render};
pub use report::{StepReport, Unknown};
pub use world::World;
