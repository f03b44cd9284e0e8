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
//! cargo xtask bench --set solver.reuse_hessian_below=0,0.1,1   # any scene field, each value
//! cargo xtask bench --only twist --steps 1 --trace twist.csv   # every Newton iteration
//! cargo xtask bench --only twist --warm 85 --steps 1 --set contact.friction=0.2  # step 86
//! ```
//!
//! `--trace FILE` writes one CSV row per Newton iteration of the measured steps (every case and
//! variant): its solve within the step, the convergence test's increment, the unknown with the
//! largest increment (grid node or FEM vertex, its mass), whether the Hessian was the exact
//! one, whether the direction was the stick model's (`solver.friction_stick_model`), `gᵀp`, the feasible-step bound and what set it, the step length, the line search's
//! halvings and the energy change — where a step's iterations go, in a file to plot.
//!
//! `--set KEY=V1,V2,…` (repeatable) sets a field of the scene file by its dotted path (array
//! elements by index: `contact.pairs.0.kappa`) to each value in turn, parsed as JSON (a bare
//! word is a string); several `--set` run every combination. The scene is validated as
//! `femp run` would, so a wrong path or value is the scene's own error.
//!
//! `block_on_plate_3d` runs its first `--steps` steps (default 2: the first lands the block, the
//! second is in contact); the twist runs to the window's start (t = 1.0 s, where the turn begins)
//! unmeasured, then `--steps` steps (default 5) measured. `--warm N` runs N unmeasured steps
//! first instead (default 0 for the plate, 100 for the twist). Steps run on every core unless
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

const USAGE: &str = "usage: cargo xtask bench [--only plate|twist …] [--warm N] [--steps N] \
                     [--ordering auto|amd|nested_dissection …] [--friction-update-below V …] \
                     [--newton-test nodes|points …] [--set KEY=V1,V2,… …] [--trace FILE]";

/// The header of `--trace`'s CSV.
const TRACE_HEADER: &str = "case,ordering,set,step,solve,iteration,increment,largest_on,\
                            index,body,axis,mass,largest_increment,exact,reused,model,gtp,\
                            bound,bound_by,alpha,backtracks,energy_change";

/// Entry point (arguments after `bench`).
pub fn main(args: &[String]) -> Result<()> {
    let mut only: Vec<String> = Vec::new();
    let mut orderings: Vec<OrderingSpec> = Vec::new();
    let mut steps: Option<usize> = None;
    let mut warm: Option<usize> = None;
    let mut below: Vec<f64> = Vec::new();
    let mut tests: Vec<NewtonTestSpec> = Vec::new();
    let mut sets: Vec<(String, Vec<serde_json::Value>)> = Vec::new();
    let mut trace_file: Option<std::path::PathBuf> = None;
    let mut it = args.iter().peekable();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--only" => {
                while let Some(n) = it.next_if(|n| !n.starts_with("--")) {
                    only.push(n.clone());
                }
            }
            "--warm" => warm = Some(it.next().and_then(|n| n.parse().ok()).context(USAGE)?),
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
            "--set" => {
                let kv = it.next().context(USAGE)?;
                let (key, values) = crate::settings::split(kv)
                    .with_context(|| format!("`--set {kv}` is not KEY=V1,V2,…\n{USAGE}"))?;
                let values = values.split(',').map(crate::settings::value).collect();
                sets.push((key.to_string(), values));
            }
            "--trace" => {
                trace_file = Some(it.next().context(USAGE)?.into());
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
        "| case | ordering | friction update below | Newton test | set | step | t (s) | Newton it. | friction it. | friction converged | contact terms | reused Hessians | wall (s) | assembly | symbolic | numeric | solve | CG | line search | refine it. | double factors | stick-model directions | expanded steps |"
    );
    println!(
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    let combinations = combinations(&sets);
    let mut trace = trace_file.as_ref().map(|_| vec![TRACE_HEADER.to_string()]);
    for case in CASES
        .iter()
        .filter(|c| only.is_empty() || only.iter().any(|o| o == c.name))
    {
        for &ordering in &orderings {
            for b in variants(&below) {
                for t in variants(&tests) {
                    for set in &combinations {
                        run_case(
                            &root,
                            case,
                            (ordering, b, t, set),
                            (warm.unwrap_or(case.warm), steps.unwrap_or(case.steps)),
                            trace.as_mut(),
                        )?;
                    }
                }
            }
        }
    }
    if let (Some(file), Some(rows)) = (trace_file, trace) {
        let mut text = rows.join("\n");
        text.push('\n');
        std::fs::write(&file, text).with_context(|| format!("writing {}", file.display()))?;
        println!(
            "\n{} Newton iterations traced in {}",
            rows.len() - 1,
            file.display()
        );
    }
    Ok(())
}

/// `--trace`'s rows for one measured step: one per Newton iteration.
fn trace_rows(
    (case, ordering, set, step): (&str, OrderingSpec, &str, usize),
    r: &femp::StepReport,
    rows: &mut Vec<String>,
) {
    // A CSV field in quotes, its own quotes doubled (`--set` values are JSON).
    let set = set.replace('"', "\"\"");
    let mut solve = 0;
    for (rec, on) in r.stats.trace.iter().zip(&r.largest_increments) {
        if rec.iteration == 1 {
            solve += 1;
        }
        let (kind, index, body, axis, mass) = match *on {
            femp::Unknown::GridNode { node, axis, mass } => {
                ("grid", node, String::new(), axis, mass)
            }
            femp::Unknown::FemVertex {
                body,
                vertex,
                axis,
                mass,
            } => ("fem", vertex, body.to_string(), axis, mass),
        };
        let limit = match rec.bound.1 {
            None => "",
            Some(femp::StepLimit::Ccd) => "ccd",
            Some(femp::StepLimit::DetF) => "det_f",
            Some(femp::StepLimit::Other) => "other",
        };
        rows.push(format!(
            "{case},{ordering:?},\"{set}\",{step},{solve},{},{:e},{kind},{index},{body},{axis},{mass:e},{:e},{},{},{},{:e},{:e},{limit},{:e},{},{:e}",
            rec.iteration,
            rec.increment,
            rec.largest.1,
            rec.exact,
            rec.reused,
            rec.modelled,
            rec.predicted,
            rec.bound.0,
            rec.alpha,
            rec.backtracks,
            rec.change,
        ));
    }
}

/// Each value asked for, or `None` (the scene's own setting) if none was.
fn variants<T: Copy>(asked: &[T]) -> Vec<Option<T>> {
    if asked.is_empty() {
        vec![None]
    } else {
        asked.iter().copied().map(Some).collect()
    }
}

/// Scene fields set by `--set`: (dotted path, value).
type Settings = [crate::settings::Setting];

/// Every combination of one value per `--set` key (one empty combination without `--set`).
fn combinations(
    sets: &[(String, Vec<serde_json::Value>)],
) -> Vec<Vec<(String, serde_json::Value)>> {
    let mut out = vec![Vec::new()];
    for (key, values) in sets {
        out = out
            .iter()
            .flat_map(|c: &Vec<(String, serde_json::Value)>| {
                values.iter().map(move |v| {
                    let mut c = c.clone();
                    c.push((key.clone(), v.clone()));
                    c
                })
            })
            .collect();
    }
    out
}

/// The scene file with each `(dotted path, value)` set ([`crate::settings::set`]).
fn scene_with(path: &Path, set: &Settings) -> Result<scene::Scene> {
    if set.is_empty() {
        return Ok(scene::load(path)?);
    }
    let text = std::fs::read_to_string(path).with_context(|| path.display().to_string())?;
    let mut json: serde_json::Value = serde_json::from_str(&text)?;
    for (key, value) in set {
        crate::settings::set(&mut json, key, value)?;
    }
    let stem = path
        .file_stem()
        .map_or_else(|| "scene".to_string(), |s| s.to_string_lossy().into_owned());
    let file = format!("{} (with --set)", path.display());
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    Ok(scene::parse(&json.to_string(), &file, base, &stem)?)
}

fn run_case(
    root: &Path,
    case: &Case,
    (ordering, below, test, set): (OrderingSpec, Option<f64>, Option<NewtonTestSpec>, &Settings),
    (warm, steps): (usize, usize),
    mut trace: Option<&mut Vec<String>>,
) -> Result<()> {
    let dir = root.join("fixtures/scenes");
    let s = scene_with(&dir.join(case.file), set)?;
    let set = crate::settings::label(set);
    let mut spec = s.spec().clone();
    spec.solver.ordering = ordering;
    if let Some(b) = below {
        spec.solver.friction_update_below = b;
    }
    if let Some(t) = test {
        spec.solver.newton_test = t;
    }
    let s = s.with_spec(&spec)?;
    let below = s.spec().solver.friction_update_below;
    let test = s.spec().solver.newton_test;
    let mut world = World::<3>::build(s)?;
    for _ in 0..warm {
        world.step()?;
    }
    world.record_newton_iterations(trace.is_some());
    let (mut newton, mut wall) = (0usize, 0.0f64);
    for _ in 0..steps {
        let clock = Instant::now();
        let r = world.step()?;
        let w = clock.elapsed().as_secs_f64();
        newton += r.newton_iterations;
        wall += w;
        if let Some(rows) = trace.as_deref_mut() {
            trace_rows((case.name, ordering, &set, world.clock.step), &r, rows);
        }
        let st = &r.stats;
        println!(
            "| {} | {:?} | {below} | {test:?} | {set} | {} | {:.3} | {} | {} | {} | {} | {} | {w:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {} | {} | {} | {} |",
            case.name,
            ordering,
            world.clock.step,
            world.clock.time,
            r.newton_iterations,
            r.friction_iterations,
            if r.friction_converged { "yes" } else { "no" },
            r.contact_terms,
            st.reused_hessians,
            st.assembly_s,
            st.symbolic_s,
            st.numeric_s,
            st.solve_s,
            st.pcg_s,
            st.line_search_s,
            st.refine_iterations,
            st.double_fallbacks,
            st.model_directions,
            st.expanded_steps
        );
    }
    println!(
        "| {} | {:?} | {below} | {test:?} | {set} | mean | | {:.1} | | | | | {:.2} | | | | | | | | | | |",
        case.name,
        ordering,
        newton as f64 / steps as f64,
        wall / steps as f64
    );
    Ok(())
}
