//! [`predict`]: before a fit, what can the trials determine?
//!
//! Inverse kinematics at the given (e.g. landmark) parameters gives each joint's range of
//! motion per axis; the reduced normal matrix there (the Fisher information of the joint
//! parameters with every frame's coordinates projected out, see
//! [`crate::calibrate::uncertainty`]) predicts each parameter's 95 % interval. The residual
//! variance at a nominal model includes its misfit, so the prediction is conservative.

use serde::Serialize;

use super::WorkflowError;
use crate::calibrate::uncertainty::{CoordRange, Identifiability, Uncertainty, UncertaintyOptions};
use crate::calibrate::Problem;
use crate::model::{Model, ParamId, MM_PER_M};
use crate::trial::Trial;

/// What [`predict`] found.
#[derive(Debug, Clone, Serialize)]
pub struct Prediction {
    pub frames: usize,
    pub skipped_frames: usize,
    /// RMS marker distance of IK at the given parameters (mm), over every present marker
    /// sample as the calibration weighs them: gross samples dropped, but no per-frame
    /// outlier rejection (which `ik` applies), so it equals `calibrate`'s RMS before the fit
    /// and can exceed `ik`'s RMS on the same trial.
    pub ik_rms_mm: f64,
    /// Range of motion per coordinate (deg or mm) from that IK.
    pub ranges: Vec<CoordRange>,
    /// Predicted uncertainty of the free parameters at the given values.
    pub prediction: Uncertainty,
    /// Names of the parameters the trials are predicted to determine within the thresholds.
    pub determined: Vec<String>,
    /// Names of the parameters they are predicted not to determine.
    pub not_determined: Vec<String>,
}

/// Predicts, at parameters `p`, how well `trials` determine the parameters `free`
/// (thresholds, noise assumption and estimators from `opts`; no bootstrap, which needs a fit).
pub fn predict(
    model: &Model,
    p: &[f64],
    trials: &[&Trial],
    free: &[ParamId],
    opts: &UncertaintyOptions,
) -> Result<Prediction, WorkflowError> {
    let prob = Problem::new(model, p.to_vec(), free, trials)?;
    let qs = prob.initial_coords(p);
    let prediction = crate::calibrate::uncertainty::predict(&prob, p, &qs, opts);
    let (determined, not_determined): (Vec<_>, Vec<_>) = prediction
        .params
        .iter()
        .partition(|q| q.status == Identifiability::Determined);
    Ok(Prediction {
        frames: prob.frames.len(),
        skipped_frames: prob.skipped.len(),
        ik_rms_mm: prob.marker_rms(p, &qs) * MM_PER_M,
        ranges: prediction.ranges.clone(),
        determined: determined.iter().map(|q| q.name.clone()).collect(),
        not_determined: not_determined.iter().map(|q| q.name.clone()).collect(),
        prediction,
    })
}
