//! `cargo xtask same A B`: whether two output trees (two `cargo xtask validate --out` runs, or
//! two `femp run --out` directories) hold the same results, wall-clock times aside — how a
//! restructuring shows it changed no number.
//!
//! Compared, file by file under both trees: every `.csv` (each cell as text, except the
//! `wall_s` column), every `summary.json` and `scene_copy.json` (as JSON values, without
//! `wall_s`, `timing` and the build's `commit`), and every validation `outcome.json` (its
//! checks and notes as text, with each duration — a number followed by `s`, `ms` or `min` —
//! masked, and without its wall time, finish time, commit and concurrency). Frames and pictures
//! are not compared (they follow from the same states). Prints what differs and fails if
//! anything does, or if a file is in one tree only.
//!
//! ```text
//! RAYON_NUM_THREADS=1 cargo xtask validate --quick --jobs 1 --out /tmp/before   # old commit
//! RAYON_NUM_THREADS=1 cargo xtask validate --quick --jobs 1 --out /tmp/after    # new commit
//! cargo xtask same /tmp/before /tmp/after
//! ```
//!
//! The `augury_speed` experiment's outcome is a timing and always differs.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde_json::Value;

/// Entry point (arguments after `same`).
pub fn main(args: &[String]) -> Result<()> {
    let [a, b] = args else {
        bail!("usage: cargo xtask same DIR_A DIR_B");
    };
    let report = compare(Path::new(a), Path::new(b))?;
    println!(
        "{} file(s) the same (wall times aside), {} differ, {} in one tree only",
        report.same,
        report.differ.len(),
        report.alone.len()
    );
    for (f, why) in &report.differ {
        println!("  differs: {f}: {why}");
    }
    for f in &report.alone {
        println!("  only in one: {f}");
    }
    if report.differ.is_empty() && report.alone.is_empty() {
        Ok(())
    } else {
        bail!("the trees differ")
    }
}

/// What [`compare`] found.
#[derive(Debug, Default)]
struct Report {
    same: usize,
    differ: Vec<(String, String)>,
    alone: Vec<String>,
}

/// The compared files under `root`, by path relative to it.
fn files(root: &Path) -> Result<BTreeMap<String, PathBuf>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).with_context(|| dir.display().to_string())? {
            let p = e?.path();
            if p.is_dir() {
                stack.push(p);
            } else if kind(&p).is_some() {
                let rel = p.strip_prefix(root)?.to_string_lossy().into_owned();
                out.insert(rel, p);
            }
        }
    }
    Ok(out)
}

#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Csv,
    Json,
    Outcome,
}

fn kind(p: &Path) -> Option<Kind> {
    let name = p.file_name()?.to_str()?;
    match name {
        "outcome.json" => Some(Kind::Outcome),
        "summary.json" | "scene_copy.json" => Some(Kind::Json),
        _ if name.ends_with(".csv") => Some(Kind::Csv),
        _ => None,
    }
}

fn compare(a: &Path, b: &Path) -> Result<Report> {
    let (fa, fb) = (files(a)?, files(b)?);
    let mut r = Report::default();
    for k in fa.keys().filter(|k| !fb.contains_key(*k)) {
        r.alone.push(format!("{k} (in {})", a.display()));
    }
    for k in fb.keys().filter(|k| !fa.contains_key(*k)) {
        r.alone.push(format!("{k} (in {})", b.display()));
    }
    for (k, pa) in &fa {
        let Some(pb) = fb.get(k) else { continue };
        let ta = std::fs::read_to_string(pa).with_context(|| pa.display().to_string())?;
        let tb = std::fs::read_to_string(pb).with_context(|| pb.display().to_string())?;
        let diff = match kind(pa).expect("listed files have a kind") {
            Kind::Csv => csv_difference(&ta, &tb),
            Kind::Json => json_difference(&ta, &tb, &["wall_s", "timing", "commit"]),
            Kind::Outcome => outcome_difference(&ta, &tb),
        };
        match diff {
            None => r.same += 1,
            Some(why) => r.differ.push((k.clone(), why)),
        }
    }
    Ok(r)
}

/// The first difference between two CSV texts, the `wall_s` column aside.
fn csv_difference(a: &str, b: &str) -> Option<String> {
    let (la, lb): (Vec<&str>, Vec<&str>) = (a.lines().collect(), b.lines().collect());
    if la.first() != lb.first() {
        return Some("the headers differ".into());
    }
    if la.len() != lb.len() {
        return Some(format!("{} rows against {}", la.len(), lb.len()));
    }
    let header: Vec<&str> = la.first().map_or_else(Vec::new, |h| h.split(',').collect());
    for (n, (ra, rb)) in la.iter().zip(&lb).enumerate().skip(1) {
        for (c, (x, y)) in ra.split(',').zip(rb.split(',')).enumerate() {
            let name = header.get(c).copied().unwrap_or("?");
            if name != "wall_s" && x != y {
                return Some(format!("line {}, column {name}: {x} against {y}", n + 1));
            }
        }
        if ra.split(',').count() != rb.split(',').count() {
            return Some(format!("line {}: a different number of cells", n + 1));
        }
    }
    None
}

/// The first difference between two JSON texts, without the top-level keys `skip`.
fn json_difference(a: &str, b: &str, skip: &[&str]) -> Option<String> {
    let parse = |t: &str| -> Option<Value> {
        let mut v: Value = serde_json::from_str(t).ok()?;
        if let Value::Object(m) = &mut v {
            for k in skip {
                m.remove(*k);
            }
        }
        Some(v)
    };
    match (parse(a), parse(b)) {
        (Some(x), Some(y)) if x == y => None,
        (Some(Value::Object(x)), Some(Value::Object(y))) => {
            let key = x
                .iter()
                .find(|(k, v)| y.get(*k) != Some(*v))
                .map(|(k, _)| k.clone())
                .or_else(|| y.keys().find(|k| !x.contains_key(*k)).cloned())
                .unwrap_or_default();
            Some(format!("`{key}` differs"))
        }
        (Some(_), Some(_)) => Some("the values differ".into()),
        _ => Some("not JSON".into()),
    }
}

/// The first difference between two validation outcomes' checks and notes, durations masked.
fn outcome_difference(a: &str, b: &str) -> Option<String> {
    let texts = |t: &str| -> Option<Vec<String>> {
        let v: Value = serde_json::from_str(t).ok()?;
        let o = v.get("outcome")?;
        let o = o.get("Ok").unwrap_or(o);
        let mut out = Vec::new();
        for k in ["checks", "notes"] {
            if let Some(Value::Array(items)) = o.get(k) {
                let mut items: Vec<String> = items
                    .iter()
                    .map(|i| mask_durations(&i.to_string()))
                    .collect();
                // Experiments whose runs finish in parallel list them in finishing order.
                items.sort();
                out.extend(items);
            }
        }
        if let Some(e) = v.get("outcome").and_then(|o| o.get("Err")) {
            out.push(mask_durations(&e.to_string()));
        }
        Some(out)
    };
    match (texts(a), texts(b)) {
        (Some(x), Some(y)) if x == y => None,
        (Some(x), Some(y)) => Some(x.iter().zip(&y).find(|(p, q)| p != q).map_or_else(
            || format!("{} checks and notes against {}", x.len(), y.len()),
            |(p, q)| format!("{p} against {q}"),
        )),
        _ => Some("not a validation outcome".into()),
    }
}

/// `text` with every duration — a number followed (after at most one space) by the unit `s`,
/// `ms` or `min` ending a word — replaced by `T`.
fn mask_durations(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < c.len() {
        let starts_number = c[i].is_ascii_digit() && (i == 0 || !c[i - 1].is_alphanumeric());
        if starts_number {
            let mut j = i;
            while j < c.len()
                && (c[j].is_ascii_digit()
                    || c[j] == '.'
                    || (matches!(c[j], 'e' | 'E')
                        && c.get(j + 1)
                            .is_some_and(|n| n.is_ascii_digit() || *n == '-')))
            {
                j += 1;
                if matches!(c[j - 1], 'e' | 'E') && c.get(j) == Some(&'-') {
                    j += 1;
                }
            }
            let mut u = j;
            if c.get(u) == Some(&' ') {
                u += 1;
            }
            let unit_end = ["min", "ms", "s"].iter().find_map(|unit| {
                let n = unit.chars().count();
                let word: String = c.get(u..u + n)?.iter().collect();
                let ends = c.get(u + n).is_none_or(|ch| !ch.is_alphanumeric());
                (word == *unit && ends).then_some(u + n)
            });
            if let Some(end) = unit_end {
                out.push('T');
                i = end;
                continue;
            }
            out.extend(&c[i..j]);
            i = j;
            continue;
        }
        out.push(c[i]);
        i += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_are_masked_and_other_numbers_are_not() {
        assert_eq!(
            mask_durations("750 steps, 2206 Newton iterations, 1.5 s; 3.2e-3 ms or 4 min, 3 m/s"),
            "750 steps, 2206 Newton iterations, T; T or T, 3 m/s"
        );
        assert_eq!(mask_durations("h = 0.25, Δt = 5e-3s"), "h = 0.25, Δt = T");
        // A unit must end its word: 2 steps, 4 samples and x1s are not durations.
        assert_eq!(
            mask_durations("2 steps, 4 samples, x1s"),
            "2 steps, 4 samples, x1s"
        );
    }

    #[test]
    fn a_changed_number_is_found_and_wall_times_are_not() {
        let dir = std::env::temp_dir().join(format!("femp-same-{}", std::process::id()));
        let (a, b) = (dir.join("a/exp/run"), dir.join("b/exp/run"));
        for d in [&a, &b] {
            std::fs::create_dir_all(d).unwrap();
        }
        let csv = |e: &str, w: &str| format!("step,total_energy,wall_s\n1,{e},{w}\n");
        let summary = |n: usize, w: f64| format!(r#"{{"newton_iterations": {n}, "wall_s": {w}}}"#);
        let outcome = |note: &str, w: f64| {
            format!(
                r#"{{"wall_s": {w}, "commit": "x", "outcome": {{"Ok": {{"checks": [], "notes": ["{note}"]}}}}}}"#
            )
        };
        let write = |d: &Path, files: [(&str, String); 3]| {
            for (name, text) in files {
                std::fs::write(d.join(name), text).unwrap();
            }
        };
        write(
            &a,
            [
                ("metrics.csv", csv("1.25", "0.5")),
                ("summary.json", summary(10, 1.0)),
                ("outcome.json", outcome("10 Newton iterations, 1.5 s", 3.0)),
            ],
        );
        write(
            &b,
            [
                ("metrics.csv", csv("1.25", "0.7")),
                ("summary.json", summary(10, 2.0)),
                ("outcome.json", outcome("10 Newton iterations, 1.9 s", 4.0)),
            ],
        );
        let r = compare(&dir.join("a"), &dir.join("b")).unwrap();
        assert_eq!((r.same, r.differ.len(), r.alone.len()), (3, 0, 0), "{r:?}");
        // One changed digit in each kind of file is found.
        write(
            &b,
            [
                ("metrics.csv", csv("1.26", "0.7")),
                ("summary.json", summary(11, 2.0)),
                ("outcome.json", outcome("11 Newton iterations, 1.9 s", 4.0)),
            ],
        );
        std::fs::write(b.join("extra.csv"), "a\n1\n").unwrap();
        let r = compare(&dir.join("a"), &dir.join("b")).unwrap();
        assert_eq!((r.same, r.differ.len(), r.alone.len()), (0, 3, 1), "{r:?}");
        assert!(r.differ.iter().any(|(_, why)| why.contains("total_energy")));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
