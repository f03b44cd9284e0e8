//! `cargo xtask validate`: the papers' experiments run through `femp` as a library, each figure
//! compared with the analytic answer or the paper's number, one table, charts and a report.
//!
//! ```text
//! cargo xtask validate [--quick | --full] [--only NAME…] [--jobs N] [--out DIR] [--publish]
//!                       [--set KEY=VALUE …]
//! ```
//!
//! The quick tier (default) uses coarser resolutions that keep each check meaningful; the full
//! tier uses the papers' parameters and rewrites `docs/validation/`. Every failure is collected;
//! the exit code is non-zero if any check fails.

mod analysis;
mod augury;
mod buckling;
mod charts;
mod compact;
mod compare;
mod ctx;
mod disk;
mod experiment;
mod fixtures;
mod hertz;
mod outcome;
mod refinement;
mod report;
mod rings;
mod saved;
mod scenes;
mod sine;
mod slope;
mod speed;
mod stability;
mod twist;
mod workers;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};

use crate::settings::{self, Setting};

pub use compact::compact_png;
pub use ctx::{Ctx, Pictures};
pub use outcome::{Check, Outcome, Status, Tier};
use saved::{Done, git_describe, load, save, utc_minute};
pub use scenes::{contact, fem_body, mpm_body, mpm_grid};
use workers::{run_workers, say};

/// The largest total-energy gain over E₀ (a fraction of E₀) still counted as round-off: the
/// bound of every "energy never above E₀" row, and of a note saying the energy rose.
const ROUND_OFF_GAIN: f64 = 1e-9;

struct Experiment {
    name: &'static str,
    section: &'static str,
    title: &'static str,
    run: fn(&Ctx) -> Result<Outcome>,
    /// Wall times to expect in each tier, `(quick, full)`, balancing `--jobs` when the output
    /// directory has no saved outcome to go by (a fresh clone). Quick: measured in CI (clean
    /// clone at a5494da, 2-core Intel Xeon 2.0 GHz; twist and buckling as trimmed on
    /// 2026-12-03, measured with `--only twist buckling --jobs 2`); 0 for an experiment the
    /// quick tier does not run. Full: a full run at afa838f on the 2-core development machine,
    /// two experiments at a time (three for its last half hour; `compare`, `disk_plates`,
    /// `stability` and part of `fixtures` and `twist_fine` estimated from earlier runs).
    wall_s: (f64, f64),
    /// The tiers it belongs to.
    runs: Runs,
}

/// Which runs of the suite an experiment belongs to.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Runs {
    /// Both tiers.
    Always,
    /// The full tier only (the quick tier neither runs nor lists it).
    Full,
    /// The full tier, only when named by `--only` (hours a case); listed once it has an outcome.
    FullWhenNamed,
}

impl Experiment {
    /// Whether `tier` runs this experiment when `--only` does not name it.
    fn by_default(&self, tier: Tier) -> bool {
        match self.runs {
            Runs::Always => true,
            Runs::Full => tier == Tier::Full,
            Runs::FullWhenNamed => false,
        }
    }

    /// Whether `tier` can run it at all.
    fn in_tier(&self, tier: Tier) -> bool {
        self.runs == Runs::Always || tier == Tier::Full
    }

    /// The wall time to expect in `tier` with no saved outcome to go by.
    fn expected_s(&self, tier: Tier) -> f64 {
        match tier {
            Tier::Quick => self.wall_s.0,
            Tier::Full => self.wall_s.1,
        }
    }
}

const EXPERIMENTS: &[Experiment] = &[
    Experiment {
        name: "rings",
        section: "BFEMP 6.1",
        title: "MPM ring vs FEM ring at 40 m/s: momentum, energy, non-penetration",
        run: experiment::drive::<rings::Rings>,
        wall_s: (180.0, 2631.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "sine_boundary",
        section: "BFEMP 6.2",
        title: "FEM sine-wave boundary vs level-set slip boundary",
        run: experiment::drive::<sine::Sine>,
        wall_s: (110.0, 422.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "hertz",
        section: "BFEMP 6.3",
        title: "Brazilian disk: force vs contact radius against 2D Hertz",
        run: experiment::drive::<hertz::Hertz>,
        wall_s: (20.0, 100.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "slope",
        section: "BFEMP 6.4",
        title: "Stiff MPM box on a frictional FEM slope: g(sinθ − μcosθ), sticking at μ = tanθ",
        run: experiment::drive::<slope::Slope>,
        wall_s: (42.0, 62.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "refinement",
        section: "BFEMP 6.5",
        title: "MPM box on FEM box under refinement: convergence order",
        run: experiment::drive::<refinement::Refinement>,
        wall_s: (54.0, 529.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "buckling",
        section: "BFEMP 6.6",
        title: "Semicircular rings compressed: buckling order vs μ",
        run: experiment::drive::<buckling::Buckling>,
        wall_s: (176.0, 1251.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "twist",
        section: "BFEMP 6.7",
        title: "3D shell twisting an MPM cube: slip angles vs μ",
        run: experiment::drive::<twist::Twist<twist::Fixture>>,
        wall_s: (158.0, 1510.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "twist_fine",
        section: "BFEMP 6.7",
        title: "3D shell twisting an MPM cube at h = 0.125: slip angles vs μ",
        run: experiment::drive::<twist::Twist<twist::Fine>>,
        // μ = 0 / 0.2 / 0.5 at afa838f: 935 / 1 858 / 3 335 s; μ = 1 estimated as 1.38× μ = 0.5's
        // (their ratio at 93949fc).
        wall_s: (0.0, 10700.0),
        runs: Runs::Full,
    },
    Experiment {
        name: "twist_paper",
        section: "BFEMP 6.7",
        title: "3D shell twisting an MPM cube at the paper's h = 0.0625: μ = 0.2",
        run: experiment::drive::<twist::Twist<twist::Paper>>,
        // Not run yet: 3–4 h estimated (docs/performance.md, the twist at h = 0.0625).
        wall_s: (0.0, 13000.0),
        runs: Runs::FullWhenNamed,
    },
    Experiment {
        name: "twist_paper_mu1",
        section: "BFEMP 6.7",
        title: "3D shell twisting an MPM cube at the paper's h = 0.0625: μ = 1",
        run: experiment::drive::<twist::Twist<twist::PaperMu1>>,
        // Not run yet: 6–8 h estimated.
        wall_s: (0.0, 23000.0),
        runs: Runs::FullWhenNamed,
    },
    Experiment {
        name: "two_particles",
        section: "augury 3.1",
        title: "Two particles in one cell, APIC vs PIC",
        run: experiment::drive::<augury::TwoParticles>,
        wall_s: (0.1, 0.1),
        runs: Runs::Always,
    },
    Experiment {
        name: "blocks_impact",
        section: "augury 3.2",
        title: "Two blocks impacting at an angle: exact momenta",
        run: experiment::drive::<augury::blocks::Blocks>,
        wall_s: (32.0, 1468.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "ramp",
        section: "augury 3.3",
        title: "Block sliding down a 30° ramp",
        run: experiment::drive::<augury::ramp::Ramp>,
        wall_s: (41.0, 499.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "augury_speed",
        section: "augury 4",
        title: "Speed: augury contact against the search-based penalty baseline, 10³–10⁶ nodes",
        run: experiment::drive::<speed::Speed>,
        wall_s: (5.0, 175.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "compare",
        section: "both papers",
        title: "Speed vs accuracy: block sliding down a ramp, BFEMP / augury / penalty",
        run: experiment::drive::<compare::Compare>,
        wall_s: (90.0, 700.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "disk_plates",
        section: "both papers",
        title: "Speed vs accuracy: a disk pressed between plates (Hertz), BFEMP / augury / penalty",
        run: experiment::drive::<disk::Disk>,
        wall_s: (86.0, 600.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "stability",
        section: "both papers",
        title: "Stability maps: time step against impact speed",
        run: experiment::drive::<stability::Stability>,
        wall_s: (7.0, 20.0),
        runs: Runs::Always,
    },
    Experiment {
        name: "fixtures",
        section: "shipped scenes",
        title: "Every fixtures/scenes/*.json runs to completion as committed",
        run: experiment::drive::<fixtures::Fixtures>,
        wall_s: (45.0, 2800.0),
        runs: Runs::Always,
    },
];

const USAGE: &str =
    "usage: cargo xtask validate [--quick | --full] [--only NAME…] [--jobs N] [--report] \
     [--out DIR] [--publish] [--set KEY=VALUE …] [--resume]

  --quick    coarse resolutions, minutes (default)
  --full     the papers' parameters (hours); with no --only, publishes to docs/validation/full/
  --only     run only these experiments; the report also shows every other experiment's saved
             outcome in the output directory (so a long tier can be run a piece at a time)
  --jobs     run the experiments in N processes at once (balanced by expected wall time); the
             checks are the same, the wall times overlap (marked ‖ in the report). CI uses 2.
             With one experiment: its cases in N lanes at once, the longest first
  --report   run nothing: assemble the report from the saved outcomes
  --out      output directory (default target/validation/<tier>)
  --publish  copy the report and what it shows into docs/validation/ (quick) or
             docs/validation/full/ (full)
  --set      run every BFEMP scene of the suite with a field set by its dotted path
             (`--set solver.projection=when_indefinite`; VALUE is JSON, or else a string;
             repeatable), to measure a setting on the whole suite before it becomes a default.
             The report says so; the output directory defaults to target/validation/<tier>-set
             and holds outcomes of one set of settings only; nothing is published
  --resume   runs that write checkpoints (twist_paper, twist_paper_mu1: hours a run) continue
             from their last one in the output directory instead of starting again — the same
             results as a run never stopped; a run without a checkpoint starts";

/// What `cargo xtask validate` was asked to do.
struct Args {
    tier: Tier,
    only: Vec<String>,
    publish: bool,
    report_only: bool,
    jobs: usize,
    worker: bool,
    out: Option<PathBuf>,
    set: Vec<Setting>,
    resume: bool,
}

/// The arguments after `validate`; `None` after printing the help.
fn parse_args(args: &[String]) -> Result<Option<Args>> {
    let mut tier = Tier::Quick;
    let mut only: Vec<String> = Vec::new();
    let mut publish = false;
    let mut report_only = false;
    let mut jobs = 1usize;
    let mut worker = false;
    let mut out: Option<PathBuf> = None;
    let mut set = Vec::new();
    let mut resume = false;
    let mut it = args.iter().peekable();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--quick" => tier = Tier::Quick,
            "--publish" => publish = true,
            "--report" => report_only = true,
            // One of `--jobs`' processes: saves outcomes, writes no report.
            "--worker" => worker = true,
            "--jobs" => {
                jobs = match it.next().map(|n| n.parse::<usize>()) {
                    Some(Ok(n)) if n >= 1 => n,
                    Some(_) => bail!("--jobs needs a whole number ≥ 1\n{USAGE}"),
                    None => bail!("--jobs needs a number\n{USAGE}"),
                }
            }
            "--full" => tier = Tier::Full,
            "--resume" => resume = true,
            "--out" => match it.next() {
                Some(d) => out = Some(PathBuf::from(d)),
                None => bail!("--out needs a directory\n{USAGE}"),
            },
            "--set" => {
                let kv = it
                    .next()
                    .with_context(|| format!("--set needs KEY=VALUE\n{USAGE}"))?;
                let (key, value) = settings::split(kv)
                    .with_context(|| format!("`--set {kv}` is not KEY=VALUE\n{USAGE}"))?;
                set.push((key.to_string(), settings::value(value)));
            }
            "--only" => {
                while let Some(n) = it.next_if(|n| !n.starts_with("--")) {
                    only.push(n.clone());
                }
                if only.is_empty() {
                    bail!("--only needs experiment names\n{USAGE}");
                }
            }
            "-h" | "--help" => {
                println!("{USAGE}\n\nexperiments:");
                for e in EXPERIMENTS {
                    let tiers = match e.runs {
                        Runs::Always => "",
                        Runs::Full => " [full tier]",
                        Runs::FullWhenNamed => " [full tier, only when named]",
                    };
                    println!("  {:15} {:11} {}{tiers}", e.name, e.section, e.title);
                }
                return Ok(None);
            }
            other => bail!("unknown argument `{other}`\n{USAGE}"),
        }
    }
    if publish && !set.is_empty() {
        bail!(
            "--publish cannot be combined with --set: the published reports are of the suite's \
             own settings\n{USAGE}"
        );
    }
    if report_only && !only.is_empty() {
        bail!("--report runs nothing; it cannot be combined with --only\n{USAGE}");
    }
    for n in &only {
        let Some(e) = EXPERIMENTS.iter().find(|e| e.name == n) else {
            let names: Vec<_> = EXPERIMENTS.iter().map(|e| e.name).collect();
            bail!("no experiment `{n}`; experiments: {}", names.join(", "));
        };
        if !e.in_tier(tier) {
            bail!("`{n}` runs in the full tier only: `--full --only {n}`\n{USAGE}");
        }
    }
    Ok(Some(Args {
        tier,
        only,
        publish,
        report_only,
        jobs,
        worker,
        out,
        set,
        resume,
    }))
}

/// Where a tier's outputs go without `--out`: `target/validation/<tier>`, or `<tier>-set` for
/// runs with `--set` (their outcomes are not the suite's own).
fn default_out(root: &std::path::Path, tier: Tier, set: &[Setting]) -> PathBuf {
    let dir = if set.is_empty() {
        tier.name().to_string()
    } else {
        format!("{}-set", tier.name())
    };
    root.join("target/validation").join(dir)
}

/// Entry point: parse `args` (after `validate`), run, print, report.
pub fn main(args: &[String]) -> Result<()> {
    let Some(Args {
        tier,
        only,
        publish,
        report_only,
        jobs,
        worker,
        out,
        set,
        resume,
    }) = parse_args(args)?
    else {
        return Ok(());
    };
    let root = workspace_root();
    // The code that runs is the code this binary was built from.
    let commit = git_describe();
    let settings = settings::labels(&set);
    let out = out.unwrap_or_else(|| default_out(&root, tier, &set));
    std::fs::create_dir_all(&out)?;
    // Before anything runs: the directory's saved outcomes are of these settings (`load`).
    for e in EXPERIMENTS {
        load(&out, e.name, tier, &settings)?;
    }
    let progress = indicatif::MultiProgress::new();
    let started = Instant::now();
    let mut done = Vec::new();
    let mut ran = 0;
    let selected = selection(tier, &only, report_only);
    let parallel = jobs > 1 && selected.len() > 1 && !worker;
    if parallel {
        run_workers(&selected, jobs, tier, &out, &set, resume)?;
    }
    // Experiments run only when named: listed once they have an outcome in `out`.
    let mut unnamed = Vec::new();
    for e in EXPERIMENTS {
        if !e.in_tier(tier) {
            continue;
        }
        if e.runs == Runs::FullWhenNamed
            && !selected.contains(&e.name)
            && load(&out, e.name, tier, &settings)?.is_none()
        {
            unnamed.push(e.name);
            continue;
        }
        if parallel {
            // Run by a worker: a missing outcome means the worker died before saving it.
            let fresh = selected.contains(&e.name);
            let mut d = Done::saved(e, load(&out, e.name, tier, &settings)?, fresh);
            if fresh && d.outcome.is_none() {
                d.outcome = Some(Err(
                    "its worker process stopped before saving an outcome (see its output above)"
                        .into(),
                ));
            }
            done.push(d);
            ran += usize::from(fresh);
            continue;
        }
        if !selected.contains(&e.name) {
            done.push(Done::saved(e, load(&out, e.name, tier, &settings)?, false));
            continue;
        }
        say(
            &progress,
            format!("{} ({}): {}", e.name, e.section, e.title),
        );
        let ctx = Ctx {
            tier,
            dir: out.join(e.name),
            charts: out.join("charts"),
            root: root.clone(),
            progress: progress.clone(),
            pictured: Default::default(),
            settings: set.clone(),
            case_lanes: if selected.len() == 1 { jobs } else { 1 },
            resume,
        };
        let t = Instant::now();
        let outcome = (e.run)(&ctx)
            .and_then(|mut o| {
                ctx.collect_pictures(&mut o)?;
                Ok(o)
            })
            .map_err(|err| format!("{err:#}"));
        let wall_s = t.elapsed().as_secs_f64();
        let saved = save(
            (&commit, &settings),
            &out,
            e.name,
            tier,
            wall_s,
            worker,
            &outcome,
        )?;
        let d = Done {
            name: e.name,
            section: e.section,
            title: e.title,
            wall_s,
            outcome: Some(outcome),
            finished: utc_minute(saved.finished_unix),
            commit: saved.commit,
            fresh: true,
            concurrent: worker,
        };
        say(&progress, report::rows(&d).join("\n"));
        done.push(d);
        ran += 1;
    }
    let total = started.elapsed().as_secs_f64();
    if !worker {
        println!("\n{}", report::table(&done));
    }
    // The exit code answers for what this invocation ran (for `--report`, for everything).
    let failed = report::failures(done.iter().filter(|d| d.fresh || report_only));
    if worker {
        // The parent process assembles the report once every worker has finished.
        if failed > 0 {
            bail!("{failed} check(s) failed");
        }
        return Ok(());
    }
    report::write(&out, tier, &done, &unnamed, &settings)?;
    println!("report: {}", out.join("README.md").display());
    if (tier == Tier::Full && only.is_empty() && !report_only && set.is_empty()) || publish {
        let docs = match tier {
            Tier::Quick => root.join("docs/validation"),
            Tier::Full => root.join("docs/validation/full"),
        };
        report::publish(&out, &docs)?;
        println!("published to {}", docs.display());
    }
    println!(
        "{ran} experiment(s) run, total wall time {total:.1} s ({} tier)",
        tier.name()
    );
    if failed > 0 {
        bail!("{failed} check(s) failed");
    }
    Ok(())
}

/// The experiments to run: those `only` names, else those `tier` runs by default (none with
/// `--report`), in the registry's order.
fn selection(tier: Tier, only: &[String], report_only: bool) -> Vec<&'static str> {
    EXPERIMENTS
        .iter()
        .filter(|e| {
            !report_only
                && if only.is_empty() {
                    e.by_default(tier)
                } else {
                    only.iter().any(|n| n == e.name)
                }
        })
        .map(|e| e.name)
        .collect()
}

/// Least-squares slope of the line through `(x, y)` points.
pub fn least_squares_slope(pts: &[(f64, f64)]) -> f64 {
    let n = pts.len() as f64;
    let (mx, my) = pts
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p.0 / n, b + p.1 / n));
    let (mut num, mut den) = (0.0, 0.0);
    for &(x, y) in pts {
        num += (x - mx) * (y - my);
        den += (x - mx) * (x - mx);
    }
    num / den
}

pub(crate) fn workspace_root() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    here.parent().unwrap_or(here).to_path_buf()
}

/// How deep a run's deepest point went inside another body, and whether any passed through
/// one, for a report row (issue 43: penetration reported with its depth, not only a count).
pub(crate) fn analysis_depth(s: &femp::output::Summary) -> String {
    let mut out = match &s.deepest_penetration {
        None => "no vertex inside another body".to_string(),
        Some(d) => format!("deepest {d}"),
    };
    if s.passed_through_steps > 0 {
        out += &format!(
            "; a vertex passed through a body in {} step(s)",
            s.passed_through_steps
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::workers::partition;
    use super::*;

    #[test]
    fn utc_minute_is_the_civil_date() {
        assert_eq!(utc_minute(0), "1970-01-01 00:00 UTC");
        // 2000-02-29 12:34 UTC (a leap day) and 2026-12-01 18:45 UTC.
        assert_eq!(utc_minute(951_827_640), "2000-02-29 12:34 UTC");
        assert_eq!(utc_minute(1_796_150_700), "2026-12-01 18:45 UTC");
    }

    #[test]
    fn a_saved_outcome_loads_back_with_its_paths_under_the_output_directory() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let outcome = Ok(Outcome {
            checks: vec![
                Check::rel("x", 1.0, 1.0, 0.1, " m"),
                Check::info("y", "2".into(), "—".into()),
            ],
            charts: vec![("chart".into(), out.join("charts/a.png"))],
            notes: vec!["a note".into()],
            pictures: vec![("scene".into(), vec![out.join("charts/scene_k.png")])],
        });
        save(
            ("abc1234", &[]),
            out,
            "demo",
            Tier::Full,
            12.5,
            true,
            &outcome,
        )
        .unwrap();
        let text = std::fs::read_to_string(out.join("demo/outcome.json")).unwrap();
        assert!(
            text.contains("\"charts/a.png\""),
            "paths saved relative: {text}"
        );
        let saved = load(out, "demo", Tier::Full, &[]).unwrap().expect("saved");
        assert_eq!(saved.commit, "abc1234");
        assert_eq!(saved.wall_s, 12.5);
        assert!(saved.concurrent);
        let o = saved.outcome.unwrap();
        assert_eq!(o.checks.len(), 2);
        assert_eq!(o.checks[0].status, Status::Pass);
        assert_eq!(o.checks[1].measured, "2");
        assert_eq!(o.charts[0].1, out.join("charts/a.png"));
        assert_eq!(o.pictures[0].1[0], out.join("charts/scene_k.png"));
        assert_eq!(o.notes, vec!["a note".to_string()]);
        // Another tier's outcome is not this tier's; nothing saved is `None`.
        assert!(load(out, "demo", Tier::Quick, &[]).unwrap().is_none());
        assert!(load(out, "other", Tier::Full, &[]).unwrap().is_none());
        // A damaged file is an error that names it.
        std::fs::write(out.join("demo/outcome.json"), "{").unwrap();
        let err = format!("{:#}", load(out, "demo", Tier::Full, &[]).err().unwrap());
        assert!(err.contains("demo/outcome.json"), "{err}");
        // A failed run is saved as its error.
        save(
            ("abc1234", &[]),
            out,
            "bad",
            Tier::Full,
            1.0,
            false,
            &Err("it broke".into()),
        )
        .unwrap();
        let bad = load(out, "bad", Tier::Full, &[]).unwrap().unwrap();
        assert!(!bad.concurrent);
        assert_eq!(bad.outcome.err().unwrap(), "it broke");
        // Saved before `--jobs` existed (no `concurrent` field): not concurrent.
        let old = r#"{"tier": "full", "wall_s": 3.0, "finished_unix": 0, "commit": "c",
            "outcome": {"Err": "old"}}"#;
        std::fs::write(out.join("bad/outcome.json"), old).unwrap();
        let old = load(out, "bad", Tier::Full, &[]).unwrap().unwrap();
        assert!(!old.concurrent);
        assert_eq!(old.wall_s, 3.0);
        // Saved with `--set`: loads back with the same settings only; with others, or none,
        // it is an error that names the file and both sets of settings.
        let set = vec!["solver.projection=\"when_indefinite\"".to_string()];
        let save_demo = |settings: &[String]| {
            save(
                ("abc1234", settings),
                out,
                "demo",
                Tier::Full,
                1.0,
                false,
                &outcome,
            )
            .unwrap();
            std::fs::read_to_string(out.join("demo/outcome.json")).unwrap()
        };
        let text = save_demo(&set);
        assert!(text.contains("when_indefinite"), "{text}");
        let back = load(out, "demo", Tier::Full, &set).unwrap().unwrap();
        assert_eq!(back.settings, set);
        let err = format!("{:#}", load(out, "demo", Tier::Full, &[]).err().unwrap());
        assert!(
            err.contains("demo/outcome.json")
                && err.contains("--set solver.projection")
                && err.contains("this run has no --set"),
            "{err}"
        );
        let other = vec!["solver.newton_test=\"points\"".to_string()];
        assert!(load(out, "demo", Tier::Full, &other).is_err());
        // Without `--set` nothing is written of settings (outcomes as before).
        let text = save_demo(&[]);
        assert!(!text.contains("settings"), "{text}");
    }

    /// On a fresh clone (no saved outcomes) `--jobs` balances by the expected wall times: every
    /// experiment has one for each tier it runs in, and the full tier's default run splits
    /// into two lanes the longer of which is within 10 % of half the total.
    #[test]
    fn a_fresh_full_tier_splits_into_balanced_lanes() {
        for e in EXPERIMENTS {
            for tier in [Tier::Quick, Tier::Full] {
                if e.in_tier(tier) {
                    assert!(e.expected_s(tier) > 0.0, "{} in {}", e.name, tier.name());
                }
            }
        }
        let cost: Vec<(f64, &str)> = EXPERIMENTS
            .iter()
            .filter(|e| e.by_default(Tier::Full))
            .map(|e| (e.expected_s(Tier::Full), e.name))
            .collect();
        let total: f64 = cost.iter().map(|c| c.0).sum();
        let lanes = partition(cost, 2);
        let longest = lanes.iter().map(|l| l.0).fold(0.0, f64::max);
        assert!(
            longest <= 0.55 * total,
            "{longest} s of {total} s: {lanes:?}"
        );
    }

    /// The quick tier neither runs nor accepts the full-tier-only twists; the full tier runs
    /// `twist_fine` by default and `twist_paper` only when named.
    #[test]
    fn each_tier_runs_its_experiments() {
        let find = |n: &str| EXPERIMENTS.iter().find(|e| e.name == n).unwrap();
        let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        for (name, quick, full) in [
            ("twist", true, true),
            ("twist_fine", false, true),
            ("twist_paper", false, false),
            ("twist_paper_mu1", false, false),
        ] {
            let e = find(name);
            assert_eq!(e.by_default(Tier::Quick), quick, "{name}");
            assert_eq!(e.by_default(Tier::Full), full, "{name}");
            assert!(e.in_tier(Tier::Full), "{name}");
            assert_eq!(e.in_tier(Tier::Quick), quick, "{name}");
        }
        for n in ["twist_fine", "twist_paper", "twist_paper_mu1"] {
            let err = parse_args(&args(&["--only", n]))
                .err()
                .expect(n)
                .to_string();
            assert!(err.contains("full tier only"), "{err}");
            let ok = parse_args(&args(&["--full", "--only", n]))
                .unwrap()
                .unwrap();
            assert_eq!(ok.only, [n]);
        }
        // Every experiment but the two run only when named is in the full tier's default run;
        // naming one runs it; `--report` runs nothing.
        let full = selection(Tier::Full, &[], false);
        assert_eq!(full.len(), EXPERIMENTS.len() - 2);
        assert!(!full.contains(&"twist_paper") && !full.contains(&"twist_paper_mu1"));
        let quick = selection(Tier::Quick, &[], false);
        assert_eq!(quick.len(), EXPERIMENTS.len() - 3);
        assert!(!quick.contains(&"twist_fine"));
        assert_eq!(
            selection(Tier::Full, &args(&["twist_paper", "rings"]), false),
            ["rings", "twist_paper"]
        );
        assert!(selection(Tier::Full, &[], true).is_empty());
    }

    #[test]
    fn jobs_share_the_experiments_longest_first_onto_the_least_loaded() {
        let cost = vec![
            (10.0, "a"),
            (245.0, "twist"),
            (219.0, "buckling"),
            (113.0, "rings"),
            (76.0, "compare"),
            (6.0, "b"),
        ];
        let groups = partition(cost.clone(), 2);
        assert_eq!(groups.len(), 2);
        assert_eq!(groups[0].1[0], "twist");
        assert_eq!(groups[1].1[0], "buckling");
        // Every experiment exactly once, and the loads add up.
        let mut all: Vec<&str> = groups.iter().flat_map(|g| g.1.clone()).collect();
        all.sort_unstable();
        assert_eq!(all, ["a", "b", "buckling", "compare", "rings", "twist"]);
        let load: f64 = groups.iter().map(|g| g.0).sum();
        assert_eq!(load, cost.iter().map(|c| c.0).sum::<f64>());
        // Balanced to within the smallest item that could still move.
        assert!((groups[0].0 - groups[1].0).abs() <= 76.0, "{groups:?}");
        // More jobs than experiments: one each.
        assert_eq!(partition(cost[..2].to_vec(), 4).len(), 2);
    }
}
