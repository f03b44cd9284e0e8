//! Running a scene to its end: steps, output, progress, and a summary that says how it ended.

use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

use crate::error::SimError;
use crate::metrics::Metrics;
use crate::output::{Output, Summary};
use crate::render::{PictureOptions, Pictures};
use crate::scene::Scene;
use crate::world::World;

/// Options of a run.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Show progress (a bar on a terminal, periodic lines otherwise).
    pub progress: bool,
    /// Stop after this many steps (tests, quick looks).
    pub max_steps: Option<usize>,
    /// Do not write frames (metrics and summary only).
    pub no_frames: bool,
    /// Set from elsewhere (e.g. a Ctrl-C handler) to stop the run after the current step; the
    /// run then ends with status `interrupted` and [`SimError::Interrupted`].
    pub interrupt: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    /// Draw key frames (PNG) and an animated GIF into `out_dir/pictures` ([`crate::render`]).
    pub pictures: Option<PictureOptions>,
}

/// Everything a finished run measured, for callers that use femp as a library.
#[derive(Clone, Debug, Default)]
pub struct RunResult {
    /// The summary (as written to `summary.json`).
    pub summary: Summary,
    /// Every step's metrics (as written to `metrics.csv`), starting with the initial state.
    pub metrics: Vec<Metrics>,
}

/// Run a scene, writing into `out_dir`. On failure the files written so far stay, the summary
/// says why, and the error is returned.
pub fn run(scene: Scene, out_dir: &Path, opts: &RunOptions) -> Result<RunResult, SimError> {
    match scene.spec.dimension {
        2 => run_d::<2>(scene, out_dir, opts),
        _ => run_d::<3>(scene, out_dir, opts),
    }
}

/// Run with a callback after every step (the validation suite inspects worlds this way).
pub fn run_d<const D: usize>(
    scene: Scene,
    out_dir: &Path,
    opts: &RunOptions,
) -> Result<RunResult, SimError> {
    run_with::<D>(scene, out_dir, opts, |_, _| {})
}

/// Run, calling `inspect(world, metrics)` after every step.
pub fn run_with<const D: usize>(
    scene: Scene,
    out_dir: &Path,
    opts: &RunOptions,
    mut inspect: impl FnMut(&World<D>, &Metrics),
) -> Result<RunResult, SimError> {
    let start = Instant::now();
    let name = scene.name.clone();
    let duration = scene.spec.time.duration;
    let frame_dt = scene.spec.time.frame_interval.unwrap_or(scene.spec.time.dt);
    let mut world = World::<D>::build(scene)?;
    let mut out = Output::create(out_dir, &world)?;
    let total_steps = ((duration / world.dt) - 1e-9).ceil().max(1.0) as usize;
    let total_steps = opts.max_steps.map_or(total_steps, |m| m.min(total_steps));
    let mut summary = Summary {
        scene: name.clone(),
        dimension: D,
        status: "running".into(),
        particles: world.mpm.as_ref().map_or(0, |m| m.x.len()),
        fem_vertices: world.fem.iter().map(|b| b.x.len()).sum(),
        method: if world.augury.is_some() {
            "augury".into()
        } else {
            "bfemp".into()
        },
        augury: world.augury.as_ref().map(|a| crate::output::AugurySummary {
            grid_spacing: a.grid_spacing,
            stable_dt: a.stable_dt,
            boundary_particles: a.system.num_particles(),
        }),
        ..Default::default()
    };
    // A summary from the start: a run killed outright still says `running` and what it is.
    out.summary(&summary)?;
    let mut all = Vec::with_capacity(total_steps + 1);
    let m0 = world.measure();
    out.metrics_row::<D>(&m0)?;
    summary.max_penetrations = m0.penetrations;
    all.push(m0);
    if !opts.no_frames {
        out.frame(&world)?;
    }
    let mut pictures = match &opts.pictures {
        Some(p) => {
            let dir = out_dir.join("pictures");
            let mut pics = Pictures::new(&world, &dir, total_steps as f64 * world.dt, p.clone())?;
            pics.update(&world)?;
            Some(pics)
        }
        None => None,
    };
    let mut next_frame = frame_dt;
    let bar = (opts.progress && std::io::stderr().is_terminal()).then(|| {
        let b = indicatif::ProgressBar::new(total_steps as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} steps  {msg}  [{elapsed_precise} < {eta_precise}]",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let mut last_line = Instant::now();
    for _ in 0..total_steps {
        let t0 = Instant::now();
        let step = if opts
            .interrupt
            .as_ref()
            .is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
        {
            Err(SimError::Interrupted {
                step: world.step,
                time: world.time,
            })
        } else {
            world.step()
        };
        match step {
            Ok(report) => {
                let clock = Instant::now();
                let mut m = world.measure();
                summary.timing.measure_s += clock.elapsed().as_secs_f64();
                let clock = Instant::now();
                m.newton_iterations = report.newton_iterations;
                m.friction_iterations = report.friction_iterations;
                m.contact_terms = report.contact_terms;
                m.backtracks = report.stats.backtracks;
                m.ccd_limited = report.stats.limited_by_ccd;
                m.exact_hessians = report.stats.exact_iterations;
                m.reused_hessians = report.stats.reused_hessians;
                m.pcg_iterations = report.stats.pcg_iterations;
                m.wall_s = t0.elapsed().as_secs_f64();
                if report.contact_terms > 0 {
                    m.min_distance = m.min_distance.min(report.min_distance);
                }
                out.metrics_row::<D>(&m)?;
                summary.steps = world.step;
                summary.simulated_time = world.time;
                summary.newton_iterations += report.newton_iterations;
                summary.friction_iterations += report.friction_iterations;
                summary.exact_hessian_iterations += report.stats.exact_iterations;
                summary.exact_hessian_rejections += report.stats.exact_rejections;
                summary.reused_hessians += report.stats.reused_hessians;
                summary.gradient_steps += report.stats.gradient_steps;
                summary.pcg_iterations += report.stats.pcg_iterations;
                summary.pcg_fallbacks += report.stats.pcg_fallbacks;
                summary.friction_unconverged_steps += usize::from(!report.friction_converged);
                summary.max_penetrations = summary.max_penetrations.max(m.penetrations);
                let s = &report.stats;
                let tm = &mut summary.timing;
                tm.transfers_s += report.transfers_s;
                tm.setup_s += report.setup_s;
                tm.assembly_s += s.assembly_s;
                tm.symbolic_s += s.symbolic_s;
                tm.numeric_s += s.numeric_s;
                tm.solve_s += s.solve_s;
                tm.pcg_s += s.pcg_s;
                tm.line_search_s += s.line_search_s;
                tm.objective.add(&report.objective);
                if !opts.no_frames && world.time + 1e-12 >= next_frame {
                    out.frame(&world)?;
                    next_frame += frame_dt;
                }
                if let Some(p) = &mut pictures {
                    p.update(&world)?;
                }
                inspect(&world, &m);
                let msg = if world.augury.is_some() {
                    format!("t = {:.4} s", world.time)
                } else {
                    format!(
                        "t = {:.4} s, Newton {}",
                        world.time, report.newton_iterations
                    )
                };
                if let Some(b) = &bar {
                    b.set_message(msg);
                    b.inc(1);
                } else if opts.progress
                    && (last_line.elapsed().as_secs_f64() > 10.0 || world.step == total_steps)
                {
                    eprintln!(
                        "[{name}] step {}/{total_steps}, {msg}, {:.1} s",
                        world.step,
                        start.elapsed().as_secs_f64()
                    );
                    last_line = Instant::now();
                }
                summary.timing.output_s += clock.elapsed().as_secs_f64();
                all.push(m);
            }
            Err(e) => {
                if let Some(b) = &bar {
                    b.abandon();
                }
                summary.status = if matches!(e, SimError::Interrupted { .. }) {
                    "interrupted".into()
                } else {
                    "failed".into()
                };
                summary.error = Some(e.to_string());
                summary.wall_s = start.elapsed().as_secs_f64();
                summary.frames = out.frames();
                if let Some(p) = pictures.take() {
                    // The pictures up to the failure are worth keeping; a drawing error here
                    // must not hide the run's own error.
                    if let Err(d) = p.finish(&world) {
                        eprintln!("warning: {d}");
                    }
                }
                out.summary(&summary)?;
                return Err(e);
            }
        }
    }
    if let Some(b) = &bar {
        b.finish();
    }
    if let Some(p) = pictures.take() {
        p.finish(&world)?;
    }
    summary.status = "completed".into();
    summary.wall_s = start.elapsed().as_secs_f64();
    summary.frames = out.frames();
    out.summary(&summary)?;
    Ok(RunResult {
        summary,
        metrics: all,
    })
}
