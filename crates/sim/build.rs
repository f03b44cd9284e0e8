//! Records the commit femp is built from (`FEMP_COMMIT`, for `summary.json`): `git describe
//! --always` of the checkout's HEAD, or `unknown` outside one (a crates.io build). Uncommitted
//! changes are not recorded (watching the index would rebuild femp after every `git status`).

use std::path::Path;
use std::process::Command;

fn main() {
    let commit = Command::new("git")
        .args(["describe", "--always", "--abbrev=12"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=FEMP_COMMIT={commit}");
    // A new commit or checkout changes HEAD or the branch it names.
    let git = Path::new("../../.git");
    if git.join("HEAD").exists() {
        println!("cargo:rerun-if-changed=../../.git/HEAD");
        println!("cargo:rerun-if-changed=../../.git/refs/heads");
    } else {
        println!("cargo:rerun-if-changed=build.rs");
    }
}
