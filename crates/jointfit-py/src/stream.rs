//! `jointfit.StreamingIK`: inverse kinematics of a live marker feed, one frame per call
//! (`jointfit::ik::stream::StreamingIk`; `docs/streaming.md`).

use jointfit::ik::stream::StreamingIk;
use jointfit::ik::{FrameStatus, IkOptions};
use jointfit::spatial::UpAxis;
use nalgebra::Vector3;
use numpy::{PyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::msg;
use crate::solve::model_arg;
use crate::trial::parse_up;

/// Inverse kinematics of a marker feed, frame by frame, for SDK bridges (Vicon DataStream,
/// Qualisys RT, …).
///
/// `StreamingIK(model, labels, up=None, hold_undetermined=False, keep_outliers=False)`:
/// `model` a Model, model file or built-in name; `labels` the feed's marker labels in the
/// order `update` receives them; `up` the laboratory's vertical axis ("y", "-y", "z", "-z",
/// "x", "-x"; None: the model's `lab_up`, else "y"). Coordinates no label determines are held
/// at their defaults (a UserWarning), model markers the feed lacks are missing in every
/// frame (a UserWarning), as `jointfit.ik` does.
///
/// `update(markers, time=None)` solves one frame: `markers` float64 (len(labels), 3) in
/// metres in the laboratory frame, NaN for a missing marker; returns the coordinates in the
/// order of `coordinate_names` (rad, m), NaN when the frame cannot be solved (see
/// `status`). Each frame is warm-started from the ones before, with the rules of
/// `jointfit.ik`; frames fed in order give `jf.ik`'s coordinates (see `docs/streaming.md` for
/// what is bit-equal and what agrees within the solver's tolerance). The GIL is released
/// while the frame is solved.
#[pyclass(name = "StreamingIK", module = "jointfit")]
pub struct PyStreamingIk {
    stream: StreamingIk,
    /// One position per label (metres), reused by every frame.
    markers: Vec<Vector3<f64>>,
    /// The time given to the last frame (s); frames without a time count on from it.
    time: Option<f64>,
}

#[pymethods]
impl PyStreamingIk {
    #[new]
    #[pyo3(signature = (model, labels, up=None, hold_undetermined=false, keep_outliers=false))]
    fn new(
        py: Python<'_>,
        model: &Bound<'_, PyAny>,
        labels: Vec<String>,
        up: Option<&str>,
        hold_undetermined: bool,
        keep_outliers: bool,
    ) -> PyResult<Self> {
        let model = model_arg(py, model)?;
        let up = parse_up(up)?.or(model.spec().lab_up).unwrap_or(UpAxis::Y);
        let opts = IkOptions::with_rules(hold_undetermined, !keep_outliers);
        let stream = StreamingIk::new(&model, &labels, up, opts)
            .map_err(|e| msg(format!("StreamingIK: {e}")))?;
        let mut warnings = Vec::new();
        let setup = stream.last();
        if !setup.held.is_empty() {
            warnings.push(format!(
                "no marker of the feed determines {}; held at the model's default values",
                setup.held.join(", ")
            ));
        }
        if !setup.absent.is_empty() {
            warnings.push(format!(
                "the feed lacks model markers {}; they count as missing in every frame",
                setup.absent.join(", ")
            ));
        }
        crate::warn_all(py, &warnings)?;
        Ok(PyStreamingIk {
            markers: vec![Vector3::zeros(); labels.len()],
            stream,
            time: None,
        })
    }

    /// Solves one frame (see the class docs); `time` in s must increase from frame to frame
    /// (None: one more than the last frame's).
    #[pyo3(signature = (markers, time=None))]
    fn update<'py>(
        &mut self,
        py: Python<'py>,
        markers: PyReadonlyArray2<'py, f64>,
        time: Option<f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let a = markers.as_array();
        let (n, three) = a.dim();
        if three != 3 || n != self.markers.len() {
            return Err(msg(format!(
                "markers must have shape ({}, 3) (one row per label), got ({n}, {three})",
                self.markers.len()
            )));
        }
        for (j, m) in self.markers.iter_mut().enumerate() {
            *m = Vector3::new(a[[j, 0]], a[[j, 1]], a[[j, 2]]);
        }
        let time = time.unwrap_or_else(|| self.time.map_or(0.0, |t| t + 1.0));
        let (stream, frame) = (&mut self.stream, &self.markers);
        py.detach(|| stream.update(time, frame).map(|_| ()))
            .map_err(|e| msg(format!("StreamingIK.update: {e}")))?;
        self.time = Some(time);
        Ok(PyArray1::from_slice(py, self.stream.last().coords))
    }

    /// Forgets the frames before: the next frame is seeded, as the first.
    fn reset(&mut self) {
        self.stream.reset();
        self.time = None;
    }

    /// Names of the coordinates `update` returns, in its order.
    #[getter]
    fn coordinate_names(&self) -> Vec<String> {
        let model = self.stream.model();
        model.coordinates().iter().map(|c| c.name.clone()).collect()
    }

    /// Names of the model's markers (the columns of `errors`).
    #[getter]
    fn marker_names(&self) -> Vec<String> {
        let model = self.stream.model();
        model.markers().iter().map(|m| m.name.clone()).collect()
    }

    /// Model markers the feed lacks (missing in every frame).
    #[getter]
    fn absent(&self) -> Vec<String> {
        self.stream.last().absent.to_vec()
    }

    /// Coordinates held at their defaults because no label determines them.
    #[getter]
    fn held(&self) -> Vec<String> {
        self.stream.last().held.to_vec()
    }

    /// Whether the last frame was solved.
    #[getter]
    fn solved(&self) -> bool {
        self.stream.last().fit.is_some_and(|f| f.solved())
    }

    /// How the last frame ended: "converged", "max_iterations", "stalled", "undetermined:
    /// COORDINATE", "diverged" (None before the first frame).
    #[getter]
    fn status(&self) -> Option<String> {
        self.stream.last().fit.map(|f| match &f.status {
            FrameStatus::Converged => "converged".into(),
            FrameStatus::MaxIterations => "max_iterations".into(),
            FrameStatus::Stalled => "stalled".into(),
            FrameStatus::Undetermined { coordinate } => format!("undetermined: {coordinate}"),
            FrameStatus::Diverged => "diverged".into(),
            FrameStatus::Implausible { .. } => "implausible".into(),
        })
    }

    /// The last frame's distance between measured and model marker per model marker (m;
    /// NaN where missing or rejected, and in a frame not solved).
    #[getter]
    fn errors<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.stream.last().errors)
    }

    /// Model markers rejected as gross errors in the last frame.
    #[getter]
    fn rejected(&self) -> Vec<String> {
        let model = self.stream.model();
        self.stream.last().fit.map_or_else(Vec::new, |f| {
            f.rejected
                .iter()
                .map(|&j| model.markers()[j].name.clone())
                .collect()
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "StreamingIK({} labels, {} coordinates)",
            self.markers.len(),
            self.stream.model().coordinates().len()
        )
    }
}
