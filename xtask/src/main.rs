//! `cargo xtask <task>`: project automation (matklad's xtask convention).
//!
//! Tasks:
//! * `ci` — run exactly what `.ci/run` runs: format check, clippy with warnings denied, and the
//!   README's test command. Every step runs even if an earlier one fails; the exit code is
//!   non-zero if any failed.
//! * `validate` — the papers' experiments (`validate/mod.rs`).
//! * `bench` — what a 3D BFEMP step costs, per ordering (`bench.rs`).
//! * `same A B` — whether two output trees hold the same results, wall times aside (`same.rs`).
//! * `compact-png FILE…` — re-encode PNGs in place as the published reports' images are (at most
//!   256 colours, `validate/compact.rs`): for images committed under `docs/` by hand.

mod bench;
mod ci;
mod same;
mod settings;
#[cfg(test)]
mod structure;
mod validate;

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("ci") => ci::run(),
        Some("validate") => validate::main(&args[1..]),
        Some("bench") => bench::main(&args[1..]),
        Some("same") => same::main(&args[1..]),
        Some("compact-png") => {
            anyhow::ensure!(args.len() > 1, "compact-png needs PNG files\n\n{USAGE}");
            for f in &args[1..] {
                let path = std::path::Path::new(f);
                validate::compact_png(path, path)?;
            }
            Ok(())
        }
        Some(other) => anyhow::bail!("unknown task `{other}`\n\n{USAGE}"),
        None => {
            println!("{USAGE}");
            Ok(())
        }
    }
}

const USAGE: &str = "usage: cargo xtask <task>

tasks:
  ci        format check, clippy -D warnings, and the test suite (what .ci/run runs)
  validate  the papers' experiments: [--quick | --full] [--only NAME…] [--out DIR]
            [--set KEY=VALUE …]
  bench     3D step cost: Newton iterations and seconds per step on block_on_plate_3d and a
            §6.7 twist window [--only plate|twist] [--steps N] [--ordering auto|amd|nested_dissection …]
            [--set KEY=V1,V2,… …]
  same A B  whether two output trees (validate or run --out) hold the same results, wall times
            aside: what a behaviour-preserving change is checked with
  compact-png FILE…  re-encode PNGs in place as the reports' images (≤ 256 colours)";
