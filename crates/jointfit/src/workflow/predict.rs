//! [`predict`]: before a fit, what can the trials determine?
//!
//! Inverse kinematics at the given (e.g. landmark) parameters gives each joint's range of
//! motion per axis; the reduced normal matrix there (the Fisher information of the joint
//! parameters with every frame's coordinates projected out, see
//! [`crate::calibrate::uncertainty`]) predicts each parameter's 95 % interval. The residual
//! variance at a nominal model includes its misfit, so the prediction is conservative.

use serde::Serialize;

use super::WorkflowError;
use crate::calibrate::uncertainty::CoordRange;
use crate::calibrate::uncertainty::Identifiability;
use crate::calibrate::uncertainty::Uncertainty;
use crate::calibrate::uncertainty::UncertaintyOptions;
use crate::calibrate::Problem;
use crate::model::{Model, ParamId};
use crate::trial::Trial;

/// What [`predict`] found.
#[derive(Debug, Clone, Serialize)]
pub struct Prediction {
    pub frames: usize,
    pub skipped_frames: usize,
    /// The marker RMS at the given parameters (m, [`super::marker_rms`]): `calibrate`'s RMS
    /// before the fit, and the one `ik` and `report` print.
    pub ik_rms: f64,
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
    let mut qs = prob.initial_coords(p);
    let ik_rms = super::marker_rms::start_rms(&prob, p, &mut qs);
    let prediction = crate::calibrate::uncertainty::predict(&prob, p, &qs, opts);
    let (determined, not_determined): (Vec<_>, Vec<_>) = prediction
        .params
        .iter()
        .partition(|q| q.status == Identifiability::Determined);
    Ok(Prediction {
        frames: prob.frames.len(),
        skipped_frames: prob.skipped.len(),
        ik_rms,
        ranges: prediction.ranges.clone(),
        determined: determined.iter().map(|q| q.name.clone()).collect(),
        not_determined: not_determined.iter().map(|q| q.name.clone()).collect(),
        prediction,
    })
}
