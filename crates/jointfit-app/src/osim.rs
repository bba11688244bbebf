//! The fit of a user's OpenSim model, the pipeline's fit stage for an `.osim` (the command
//! line's `calibrate MODEL.osim`, Python's `jointfit.calibrate` on an `.osim`, a batch job):
//! selection → parameterized model ([`jointfit_io::osim_read::personalize::parameterize`]) → calibration
//! with the redundant offset directions held
//! ([`jointfit::workflow::redundant::calibrate_holding_redundant`]) → the user's file with the fitted
//! offsets written back ([`jointfit_io::osim_read::personalize::fitted_text`]).
//!
//! Every selected offset scalar is free, except those the trials cannot tell from others
//! (held at the file's value and listed). The default prior of each offset scalar
//! (`docs/priors.md`) applies when `settings.priors` is set: the maximum a posteriori fit;
//! without it, Reinbolt et al.'s (2005) unregularized least squares.

use jointfit::model::spec::ModelSpec;
use jointfit::model::{Model, ModelError, ParamId};
use jointfit::solver::Observer;
use jointfit::trial::Trial;
use jointfit::workflow::redundant::calibrate_holding_redundant;
use jointfit::workflow::redundant::HeldCalibration;
use jointfit::workflow::{FitSettings, WorkflowError};
use thiserror::Error;

use jointfit_io::osim_read::personalize::{fitted_text, parameterize, SelectionError};
use jointfit_io::osim_read::{OsimModel, WriteBackError};

#[derive(Debug, Error)]
pub enum OsimFitError {
    #[error(transparent)]
    Selection(#[from] SelectionError),
    #[error("the personalized model is invalid: {0}")]
    Model(#[from] ModelError),
    #[error(transparent)]
    Workflow(#[from] WorkflowError),
    #[error("writing the fitted offsets back: {0}")]
    WriteBack(#[from] WriteBackError),
}

/// The selected offsets as parameters: `joints` (whole joints) and `params` (the finer
/// selection, [`jointfit_io::osim_read::personalize`]'s syntax) together, in that order.
pub fn selection_spec(
    osim: &OsimModel,
    joints: &[String],
    params: &[String],
) -> Result<ModelSpec, SelectionError> {
    let items: Vec<&str> = joints
        .iter()
        .chain(params)
        .map(|s| s.trim())
        .filter(|s| !s.is_empty())
        .collect();
    parameterize(osim, &items)
}

/// A finished personalization.
#[derive(Debug, Clone)]
pub struct OsimFit {
    /// The parameterized description as given (every marker, no coordinate locked).
    pub spec: ModelSpec,
    /// The compiled model of the fit (without the absent markers, with the undetermined
    /// coordinates locked); its nominal values are the file's.
    pub model: Model,
    /// The calibration and the parameters held as redundant.
    pub result: HeldCalibration,
    /// Markers of the model some trial lacks: left out of the fit (OpenSim's IK likewise
    /// uses only the markers a trial has).
    pub absent_markers: Vec<String>,
    /// Coordinates the trials' markers cannot determine (e.g. `mtp_angle_r` without toe
    /// markers), held at their default values for the fit ([`jointfit::ik::hold::hold_undetermined`]).
    pub held_coordinates: Vec<String>,
}

impl OsimFit {
    /// Every parameter's fitted value (held and fixed ones at their start), SI.
    pub fn params(&self) -> &[f64] {
        &self.result.calibration.fit.p
    }

    /// The given description at the fitted values (nominal = fitted; priors stay centred on
    /// the file's values, as [`Model::spec_with_nominal`] writes them).
    pub fn fitted_spec(&self) -> ModelSpec {
        let mut spec = self.spec.clone();
        for (ps, &v) in spec.parameters.iter_mut().zip(self.params()) {
            if ps.prior_sd.is_some() && ps.prior_mean.is_none() {
                ps.prior_mean = Some(ps.nominal);
            }
            ps.nominal = v;
        }
        spec
    }

    /// The user's file with only the fitted offsets replaced.
    pub fn osim_text(&self, osim: &OsimModel) -> Result<String, WriteBackError> {
        fitted_text(osim, self.model.spec(), self.params())
    }
}

/// Personalizes every parameter of `spec` (made by [`selection_spec`] or
/// [`parameterize`], maybe with edited priors) on `trials`, from `start` (default: the file's
/// values), as `settings` say. Model markers that any trial lacks are left out of the fit
/// (listed in [`OsimFit::absent_markers`]); they stay in the written file.
pub fn personalize(
    spec: &ModelSpec,
    start: Option<Vec<f64>>,
    trials: &[&Trial],
    settings: &FitSettings,
    observer: &mut dyn Observer,
) -> Result<OsimFit, OsimFitError> {
    let given = spec.clone();
    let mut spec = spec.clone();
    let absent_markers: Vec<String> = spec
        .markers
        .iter()
        .filter(|m| !trials.iter().all(|t| t.labels().contains(&m.name)))
        .map(|m| m.name.clone())
        .collect();
    if absent_markers.len() < spec.markers.len() {
        spec.markers.retain(|m| !absent_markers.contains(&m.name));
    }
    let model = Model::compile(&spec)?;
    let (held, held_coordinates) = jointfit::ik::hold::hold_undetermined(&model, trials)?;
    let model = held.unwrap_or(model);
    let start = start.unwrap_or_else(|| model.nominal_params());
    let free: Vec<ParamId> = (0..model.parameters().len()).map(ParamId).collect();
    let result = calibrate_holding_redundant(&model, &start, trials, &free, settings, observer)?;
    Ok(OsimFit {
        spec: given,
        model,
        result,
        absent_markers,
        held_coordinates,
    })
}
