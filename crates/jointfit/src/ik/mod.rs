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
//! other coordinates start at their defaults. A frame in which some segment that carries
//! markers has fewer than three of them present is reported, not guessed.

mod lm;
mod markers;
mod normal;
mod seed;
mod trial_fit;

use thiserror::Error;

pub use lm::{solve_frame, IkWorkspace};
pub use markers::MarkerMap;
pub use seed::seed_frame;
pub use trial_fit::{extrapolate, rms, solve_trial, TrialFit};

/// Why IK could not start.
#[derive(Debug, Error, PartialEq)]
pub enum IkError {
    #[error("the trial lacks model markers {missing:?}; it has: {available}")]
    MissingMarkers {
        missing: Vec<String>,
        available: String,
    },
    #[error("parameter vector has {got} values, the model has {expected} parameters")]
    ParamLength { got: usize, expected: usize },
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkOptions {
    pub max_iterations: usize,
    /// Stop when the largest accepted step component is below this (rad or m). Gauss-Newton
    /// on noisy markers converges linearly (each step a fixed fraction of the last, about
    /// 0.1 on gait data), so the remaining error is about a tenth of this. The default,
    /// 1e-8, is far below what any marker data determines (1e-8 rad = 6e-7 deg, 1e-8 m =
    /// 1e-5 mm).
    pub step_tolerance: f64,
    /// Minimum present markers on every segment that carries markers.
    pub min_markers_per_segment: usize,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            max_iterations: 100,
            step_tolerance: 1e-8,
            min_markers_per_segment: 3,
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
    /// A segment with markers had fewer than the minimum present: not solved.
    TooFewMarkers {
        segment: String,
        present: usize,
    },
}

/// The outcome of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameFit {
    /// Weighted sum of squared marker errors at the solution (m²).
    pub cost: f64,
    pub iterations: usize,
    pub status: FrameStatus,
}

impl FrameFit {
    pub fn solved(&self) -> bool {
        !matches!(self.status, FrameStatus::TooFewMarkers { .. })
    }
}
