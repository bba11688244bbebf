//! `_check_calibrate`: the arguments of `calibrate` (and of `jointfit.Job`) checked before
//! any work, against the limits of `jointfit calibrate` (`FitOptions::check`), each refusal a
//! `JointfitError` naming the argument and its accepted range. Trials given as paths are
//! not read here (a `Job` may name files only its workers see).

use jointfit_app::fit::{MAX_BOOTSTRAP, MAX_ITERATIONS, MAX_STARTS};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::args;
use crate::model::PyModel;
use crate::msg;
use crate::trial::{up_arg, PyTrial};

fn given<'a, 'py>(v: Option<&'a Bound<'py, PyAny>>) -> Option<&'a Bound<'py, PyAny>> {
    v.filter(|v| !v.is_none())
}

/// Checks the arguments of `calibrate(model, trials, **options)`; returns None or raises
/// `JointfitError`. Options it does not know are left to `calibrate` itself.
#[pyfunction]
#[pyo3(name = "_check_calibrate", signature = (model, trials, **options))]
pub fn check_calibrate(
    model: &Bound<'_, PyAny>,
    trials: &Bound<'_, PyAny>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<()> {
    crate::run::guard(|| {
        if let Some(options) = options {
            check_options(options)?;
        }
        let compiled = match model.cast::<PyModel>() {
            Ok(m) if m.get().osim.is_none() => Some(m.get().model.clone()),
            Ok(_) => None,
            Err(_) => {
                let name = crate::solve::model_name(model)?;
                jointfit::model::lower_limb::BUILTIN_NAMES
                    .contains(&name.as_str())
                    .then(|| jointfit_io::model_file::load_model(&name).ok())
                    .flatten()
            }
        };
        // The joint groups exist in the model (an .osim model names its joints instead, and a
        // model file is read only when the fit runs).
        if let (Some(m), Some(j)) = (
            compiled,
            options.and_then(|o| o.get_item("joints").ok().flatten()),
        ) {
            if !j.is_none() {
                let groups: Vec<String> = match j.extract::<String>() {
                    Ok(s) => s.split(',').map(|g| g.trim().to_string()).collect(),
                    Err(_) => args::strings(&j, "joints")?,
                };
                let refs: Vec<&str> = groups.iter().map(String::as_str).collect();
                jointfit::calibrate::params_for_groups(&m, &refs).map_err(|e| crate::err(&e))?;
            }
        }
        check_trials(trials)
    })
}

/// The options of `calibrate`, each against its limits.
fn check_options(options: &Bound<'_, PyDict>) -> PyResult<()> {
    {
        for (key, v) in options.iter() {
            let key: String = key.extract()?;
            let Some(v) = given(Some(&v)) else {
                continue;
            };
            match key.as_str() {
                "joints" if !v.is_instance_of::<pyo3::types::PyString>() => {
                    args::strings(v, "joints")?;
                }
                "method" => {
                    args::choice(v, "method", &["joint", "gradient", "pso"])?;
                }
                "up" => {
                    up_arg(Some(v))?;
                }
                "filter" => {
                    args::cutoff(Some(v), "filter")?;
                }
                "seed" => {
                    args::whole(v, "seed", 0, u64::MAX)?;
                }
                "bootstrap" => {
                    args::whole(v, "bootstrap", 0, MAX_BOOTSTRAP as u64)?;
                }
                "starts" => {
                    args::whole(v, "starts", 1, MAX_STARTS as u64)?;
                }
                "max_iter" => {
                    args::whole(v, "max_iter", 1, MAX_ITERATIONS as u64)?;
                }
                "threshold_mm" => {
                    args::positive(v, "threshold_mm", f64::MAX, " mm")?;
                }
                "threshold_deg" => {
                    args::positive(v, "threshold_deg", f64::MAX, " deg")?;
                }
                "marker_noise_mm" => {
                    args::positive(v, "marker_noise_mm", jointfit_app::fit::MAX_NOISE_MM, " mm")?;
                }
                "fix_unidentifiable" => {
                    args::flag(v, "fix_unidentifiable")?;
                }
                "accept_rejected" => {
                    args::flag(v, "accept_rejected")?;
                }
                "prior" => {
                    args::choice(v, "prior", &["model", "none"])?;
                }
                "params" => {
                    args::strings(v, "params")?;
                }
                "progress" if !(v.is_instance_of::<pyo3::types::PyBool>() || v.is_callable()) => {
                    return Err(msg(format!(
                        "progress must be None, True, False or a callable \
                             progress(stage, iteration, objective), not {}",
                        args::type_name(v)
                    )));
                }
                _ => {}
            }
        }
        Ok(())
    }
}

/// `trials`: a Trial, a path, or a non-empty list of them.
fn check_trials(trials: &Bound<'_, PyAny>) -> PyResult<()> {
    let one = |t: &Bound<'_, PyAny>| -> PyResult<()> {
        if t.cast::<PyTrial>().is_ok() {
            return Ok(());
        }
        crate::solve::trial_path(t).map(|_| ())
    };
    if trials.cast::<PyTrial>().is_ok() || trials.is_instance_of::<pyo3::types::PyString>() {
        return one(trials);
    }
    if trials.extract::<std::path::PathBuf>().is_ok() {
        return Ok(());
    }
    let items: Vec<Bound<'_, PyAny>> = match trials.cast::<PyList>() {
        Ok(l) => l.iter().collect(),
        Err(_) => trials
            .try_iter()
            .and_then(|it| it.collect::<PyResult<Vec<_>>>())
            .map_err(|_| {
                msg(format!(
                    "trials must be a jointfit.Trial, a path or a list of them, not {}",
                    args::type_name(trials)
                ))
            })?,
    };
    if items.is_empty() {
        return Err(msg(
            "trials must hold at least one trial (got an empty list)",
        ));
    }
    for t in &items {
        one(t)?;
    }
    Ok(())
}
