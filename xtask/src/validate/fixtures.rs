//! The shipped scenes: every `fixtures/scenes/*.json` runs to completion exactly as committed
//! (a shipped example that fails is a defect). The quick tier runs the ones that take seconds;
//! the full tier runs all of them. BFEMP scenes must also keep every point out of every body;
//! augury scenes report how many steps had a vertex inside another body (the method allows it).

use anyhow::{Context, Result};

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

/// Run the experiment.
pub fn run(ctx: &Ctx) -> Result<Outcome> {
    let dir = ctx.root.join("fixtures/scenes");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .with_context(|| format!("listing {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .collect();
    names.sort();
    let mut out = Outcome::default();
    let mut skipped = Vec::new();
    for name in &names {
        if ctx.tier == Tier::Quick && !QUICK.contains(&name.as_str()) {
            skipped.push(name.clone());
            continue;
        }
        let spec = ctx.fixture(name)?;
        let label = format!("fixture_{name}");
        match ctx.run_scene(&label, &spec, None) {
            Ok(r) => {
                let s = &r.summary;
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
                out.notes.push(format!("`{name}.json`: {e:#}"));
            }
        }
    }
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
    Ok(out)
}
