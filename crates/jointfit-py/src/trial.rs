//! `jointfit.Trial`: marker trajectories (frames × markers × 3, metres, NaN for gaps).

use jointfit::spatial::UpAxis;
use jointfit::trial::Trial;
use jointfit_app::{prepare_trial, read_trial, ReadOptions};
use nalgebra::Vector3;
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::args::{self, MAX_RATE_HZ};
use crate::run::guard;
use crate::{err, msg, warn_all};

/// The `up` argument: which laboratory axis points up (`None` or `"y"`: no rotation).
pub(crate) fn parse_up(up: Option<&str>) -> PyResult<Option<UpAxis>> {
    match up {
        None => Ok(None),
        Some(s) => s.parse::<UpAxis>().map(Some).map_err(|_| {
            msg(format!(
                "up must be \"y\", \"-y\", \"z\", \"-z\", \"x\" or \"-x\", not {s:?}"
            ))
        }),
    }
}

/// The `up` argument as any Python value (None, or one of the axis names).
pub(crate) fn up_arg(up: Option<&Bound<'_, PyAny>>) -> PyResult<Option<UpAxis>> {
    let choices = "\"y\", \"-y\", \"z\", \"-z\", \"x\" or \"-x\"";
    match args::opt_text(up, "up", &format!("None or {choices}"))? {
        None => Ok(None),
        Some(s) => s
            .parse::<UpAxis>()
            .map(Some)
            .map_err(|_| msg(format!("up must be {choices}, not {s:?}"))),
    }
}

/// The data of a trial are plausible ([`jointfit_app::check_plausible`], the pipeline's
/// check of what it reads).
pub(crate) fn check_data(trial: &Trial, name: &str) -> PyResult<()> {
    jointfit_app::check_plausible(trial, name).map_err(|e| crate::err(&e))
}

/// Marker trajectories of one trial, in the model's Y-up frame.
///
/// Read a file with `Trial.read(path, up=None)` or build one from arrays with
/// `Trial.from_arrays(labels, markers, rate)`. `markers` is a float64 array of shape
/// (frames, markers, 3) in metres; a missing sample is NaN in all three coordinates.
/// A Trial is immutable: `markers` returns a new array on every access (changing it leaves
/// the trial as it was; build a changed trial with `Trial.from_arrays`). Trials compare equal
/// (`==`) when their labels, rate, first frame, times and samples are equal (NaN gaps equal
/// NaN gaps); the name is not compared.
#[pyclass(name = "Trial", module = "jointfit", frozen)]
#[derive(Clone)]
pub struct PyTrial {
    pub(crate) trial: Trial,
    /// Where the trial came from (its path, or `<arrays>`): names it in messages.
    pub(crate) name: String,
}

/// The float64 array (frames, markers, 3) of `markers`: NumPy arrays of any real dtype,
/// nested lists and tuples converted, anything else refused.
fn marker_array<'py>(
    py: Python<'py>,
    markers: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let np = py.import("numpy")?;
    let refuse = |why: String| {
        msg(format!(
            "markers must be an array of real numbers of shape (frames, markers, 3) in metres \
             (a NumPy array or nested lists): {why}"
        ))
    };
    let kind: String = np
        .call_method1("asarray", (markers,))
        .and_then(|a| a.getattr("dtype")?.getattr("kind")?.extract())
        .map_err(|e| refuse(e.to_string()))?;
    if !"fiub".contains(kind.as_str()) || kind.len() != 1 {
        return Err(refuse(format!(
            "got an array of dtype kind {kind:?} from {}",
            args::type_name(markers)
        )));
    }
    let a = np
        .call_method1("asarray", (markers, "float64"))
        .map_err(|e| refuse(e.to_string()))?;
    let shape: Vec<usize> = a.getattr("shape")?.extract()?;
    if shape.len() != 3 || shape[2] != 3 {
        return Err(msg(format!(
            "markers must have shape (frames, markers, 3), got {shape:?}"
        )));
    }
    a.cast_into::<PyArray3<f64>>()
        .map_err(|e| refuse(e.to_string()))
}

#[pymethods]
impl PyTrial {
    /// Reads a motion file (.c3d or .trc) in metres, rotated so that the model's y axis is
    /// up. `up` names the laboratory's vertical axis ("y", "-y", "z", "-z", "x", "-x");
    /// None: the `lab_up` of `model` (a Model, model file or built-in name: the axis
    /// `personalize` detected or was given), else "y". A trial whose marker layout puts
    /// another axis up is reported as a JointfitWarning.
    /// `filter` low-pass filters the markers (zero-phase Butterworth, Hz, at least 0.1);
    /// filtering that moves a marker by more than 2 cm is reported as a JointfitWarning.
    #[staticmethod]
    #[pyo3(signature = (path, up=None, filter=None, model=None))]
    fn read(
        py: Python<'_>,
        path: &Bound<'_, PyAny>,
        up: Option<&Bound<'_, PyAny>>,
        filter: Option<&Bound<'_, PyAny>>,
        model: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        guard(|| {
            let path = args::path(path, "path")?;
            let up = up_arg(up)?;
            let filter_hz = args::cutoff(filter, "filter")?;
            let model_up = match model {
                Some(m) if !m.is_none() => crate::solve::model_arg(py, m)?.spec().lab_up,
                _ => None,
            };
            let read = ReadOptions {
                up: up.or(model_up),
                filter_hz,
            };
            let (trial, warnings) = py
                .detach(|| read_trial(&path, &read))
                .map_err(|e| err(&e))?;
            let name = path.display().to_string();
            check_data(&trial, &name)?;
            warn_all(py, &warnings)?;
            Ok(PyTrial { trial, name })
        })
    }

    /// Builds a trial from marker labels, an array (frames, markers, 3) in metres (NaN:
    /// missing; float32, integer and nested-list input is converted to float64) and the
    /// sampling rate in Hz (at most 100000). `times` (s, one per frame, strictly increasing)
    /// replaces the default `i / rate`. A sample with one NaN coordinate is missing as a
    /// whole; infinite coordinates and coordinates beyond ±1000 m are refused.
    #[staticmethod]
    #[pyo3(signature = (labels, markers, rate, first_frame=None, name=None, times=None))]
    fn from_arrays(
        py: Python<'_>,
        labels: &Bound<'_, PyAny>,
        markers: &Bound<'_, PyAny>,
        rate: &Bound<'_, PyAny>,
        first_frame: Option<&Bound<'_, PyAny>>,
        name: Option<&Bound<'_, PyAny>>,
        times: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        guard(|| {
            let labels = args::strings(labels, "labels")?;
            let rate = args::positive(rate, "rate", MAX_RATE_HZ, " Hz")?;
            let first_frame = match first_frame {
                Some(f) if !f.is_none() => args::signed(f, "first_frame")?,
                _ => 0,
            };
            let name = args::opt_text(name, "name", "a str")?.unwrap_or_else(|| "<arrays>".into());
            let arr = marker_array(py, markers)?;
            let ro = arr.readonly();
            let a = ro.as_array();
            let (frames, n, _) = a.dim();
            if n != labels.len() {
                return Err(msg(format!(
                    "{} labels for {n} marker columns (markers has shape ({frames}, {n}, 3))",
                    labels.len()
                )));
            }
            let mut positions = Vec::with_capacity(frames * n);
            for f in 0..frames {
                for (j, label) in labels.iter().enumerate() {
                    let p = Vector3::new(a[[f, j, 0]], a[[f, j, 1]], a[[f, j, 2]]);
                    if p.iter().any(|v| v.is_infinite()) {
                        return Err(msg(format!(
                            "markers: frame {f}, marker {label}: position ({}, {}, {}) is not \
                             finite (NaN marks a gap; infinity is refused)",
                            p.x, p.y, p.z
                        )));
                    }
                    positions.push(p);
                }
            }
            let mut trial =
                Trial::new(labels, rate, first_frame, positions).map_err(|e| err(&e))?;
            if let Some(t) = times.filter(|t| !t.is_none()) {
                let t: Vec<f64> = py
                    .import("numpy")?
                    .call_method1("asarray", (t, "float64"))
                    .and_then(|a| a.call_method0("tolist"))
                    .and_then(|l| l.extract())
                    .map_err(|_| {
                        msg("times must be None or a sequence of numbers (s), one per frame")
                    })?;
                trial = trial
                    .with_times(Some(t))
                    .map_err(|e| msg(format!("times: {e}")))?;
            }
            check_data(&trial, &name)?;
            Ok(PyTrial { trial, name })
        })
    }

    /// A repaired copy and what was done (one sentence each): `exclude` leaves markers out,
    /// `swap` exchanges labels ("A,B", "A,B@F" from file frame F on, "A,B@F-L"), `fill_gaps`
    /// fills gaps of at most that many frames (rigid-body fill from the segment's other
    /// markers when `model` names the segments, else cubic spline). See `jointfit::repair`.
    #[pyo3(signature = (exclude=None, swap=None, fill_gaps=None, model=None))]
    fn repair(
        &self,
        py: Python<'_>,
        exclude: Option<&Bound<'_, PyAny>>,
        swap: Option<&Bound<'_, PyAny>>,
        fill_gaps: Option<&Bound<'_, PyAny>>,
        model: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<(Self, Vec<String>)> {
        guard(|| {
            let list = |v: Option<&Bound<'_, PyAny>>, name: &str| match v {
                Some(v) if !v.is_none() => args::strings(v, name),
                _ => Ok(Vec::new()),
            };
            let exclude = list(exclude, "exclude")?;
            let swap = list(swap, "swap")?;
            let fill_gaps = match fill_gaps {
                Some(v) if !v.is_none() => args::whole(v, "fill_gaps", 0, 1_000_000)? as usize,
                _ => 0,
            };
            let model = match model {
                Some(m) if !m.is_none() => Some(crate::solve::model_arg(py, m)?),
                _ => None,
            };
            let opts = jointfit::repair::RepairOptions {
                exclude,
                swaps: swap
                    .iter()
                    .map(|s| s.parse::<jointfit::repair::Swap>())
                    .collect::<Result<_, _>>()
                    .map_err(|e| err(&e))?,
                fill_gaps,
            };
            let (trial, actions) = jointfit::repair::repair(&self.trial, model.as_ref(), &opts)
                .map_err(|e| msg(format!("{}: {e}", self.name)))?;
            Ok((
                PyTrial {
                    trial,
                    name: self.name.clone(),
                },
                actions.iter().map(|a| a.to_string()).collect(),
            ))
        })
    }

    /// Marker labels, one per marker column.
    #[getter]
    fn labels(&self) -> Vec<String> {
        self.trial.labels().to_vec()
    }

    /// Sampling rate (Hz).
    #[getter]
    fn rate(&self) -> f64 {
        self.trial.rate()
    }

    /// Number of the first frame as the source file counts it.
    #[getter]
    fn first_frame(&self) -> i64 {
        self.trial.first_frame()
    }

    /// Where the trial came from (a path, or "<arrays>").
    #[getter]
    fn name(&self) -> String {
        self.name.clone()
    }

    /// Marker positions: float64 array (frames, markers, 3), metres, NaN for gaps. A new
    /// array on every access: changing it does not change the trial.
    #[getter]
    fn markers<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f64>> {
        let t = &self.trial;
        let (frames, n) = (t.n_frames(), t.labels().len());
        let a = Array3::from_shape_fn((frames, n, 3), |(f, j, k)| t.frame(f)[j][k]);
        a.into_pyarray(py)
    }

    /// Time of every frame (s): the file's own time column (TRC) when it had one, else
    /// frame / rate from the first frame.
    #[getter]
    fn times(&self) -> Vec<f64> {
        (0..self.trial.n_frames())
            .map(|f| self.trial.time(f))
            .collect()
    }

    /// Duration from the first to the last frame (s).
    #[getter]
    fn duration(&self) -> f64 {
        match self.trial.n_frames() {
            0 => 0.0,
            n => self.trial.time(n - 1) - self.trial.time(0),
        }
    }

    /// The trial low-pass filtered (zero-phase Butterworth, effective order 4) at `cutoff`
    /// Hz (at least 0.1, below the Nyquist frequency); moves of more than 2 cm are reported
    /// as a JointfitWarning.
    fn filtered(&self, py: Python<'_>, cutoff: &Bound<'_, PyAny>) -> PyResult<Self> {
        guard(|| {
            let hz = args::cutoff(Some(cutoff), "cutoff")?;
            let (trial, warnings) = py
                .detach(|| prepare_trial(self.trial.clone(), &self.name, None, hz))
                .map_err(|e| err(&e))?;
            warn_all(py, &warnings)?;
            Ok(PyTrial {
                trial,
                name: self.name.clone(),
            })
        })
    }

    /// The trial restricted to the named markers, in that order.
    fn select(&self, labels: &Bound<'_, PyAny>) -> PyResult<Self> {
        guard(|| {
            let labels = args::strings(labels, "labels")?;
            let names: Vec<&str> = labels.iter().map(String::as_str).collect();
            let trial = self.trial.select(&names).map_err(|e| err(&e))?;
            Ok(PyTrial {
                trial,
                name: self.name.clone(),
            })
        })
    }

    /// The frames whose time (`times`, s) lies from `t0` to `t1` inclusive, keeping their
    /// times and file frame numbers (so the IK of a part of a trial lines up with the whole).
    fn between(&self, t0: &Bound<'_, PyAny>, t1: &Bound<'_, PyAny>) -> PyResult<Self> {
        guard(|| {
            let t0 = args::number(t0, "t0", "a finite time in seconds")?;
            let t1 = args::number(t1, "t1", "a finite time in seconds")?;
            if t1 < t0 {
                return Err(msg(format!(
                    "t1 must not be earlier than t0 (got t0 = {t0} s, t1 = {t1} s)"
                )));
            }
            let n = self.trial.n_frames();
            // Half a microsecond of slack: times printed in a file round the frame period.
            let eps = 5e-7;
            let inside: Vec<usize> = (0..n)
                .filter(|&f| {
                    let t = self.trial.time(f);
                    t >= t0 - eps && t <= t1 + eps
                })
                .collect();
            let (Some(&first), Some(&last)) = (inside.first(), inside.last()) else {
                let span = match n {
                    0 => "it has no frames".to_string(),
                    _ => format!(
                        "its frames run from {} s to {} s",
                        self.trial.time(0),
                        self.trial.time(n - 1)
                    ),
                };
                return Err(msg(format!(
                    "{}: no frame between {t0} s and {t1} s ({span})",
                    self.name
                )));
            };
            let times: Vec<f64> = (first..=last).map(|f| self.trial.time(f)).collect();
            let trial = self
                .trial
                .slice_frames(first, last + 1)
                .with_times(Some(times))
                .map_err(|e| err(&e))?;
            Ok(PyTrial {
                trial,
                name: self.name.clone(),
            })
        })
    }

    /// Writes the trial as an OpenSim marker file (.trc, Y up as the trial holds it), in
    /// millimetres (`units="mm"`, the default) or metres (`units="m"`) with `decimals`
    /// digits after the point (0 to 15). Written atomically.
    #[pyo3(signature = (path, units=None, decimals=None))]
    fn write_trc(
        &self,
        py: Python<'_>,
        path: &Bound<'_, PyAny>,
        units: Option<&Bound<'_, PyAny>>,
        decimals: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        guard(|| {
            let path = args::path(path, "path")?;
            let mut opts = jointfit_io::trc::TrcWriteOptions::default();
            if let Some(u) = units.filter(|u| !u.is_none()) {
                opts.units = match args::choice(u, "units", &["mm", "m"])?.as_str() {
                    "mm" => jointfit_io::trc::TrcUnits::Millimetres,
                    _ => jointfit_io::trc::TrcUnits::Metres,
                };
            }
            if let Some(d) = decimals.filter(|d| !d.is_none()) {
                opts.decimals = args::whole(d, "decimals", 0, 15)? as usize;
            }
            py.detach(|| jointfit_io::trc::write_trc(&path, &self.trial, &opts))
                .map_err(|e| err(&e))
        })
    }

    fn __len__(&self) -> usize {
        self.trial.n_frames()
    }

    fn __repr__(&self) -> String {
        format!(
            "Trial({:?}: {} frames, {} markers, {} Hz)",
            self.name,
            self.trial.n_frames(),
            self.trial.labels().len(),
            self.trial.rate()
        )
    }

    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        let Ok(other) = other.cast::<PyTrial>() else {
            return false;
        };
        let (a, b) = (&self.trial, &other.get().trial);
        let same = |x: f64, y: f64| x == y || (x.is_nan() && y.is_nan());
        a.labels() == b.labels()
            && a.rate() == b.rate()
            && a.first_frame() == b.first_frame()
            && a.times() == b.times()
            && a.positions().len() == b.positions().len()
            && a.positions()
                .iter()
                .zip(b.positions())
                .all(|(p, q)| (0..3).all(|k| same(p[k], q[k])))
    }

    /// Pickles by value (labels, markers, rate, first frame, name, times): trials travel to
    /// Dask workers this way.
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let cls = py.get_type::<PyTrial>();
        let ctor = cls.getattr("from_arrays")?;
        let args = PyTuple::new(
            py,
            [
                self.labels().into_pyobject(py)?.into_any(),
                self.markers(py).into_any(),
                self.rate().into_pyobject(py)?.into_any(),
                self.first_frame().into_pyobject(py)?.into_any(),
                self.name.clone().into_pyobject(py)?.into_any(),
                self.trial
                    .times()
                    .map(|t| t.to_vec())
                    .into_pyobject(py)?
                    .into_any(),
            ],
        )?;
        Ok((ctor, args))
    }
}
