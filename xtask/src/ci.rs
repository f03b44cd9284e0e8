//! `cargo xtask ci`: the CI steps, each run even if an earlier one failed.

use std::process::Command;

/// The steps of CI, in order. Keep in sync with `.ci/run` and the README's test command.
const STEPS: &[(&str, &[&str])] = &[
    ("format", &["fmt", "--all", "--", "--check"]),
    (
        "clippy",
        &[
            "clippy",
            "--workspace",
            "--all-targets",
            "--",
            "-D",
            "warnings",
        ],
    ),
    ("tests", &["test", "--workspace", "--release"]),
    ("validate", &["xtask", "validate", "--quick", "--jobs", "2"]),
];

/// The Python package's tests (after the Rust tests in `.ci/run`; a script, not cargo).
const PYTHON_TESTS: &str = "crates/python/test.sh";

pub fn run() -> anyhow::Result<()> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut failed = Vec::new();
    for (name, args) in STEPS {
        eprintln!("== {name}: cargo {}", args.join(" "));
        let ok = Command::new(&cargo)
            .args(*args)
            .status()
            .map(|s| s.success())
            .unwrap_or(false);
        if !ok {
            failed.push(*name);
        }
        if *name == "tests" {
            eprintln!("== python: {PYTHON_TESTS}");
            let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
            let ok = Command::new(root.join(PYTHON_TESTS))
                .current_dir(&root)
                .status()
                .map(|s| s.success())
                .unwrap_or(false);
            if !ok {
                failed.push("python");
            }
        }
    }
    if failed.is_empty() {
        eprintln!("== all CI steps passed");
        Ok(())
    } else {
        anyhow::bail!("CI steps failed: {}", failed.join(", "))
    }
}
