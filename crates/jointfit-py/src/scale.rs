//! `jointfit.scale`: a generic OpenSim model scaled to the subject with its markers
//! registered (the `jointfit scale` pipeline, `docs/scaling.md`).

use std::path::PathBuf;

use jointfit_app::scale::{scale_subject, ScaleRequest};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::msg;

/// Scales the generic OpenSim model `model` (a path) to the subject of the static trial
/// `static` (a path), optional motion trials `trials`, an OpenSim MarkerSet file
/// `markerset`, total mass `mass` (kg) and stature `height` (m, for the anthropometric
/// prior; `prior="none"` fits without it). Writes `output` (an .osim) when given, with the
/// scaling record beside it (`SUBJECT.scale.json`, shown by the model's reports).
///
/// Returns a dict: `osim` (the subject model's text), `scale_factors` ({body: [sx, sy, sz]}),
/// `groups` (name, bodies, factors, sd), `markers` (name, body, position and `moved` in m),
/// `rms` (m), `flags` (implausible factors, in words), `total_mass`, `seconds`.
#[pyfunction]
#[pyo3(signature = (model, r#static, trials=Vec::new(), markerset=None, mass=None, height=None, output=None, prior="anthropometric", per_axis=false, symmetric=false, time_range=None))]
#[allow(clippy::too_many_arguments)]
pub fn scale<'py>(
    py: Python<'py>,
    model: PathBuf,
    r#static: PathBuf,
    trials: Vec<PathBuf>,
    markerset: Option<PathBuf>,
    mass: Option<f64>,
    height: Option<f64>,
    output: Option<PathBuf>,
    prior: &str,
    per_axis: bool,
    symmetric: bool,
    time_range: Option<(f64, f64)>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut req = ScaleRequest::new(model, r#static);
    req.trials = trials;
    req.marker_set = markerset;
    req.mass = mass;
    req.height = height;
    req.per_axis = per_axis;
    req.symmetric = symmetric;
    req.time_range = time_range.map(|(a, b)| [a, b]);
    req.prior = match prior {
        "anthropometric" => true,
        "none" => false,
        other => {
            return Err(msg(format!(
                "prior must be \"anthropometric\" or \"none\", not {other:?}"
            )))
        }
    };
    let out = py.detach(|| scale_subject(&req)).map_err(msg)?;
    if let Some(path) = &output {
        jointfit_io::atomic::write_atomic(path, out.text.as_bytes())
            .map_err(|e| msg(format!("{}: cannot write: {e}", path.display())))?;
        let record = jointfit_app::scale::record(&req, &out);
        jointfit_io::osim_scale::record::write_record(path, &record).map_err(msg)?;
    }
    let d = PyDict::new(py);
    d.set_item("osim", &out.text)?;
    let factors = PyDict::new(py);
    for (k, v) in &out.fit.factors {
        factors.set_item(k, v.to_vec())?;
    }
    d.set_item("scale_factors", factors)?;
    let groups = out
        .fit
        .groups
        .iter()
        .map(|g| {
            let e = PyDict::new(py);
            e.set_item("name", &g.name)?;
            e.set_item("bodies", g.bodies.clone())?;
            e.set_item("factors", g.factors.to_vec())?;
            e.set_item("sd", g.sd.to_vec())?;
            Ok(e)
        })
        .collect::<PyResult<Vec<_>>>()?;
    d.set_item("groups", groups)?;
    let markers = out
        .fit
        .markers
        .iter()
        .map(|m| {
            let e = PyDict::new(py);
            e.set_item("name", &m.name)?;
            e.set_item("body", &m.body)?;
            e.set_item("position", m.position.to_vec())?;
            e.set_item("moved", m.moved.to_vec())?;
            Ok(e)
        })
        .collect::<PyResult<Vec<_>>>()?;
    d.set_item("markers", markers)?;
    d.set_item("rms", out.fit.rms)?;
    d.set_item("flags", out.flags.clone())?;
    d.set_item("total_mass", out.total_mass)?;
    d.set_item("seconds", out.seconds)?;
    Ok(d)
}
