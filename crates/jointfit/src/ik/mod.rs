//! The inner level: per-frame inverse kinematics by damped Gauss-Newton (Levenberg–Marquardt).
//!
//! For parameters `p` and measured markers `m_j` (frame i), find
//!
//! `q_i = argmin_q Σ_j w_j ‖m_j − x_j(p, q)‖²`,
//!
//! Reinbolt et al. 2005, Eq. (1), with per-marker weights `w_j` (0 for a missing marker). Each
//! iteration solves `(JᵀWJ + λ·diag(JᵀWJ)) δ = JᵀW r` with the analytic Jacobian
//! `J = ∂x/∂q` ([`crate::kinematics`]) and `r = m − x`, accepts the step when the cost drops
//! and adapts `λ` (Marquardt's scaling). Without noise the residual vanishes at the solution
//! and Gauss-Newton converges quadratically.
//!
//! Frames are solved in order, each warm-started from the previous solutions (the paper's
//! scheme, with a linear extrapolation of the last two). The first frame is seeded from the root segment's markers alone: the root joint's
//! coordinates are fitted from several starting orientations and the best fit is kept, the
//! other coordinates start at their defaults.
//!
//! A frame is solved when its present markers determine every coordinate through the chain
//! ([`solvable`]); otherwise it is reported with the undetermined coordinate, or (with
//! [`IkOptions::hold_undetermined`]) solved with those coordinates held at the previous
//! frame's values (in a seeded frame, the seed's). A coordinate task
//! ([`CoordinateTask`], OpenSim's `IKCoordinateTask`) adds `W w_c (q_c − q̂_c)²` to a frame's
//! objective (`W` the frame's total marker weight; [`tasks`]). Gross errors do not reach the solution: a marker sample that is not finite
//! or lies farther than 1 km from the origin counts as missing, and after the fit the marker
//! farthest from its model position is rejected and the frame re-solved while that distance
//! is both large and large against the frame's other residuals ([`IkOptions::outlier_distance`];
//! each rejection is reported). A frame whose result
//! is not finite is not solved, and the next frame starts again from seeding.
//!
//! The frames of a trial are solved in fixed chunks of consecutive frames, in parallel
//! ([`trial_chunk_ranges`](trial_fit::trial_chunk_ranges): two from 128 frames on; the first frame of each chunk is seeded), so the result does not depend
//! on the number of threads. A frame whose fit is far worse than the trial's median is then
//! solved again from its neighbours' solutions and a fresh seed, and reported not solved when
//! it stays implausible ([`repair`]). The coordinates are reported on the branch of each
//! Euler-angle triple that lies inside the model's coordinate ranges, whole turns removed
//! ([`branch`]). The fit keeps the coordinates a model marks `clamped` (OpenSim's flag)
//! inside their ranges ([`IkOptions::clamp`]); the others are not bounded.

pub(crate) mod branch;
mod composite;
#[cfg(test)]
mod frames;
pub mod hold;
pub mod lm;
use hold::hold_undetermined;
use lm::{solve_frame, IkWorkspace};
mod markers;
mod normal;
pub(crate) mod repair;
mod seed;
#[cfg(test)]
mod seed_tests;
pub(crate) mod solvable;
pub mod stream;
pub(crate) mod tasks;
#[cfg(test)]
mod tasks_tests;
pub mod trial_fit;
#[cfg(test)]
use trial_fit::chunk_ranges;
use trial_fit::TrialFit;

use thiserror::Error;

#[cfg(test)]
pub(crate) use frames::warm_started_coords;
pub(crate) use lm::is_gross;
pub(crate) use lm::undetermined_coordinate;
pub use markers::MarkerMap;
pub(crate) use seed::seed_frame;
#[cfg(test)]
use seed::seed_frame_by_scouting;
pub use tasks::CoordinateTask;
pub(crate) use trial_fit::extrapolate;
pub(crate) use trial_fit::solve_trial_alongside;

/// Why IK could not start: on a trial, or on a live feed (its set-up,
/// [`stream::StreamingIk::new`], and its frames, [`stream::StreamingIk::update`]).
#[derive(Debug, Error, PartialEq)]
pub enum IkError {
    #[error("the trial lacks model markers {missing:?}; it has: {available}")]
    MissingMarkers {
        missing: Vec<String>,
        available: String,
    },
    #[error("parameter vector has {got} values, the model has {expected} parameters")]
    ParamLength { got: usize, expected: usize },
    #[error("the feed has no marker labels")]
    NoLabels,
    #[error("the feed has the label {0:?} twice")]
    DuplicateLabel(String),
    #[error(
        "no label of the feed is a marker of the model ({model_markers} model markers); the \
         feed has: {available}"
    )]
    NoCommonMarker {
        model_markers: usize,
        available: String,
    },
    #[error("the model cannot hold its undetermined coordinates: {0}")]
    Hold(String),
    #[error("{got} marker positions for {expected} labels")]
    MarkerCount { got: usize, expected: usize },
    #[error("time {0} is not a finite number")]
    TimeNotFinite(f64),
    #[error("time {time} s does not follow the previous frame's time {previous} s")]
    TimeNotIncreasing { time: f64, previous: f64 },
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkOptions {
    pub max_iterations: usize,
    /// Stop when the distance still to go, estimated from the last two accepted steps, is
    /// below this (rad or m, largest component), or when an accepted step itself is.
    /// Gauss-Newton on noisy markers converges linearly (each step a fixed fraction `ρ` of
    /// the last, about 0.1 on gait data), so after a step `s` the steps still to come sum to
    /// about `s ρ / (1 − ρ)`; that estimate is used while `ρ ≤ 0.5` (see
    /// `lm::remaining_error`). The default, 1e-8, is far below what any marker data
    /// determines (1e-8 rad = 6e-7 deg, 1e-8 m = 1e-5 mm).
    pub step_tolerance: f64,
    /// A rotational coordinate is undetermined when 1 mm of noise on the present markers
    /// moves it by more than this standard deviation (rad; see [`solvable`]). The default,
    /// 1 rad, is the rank test's tolerance: the markers act on the coordinate through a lever
    /// arm shorter than 1 mm. (A wrist marker 17 mm from the pronation axis, 3.4° per mm,
    /// determines pronation.)
    pub max_angle_per_mm: f64,
    /// The same for a translational coordinate (m per mm of marker noise; default 1 m: the
    /// markers move less than 1 mm per metre of the coordinate).
    pub max_translation_per_mm: f64,
    /// Solve frames with undetermined coordinates by holding those at the values they enter
    /// with (the previous frame's solution in [`solve_trial`](trial_fit::solve_trial), the seed's in a seeded frame:
    /// the defaults beyond the root) instead of skipping them.
    pub hold_undetermined: bool,
    /// After the fit, a marker farther than this from its model position (m) *and* farther
    /// than [`IkOptions::outlier_ratio`] times the median distance of the frame's present
    /// markers is rejected as a gross error and the frame re-solved without it (farthest
    /// first, one at a time). The ratio keeps a model that is off everywhere (a systematic
    /// error, for the data checks) from losing its markers.
    pub outlier_distance: f64,
    /// See [`IkOptions::outlier_distance`].
    pub outlier_ratio: f64,
    /// Keep the coordinates the model marks `clamped` (OpenSim's `<clamped>true</clamped>`)
    /// inside their ranges, as OpenSim's IK does: a projected Gauss-Newton step (see
    /// `lm::hold_at_bounds`). No effect on models without clamped coordinates.
    pub clamp: bool,
}

impl IkOptions {
    /// The defaults with the two rules a front end chooses: coordinates no marker determines
    /// held at the previous frame's values (`hold_undetermined`), and gross-error rejection
    /// of markers beyond the default outlier distance (`reject_outliers`; off: every marker
    /// is kept, as OpenSim's IK keeps them).
    pub fn with_rules(hold_undetermined: bool, reject_outliers: bool) -> IkOptions {
        let d = IkOptions::default();
        IkOptions {
            hold_undetermined,
            outlier_distance: if reject_outliers {
                d.outlier_distance
            } else {
                f64::INFINITY
            },
            ..d
        }
    }
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            max_iterations: 100,
            step_tolerance: 1e-8,
            max_angle_per_mm: 1.0,
            max_translation_per_mm: 1.0,
            hold_undetermined: false,
            outlier_distance: 0.05,
            outlier_ratio: 5.0,
            clamp: true,
        }
    }
}

/// How a frame ended.
#[derive(Debug, Clone, PartialEq)]
pub enum FrameStatus {
    Converged,
    /// The iteration budget ran out (the result is the best point found).
    MaxIterations,
    /// No step lowered the cost even at damping 1e10 (the result is the best point found;
    /// not a verified minimum).
    Stalled,
    /// The present markers leave `coordinate` undetermined (the first found; see
    /// [`solvable`]): not solved.
    Undetermined {
        coordinate: String,
    },
    /// The result was not finite: not solved.
    Diverged,
    /// The fit stayed far worse than the trial's other frames from every start tried
    /// ([`repair`]): RMS marker distance `rms` against the trial's median `median` (m). Not
    /// solved: most likely a wrong local minimum or bad data.
    Implausible {
        rms: f64,
        median: f64,
    },
}

/// The outcome of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameFit {
    /// Weighted sum of squared marker errors at the solution (m²).
    pub cost: f64,
    pub iterations: usize,
    pub status: FrameStatus,
    /// Coordinates held at their entry values because the markers left them undetermined.
    pub held: Vec<usize>,
    /// Model markers whose samples were rejected as gross errors (not finite beyond the
    /// missing ones, absurdly far, or farther than the outlier distance after the fit).
    pub rejected: Vec<usize>,
}

impl FrameFit {
    pub fn solved(&self) -> bool {
        matches!(
            self.status,
            FrameStatus::Converged | FrameStatus::MaxIterations | FrameStatus::Stalled
        )
    }
}

#[cfg(test)]
pub(crate) mod clamped_tests;
#[cfg(test)]
mod parallel_tests;
#[cfg(test)]
mod robust_tests;
#[cfg(test)]
mod stream_tests;
#[cfg(test)]
pub(crate) mod tests;
