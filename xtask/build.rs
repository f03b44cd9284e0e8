//! Records the commit of the code being built (`git describe --always --dirty`) for the
//! validation report: a long run states the code it ran, not the tree at the time it ended.

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
    let describe = Command::new("git")
        .args(["describe", "--always", "--dirty"])
        .current_dir(&root)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map_or_else(|| "unknown commit".into(), |s| s.trim().to_string());
    println!("cargo:rustc-env=FEMP_BUILD_COMMIT={describe}");
}
