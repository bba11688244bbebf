//! Coordinate tasks: OpenSim's `IKCoordinateTask` as a term of the inverse-kinematics
//! objective.
//!
//! OpenSim's IK (Simbody's `Assembler`, via `InverseKinematicsSolver`) minimises, frame by
//! frame, the sum of its goals: the marker goal `Σ_j w_j ‖x_j − m_j‖² / (2 Σ_j w_j)` (sums
//! over the markers present in the frame; Simbody `Markers::calcGoal`) and, per coordinate
//! task, `w_c (q_c − q̂_c)² / 2` (Simbody `QValue::calcGoal`, the task's weight as the goal
//! weight). Multiplied by `2 W` with `W = Σ_j w_j`, that is the objective jointfit's frames
//! minimise:
//!
//! `Σ_j w_j ‖x_j − m_j‖² + W Σ_c w_c (q_c − q̂_c)²`,
//!
//! the same minimiser, and the same cost as without tasks when there are none. A task's
//! target `q̂_c` may change from frame to frame (OpenSim's `from_file` tasks); a frame whose
//! target is not finite has no task for that coordinate.

/// One coordinate task over a trial.
#[derive(Debug, Clone, PartialEq)]
pub struct CoordinateTask {
    /// Index into [`crate::model::Model::coordinates`].
    pub coordinate: usize,
    /// The task's weight `w_c` (OpenSim's `<weight>`; relative to the marker weights as
    /// stated in the module docs). A task of weight 0 has no effect.
    pub weight: f64,
    /// The target `q̂_c` in every frame of the trial (rad or m; NaN: no task in that frame).
    pub values: Vec<f64>,
}

/// The tasks that act in frame `frame`: `(coordinate, weight, target)` in `goals`, and
/// `known[c]` set for their coordinates (which a task determines, whatever the markers do).
pub(super) fn frame_goals(
    tasks: &[CoordinateTask],
    frame: usize,
    goals: &mut Vec<(usize, f64, f64)>,
    known: &mut [bool],
) {
    goals.clear();
    known.iter_mut().for_each(|k| *k = false);
    for t in tasks {
        let v = t.values.get(frame).copied().unwrap_or(f64::NAN);
        if t.weight > 0.0 && v.is_finite() {
            goals.push((t.coordinate, t.weight, v));
            known[t.coordinate] = true;
        }
    }
}

/// `W Σ_c w_c (q_c − q̂_c)²` for the goals `(c, w_c, q̂_c)` and total marker weight `total`.
pub(super) fn goal_cost(q: &[f64], goals: &[(usize, f64, f64)], total: f64) -> f64 {
    goals
        .iter()
        .map(|&(c, w, v)| total * w * (q[c] - v).powi(2))
        .sum()
}
