//! The workspace's structure check: no crate's modules import each other in a circle.
//!
//! Each crate's source files are modules (`a/b.rs` and `a/b/mod.rs` are `a::b`); a module
//! depends on another when its code (comments aside) names it through `crate::…` or
//! `super::…`. A parent and its own child modules are one unit (a parent declares its
//! children; a child may use its parent's items). Any strongly connected set of two or more
//! modules is a circle: each can only be understood, tested or moved with all the others.
//! Run as a test (`cargo test -p xtask`), so CI fails on a new circle, naming its modules and the
//! edges that close it.
//!
//! And no function of a crate's library code (tests aside) longer than [`MAX_FUNCTION_LINES`]
//! without a stated reason: a comment starting `// Long:` in the lines just above it (its doc
//! comment or attributes between) says why it is one piece. A long function is read, tested and
//! changed as a whole; the check fails naming each one, with its length.

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

/// The longest function a crate's library code has without a stated reason (lines from `fn`
/// to its closing brace).
const MAX_FUNCTION_LINES: usize = 150;

/// One function of a source file: its name, first line (1-based) and length in lines.
#[derive(Debug, PartialEq)]
struct Function {
    name: String,
    line: usize,
    lines: usize,
    /// A `// Long:` comment just above it says why it is long.
    reason: bool,
}

/// The characters of `text` with comments, string and character literals blanked to spaces
/// (newlines kept): code positions only, so that a brace in them does not count.
fn code_only(text: &str) -> Vec<char> {
    let c: Vec<char> = text.chars().collect();
    let n = c.len();
    let mut code = c.clone();
    let mut i = 0;
    let blank = |code: &mut Vec<char>, from: usize, to: usize| {
        for ch in &mut code[from..to.min(n)] {
            if *ch != '\n' {
                *ch = ' ';
            }
        }
    };
    while i < n {
        if c[i] == '/' && c.get(i + 1) == Some(&'/') {
            let j = (i..n).find(|&k| c[k] == '\n').unwrap_or(n);
            blank(&mut code, i, j);
            i = j;
        } else if c[i] == '/' && c.get(i + 1) == Some(&'*') {
            let j = (i + 2..n.saturating_sub(1))
                .find(|&k| c[k] == '*' && c[k + 1] == '/')
                .map_or(n, |k| k + 2);
            blank(&mut code, i, j);
            i = j;
        } else if c[i] == 'r'
            && (i == 0 || !(c[i - 1].is_alphanumeric() || c[i - 1] == '_'))
            && matches!(c.get(i + 1), Some('"' | '#'))
        {
            // A raw string r"…", r#"…"#.
            let hashes = c[i + 1..].iter().take_while(|&&ch| ch == '#').count();
            if c.get(i + 1 + hashes) != Some(&'"') {
                i += 1;
                continue;
            }
            let close: Vec<char> = std::iter::once('"')
                .chain(std::iter::repeat_n('#', hashes))
                .collect();
            let start = i + 2 + hashes;
            let j = (start..n)
                .find(|&k| c[k..].starts_with(&close))
                .map_or(n, |k| k + close.len());
            blank(&mut code, i, j);
            i = j;
        } else if c[i] == '"' {
            let mut j = i + 1;
            while j < n && c[j] != '"' {
                j += if c[j] == '\\' { 2 } else { 1 };
            }
            blank(&mut code, i, j + 1);
            i = j + 1;
        } else if c[i] == '\'' {
            // A character literal ('x', '\n', '\u{7b}'), or a lifetime ('a).
            let end = if c.get(i + 1) == Some(&'\\') {
                (i + 2..n).find(|&k| c[k] == '\'')
            } else if c.get(i + 2) == Some(&'\'') {
                Some(i + 2)
            } else {
                None
            };
            match end {
                Some(j) => {
                    blank(&mut code, i, j + 1);
                    i = j + 1;
                }
                None => i += 1,
            }
        } else {
            i += 1;
        }
    }
    code
}

/// The functions of `text` that have a body, outside `#[cfg(test)]` items, nested ones too.
/// Comments, string and character literals are skipped ([`code_only`]).
fn functions(text: &str) -> Vec<Function> {
    let c: Vec<char> = text.chars().collect();
    let code = code_only(text);
    let n = code.len();
    let line_of = |k: usize| c[..k].iter().filter(|&&ch| ch == '\n').count() + 1;
    let word_at = |k: usize, w: &str| {
        let wc: Vec<char> = w.chars().collect();
        code[k..].starts_with(&wc)
            && (k == 0 || !(code[k - 1].is_alphanumeric() || code[k - 1] == '_'))
            && code
                .get(k + wc.len())
                .is_none_or(|ch| !(ch.is_alphanumeric() || *ch == '_'))
    };
    // The end (one past the closing brace) of the block opening at the first `{` from `k`
    // (None if a `;` comes first: no body).
    let block_end = |k: usize| -> Option<(usize, usize)> {
        let open = (k..n).find(|&j| code[j] == '{' || code[j] == ';')?;
        if code[open] == ';' {
            return None;
        }
        let mut depth = 0usize;
        for (j, &ch) in code.iter().enumerate().skip(open) {
            match ch {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        return Some((open, j + 1));
                    }
                }
                _ => {}
            }
        }
        Some((open, n))
    };
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut k = 0;
    while k < n {
        if code[k..].starts_with(&['#', '[', 'c', 'f', 'g', '(', 't', 'e', 's', 't', ')', ']']) {
            // Skip the item the attribute is on.
            match block_end(k) {
                Some((_, end)) => k = end,
                None => k += 1,
            }
            continue;
        }
        if word_at(k, "fn") {
            let name: String = code[k + 2..]
                .iter()
                .skip_while(|ch| ch.is_whitespace())
                .take_while(|ch| ch.is_alphanumeric() || **ch == '_')
                .collect();
            if let Some((_, end)) = block_end(k) {
                let (first, last) = (line_of(k), line_of(end - 1));
                // The comment lines, attributes and doc lines right above the `fn` line.
                let reason = lines[..first - 1]
                    .iter()
                    .rev()
                    .map(|l| l.trim())
                    .take_while(|l| l.starts_with("//") || l.starts_with("#["))
                    .any(|l| l.starts_with("// Long:"));
                out.push(Function {
                    name,
                    line: first,
                    lines: last - first + 1,
                    reason,
                });
            }
            k += 2;
            continue;
        }
        k += 1;
    }
    out
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

    /// The simulator's output layer (crates/sim `io`: metrics, output, pictures) sits above the
    /// simulation: only `run` (which drives it) and the crate root (which re-exports it) use it,
    /// by its own path or the re-exported one.
    #[test]
    fn nothing_below_the_io_layer_imports_it() {
        let mods = modules(&crate::validate::workspace_root().join("crates/sim/src"));
        assert!(
            mods.contains_key("io::metrics"),
            "crates/sim/src/io not found"
        );
        let g = edges(&mods);
        let above = |m: &str| m.is_empty() || m == "run" || m == "io" || m.starts_with("io::");
        let mut bad = Vec::new();
        for (m, code) in &mods {
            if above(m) {
                continue;
            }
            for t in g.get(m.as_str()).into_iter().flatten() {
                if t.starts_with("io") {
                    bad.push(format!("{m} → {t}"));
                }
            }
            for name in ["metrics", "output", "render"] {
                if !paths_after(code, "crate::")
                    .iter()
                    .all(|p| p.first() != Some(&name))
                {
                    bad.push(format!("{m} → crate::{name} (the io layer, re-exported)"));
                }
            }
        }
        assert!(
            bad.is_empty(),
            "the io layer imported from below:\n{}",
            bad.join("\n")
        );
    }

    /// No function of the crates and xtask (`src`, tests aside) is longer than [`MAX_FUNCTION_LINES`]
    /// without a `// Long:` reason above it.
    #[test]
    fn no_library_function_is_long_without_a_reason() {
        let root = crate::validate::workspace_root();
        let mut long = Vec::new();
        let mut stack = vec![root.join("crates"), root.join("xtask")];
        let mut read = 0;
        while let Some(dir) = stack.pop() {
            for e in std::fs::read_dir(&dir).unwrap().flatten() {
                let p = e.path();
                let rel = p
                    .strip_prefix(&root)
                    .unwrap()
                    .to_string_lossy()
                    .into_owned();
                if p.is_dir() {
                    // Library code only: not integration tests, benches or examples.
                    let name = p.file_name().unwrap().to_string_lossy();
                    if !matches!(name.as_ref(), "tests" | "benches" | "examples" | "target") {
                        stack.push(p);
                    }
                } else if p.extension().is_some_and(|x| x == "rs") && rel.contains("/src/") {
                    read += 1;
                    let text = std::fs::read_to_string(&p).unwrap();
                    for f in functions(&text) {
                        if f.lines > MAX_FUNCTION_LINES && !f.reason {
                            long.push(format!(
                                "{rel}:{} fn {} ({} lines)",
                                f.line, f.name, f.lines
                            ));
                        }
                    }
                }
            }
        }
        assert!(read > 50, "{read} source files read");
        long.sort();
        assert!(
            long.is_empty(),
            "functions over {MAX_FUNCTION_LINES} lines without a `// Long:` reason above them \
             (split them, or say why they are one piece):\n{}",
            long.join("\n")
        );
    }

    /// Function lengths are counted from `fn` to its closing brace, braces in comments and
    /// literals aside, test items skipped, and a `// Long:` reason seen through doc comments.
    #[test]
    fn function_lengths_are_counted_as_written() {
        let text = r##"
/// Doc.
pub fn a() {
    let s = "}}}"; let r = r#"{"#; let c = '}'; let l: &'static str = "x";
    // }
    /* { */
}

fn decl();

// Long: one piece.
/// Doc.
#[inline]
fn b<'a>(x: &'a str) -> &'a str {
    fn inner() {}
    x
}

#[cfg(test)]
mod tests {
    fn hidden() {}
}
"##;
        let f = functions(text);
        let got: Vec<(&str, usize, usize, bool)> = f
            .iter()
            .map(|f| (f.name.as_str(), f.line, f.lines, f.reason))
            .collect();
        assert_eq!(
            got,
            vec![
                ("a", 3, 5, false),
                ("b", 14, 4, true),
                ("inner", 15, 1, false)
            ]
        );
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
