//! `cargo xtask bench`: what a 3D BFEMP step costs — Newton and friction iterations and seconds
//! per step, and where the seconds go (assembly, symbolic and numeric factorisation, solves,
//! line search) — on the two scenes issue 40 measures: `block_on_plate_3d` (26k unknowns, an MPM
//! block landing on a FEM plate with friction) and a window of the §6.7 twist (the shell turning
//! on the cube). Each case runs once per Cholesky ordering asked for, so a change can be compared
//! with the code before it, and orderings with each other, in one table.
//!
//! ```text
//! cargo xtask bench                                  # both cases, the scenes' own ordering
//! cargo xtask bench --only plate --ordering amd nested_dissection
//! cargo xtask bench --only twist --steps 10
//! cargo xtask bench --friction-update-below 0 0.01   # friction between solves / in Newton too
//! cargo xtask bench --newton-test nodes points         # Newton's test on grid nodes / particles
//! ```
//!
//! `block_on_plate_3d` runs its first `--steps` steps (default 2: the first lands the block, the
//! second is in contact); the twist runs to the window's start (t = 1.0 s, where the turn begins)
//! unmeasured, then `--steps` steps (default 5) measured. Steps run on every core unless
//! `RAYON_NUM_THREADS` says otherwise.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use femp::World;
use femp::scene::{self, NewtonTestSpec, OrderingSpec};

struct Case {
    name: &'static str,
    file: &'static str,
    /// Steps run before the measured ones.
    warm: usize,
    /// Measured steps by default.
    steps: usize,
}

const CASES: [Case; 2] = [
    Case {
        name: "plate",
        file: "block_on_plate_3d.json",
        warm: 0,
        steps: 2,
    },
    Case {
        name: "twist",
        file: "twist.json",
        warm: 100,
        steps: 5,
    },
];

const USAGE: &str = "usage: cargo xtask bench [--only plate|twist …] [--steps N] \
                     [--ordering auto|amd|nested_dissection …] [--friction-update-below V …] \
                     [--newton-test nodes|points …]";

/// Entry point (arguments after `bench`).
pub fn main(args: &[String]) -> Result<()> {
    let mut only: Vec<String> = Vec::new();
    let mut orderings: Vec<OrderingSpec> = Vec::new();
    let mut steps: Option<usize> = None;
    let mut below: Vec<f64> = Vec::new();
    let mut tests: Vec<NewtonTestSpec> = Vec::new();
    let mut it = args.iter().peekable();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--only" => {
                while let Some(n) = it.next_if(|n| !n.starts_with("--")) {
                    only.push(n.clone());
                }
            }
            "--steps" => {
                steps = Some(
                    it.next()
                        .and_then(|n| n.parse().ok())
                        .filter(|&n: &usize| n >= 1)
                        .context(USAGE)?,
                )
            }
            "--ordering" => {
                while let Some(n) = it.next_if(|n| !n.starts_with("--")) {
                    orderings.push(match n.as_str() {
                        "auto" => OrderingSpec::Auto,
                        "amd" => OrderingSpec::Amd,
                        "nested_dissection" | "nd" => OrderingSpec::NestedDissection,
                        o => bail!("unknown ordering `{o}`\n{USAGE}"),
                    });
                }
            }
            "--friction-update-below" => {
                while let Some(n) = it.next_if(|n| !n.starts_with("--")) {
                    below.push(
                        n.parse()
                            .ok()
                            .filter(|v: &f64| *v >= 0.0 && v.is_finite())
                            .with_context(|| format!("`{n}` is not a speed ≥ 0\n{USAGE}"))?,
                    );
                }
            }
            "--newton-test" => {
                while let Some(n) = it.next_if(|n| !n.starts_with("--")) {
                    tests.push(match n.as_str() {
                        "nodes" => NewtonTestSpec::Nodes,
                        "points" => NewtonTestSpec::Points,
                        o => bail!("unknown Newton test `{o}`\n{USAGE}"),
                    });
                }
            }
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(());
            }
            o => bail!("unknown argument `{o}`\n{USAGE}"),
        }
    }
    if orderings.is_empty() {
        orderings.push(OrderingSpec::Auto);
    }
    let root = super::validate::workspace_root();
    println!(
        "| case | ordering | friction update below | Newton test | step | t (s) | Newton it. | friction it. | friction converged | contact terms | wall (s) | assembly | symbolic | numeric | solve | line search |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for case in CASES
        .iter()
        .filter(|c| only.is_empty() || only.iter().any(|o| o == c.name))
    {
        for &ordering in &orderings {
            for b in variants(&below) {
                for t in variants(&tests) {
                    run_case(&root, case, (ordering, b, t), steps.unwrap_or(case.steps))?;
                }
            }
        }
    }
    Ok(())
}

/// Each value asked for, or `None` (the scene's own setting) if none was.
fn variants<T: Copy>(asked: &[T]) -> Vec<Option<T>> {
    if asked.is_empty() {
        vec![None]
    } else {
        asked.iter().copied().map(Some).collect()
    }
}

fn run_case(
    root: &Path,
    case: &Case,
    (ordering, below, test): (OrderingSpec, Option<f64>, Option<NewtonTestSpec>),
    steps: usize,
) -> Result<()> {
    let dir = root.join("fixtures/scenes");
    let mut s = scene::load(&dir.join(case.file))?;
    s.spec.solver.ordering = ordering;
    if let Some(b) = below {
        s.spec.solver.friction_update_below = b;
    }
    if let Some(t) = test {
        s.spec.solver.newton_test = t;
    }
    let below = s.spec.solver.friction_update_below;
    let test = s.spec.solver.newton_test;
    let mut world = World::<3>::build(s)?;
    for _ in 0..case.warm {
        world.step()?;
    }
    let (mut newton, mut wall) = (0usize, 0.0f64);
    for _ in 0..steps {
        let clock = Instant::now();
        let r = world.step()?;
        let w = clock.elapsed().as_secs_f64();
        newton += r.newton_iterations;
        wall += w;
        let st = &r.stats;
        println!(
            "| {} | {:?} | {below} | {test:?} | {} | {:.3} | {} | {} | {} | {} | {w:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
            case.name,
            ordering,
            world.clock.step,
            world.clock.time,
            r.newton_iterations,
            r.friction_iterations,
            if r.friction_converged { "yes" } else { "no" },
            r.contact_terms,
            st.assembly_s,
            st.symbolic_s,
            st.numeric_s,
            st.solve_s,
            st.line_search_s
        );
    }
    println!(
        "| {} | {:?} | {below} | {test:?} | mean | | {:.1} | | | | {:.2} | | | | | |",
        case.name,
        ordering,
        newton as f64 / steps as f64,
        wall / steps as f64
    );
    Ok(())
}
