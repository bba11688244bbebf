//! `jointfit.Trial`: marker trajectories (frames × markers × 3, metres, NaN for gaps).

use std::path::PathBuf;

use jointfit::trial::{Trial, UpAxis};
use jointfit_io::batch::{prepare_trial, read_trial, ReadOptions};
use nalgebra::Vector3;
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3, PyReadonlyArray3};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::{err, msg, warn_all};

/// The `up` argument: which laboratory axis points up (`None` or `"y"`: no rotation).
pub(crate) fn parse_up(up: Option<&str>) -> PyResult<Option<UpAxis>> {
    match up {
        None => Ok(None),
        Some(s) => UpAxis::parse(s).map(Some).ok_or_else(|| {
            msg(format!(
                "up must be \"y\", \"-y\", \"z\", \"-z\", \"x\" or \"-x\", not {s:?}"
            ))
        }),
    }
}

/// Marker trajectories of one trial, in the model's Y-up frame.
///
/// Read a file with `Trial.read(path, up=None)` or build one from arrays with
/// `Trial.from_arrays(labels, markers, rate)`. `markers` is a float64 array of shape
/// (frames, markers, 3) in metres; a missing sample is NaN in all three coordinates.
#[pyclass(name = "Trial", module = "jointfit", frozen)]
#[derive(Clone)]
pub struct PyTrial {
    pub(crate) trial: Trial,
    /// Where the trial came from (its path, or `<arrays>`): names it in messages.
    pub(crate) name: String,
}

#[pymethods]
impl PyTrial {
    /// Reads a motion file (.c3d or .trc) in metres, rotated so that the model's y axis is
    /// up. `up` names the laboratory's vertical axis ("y", "-y", "z", "-z", "x", "-x");
    /// None: the `lab_up` of `model` (a Model, model file or built-in name: the axis
    /// `personalize` detected or was given), else "y". A trial whose marker layout puts
    /// another axis up is reported as a UserWarning.
    /// `filter` low-pass filters the markers (zero-phase Butterworth, Hz); filtering that
    /// moves a marker by more than 2 cm is reported as a UserWarning.
    #[staticmethod]
    #[pyo3(signature = (path, up=None, filter=None, model=None))]
    fn read(
        py: Python<'_>,
        path: PathBuf,
        up: Option<&str>,
        filter: Option<f64>,
        model: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let model_up = match model {
            Some(m) => crate::solve::model_arg(m)?.spec().lab_up,
            None => None,
        };
        let read = ReadOptions {
            up: parse_up(up)?.or(model_up),
            filter_hz: filter,
        };
        let (trial, warnings) = py
            .detach(|| read_trial(&path, &read))
            .map_err(|e| err(&e))?;
        warn_all(py, &warnings)?;
        Ok(PyTrial {
            trial,
            name: path.display().to_string(),
        })
    }

    /// Builds a trial from marker labels, a float64 array (frames, markers, 3) in metres
    /// (NaN: missing) and the sampling rate in Hz.
    #[staticmethod]
    #[pyo3(signature = (labels, markers, rate, first_frame=0, name=None))]
    fn from_arrays(
        labels: Vec<String>,
        markers: PyReadonlyArray3<'_, f64>,
        rate: f64,
        first_frame: i64,
        name: Option<String>,
    ) -> PyResult<Self> {
        let a = markers.as_array();
        let (frames, n, three) = a.dim();
        if three != 3 {
            return Err(msg(format!(
                "markers must have shape (frames, markers, 3), got ({frames}, {n}, {three})"
            )));
        }
        if n != labels.len() {
            return Err(msg(format!(
                "{} labels for {n} marker columns (markers has shape ({frames}, {n}, 3))",
                labels.len()
            )));
        }
        let mut positions = Vec::with_capacity(frames * n);
        for f in 0..frames {
            for j in 0..n {
                positions.push(Vector3::new(a[[f, j, 0]], a[[f, j, 1]], a[[f, j, 2]]));
            }
        }
        let trial = Trial::new(labels, rate, first_frame, positions).map_err(|e| err(&e))?;
        Ok(PyTrial {
            trial,
            name: name.unwrap_or_else(|| "<arrays>".into()),
        })
    }

    /// A repaired copy and what was done (one sentence each): `exclude` leaves markers out,
    /// `swap` exchanges labels ("A,B", "A,B@F" from file frame F on, "A,B@F-L"), `fill_gaps`
    /// fills gaps of at most that many frames (rigid-body fill from the segment's other
    /// markers when `model` names the segments, else cubic spline). See `jointfit::repair`.
    #[pyo3(signature = (exclude=Vec::new(), swap=Vec::new(), fill_gaps=0, model=None))]
    fn repair(
        &self,
        exclude: Vec<String>,
        swap: Vec<String>,
        fill_gaps: usize,
        model: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<(Self, Vec<String>)> {
        let model = model.map(crate::solve::model_arg).transpose()?;
        let opts = jointfit::repair::RepairOptions {
            exclude,
            swaps: swap
                .iter()
                .map(|s| jointfit::repair::Swap::parse(s))
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

    /// Marker positions: float64 array (frames, markers, 3), metres, NaN for gaps (a copy).
    #[getter]
    fn markers<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f64>> {
        let t = &self.trial;
        let (frames, n) = (t.n_frames(), t.n_markers());
        let a = Array3::from_shape_fn((frames, n, 3), |(f, j, k)| t.frame(f)[j][k]);
        a.into_pyarray(py)
    }

    /// Time of every frame (s), starting at 0.
    #[getter]
    fn times(&self) -> Vec<f64> {
        (0..self.trial.n_frames())
            .map(|f| self.trial.time(f))
            .collect()
    }

    /// The trial low-pass filtered (zero-phase Butterworth, effective order 4) at `cutoff`
    /// Hz; moves of more than 2 cm are reported as UserWarnings.
    fn filtered(&self, py: Python<'_>, cutoff: f64) -> PyResult<Self> {
        let (trial, warnings) = py
            .detach(|| prepare_trial(self.trial.clone(), &self.name, None, Some(cutoff)))
            .map_err(|e| err(&e))?;
        warn_all(py, &warnings)?;
        Ok(PyTrial {
            trial,
            name: self.name.clone(),
        })
    }

    /// The trial restricted to the named markers, in that order.
    fn select(&self, labels: Vec<String>) -> PyResult<Self> {
        let names: Vec<&str> = labels.iter().map(String::as_str).collect();
        let trial = self.trial.select(&names).map_err(|e| err(&e))?;
        Ok(PyTrial {
            trial,
            name: self.name.clone(),
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
            self.trial.n_markers(),
            self.trial.rate()
        )
    }

    /// Pickles by value (labels, markers, rate, first frame, name): trials travel to Dask
    /// workers this way.
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
            ],
        )?;
        Ok((ctor, args))
    }
}
