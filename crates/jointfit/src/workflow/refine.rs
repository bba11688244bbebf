//! [`calibrate_refined`]: a calibration that also fits the tracking markers' positions in
//! their segments ([`crate::model::refine`]), as [`FitSettings::refine_markers`] asks.
//!
//! The model is rewritten so that each marker the trials measure gets three position
//! parameters with a prior `N(static position, s²)`; the joint parameters `free` and these
//! marker parameters are fitted together by [`calibrate`] (same solvers, priors, σ
//! estimation, uncertainty). The result carries the rewritten model (for reports), the
//! fitted description in the input's structure (joint parameters fitted, markers moved), how
//! far every marker moved, and which marker offsets trade off with which joint parameters
//! (posterior correlations, from the uncertainty analysis when it ran).

use serde::Serialize;

use super::{calibrate, Calibration, FitSettings, Observer, WorkflowError};
use crate::model::refine::{
    fold_marker_parameters, marker_param_name, tracking_markers, with_marker_parameters,
    MARKER_GROUP,
};
use crate::model::{Model, ModelSpec, ParamId, MM_PER_M};
use crate::trial::Trial;

/// How far the fit moved one marker in its segment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RefinedMarker {
    pub name: String,
    pub segment: String,
    /// Static-trial position and fitted position in the segment frame (mm).
    pub start_mm: [f64; 3],
    pub fitted_mm: [f64; 3],
    /// Distance between the two (mm).
    pub shift_mm: f64,
}

/// A marker offset and a joint parameter whose estimates are correlated (|r| ≥ 0.5): the
/// trial cannot tell a move of one from a move of the other as well as it tells either alone.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TradeOff {
    pub marker_parameter: String,
    pub joint_parameter: String,
    pub correlation: f64,
}

/// The result of [`calibrate_refined`].
#[derive(Debug, Clone)]
pub struct RefinedCalibration {
    /// The model that was fitted: the input plus the marker position parameters (original
    /// parameter, coordinate and marker indices unchanged).
    pub model: Model,
    /// The calibration of `model` (its rows include the marker parameters, group `markers`).
    pub calibration: Calibration,
    /// The fitted description in the input's structure: fitted joint parameters (priors as
    /// in the input) and the refined marker positions.
    pub fitted: ModelSpec,
    pub markers: Vec<RefinedMarker>,
    /// Strongest first.
    pub trade_offs: Vec<TradeOff>,
}

/// Calibrates `model` like [`calibrate`], refining the positions of the markers the trials
/// measure when `settings.refine_markers` is set (prior SD in m); without it, a plain
/// calibration in the same result type. Refinement needs the priors (`settings.priors`):
/// without one, a marker position trades off exactly with the joint it hangs from.
pub fn calibrate_refined(
    model: &Model,
    start: &[f64],
    trials: &[&Trial],
    free: &[ParamId],
    settings: &FitSettings,
    observer: &mut dyn Observer,
) -> Result<RefinedCalibration, WorkflowError> {
    let Some(sd) = settings.refine_markers else {
        let calibration = calibrate(model, start, trials, free, settings, observer)?;
        let fitted = model.spec_with_nominal(&calibration.fit.p);
        return Ok(RefinedCalibration {
            model: model.clone(),
            calibration,
            fitted,
            markers: Vec::new(),
            trade_offs: Vec::new(),
        });
    };
    if !settings.priors {
        return Err(WorkflowError::RefineNeedsPriors);
    }
    let present: Vec<Vec<String>> = trials.iter().map(|t| t.labels().to_vec()).collect();
    let spec = model.spec();
    let names = tracking_markers(spec, &present);
    let aug = Model::compile(&with_marker_parameters(spec, &names, sd))
        .map_err(|e| WorkflowError::Refine(e.to_string()))?;
    let mut aug_start = aug.nominal_params();
    aug_start[..start.len()].copy_from_slice(start);
    let mut aug_free = free.to_vec();
    aug_free.extend(aug.params_in_group(MARKER_GROUP));
    let calibration = calibrate(&aug, &aug_start, trials, &aug_free, settings, observer)?;
    let p = &calibration.fit.p;
    let mut fitted = model.spec_with_nominal(&p[..start.len()]);
    fitted.markers = fold_marker_parameters(&aug.spec_with_nominal(p)).markers;
    let markers = names
        .iter()
        .filter_map(|&n| {
            let before = spec.markers.iter().find(|m| m.name == n)?;
            let after = fitted.markers.iter().find(|m| m.name == n)?;
            let mm = |x: [f64; 3]| x.map(|v| v * MM_PER_M);
            let d = (0..3)
                .map(|k| (after.position[k] - before.position[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            Some(RefinedMarker {
                name: n.to_string(),
                segment: before.segment.clone(),
                start_mm: mm(before.position),
                fitted_mm: mm(after.position),
                shift_mm: d * MM_PER_M,
            })
        })
        .collect();
    let trade_offs = trade_offs(&aug, &calibration, &names);
    Ok(RefinedCalibration {
        model: aug,
        calibration,
        fitted,
        markers,
        trade_offs,
    })
}

/// Pairs (marker offset, joint parameter) with |posterior correlation| ≥ 0.5.
fn trade_offs(model: &Model, cal: &Calibration, markers: &[&str]) -> Vec<TradeOff> {
    let Some(u) = &cal.uncertainty else {
        return Vec::new();
    };
    let is_marker: Vec<bool> = u
        .params
        .iter()
        .map(|p| {
            markers
                .iter()
                .any(|m| (0..3).any(|k| marker_param_name(m, k) == p.name))
        })
        .collect();
    let _ = model;
    let mut out = Vec::new();
    for (i, pi) in u.params.iter().enumerate() {
        if !is_marker[i] {
            continue;
        }
        for (j, pj) in u.params.iter().enumerate() {
            if is_marker[j] {
                continue;
            }
            if let Some(r) = u.corr.get(i).and_then(|row| row.get(j)).copied().flatten() {
                if r.abs() >= 0.5 {
                    out.push(TradeOff {
                        marker_parameter: pi.name.clone(),
                        joint_parameter: pj.name.clone(),
                        correlation: r,
                    });
                }
            }
        }
    }
    out.sort_by(|a, b| b.correlation.abs().total_cmp(&a.correlation.abs()));
    out
}
