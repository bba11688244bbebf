//! Runs `scripts/opensim_oracle.py` and collects its `@@` result lines.

use jointfit_testkit::script::{result_lines, Script};

/// The tab-separated fields of every result line, or `None` (skipped) without Python.
///
/// # Panics
/// When the script fails to run or exits with an error.
pub fn run(args: &[&str]) -> Option<Vec<Vec<String>>> {
    let python = jointfit_testkit::python()?;
    let stdout = Script::new(&python, "opensim_oracle.py").args(args).run();
    Some(
        result_lines(&stdout)
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
