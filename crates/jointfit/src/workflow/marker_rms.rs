//! The one marker RMS every command prints ([`marker_rms`]): `docs/marker_rms.md`.
//!
//! For a model at parameters `p` and trials `T`:
//!
//! ```text
//! RMS(p) = sqrt( Σ_{i ∈ frames} Σ_{j ∈ present(i)} ‖m_ij − x_j(p, q_i)‖² / N )
//! ```
//!
//! over every frame the calibration fits (frames whose markers leave a coordinate
//! undetermined are skipped) and every model marker present in that frame (gross samples
//! dropped, as the calibration drops them; a marker the trial lacks is absent everywhere),
//! `N` the number of such samples, and `q_i` the inverse kinematics of frame `i` at `p` with
//! the calibration's inner-level options and tolerance (every present marker counts, no per-frame outlier
//! rejection). Before a fit it is `calibrate`'s "before" RMS; `check`, `ik` and `report`
//! print the same number for the same model and trial. It is not the mean of the per-frame
//! RMS (which `ik` also prints, labelled as such): a frame with few markers weighs less here.

use super::WorkflowError;
use crate::calibrate::Problem;
use crate::model::{Model, ParamId};
use crate::trial::Trial;

/// [`marker_rms`]'s result.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerRms {
    /// The RMS (m; NaN when no marker sample is present).
    pub rms: f64,
    /// The inner objective `e_inner(p)` at the same coordinates: the sum over those samples
    /// of the weighted squared marker distances (m²).
    pub cost: f64,
    /// Frames it is taken over, and frames skipped as undetermined.
    pub frames: usize,
    pub skipped_frames: usize,
}

/// The marker RMS of `model` at `p` on `trials` (module docs), the inner objective and the
/// frames.
pub fn marker_rms(model: &Model, p: &[f64], trials: &[&Trial]) -> Result<MarkerRms, WorkflowError> {
    if model.parameters().is_empty() {
        return Err(WorkflowError::Refine(format!(
            "{}: the marker RMS needs a model with joint parameters",
            model.name()
        )));
    }
    // The problem's frames and samples do not depend on which parameters are free.
    let prob = Problem::new(model, p.to_vec(), &[ParamId(0)], trials)?;
    let mut qs = prob.initial_coords(p);
    let cost = prob.inner(p, &mut qs, &mut crate::ik::lm::IkWorkspace::new(model));
    Ok(MarkerRms {
        rms: prob.marker_rms(p, &qs),
        cost,
        frames: prob.frames.len(),
        skipped_frames: prob.skipped.len(),
    })
}

/// The marker RMS (m) of `prob`'s frames at `p`, from their seeded coordinates `qs`
/// ([`Problem::initial_coords`]), which one more inner pass polishes in place: the
/// coordinates a calibration starts from.
pub(crate) fn start_rms(prob: &Problem, p: &[f64], qs: &mut [Vec<f64>]) -> f64 {
    prob.inner(p, qs, &mut crate::ik::lm::IkWorkspace::new(prob.model));
    prob.marker_rms(p, qs)
}
