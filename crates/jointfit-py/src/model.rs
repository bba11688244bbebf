//! `jointfit.Model`: a compiled kinematic model with its nominal parameters.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use jointfit::model::spec::ModelSpec;
use jointfit::model::Model;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::args;
use crate::run::guard;
use crate::{err, msg};

/// A kinematic leg model: segments, joints, markers and its joint parameters (SI units).
///
/// `Model.load(path_or_builtin)` reads a model TOML file, an OpenSim 4 model (.osim) or a
/// built-in model ("lower-limb-right", "lower-limb-left"); `save(path)` writes TOML (.toml)
/// or an OpenSim 4 model (.osim: for a model read from an .osim, that file with only its
/// personalized offset values replaced; otherwise a new kinematic model).
#[pyclass(name = "Model", module = "jointfit", frozen)]
pub struct PyModel {
    pub(crate) model: Model,
    /// The `.osim` file this model came from (write-back target of `save`).
    pub(crate) osim: Option<Arc<jointfit_io::osim_read::OsimModel>>,
}

impl PyModel {
    pub(crate) fn from_spec(spec: &ModelSpec) -> PyResult<Self> {
        let model = Model::compile(spec).map_err(|source| {
            err(&jointfit_io::model_file::ModelFileError::Invalid {
                path: PathBuf::from(&spec.name),
                source,
            })
        })?;
        Ok(PyModel { model, osim: None })
    }

    /// `spec` compiled, keeping the `.osim` it came from.
    pub(crate) fn with_osim(
        spec: &ModelSpec,
        osim: Option<Arc<jointfit_io::osim_read::OsimModel>>,
    ) -> PyResult<Self> {
        let mut m = PyModel::from_spec(spec)?;
        m.osim = osim;
        Ok(m)
    }
}

impl PyModel {
    fn load_path(py: Python<'_>, path_or_builtin: &std::path::Path) -> PyResult<Self> {
        let text = path_or_builtin.to_string_lossy().into_owned();
        if jointfit_io::model_file::is_osim(path_or_builtin) {
            let osim = py
                .detach(|| jointfit_io::osim_read::read_osim(path_or_builtin))
                .map_err(|e| err(&e))?;
            return PyModel::with_osim(&osim.spec.clone(), Some(Arc::new(osim)));
        }
        let model = jointfit_io::model_file::load_model(&text).map_err(|e| err(&e))?;
        Ok(PyModel { model, osim: None })
    }

    fn save_path(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("toml") => py
                .detach(|| jointfit_io::model_file::save_spec(&path, self.model.spec()))
                .map_err(|e| msg(format!("writing {}: {e}", path.display()))),
            Some("osim") if self.osim.is_some() => {
                let osim = self.osim.as_deref().expect("checked");
                py.detach(|| {
                    let text = jointfit_io::osim_read::personalize::fitted_text(
                        osim,
                        self.model.spec(),
                        &self.model.nominal_params(),
                    )
                    .map_err(|e| msg(format!("writing {}: {e}", path.display())))?;
                    jointfit_io::atomic::write_atomic(&path, text.as_bytes())
                        .map_err(|e| msg(format!("writing {}: {e}", path.display())))
                })
            }
            Some("osim") => py
                .detach(|| {
                    jointfit_io::osim::write_osim(&path, &self.model, &self.model.nominal_params())
                })
                .map_err(|e| err(&e)),
            _ => Err(msg(format!(
                "{}: unknown model file type (expected .toml or .osim)",
                path.display()
            ))),
        }
    }
}

#[pymethods]
impl PyModel {
    /// Reads a model: a TOML file, an OpenSim 4 model (.osim; personalize its joints with
    /// `jointfit.calibrate(model, trials, joints=["hip_r", ...])`) or a built-in name (see
    /// `jointfit.BUILTIN_MODELS`).
    #[staticmethod]
    fn load(py: Python<'_>, path_or_builtin: &Bound<'_, PyAny>) -> PyResult<Self> {
        guard(|| Self::load_path(py, &args::path(path_or_builtin, "path_or_builtin")?))
    }

    /// Builds a model from the text of a model TOML file.
    #[staticmethod]
    fn from_toml(text: &Bound<'_, PyAny>) -> PyResult<Self> {
        guard(|| {
            let text = args::text(text, "text", "the text of a model TOML file")?;
            let spec = ModelSpec::from_toml(&text).map_err(|e| err(&e))?;
            PyModel::from_spec(&spec)
        })
    }

    /// The model as TOML text (the format of `save("….toml")`).
    fn to_toml(&self) -> String {
        self.model.spec().to_toml()
    }

    /// Writes the model; the format follows the extension: .toml (jointfit) or .osim
    /// (OpenSim 4, at the model's parameters). Written atomically.
    fn save(&self, py: Python<'_>, path: &Bound<'_, PyAny>) -> PyResult<()> {
        guard(|| self.save_path(py, args::path(path, "path")?))
    }

    /// Model name.
    #[getter]
    fn name(&self) -> String {
        self.model.spec().name.clone()
    }

    /// Joint parameters: dict name → value (m or rad), in model order.
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for p in self.model.parameters() {
            d.set_item(&p.name, p.nominal)?;
        }
        Ok(d)
    }

    /// Bounds of every parameter: dict name → (lower, upper) (m or rad).
    #[getter]
    fn bounds<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for p in self.model.parameters() {
            d.set_item(&p.name, (p.lower, p.upper))?;
        }
        Ok(d)
    }

    /// Parameter groups: dict group → list of parameter names ("hip", "knee", "ankle").
    #[getter]
    fn groups(&self) -> BTreeMap<String, Vec<String>> {
        let mut out: BTreeMap<String, Vec<String>> = BTreeMap::new();
        for p in self.model.parameters() {
            out.entry(p.group.clone()).or_default().push(p.name.clone());
        }
        out
    }

    /// Unit of every parameter: dict name → "m" or "rad".
    #[getter]
    fn units(&self) -> BTreeMap<String, &'static str> {
        self.model
            .parameters()
            .iter()
            .map(|p| {
                let u = match p.unit {
                    jointfit::model::spec::Unit::Metre => "m",
                    jointfit::model::spec::Unit::Radian => "rad",
                };
                (p.name.clone(), u)
            })
            .collect()
    }

    /// Generalized coordinates, in model order.
    #[getter]
    fn coordinate_names(&self) -> Vec<String> {
        self.model
            .coordinates()
            .iter()
            .map(|c| c.name.clone())
            .collect()
    }

    /// Marker names, in model order.
    #[getter]
    fn marker_names(&self) -> Vec<String> {
        self.model
            .markers()
            .iter()
            .map(|m| m.name.clone())
            .collect()
    }

    /// A copy with some parameters changed (dict name → value, m or rad).
    fn with_parameters(&self, values: &Bound<'_, PyAny>) -> PyResult<Self> {
        let values: BTreeMap<String, Bound<'_, PyAny>> = values.extract().map_err(|_| {
            msg(format!(
                "values must be a dict of parameter name to value (m or rad), not {}",
                args::type_name(values)
            ))
        })?;
        let mut p = self.model.nominal_params();
        for (name, v) in values {
            let v = args::number(
                &v,
                &format!("values[{name:?}]"),
                "a finite number (m or rad)",
            )?;
            match self.model.param_id(&name) {
                Some(id) => p[id.0] = v,
                None => {
                    return Err(msg(format!(
                        "model {:?} has no parameter {name:?}",
                        self.model.spec().name
                    )))
                }
            }
        }
        PyModel::with_osim(&self.model.spec_with_nominal(&p), self.osim.clone())
    }

    fn __repr__(&self) -> String {
        format!(
            "Model({:?}: {} coordinates, {} parameters, {} markers)",
            self.model.spec().name,
            self.model.coordinates().len(),
            self.model.parameters().len(),
            self.model.markers().len()
        )
    }

    fn __eq__(&self, other: &Self) -> bool {
        self.model.spec() == other.model.spec()
    }

    /// Pickles as its TOML text (exact: floats are written in shortest round-trip form).
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let ctor = py.get_type::<PyModel>().getattr("from_toml")?;
        Ok((ctor, PyTuple::new(py, [self.to_toml()])?))
    }
}
