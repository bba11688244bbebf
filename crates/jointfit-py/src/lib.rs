//! Python bindings of jointfit: the native module `jointfit._jointfit`.
//!
//! The Python package `jointfit` (crates/jointfit-py/python/jointfit) re-exports these
//! classes and functions and adds `Job` and `batch` (sequential or on a Dask cluster) in
//! Python. Everything here is a thin conversion layer over the library crates: arrays in and
//! out as NumPy float64 (metres, radians, NaN for gaps), the GIL released during every solve,
//! every error raised as `jointfit.JointfitError` carrying the command line's one-line
//! message (the error and its causes joined by `": "`).

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

mod calibration;
mod model;
mod scale;
mod solve;
mod trial;

create_exception!(
    jointfit,
    JointfitError,
    PyException,
    "An error of jointfit; the message is the command line's for the same failure."
);

/// A `JointfitError` with the message of `e` and its causes, as the command line prints it.
pub(crate) fn err(e: &(dyn std::error::Error + 'static)) -> PyErr {
    JointfitError::new_err(jointfit_io::batch::message(e))
}

/// A `JointfitError` with a message of ours.
pub(crate) fn msg(text: impl Into<String>) -> PyErr {
    JointfitError::new_err(text.into())
}

/// Issues each warning as a Python `UserWarning`.
pub(crate) fn warn_all(py: Python<'_>, warnings: &[String]) -> PyResult<()> {
    let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
    for w in warnings {
        let text = std::ffi::CString::new(w.replace('\0', " ")).expect("no NUL left");
        PyErr::warn(py, &category, &text, 1)?;
    }
    Ok(())
}

#[pymodule]
fn _jointfit(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("JointfitError", m.py().get_type::<JointfitError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add(
        "BUILTIN_MODELS",
        jointfit::model::lower_limb::BUILTIN_NAMES.to_vec(),
    )?;
    m.add(
        "MARKER_SET_PRESETS",
        jointfit::landmarks::PRESET_NAMES.to_vec(),
    )?;
    m.add_class::<trial::PyTrial>()?;
    m.add_class::<model::PyModel>()?;
    m.add_class::<solve::PyIkResult>()?;
    m.add_class::<calibration::PyCalibration>()?;
    m.add_function(wrap_pyfunction!(solve::personalize, m)?)?;
    m.add_function(wrap_pyfunction!(solve::ik, m)?)?;
    m.add_function(wrap_pyfunction!(solve::synthesize, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(scale::scale, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::calibration_from_json, m)?)?;
    Ok(())
}
