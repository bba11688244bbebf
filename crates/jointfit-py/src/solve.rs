//! `personalize`, `ik` and `synthesize`: model from a static trial, inverse kinematics of a
//! trial, a synthetic trial from a model.

use std::path::Path;

use jointfit::ik::IkOptions;
use jointfit::landmarks::functional::FunctionalTrials;
use jointfit::landmarks::PRESET_NAMES;
use jointfit::landmarks::{
    personalize_sides, HipCentreMethod, MarkerSet, PersonalizeOptions, Sides,
};
use jointfit_experiments::synth::{coordinates, markers, perturbed_params, Motion, SkinNoise};
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

use crate::model::PyModel;
use crate::trial::{parse_up, PyTrial};
use crate::{err, msg, warn_all};

/// A trial argument: a `Trial`, or a path read with `up` (else `model_up`, the subject
/// model's `lab_up`; else y) and `filter`.
pub(crate) fn trial_arg(
    py: Python<'_>,
    trial: &Bound<'_, PyAny>,
    up: Option<&str>,
    filter: Option<f64>,
    model_up: Option<jointfit::trial::UpAxis>,
) -> PyResult<PyTrial> {
    if let Ok(t) = trial.cast::<PyTrial>() {
        let t = t.get().clone();
        return match filter {
            Some(hz) => {
                let (trial, warnings) = py
                    .detach(|| jointfit_io::batch::prepare_trial(t.trial, &t.name, None, Some(hz)))
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
    let path: std::path::PathBuf = trial.extract().map_err(|_| {
        msg(format!(
            "a trial must be a jointfit.Trial or a path, not {}",
            trial
                .get_type()
                .name()
                .map_or("?".into(), |n| n.to_string())
        ))
    })?;
    let read = jointfit_io::batch::ReadOptions {
        up: parse_up(up)?.or(model_up),
        filter_hz: filter,
    };
    let (t, warnings) = py
        .detach(|| jointfit_io::batch::read_trial(&path, &read))
        .map_err(|e| err(&e))?;
    warn_all(py, &warnings)?;
    Ok(PyTrial {
        trial: t,
        name: path.display().to_string(),
    })
}

/// A model argument: a `Model`, or a TOML path / built-in name.
pub(crate) fn model_arg(model: &Bound<'_, PyAny>) -> PyResult<jointfit::model::Model> {
    if let Ok(m) = model.cast::<PyModel>() {
        return Ok(m.get().model.clone());
    }
    let name: std::path::PathBuf = model.extract().map_err(|_| {
        msg("a model must be a jointfit.Model, a model file path or a built-in name")
    })?;
    jointfit_io::model_file::load_model(&name.to_string_lossy()).map_err(|e| err(&e))
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
/// only one leg's markers gives that leg's model and a `UserWarning`), "right" or "left";
/// `hip` "bell" (Bell et al. 1990) or "harrington" (Harrington et al. 2007);
/// `window` the averaged window (s).
#[pyfunction]
#[pyo3(signature = (r#static, markers, side="both", up=None, hip="bell", window=1.0, name=None))]
#[allow(clippy::too_many_arguments)]
pub fn personalize(
    py: Python<'_>,
    r#static: &Bound<'_, PyAny>,
    markers: &str,
    side: &str,
    up: Option<&str>,
    hip: &str,
    window: f64,
    name: Option<String>,
) -> PyResult<PyModel> {
    let set = marker_set(markers)?;
    // The vertical: `up`, else detected from a static file's marker layout.
    let lab_up = match parse_up(up)? {
        Some(u) => Some(u),
        None => match r#static.extract::<std::path::PathBuf>() {
            Ok(path) => jointfit_io::trial_file::read_trial(&path)
                .ok()
                .and_then(|raw| jointfit::vertical::detect_up(&raw))
                .map(|d| d.up),
            Err(_) => None,
        },
    };
    let trial = trial_arg(py, r#static, up, None, lab_up)?;
    let sides: Sides = side.parse().map_err(|e| err(&e))?;
    let hip_centre = match hip {
        "bell" => HipCentreMethod::Bell,
        "harrington" => HipCentreMethod::Harrington,
        other => {
            return Err(msg(format!(
                "hip must be \"bell\" or \"harrington\", not {other:?}"
            )))
        }
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
            lab_up.map_or("y", |u| u.name()),
            jointfit_io::batch::message(&e)
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
}

/// Inverse kinematics of one trial (`ik`): per-frame coordinates and marker errors.
#[pyclass(name = "IkResult", module = "jointfit", frozen)]
pub struct PyIkResult {
    coordinate_names: Vec<String>,
    marker_names: Vec<String>,
    coords: Array2<f64>,
    errors: Array2<f64>,
    solved: Vec<bool>,
    times: Vec<f64>,
}

#[pymethods]
impl PyIkResult {
    /// Coordinates per frame: float64 (frames, n) in rad (rotations) and m (translations);
    /// NaN rows for frames that could not be solved.
    #[getter]
    fn coordinates<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.coords.clone().into_pyarray(py)
    }
    /// Names of the columns of `coordinates`.
    #[getter]
    fn coordinate_names(&self) -> Vec<String> {
        self.coordinate_names.clone()
    }
    /// Names of the columns of `errors` (the model's markers).
    #[getter]
    fn marker_names(&self) -> Vec<String> {
        self.marker_names.clone()
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
            .map(|r| jointfit::ik::rms(r.iter().copied()))
            .collect();
        v.into_pyarray(py)
    }
    /// Whether each frame was solved (false: a segment had too few markers).
    #[getter]
    fn solved<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        Array1::from(self.solved.clone()).into_pyarray(py)
    }
    /// Time of every frame (s).
    #[getter]
    fn times<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        Array1::from(self.times.clone()).into_pyarray(py)
    }
    fn __repr__(&self) -> String {
        let n = self.solved.iter().filter(|s| **s).count();
        format!("IkResult({} frames, {n} solved)", self.solved.len())
    }
}

/// Inverse kinematics (the inner level) of `trial` with `model` at its parameters: each
/// frame's coordinates minimize the squared marker distances, warm-started from the frames
/// before. `trial` is a Trial or a path (read with `up`, filtered at `filter` Hz). Model
/// markers the trial lacks count as missing in every frame (a UserWarning).
#[pyfunction]
#[pyo3(signature = (model, trial, up=None, filter=None))]
pub fn ik(
    py: Python<'_>,
    model: &Bound<'_, PyAny>,
    trial: &Bound<'_, PyAny>,
    up: Option<&str>,
    filter: Option<f64>,
) -> PyResult<PyIkResult> {
    let model = model_arg(model)?;
    let trial = trial_arg(py, trial, up, filter, model.spec().lab_up)?;
    let (held_model, held) = jointfit::workflow::hold_undetermined(&model, &[&trial.trial])
        .map_err(|e| msg(e.to_string()))?;
    if !held.is_empty() {
        warn_all(
            py,
            &[format!(
                "{}: no marker determines {}; held at the model's default values",
                trial.name,
                held.join(", ")
            )],
        )?;
    }
    let model = held_model.unwrap_or(model);
    let p = model.nominal_params();
    let run = py
        .detach(|| jointfit::workflow::ik_trial(&model, &p, &trial.trial, &IkOptions::default()))
        .map_err(|e| {
            msg(format!(
                "{}: {}",
                trial.name,
                jointfit_io::batch::message(&e)
            ))
        })?;
    if !run.absent.is_empty() {
        warn_all(
            py,
            &[format!(
                "{}: lacks model markers {}; they count as missing in every frame",
                trial.name,
                run.absent.join(", ")
            )],
        )?;
    }
    let fit = run.fit;
    let (nf, nq, nm) = (fit.frames.len(), model.n_q(), model.n_markers());
    Ok(PyIkResult {
        coordinate_names: model.coordinates().iter().map(|c| c.name.clone()).collect(),
        marker_names: model.markers().iter().map(|m| m.name.clone()).collect(),
        coords: Array2::from_shape_fn((nf, nq), |(f, k)| fit.coords[f][k]),
        errors: Array2::from_shape_fn((nf, nm), |(f, j)| fit.errors[f][j]),
        solved: fit.frames.iter().map(|f| f.solved()).collect(),
        times: (0..nf).map(|f| trial.trial.time(f)).collect(),
    })
}

/// A synthetic trial (as `jointfit demo` makes): `model`'s markers along a motion ("hip",
/// "knee", "ankle" or "all") of `frames` frames at `rate` Hz, with the parameters moved
/// from nominal by up to `perturb` of each half-range (seeded), plus sinusoidal skin-artifact
/// noise of up to `noise_mm` (seeded; 0: none). `model`: a Model, path or built-in name
/// (None: "lower-limb-right"). Returns `(trial, true_model)`.
#[pyfunction]
#[pyo3(signature = (model=None, motion="all", frames=100, rate=50.0, noise_mm=10.0, perturb=0.4, seed=1))]
#[allow(clippy::too_many_arguments)]
pub fn synthesize(
    model: Option<&Bound<'_, PyAny>>,
    motion: &str,
    frames: usize,
    rate: f64,
    noise_mm: f64,
    perturb: f64,
    seed: u64,
) -> PyResult<(PyTrial, PyModel)> {
    let model = match model {
        Some(m) => model_arg(m)?,
        None => jointfit_io::model_file::load_model("lower-limb-right").map_err(|e| err(&e))?,
    };
    let motion: Motion = motion.parse().map_err(|e| err(&e))?;
    if !(0.0..=1.0).contains(&perturb) {
        return Err(msg(format!("perturb must lie in [0, 1], not {perturb}")));
    }
    let truth = perturbed_params(&model, perturb, seed);
    let coords = coordinates(&model, motion, frames).map_err(|e| err(&e))?;
    let noise = SkinNoise {
        max_amplitude: noise_mm / 1e3,
        seed,
        ..SkinNoise::default()
    };
    if !(rate.is_finite() && rate > 0.0) {
        return Err(msg(format!("rate must be positive, not {rate}")));
    }
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
}
