//! Running a scene to its end: steps, output, progress, and a summary that says how it ended.
//!
//! A run writes only inside its output directory ([`Output`] locks it and refuses or replaces
//! an earlier run's files). `summary.json` is kept current while the run goes (at most a second
//! old), and however the run ends — completed, a failed step, a failed write, an interrupt —
//! the summary says so and everything written up to then stays: whole metrics rows, whole
//! frames.

use std::io::{IsTerminal, Write};
use std::path::Path;
use std::time::Instant;

use crate::error::SimError;
use crate::io::checkpoint::{CHECKPOINT, Checkpoint};
use crate::io::metrics::Metrics;
use crate::io::output::{Output, OutputOptions, Summary};
use crate::io::render::{PictureOptions, Pictures};
use crate::report::StepReport;
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
    /// Set from elsewhere (e.g. a signal handler) to stop the run — between steps, or inside a
    /// step before its next Newton iteration; the run then ends with status `interrupted` and
    /// [`SimError::Interrupted`].
    pub interrupt: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    /// Draw key frames (PNG) and an animated GIF into `out_dir/pictures` ([`crate::render`]).
    pub pictures: Option<PictureOptions>,
    /// Replace an earlier run's outputs in the output directory instead of refusing them.
    pub overwrite: bool,
    /// The command line that started the run, recorded in `summary.json`.
    pub command: Vec<String>,
    /// Keep no per-step metrics in memory ([`RunResult::metrics`] holds the initial state only;
    /// `metrics.csv` has them all) — for long runs, whose metrics would grow without bound.
    pub metrics_in_file_only: bool,
    /// Measure the state (energies, momenta, penetrations, distances: [`World::measure`]) and
    /// write its `metrics.csv` row after every this many steps, and after the last; 0 and 1
    /// mean every step. Measuring a large explicit (augury) step can cost as much as the step
    /// itself. The checks that keep a run honest do not depend on it: every step's straight
    /// paths are still checked for passing through a body, and the summary's solver totals
    /// count every step; penetration depth (and `augury.penetration_limit`), the energy-rise
    /// warning and the summary's penetration counts see the measured steps only.
    pub metrics_every: usize,
    /// Write `checkpoint.femp` into the output directory at every frame time (whether or not
    /// frames are written), replacing the last: the state `resume` continues from. BFEMP
    /// scenes only (an error for augury).
    pub checkpoint: bool,
    /// Continue the run whose `checkpoint.femp` is in the output directory instead of starting
    /// one: the world put where the checkpoint was taken, `metrics.csv` cut back to its rows up
    /// to then, later frames removed, the summary's totals carried on (and the step recorded in
    /// `resumed_at`). The steps that follow are bit for bit those of a run never stopped. The
    /// scene must be the checkpoint's but for `time.duration` (a run may be continued further).
    /// Not with `overwrite` or `pictures`.
    pub resume: bool,
    /// With `resume`: the scene's `solver` section may differ from the checkpoint's — the run
    /// goes on as a branch under other solver settings ([`World::restore_branch`]; its steps
    /// after the checkpoint are not bit for bit the run's even with the same settings), and
    /// the summary's warnings say so, with the first difference.
    pub branch: bool,
}

/// Everything a finished run measured, for callers that use femp as a library.
#[derive(Clone, Debug, Default)]
pub struct RunResult {
    /// The summary (as written to `summary.json`).
    pub summary: Summary,
    /// Every step's metrics (as written to `metrics.csv`), starting with the initial state.
    pub metrics: Vec<Metrics>,
    /// The bodies with contact-force columns in `metrics.csv`
    /// ([`crate::io::metrics::csv_header`]'s `forces_of`).
    pub force_bodies: Vec<String>,
}

/// Run a scene, writing into `out_dir`. On failure the files written so far stay, the summary
/// says why, and the error is returned.
pub fn run(scene: Scene, out_dir: &Path, opts: &RunOptions) -> Result<RunResult, SimError> {
    match scene.spec().dimension {
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

/// A line on standard error that may not be there (closed by `| head`, say): progress and
/// warnings are worth nothing to a run if printing them would stop it.
pub(crate) fn note(args: std::fmt::Arguments) {
    let _ = writeln!(std::io::stderr().lock(), "{args}");
}

/// The number of steps to cover `duration` with steps of `dt` (at least 1).
pub fn step_count(duration: f64, dt: f64) -> usize {
    // The float-to-int cast saturates; scene limits refuse absurd counts before a run starts.
    ((duration / dt) - 1e-9).ceil().max(1.0) as usize
}

/// How often `summary.json` is rewritten while a run goes.
const SUMMARY_EVERY_S: f64 = 1.0;

/// Run, calling `inspect(world, metrics)` after every measured step.
pub fn run_with<const D: usize>(
    scene: Scene,
    out_dir: &Path,
    opts: &RunOptions,
    mut inspect: impl FnMut(&World<D>, &Metrics),
) -> Result<RunResult, SimError> {
    let start = Instant::now();
    let mut world = World::<D>::build_with(scene, opts.interrupt.clone())?;
    if (opts.checkpoint || opts.resume) && !world.stepper.is_implicit() {
        return Err(SimError::Checkpoint {
            what: out_dir.join(CHECKPOINT).display().to_string(),
            message: "checkpoints are for BFEMP scenes; an augury run keeps state in its own \
                      explicit system and is not resumed"
                .into(),
        });
    }
    let mut rec = if opts.resume {
        Recorder::resume(&mut world, out_dir, opts)?
    } else {
        Recorder::start_at(&world, out_dir, opts, start)?
    };
    let start = rec.start;
    match drive(&mut world, &mut rec, opts, start, &mut inspect) {
        Ok(()) => rec.finish(&world),
        Err(e) => Err(rec.fail(&world, e)),
    }
}

/// The outputs of a run — `metrics.csv`, frames, `summary.json`, pictures — for a world stepped
/// by whoever drives it: [`run_with`]'s loop, or a caller stepping (and steering) a [`World`]
/// itself, as the Python package's `World.record` does. Made with [`Recorder::start`] (the
/// initial row, frame and summary), told of every step with [`Recorder::record`], ended with
/// [`Recorder::finish`] (or [`Recorder::fail`]); the same files as `femp run` for the same steps.
pub struct Recorder {
    out: Output,
    summary: Summary,
    all: Vec<Metrics>,
    pictures: Option<Pictures>,
    energy: EnergyWatch,
    total_steps: usize,
    frame_dt: f64,
    next_frame: f64,
    opts: RunOptions,
    start: Instant,
    last_summary: Instant,
}

impl Recorder {
    /// Start recording `world` into `out_dir` (locked; an earlier run's outputs refused or,
    /// with `opts.overwrite`, replaced): the scene's copy, `summary.json` (status `running`),
    /// the initial metrics row, frame and pictures. `opts.max_steps` and the scene's duration
    /// set how many steps the run is expected to take (the last is always measured; pictures
    /// are spaced over them).
    pub fn start<const D: usize>(
        world: &World<D>,
        out_dir: &Path,
        opts: &RunOptions,
    ) -> Result<Self, SimError> {
        Self::start_at(world, out_dir, opts, Instant::now())
    }

    fn start_at<const D: usize>(
        world: &World<D>,
        out_dir: &Path,
        opts: &RunOptions,
        start: Instant,
    ) -> Result<Self, SimError> {
        let mut out = Output::create(
            out_dir,
            world,
            OutputOptions {
                overwrite: opts.overwrite,
            },
        )?;
        if !out.removed().is_empty() && opts.progress {
            note(format_args!(
                "[{}] removed the outputs of an earlier run from {}: {}",
                world.scene.name,
                out_dir.display(),
                crate::io::output::describe_outputs(out_dir, out.removed())
            ));
        }
        let (total_steps, frame_dt) = schedule(world, opts);
        let scene_copy = match &world.scene.source {
            Some(text) => {
                out.scene_copy(text)?;
                Some(crate::io::output::SCENE_COPY.to_string())
            }
            None => None,
        };
        let mut summary = start_summary(world, scene_copy, opts);
        // A summary from the start: a run killed outright still says `running` and what it is.
        out.summary(&summary)?;
        let mut all = Vec::new();
        let mut pictures = None;
        // A failed write of the initial state ends the run as any later one does: the summary
        // says why.
        let energy = match first_row(
            world,
            &mut out,
            &mut summary,
            &mut all,
            &mut pictures,
            total_steps,
            opts,
        ) {
            Ok(e) => e,
            // (`first_row` sets the pictures only once it has drawn them: none to close.)
            Err(e) => {
                return Err(finish_failed(&mut summary, &out, start, e, world.driven()));
            }
        };
        Ok(Self {
            out,
            summary,
            all,
            pictures,
            energy,
            total_steps,
            frame_dt,
            next_frame: world.clock.time + frame_dt,
            opts: opts.clone(),
            start,
            last_summary: Instant::now(),
        })
    }

    /// Continue the run whose checkpoint is in `out_dir` ([`RunOptions::resume`]): `world`
    /// (built from the scene, not stepped) put where the checkpoint was taken, the outputs cut
    /// back to it, the recorder's state as it was then.
    pub fn resume<const D: usize>(
        world: &mut World<D>,
        out_dir: &Path,
        opts: &RunOptions,
    ) -> Result<Self, SimError> {
        let path = out_dir.join(CHECKPOINT);
        let refuse = |message: &str| SimError::Checkpoint {
            what: path.display().to_string(),
            message: message.into(),
        };
        if opts.overwrite {
            return Err(refuse("a run is resumed or overwritten, not both"));
        }
        if opts.pictures.is_some() {
            return Err(refuse(
                "pictures are drawn over a whole run: a resumed run draws none",
            ));
        }
        if !path.is_file() {
            return Err(refuse(
                "no checkpoint to resume from (runs write one with --checkpoint)",
            ));
        }
        let checkpoint = Checkpoint::read(&path)?;
        let branched = if opts.branch {
            Some(world.restore_branch(&checkpoint.world)?)
        } else {
            world.restore(&checkpoint.world)?;
            None
        };
        let state: RunState = serde_json::from_value(checkpoint.run)
            .map_err(|e| refuse(&format!("its run state: {e}")))?;
        let out = Output::reopen(out_dir, world, world.clock.step, &state.frame_times)?;
        if let Some(text) = &world.scene.source {
            out.scene_copy(text)?;
        }
        if opts.progress {
            note(format_args!(
                "[{}] resumed from {} at step {} (t = {:.4} s)",
                world.scene.name,
                path.display(),
                world.clock.step,
                world.clock.time
            ));
        }
        let mut summary = state.summary;
        summary.status = "running".into();
        summary.error = None;
        summary.resumed_at.push(world.clock.step);
        summary.command = opts.command.clone();
        if let Some(changed) = branched {
            summary.warnings.push(format!(
                "branched at step {} under {}: the steps after it are not the run's \
                 continuation",
                world.clock.step,
                match changed {
                    Some((path, then, now)) => format!(
                        "other solver settings (the first difference: `{path}` was {then}, is \
                         {now})"
                    ),
                    None => "the same solver settings, the solvers' analyses afresh".into(),
                }
            ));
        }
        let commit = env!("FEMP_COMMIT");
        if summary.commit != commit {
            summary.warnings.push(format!(
                "resumed at step {} by femp {commit}, the run before by {}: the steps after \
                 the resumption may differ in round-off from an uninterrupted run of either",
                world.clock.step, summary.commit
            ));
            summary.commit = commit.into();
        }
        out.summary(&summary)?;
        let (total_steps, frame_dt) = schedule(world, opts);
        // The wall time so far counts on from the checkpoint's.
        let now = Instant::now();
        let start = now
            .checked_sub(std::time::Duration::from_secs_f64(summary.wall_s.max(0.0)))
            .unwrap_or(now);
        Ok(Self {
            out,
            summary,
            all: Vec::new(),
            pictures: None,
            energy: state.energy,
            total_steps,
            frame_dt,
            next_frame: state.next_frame,
            opts: opts.clone(),
            start,
            last_summary: now,
        })
    }

    /// Write `checkpoint.femp`: `world` as it is now and the recorder's state.
    fn checkpoint<const D: usize>(&mut self, world: &World<D>) -> Result<(), SimError> {
        let mut summary = self.summary.clone();
        summary.wall_s = self.start.elapsed().as_secs_f64();
        summary.frames = self.out.frames();
        let state = RunState {
            summary,
            energy: self.energy.clone(),
            next_frame: self.next_frame,
            frame_times: self.out.frame_times().to_vec(),
        };
        let path = self.out.dir().join(CHECKPOINT);
        let run = serde_json::to_value(&state).map_err(|e| SimError::Checkpoint {
            what: path.display().to_string(),
            message: format!("its run state: {e}"),
        })?;
        Checkpoint {
            world: world.state()?,
            run,
        }
        .write(&path)
    }

    /// The number of steps the run is expected to take.
    pub fn total_steps(&self) -> usize {
        self.total_steps
    }

    /// The summary so far.
    pub fn summary(&self) -> &Summary {
        &self.summary
    }

    /// Record the step `world` just took (its `report`; it started at `started`): the step's
    /// metrics row (every `opts.metrics_every` steps and the last), its frame when the frame
    /// interval has passed, the pictures, the summary's totals (written at most a second
    /// apart); `inspect(world, metrics)` after a measured step. An augury step that let a
    /// boundary vertex through another body, or deeper than `augury.penetration_limit`, is the
    /// error — after its row and frame are written.
    pub fn record<const D: usize>(
        &mut self,
        world: &World<D>,
        report: &StepReport,
        started: Instant,
        inspect: &mut impl FnMut(&World<D>, &Metrics),
    ) -> Result<(), SimError> {
        let clock = Instant::now();
        let measured = sampled(world.clock.step, self.total_steps, self.opts.metrics_every);
        let mut m = if measured {
            world.measure()
        } else {
            Metrics::default()
        };
        let summary = &mut self.summary;
        summary.timing.measure_s += clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        record(&mut m, summary, report);
        if measured {
            (m.contact_forces, m.friction_forces) = world.body_forces(&report.pair_forces);
            m.wall_s = started.elapsed().as_secs_f64();
            self.out.metrics_row::<D>(&m)?;
            self.energy.observe(&m, world.clock.step, summary);
        }
        summary.steps = world.clock.step;
        summary.simulated_time = world.clock.time;
        if (!self.opts.no_frames || self.opts.checkpoint)
            && world.clock.time + 1e-12 >= self.next_frame
        {
            if !self.opts.no_frames {
                self.out.frame(world)?;
            }
            self.next_frame += self.frame_dt;
            if self.opts.checkpoint {
                self.checkpoint(world)?;
            }
        }
        // Augury: bodies that went through each other, or too deep into each other, stop the
        // run (`augury.penetration_limit`), after the step's row and frame are written.
        if let Some(e) = penetration_stop(world, &m, report) {
            return Err(e);
        }
        // A large picture takes seconds: not after an interrupt, which ends the run at the
        // next step.
        if let Some(p) = self.pictures.as_mut()
            && !world.interrupted()
        {
            p.update(world)?;
        }
        if measured {
            inspect(world, &m);
        }
        if self.last_summary.elapsed().as_secs_f64() >= SUMMARY_EVERY_S {
            self.summary.wall_s = self.start.elapsed().as_secs_f64();
            self.summary.frames = self.out.frames();
            self.out.summary(&self.summary)?;
            self.last_summary = Instant::now();
        }
        self.summary.timing.output_s += clock.elapsed().as_secs_f64();
        if measured && !self.opts.metrics_in_file_only {
            self.all.push(m);
        }
        Ok(())
    }

    /// Write a frame of `world` as it is now, whether or not the frame interval has passed.
    pub fn write_frame<const D: usize>(&mut self, world: &World<D>) -> Result<(), SimError> {
        self.out.frame(world)
    }

    /// End the recording of `world`, completed: the pictures finished, the end's warnings
    /// (penetrations, an energy rise nothing drove, substeps, …) and `summary.json` with status
    /// `completed`; what was recorded.
    pub fn finish<const D: usize>(mut self, world: &World<D>) -> Result<RunResult, SimError> {
        let driven = world.driven();
        if let Some(p) = self.pictures.take()
            && let Err(d) = p.finish(world)
        {
            return Err(finish_failed(
                &mut self.summary,
                &self.out,
                self.start,
                d,
                driven,
            ));
        }
        let summary = &mut self.summary;
        summary.status = "completed".into();
        summary.wall_s = self.start.elapsed().as_secs_f64();
        summary.frames = self.out.frames();
        end_warnings(summary, driven);
        self.out.summary(summary)?;
        Ok(RunResult {
            summary: self.summary,
            metrics: self.all,
            force_bodies: world.force_bodies().iter().map(|s| s.to_string()).collect(),
        })
    }

    /// End the recording of `world` by the error `e` (a failed step or write, an interrupt):
    /// the pictures drawn so far kept (an interrupt draws nothing more), and `summary.json`
    /// with status `failed` (`interrupted`) and the error, which is handed back. Every file
    /// written so far stays.
    pub fn fail<const D: usize>(mut self, world: &World<D>, e: SimError) -> SimError {
        let driven = world.driven();
        if let Some(p) = self.pictures.take() {
            let finished = if matches!(e, SimError::Interrupted { .. }) {
                Ok(p.abandon())
            } else {
                p.finish(world)
            };
            // The pictures up to a failure are worth keeping; a drawing error then must not
            // hide the run's own error.
            if let Err(d) = finished {
                note(format_args!("warning: {d}"));
            }
        }
        finish_failed(&mut self.summary, &self.out, self.start, e, driven)
    }
}

/// The summary of a run of `world` starting: what it is (scene, build, bodies, method) and the
/// scene's warnings (printed with `opts.progress`), status `running`.
fn start_summary<const D: usize>(
    world: &World<D>,
    scene_copy: Option<String>,
    opts: &RunOptions,
) -> Summary {
    let mut summary = Summary {
        scene: world.scene.name.clone(),
        femp_version: env!("CARGO_PKG_VERSION").into(),
        commit: env!("FEMP_COMMIT").into(),
        command: opts.command.clone(),
        scene_copy,
        mpm_bodies: world
            .bodies
            .mpm
            .as_ref()
            .map(|m| m.bodies.iter().map(|b| b.name.clone()).collect())
            .unwrap_or_default(),
        dimension: D,
        status: "running".into(),
        particles: world.bodies.mpm.as_ref().map_or(0, |m| m.x.len()),
        fem_vertices: world.bodies.fem.iter().map(|b| b.x.len()).sum(),
        method: world.scene.spec().method,
        augury: world
            .stepper
            .augury()
            .map(|a| crate::io::output::AugurySummary {
                grid_spacing: a.grid_spacing,
                stable_dt: a.stable_dt,
                boundary_particles: a.system.num_particles(),
            }),
        ..Default::default()
    };
    for w in world.warnings() {
        if opts.progress {
            note(format_args!("[{}] warning: {w}", summary.scene));
        }
        summary.warnings.push(w);
    }
    summary
}

/// The warnings a completed run's outcome calls for (penetrations, an energy rise nothing
/// drove, paths through bodies, substeps, retried solves, unconverged friction), printed where a
/// user must see them and added to the summary.
fn end_warnings(summary: &mut Summary, driven: bool) {
    let name = summary.scene.clone();
    if summary.penetrating_steps > 0 {
        let w = format!(
            "points were inside another body after {} of {} steps (at most {} at once; the \
             deepest: {}): the contact did not keep the bodies apart; see `penetrations` and \
             `penetration_depth` in metrics.csv",
            summary.penetrating_steps,
            summary.steps,
            summary.max_penetrations,
            summary
                .deepest_penetration
                .as_deref()
                .unwrap_or("crossing boundaries, no vertex inside")
        );
        note(format_args!("[{name}] warning: {w}"));
        summary.warnings.push(w);
    }
    if let Some(w) = energy_warning(summary, driven) {
        note(format_args!("[{name}] warning: {w}"));
        summary.warnings.push(w);
    }
    if summary.passed_through_steps > 0 {
        let w = format!(
            "in {} of {} steps a point's straight path passed through another body (at most \
             {:.3e} m deep): the contact let it through; see `swept_entered` and `swept_depth` \
             in metrics.csv",
            summary.passed_through_steps, summary.steps, summary.max_swept_depth
        );
        note(format_args!("[{name}] warning: {w}"));
        summary.warnings.push(w);
    }
    if summary.substepped_steps > 0 {
        let w = format!(
            "{} of {} steps were solved again in substeps (up to {} of Δt/{}) because a point's \
             straight path would have passed through a body: time.dt is too large for how fast \
             the points move past the bodies they meet",
            summary.substepped_steps, summary.steps, summary.max_substeps, summary.max_substeps
        );
        note(format_args!("[{name}] warning: {w}"));
        summary.warnings.push(w);
    }
    if summary.retried_steps > 0 {
        let n = summary.retried_steps;
        summary.warnings.push(format!(
            "{n} {} failed {} first solve and {} solved again from the start, with direct \
             solves after an inexact linear solve (solver.linear) or with the other Hessian \
             strategy (solver.retry_other_projection); each is printed as it happens",
            if n == 1 { "step" } else { "steps" },
            if n == 1 { "its" } else { "their" },
            if n == 1 { "was" } else { "were" },
        ));
    }
    if summary.friction_unconverged_steps > 0 {
        summary.warnings.push(format!(
            "the friction iteration hit solver.max_friction_iterations in {} steps",
            summary.friction_unconverged_steps
        ));
    }
}

/// Record a run's end by error in the summary (as far as the disk lets us) and hand the error
/// back.
fn finish_failed(
    summary: &mut Summary,
    out: &Output,
    start: Instant,
    e: SimError,
    driven: bool,
) -> SimError {
    if let Some(w) = energy_warning(summary, driven) {
        note(format_args!("[{}] warning: {w}", summary.scene));
        summary.warnings.push(w);
    }
    summary.status = if matches!(e, SimError::Interrupted { .. }) {
        "interrupted".into()
    } else {
        "failed".into()
    };
    summary.error = Some(e.to_string());
    summary.wall_s = start.elapsed().as_secs_f64();
    summary.frames = out.frames();
    if let Err(w) = out.summary(summary) {
        note(format_args!(
            "warning: could not record the run's end in summary.json: {w}"
        ));
    }
    e
}

/// What a [`Recorder`] keeps in a checkpoint besides the world: the summary so far, the energy
/// watch, when the next frame is due and the frames written.
#[derive(serde::Serialize, serde::Deserialize)]
struct RunState {
    summary: Summary,
    energy: EnergyWatch,
    next_frame: f64,
    frame_times: Vec<f64>,
}

/// The energy a run starts with and the scale a rise is measured against.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct EnergyWatch {
    energy0: f64,
    gravity0: f64,
    scale: f64,
}

impl EnergyWatch {
    /// Step `step`'s row `m`: the peak total energy and the rise so far into `summary`.
    fn observe(&mut self, m: &Metrics, step: usize, summary: &mut Summary) {
        self.scale = self.scale.max((m.gravity_energy - self.gravity0).abs());
        if total_energy(m) > summary.peak_energy {
            summary.energy_rise_step = step;
            summary.peak_energy = total_energy(m);
        }
        summary.energy_rise = ((summary.peak_energy - self.energy0) / self.scale).max(0.0);
    }
}

/// How many steps a run of `world` takes (the scene's duration, or `opts.max_steps` if fewer)
/// and the time between its frames (and checkpoints).
fn schedule<const D: usize>(world: &World<D>, opts: &RunOptions) -> (usize, f64) {
    let total_steps = step_count(world.scene.spec().time.duration, world.clock.dt);
    let frame_dt = world
        .scene
        .spec()
        .time
        .frame_interval
        .unwrap_or(world.clock.dt);
    (
        opts.max_steps.map_or(total_steps, |m| m.min(total_steps)),
        frame_dt,
    )
}

/// A run's start: the initial state's metrics row (and in `all`), frame and pictures; the
/// energy it starts with.
fn first_row<const D: usize>(
    world: &World<D>,
    out: &mut Output,
    summary: &mut Summary,
    all: &mut Vec<Metrics>,
    pictures: &mut Option<Pictures>,
    total_steps: usize,
    opts: &RunOptions,
) -> Result<EnergyWatch, SimError> {
    let mut m0 = world.measure();
    let energy0 = total_energy(&m0);
    // The scale a rise is measured against, independent of the gravity potential's origin
    // (which can make the total as large, or as close to 0, as one likes): the energy in
    // motion and deformation at the start, or the gravitational energy released so far —
    // and never below the total's own round-off.
    let gravity0 = m0.gravity_energy;
    let energy_scale = (m0.kinetic_energy + m0.elastic_energy + m0.barrier_energy)
        .max(1e-9 * energy0.abs())
        .max(f64::MIN_POSITIVE);
    summary.initial_energy = energy0;
    summary.peak_energy = energy0;
    // Forces are those of a step: none before the first.
    (m0.contact_forces, m0.friction_forces) = world.body_forces(&[]);
    out.metrics_row::<D>(&m0)?;
    summary.max_penetrations = m0.penetrations;
    all.push(m0);
    if !opts.no_frames {
        out.frame(world)?;
    }
    if let Some(p) = &opts.pictures {
        let dir = out.dir().join("pictures");
        let mut pics = Pictures::new(world, &dir, total_steps as f64 * world.clock.dt, p.clone())?;
        pics.update(world)?;
        *pictures = Some(pics);
    }
    Ok(EnergyWatch {
        energy0,
        gravity0,
        scale: energy_scale,
    })
}

/// A line about a step, above the progress bar (if any) or on standard error with progress.
fn announce(bar: Option<&indicatif::ProgressBar>, progress: bool, name: &str, line: &str) {
    if let Some(b) = bar {
        b.println(format!("[{name}] {line}"));
    } else if progress {
        note(format_args!("[{name}] {line}"));
    }
}

/// The steps of a run, each recorded; returns at the first error (of a step or a write).
fn drive<const D: usize>(
    world: &mut World<D>,
    rec: &mut Recorder,
    opts: &RunOptions,
    start: Instant,
    inspect: &mut impl FnMut(&World<D>, &Metrics),
) -> Result<(), SimError> {
    let name = world.scene.name.clone();
    let total_steps = rec.total_steps();
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
    if let Some(b) = &bar {
        b.set_position(world.clock.step as u64);
    }
    for _ in world.clock.step..total_steps {
        let t0 = Instant::now();
        let step = if world.interrupted() {
            Err(SimError::Interrupted {
                step: world.clock.step,
                time: world.clock.time,
            })
        } else {
            world.step()
        };
        let report = match step {
            Ok(r) => r,
            Err(e) => {
                if let Some(b) = &bar {
                    b.abandon();
                }
                return Err(e);
            }
        };
        if let Some(retried) = &report.retried {
            announce(bar.as_ref(), opts.progress, &name, retried);
        }
        if report.substeps > 1 {
            let line = format!(
                "step {}: a point's straight path passed through a body at Δt = {:e}; solved \
                 again in {} substeps",
                world.clock.step, world.clock.dt, report.substeps
            );
            announce(bar.as_ref(), opts.progress, &name, &line);
        }
        rec.record(world, &report, t0, inspect)?;
        let msg = if world.stepper.is_implicit() {
            format!(
                "t = {:.4} s, Newton {}",
                world.clock.time, report.newton_iterations
            )
        } else {
            format!("t = {:.4} s", world.clock.time)
        };
        if let Some(b) = &bar {
            b.set_message(msg);
            b.inc(1);
        } else if opts.progress
            && (last_line.elapsed().as_secs_f64() > 10.0 || world.clock.step == total_steps)
        {
            let elapsed = start.elapsed().as_secs_f64();
            let left = eta(elapsed, world.clock.step, total_steps);
            note(format_args!(
                "[{name}] step {}/{total_steps}, {msg}, {elapsed:.1} s{left}",
                world.clock.step,
            ));
            last_line = Instant::now();
        }
    }
    if let Some(b) = &bar {
        b.finish();
    }
    Ok(())
}

/// Whether step `step` (counted from 1) of `total` is measured with one row in `every`
/// ([`RunOptions::metrics_every`]): every `every`-th step and the last.
fn sampled(step: usize, total: usize, every: usize) -> bool {
    every <= 1 || step.is_multiple_of(every) || step >= total
}

/// An augury step that let a boundary vertex pass through another body, or left one deeper in
/// it than `augury.penetration_limit` of that body's mean boundary edge: the error that stops
/// the run (`None` for BFEMP, within the limit, or with the limit `null`).
fn penetration_stop<const D: usize>(
    world: &World<D>,
    m: &Metrics,
    report: &StepReport,
) -> Option<SimError> {
    let limit = world.stepper.penetration_limit(&world.scene)?;
    let fail = |message: String| SimError::StepFailed {
        step: world.clock.step.saturating_sub(1),
        time: world.clock.time - world.clock.dt,
        message,
    };
    if report.swept.tunnelled > 0 {
        return Some(fail(format!(
            "a boundary vertex passed through another body: {} — the augury correction let \
             the bodies through (a smaller Δt or τ, or a finer grid, keeps them apart; \
             `augury.penetration_limit: null` to keep going)",
            report.swept.describe()
        )));
    }
    let d = m.deepest.as_ref()?;
    (d.depth > limit * d.edge).then(|| {
        fail(format!(
            "{}, deeper than augury.penetration_limit = {limit} of that edge: the augury \
             correction let the bodies into each other (`augury.penetration_limit: null` to keep \
             going)",
            d.describe()
        ))
    })
}

/// The warning for a run whose total energy rose more than [`ENERGY_RISE_WARNING`] above its
/// initial value although nothing (`driven`) does work on the bodies.
fn energy_warning(summary: &Summary, driven: bool) -> Option<String> {
    let who = if summary.method == crate::scene::Method::Augury {
        "the explicit step and the augury correction added it (docs/augury.md)"
    } else {
        "the time integrator added it — plain Newmark can with contact (docs/bfemp.md, time \
         integrators); contact_stabilized_newmark and backward_euler do not"
    };
    if !(summary.energy_rise > ENERGY_RISE_WARNING) || driven {
        return None;
    }
    let factor = if summary.initial_energy > 0.0 {
        format!(
            " ({:.3}× its initial value)",
            summary.peak_energy / summary.initial_energy
        )
    } else {
        String::new()
    };
    Some(format!(
        "the total energy rose from {:.4e} to {:.4e}{factor} by step {}, though no prescribed \
         motion or moving boundary does work on the bodies: {who}",
        summary.initial_energy, summary.peak_energy, summary.energy_rise_step
    ))
}

/// Kinetic, elastic, barrier and gravitational energy of a metrics row.
fn total_energy(m: &Metrics) -> f64 {
    m.kinetic_energy + m.elastic_energy + m.barrier_energy + m.gravity_energy
}

/// A run's total energy may rise above its initial value by this fraction of its scale before
/// a run that nothing drives warns ([`Summary::energy_rise`]).
pub const ENERGY_RISE_WARNING: f64 = 0.01;

/// `, about 3 min left` from the mean step time so far (empty when done or nothing is known).
fn eta(elapsed: f64, done: usize, total: usize) -> String {
    if done == 0 || done >= total {
        return String::new();
    }
    let left = elapsed / done as f64 * (total - done) as f64;
    format!(", about {} left", human_seconds(left))
}

/// A duration for people: seconds (tenths below 10 s) below 2 min, minutes below 2 h, hours above.
pub fn human_seconds(s: f64) -> String {
    if s < 10.0 {
        format!("{s:.1} s")
    } else if s < 120.0 {
        format!("{s:.0} s")
    } else if s < 7200.0 {
        format!("{:.0} min", s / 60.0)
    } else {
        format!("{:.1} h", s / 3600.0)
    }
}

/// Copy a step's solver report into its metrics row and add it to the summary's totals.
fn record(m: &mut Metrics, summary: &mut Summary, report: &StepReport) {
    let s = &report.stats;
    m.record_step(report);
    summary.newton_iterations += report.newton_iterations;
    summary.friction_iterations += report.friction_iterations;
    summary.stick_model_directions += s.model_directions;
    summary.expanded_steps += s.expanded_steps;
    summary.augury_iterations += report.augury_iterations;
    summary.exact_hessian_iterations += s.exact_iterations;
    summary.exact_hessian_rejections += s.exact_rejections;
    summary.reused_hessians += s.reused_hessians;
    summary.gradient_steps += s.gradient_steps;
    summary.pcg_iterations += s.pcg_iterations;
    summary.pcg_fallbacks += s.pcg_fallbacks;
    summary.refine_iterations += s.refine_iterations;
    summary.double_fallbacks += s.double_fallbacks;
    summary.friction_unconverged_steps += usize::from(!report.friction_converged);
    summary.retried_steps += usize::from(report.retried.is_some());
    summary.max_penetrations = summary.max_penetrations.max(m.penetrations);
    summary.penetrating_steps += usize::from(m.penetrations > 0);
    if let Some(d) = &m.deepest
        && d.depth > summary.max_penetration_depth
    {
        summary.max_penetration_depth = d.depth;
        summary.deepest_penetration = Some(format!("{} after step {}", d.describe(), m.step));
    }
    summary.swept_steps += usize::from(report.swept.entered > 0);
    summary.max_swept_depth = summary.max_swept_depth.max(report.swept.depth);
    summary.passed_through_steps += usize::from(report.swept.tunnelled > 0);
    summary.substepped_steps += usize::from(report.substeps > 1);
    summary.max_substeps = summary.max_substeps.max(report.substeps);
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
}

#[cfg(test)]
mod tests {
    use super::eta;

    #[test]
    fn eta_is_the_mean_step_time_times_the_steps_left() {
        assert_eq!(eta(10.0, 5, 20), ", about 30 s left");
        assert_eq!(eta(60.0, 1, 11), ", about 10 min left");
        assert_eq!(eta(3600.0, 1, 4), ", about 3.0 h left");
        assert_eq!(eta(1.0, 0, 5), "");
        assert_eq!(eta(1.0, 5, 5), "");
    }
}
