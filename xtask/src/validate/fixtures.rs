//! The shipped scenes: every `fixtures/scenes/*.json` runs to completion exactly as committed
//! (a shipped example that fails is a defect). The quick tier runs the ones that take seconds;
//! the full tier runs all of them. BFEMP scenes must also keep every point out of every body;
//! augury scenes report how many steps had a vertex inside another body (the method allows it).

use anyhow::{Context, Result};

use super::experiment::Experiment;
use super::{Check, Ctx, Outcome, Tier};

/// The fixtures the quick tier runs whole (seconds each on the CI machine); the rest take
/// minutes to tens of minutes and run in the full tier.
const QUICK: &[&str] = &[
    "augury_blocks",
    "augury_blocks_3d",
    "augury_ramp_3d",
    "block_on_plate",
    "brazilian_disk",
    "rings_fem_fem_newmark",
];

/// The shipped scenes.
#[derive(Default)]
pub(super) struct Fixtures;

/// The scenes in `fixtures/scenes/` by name, sorted: those `ctx`'s tier runs and those it skips.
fn listing(ctx: &Ctx) -> Result<(Vec<String>, Vec<String>)> {
    let dir = ctx.root.join("fixtures/scenes");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .with_context(|| format!("listing {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .collect();
    names.sort();
    Ok(names
        .into_iter()
        .partition(|name| ctx.tier == Tier::Full || QUICK.contains(&name.as_str())))
}

impl Experiment for Fixtures {
    /// A scene's name.
    type Case = String;
    /// Its run's summary, or why it stopped.
    type Measured = std::result::Result<femp::output::Summary, String>;

    fn cases(&self, ctx: &Ctx) -> Result<Vec<String>> {
        Ok(listing(ctx)?.0)
    }

    fn measure(&self, ctx: &Ctx, name: &String) -> Result<Self::Measured> {
        let spec = ctx.fixture(name)?;
        let label = format!("fixture_{name}");
        Ok(ctx
            .run_scene(&label, &spec, None)
            .map(|r| r.summary)
            .map_err(|e| format!("{e:#}")))
    }

    fn checks(
        &self,
        ctx: &Ctx,
        runs: &[(String, Self::Measured)],
        out: &mut Outcome,
    ) -> Result<()> {
        for (name, run) in runs {
            match run {
                Ok(s) => {
                    out.checks.push(Check::holds(
                        &format!("`{name}.json` runs to completion"),
                        format!(
                            "{} steps to t = {:.4} s in {:.1} s",
                            s.steps, s.simulated_time, s.wall_s
                        ),
                        "completed",
                        "—",
                        s.status == "completed",
                    ));
                    if s.method == femp::scene::Method::Bfemp {
                        out.checks.push(Check::count(
                            &format!("`{name}.json`: penetrations, max over steps"),
                            s.max_penetrations,
                            0,
                        ));
                    } else {
                        out.checks.push(Check::info(
                            &format!("`{name}.json`: steps with a vertex inside another body"),
                            format!(
                                "{} of {} (at most {} vertices)",
                                s.penetrating_steps, s.steps, s.max_penetrations
                            ),
                            "augury lets vertices in under load (docs/augury.md)".into(),
                        ));
                    }
                }
                Err(e) => {
                    out.checks.push(Check::stopped(
                        format!("`{name}.json` runs to completion"),
                        "stopped".into(),
                        "completed".into(),
                    ));
                    out.notes.push(format!("`{name}.json`: {e}"));
                }
            }
        }
        let skipped = listing(ctx)?.1;
        out.notes.push(format!(
            "Every scene in `fixtures/scenes/` is run as committed, through `femp::run` (what \
             `femp run` does). {}",
            if skipped.is_empty() {
                "All of them ran in this tier.".to_string()
            } else {
                format!(
                    "The quick tier runs the ones that take seconds; the full tier also runs {}.",
                    skipped.join(", ")
                )
            }
        ));
        Ok(())
    }

    /// None: the table rows are the figures.
    fn charts(&self, _: &Ctx, _: &[(String, Self::Measured)], _: &mut Outcome) -> Result<()> {
        Ok(())
    }
}
