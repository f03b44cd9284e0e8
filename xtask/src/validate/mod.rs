//! `cargo xtask validate`: the papers' experiments run through `femp` as a library, each figure
//! compared with the analytic answer or the paper's number, one table, charts and a report.
//!
//! ```text
//! cargo xtask validate [--quick | --full] [--only NAME…] [--jobs N] [--out DIR] [--publish]
//! ```
//!
//! The quick tier (default) uses coarser resolutions that keep each check meaningful; the full
//! tier uses the papers' parameters and rewrites `docs/validation/`. Every failure is collected;
//! the exit code is non-zero if any check fails.

mod augury;
mod buckling;
mod charts;
mod compact;
mod compare;
mod disk;
mod fixtures;
mod hertz;
mod refinement;
mod report;
mod rings;
mod scenes;
mod sine;
mod slope;
mod stability;
mod twist;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use femp::metrics::Metrics;
use femp::run::{RunOptions, RunResult, run_with};
use femp::scene::{BodySpec, ContactSpec, FemBody, MpmBody, MpmSpec, SceneSpec};

/// Resolution tier.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Tier {
    /// Coarse, minutes (CI).
    Quick,
    /// The papers' parameters.
    Full,
}

impl Tier {
    fn name(self) -> &'static str {
        match self {
            Tier::Quick => "quick",
            Tier::Full => "full",
        }
    }
}

/// Outcome of one check.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Status {
    /// Within tolerance.
    Pass,
    /// Outside tolerance.
    Fail,
    /// A figure reported against the paper without a pass/fail criterion (say why in `note`).
    Info,
}

impl Status {
    fn label(self) -> &'static str {
        match self {
            Status::Pass => "PASS",
            Status::Fail => "FAIL",
            Status::Info => "INFO",
        }
    }
}

/// One row of the table.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Check {
    /// What is measured.
    pub figure: String,
    /// Measured value, formatted.
    pub measured: String,
    /// Expected value, formatted.
    pub expected: String,
    /// Tolerance, formatted.
    pub tolerance: String,
    /// Outcome.
    pub status: Status,
}

impl Check {
    /// `|measured − expected| ≤ tol` (absolute).
    pub fn abs(figure: &str, measured: f64, expected: f64, tol: f64, unit: &str) -> Self {
        let ok = (measured - expected).abs() <= tol;
        Self {
            figure: figure.into(),
            measured: format!("{measured:.6e}{unit}"),
            expected: format!("{expected:.6e}{unit}"),
            tolerance: format!("± {tol:.1e}{unit}"),
            status: if ok { Status::Pass } else { Status::Fail },
        }
    }

    /// `|measured − expected| ≤ rel · |expected|`.
    pub fn rel(figure: &str, measured: f64, expected: f64, rel: f64, unit: &str) -> Self {
        let ok = (measured - expected).abs() <= rel * expected.abs();
        Self {
            figure: figure.into(),
            measured: format!("{measured:.6e}{unit}"),
            expected: format!("{expected:.6e}{unit}"),
            tolerance: format!("± {:.2e} rel", rel),
            status: if ok { Status::Pass } else { Status::Fail },
        }
    }

    /// `measured ≤ bound`.
    pub fn at_most(figure: &str, measured: f64, bound: f64, unit: &str) -> Self {
        Self {
            figure: figure.into(),
            measured: format!("{measured:.3e}{unit}"),
            expected: format!("≤ {bound:.3e}{unit}"),
            tolerance: "—".into(),
            status: if measured <= bound {
                Status::Pass
            } else {
                Status::Fail
            },
        }
    }

    /// A count that must be exactly `expected`.
    pub fn count(figure: &str, measured: usize, expected: usize) -> Self {
        Self {
            figure: figure.into(),
            measured: measured.to_string(),
            expected: expected.to_string(),
            tolerance: "exact".into(),
            status: if measured == expected {
                Status::Pass
            } else {
                Status::Fail
            },
        }
    }

    /// A run that should have reached `expected` but stopped at `measured`: always a failure.
    pub fn stopped(figure: String, measured: String, expected: String) -> Self {
        Self {
            figure,
            measured,
            expected,
            tolerance: "—".into(),
            status: Status::Fail,
        }
    }

    /// A condition that must hold (`ok`), with how it was measured.
    pub fn holds(
        figure: &str,
        measured: String,
        expected: &str,
        tolerance: &str,
        ok: bool,
    ) -> Self {
        Self {
            figure: figure.into(),
            measured,
            expected: expected.into(),
            tolerance: tolerance.into(),
            status: if ok { Status::Pass } else { Status::Fail },
        }
    }

    /// A reported figure.
    pub fn info(figure: &str, measured: String, expected: String) -> Self {
        Self {
            figure: figure.into(),
            measured,
            expected,
            tolerance: "—".into(),
            status: Status::Info,
        }
    }
}

/// What one experiment produced.
#[derive(Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Outcome {
    /// Rows of the table.
    pub checks: Vec<Check>,
    /// Charts (PNG paths, relative to the output directory).
    pub charts: Vec<(String, PathBuf)>,
    /// Plain-language notes for the report (where a result differs from the paper, and by how
    /// much; what the scene is).
    pub notes: Vec<String>,
    /// Scene pictures: a caption and its images (key frames, then an animation), shown in a row.
    pub pictures: Vec<(String, Vec<PathBuf>)>,
}

/// The scene pictures the report shows of one run, chosen where the experiment starts the run
/// (`Pictures::keys("caption", 3).gif()`).
#[derive(Clone, Debug)]
pub struct Pictures {
    /// Caption in the report.
    caption: String,
    /// Key frames, evenly spaced from start to end.
    keys: usize,
    /// Show only the last key frame.
    last_only: bool,
    /// Make a GIF.
    gif: bool,
    /// The axis drawn up in 3D (`None`: against gravity).
    up: Option<usize>,
}

impl Pictures {
    /// `keys` key frames (at least 2: the first and the last) shown side by side under
    /// `caption`.
    pub fn keys(caption: impl Into<String>, keys: usize) -> Self {
        Self {
            caption: caption.into(),
            keys: keys.max(2),
            last_only: false,
            gif: false,
            up: None,
        }
    }

    /// Show only the last key frame.
    pub fn last_only(self) -> Self {
        Self {
            last_only: true,
            ..self
        }
    }

    /// Also make and show an animated GIF.
    pub fn gif(self) -> Self {
        Self { gif: true, ..self }
    }

    /// Draw 3D pictures with `axis` up.
    pub fn up(self, axis: usize) -> Self {
        Self {
            up: Some(axis),
            ..self
        }
    }
}

struct Experiment {
    name: &'static str,
    section: &'static str,
    title: &'static str,
    run: fn(&Ctx) -> Result<Outcome>,
    /// Quick-tier wall time measured in CI (clean clone at a5494da, 2-core Intel Xeon 2.0 GHz;
    /// twist and buckling as trimmed on 2026-12-03, measured with `--only twist buckling
    /// --jobs 2`): balances `--jobs` when the output directory has no saved outcome to go by.
    quick_s: f64,
}

/// Everything an experiment needs.
pub struct Ctx {
    /// Tier.
    pub tier: Tier,
    /// The experiment's own output directory.
    pub dir: PathBuf,
    /// Charts directory (shared).
    pub charts: PathBuf,
    /// Workspace root (for fixtures).
    pub root: PathBuf,
    progress: indicatif::MultiProgress,
    /// Pictured runs so far: label, caption, which files to show.
    pictured: std::cell::RefCell<Vec<(String, String, usize, bool)>>,
}

impl Ctx {
    /// Render options for `pictures` of the run `label`, which is remembered for
    /// [`Ctx::collect_pictures`].
    fn picture_options(
        &self,
        label: &str,
        pictures: Option<Pictures>,
    ) -> Option<femp::render::PictureOptions> {
        let Pictures {
            caption,
            keys,
            last_only,
            gif,
            up,
        } = pictures?;
        self.pictured
            .borrow_mut()
            .push((label.to_string(), caption, keys, last_only));
        Some(femp::render::PictureOptions {
            key_frames: keys,
            gif_frames: if gif { 30 } else { 0 },
            size: (320, 240),
            gif_delay_ms: 120,
            up,
        })
    }

    /// Copy the pictures of the runs made so far into the charts directory and list them in
    /// `out` (key frames side by side, then the GIF if there is one).
    fn collect_pictures(&self, out: &mut Outcome) -> Result<()> {
        for (label, caption, keys, last_only) in self.pictured.borrow_mut().drain(..) {
            let src = self.dir.join(&label).join("pictures");
            std::fs::create_dir_all(&self.charts)?;
            let mut files = Vec::new();
            let first = if last_only { keys - 1 } else { 0 };
            for k in first..keys {
                let name = format!("key_{k:02}.png");
                if !src.join(&name).exists() {
                    continue; // the run stopped early
                }
                let dst = self.charts.join(format!("scene_{label}_{name}"));
                std::fs::copy(src.join(&name), &dst)
                    .with_context(|| format!("copying {}", src.join(&name).display()))?;
                files.push(dst);
            }
            if src.join("animation.gif").exists() {
                let dst = self.charts.join(format!("scene_{label}.gif"));
                std::fs::copy(src.join("animation.gif"), &dst)?;
                files.push(dst);
            }
            out.pictures.push((caption, files));
        }
        Ok(())
    }

    /// The committed scene `fixtures/scenes/{name}.json` as a typed value to edit and run
    /// (through [`SceneSpec::to_json`]).
    pub fn fixture(&self, name: &str) -> Result<SceneSpec> {
        let path = self.root.join(format!("fixtures/scenes/{name}.json"));
        Ok(femp::scene::load(&path)?.spec)
    }

    /// `spec` parsed back from its text and validated, as `femp run` would read it (relative
    /// paths against `fixtures/scenes/`); the text is what the run copies into its directory.
    pub fn scene(&self, label: &str, spec: &SceneSpec) -> Result<femp::scene::Scene> {
        Ok(femp::scene::parse(
            &spec.to_json(),
            label,
            self.root.join("fixtures/scenes"),
            label,
        )?)
    }

    /// The 2D world of `spec`, built but not run (to probe it).
    pub fn probe(&self, spec: &SceneSpec) -> Result<femp::World<2>> {
        Ok(femp::World::<2>::build(self.scene("probe", spec)?)?)
    }

    /// The explicit stability estimate of the 2D augury scene `spec`, from a probe build.
    pub fn stable_dt(&self, spec: &SceneSpec) -> Result<f64> {
        let world = self.probe(spec)?;
        world
            .augury()
            .map(|a| a.stable_dt)
            .ok_or_else(|| anyhow::anyhow!("the probe scene is not an augury scene"))
    }

    /// Run a 2D scene, recording `probe(world)` after every step.
    pub fn run_scene_2d<T>(
        &self,
        label: &str,
        spec: &SceneSpec,
        pictures: Option<Pictures>,
        probe: impl FnMut(&femp::World<2>) -> T,
    ) -> Result<(RunResult, Vec<T>)> {
        self.run_scene_probe::<2, T>(label, spec, pictures, probe)
    }

    /// Run a `D`-dimensional scene, recording `probe(world)` after every step.
    pub fn run_scene_probe<const D: usize, T>(
        &self,
        label: &str,
        spec: &SceneSpec,
        pictures: Option<Pictures>,
        probe: impl FnMut(&femp::World<D>) -> T,
    ) -> Result<(RunResult, Vec<T>)> {
        let (r, probes) = self.run_scene_keep::<D, T>(label, spec, pictures, probe)?;
        Ok((r?, probes))
    }

    /// Run a `D`-dimensional scene, recording `probe(world)` after every step (and `pictures`
    /// of it); a run that fails mid-way still returns its probes.
    pub fn run_scene_keep<const D: usize, T>(
        &self,
        label: &str,
        spec: &SceneSpec,
        pictures: Option<Pictures>,
        mut probe: impl FnMut(&femp::World<D>) -> T,
    ) -> Result<(Result<RunResult, femp::SimError>, Vec<T>)> {
        let scene = self.scene(label, spec)?;
        anyhow::ensure!(scene.spec.dimension == D, "{label}: not a {D}D scene");
        let bar = self.bar(label, &scene);
        let out = self.dir.join(label);
        let opts = RunOptions {
            no_frames: true,
            pictures: self.picture_options(label, pictures),
            // A validation run replaces the same run's outputs from an earlier `validate`.
            overwrite: true,
            ..Default::default()
        };
        let mut probes = Vec::new();
        let r = run_with::<D>(scene, &out, &opts, |w, _: &Metrics| {
            probes.push(probe(w));
            bar.inc(1);
        });
        bar.finish_and_clear();
        self.progress.remove(&bar);
        Ok((r, probes))
    }

    fn bar(&self, label: &str, scene: &femp::scene::Scene) -> indicatif::ProgressBar {
        let steps = (scene.spec.time.duration / scene.spec.time.dt).ceil() as u64;
        let bar = self.progress.add(indicatif::ProgressBar::new(steps));
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "  {prefix:28} {bar:30} {pos}/{len} steps [{elapsed_precise} < {eta_precise}]",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar.set_prefix(label.to_string());
        bar
    }

    /// Run a scene through femp with a progress bar (and `pictures` of it); `label` names the
    /// run.
    pub fn run_scene(
        &self,
        label: &str,
        spec: &SceneSpec,
        pictures: Option<Pictures>,
    ) -> Result<RunResult> {
        let scene = self.scene(label, spec)?;
        let bar = self.bar(label, &scene);
        let out = self.dir.join(label);
        let opts = RunOptions {
            no_frames: true,
            pictures: self.picture_options(label, pictures),
            // A validation run replaces the same run's outputs from an earlier `validate`.
            overwrite: true,
            ..Default::default()
        };
        let r = match scene.spec.dimension {
            2 => run_with::<2>(scene, &out, &opts, |_, _: &Metrics| bar.inc(1)),
            _ => run_with::<3>(scene, &out, &opts, |_, _: &Metrics| bar.inc(1)),
        };
        bar.finish_and_clear();
        self.progress.remove(&bar);
        Ok(r?)
    }
}

/// The MPM body named `name` in `spec`.
pub fn mpm_body<'s>(spec: &'s mut SceneSpec, name: &str) -> Result<&'s mut MpmBody> {
    spec.bodies
        .iter_mut()
        .find_map(|b| match b {
            BodySpec::Mpm(b) if b.name == name => Some(b),
            _ => None,
        })
        .with_context(|| format!("the scene has no MPM body `{name}`"))
}

/// The FEM body named `name` in `spec`.
pub fn fem_body<'s>(spec: &'s mut SceneSpec, name: &str) -> Result<&'s mut FemBody> {
    spec.bodies
        .iter_mut()
        .find_map(|b| match b {
            BodySpec::Fem(b) if b.name == name => Some(b),
            _ => None,
        })
        .with_context(|| format!("the scene has no FEM body `{name}`"))
}

/// The contact settings of `spec`.
pub fn contact(spec: &mut SceneSpec) -> Result<&mut ContactSpec> {
    spec.contact
        .as_mut()
        .context("the scene has no `contact` settings")
}

/// The MPM grid settings of `spec`.
pub fn mpm_grid(spec: &mut SceneSpec) -> Result<&mut MpmSpec> {
    spec.mpm.as_mut().context("the scene has no `mpm` settings")
}

const EXPERIMENTS: &[Experiment] = &[
    Experiment {
        name: "rings",
        section: "BFEMP 6.1",
        title: "MPM ring vs FEM ring at 40 m/s: momentum, energy, non-penetration",
        run: rings::run,
        quick_s: 180.0,
    },
    Experiment {
        name: "sine_boundary",
        section: "BFEMP 6.2",
        title: "FEM sine-wave boundary vs level-set slip boundary",
        run: sine::run,
        quick_s: 110.0,
    },
    Experiment {
        name: "hertz",
        section: "BFEMP 6.3",
        title: "Brazilian disk: force vs contact radius against 2D Hertz",
        run: hertz::run,
        quick_s: 20.0,
    },
    Experiment {
        name: "slope",
        section: "BFEMP 6.4",
        title: "Stiff MPM box on a frictional FEM slope: g(sinθ − μcosθ), sticking at μ = tanθ",
        run: slope::run,
        quick_s: 42.0,
    },
    Experiment {
        name: "refinement",
        section: "BFEMP 6.5",
        title: "MPM box on FEM box under refinement: convergence order",
        run: refinement::run,
        quick_s: 54.0,
    },
    Experiment {
        name: "buckling",
        section: "BFEMP 6.6",
        title: "Semicircular rings compressed: buckling order vs μ",
        run: buckling::run,
        quick_s: 176.0,
    },
    Experiment {
        name: "twist",
        section: "BFEMP 6.7",
        title: "3D shell twisting an MPM cube: slip angles vs μ",
        run: twist::run,
        quick_s: 158.0,
    },
    Experiment {
        name: "two_particles",
        section: "augury 3.1",
        title: "Two particles in one cell, APIC vs PIC",
        run: augury::two_particles,
        quick_s: 0.1,
    },
    Experiment {
        name: "blocks_impact",
        section: "augury 3.2",
        title: "Two blocks impacting at an angle: exact momenta",
        run: augury::blocks_impact,
        quick_s: 32.0,
    },
    Experiment {
        name: "ramp",
        section: "augury 3.3",
        title: "Block sliding down a 30° ramp",
        run: augury::ramp_experiment,
        quick_s: 41.0,
    },
    Experiment {
        name: "compare",
        section: "both papers",
        title: "Speed vs accuracy: block sliding down a ramp, BFEMP / augury / penalty",
        run: compare::run,
        quick_s: 90.0,
    },
    Experiment {
        name: "disk_plates",
        section: "both papers",
        title: "Speed vs accuracy: a disk pressed between plates (Hertz), BFEMP / augury / penalty",
        run: disk::run,
        quick_s: 86.0,
    },
    Experiment {
        name: "stability",
        section: "both papers",
        title: "Stability maps: time step against impact speed",
        run: stability::run,
        quick_s: 7.0,
    },
    Experiment {
        name: "fixtures",
        section: "shipped scenes",
        title: "Every fixtures/scenes/*.json runs to completion as committed",
        run: fixtures::run,
        quick_s: 45.0,
    },
];

/// One experiment's row group in the table and report.
pub struct Done {
    name: &'static str,
    section: &'static str,
    title: &'static str,
    /// The experiment's wall time.
    wall_s: f64,
    /// What it produced; `None`: not run in this tier yet.
    outcome: Option<Result<Outcome, String>>,
    /// When it finished (`2026-12-01 19:04 UTC`).
    finished: String,
    /// The commit of the code that ran it.
    commit: String,
    /// Run by this invocation (not loaded from a saved outcome).
    fresh: bool,
    /// Ran alongside other experiments (`--jobs`): its wall time is not comparable.
    concurrent: bool,
}

impl Done {
    /// Experiment `e`'s row from its saved outcome (`None`: not run in this tier yet).
    fn saved(e: &Experiment, saved: Option<Saved>, fresh: bool) -> Self {
        Self {
            name: e.name,
            section: e.section,
            title: e.title,
            wall_s: saved.as_ref().map_or(0.0, |s| s.wall_s),
            finished: saved
                .as_ref()
                .map_or_else(String::new, |s| utc_minute(s.finished_unix)),
            commit: saved
                .as_ref()
                .map_or_else(String::new, |s| s.commit.clone()),
            concurrent: saved.as_ref().is_some_and(|s| s.concurrent),
            outcome: saved.map(|s| s.outcome),
            fresh,
        }
    }
}

/// An experiment's outcome as saved in `OUT/NAME/outcome.json`, so that a long tier can be run
/// an experiment at a time (`--only`) and its report assembled from every saved outcome.
#[derive(serde::Serialize, serde::Deserialize)]
struct Saved {
    tier: Tier,
    wall_s: f64,
    /// Seconds since 1970-01-01 UTC when the experiment finished.
    finished_unix: u64,
    /// `git describe --always --dirty` of the code that ran it.
    commit: String,
    /// Ran alongside other experiments (`--jobs`).
    #[serde(default)]
    concurrent: bool,
    /// Paths are relative to the output directory.
    outcome: Result<Outcome, String>,
}

/// Save `outcome` of experiment `name` under `out` (paths made relative to `out`).
fn save(
    commit: &str,
    out: &Path,
    name: &str,
    tier: Tier,
    wall_s: f64,
    concurrent: bool,
    outcome: &Result<Outcome, String>,
) -> Result<Saved> {
    let rel = |p: &PathBuf| {
        p.strip_prefix(out)
            .map_or_else(|_| p.clone(), Path::to_path_buf)
    };
    let outcome = match outcome {
        Err(e) => Err(e.clone()),
        Ok(o) => Ok(Outcome {
            checks: o.checks.clone(),
            charts: o.charts.iter().map(|(c, p)| (c.clone(), rel(p))).collect(),
            notes: o.notes.clone(),
            pictures: o
                .pictures
                .iter()
                .map(|(c, fs)| (c.clone(), fs.iter().map(rel).collect()))
                .collect(),
        }),
    };
    let saved = Saved {
        tier,
        wall_s,
        finished_unix: std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs()),
        commit: commit.to_string(),
        concurrent,
        outcome,
    };
    let path = out.join(name).join("outcome.json");
    std::fs::create_dir_all(out.join(name))?;
    std::fs::write(&path, serde_json::to_string_pretty(&saved)?)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(saved)
}

/// The saved outcome of experiment `name` under `out`, if there is one of this tier (paths
/// joined back onto `out`); an unreadable file is an error naming it.
fn load(out: &Path, name: &str, tier: Tier) -> Result<Option<Saved>> {
    let path = out.join(name).join("outcome.json");
    if !path.exists() {
        return Ok(None);
    }
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let mut saved: Saved = serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: not a saved outcome (re-run the experiment)",
            path.display()
        )
    })?;
    if saved.tier != tier {
        return Ok(None);
    }
    if let Ok(o) = &mut saved.outcome {
        for (_, p) in &mut o.charts {
            *p = out.join(&*p);
        }
        for (_, fs) in &mut o.pictures {
            for p in fs {
                *p = out.join(&*p);
            }
        }
    }
    Ok(Some(saved))
}

/// `git describe --always --dirty` of the code this binary was built from (see `build.rs`).
fn git_describe() -> String {
    env!("FEMP_BUILD_COMMIT").to_string()
}

/// `YYYY-MM-DD HH:MM UTC` of a Unix time (civil-from-days, proleptic Gregorian calendar).
fn utc_minute(unix: u64) -> String {
    let days = (unix / 86_400) as i64;
    let secs = unix % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02} UTC",
        secs / 3600,
        (secs % 3600) / 60
    )
}

const USAGE: &str =
    "usage: cargo xtask validate [--quick | --full] [--only NAME…] [--jobs N] [--report] \
     [--out DIR] [--publish]

  --quick    coarse resolutions, minutes (default)
  --full     the papers' parameters (hours); with no --only, publishes to docs/validation/full/
  --only     run only these experiments; the report also shows every other experiment's saved
             outcome in the output directory (so a long tier can be run a piece at a time)
  --jobs     run the experiments in N processes at once (balanced by expected wall time); the
             checks are the same, the wall times overlap (marked ‖ in the report). CI uses 2
  --report   run nothing: assemble the report from the saved outcomes
  --out      output directory (default target/validation/<tier>)
  --publish  copy the report and what it shows into docs/validation/ (quick) or
             docs/validation/full/ (full)";

/// Entry point: parse `args` (after `validate`), run, print, report.
pub fn main(args: &[String]) -> Result<()> {
    let mut tier = Tier::Quick;
    let mut only: Vec<String> = Vec::new();
    let mut publish = false;
    let mut report_only = false;
    let mut jobs = 1usize;
    let mut worker = false;
    let mut out: Option<PathBuf> = None;
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
            "--out" => match it.next() {
                Some(d) => out = Some(PathBuf::from(d)),
                None => bail!("--out needs a directory\n{USAGE}"),
            },
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
                    println!("  {:14} {:11} {}", e.name, e.section, e.title);
                }
                return Ok(());
            }
            other => bail!("unknown argument `{other}`\n{USAGE}"),
        }
    }
    if report_only && !only.is_empty() {
        bail!("--report runs nothing; it cannot be combined with --only\n{USAGE}");
    }
    for n in &only {
        if !EXPERIMENTS.iter().any(|e| e.name == n) {
            let names: Vec<_> = EXPERIMENTS.iter().map(|e| e.name).collect();
            bail!("no experiment `{n}`; experiments: {}", names.join(", "));
        }
    }
    let root = workspace_root();
    // The code that runs is the code this binary was built from.
    let commit = git_describe();
    let out = out.unwrap_or_else(|| root.join("target/validation").join(tier.name()));
    std::fs::create_dir_all(&out)?;
    let progress = indicatif::MultiProgress::new();
    let started = Instant::now();
    let mut done = Vec::new();
    let mut ran = 0;
    let is_selected =
        |name: &str| !report_only && (only.is_empty() || only.iter().any(|n| n == name));
    let selected: Vec<&'static str> = EXPERIMENTS
        .iter()
        .map(|e| e.name)
        .filter(|n| is_selected(n))
        .collect();
    let parallel = jobs > 1 && selected.len() > 1 && !worker;
    if parallel {
        run_workers(&selected, jobs, tier, &out)?;
    }
    for e in EXPERIMENTS {
        if parallel {
            // Run by a worker: a missing outcome means the worker died before saving it.
            let fresh = selected.contains(&e.name);
            let mut d = Done::saved(e, load(&out, e.name, tier)?, fresh);
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
        if !is_selected(e.name) {
            done.push(Done::saved(e, load(&out, e.name, tier)?, false));
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
        };
        let t = Instant::now();
        let outcome = (e.run)(&ctx)
            .and_then(|mut o| {
                ctx.collect_pictures(&mut o)?;
                Ok(o)
            })
            .map_err(|err| format!("{err:#}"));
        let wall_s = t.elapsed().as_secs_f64();
        let saved = save(&commit, &out, e.name, tier, wall_s, worker, &outcome)?;
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
    report::write(&out, tier, &done)?;
    println!("report: {}", out.join("README.md").display());
    if (tier == Tier::Full && only.is_empty() && !report_only) || publish {
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

/// Run the experiments `names` in `jobs` processes of this program (`validate --worker --only
/// …`, a share each, longest expected first onto the least loaded), relaying their output
/// line by line prefixed with the worker's number, and wait for all of them. Each saves its
/// outcomes under `out` as it goes; a stale outcome of a selected experiment is removed first,
/// so that a worker that dies leaves no outcome to be mistaken for a fresh one.
fn run_workers(names: &[&'static str], jobs: usize, tier: Tier, out: &Path) -> Result<()> {
    use std::io::BufRead;
    use std::process::{Command, Stdio};
    let mut cost: Vec<(f64, &str)> = Vec::with_capacity(names.len());
    for &n in names {
        let e = EXPERIMENTS
            .iter()
            .find(|e| e.name == n)
            .expect("names are checked against EXPERIMENTS");
        // The last saved wall time of this tier, else the CI figure (scaled for the full tier:
        // only the order matters).
        let expected = match load(out, n, tier).ok().flatten() {
            Some(s) => s.wall_s,
            None if tier == Tier::Quick => e.quick_s,
            None => 30.0 * e.quick_s,
        };
        cost.push((expected, n));
        let stale = out.join(n).join("outcome.json");
        if stale.exists() {
            std::fs::remove_file(&stale)
                .with_context(|| format!("removing {}", stale.display()))?;
        }
    }
    let groups = partition(cost, jobs);
    let exe = std::env::current_exe().context("locating the xtask program")?;
    let mut children = Vec::new();
    let mut relays = Vec::new();
    for (k, (c, g)) in groups.iter().enumerate() {
        println!("worker {k}: {} (expected ≈ {c:.0} s)", g.join(", "));
        let mut child = Command::new(&exe)
            .arg("validate")
            .arg(format!("--{}", tier.name()))
            .arg("--worker")
            .arg("--out")
            .arg(out)
            .arg("--only")
            .args(g)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .with_context(|| format!("starting worker {k} ({})", exe.display()))?;
        let stdout = child.stdout.take().expect("piped");
        let stderr = child.stderr.take().expect("piped");
        relays.push(std::thread::spawn(move || {
            for line in std::io::BufReader::new(stdout)
                .lines()
                .map_while(Result::ok)
            {
                println!("[{k}] {line}");
            }
        }));
        relays.push(std::thread::spawn(move || {
            for line in std::io::BufReader::new(stderr)
                .lines()
                .map_while(Result::ok)
            {
                eprintln!("[{k}] {line}");
            }
        }));
        children.push(child);
    }
    for (k, mut child) in children.into_iter().enumerate() {
        let status = child
            .wait()
            .with_context(|| format!("waiting for worker {k}"))?;
        // A non-zero exit is a failed check (counted from the saved outcomes) or a crash (a
        // missing outcome): both show in the report.
        println!("worker {k} finished ({status})");
    }
    for r in relays {
        let _ = r.join();
    }
    Ok(())
}

/// A line above the progress bars, or on stdout when there are none (not a terminal: CI logs,
/// `--jobs` workers), so that a log shows each experiment as it starts and ends.
fn say(progress: &indicatif::MultiProgress, line: String) {
    if progress.is_hidden() {
        println!("{line}");
    } else {
        let _ = progress.println(line);
    }
}

/// `(expected seconds, name)` shared among at most `jobs` groups: longest first onto the least
/// loaded group (each group's total load, names in the order assigned).
fn partition(mut cost: Vec<(f64, &str)>, jobs: usize) -> Vec<(f64, Vec<&str>)> {
    cost.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut groups: Vec<(f64, Vec<&str>)> =
        vec![(0.0, Vec::new()); jobs.clamp(1, cost.len().max(1))];
    for (c, n) in cost {
        let g = groups
            .iter_mut()
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .expect("at least one group");
        g.0 += c;
        g.1.push(n);
    }
    groups
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

fn workspace_root() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    here.parent().unwrap_or(here).to_path_buf()
}

#[cfg(test)]
mod tests {
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
        save("abc1234", out, "demo", Tier::Full, 12.5, true, &outcome).unwrap();
        let text = std::fs::read_to_string(out.join("demo/outcome.json")).unwrap();
        assert!(
            text.contains("\"charts/a.png\""),
            "paths saved relative: {text}"
        );
        let saved = load(out, "demo", Tier::Full).unwrap().expect("saved");
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
        assert!(load(out, "demo", Tier::Quick).unwrap().is_none());
        assert!(load(out, "other", Tier::Full).unwrap().is_none());
        // A damaged file is an error that names it.
        std::fs::write(out.join("demo/outcome.json"), "{").unwrap();
        let err = format!("{:#}", load(out, "demo", Tier::Full).err().unwrap());
        assert!(err.contains("demo/outcome.json"), "{err}");
        // A failed run is saved as its error.
        save(
            "abc1234",
            out,
            "bad",
            Tier::Full,
            1.0,
            false,
            &Err("it broke".into()),
        )
        .unwrap();
        let bad = load(out, "bad", Tier::Full).unwrap().unwrap();
        assert!(!bad.concurrent);
        assert_eq!(bad.outcome.err().unwrap(), "it broke");
        // Saved before `--jobs` existed (no `concurrent` field): not concurrent.
        let old = r#"{"tier": "full", "wall_s": 3.0, "finished_unix": 0, "commit": "c",
            "outcome": {"Err": "old"}}"#;
        std::fs::write(out.join("bad/outcome.json"), old).unwrap();
        let old = load(out, "bad", Tier::Full).unwrap().unwrap();
        assert!(!old.concurrent);
        assert_eq!(old.wall_s, 3.0);
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
