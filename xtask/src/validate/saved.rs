//! Each experiment's outcome saved under the output directory as it finishes, so a long tier
//! runs a piece at a time and its report is assembled from what is saved; the table rows of an
//! experiment ([`Done`]).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::{Experiment, Outcome, Tier};

/// One experiment's row group in the table and report.
pub struct Done {
    pub(super) name: &'static str,
    pub(super) section: &'static str,
    pub(super) title: &'static str,
    /// The experiment's wall time.
    pub(super) wall_s: f64,
    /// What it produced; `None`: not run in this tier yet.
    pub(super) outcome: Option<Result<Outcome, String>>,
    /// When it finished (`2026-12-01 19:04 UTC`).
    pub(super) finished: String,
    /// The commit of the code that ran it.
    pub(super) commit: String,
    /// Run by this invocation (not loaded from a saved outcome).
    pub(super) fresh: bool,
    /// Ran alongside other experiments (`--jobs`): its wall time is not comparable.
    pub(super) concurrent: bool,
}

impl Done {
    /// Experiment `e`'s row from its saved outcome (`None`: not run in this tier yet).
    pub(super) fn saved(e: &Experiment, saved: Option<Saved>, fresh: bool) -> Self {
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
pub(super) struct Saved {
    pub(super) tier: Tier,
    pub(super) wall_s: f64,
    /// Seconds since 1970-01-01 UTC when the experiment finished.
    pub(super) finished_unix: u64,
    /// `git describe --always --dirty` of the code that ran it.
    pub(super) commit: String,
    /// Ran alongside other experiments (`--jobs`).
    #[serde(default)]
    pub(super) concurrent: bool,
    /// The scene fields `--set` on every BFEMP scene (`key=value`; none: the suite's own).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub(super) settings: Vec<String>,
    /// Paths are relative to the output directory.
    pub(super) outcome: Result<Outcome, String>,
}

/// Save `outcome` of experiment `name` under `out` (paths made relative to `out`), run by the
/// code of `commit` with `settings` (`--set`).
pub(super) fn save(
    (commit, settings): (&str, &[String]),
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
        settings: settings.to_vec(),
        outcome,
    };
    let path = out.join(name).join("outcome.json");
    std::fs::create_dir_all(out.join(name))?;
    std::fs::write(&path, serde_json::to_string_pretty(&saved)?)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(saved)
}

/// The saved outcome of experiment `name` under `out`, if there is one of this tier (paths
/// joined back onto `out`); an unreadable file is an error naming it, and so is one run with
/// other `--set` settings than `settings` (one report shows one set of settings).
pub(super) fn load(
    out: &Path,
    name: &str,
    tier: Tier,
    settings: &[String],
) -> Result<Option<Saved>> {
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
    if saved.settings != settings {
        let said = |s: &[String]| match s {
            [] => "no --set".to_string(),
            s => format!("--set {}", s.join(" --set ")),
        };
        anyhow::bail!(
            "{} was run with {}, this run has {}: one output directory holds one set of \
             settings (choose another --out)",
            path.display(),
            said(&saved.settings),
            said(settings)
        );
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
pub(super) fn git_describe() -> String {
    env!("FEMP_BUILD_COMMIT").to_string()
}

/// `YYYY-MM-DD HH:MM UTC` of a Unix time (civil-from-days, proleptic Gregorian calendar).
pub(super) fn utc_minute(unix: u64) -> String {
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
