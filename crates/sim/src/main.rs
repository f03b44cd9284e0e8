//! The `femp` program: run or check a scene.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Parser, Subcommand};
use femp::render::MAX_SIDE as MAX_PICTURE_SIDE;

/// Elastic MPM and FEM bodies in frictional contact: BFEMP (implicit, barrier contact) and APIC
/// augury contact (explicit FEM), chosen by the scene's `method`.
#[derive(Parser)]
#[command(name = "femp", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// How large a scene may be (checked before anything is allocated).
#[derive(clap::Args, Clone, Copy)]
struct LimitArgs {
    /// Refuse scenes whose estimated memory exceeds this many GiB (default: 80 % of this
    /// machine's memory). `femp check` prints the estimate.
    #[arg(long, value_name = "GIB")]
    memory_limit: Option<f64>,
    /// Refuse scenes of more time steps than this (default 1e8).
    #[arg(long, value_name = "STEPS")]
    step_limit: Option<f64>,
}

impl LimitArgs {
    fn apply(self, scene: &mut femp::scene::Scene) -> anyhow::Result<()> {
        if let Some(g) = self.memory_limit {
            anyhow::ensure!(g > 0.0, "--memory-limit {g}: must be positive (GiB)");
            scene.limits.memory_bytes = g * 1024.0 * 1024.0 * 1024.0;
        }
        if let Some(n) = self.step_limit {
            anyhow::ensure!(n > 0.0, "--step-limit {n}: must be positive");
            scene.limits.steps = n;
        }
        Ok(())
    }
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene and write frames, metrics.csv and summary.json into DIR.
    Run {
        /// Scene file (JSON; see docs/scenes.md).
        scene: PathBuf,
        /// Output directory (created if missing). Every file the run writes is inside it.
        #[arg(long, short)]
        out: PathBuf,
        /// Replace the outputs of an earlier run in DIR (summary, metrics, frames, pictures);
        /// without it such outputs are an error.
        #[arg(long)]
        overwrite: bool,
        /// Stop after this many steps (counted from the run's start, also when resumed).
        #[arg(long)]
        max_steps: Option<usize>,
        /// Write DIR/checkpoint.femp at every frame time, replacing the last: what --resume
        /// continues from if the run is stopped (BFEMP scenes).
        #[arg(long)]
        checkpoint: bool,
        /// Continue the run in DIR from its checkpoint.femp instead of starting: metrics.csv
        /// cut back to the checkpoint's step, later frames removed, the summary's totals carried
        /// on; the steps after it are bit for bit those of a run never stopped. The scene must
        /// be the run's own; only time.duration may differ (to run further). Keeps writing
        /// checkpoints if --checkpoint is given too.
        #[arg(long, conflicts_with_all = ["overwrite", "pictures"])]
        resume: bool,
        /// With --resume: the scene's solver section may differ from the checkpoint's — the
        /// run goes on as a branch under other solver settings (copy DIR first to keep the
        /// run itself); summary.json's warnings name the first difference.
        #[arg(long, requires = "resume")]
        branch: bool,
        /// Write metrics and the summary only, no frames.
        #[arg(long)]
        no_frames: bool,
        /// Measure the state and write a metrics.csv row every N steps (and after the last)
        /// instead of every step: measuring a large explicit step can cost as much as the
        /// step. Every step is still checked for points passing through a body.
        #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
        metrics_every: u32,
        /// No progress output.
        #[arg(long, short)]
        quiet: bool,
        /// Draw pictures into DIR/pictures: key frames as PNG (particles coloured by von Mises
        /// stress, FEM meshes with their edges, level sets shaded) and an animated GIF.
        #[arg(long)]
        pictures: bool,
        /// Number of PNG key frames, evenly spaced from start to end (with --pictures; 0 or
        /// 2–1000).
        #[arg(long, default_value_t = 6, value_parser = clap::value_parser!(u16).range(0..=1000))]
        key_frames: u16,
        /// Number of GIF frames over the run; 0 for none (with --pictures; at most 10 000).
        #[arg(long, default_value_t = 60, value_parser = clap::value_parser!(u16).range(0..=10_000))]
        gif_frames: u16,
        /// 3D pictures: the axis drawn upwards, x, y or z (default: against gravity, else y).
        #[arg(long, value_parser = ["x", "y", "z"])]
        up: Option<String>,
        /// Picture size in pixels, WIDTHxHEIGHT (with --pictures).
        #[arg(long, default_value = "640x480", value_parser = parse_size)]
        picture_size: (u32, u32),
        #[command(flatten)]
        limits: LimitArgs,
    },
    /// Validate a scene without running it (format, values, size, initial overlaps) and print
    /// what it will cost (particles, grid nodes, unknowns, memory, steps, frame output; with
    /// `--trial N`, the wall time extrapolated from its first N steps).
    Check {
        /// Scene file.
        scene: PathBuf,
        /// Also run the first N steps (nothing is written) and extrapolate the wall time of
        /// the whole run from them.
        #[arg(long, value_name = "N", default_value_t = 0)]
        trial: usize,
        #[command(flatten)]
        limits: LimitArgs,
    },
}

/// Set a run's `summary.json` to `interrupted` (a second signal stops femp at once, before the
/// run can record its end): rewritten whole, atomically, if it exists and still says
/// `running`.
fn mark_interrupted(path: &std::path::Path) {
    let Ok(text) = std::fs::read_to_string(path) else {
        return;
    };
    let Ok(mut v) = serde_json::from_str::<serde_json::Value>(&text) else {
        return;
    };
    if v["status"] != "running" {
        return;
    }
    v["status"] = "interrupted".into();
    v["error"] = "stopped at once by a second interrupt signal (SIGINT, SIGTERM or SIGHUP), \
                  during a step: the last step's row and frame may be missing"
        .into();
    if let Ok(text) = serde_json::to_string_pretty(&v) {
        let _ = femp::output::write_replacing(path, text.as_bytes());
    }
}

/// `femp check --trial N`: run the first `n` steps of `w` and extrapolate the whole run's wall
/// time from them (empty for `n = 0`).
fn trial_steps<const D: usize>(w: &mut femp::World<D>, n: usize) -> anyhow::Result<String> {
    if n == 0 {
        return Ok(String::new());
    }
    let total = femp::run::step_count(w.scene.spec().time.duration, w.clock.dt);
    let n = n.min(total);
    let (mut newton, mut contact) = (0usize, 0usize);
    let start = std::time::Instant::now();
    for k in 0..n {
        let r = w
            .step()
            .map_err(|e| anyhow::anyhow!("trial step {} of {n}: {e}", k + 1))?;
        newton += r.newton_iterations;
        contact += usize::from(r.contact_terms > 0);
    }
    let elapsed = start.elapsed().as_secs_f64();
    let per = elapsed / n as f64;
    let mut s = format!(
        "\n  trial: {n} steps in {elapsed:.2} s ({per:.3} s per step, {:.1} Newton iterations per \
         step, contact in {contact}); all {total} steps at that rate: about {}",
        newton as f64 / n as f64,
        femp::run::human_seconds(per * total as f64)
    );
    if n < total && w.stepper.is_implicit() {
        s += if contact == 0 {
            " — a lower bound: no trial step had contact, and steps in contact cost more \
             (often 10× in 3D MPM)"
        } else {
            " — a guide: steps in contact cost more than steps without, so the rate depends \
             on how much of the run is in contact"
        };
    }
    Ok(s)
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || {
        format!("`{s}`: expected WIDTHxHEIGHT, e.g. 640x480, each from 64 to {MAX_PICTURE_SIDE}")
    };
    let (w, h) = s.split_once('x').ok_or_else(bad)?;
    let (w, h): (u32, u32) = (w.parse().map_err(|_| bad())?, h.parse().map_err(|_| bad())?);
    if !(64..=MAX_PICTURE_SIDE).contains(&w) || !(64..=MAX_PICTURE_SIDE).contains(&h) {
        return Err(bad());
    }
    Ok((w, h))
}

/// Exit status of a run stopped by SIGINT, SIGTERM or SIGHUP (128 + SIGINT, as shells report
/// Ctrl-C).
const EXIT_INTERRUPTED: u8 = 130;

/// A line on standard error, or nothing if it is closed (`femp run … 2>&1 | head -1`).
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($t)*);
    }};
}

fn main() -> std::process::ExitCode {
    // A file-size limit (`ulimit -f`, a scheduler's) sends SIGXFSZ, which by default kills the
    // process mid-write with `summary.json` still saying `running` and a `.tmp` frame left.
    // Ignored, the write fails with EFBIG instead: the run records the failure, removes the
    // partial file and keeps everything written so far.
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to SIG_IGN at the start of `main`, before any
    // other thread exists, has no preconditions.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
    // Errors are for users: one line naming what and where, no backtrace.
    match run(Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            say!("error: {e:#}");
            if matches!(
                e.downcast_ref::<femp::SimError>(),
                Some(femp::SimError::Interrupted { .. })
            ) {
                std::process::ExitCode::from(EXIT_INTERRUPTED)
            } else {
                std::process::ExitCode::FAILURE
            }
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Run {
            scene,
            out,
            overwrite,
            max_steps,
            checkpoint,
            resume,
            branch,
            no_frames,
            metrics_every,
            quiet,
            pictures,
            key_frames,
            gif_frames,
            picture_size,
            up,
            limits,
        } => {
            let mut s = femp::scene::load(&scene)?;
            limits.apply(&mut s)?;
            // Ctrl-C, SIGTERM and SIGHUP (what schedulers and closing terminals send) stop the
            // run before its next Newton iteration; the files so far stay, the summary says
            // `interrupted`, and femp exits with 130. A second signal stops at once.
            let interrupt = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
            let flag = interrupt.clone();
            let summary_path = out.join("summary.json");
            ctrlc::set_handler(move || {
                if flag.swap(true, std::sync::atomic::Ordering::Relaxed) {
                    say!("second interrupt: stopping now");
                    // The run cannot record its end itself now: say so in its summary.
                    mark_interrupted(&summary_path);
                    std::process::exit(EXIT_INTERRUPTED.into());
                }
            })
            .context("installing the signal handler")?;
            let opts = femp::run::RunOptions {
                progress: !quiet,
                max_steps,
                no_frames,
                interrupt: Some(interrupt),
                overwrite,
                metrics_in_file_only: true,
                metrics_every: metrics_every as usize,
                checkpoint,
                resume,
                branch,
                command: std::env::args().collect(),
                pictures: pictures.then(|| femp::render::PictureOptions {
                    key_frames: key_frames.into(),
                    gif_frames: gif_frames.into(),
                    size: picture_size,
                    up: up.map(|a| match a.as_str() {
                        "x" => 0,
                        "y" => 1,
                        _ => 2,
                    }),
                    ..Default::default()
                }),
            };
            let r = femp::run::run(s, &out, &opts)
                .with_context(|| format!("running {}", scene.display()))?;
            let work = if r.summary.method == femp::scene::Method::Augury {
                format!("{} augury iterations", r.summary.augury_iterations)
            } else {
                format!("{} Newton iterations", r.summary.newton_iterations)
            };
            say!(
                "{}: {} steps, t = {:.4} s, {:.1} s wall, {work}, max penetrations {} -> {}",
                r.summary.scene,
                r.summary.steps,
                r.summary.simulated_time,
                r.summary.wall_s,
                r.summary.max_penetrations,
                out.display()
            );
        }
        Command::Check {
            scene,
            trial,
            limits,
        } => {
            let mut s = femp::scene::load(&scene)?;
            limits.apply(&mut s)?;
            let estimate = femp::scene::size::estimate(&s)?;
            let cost = format!(
                "{}; limits: {} memory, {:.0e} steps",
                estimate.describe(),
                femp::scene::size::human_bytes(s.limits.memory_bytes),
                s.limits.steps
            );
            let dim = s.spec().dimension;
            let name = s.name.clone();
            fn describe<const D: usize>(w: &femp::World<D>) -> String {
                let particles = w.bodies.mpm.as_ref().map_or(0, |m| m.x.len());
                let vertices = w.bodies.fem.iter().map(|b| b.x.len()).sum::<usize>();
                let mut s = format!("{particles} particles, {vertices} FEM vertices");
                s += &w.stepper.describe(w.clock.dt);
                for warning in w.warnings() {
                    s += &format!("\n  warning: {warning}");
                }
                s
            }
            let what = match dim {
                2 => {
                    let mut w = femp::World::<2>::build(s)?;
                    describe(&w) + &trial_steps(&mut w, trial)?
                }
                _ => {
                    let mut w = femp::World::<3>::build(s)?;
                    describe(&w) + &trial_steps(&mut w, trial)?
                }
            };
            // A closed standard output (`femp check … | true`) is not an error of the scene.
            use std::io::Write as _;
            let _ = writeln!(
                std::io::stdout().lock(),
                "{name}: valid {dim}D scene, {what}\n  {cost}"
            );
        }
    }
    Ok(())
}
