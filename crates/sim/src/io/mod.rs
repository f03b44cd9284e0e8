//! What a run writes and measures, above the simulation: `metrics` (the measured state and the
//! `metrics.csv` columns), `checkpoint` (a run's state on disk, to resume it), `output` (frames, `metrics.csv`, `summary.json` in the output
//! directory) and `render` (pictures and animations). Nothing below this layer — the world, its
//! bodies, steppers and scenes — imports it (a structure test says so); `run` drives it.

pub mod checkpoint;
pub mod metrics;
pub mod output;
pub mod render;
