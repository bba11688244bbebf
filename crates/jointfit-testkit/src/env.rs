//! Where the real data and the Python oracles are: `$JOINTFIT_DATA` and `$JOINTFIT_PYTHON`.
//!
//! Real motion-capture data are never copied into the repository; tests read them from
//! `$JOINTFIT_DATA` (default: `../shared/data` beside the repository root). Python oracles
//! (scipy, ezc3d, c3d, opensim) are reached through `$JOINTFIT_PYTHON`, the interpreter of a
//! virtual environment that `.ci/run` creates. In CI (`CI` set) a missing resource is a test
//! failure; elsewhere the test prints a `skipped:` notice and passes.

use std::path::PathBuf;

/// True when the environment variable `CI` is set to something other than empty, `0` or
/// `false`: missing data or oracles are then failures, not skips.
pub fn in_ci() -> bool {
    std::env::var_os("CI").is_some_and(|v| !v.is_empty() && v != "0" && v != "false")
}

/// The shared data directory, or `None` (with a printed notice) when it is absent outside CI.
///
/// # Panics
/// In CI, when the directory does not exist.
pub fn data_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("JOINTFIT_DATA") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
    };
    if dir.is_dir() {
        return Some(dir);
    }
    if in_ci() {
        panic!(
            "test data directory {} is missing (set JOINTFIT_DATA); CI must have it",
            dir.display()
        );
    }
    eprintln!("skipped: no data at {} (set JOINTFIT_DATA)", dir.display());
    None
}

/// A file inside the shared data directory, or `None` when the directory is absent outside CI.
///
/// # Panics
/// When the data directory exists but the file does not (the test is wrong), or in CI when the
/// data directory is missing.
pub fn data_file(relative: &str) -> Option<PathBuf> {
    let path = data_dir()?.join(relative);
    assert!(path.exists(), "data file {} is missing", path.display());
    Some(path)
}

/// Every file under the shared data directory whose extension is one of `exts` (compared
/// without regard to case), sorted by path; `None` when the directory is absent outside CI.
pub fn data_files(exts: &[&str]) -> Option<Vec<PathBuf>> {
    let mut out = Vec::new();
    let mut stack = vec![data_dir()?];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("the data directory is readable") {
            let p = e.expect("the data directory is readable").path();
            if p.is_dir() {
                stack.push(p);
            } else if p
                .extension()
                .and_then(|x| x.to_str())
                .is_some_and(|x| exts.iter().any(|e| x.eq_ignore_ascii_case(e)))
            {
                out.push(p);
            }
        }
    }
    out.sort();
    Some(out)
}

/// The Python interpreter with the oracle packages, or `None` (with a notice) outside CI.
///
/// # Panics
/// In CI, when `JOINTFIT_PYTHON` is not set.
pub fn python() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("JOINTFIT_PYTHON") {
        return Some(PathBuf::from(p));
    }
    if in_ci() {
        panic!("JOINTFIT_PYTHON is not set; .ci/run must create the oracle venv");
    }
    eprintln!(
        "skipped: no Python oracle (set JOINTFIT_PYTHON to a venv with scipy, ezc3d, c3d, opensim)"
    );
    None
}
