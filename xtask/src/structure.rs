//! The workspace's structure check: no crate's modules import each other in a circle.
//!
//! Each crate's source files are modules (`a/b.rs` and `a/b/mod.rs` are `a::b`); a module
//! depends on another when its code (comments aside) names it through `crate::…` or
//! `super::…`. A parent and its own child modules are one unit (a parent declares its
//! children; a child may use its parent's items). Any strongly connected set of two or more
//! modules is a circle: each can only be understood, tested or moved with all the others.
//! Run as a test (`cargo test -p xtask`), so CI fails on a new circle, naming its modules and the
//! edges that close it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Modules of the crate whose sources are under `src`: name (`a::b`, `""` for the root) →
/// code with comments removed.
fn modules(src: &Path) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                let rel = p.strip_prefix(src).unwrap().with_extension("");
                let mut parts: Vec<String> = rel
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().into_owned())
                    .collect();
                if matches!(
                    parts.last().map(String::as_str),
                    Some("mod" | "lib" | "main")
                ) {
                    parts.pop();
                }
                let text = std::fs::read_to_string(&p).unwrap_or_default();
                out.insert(parts.join("::"), strip_comments(&text));
            }
        }
    }
    out
}

/// `text` without `//` and `/* */` comments (string literals are left alone: a `crate::` in a
/// string is rare and at worst adds an edge).
fn strip_comments(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'/' && i + 1 < b.len() && b[i + 1] == b'/' {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i] == b'/' && i + 1 < b.len() && b[i + 1] == b'*' {
            i += 2;
            while i + 1 < b.len() && !(b[i] == b'*' && b[i + 1] == b'/') {
                i += 1;
            }
            i += 2;
        } else {
            out.push(b[i] as char);
            i += 1;
        }
    }
    out
}

/// The path segments following each occurrence of `prefix` (`crate::a::b` → `[a, b]`).
fn paths_after<'t>(code: &'t str, prefix: &str) -> Vec<Vec<&'t str>> {
    let mut out = Vec::new();
    let mut rest = code;
    while let Some(k) = rest.find(prefix) {
        let before_ok = k == 0
            || !rest.as_bytes()[k - 1].is_ascii_alphanumeric() && rest.as_bytes()[k - 1] != b'_';
        let tail = &rest[k + prefix.len()..];
        let end = tail
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == ':'))
            .unwrap_or(tail.len());
        if before_ok {
            out.push(tail[..end].split("::").filter(|s| !s.is_empty()).collect());
        }
        rest = &rest[k + prefix.len()..];
    }
    out
}

/// Module-to-module dependencies of one crate.
fn edges(mods: &BTreeMap<String, String>) -> BTreeMap<&str, BTreeSet<&str>> {
    let mut g: BTreeMap<&str, BTreeSet<&str>> = BTreeMap::new();
    for (m, code) in mods {
        let base: Vec<&str> = if m.is_empty() {
            Vec::new()
        } else {
            m.split("::").collect()
        };
        let mut targets: Vec<Vec<&str>> = paths_after(code, "crate::");
        for mut p in paths_after(code, "super::") {
            let mut up = 1;
            while p.first() == Some(&"super") {
                p.remove(0);
                up += 1;
            }
            let mut full: Vec<&str> = base[..base.len().saturating_sub(up)].to_vec();
            full.extend(p);
            targets.push(full);
        }
        for t in targets {
            // The longest prefix that names a module.
            let Some(target) = (1..=t.len())
                .rev()
                .map(|k| t[..k].join("::"))
                .find(|c| mods.contains_key(c))
            else {
                continue;
            };
            let related = m.is_empty()
                || target == *m
                || m.starts_with(&format!("{target}::"))
                || target.starts_with(&format!("{m}::"));
            if !related {
                let (mk, _) = mods.get_key_value(m).unwrap();
                let (tk, _) = mods.get_key_value(&target).unwrap();
                g.entry(mk.as_str()).or_default().insert(tk.as_str());
            }
        }
    }
    g
}

/// The strongly connected sets of two or more modules (Tarjan).
fn circles<'a>(g: &BTreeMap<&'a str, BTreeSet<&'a str>>) -> Vec<Vec<&'a str>> {
    struct T<'a, 'g> {
        g: &'g BTreeMap<&'a str, BTreeSet<&'a str>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        out: Vec<Vec<&'a str>>,
    }
    impl<'a> T<'a, '_> {
        fn visit(&mut self, v: &'a str) {
            let i = self.index.len();
            self.index.insert(v, i);
            self.low.insert(v, i);
            self.stack.push(v);
            self.on.insert(v);
            for &w in self.g.get(v).into_iter().flatten() {
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let l = self.low[v].min(self.low[w]);
                    self.low.insert(v, l);
                } else if self.on.contains(w) {
                    let l = self.low[v].min(self.index[w]);
                    self.low.insert(v, l);
                }
            }
            if self.low[v] == self.index[v] {
                let mut c = Vec::new();
                while let Some(w) = self.stack.pop() {
                    self.on.remove(w);
                    c.push(w);
                    if w == v {
                        break;
                    }
                }
                if c.len() > 1 {
                    c.sort_unstable();
                    self.out.push(c);
                }
            }
        }
    }
    let mut t = T {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for &v in g.keys() {
        if !t.index.contains_key(v) {
            t.visit(v);
        }
    }
    t.out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every crate of the workspace (and xtask) is free of module circles.
    #[test]
    fn no_crate_has_modules_that_import_each_other_in_a_circle() {
        let root = crate::validate::workspace_root();
        let mut srcs: Vec<_> = std::fs::read_dir(root.join("crates"))
            .unwrap()
            .flatten()
            .map(|e| e.path().join("src"))
            .filter(|p| p.is_dir())
            .collect();
        srcs.push(root.join("xtask/src"));
        srcs.sort();
        let mut found = Vec::new();
        for src in &srcs {
            let mods = modules(src);
            assert!(!mods.is_empty(), "{}: no modules read", src.display());
            let g = edges(&mods);
            for c in circles(&g) {
                let closing: Vec<String> = c
                    .iter()
                    .flat_map(|m| {
                        g[m].iter()
                            .filter(|t| c.contains(t))
                            .map(move |t| format!("{m} → {t}"))
                    })
                    .collect();
                found.push(format!("{}: {}", src.display(), closing.join(", ")));
            }
        }
        assert!(found.is_empty(), "module circles:\n{}", found.join("\n"));
        assert!(srcs.len() >= 8, "{} crates read", srcs.len());
    }

    /// The check sees a circle when there is one (two modules naming each other, through
    /// `crate::` and `super::`), and not in comments or parent–child use.
    #[test]
    fn the_check_finds_a_planted_circle() {
        let mut mods = BTreeMap::new();
        mods.insert(String::new(), "mod a; mod b; mod c;".to_string());
        mods.insert("a".into(), strip_comments("use crate::b::X; // crate::c"));
        mods.insert("b".into(), "fn f() { super::a::g() }".to_string());
        mods.insert("c".into(), "use crate::c::d::Y;".to_string());
        mods.insert("c::d".into(), "use super::Z; use crate::a::Q;".to_string());
        let g = edges(&mods);
        assert_eq!(circles(&g), vec![vec!["a", "b"]]);
        assert!(!g["a"].contains("c"), "a comment is not an edge");
        assert!(!g.get("c").is_some_and(|s| s.contains("c::d")));
    }
}
