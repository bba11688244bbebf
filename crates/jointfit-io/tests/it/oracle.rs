//! Runs `scripts/opensim_oracle.py` and collects its `@@` result lines.

use std::path::{Path, PathBuf};
use std::process::Command;

pub fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/opensim_oracle.py")
}

/// The tab-separated fields of every result line, or `None` (skipped) without Python.
///
/// # Panics
/// When the script fails to run or exits with an error.
pub fn run(args: &[&str]) -> Option<Vec<Vec<String>>> {
    let python = jointfit::testing::python()?;
    let out = Command::new(&python)
        .arg(script())
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", python.display()));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "oracle {args:?} failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        stdout
    );
    Some(
        stdout
            .lines()
            .filter_map(|l| l.strip_prefix("@@"))
            .map(|l| l.split('\t').map(str::to_string).collect())
            .collect(),
    )
}

/// Parses a number printed by Python's `repr` (`nan`, `inf` included).
pub fn num(s: &str) -> f64 {
    s.parse()
        .unwrap_or_else(|_| panic!("oracle printed {s:?}, not a number"))
}

/// Same value bit for bit, or both NaN.
pub fn same(a: f64, b: f64) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}
