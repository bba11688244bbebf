//! `personalize`, `ik` and `synthesize`: model from a static trial, inverse kinematics of a
//! trial, a synthetic trial from a model.

use std::path::Path;

use jointfit::ik::IkOptions;
use jointfit::model::{CoordKind, Model};
use jointfit::trial::Trial;
use jointfit_experiments::synth::{coordinates, markers, perturbed_params, Motion, SkinNoise};
use jointfit_landmarks::bilateral::personalize_sides;
use jointfit_landmarks::bilateral::Sides;
use jointfit_landmarks::functional::apply::FunctionalTrials;
use jointfit_landmarks::markerset::MarkerSet;
use jointfit_landmarks::markerset::PRESET_NAMES;
use jointfit_landmarks::{HipCentreMethod, PersonalizeOptions};
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::args::{self, MAX_FRAMES, MAX_NOISE_MM, MAX_RATE_HZ, MAX_WINDOW_S};
use crate::model::PyModel;
use crate::run::{guard, interruptible};
use crate::trial::{up_arg, PyTrial};
use crate::{err, msg, warn_all};

/// A trial argument: a `Trial`, or a path read with `up` (else `model_up`, the subject
/// model's `lab_up`; else y) and `filter`.
pub(crate) fn trial_arg(
    py: Python<'_>,
    trial: &Bound<'_, PyAny>,
    up: Option<jointfit::spatial::UpAxis>,
    filter: Option<f64>,
    model_up: Option<jointfit::spatial::UpAxis>,
) -> PyResult<PyTrial> {
    if let Ok(t) = trial.cast::<PyTrial>() {
        let t = t.get().clone();
        return match filter {
            Some(hz) => {
                let (trial, warnings) = py
                    .detach(|| jointfit_app::prepare_trial(t.trial, &t.name, None, Some(hz)))
                    .map_err(|e| err(&e))?;
                warn_all(py, &warnings)?;
                Ok(PyTrial {
                    trial,
                    name: t.name,
                })
            }
            None => Ok(t),
        };
    }
    let path = trial_path(trial)?;
    let read = jointfit_app::ReadOptions {
        up: up.or(model_up),
        filter_hz: filter,
    };
    let (t, warnings) = py
        .detach(|| jointfit_app::read_trial(&path, &read))
        .map_err(|e| err(&e))?;
    let name = path.display().to_string();
    crate::trial::check_data(&t, &name)?;
    warn_all(py, &warnings)?;
    Ok(PyTrial { trial: t, name })
}

/// An optional argument that is given (not None).
fn given<'py>(v: Option<&Bound<'py, PyAny>>) -> Option<Bound<'py, PyAny>> {
    v.filter(|v| !v.is_none()).cloned()
}

/// A trial given as a path (str or os.PathLike).
pub(crate) fn trial_path(trial: &Bound<'_, PyAny>) -> PyResult<std::path::PathBuf> {
    if trial.is_instance_of::<pyo3::types::PyBool>() || trial.is_none() {
        return Err(not_a_trial(trial));
    }
    match trial.extract::<std::path::PathBuf>() {
        Ok(p) if !p.as_os_str().is_empty() => Ok(p),
        _ => Err(not_a_trial(trial)),
    }
}

fn not_a_trial(trial: &Bound<'_, PyAny>) -> PyErr {
    msg(format!(
        "a trial must be a jointfit.Trial or a path, not {} {}",
        args::type_name(trial),
        args::shown(trial)
    ))
}

/// A model argument: a `Model`, or a TOML path / built-in name.
pub(crate) fn model_arg(
    py: Python<'_>,
    model: &Bound<'_, PyAny>,
) -> PyResult<jointfit::model::Model> {
    if let Ok(m) = model.cast::<PyModel>() {
        return Ok(m.get().model.clone());
    }
    let name = model_name(model)?;
    py.detach(|| jointfit_io::model_file::load_model(&name))
        .map_err(|e| err(&e))
}

/// A model given by file path or built-in name.
pub(crate) fn model_name(model: &Bound<'_, PyAny>) -> PyResult<String> {
    let refuse = || {
        msg(format!(
            "a model must be a jointfit.Model, a model file path or a built-in name ({}), not {} {}",
            jointfit::model::lower_limb::BUILTIN_NAMES.join(", "),
            args::type_name(model),
            args::shown(model)
        ))
    };
    if model.is_instance_of::<pyo3::types::PyBool>() {
        return Err(refuse());
    }
    match model.extract::<std::path::PathBuf>() {
        Ok(p) if !p.as_os_str().is_empty() => Ok(p.to_string_lossy().into_owned()),
        _ => Err(refuse()),
    }
}

fn marker_set(arg: &str) -> PyResult<MarkerSet> {
    let path = Path::new(arg);
    if path.exists() {
        let text = std::fs::read_to_string(path)
            .map_err(|e| msg(format!("{}: cannot read: {e}", path.display())))?;
        return MarkerSet::from_toml(&text, &path.display().to_string()).map_err(|e| err(&e));
    }
    if PRESET_NAMES.contains(&arg) {
        return MarkerSet::preset(arg).map_err(|e| err(&e));
    }
    Err(msg(format!(
        "{arg:?} is neither a marker-set file nor a preset ({})",
        PRESET_NAMES.join(", ")
    )))
}

/// Builds a subject's leg model from a static standing trial (anatomical-landmark method:
/// segment frames from landmarks, hip centre by regression, knee and ankle axes from the
/// epicondyles and malleoli, tracking markers from the averaged static pose).
///
/// `static` is a Trial or a path (read with `up`); `markers` a marker-set preset
/// (see `jointfit.MARKER_SET_PRESETS`) or a marker-set TOML file; `side` "both" (the default,
/// as on the command line: both legs and the pelvis in one 54-parameter model; a trial with
/// only one leg's markers gives that leg's model and a `JointfitWarning`), "right" or "left";
/// `hip` "bell" (Bell et al. 1990) or "harrington" (Harrington et al. 2007);
/// `window` the averaged window (s, greater than 0 and at most 3600).
#[pyfunction]
#[pyo3(signature = (r#static, markers, side=None, up=None, hip=None, window=None, name=None))]
#[allow(clippy::too_many_arguments)]
pub fn personalize(
    py: Python<'_>,
    r#static: &Bound<'_, PyAny>,
    markers: &Bound<'_, PyAny>,
    side: Option<&Bound<'_, PyAny>>,
    up: Option<&Bound<'_, PyAny>>,
    hip: Option<&Bound<'_, PyAny>>,
    window: Option<&Bound<'_, PyAny>>,
    name: Option<&Bound<'_, PyAny>>,
) -> PyResult<PyModel> {
    guard(|| {
        let markers = args::text(
            markers,
            "markers",
            &format!(
                "a marker-set preset ({}) or a marker-set TOML file",
                PRESET_NAMES.join(", ")
            ),
        )?;
        let set = marker_set(&markers)?;
        let side = match side.filter(|v| !v.is_none()) {
            Some(v) => args::choice(v, "side", &["both", "right", "left"])?,
            None => "both".into(),
        };
        let hip = match hip.filter(|v| !v.is_none()) {
            Some(v) => args::choice(v, "hip", &["bell", "harrington"])?,
            None => "bell".into(),
        };
        let window = match window.filter(|v| !v.is_none()) {
            Some(v) => args::positive(v, "window", MAX_WINDOW_S, " s")?,
            None => 1.0,
        };
        let name = args::opt_text(name, "name", "a str")?;
        let up = up_arg(up)?;
        // The vertical: `up`, else detected from a static file's marker layout.
        let lab_up = match up {
            Some(u) => Some(u),
            None if r#static.cast::<PyTrial>().is_err() => {
                let path = trial_path(r#static)?;
                py.detach(|| jointfit_io::trial_file::read_trial(&path))
                    .ok()
                    .and_then(|raw| jointfit::vertical::detect_up(&raw))
                    .map(|d| d.up)
            }
            None => None,
        };
        let trial = trial_arg(py, r#static, up, None, lab_up)?;
        let sides: Sides = side.parse().map_err(|e| err(&e))?;
        let hip_centre = match hip.as_str() {
            "bell" => HipCentreMethod::Bell,
            _ => HipCentreMethod::Harrington,
        };
        let default_name = Path::new(&trial.name)
            .file_stem()
            .map_or("subject".into(), |s| s.to_string_lossy().into_owned());
        let opts = PersonalizeOptions {
            hip_centre,
            window_seconds: window,
            name: name.unwrap_or(default_name),
            ..PersonalizeOptions::default()
        };
        let result = py.detach(|| {
            personalize_sides(
                &trial.trial,
                &set,
                sides,
                &opts,
                &FunctionalTrials::default(),
            )
        });
        let result = result.map_err(|e| {
            msg(format!(
                "{} (read with --up={}): cannot personalize: {}",
                trial.name,
                lab_up.map_or("y".to_string(), |u| u.to_string()),
                jointfit_app::message(&e)
            ))
        })?;
        if let Some(w) = &result.warning {
            warn_all(py, &[format!("{}: {w}", trial.name)])?;
        }
        let mut model = result.model;
        let spec = model.spec_mut();
        spec.description = format!("{}; from {}", spec.description, trial.name);
        spec.lab_up = lab_up;
        PyModel::from_spec(spec)
    })
}

/// Inverse kinematics of one trial (`ik`): per-frame coordinates and marker errors.
///
/// Labelled views: `to_dataframe()` (pandas, index time in s, a column per coordinate),
/// `units` (coordinate → "rad" or "m"), `write_mot(path)` (OpenSim's .mot, rotations in
/// degrees, the trial's own time), `to_xarray()` (when xarray is installed).
#[pyclass(name = "IkResult", module = "jointfit", frozen)]
pub struct PyIkResult {
    model: Model,
    trial: Trial,
    trial_name: String,
    coords: Array2<f64>,
    errors: Array2<f64>,
    solved: Vec<bool>,
}

impl PyIkResult {
    fn coordinate_names(&self) -> Vec<String> {
        self.model
            .coordinates()
            .iter()
            .map(|c| c.name.clone())
            .collect()
    }
    fn times(&self) -> Vec<f64> {
        (0..self.solved.len()).map(|f| self.trial.time(f)).collect()
    }
    fn unit_list(&self) -> Vec<&'static str> {
        self.model
            .coordinates()
            .iter()
            .map(|c| match c.kind {
                CoordKind::Rotational => "rad",
                CoordKind::Translational => "m",
            })
            .collect()
    }
}

#[pymethods]
impl PyIkResult {
    /// Coordinates per frame: float64 (frames, n) in rad (rotations) and m (translations),
    /// see `units`; NaN rows for frames that could not be solved.
    #[getter]
    fn coordinates<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.coords.clone().into_pyarray(py)
    }
    /// Names of the columns of `coordinates`.
    #[getter(coordinate_names)]
    fn py_coordinate_names(&self) -> Vec<String> {
        self.coordinate_names()
    }
    /// Unit of every coordinate: dict name → "rad" (rotations) or "m" (translations), in
    /// column order.
    #[getter]
    fn units<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (n, u) in self.coordinate_names().iter().zip(self.unit_list()) {
            d.set_item(n, u)?;
        }
        Ok(d)
    }
    /// Names of the columns of `errors` (the model's markers).
    #[getter]
    fn marker_names(&self) -> Vec<String> {
        self.model
            .markers()
            .iter()
            .map(|m| m.name.clone())
            .collect()
    }
    /// Distance between measured and model marker per frame and model marker: float64
    /// (frames, markers), m, NaN where the marker is missing.
    #[getter]
    fn errors<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.errors.clone().into_pyarray(py)
    }
    /// RMS marker distance per frame over its present markers (m; NaN when not solved).
    #[getter]
    fn rms<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let v: Array1<f64> = self
            .errors
            .rows()
            .into_iter()
            .map(|r| jointfit::ik::trial_fit::rms(r.iter().copied()))
            .collect();
        v.into_pyarray(py)
    }
    /// Whether each frame was solved (false: a segment had too few markers).
    #[getter]
    fn solved<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        Array1::from(self.solved.clone()).into_pyarray(py)
    }
    /// Time of every frame (s): the trial's own times (a TRC's time column, or frame / rate).
    #[getter(times)]
    fn py_times<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        Array1::from(self.times()).into_pyarray(py)
    }
    /// The coordinates as a pandas DataFrame: index `time` (s), one column per coordinate in
    /// rad and m (`degrees=True`: rotations in degrees, as in a .mot file). The units are in
    /// `df.attrs["units"]`. Needs pandas.
    #[pyo3(signature = (degrees=None))]
    fn to_dataframe<'py>(
        &self,
        py: Python<'py>,
        degrees: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let degrees = match degrees.filter(|d| !d.is_none()) {
            Some(d) => args::flag(d, "degrees")?,
            None => false,
        };
        let pd = py
            .import("pandas")
            .map_err(|_| msg("to_dataframe needs pandas (pip install pandas)"))?;
        let units = self.unit_list();
        let mut values = self.coords.clone();
        if degrees {
            for (k, u) in units.iter().enumerate() {
                if *u == "rad" {
                    values.column_mut(k).mapv_inplace(f64::to_degrees);
                }
            }
        }
        let index_kw = PyDict::new(py);
        index_kw.set_item("name", "time")?;
        let index = pd.call_method("Index", (self.times(),), Some(&index_kw))?;
        let kw = PyDict::new(py);
        kw.set_item("index", index)?;
        kw.set_item("columns", self.coordinate_names())?;
        let df = pd.call_method("DataFrame", (values.into_pyarray(py),), Some(&kw))?;
        let unit_dict = PyDict::new(py);
        for (n, u) in self.coordinate_names().iter().zip(&units) {
            unit_dict.set_item(n, if degrees && *u == "rad" { "deg" } else { u })?;
        }
        df.getattr("attrs")?.set_item("units", unit_dict)?;
        Ok(df)
    }
    /// The coordinates as an xarray DataArray (dims `time`, `coordinate`; rad and m, the
    /// units in `attrs["units"]`). Needs xarray.
    fn to_xarray<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let xr = py
            .import("xarray")
            .map_err(|_| msg("to_xarray needs xarray (pip install xarray)"))?;
        let coords = PyDict::new(py);
        coords.set_item("time", self.times())?;
        coords.set_item("coordinate", self.coordinate_names())?;
        let kw = PyDict::new(py);
        kw.set_item("dims", ("time", "coordinate"))?;
        kw.set_item("coords", coords)?;
        kw.set_item("name", "coordinates")?;
        let attrs = PyDict::new(py);
        attrs.set_item("units", self.units(py)?)?;
        attrs.set_item("trial", &self.trial_name)?;
        kw.set_item("attrs", attrs)?;
        xr.call_method(
            "DataArray",
            (self.coords.clone().into_pyarray(py),),
            Some(&kw),
        )
    }
    /// Writes the coordinates as OpenSim's inverse kinematics does (.mot: a time column in s,
    /// the trial's own times; rotations in degrees, translations in m; `inDegrees=yes`;
    /// frames that could not be solved as NaN rows). OpenSim's `Storage` reads it. Written
    /// atomically.
    fn write_mot(&self, py: Python<'_>, path: &Bound<'_, PyAny>) -> PyResult<()> {
        guard(|| {
            let path = args::path(path, "path")?;
            let rows: Vec<Vec<f64>> = self.coords.rows().into_iter().map(|r| r.to_vec()).collect();
            let table = jointfit_io::sto::coordinates_table(&self.model, &self.trial, &rows);
            py.detach(|| jointfit_io::sto::write_sto(&path, &table))
                .map_err(|e| err(&e))
        })
    }
    fn __len__(&self) -> usize {
        self.solved.len()
    }
    fn __repr__(&self) -> String {
        let n = self.solved.iter().filter(|s| **s).count();
        format!("IkResult({} frames, {n} solved)", self.solved.len())
    }
}

/// Inverse kinematics (the inner level) of `trial` with `model` at its parameters: each
/// frame's coordinates minimize the squared marker distances, warm-started from the frames
/// before. `trial` is a Trial or a path (read with `up`, filtered at `filter` Hz, at least
/// 0.1). Model markers the trial lacks count as missing in every frame (a JointfitWarning).
/// Ctrl-C interrupts it (KeyboardInterrupt).
#[pyfunction]
#[pyo3(signature = (model, trial, up=None, filter=None))]
pub fn ik(
    py: Python<'_>,
    model: &Bound<'_, PyAny>,
    trial: &Bound<'_, PyAny>,
    up: Option<&Bound<'_, PyAny>>,
    filter: Option<&Bound<'_, PyAny>>,
) -> PyResult<PyIkResult> {
    guard(|| {
        let up = up_arg(up)?;
        let filter = args::cutoff(filter, "filter")?;
        let model = model_arg(py, model)?;
        let trial = trial_arg(py, trial, up, filter, model.spec().lab_up)?;
        let (held_model, held) = jointfit::ik::hold::hold_undetermined(&model, &[&trial.trial])
            .map_err(|e| msg(format!("{}: {e}", trial.name)))?;
        let mut warnings = Vec::new();
        if !held.is_empty() {
            warnings.push(format!(
                "{}: no marker determines {}; held at the model's default values",
                trial.name,
                held.join(", ")
            ));
        }
        let model = held_model.unwrap_or(model);
        let p = model.nominal_params();
        let (m2, t2) = (model.clone(), trial.trial.clone());
        let run = interruptible(py, None, move |_| {
            jointfit::workflow::ik::ik_trial(&m2, &p, &t2, &IkOptions::default())
        })?
        .map_err(|e| msg(format!("{}: {}", trial.name, jointfit_app::message(&e))))?;
        if !run.absent.is_empty() {
            warnings.push(format!(
                "{}: lacks model markers {}; they count as missing in every frame",
                trial.name,
                run.absent.join(", ")
            ));
        }
        warn_all(py, &warnings)?;
        let fit = run.fit;
        let (nf, nq, nm) = (
            fit.frames.len(),
            model.coordinates().len(),
            model.markers().len(),
        );
        Ok(PyIkResult {
            coords: Array2::from_shape_fn((nf, nq), |(f, k)| fit.coords[f][k]),
            errors: Array2::from_shape_fn((nf, nm), |(f, j)| fit.errors[f][j]),
            solved: fit.frames.iter().map(|f| f.solved()).collect(),
            model,
            trial: trial.trial,
            trial_name: trial.name,
        })
    })
}

/// A synthetic trial (as `jointfit demo` makes): `model`'s markers along a motion ("hip",
/// "knee", "ankle" or "all") of `frames` frames (1 to 100000) at `rate` Hz (greater than 0,
/// at most 100000), with the parameters moved from nominal by up to `perturb` (0 to 1) of
/// each half-range (seeded), plus sinusoidal skin-artifact noise of up to `noise_mm` (0 to
/// 1000; seeded; 0: none). `seed` is a whole number from 0 to 2⁶⁴ − 1. `model`: a Model,
/// path or built-in name (None: "lower-limb-right"). Returns `(trial, true_model)`.
#[pyfunction]
#[pyo3(signature = (model=None, motion=None, frames=None, rate=None, noise_mm=None, perturb=None, seed=None))]
#[allow(clippy::too_many_arguments)]
pub fn synthesize(
    py: Python<'_>,
    model: Option<&Bound<'_, PyAny>>,
    motion: Option<&Bound<'_, PyAny>>,
    frames: Option<&Bound<'_, PyAny>>,
    rate: Option<&Bound<'_, PyAny>>,
    noise_mm: Option<&Bound<'_, PyAny>>,
    perturb: Option<&Bound<'_, PyAny>>,
    seed: Option<&Bound<'_, PyAny>>,
) -> PyResult<(PyTrial, PyModel)> {
    guard(|| {
        let motion = match given(motion) {
            Some(m) => args::choice(&m, "motion", &["hip", "knee", "ankle", "all"])?,
            None => "all".into(),
        };
        let frames = match given(frames) {
            Some(f) => args::whole(&f, "frames", 1, MAX_FRAMES)? as usize,
            None => 100,
        };
        let rate = match given(rate) {
            Some(r) => args::positive(&r, "rate", MAX_RATE_HZ, " Hz")?,
            None => 50.0,
        };
        let noise_mm = match given(noise_mm) {
            Some(n) => args::within(&n, "noise_mm", 0.0, MAX_NOISE_MM, " mm")?,
            None => 10.0,
        };
        let perturb = match given(perturb) {
            Some(p) => args::within(&p, "perturb", 0.0, 1.0, "")?,
            None => 0.4,
        };
        let seed = match given(seed) {
            Some(s) => args::whole(&s, "seed", 0, u64::MAX)?,
            None => 1,
        };
        let model = match given(model) {
            Some(m) => model_arg(py, &m)?,
            None => jointfit_io::model_file::load_model("lower-limb-right").map_err(|e| err(&e))?,
        };
        if model.markers().is_empty() {
            return Err(msg(format!(
                "model {:?} has no markers: a synthetic trial needs some",
                model.spec().name
            )));
        }
        let motion: Motion = motion.parse().map_err(|e| err(&e))?;
        let truth = perturbed_params(&model, perturb, seed);
        let coords = coordinates(&model, motion, frames).map_err(|e| err(&e))?;
        let noise = SkinNoise {
            max_amplitude: noise_mm / 1e3,
            seed,
            ..SkinNoise::default()
        };
        let (trial, _) = markers(
            &model,
            &truth,
            &coords,
            rate,
            (noise_mm > 0.0).then_some(&noise),
        );
        let true_model = PyModel::from_spec(&model.spec_with_nominal(&truth))?;
        Ok((
            PyTrial {
                trial,
                name: format!("<synthetic {motion:?} seed {seed}>").to_lowercase(),
            },
            true_model,
        ))
    })
}
