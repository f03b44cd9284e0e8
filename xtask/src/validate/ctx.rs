//! What an experiment runs its scenes through: [`Ctx`] (tier, directories, progress bars, the
//! runs' pictures) and [`Pictures`], chosen where a run starts.

use std::cell::Cell;
use std::path::PathBuf;
use std::sync::Mutex;

use anyhow::{Context, Result};
use femp::metrics::Metrics;
use femp::run::{RunOptions, RunResult, run_with};
use femp::scene::SceneSpec;

use super::{Outcome, Tier};

/// The scene pictures the report shows of one run, chosen where the experiment starts the run
/// (`Pictures::keys("caption", 3).gif()`).
#[derive(Clone, Debug)]
pub struct Pictures {
    /// Caption in the report.
    pub(super) caption: String,
    /// Key frames, evenly spaced from start to end.
    pub(super) keys: usize,
    /// Show only the last key frame.
    pub(super) last_only: bool,
    /// Make a GIF.
    pub(super) gif: bool,
    /// The axis drawn up in 3D (`None`: against gravity).
    pub(super) up: Option<usize>,
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
    pub(super) progress: indicatif::MultiProgress,
    /// Pictured runs so far: the case that ran them ([`in_case`]), label, caption, which files
    /// to show.
    pub(super) pictured: Mutex<Vec<Pictured>>,
    /// Scene fields set on every BFEMP scene (`validate --set`).
    pub(super) settings: Vec<crate::settings::Setting>,
    /// Lanes the experiment's cases run in at once (`validate --jobs N` with one experiment;
    /// [`super::experiment::drive`]).
    pub(super) case_lanes: usize,
    /// `validate --resume`: runs with a checkpoint continue from it
    /// ([`Ctx::run_scene_resumable`]).
    pub(super) resume: bool,
}

/// A pictured run: its case's index, label, caption, key frames, whether only the last shows.
pub(super) type Pictured = (usize, String, String, usize, bool);

thread_local! {
    /// The index of the case this thread is measuring ([`in_case`]).
    static CASE: Cell<usize> = const { Cell::new(0) };
}

/// Run `f` as the measurement of case `index`: the pictures it asks for are listed in case
/// order whichever lane finishes first.
pub(super) fn in_case<R>(index: usize, f: impl FnOnce() -> R) -> R {
    CASE.with(|c| c.set(index));
    f()
}

impl Ctx {
    /// Render options for `pictures` of the run `label`, which is remembered for
    /// [`Ctx::collect_pictures`].
    pub(super) fn picture_options(
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
        self.pictured.lock().expect("a lane panicked").push((
            CASE.with(Cell::get),
            label.to_string(),
            caption,
            keys,
            last_only,
        ));
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
    pub(super) fn collect_pictures(&self, out: &mut Outcome) -> Result<()> {
        let mut pictured = std::mem::take(&mut *self.pictured.lock().expect("a lane panicked"));
        // In case order (stable: a case's runs in the order it made them).
        pictured.sort_by_key(|p| p.0);
        for (_, label, caption, keys, last_only) in pictured {
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
        Ok(femp::scene::load(&path)?.spec().clone())
    }

    /// `spec` parsed back from its text and validated, as `femp run` would read it (relative
    /// paths against `fixtures/scenes/`); the text is what the run copies into its directory.
    ///
    /// Augury scenes run with `augury.penetration_limit: null`: the suite studies where the
    /// method lets bodies into (or through) each other, so such a run goes on and its rows
    /// report how deep (`summary.max_penetration_depth`, `passed_through_steps`). BFEMP scenes
    /// get the `--set` fields ([`Ctx::settings`]), then are validated as any scene is.
    pub fn scene(&self, label: &str, spec: &SceneSpec) -> Result<femp::scene::Scene> {
        let mut spec = spec.clone();
        if spec.method == femp::scene::Method::Bfemp && !self.settings.is_empty() {
            let mut json: serde_json::Value = serde_json::from_str(&spec.to_json())?;
            for (key, value) in &self.settings {
                crate::settings::set(&mut json, key, value)?;
            }
            return Ok(femp::scene::parse(
                &json.to_string(),
                &format!("{label} (with --set)"),
                self.root.join("fixtures/scenes"),
                label,
            )?);
        }
        if let Some(a) = spec.augury.as_mut() {
            a.penetration_limit = None;
        } else if spec.method == femp::scene::Method::Augury {
            spec.augury = Some(femp::scene::AugurySpec {
                penetration_limit: None,
                ..Default::default()
            });
        }
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
            .stepper
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
        anyhow::ensure!(scene.spec().dimension == D, "{label}: not a {D}D scene");
        let bar = self.bar(label, &scene);
        let out = self.dir.join(label);
        let opts = self.run_options(label, pictures);
        let mut probes = Vec::new();
        let r = run_with::<D>(scene, &out, &opts, |w, _: &Metrics| {
            probes.push(probe(w));
            bar.inc(1);
        });
        bar.finish_and_clear();
        self.progress.remove(&bar);
        Ok((r, probes))
    }

    /// [`Ctx::run_scene_keep`] for runs of hours: a checkpoint at every frame time and every
    /// probe appended to `probes.jsonl` beside the run's outputs (as `[step, probe]`), so that
    /// with `validate --resume` a run stopped before its end — an interrupt, a machine or a
    /// session going down — continues from its last checkpoint, with its probes up to it read
    /// back: the same results as a run never stopped (femp's `--resume`). No pictures (a
    /// resumed run draws none). The run's metrics in memory are those since the resumption
    /// (the summary and `metrics.csv` have them all).
    pub fn run_scene_resumable<const D: usize, T>(
        &self,
        label: &str,
        spec: &SceneSpec,
        mut probe: impl FnMut(&femp::World<D>) -> T,
    ) -> Result<(Result<RunResult, femp::SimError>, Vec<T>)>
    where
        T: serde::Serialize + serde::de::DeserializeOwned,
    {
        let scene = self.scene(label, spec)?;
        anyhow::ensure!(scene.spec().dimension == D, "{label}: not a {D}D scene");
        let out = self.dir.join(label);
        let checkpoint = out.join(femp::checkpoint::CHECKPOINT);
        let resume = self.resume && checkpoint.is_file();
        let probes_path = out.join("probes.jsonl");
        let mut probes = Vec::new();
        let mut kept = String::new();
        if resume {
            let step = femp::checkpoint::Checkpoint::read(&checkpoint)?.step();
            let text = std::fs::read_to_string(&probes_path)
                .with_context(|| format!("reading {}", probes_path.display()))?;
            for line in text.lines() {
                let (k, p): (usize, T) = serde_json::from_str(line)
                    .with_context(|| format!("{}: a line is not [step, probe]", label))?;
                if k <= step {
                    probes.push(p);
                    kept.push_str(line);
                    kept.push('\n');
                }
            }
        }
        std::fs::create_dir_all(&out)?;
        std::fs::write(&probes_path, &kept)?;
        let mut file = std::fs::OpenOptions::new()
            .append(true)
            .open(&probes_path)?;
        let bar = self.bar(label, &scene);
        bar.set_position(probes.len() as u64);
        let opts = RunOptions {
            no_frames: true,
            overwrite: !resume,
            checkpoint: true,
            resume,
            ..Default::default()
        };
        let mut failed_write = None;
        let r = run_with::<D>(scene, &out, &opts, |w, _: &Metrics| {
            let p = probe(w);
            if failed_write.is_none() {
                let line = serde_json::to_string(&(w.clock.step, &p)).map_err(anyhow::Error::from);
                failed_write = line
                    .and_then(|l| {
                        use std::io::Write;
                        Ok(writeln!(file, "{l}")?)
                    })
                    .err();
            }
            probes.push(p);
            bar.inc(1);
        });
        bar.finish_and_clear();
        self.progress.remove(&bar);
        if let Some(e) = failed_write {
            return Err(e.context(format!("writing {}", probes_path.display())));
        }
        Ok((r, probes))
    }

    /// How a run labelled `label` writes: no frames, `pictures` if any, replacing the same
    /// run's outputs from an earlier `validate`.
    fn run_options(&self, label: &str, pictures: Option<Pictures>) -> RunOptions {
        RunOptions {
            no_frames: true,
            pictures: self.picture_options(label, pictures),
            overwrite: true,
            ..Default::default()
        }
    }

    pub(super) fn bar(&self, label: &str, scene: &femp::scene::Scene) -> indicatif::ProgressBar {
        let steps = (scene.spec().time.duration / scene.spec().time.dt).ceil() as u64;
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
        let opts = self.run_options(label, pictures);
        let r = match scene.spec().dimension {
            2 => run_with::<2>(scene, &out, &opts, |_, _: &Metrics| bar.inc(1)),
            _ => run_with::<3>(scene, &out, &opts, |_, _: &Metrics| bar.inc(1)),
        };
        bar.finish_and_clear();
        self.progress.remove(&bar);
        Ok(r?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ctx(settings: &[(&str, &str)]) -> Ctx {
        let dir = std::env::temp_dir().join("femp-xtask-ctx-test");
        Ctx {
            tier: Tier::Quick,
            dir: dir.clone(),
            charts: dir,
            root: crate::validate::workspace_root(),
            progress: indicatif::MultiProgress::new(),
            pictured: Default::default(),
            case_lanes: 1,
            resume: false,
            settings: settings
                .iter()
                .map(|(k, v)| (k.to_string(), crate::settings::value(v)))
                .collect(),
        }
    }

    /// `validate --set` reaches every BFEMP scene the suite runs, leaves augury scenes as they
    /// are, and a field the format does not have is an error naming it.
    #[test]
    fn set_fields_reach_bfemp_scenes_only() {
        use femp::scene::ProjectionSpec;
        let plain = ctx(&[]);
        let set = ctx(&[
            ("solver.projection", "always"),
            ("solver.friction_forcing", "0.5"),
        ]);
        let twist = plain.fixture("twist").unwrap();
        assert_eq!(twist.solver.projection, ProjectionSpec::WhenIndefinite);
        let s = set.scene("twist", &twist).unwrap();
        assert_eq!(s.spec().solver.projection, ProjectionSpec::Always);
        assert_eq!(s.spec().solver.friction_forcing, Some(0.5));
        // Everything else as it was.
        let mut back = s.spec().clone();
        back.solver.projection = ProjectionSpec::WhenIndefinite;
        back.solver.friction_forcing = None;
        assert_eq!(
            back.to_json(),
            plain.scene("twist", &twist).unwrap().spec().to_json()
        );
        let blocks = plain.fixture("augury_blocks").unwrap();
        assert_eq!(
            set.scene("blocks", &blocks).unwrap().spec().to_json(),
            plain.scene("blocks", &blocks).unwrap().spec().to_json()
        );
        let err = format!(
            "{:#}",
            ctx(&[("solver.no_such_field", "1")])
                .scene("twist", &twist)
                .err()
                .unwrap()
        );
        assert!(err.contains("no_such_field"), "{err}");
    }

    /// A resumable run stopped part-way (here: a shorter duration, as a session's end would
    /// stop it) and resumed with `validate --resume` gives the probes and metrics of a run
    /// never stopped, bit for bit; without a checkpoint `--resume` starts afresh.
    #[test]
    fn a_resumed_run_keeps_its_probes_and_ends_as_one_never_stopped() {
        let root = std::env::temp_dir().join(format!("femp-xtask-resume-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let at = |sub: &str, resume: bool| Ctx {
            dir: root.join(sub),
            charts: root.join(sub),
            resume,
            ..ctx(&[])
        };
        let mut spec = ctx(&[]).fixture("block_on_plate").unwrap();
        spec.time.frame_interval = Some(2.0 * spec.time.dt);
        spec.time.duration = 16.0 * spec.time.dt;
        let probe = |w: &femp::World<2>| {
            let m = w.bodies.mpm.as_ref().unwrap();
            (w.clock.step, m.x[0][1].to_bits(), m.v[7][0].to_bits())
        };
        let whole = at("whole", false)
            .run_scene_resumable::<2, _>("run", &spec, probe)
            .unwrap();
        let whole_run = whole.0.unwrap();
        assert_eq!(whole.1.len(), 16);
        // Stopped after 11 steps (its last checkpoint: step 10), then resumed to the end.
        let mut short = spec.clone();
        short.time.duration = 11.0 * spec.time.dt;
        let (first, p) = at("parts", false)
            .run_scene_resumable::<2, _>("run", &short, probe)
            .unwrap();
        assert_eq!((first.unwrap().summary.steps, p.len()), (11, 11));
        let (rest, probes) = at("parts", true)
            .run_scene_resumable::<2, _>("run", &spec, probe)
            .unwrap();
        let rest = rest.unwrap();
        assert_eq!(rest.summary.resumed_at, [10]);
        assert!(probes == whole.1, "the probes differ");
        assert_eq!(
            rest.summary.newton_iterations,
            whole_run.summary.newton_iterations
        );
        // metrics.csv without its wall-time column.
        let csv = |sub: &str| {
            let text = std::fs::read_to_string(root.join(sub).join("run/metrics.csv")).unwrap();
            let wall = text
                .lines()
                .next()
                .and_then(|h| h.split(',').position(|c| c == "wall_s"))
                .unwrap();
            text.lines()
                .map(|l| {
                    let mut f: Vec<&str> = l.split(',').collect();
                    f.remove(wall);
                    f.join(",")
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(csv("whole").len(), 18);
        assert_eq!(csv("whole"), csv("parts"));
        // `--resume` where no checkpoint is: the run starts from the beginning.
        let (fresh, p) = at("fresh", true)
            .run_scene_resumable::<2, _>("run", &spec, probe)
            .unwrap();
        assert!(fresh.unwrap().summary.resumed_at.is_empty());
        assert!(p == whole.1);
        let _ = std::fs::remove_dir_all(&root);
    }
}
