//! `--jobs N`: the selected experiments shared among N worker processes of this program.

use std::path::Path;

use anyhow::{Context, Result};

use super::saved::load;
use super::{EXPERIMENTS, Tier};

/// Run the experiments `names` in `jobs` processes of this program (`validate --worker --only
/// …`, a share each, longest expected first onto the least loaded), relaying their output
/// line by line prefixed with the worker's number, and wait for all of them. Each saves its
/// outcomes under `out` as it goes; a stale outcome of a selected experiment is removed first,
/// so that a worker that dies leaves no outcome to be mistaken for a fresh one.
pub(super) fn run_workers(
    names: &[&'static str],
    jobs: usize,
    tier: Tier,
    out: &Path,
    settings: &[crate::settings::Setting],
    resume: bool,
) -> Result<()> {
    use std::io::BufRead;
    use std::process::{Command, Stdio};
    let mut cost: Vec<(f64, &str)> = Vec::with_capacity(names.len());
    let labels = crate::settings::labels(settings);
    for &n in names {
        let e = EXPERIMENTS
            .iter()
            .find(|e| e.name == n)
            .expect("names are checked against EXPERIMENTS");
        // The last saved wall time of this tier, else the CI figure (scaled for the full tier:
        // only the order matters).
        let expected = match load(out, n, tier, &labels).ok().flatten() {
            Some(s) => s.wall_s,
            None => e.expected_s(tier),
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
            .args(labels.iter().flat_map(|l| ["--set", l.as_str()]))
            .args(resume.then_some("--resume"))
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
    for (k, r) in relays.into_iter().enumerate() {
        // Two relays per worker (stdout, stderr): a panic there lost lines of its log.
        r.join().map_err(|_| {
            anyhow::anyhow!(
                "the {} relay of worker {} panicked: its log is incomplete",
                if k % 2 == 0 { "stdout" } else { "stderr" },
                k / 2
            )
        })?;
    }
    Ok(())
}

/// A line above the progress bars, or on stdout when there are none (not a terminal: CI logs,
/// `--jobs` workers), so that a log shows each experiment as it starts and ends.
pub(super) fn say(progress: &indicatif::MultiProgress, line: String) {
    if progress.is_hidden() {
        println!("{line}");
    } else {
        let _ = progress.println(line);
    }
}

/// `(expected seconds, name)` shared among at most `jobs` groups: longest first onto the least
/// loaded group (each group's total load, names in the order assigned).
pub(super) fn partition(mut cost: Vec<(f64, &str)>, jobs: usize) -> Vec<(f64, Vec<&str>)> {
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
