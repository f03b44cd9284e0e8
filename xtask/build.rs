//! Records the commit of the code being built (`git describe --always`, `-dirty` if the code —
//! not the docs — has uncommitted changes) for the validation report: a long run states the code
//! it ran, not the tree at the time it ended.

use std::process::Command;

fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    // Re-run when the sources or the checked-out commit change (directories are scanned whole).
    // (A path that does not exist would re-run it on every build: outside a git work tree there
    // is nothing to watch but the sources.)
    for p in [
        "crates",
        "xtask/src",
        "fixtures/scenes",
        ".git/HEAD",
        ".git/index",
    ] {
        if root.join(p).exists() {
            println!("cargo:rerun-if-changed={}", root.join(p).display());
        }
    }
    let git = |args: &[&str]| {
        Command::new("git")
            .args(args)
            .current_dir(&root)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .and_then(|o| String::from_utf8(o.stdout).ok())
    };
    let describe = git(&["describe", "--always"])
        .map_or_else(|| "unknown commit".into(), |s| s.trim().to_string());
    // Only what the binary is built from counts (a regenerated report in docs/ does not).
    let code = [
        "crates",
        "xtask",
        "fixtures",
        "Cargo.toml",
        "Cargo.lock",
        ".cargo",
    ];
    let mut status = vec!["status", "--porcelain", "--"];
    status.extend(code);
    let dirty = git(&status).is_some_and(|s| !s.trim().is_empty());
    let suffix = if dirty { "-dirty" } else { "" };
    println!("cargo:rustc-env=FEMP_BUILD_COMMIT={describe}{suffix}");
}
