//! [`calibrate_refined`]: a calibration that also fits the tracking markers' positions in
//! their segments ([`crate::model::refine`]), as [`FitSettings::refine_markers`] asks.
//!
//! The model is rewritten so that each marker the trials measure gets three position
//! parameters with a prior `N(static position, s²)`; the joint parameters `free` and these
//! marker parameters are fitted together by [`calibrate`](super::calibrate) (same solvers,
//! priors, σ estimation, uncertainty). The result carries the rewritten model (for reports), the
//! fitted description in the input's structure (joint parameters fitted, markers moved), how
//! far every marker moved, and which marker offsets trade off with which joint parameters
//! (posterior correlations, from the uncertainty analysis when it ran).

use serde::Serialize;

use super::calibration::{fit_keeping_system, Kept};
use super::envelope::{EnvelopeBound, HELD_AT_LIMIT};
use super::marker_policy::{decide_on, refined, robust_ik, without_excluded, MarkerDecision};
use super::{Calibration, FitSettings, Observer, WorkflowError};
use crate::calibrate::prior::Source;
use crate::model::refine::{
    fold_marker_parameters, marker_param_name, tracking_markers, with_marker_parameters,
    MARKER_GROUP,
};
use crate::model::spec::ModelSpec;
use crate::model::{Model, ParamId};
use crate::trial::Trial;

/// How far the fit moved one marker in its segment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RefinedMarker {
    pub name: String,
    pub segment: String,
    /// Static-trial position and fitted position in the segment frame (m).
    pub start: [f64; 3],
    pub fitted: [f64; 3],
    /// Distance between the two (m).
    pub shift: f64,
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
    /// parameter, coordinate and marker indices unchanged) and the envelope's bounds.
    pub model: Model,
    /// The calibration of `model` (its rows include the marker parameters, group `markers`).
    pub calibration: Calibration,
    /// The fitted description in the input's structure: fitted joint parameters (priors and
    /// bounds as in the input) and the refined marker positions.
    pub fitted: ModelSpec,
    pub markers: Vec<RefinedMarker>,
    /// Strongest first.
    pub trade_offs: Vec<TradeOff>,
    /// The anatomical envelope's bounds ([`super::envelope`]), each marked active when the
    /// fit ended on it.
    pub envelope: Vec<EnvelopeBound>,
    /// The marker policy's decisions ([`super::marker_policy`]).
    pub marker_decisions: Vec<MarkerDecision>,
    /// Each joint's prior–data conflict and whether its intervals were widened
    /// ([`super::conflict`]); empty without a prior or with `prior_conflict` off.
    pub conflict: Vec<super::conflict::JointConflict>,
    /// Joints the trials barely move, held at their start ([`super::motion_range`]).
    pub held_joints: Vec<super::motion_range::HeldJoint>,
}

/// Calibrates `model` like [`calibrate`](super::calibrate), and, for a maximum a posteriori
/// fit (the settings ask for priors and a free parameter has one):
///
/// * with `settings.anatomical_envelope`, bounds the hip centre medial to the ASIS
///   ([`super::envelope`]);
/// * with `settings.marker_policy`, refines the markers displaced since the static trial and
///   leaves broken ones out ([`super::marker_policy`]; `settings.keep_markers` are left as
///   they are);
/// * with `settings.refine_markers` (prior SD in m), refines every marker the trials measure
///   (a displaced one with the larger of that SD and the policy's).
///
/// Without any of these, a plain calibration in the same result type. Refinement needs the
/// priors (`settings.priors`): without one, a marker position trades off exactly with the
/// joint it hangs from.
pub fn calibrate_refined(
    model: &Model,
    start: &[f64],
    trials: &[&Trial],
    free: &[ParamId],
    settings: &FitSettings,
    observer: &mut dyn Observer,
) -> Result<RefinedCalibration, WorkflowError> {
    if settings.refine_markers.is_some() && !settings.priors {
        return Err(WorkflowError::RefineNeedsPriors);
    }
    let mismatches = super::verdict::check_inputs(model, trials, settings.refuse_mismatch)?;
    let prep = prepare(model, start, trials, free, settings)?;
    let (free, decisions, map_fit) = (prep.free.as_slice(), prep.decisions, prep.map_fit);
    let used = without_excluded(trials, &decisions);
    let used: Vec<&Trial> = used.iter().collect();
    let to_refine = markers_to_refine(model, &decisions, &used, settings.refine_markers);
    let mut aug = with_refined_markers(model, &to_refine)?;
    let mut aug_start = aug.nominal_params();
    aug_start[..start.len()].copy_from_slice(start);
    let mut aug_free = free.to_vec();
    aug_free.extend(aug.params_in_group(MARKER_GROUP));
    let seed = prep
        .seed
        .as_deref()
        .filter(|_| decisions.is_empty() && to_refine.is_empty());
    // The analysis runs once, on the final fit, with the conflict step's widened prior.
    let first = fit_keeping_system(&aug, &aug_start, &used, &aug_free, settings, seed, observer)?;
    // A joint whose prior the trial contradicts (`super::conflict`): tested on the fit
    // before any envelope bound (on its problem), its intervals widened on the final fit below.
    let mut conflict = Vec::new();
    if map_fit && settings.prior_conflict {
        conflict =
            super::conflict::assess(&first.problem, &first.calibration, first.system.as_ref())?;
    }
    let mut envelope = Vec::new();
    let bounded = match map_fit && settings.anatomical_envelope {
        true => envelope_model(&aug, &aug_start, &first.calibration.fit.p, &mut envelope)?,
        false => None,
    };
    // The bounded model sets other parameter scales (its bounds), so its refit solves a
    // problem of its own.
    let refit = match &bounded {
        Some(model) => {
            let kept = fit_keeping_system(
                model, &aug_start, &used, &aug_free, settings, None, observer,
            )?;
            super::envelope::mark_active(&mut envelope, model, &kept.calibration.fit.p);
            Some(kept)
        }
        None => None,
    };
    let Kept {
        mut calibration,
        system,
        problem,
    } = refit.unwrap_or(first);
    super::conflict::analyze_widened(
        &problem,
        settings,
        &mut calibration,
        &conflict,
        system,
        observer,
    );
    drop(problem);
    if let Some(model) = bounded {
        aug = model;
    }
    let p = calibration.fit.p.clone();
    note_envelope(&mut calibration, &envelope);
    let mut fitted = model.spec_with_nominal(&p[..start.len()]);
    fitted.markers = fold_marker_parameters(&aug.spec_with_nominal(&p)).markers;
    let markers = refined_markers(model.spec(), &fitted, &to_refine);
    let names: Vec<&str> = to_refine.iter().map(|r| r.0).collect();
    let trade_offs = trade_offs(&aug, &calibration, &names);
    let evidence = super::verdict::Evidence {
        mismatches: &mismatches,
        refined: &markers,
        decisions: &decisions,
        conflict: &conflict,
        envelope: &envelope,
        held: &prep.held_joints,
    };
    calibration.verdict = super::verdict::judge(&aug, &calibration, &evidence);
    Ok(RefinedCalibration {
        model: aug,
        calibration,
        fitted,
        markers,
        trade_offs,
        envelope,
        marker_decisions: decisions,
        conflict,
        held_joints: prep.held_joints,
    })
}

/// What is decided before the fit: the free parameters left once the still joints are held
/// (with those joints and the coordinates their inverse kinematics found at the start),
/// whether the fit is a maximum a posteriori one, and the marker policy's decisions.
struct Prepared {
    free: Vec<ParamId>,
    held_joints: Vec<super::motion_range::HeldJoint>,
    seed: Option<Vec<Vec<f64>>>,
    map_fit: bool,
    decisions: Vec<MarkerDecision>,
}

/// The still joints held ([`super::motion_range`]) and the marker policy's decisions
/// ([`super::marker_policy`]); the policy's robust inverse kinematics at the start also
/// starts the motion ranges' one.
fn prepare(
    model: &Model,
    start: &[f64],
    trials: &[&Trial],
    free: &[ParamId],
    settings: &FitSettings,
) -> Result<Prepared, WorkflowError> {
    let with_prior = |free: &[ParamId]| {
        settings.priors
            && free
                .iter()
                .any(|id| model.parameters()[id.0].prior_sd.is_some())
    };
    let looked = match with_prior(free) && settings.marker_policy {
        true => robust_ik(model, start, trials),
        false => Vec::new(),
    };
    let near = |t: usize, f: usize| looked.get(t)?.as_ref()?.coords(f);
    // The motion ranges and the marker decisions read the same robust inverse kinematics and
    // not each other: side by side. The decisions count only for a MAP fit, which holding
    // still joints can only turn off (fewer free parameters).
    let policy = with_prior(free) && settings.marker_policy;
    let (held, decisions) = rayon::join(
        || super::motion_range::hold_still_joints(model, start, trials, free, &near),
        || match policy {
            true => decide_on(model, start, trials, &settings.keep_markers, &looked),
            false => Vec::new(),
        },
    );
    let (free, held_joints, seed) = held?;
    let map_fit = with_prior(&free);
    let decisions = match map_fit && settings.marker_policy {
        true => decisions,
        false => Vec::new(),
    };
    Ok(Prepared {
        free,
        held_joints,
        seed,
        map_fit,
        decisions,
    })
}

/// The markers to refine with their prior SDs (m): the policy's, or with `refine_all` every
/// marker the `used` trials measure (a displaced one with the larger of the two SDs).
fn markers_to_refine<'a>(
    model: &'a Model,
    decisions: &'a [MarkerDecision],
    used: &[&Trial],
    refine_all: Option<f64>,
) -> Vec<(&'a str, f64)> {
    let policy = refined(decisions);
    let Some(sd) = refine_all else {
        return policy;
    };
    let present: Vec<Vec<String>> = used.iter().map(|t| t.labels().to_vec()).collect();
    tracking_markers(model.spec(), &present)
        .into_iter()
        .map(|n| {
            let own = policy.iter().find(|(m, _)| *m == n).map_or(0.0, |p| p.1);
            (n, sd.max(own))
        })
        .collect()
}

/// `model` with the positions of the markers `to_refine` as parameters (one call per prior
/// SD, in the order of the markers: the parameters' order); `model` itself without any.
fn with_refined_markers(model: &Model, to_refine: &[(&str, f64)]) -> Result<Model, WorkflowError> {
    if to_refine.is_empty() {
        return Ok(model.clone());
    }
    let mut spec = model.spec().clone();
    let mut sds: Vec<f64> = to_refine.iter().map(|r| r.1).collect();
    sds.sort_by(f64::total_cmp);
    sds.dedup();
    for sd in sds {
        let names: Vec<&str> = to_refine
            .iter()
            .filter(|r| r.1 == sd)
            .map(|r| r.0)
            .collect();
        spec = with_marker_parameters(&spec, &names, sd);
    }
    Model::compile(&spec).map_err(|e| WorkflowError::Refine(e.to_string()))
}

/// The envelope: a fit `p` of `aug` (from `start`) inside it is the bounded problem's
/// optimum too (`None`); one outside is refitted with the bound, on the bounded model
/// returned (`super::envelope`: bounding every fit would change the parameters' scaling, and
/// with it the σ estimate, where the bound is never reached). The bounds, with the unbounded
/// fit of each, go to `envelope`; the caller marks them active after the refit.
fn envelope_model(
    aug: &Model,
    start: &[f64],
    p: &[f64],
    envelope: &mut Vec<EnvelopeBound>,
) -> Result<Option<Model>, WorkflowError> {
    let Some((bounded, mut bounds)) = super::envelope::bounded_spec(aug, start) else {
        return Ok(None);
    };
    let outside = bounds.iter().any(|b| {
        aug.param_id(&b.parameter)
            .is_some_and(|id| p[id.0] > b.limit)
    });
    let model = if outside {
        for b in bounds.iter_mut() {
            b.unbounded_fit = aug
                .param_id(&b.parameter)
                .map(|id| p[id.0])
                .filter(|&x| x > b.limit);
        }
        Some(Model::compile(&bounded).map_err(|e| WorkflowError::Refine(e.to_string()))?)
    } else {
        None
    };
    *envelope = bounds;
    Ok(model)
}

/// Each refined marker's position in its segment before and after the fit.
fn refined_markers(
    spec: &ModelSpec,
    fitted: &ModelSpec,
    to_refine: &[(&str, f64)],
) -> Vec<RefinedMarker> {
    to_refine
        .iter()
        .filter_map(|&(n, _)| {
            let before = spec.markers.iter().find(|m| m.name == n)?;
            let after = fitted.markers.iter().find(|m| m.name == n)?;
            let d = (0..3)
                .map(|k| (after.position[k] - before.position[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            Some(RefinedMarker {
                name: n.to_string(),
                segment: before.segment.clone(),
                start: before.position,
                fitted: after.position,
                shift: d,
            })
        })
        .collect()
}

/// A parameter held on an active envelope bound: its information class says so (the limit,
/// not the trial, decided it), and so does the plausibility check of the hip's lateral
/// offset.
fn note_envelope(cal: &mut Calibration, envelope: &[EnvelopeBound]) {
    for b in envelope.iter().filter(|b| b.active) {
        if let Some(row) = cal.parameters.iter_mut().find(|r| r.name == b.parameter) {
            row.source = Some(Source::HeldAtLimit);
        }
        for c in cal.plausibility.iter_mut() {
            if c.parameters.len() == 1 && c.parameters[0] == b.parameter {
                c.check = format!("{} ({HELD_AT_LIMIT})", c.check);
            }
        }
    }
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
