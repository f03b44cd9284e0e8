//! The `femp` program: run or check a scene.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Parser, Subcommand};

/// Elastic MPM and FEM bodies in frictional contact: BFEMP (implicit, barrier contact) and APIC
/// augury contact (explicit FEM), chosen by the scene's `method`.
#[derive(Parser)]
#[command(name = "femp", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene and write frames, metrics.csv and summary.json into DIR.
    Run {
        /// Scene file (JSON; see docs/scenes.md).
        scene: PathBuf,
        /// Output directory (created if missing).
        #[arg(long, short)]
        out: PathBuf,
        /// Stop after this many steps.
        #[arg(long)]
        max_steps: Option<usize>,
        /// Write metrics and the summary only, no frames.
        #[arg(long)]
        no_frames: bool,
        /// No progress output.
        #[arg(long, short)]
        quiet: bool,
        /// Draw pictures into DIR/pictures: key frames as PNG (particles coloured by von Mises
        /// stress, FEM meshes with their edges, level sets shaded) and an animated GIF.
        #[arg(long)]
        pictures: bool,
        /// Number of PNG key frames, evenly spaced from start to end (with --pictures).
        #[arg(long, default_value_t = 6)]
        key_frames: usize,
        /// Number of GIF frames over the run; 0 for none (with --pictures).
        #[arg(long, default_value_t = 60)]
        gif_frames: usize,
        /// 3D pictures: the axis drawn upwards, x, y or z (default: against gravity, else y).
        #[arg(long, value_parser = ["x", "y", "z"])]
        up: Option<String>,
        /// Picture size in pixels, WIDTHxHEIGHT (with --pictures).
        #[arg(long, default_value = "640x480", value_parser = parse_size)]
        picture_size: (u32, u32),
    },
    /// Validate a scene without running it (format, values, initial overlaps).
    Check {
        /// Scene file.
        scene: PathBuf,
    },
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("`{s}`: expected WIDTHxHEIGHT, e.g. 640x480, each at least 64");
    let (w, h) = s.split_once('x').ok_or_else(bad)?;
    let (w, h): (u32, u32) = (w.parse().map_err(|_| bad())?, h.parse().map_err(|_| bad())?);
    if w < 64 || h < 64 {
        return Err(bad());
    }
    Ok((w, h))
}

fn main() -> std::process::ExitCode {
    // Errors are for users: one line naming what and where, no backtrace.
    match run(Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Run {
            scene,
            out,
            max_steps,
            no_frames,
            quiet,
            pictures,
            key_frames,
            gif_frames,
            picture_size,
            up,
        } => {
            let s = femp::scene::load(&scene)?;
            // Ctrl-C stops after the current step; the files so far stay and the summary says so.
            let interrupt = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
            let flag = interrupt.clone();
            ctrlc::set_handler(move || flag.store(true, std::sync::atomic::Ordering::Relaxed))
                .context("installing the Ctrl-C handler")?;
            let opts = femp::run::RunOptions {
                progress: !quiet,
                max_steps,
                no_frames,
                interrupt: Some(interrupt),
                pictures: pictures.then(|| femp::render::PictureOptions {
                    key_frames,
                    gif_frames,
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
            let work = if r.summary.method == "augury" {
                format!("{} augury iterations", r.summary.friction_iterations)
            } else {
                format!("{} Newton iterations", r.summary.newton_iterations)
            };
            eprintln!(
                "{}: {} steps, t = {:.4} s, {:.1} s wall, {work}, max penetrations {} -> {}",
                r.summary.scene,
                r.summary.steps,
                r.summary.simulated_time,
                r.summary.wall_s,
                r.summary.max_penetrations,
                out.display()
            );
        }
        Command::Check { scene } => {
            let s = femp::scene::load(&scene)?;
            let dim = s.spec.dimension;
            let name = s.name.clone();
            fn describe<const D: usize>(w: &femp::World<D>) -> String {
                let particles = w.mpm.as_ref().map_or(0, |m| m.x.len());
                let vertices = w.fem.iter().map(|b| b.x.len()).sum::<usize>();
                let mut s = format!("{particles} particles, {vertices} FEM vertices");
                if let Some(a) = &w.augury {
                    s += &format!(
                        "; augury: grid spacing {:.4e} m, {} boundary particles, Δt = {:.3e} s ({:.2} × the explicit stability estimate {:.3e} s)",
                        a.grid_spacing,
                        a.system.num_particles(),
                        w.dt,
                        w.dt / a.stable_dt,
                        a.stable_dt
                    );
                    // τ, not Δt, sets how strongly the correction acts (docs/augury.md).
                    if let Some(c) = &a.system.contact {
                        let tau = c.params().tau;
                        s += &format!(
                            ", look-ahead τ = {tau:.3e} s ({:.2} × the estimate)",
                            tau / a.stable_dt
                        );
                    }
                }
                s
            }
            let what = match dim {
                2 => describe(&femp::World::<2>::build(s)?),
                _ => describe(&femp::World::<3>::build(s)?),
            };
            println!("{name}: valid {dim}D scene, {what}");
        }
    }
    Ok(())
}
