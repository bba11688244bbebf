//! Inverse kinematics of a live marker feed, one frame at a time ([`StreamingIk`]).
//!
//! Each frame solves the inner-level problem of the module docs ([`super`]),
//!
//! `q_t = argmin_q Σ_j w_j ‖m_j(t) − x_j(p, q)‖²`,
//!
//! with the rules of the trial loop ([`super::solve_trial`]) applied to the frames as they
//! arrive: the first frame, and the first after a frame whose result was not finite, is seeded
//! ([`super::seed_frame`]); the frame after a seeded or unsolved one starts from the last
//! solution; every other frame from the linear extrapolation `2 q_{t−1} − q_{t−2}` of the two
//! before ([`super::extrapolate`]). Solvability ([`super::solvable`]), gross-error rejection
//! ([`IkOptions::outlier_distance`]), clamped coordinates and holding undetermined coordinates
//! ([`IkOptions::hold_undetermined`]) are those of [`super::solve_frame`] and the trial loop,
//! and each pose is reported on the branch inside the model's coordinate ranges
//! ([`super::branch`]).
//!
//! **What equals the trial loop.** Frames `0..n` fed in order give bit for bit the
//! coordinates, errors and statuses of [`super::solve_trial_in_chunks`] with the one chunk
//! `0..n`, on every frame its repair pass left alone ([`super::repair`]: a frame whose RMS is
//! far above the trial's median is re-solved from its neighbours, which needs the frames that
//! have not arrived yet; a stream cannot apply it). [`super::solve_trial`] cuts a trial of 128
//! frames or more into chunks and seeds the first frame of each; those frames and the ones
//! after them reach the same minimum from another start, so their coordinates agree with the
//! stream's to within the solver's step tolerance ([`IkOptions::step_tolerance`]), not bit for
//! bit.
//!
//! Samples are taken as a trial file's reader takes them: a sample with a coordinate that is
//! not finite is missing, and the others are rotated from the laboratory's vertical to the
//! model's Y up (`crate::spatial::up_axis_rotation`, as `Trial::rotate`).
//!
//! Memory does not grow with the stream: the object keeps the last two solutions, one
//! workspace and the bounded cache of solvability verdicts.

use nalgebra::{Matrix3, Vector3};

use super::branch::Branches;
use super::lm::frame_weights;
use super::trial_fit::marker_errors;
use super::{
    extrapolate, seed_frame, solve_frame, FrameFit, FrameStatus, IkError, IkOptions, IkWorkspace,
    MarkerMap,
};
use crate::model::Model;
use crate::spatial::up_axis_rotation;
use crate::spatial::UpAxis;
use crate::trial::Trial;

/// The result of one frame of a stream ([`StreamingIk::update`], [`StreamingIk::last`]),
/// borrowed from the stream until the next frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamFrame<'a> {
    /// Coordinates in model order (rad, m); NaN when the frame is not solved (see `fit`).
    pub coords: &'a [f64],
    /// Marker distances `‖m − x‖` per model marker (m); NaN for missing and rejected markers
    /// and in a frame not solved.
    pub errors: &'a [f64],
    /// How the frame's solve ended: its status, iterations and rejected markers (`None`
    /// before the first frame).
    pub fit: Option<&'a FrameFit>,
    /// Model markers the feed lacks: missing in every frame.
    pub absent: &'a [String],
    /// Coordinates locked at their defaults by [`StreamingIk::new`] because no label of
    /// the feed determines them.
    pub held: &'a [String],
}

/// Inverse kinematics of a marker feed, frame by frame, warm-started from the frames before
/// (see the module docs). Owns its model and workspace; `Send`, so it can move to the
/// thread that reads the feed.
#[derive(Debug, Clone)]
pub struct StreamingIk {
    model: Model,
    p: Vec<f64>,
    map: MarkerMap,
    n_labels: usize,
    /// Model markers the feed lacks (missing in every frame).
    absent: Vec<String>,
    /// Coordinates locked at their defaults because no label determines them.
    held: Vec<String>,
    /// Laboratory → model frame.
    rotation: Matrix3<f64>,
    opts: IkOptions,
    ws: IkWorkspace,
    branches: Branches,
    targets: Vec<Vector3<f64>>,
    /// The last two solutions (as solved, before choosing their branch) when they belong to
    /// consecutive frames, as in the trial loop.
    q: Option<Vec<f64>>,
    q_before: Option<Vec<f64>>,
    /// The last frame's reported coordinates (NaN when not solved), errors and outcome.
    coords: Vec<f64>,
    errors: Vec<f64>,
    fit: Option<FrameFit>,
    last_time: Option<f64>,
}

impl StreamingIk {
    /// The feed's stream at parameters `p`, no coordinate locked (see [`StreamingIk::new`]).
    pub(crate) fn with_params(
        model: Model,
        p: Vec<f64>,
        labels: &[String],
        up: UpAxis,
        opts: IkOptions,
    ) -> Result<Self, IkError> {
        check_labels(labels)?;
        if p.len() != model.parameters().len() {
            return Err(IkError::ParamLength {
                got: p.len(),
                expected: model.parameters().len(),
            });
        }
        let (map, absent) = MarkerMap::allowing_absent(&model, labels);
        if absent.len() == model.markers().len() {
            return Err(IkError::NoCommonMarker {
                model_markers: model.markers().len(),
                available: labels.join(", "),
            });
        }
        let ws = IkWorkspace::new(&model);
        let branches = Branches::new(&model);
        Ok(StreamingIk {
            p,
            map,
            n_labels: labels.len(),
            absent,
            held: Vec::new(),
            rotation: up_axis_rotation(up),
            opts,
            ws,
            branches,
            targets: Vec::with_capacity(model.markers().len()),
            q: None,
            q_before: None,
            coords: vec![f64::NAN; model.coordinates().len()],
            errors: vec![f64::NAN; model.markers().len()],
            fit: None,
            last_time: None,
            model,
        })
    }

    /// A stream of the feed whose samples come in the order of `labels`, in the frame of a
    /// laboratory whose vertical is `up`, solved with `model` at its nominal parameters.
    /// Coordinates no label of the feed determines are locked at their defaults first (a toe
    /// joint without toe markers), as inverse kinematics of a trial does
    /// ([`super::hold_undetermined`], judged with every label present; their names in
    /// [`StreamFrame::held`]). Model markers the feed lacks are missing in every frame
    /// ([`StreamFrame::absent`]), as [`MarkerMap::allowing_absent`] pairs them for a trial;
    /// labels the model lacks are ignored.
    pub fn new(
        model: &Model,
        labels: &[String],
        up: UpAxis,
        opts: IkOptions,
    ) -> Result<Self, IkError> {
        check_labels(labels)?;
        // One frame with every label present: solvability depends only on which markers are
        // present.
        let probe = Trial::new(
            labels.to_vec(),
            1.0,
            0,
            vec![Vector3::repeat(1.0); labels.len()],
        )
        .map_err(|e| IkError::Hold(e.to_string()))?;
        let (held_model, held) =
            super::hold_undetermined(model, &[&probe]).map_err(|e| IkError::Hold(e.to_string()))?;
        let model = held_model.unwrap_or_else(|| model.clone());
        let p = model.nominal_params();
        let mut stream = StreamingIk::with_params(model, p, labels, up, opts)?;
        stream.held = held;
        Ok(stream)
    }

    /// Solves the frame at `time` (s) from `markers`: one position per feed label, in its
    /// order, in metres in the laboratory frame (NaN or any non-finite coordinate: missing).
    /// Returns the frame's result ([`StreamFrame`]: coordinates, marker errors, status).
    /// Errors, without changing the stream, when the number of positions is not the number of
    /// labels or `time` does not increase.
    pub fn update(
        &mut self,
        time: f64,
        markers: &[Vector3<f64>],
    ) -> Result<StreamFrame<'_>, IkError> {
        if markers.len() != self.n_labels {
            return Err(IkError::MarkerCount {
                got: markers.len(),
                expected: self.n_labels,
            });
        }
        if !time.is_finite() {
            return Err(IkError::TimeNotFinite(time));
        }
        if let Some(previous) = self.last_time.filter(|&t| time <= t) {
            return Err(IkError::TimeNotIncreasing { time, previous });
        }
        self.last_time = Some(time);
        self.set_targets(markers);
        self.solve();
        Ok(self.last())
    }

    /// Forgets the frames before: the next frame is seeded, as the first.
    pub fn reset(&mut self) {
        self.q = None;
        self.q_before = None;
        self.last_time = None;
    }

    /// The model the frames are solved with (with [`StreamFrame::held`] coordinates locked).
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The result of the last frame, as [`StreamingIk::update`] returned it; before the first
    /// frame, NaN coordinates and errors and no [`StreamFrame::fit`] (the feed's
    /// [`StreamFrame::absent`] markers and [`StreamFrame::held`] coordinates are known from the
    /// start).
    pub fn last(&self) -> StreamFrame<'_> {
        StreamFrame {
            coords: &self.coords,
            errors: &self.errors,
            fit: self.fit.as_ref(),
            absent: &self.absent,
            held: &self.held,
        }
    }

    /// Model-ordered targets of one feed frame in the model's frame, as a trial's reader and
    /// [`MarkerMap::targets`] would give them.
    fn set_targets(&mut self, markers: &[Vector3<f64>]) {
        let nan = Vector3::repeat(f64::NAN);
        let r = &self.rotation;
        self.targets.clear();
        self.targets
            .extend(self.map.columns.iter().map(|c| match c {
                Some(c) => {
                    let m = markers[*c];
                    if m.iter().all(|v| v.is_finite()) {
                        r * m
                    } else {
                        nan
                    }
                }
                None => nan,
            }));
    }

    /// One step of the trial loop (`trial_fit::solve_range`) on the current targets.
    fn solve(&mut self) {
        let (model, p) = (&self.model, &self.p[..]);
        let mut qf = match (&self.q, &self.q_before) {
            (Some(prev), Some(before)) => extrapolate(prev, before),
            (Some(prev), None) => prev.clone(),
            (None, _) => seed_frame(model, p, &self.targets, &self.opts, &mut self.ws),
        };
        let no_hold = IkOptions {
            hold_undetermined: false,
            ..self.opts
        };
        let frame_opts = match &self.q {
            Some(prev) if self.opts.hold_undetermined => {
                // Held coordinates stay exactly at the previous frame's values.
                let mut rejected = Vec::new();
                frame_weights(model, &self.targets, &mut self.ws.weights, &mut rejected);
                let held = self.ws.solvability.undetermined_at(
                    model,
                    p,
                    &self.ws.weights,
                    &self.ws.known,
                    &qf,
                    &self.opts,
                );
                for c in held {
                    qf[c] = prev[c];
                }
                &self.opts
            }
            _ => &no_hold,
        };
        let fit = solve_frame(model, p, &self.targets, &mut qf, frame_opts, &mut self.ws);
        if fit.solved() {
            self.errors = marker_errors(model, &self.targets, &fit, &self.ws);
            self.coords.copy_from_slice(&qf);
            self.branches.canonicalize(&mut self.coords);
            self.q_before = self.q.replace(qf);
        } else {
            self.errors.fill(f64::NAN);
            self.coords.fill(f64::NAN);
            // Across a gap the velocity is unknown: restart from the last solution alone;
            // after a result that went wrong, from seeding.
            self.q_before = None;
            if fit.status == FrameStatus::Diverged {
                self.q = None;
            }
        }
        self.fit = Some(fit);
    }
}

/// Labels must be given, each once.
fn check_labels(labels: &[String]) -> Result<(), IkError> {
    if labels.is_empty() {
        return Err(IkError::NoLabels);
    }
    let mut seen = std::collections::HashSet::new();
    match labels.iter().find(|l| !seen.insert(l.as_str())) {
        Some(l) => Err(IkError::DuplicateLabel(l.clone())),
        None => Ok(()),
    }
}
