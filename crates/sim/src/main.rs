//! The `femp` program: run or check a scene.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Parser, Subcommand};

/// Elastic MPM and FEM bodies in frictional contact (BFEMP).
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
    },
    /// Validate a scene without running it (format, values, initial overlaps).
    Check {
        /// Scene file.
        scene: PathBuf,
    },
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
            };
            let r = femp::run::run(s, &out, &opts)
                .with_context(|| format!("running {}", scene.display()))?;
            eprintln!(
                "{}: {} steps, t = {:.4} s, {:.1} s wall, {} Newton iterations, max penetrations {} -> {}",
                r.summary.scene,
                r.summary.steps,
                r.summary.simulated_time,
                r.summary.wall_s,
                r.summary.newton_iterations,
                r.summary.max_penetrations,
                out.display()
            );
        }
        Command::Check { scene } => {
            let s = femp::scene::load(&scene)?;
            let dim = s.spec.dimension;
            let name = s.name.clone();
            let (particles, vertices) = match dim {
                2 => {
                    let w = femp::World::<2>::build(s)?;
                    (
                        w.mpm.as_ref().map_or(0, |m| m.x.len()),
                        w.fem.iter().map(|b| b.x.len()).sum::<usize>(),
                    )
                }
                _ => {
                    let w = femp::World::<3>::build(s)?;
                    (
                        w.mpm.as_ref().map_or(0, |m| m.x.len()),
                        w.fem.iter().map(|b| b.x.len()).sum::<usize>(),
                    )
                }
            };
            println!("{name}: valid {dim}D scene, {particles} particles, {vertices} FEM vertices");
        }
    }
    Ok(())
}
