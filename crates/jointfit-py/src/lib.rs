//! Python bindings of jointfit: the native module `jointfit._jointfit`.
//!
//! The Python package `jointfit` (crates/jointfit-py/python/jointfit) re-exports these
//! classes and functions and adds `Job` and `batch` (sequential or on a Dask cluster) in
//! Python. Everything here is a thin conversion layer over the library crates: arrays in and
//! out as NumPy float64 (metres, radians, NaN for gaps), the GIL released during every solve,
//! every error raised as `jointfit.JointfitError` carrying the command line's one-line
//! message (the error and its causes joined by `": "`). Arguments are checked against the
//! command line's limits before any work ([`args`]); long solves can be interrupted and
//! report progress ([`run`]); a panic never reaches Python ([`run::guard`]).

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyUserWarning};
use pyo3::prelude::*;
use pyo3::types::PyDict;

mod args;
mod calibration;
mod checks;
mod model;
mod run;
mod scale;
mod solve;
mod stream;
mod trial;

create_exception!(
    jointfit,
    JointfitError,
    PyException,
    "An error of jointfit; the message is the command line's for the same failure."
);

create_exception!(
    jointfit,
    JointfitWarning,
    PyUserWarning,
    "The warnings of one call, summarized in one warning; `details` lists each of them."
);

/// A `JointfitError` with the message of `e` and its causes, as the command line prints it.
pub(crate) fn err(e: &(dyn std::error::Error + 'static)) -> PyErr {
    JointfitError::new_err(jointfit_app::message(e))
}

/// A `JointfitError` with a message of ours.
pub(crate) fn msg(text: impl Into<String>) -> PyErr {
    JointfitError::new_err(text.into())
}

/// Issues the warnings of one call as ONE `JointfitWarning`: the warning itself when there is
/// one, else their count and the first; every line in the warning's `details` attribute.
pub(crate) fn warn_all(py: Python<'_>, warnings: &[String]) -> PyResult<()> {
    if warnings.is_empty() {
        return Ok(());
    }
    let text = match warnings {
        [one] => one.clone(),
        [first, ..] => format!(
            "{} warnings; the first: {first} (all of them in this warning's .details)",
            warnings.len()
        ),
        [] => unreachable!("checked above"),
    };
    let w = JointfitWarning::new_err(text);
    let inst = w.value(py);
    inst.setattr("details", warnings.to_vec())?;
    let kwargs = PyDict::new(py);
    kwargs.set_item("stacklevel", caller_level(py))?;
    py.import("warnings")?
        .call_method("warn", (inst,), Some(&kwargs))?;
    Ok(())
}

/// The `stacklevel` of a warning issued from native code that points at the user's line:
/// 1 (the calling Python frame) plus the frames of the `jointfit` package's own Python code
/// (such as the `calibrate` wrapper) between the user and the native call.
fn caller_level(py: Python<'_>) -> usize {
    let dir = py
        .import("jointfit")
        .and_then(|m| m.getattr("__file__"))
        .and_then(|f| f.extract::<String>())
        .ok()
        .and_then(|f| {
            std::path::Path::new(&f)
                .parent()
                .map(|d| d.to_string_lossy().into_owned())
        });
    let Some(dir) = dir else {
        return 1;
    };
    let mut level = 1;
    let mut frame = py
        .import("sys")
        .and_then(|s| s.call_method1("_getframe", (0,)))
        .ok();
    while let Some(f) = frame.filter(|f| !f.is_none()) {
        let file = f
            .getattr("f_code")
            .and_then(|c| c.getattr("co_filename"))
            .and_then(|n| n.extract::<String>())
            .unwrap_or_default();
        if !file.starts_with(&dir) {
            break;
        }
        level += 1;
        frame = f.getattr("f_back").ok();
    }
    level
}

#[pymodule]
fn _jointfit(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("JointfitError", m.py().get_type::<JointfitError>())?;
    m.add("JointfitWarning", m.py().get_type::<JointfitWarning>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add(
        "BUILTIN_MODELS",
        jointfit::model::lower_limb::BUILTIN_NAMES.to_vec(),
    )?;
    m.add(
        "MARKER_SET_PRESETS",
        jointfit_landmarks::markerset::PRESET_NAMES.to_vec(),
    )?;
    m.add_class::<trial::PyTrial>()?;
    m.add_class::<model::PyModel>()?;
    m.add_class::<solve::PyIkResult>()?;
    m.add_class::<calibration::PyCalibration>()?;
    m.add_class::<calibration::PyVerdict>()?;
    m.add_class::<stream::PyStreamingIk>()?;
    m.add_function(wrap_pyfunction!(solve::personalize, m)?)?;
    m.add_function(wrap_pyfunction!(solve::ik, m)?)?;
    m.add_function(wrap_pyfunction!(solve::synthesize, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(checks::check_calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(scale::scale, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::calibration_from_json, m)?)?;
    Ok(())
}
