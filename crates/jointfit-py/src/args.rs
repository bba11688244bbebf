//! Arguments from Python, checked against the command line's limits: every refusal is a
//! `JointfitError` naming the argument and what it accepts, raised before any work (and any
//! allocation sized by the argument).

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::{PyBool, PyFloat, PyString};

use crate::msg;

/// Most frames of a synthetic motion (the command line's `--frames` limit).
pub const MAX_FRAMES: u64 = 100_000;
/// Largest sampling rate (Hz), as on the command line.
pub const MAX_RATE_HZ: f64 = jointfit_app::read::MAX_RATE_HZ;
/// Lowest low-pass cutoff (Hz), as on the command line.
pub const MIN_FILTER_HZ: f64 = 0.1;
/// Largest noise amplitude of a synthetic trial (mm).
pub const MAX_NOISE_MM: f64 = jointfit_app::fit::MAX_NOISE_MM;
/// Longest averaging window of a static trial (s).
pub const MAX_WINDOW_S: f64 = 3_600.0;

/// How a value shows in a message: its `repr`, shortened.
pub(crate) fn shown(v: &Bound<'_, PyAny>) -> String {
    let r = v
        .repr()
        .map(|r| r.to_string())
        .unwrap_or_else(|_| "?".into());
    if r.chars().count() > 60 {
        let head: String = r.chars().take(57).collect();
        format!("{head}...")
    } else {
        r
    }
}

/// The Python type name of `v`.
pub(crate) fn type_name(v: &Bound<'_, PyAny>) -> String {
    v.get_type()
        .name()
        .map_or_else(|_| "?".into(), |n| n.to_string())
}

/// A whole number from `lo` to `hi` (Python ints and NumPy integers; not bools or floats).
pub(crate) fn whole(v: &Bound<'_, PyAny>, name: &str, lo: u64, hi: u64) -> PyResult<u64> {
    let refuse = || {
        msg(format!(
            "{name} must be a whole number from {lo} to {hi} (got {})",
            shown(v)
        ))
    };
    if v.is_instance_of::<PyBool>()
        || v.is_instance_of::<PyFloat>()
        || v.is_instance_of::<PyString>()
    {
        return Err(refuse());
    }
    match v.extract::<u64>() {
        Ok(n) if (lo..=hi).contains(&n) => Ok(n),
        _ => Err(refuse()),
    }
}

/// A whole number that may be negative (a frame number).
pub(crate) fn signed(v: &Bound<'_, PyAny>, name: &str) -> PyResult<i64> {
    if v.is_instance_of::<PyBool>()
        || v.is_instance_of::<PyFloat>()
        || v.is_instance_of::<PyString>()
    {
        return Err(msg(format!(
            "{name} must be a whole number (got {})",
            shown(v)
        )));
    }
    v.extract::<i64>().map_err(|_| {
        msg(format!(
            "{name} must be a whole number from {} to {} (got {})",
            i64::MIN,
            i64::MAX,
            shown(v)
        ))
    })
}

/// A finite number (Python ints and floats, NumPy scalars).
pub(crate) fn number(v: &Bound<'_, PyAny>, name: &str, range: &str) -> PyResult<f64> {
    if v.is_instance_of::<PyString>() || v.is_instance_of::<PyBool>() {
        return Err(msg(format!("{name} must be {range} (got {})", shown(v))));
    }
    match v.extract::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(msg(format!("{name} must be {range} (got {})", shown(v)))),
    }
}

/// A finite number from `lo` to `hi` (`unit` follows the numbers in the message).
pub(crate) fn within(
    v: &Bound<'_, PyAny>,
    name: &str,
    lo: f64,
    hi: f64,
    unit: &str,
) -> PyResult<f64> {
    let range = format!("a finite number from {lo} to {hi}{unit}");
    let x = number(v, name, &range)?;
    if x < lo || x > hi {
        return Err(msg(format!("{name} must be {range} (got {x})")));
    }
    Ok(x)
}

/// A finite number greater than 0 and at most `hi`.
pub(crate) fn positive(v: &Bound<'_, PyAny>, name: &str, hi: f64, unit: &str) -> PyResult<f64> {
    let range = if hi == f64::MAX {
        format!("a finite number greater than 0{unit}")
    } else {
        format!("a finite number greater than 0 and at most {hi}{unit}")
    };
    let x = number(v, name, &range)?;
    if x <= 0.0 || x > hi {
        return Err(msg(format!("{name} must be {range} (got {x})")));
    }
    Ok(x)
}

/// A low-pass cutoff (Hz): None, or a finite number of at least [`MIN_FILTER_HZ`].
pub(crate) fn cutoff(v: Option<&Bound<'_, PyAny>>, name: &str) -> PyResult<Option<f64>> {
    match v {
        None => Ok(None),
        Some(v) if v.is_none() => Ok(None),
        Some(v) => {
            let range = format!("None or a finite cutoff of at least {MIN_FILTER_HZ} Hz");
            let x = number(v, name, &range)?;
            if x < MIN_FILTER_HZ {
                return Err(msg(format!("{name} must be {range} (got {x})")));
            }
            Ok(Some(x))
        }
    }
}

/// A string argument.
pub(crate) fn text(v: &Bound<'_, PyAny>, name: &str, what: &str) -> PyResult<String> {
    if !v.is_instance_of::<PyString>() {
        return Err(msg(format!(
            "{name} must be {what}, not {} {}",
            type_name(v),
            shown(v)
        )));
    }
    v.extract::<String>()
}

/// An optional string argument (None accepted).
pub(crate) fn opt_text(
    v: Option<&Bound<'_, PyAny>>,
    name: &str,
    what: &str,
) -> PyResult<Option<String>> {
    match v {
        None => Ok(None),
        Some(v) if v.is_none() => Ok(None),
        Some(v) => text(v, name, what).map(Some),
    }
}

/// One of `choices`.
pub(crate) fn choice(v: &Bound<'_, PyAny>, name: &str, choices: &[&str]) -> PyResult<String> {
    let list = choices
        .iter()
        .map(|c| format!("{c:?}"))
        .collect::<Vec<_>>()
        .join(", ");
    let s = text(v, name, &format!("one of {list}"))?;
    if choices.contains(&s.as_str()) {
        Ok(s)
    } else {
        Err(msg(format!("{name} must be one of {list}, not {s:?}")))
    }
}

/// A path: a str or an os.PathLike.
pub(crate) fn path(v: &Bound<'_, PyAny>, name: &str) -> PyResult<PathBuf> {
    if v.is_instance_of::<PyBool>() {
        return Err(msg(format!(
            "{name} must be a path (str or os.PathLike), not bool"
        )));
    }
    let p: PathBuf = v.extract().map_err(|_| {
        msg(format!(
            "{name} must be a path (str or os.PathLike), not {} {}",
            type_name(v),
            shown(v)
        ))
    })?;
    if p.as_os_str().is_empty() {
        return Err(msg(format!("{name} must be a path, not an empty string")));
    }
    Ok(p)
}

/// A list of strings (a tuple or any iterable of str; a lone str is refused as ambiguous).
pub(crate) fn strings(v: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<String>> {
    let refuse = || {
        msg(format!(
            "{name} must be a list of strings, not {} {}",
            type_name(v),
            shown(v)
        ))
    };
    if v.is_instance_of::<PyString>() {
        return Err(refuse());
    }
    let items = v.try_iter().map_err(|_| refuse())?;
    let mut out = Vec::new();
    for item in items {
        let item = item?;
        if !item.is_instance_of::<PyString>() {
            return Err(msg(format!(
                "{name} must be a list of strings; it holds {} {}",
                type_name(&item),
                shown(&item)
            )));
        }
        out.push(item.extract::<String>()?);
    }
    Ok(out)
}

/// A bool (Python's bool, NumPy's bool_).
pub(crate) fn flag(v: &Bound<'_, PyAny>, name: &str) -> PyResult<bool> {
    if v.is_instance_of::<PyBool>() || type_name(v) == "bool_" {
        return v.is_truthy();
    }
    Err(msg(format!(
        "{name} must be True or False (got {})",
        shown(v)
    )))
}
