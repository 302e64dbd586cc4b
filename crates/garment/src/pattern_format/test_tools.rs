//! Helpers for the writers' tests that call outside checkers (ezdxf, pdftoppm): find them, or skip with a
//! note — except in CI (`CI=true`), where a missing checker fails the test.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Whether the tests run in CI (`CI=true`), where every outside checker must be there.
pub(crate) fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// Skips a check whose tool is missing: a note outside CI, a failure in CI.
pub(crate) fn missing(check: &str, why: &str) {
    assert!(!in_ci(), "CI=true but {check} cannot run: {why}");
    eprintln!("note: skipping {check}: {why}");
}

/// A Python interpreter that has a module.
pub(crate) struct Python(PathBuf);

/// The interpreter in `SKINTIGHT_PYTHON` if it imports `module`; `None` (after [`missing`]) otherwise.
pub(crate) fn python_with(module: &str, check: &str) -> Option<Python> {
    let Some(path) = std::env::var_os("SKINTIGHT_PYTHON").filter(|p| !p.is_empty()) else {
        missing(
            check,
            "SKINTIGHT_PYTHON is not set (a Python with ezdxf; .ci/run makes one)",
        );
        return None;
    };
    let ok = Command::new(&path)
        .args(["-c", &format!("import {module}")])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        missing(
            check,
            &format!("SKINTIGHT_PYTHON={path:?} cannot import {module}"),
        );
        return None;
    }
    Some(Python(path.into()))
}

impl Python {
    /// Runs `python -c script args…` and parses its standard output as JSON; panics with its standard
    /// error if it fails.
    pub(crate) fn run(&self, script: &str, args: &[&str]) -> serde_json::Value {
        let out = Command::new(&self.0)
            .arg("-c")
            .arg(script)
            .args(args)
            .output()
            .expect("run python");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "python failed: {stderr}");
        if !stderr.trim().is_empty() {
            eprintln!("python: {stderr}");
        }
        serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
            panic!(
                "python printed no JSON ({e}): {}",
                String::from_utf8_lossy(&out.stdout)
            )
        })
    }
}

/// Whether `program` is on `PATH`.
pub(crate) fn on_path(program: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|dir| is_file(&dir.join(program))))
}

fn is_file(path: &Path) -> bool {
    path.is_file()
}

/// A fresh scratch folder for one test (removed by the test when it passes).
pub(crate) fn scratch_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "skintight-pattern-format-{tag}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
