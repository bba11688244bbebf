//! `calibrate` and `jointfit.Calibration`: the two-level fit of joint parameters.

use jointfit::model::spec::Unit;
use jointfit_app::{
    run_observed, Calibration, FitOptions, ModelSource, ReadOptions, Request, TrialSource,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

use crate::model::PyModel;
use crate::trial::{parse_up, PyTrial};
use crate::{err, msg, warn_all};

/// The result of `calibrate`: the fitted model, the fitted parameters with their 95 %
/// intervals, the marker RMS before and after, warnings. SI units (m, rad) throughout.
#[pyclass(name = "Calibration", module = "jointfit", frozen)]
pub struct PyCalibration {
    pub(crate) cal: Calibration,
    /// The `.osim` the model came from (its fitted model saves back into it).
    pub(crate) osim: Option<std::sync::Arc<jointfit_io::osim_read::OsimModel>>,
}

#[pymethods]
impl PyCalibration {
    /// The fitted model (its parameters are the fitted values; fixed ones unchanged).
    #[getter]
    fn model(&self) -> PyResult<PyModel> {
        PyModel::with_osim(&self.cal.model, self.osim.clone())
    }
    /// Fitted values of the free parameters: dict name → value (m or rad).
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for p in &self.cal.parameters {
            d.set_item(&p.name, p.fitted)?;
        }
        Ok(d)
    }
    /// Starting values of the free parameters: dict name → value (m or rad).
    #[getter]
    fn start<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for p in &self.cal.parameters {
            d.set_item(&p.name, p.start)?;
        }
        Ok(d)
    }
    /// 95 % intervals of the free parameters: dict name → (low, high), or None where the
    /// trials do not determine the parameter.
    #[getter]
    fn intervals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for p in &self.cal.parameters {
            d.set_item(&p.name, p.ci95.map(|[lo, hi]| (lo, hi)))?;
        }
        Ok(d)
    }
    /// Standard errors of the free parameters: dict name → value or None.
    #[getter]
    fn standard_errors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for p in &self.cal.parameters {
            d.set_item(&p.name, p.se)?;
        }
        Ok(d)
    }
    /// RMS marker distance over all present samples at the start (m).
    #[getter]
    fn rms_before(&self) -> f64 {
        self.cal.rms_before
    }
    /// RMS marker distance over all present samples at the optimum (m).
    #[getter]
    fn rms_after(&self) -> f64 {
        self.cal.rms_after
    }
    /// Frames fitted (over all trials) and frames skipped for missing markers.
    #[getter]
    fn frames(&self) -> (usize, usize) {
        (self.cal.frames, self.cal.skipped_frames)
    }
    /// Whether the outer solver met its convergence test.
    #[getter]
    fn converged(&self) -> bool {
        self.cal.converged
    }
    /// Outer iterations.
    #[getter]
    fn iterations(&self) -> usize {
        self.cal.iterations
    }
    /// Reading and fitting warnings (filtering moves, poorly determined parameters).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.cal.warnings.clone()
    }
    /// How far to trust the fit: `.level` ("ok", "caution" or "reject") and `.reasons`, the
    /// command line's verdict.
    #[getter]
    fn verdict(&self) -> PyVerdict {
        PyVerdict {
            level: self.cal.verdict.level.to_string(),
            reasons: self.cal.verdict.reasons.clone(),
        }
    }
    /// Everything as plain Python values (the row of `jointfit batch`'s results.json,
    /// plus the fitted model as TOML text).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let json = py.import("json")?;
        let d = json.call_method1("loads", (self.to_json()?,))?;
        d.set_item("model", self.cal.model.to_toml())?;
        Ok(d)
    }
    /// The calibration as JSON text (floats round-trip exactly).
    fn to_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.cal).map_err(|e| msg(e.to_string()))
    }
    fn __repr__(&self) -> String {
        format!(
            "Calibration({} parameters, RMS {:.2} → {:.2} mm{})",
            self.cal.parameters.len(),
            self.cal.rms_before * 1e3,
            self.cal.rms_after * 1e3,
            if self.cal.converged {
                ""
            } else {
                ", not converged"
            }
        )
    }
    fn __eq__(&self, other: &Self) -> bool {
        self.cal == other.cal
    }
    /// Pickles as JSON (exact), so results come back from Dask workers unchanged.
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let ctor = py
            .import("jointfit._jointfit")?
            .getattr("_calibration_from_json")?;
        Ok((ctor, PyTuple::new(py, [self.to_json()?])?))
    }
    /// The parameter table as a pandas DataFrame, one row per free parameter (index
    /// `parameter`): `group`, `unit` ("m" or "rad"), `start`, `fitted`, `se` (standard
    /// error), `ci95_low`, `ci95_high` (NaN where the trials do not determine the parameter),
    /// `identifiability`. SI units. Needs pandas.
    fn to_dataframe<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let pd = py
            .import("pandas")
            .map_err(|_| msg("to_dataframe needs pandas (pip install pandas)"))?;
        let rows = &self.cal.parameters;
        let col = PyDict::new(py);
        let nan = f64::NAN;
        col.set_item(
            "group",
            rows.iter().map(|r| r.group.clone()).collect::<Vec<_>>(),
        )?;
        col.set_item(
            "unit",
            rows.iter().map(|r| r.unit.clone()).collect::<Vec<_>>(),
        )?;
        col.set_item("start", rows.iter().map(|r| r.start).collect::<Vec<_>>())?;
        col.set_item("fitted", rows.iter().map(|r| r.fitted).collect::<Vec<_>>())?;
        col.set_item(
            "se",
            rows.iter().map(|r| r.se.unwrap_or(nan)).collect::<Vec<_>>(),
        )?;
        col.set_item(
            "ci95_low",
            rows.iter()
                .map(|r| r.ci95.map_or(nan, |c| c[0]))
                .collect::<Vec<_>>(),
        )?;
        col.set_item(
            "ci95_high",
            rows.iter()
                .map(|r| r.ci95.map_or(nan, |c| c[1]))
                .collect::<Vec<_>>(),
        )?;
        col.set_item(
            "identifiability",
            rows.iter().map(identifiability).collect::<Vec<_>>(),
        )?;
        let index_kw = PyDict::new(py);
        index_kw.set_item("name", "parameter")?;
        let index = pd.call_method(
            "Index",
            (rows.iter().map(|r| r.name.clone()).collect::<Vec<_>>(),),
            Some(&index_kw),
        )?;
        let kw = PyDict::new(py);
        kw.set_item("index", index)?;
        pd.call_method("DataFrame", (col,), Some(&kw))
    }
    /// An HTML summary for notebooks: the fit (RMS before and after, frames, convergence),
    /// the parameter table in mm and degrees with 95 % intervals, and the warnings.
    fn _repr_html_(&self) -> String {
        let c = &self.cal;
        let mut h = String::from("<div class=\"jointfit-calibration\">");
        h.push_str(&format!(
            "<p><b>Calibration</b> ({method}): {n} parameters, {frames} frames{skipped}; \
             marker RMS {b:.2} mm → {a:.2} mm; {conv} after {it} iterations</p>",
            method = html(
                &serde_json::to_string(&c.method)
                    .unwrap_or_default()
                    .replace('"', "")
            ),
            n = c.parameters.len(),
            frames = c.frames,
            skipped = if c.skipped_frames > 0 {
                format!(" ({} skipped)", c.skipped_frames)
            } else {
                String::new()
            },
            b = c.rms_before * 1e3,
            a = c.rms_after * 1e3,
            conv = if c.converged {
                "converged"
            } else {
                "<b>not converged</b>"
            },
            it = c.iterations,
        ));
        // The verdict first after the summary line, as in the command line's report.
        h.push_str(&format!(
            "<p><b>verdict: {}</b></p>",
            html(&c.verdict.level.to_string())
        ));
        if !c.verdict.reasons.is_empty() {
            h.push_str("<ul>");
            for r in &c.verdict.reasons {
                h.push_str(&format!("<li>{}</li>", html(r)));
            }
            h.push_str("</ul>");
        }
        h.push_str(
            "<table><thead><tr><th>parameter</th><th>group</th><th>unit</th><th>start</th>\
             <th>fitted</th><th>95 % interval</th><th>identifiability</th></tr></thead><tbody>",
        );
        for r in &c.parameters {
            let si = if r.unit == "m" {
                Unit::Metre
            } else {
                Unit::Radian
            };
            let show = |v: f64| jointfit_app::present::shown(v, si).0;
            let unit = jointfit_app::present::shown(0.0, si).1;
            let ci = r.ci95.map_or("—".to_string(), |[lo, hi]| {
                format!("{:.2} to {:.2}", show(lo), show(hi))
            });
            h.push_str(&format!(
                "<tr><td>{}</td><td>{}</td><td>{unit}</td><td>{:.2}</td><td>{:.2}</td>\
                 <td>{ci}</td><td>{}</td></tr>",
                html(&r.name),
                html(&r.group),
                show(r.start),
                show(r.fitted),
                html(&identifiability(r)),
            ));
        }
        h.push_str("</tbody></table>");
        if !c.warnings.is_empty() {
            h.push_str(&format!(
                "<details><summary>{} warning{}</summary><ul>",
                c.warnings.len(),
                if c.warnings.len() == 1 { "" } else { "s" }
            ));
            for w in &c.warnings {
                h.push_str(&format!("<li>{}</li>", html(w)));
            }
            h.push_str("</ul></details>");
        }
        h.push_str("</div>");
        h
    }
}

/// A parameter's identifiability as a word ("identified", "poorly", ...; "" when unknown).
fn identifiability(r: &jointfit_app::ParamRow) -> String {
    r.identifiability
        .map(|i| {
            serde_json::to_string(&i)
                .unwrap_or_default()
                .replace('"', "")
        })
        .unwrap_or_default()
}

/// `text` escaped for HTML.
fn html(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The verdict on a fit (`Calibration.verdict`): `level` is "ok", "caution" or "reject";
/// `reasons` the sentences behind it, the gravest first.
#[pyclass(name = "Verdict", module = "jointfit", frozen)]
#[derive(Clone)]
pub struct PyVerdict {
    #[pyo3(get)]
    level: String,
    #[pyo3(get)]
    reasons: Vec<String>,
}

#[pymethods]
impl PyVerdict {
    fn __repr__(&self) -> String {
        format!("Verdict({:?}, {} reasons)", self.level, self.reasons.len())
    }
    fn __str__(&self) -> String {
        let mut s = format!("verdict: {}", self.level);
        for r in &self.reasons {
            s.push_str(&format!("\n  - {r}"));
        }
        s
    }
}

/// Rebuilds a Calibration from `Calibration.to_json()` (used by pickling).
#[pyfunction]
#[pyo3(name = "_calibration_from_json")]
pub fn calibration_from_json(text: &str) -> PyResult<PyCalibration> {
    let cal = serde_json::from_str(text).map_err(|e| msg(format!("not a calibration: {e}")))?;
    Ok(PyCalibration { cal, osim: None })
}

fn joints_arg(joints: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<String>> {
    let Some(j) = joints else {
        return Ok(vec!["all".into()]);
    };
    if let Ok(s) = j.extract::<String>() {
        return Ok(s.split(',').map(|g| g.trim().to_string()).collect());
    }
    j.extract::<Vec<String>>()
        .map_err(|_| msg("joints must be a list of group names (hip, knee, ankle, all) or one comma-separated string"))
}

/// Fits joint parameters to one or more trials (two-level optimization, Reinbolt et al.
/// 2005): the parameters of the `joints` groups ("hip", "knee", "ankle", "all"; None: all)
/// minimize the summed squared marker distances over every frame, each frame's coordinates
/// at their own optimum. Starts from the model's parameters. `model` is a Model, a model
/// file path (TOML or .osim) or a built-in name; of an OpenSim model, `joints` names the
/// joints whose offset frames to personalize and `params` finer selections. `trials` are
/// Trial objects or paths (read with `up` and `filter`, as on the command line); `method` is
/// "joint" (sparse Levenberg–Marquardt), "gradient" (two-level Gauss–Newton) or "pso"
/// (particle swarm, then joint polish, seeded by `seed`). The other options are those of
/// `jointfit calibrate`: `starts`, `fix_unidentifiable`, `prior` ("model" or "none"),
/// `marker_noise_mm`, `max_iter`, `bootstrap`, `threshold_mm`, `threshold_deg`. The fitted
/// parameters equal `jointfit calibrate`'s for the same inputs and options, bit for bit (an
/// unconverged fit is kept with a warning, as `--accept-unconverged`). A fit whose verdict is
/// `reject` (inputs that do not belong together, an implausible result) raises
/// `JointfitError` with the cause unless `accept_rejected` is true; `Calibration.verdict`
/// says how far to trust the rest. Releases the GIL while it runs.
#[pyfunction]
#[pyo3(signature = (model, trials, joints=None, method="joint", up=None, filter=None, seed=1, bootstrap=0, threshold_mm=5.0, threshold_deg=5.0, starts=1, fix_unidentifiable=false, prior="model", marker_noise_mm=None, max_iter=None, params=None, progress=None, accept_rejected=false))]
#[allow(clippy::too_many_arguments)]
pub fn calibrate(
    py: Python<'_>,
    model: &Bound<'_, PyAny>,
    trials: &Bound<'_, PyAny>,
    joints: Option<&Bound<'_, PyAny>>,
    method: &str,
    up: Option<&str>,
    filter: Option<f64>,
    seed: u64,
    bootstrap: usize,
    threshold_mm: f64,
    threshold_deg: f64,
    starts: usize,
    fix_unidentifiable: bool,
    prior: &str,
    marker_noise_mm: Option<f64>,
    max_iter: Option<usize>,
    params: Option<Vec<String>>,
    progress: Option<&Bound<'_, PyAny>>,
    accept_rejected: bool,
) -> PyResult<PyCalibration> {
    let progress = crate::run::progress_arg(py, progress)?;
    let model = model_arg(model)?;
    let osim = match &model {
        ModelSource::Osim(o) => Some(o.clone()),
        _ => None,
    };
    if osim.is_none() && params.is_some() {
        return Err(msg(
            "params selects offset frames of a model loaded from an .osim file",
        ));
    }
    let fit = FitOptions {
        joints: joints_arg(joints)?,
        method: method.parse().map_err(msg)?,
        seed,
        threshold_mm,
        threshold_deg,
        bootstrap,
        starts,
        fix_unidentifiable,
        priors: prior_arg(prior)?,
        marker_noise_mm,
        max_iterations: max_iter,
        accept_rejected,
        params: params.unwrap_or_default(),
        ..FitOptions::default()
    };
    fit.check().map_err(msg)?;
    let request = Request {
        model,
        trials: trials_arg(trials)?,
        read: ReadOptions {
            up: parse_up(up)?,
            filter_hz: filter,
        },
        fit,
    };
    let cal = crate::run::interruptible(py, progress.as_ref(), move |obs| {
        run_observed(&request, obs)
    });
    crate::run::close_progress(py, progress.as_ref())?;
    let cal = cal?.map_err(|e| calibrate_error(&e))?;
    warn_all(py, &cal.warnings)?;
    Ok(PyCalibration { cal, osim })
}

/// The error of a calibration, with the keyword argument that resolves it when one does.
fn calibrate_error(e: &jointfit_app::Error) -> PyErr {
    use jointfit_app::present::{hint, Front};
    match e {
        jointfit_app::Error::Calibrate(w) => match hint(w, Front::Python) {
            Some(h) => msg(format!("{} ({h})", jointfit_app::message(e))),
            None => err(e),
        },
        e => err(e),
    }
}

/// `model` of `calibrate`: a Model (with the `.osim` it was loaded from, if any), a model
/// file path (an `.osim` is read here, to write the fitted offsets back) or a built-in name.
fn model_arg(model: &Bound<'_, PyAny>) -> PyResult<ModelSource> {
    if let Ok(m) = model.cast::<PyModel>() {
        let m = m.get();
        return Ok(match &m.osim {
            Some(osim) => ModelSource::Osim(osim.clone()),
            None => ModelSource::Spec(Box::new(m.model.spec().clone())),
        });
    }
    let name: std::path::PathBuf = model.extract().map_err(|_| {
        msg("a model must be a jointfit.Model, a model file path or a built-in name")
    })?;
    ModelSource::read(&name.to_string_lossy()).map_err(|e| err(&e))
}

/// `prior` of `calibrate`: "model" (the model's priors) or "none".
fn prior_arg(prior: &str) -> PyResult<bool> {
    match prior {
        "model" => Ok(true),
        "none" => Ok(false),
        other => Err(msg(format!(
            "prior must be \"model\" or \"none\", not {other:?}"
        ))),
    }
}

/// `trials` of `calibrate`: one Trial or path, or a list of them.
fn trials_arg(trials: &Bound<'_, PyAny>) -> PyResult<Vec<TrialSource>> {
    let items: Vec<Bound<'_, PyAny>> =
        if trials.cast::<PyTrial>().is_ok() || trials.extract::<std::path::PathBuf>().is_ok() {
            vec![trials.clone()]
        } else {
            trials
                .cast::<PyList>()
                .map(|l| l.iter().collect())
                .or_else(|_| {
                    trials
                        .try_iter()
                        .and_then(|it| it.collect::<PyResult<Vec<_>>>())
                })
                .map_err(|_| msg("trials must be a list of jointfit.Trial objects or paths"))?
        };
    items
        .iter()
        .map(|t| {
            if let Ok(tr) = t.cast::<PyTrial>() {
                let tr = tr.get();
                return Ok(TrialSource::Data {
                    name: tr.name.clone(),
                    trial: Box::new(tr.trial.clone()),
                });
            }
            let path: std::path::PathBuf = t
                .extract()
                .map_err(|_| msg("trials must be jointfit.Trial objects or paths"))?;
            Ok(TrialSource::Path(path))
        })
        .collect()
}
