//! Fills a [`ReportInput`] from a model, its fitted and baseline parameters and the trials:
//! inverse kinematics of every trial with each parameter vector ([`jointfit::ik::trial_fit::solve_trial`],
//! warm-started frame to frame), per-frame and per-marker RMS marker distances, the overall
//! marker RMS every command prints ([`jointfit::workflow::marker_rms::marker_rms`]), the fitted
//! model's coordinates over time, and the parameter table. Model markers a trial lacks count
//! as missing in every frame of it (noted on the page), as they do in the fit.

use jointfit::ik::trial_fit::rms;
use jointfit::ik::trial_fit::solve_trial;
use jointfit::ik::trial_fit::TrialFit;
use jointfit::ik::{IkOptions, MarkerMap};
use jointfit::model::{CoordKind, Model};
use jointfit::trial::Trial;

use crate::data::{CoordSeries, MarkerRms, ParamRow, ReportInput, TrialSeries};
use crate::ReportError;

use jointfit_app::present::{unit_name, unit_scale, MM_PER_M as MM};

/// Inverse kinematics of every trial with the fitted (and baseline) parameters; sets
/// `trials`, `markers`, `overall_rms_mm` and `notes` of `input`.
///
/// `trials` pairs a display name (the file name) with the trial, already in the model's
/// frame (Y up) and filtered as the fit was.
pub fn analyze(
    input: &mut ReportInput,
    model: &Model,
    fitted: &[f64],
    baseline: Option<&[f64]>,
    trials: &[(String, &Trial)],
    ik: &IkOptions,
) -> Result<(), ReportError> {
    analyze_with_progress(input, model, fitted, baseline, trials, ik, &mut |_, _| {})
}

/// [`analyze`] that calls `progress(done, total)` after each inverse-kinematics pass (one
/// per trial and parameter vector). The overall RMS is the one every command prints
/// ([`jointfit::workflow::marker_rms::marker_rms`]); the per-frame and per-marker figures come from the
/// report's own inverse kinematics (`ik`).
pub fn analyze_with_progress(
    input: &mut ReportInput,
    model: &Model,
    fitted: &[f64],
    baseline: Option<&[f64]>,
    trials: &[(String, &Trial)],
    ik: &IkOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(), ReportError> {
    let passes = trials.len() * (1 + baseline.is_some() as usize);
    let mut done = 0;
    let mut errors = MarkerErrors::new(model.markers().len());
    for (name, trial) in trials {
        let map = trial_map(input, model, name, trial)?;
        let solve =
            |p: &[f64]| solve_trial(model, p, trial, &map, ik).map_err(|e| trial_error(name, e));
        let fit = solve(fitted)?;
        done += 1;
        progress(done, passes);
        let base = baseline.map(solve).transpose()?;
        if base.is_some() {
            done += 1;
            progress(done, passes);
        }
        errors.add(&fit, base.as_ref());
        let series = trial_series(model, name, trial, &fit, base.as_ref());
        if series.unsolved_frames > 0 {
            input.notes.push(format!(
                "{name}: {} of {} frames could not be solved with the fitted model \
                 (their markers left a coordinate undetermined); they are gaps in the figures.",
                series.unsolved_frames,
                fit.frames.len()
            ));
        }
        input.trials.push(series);
    }
    input.markers = errors.per_marker(model, baseline.is_some());
    let all: Vec<&Trial> = trials.iter().map(|(_, t)| *t).collect();
    // A model without joint parameters (an .osim read as it is) has no calibration and so no
    // RMS of that definition: the RMS of the report's own inverse kinematics instead.
    let overall = |p: &[f64], own: &[Vec<f64>]| match model.parameters().len() {
        0 => rms(own.iter().flatten().copied()) * MM,
        _ => jointfit::workflow::marker_rms::marker_rms(model, p, &all)
            .map_or(f64::NAN, |r| jointfit_app::present::mm(r.rms)),
    };
    input.overall_rms_mm = (
        baseline.map(|b| overall(b, &errors.baseline)),
        overall(fitted, &errors.fitted),
    );
    Ok(())
}

fn trial_error(name: &str, e: impl std::fmt::Display) -> ReportError {
    ReportError::Trial {
        trial: name.to_string(),
        message: e.to_string(),
    }
}

/// The trial's columns for the model's markers. Model markers the trial lacks count as
/// missing in every frame, as in the fit (`calibrate` on a trial without the static-only
/// markers), and are said in a note; a trial that names none of them is refused.
fn trial_map(
    input: &mut ReportInput,
    model: &Model,
    name: &str,
    trial: &Trial,
) -> Result<MarkerMap, ReportError> {
    let (map, absent) = MarkerMap::allowing_absent(model, trial.labels());
    if absent.len() == model.markers().len() {
        let names: Vec<&str> = model.markers().iter().map(|m| m.name.as_str()).collect();
        return Err(trial_error(
            name,
            format!(
                "no label of the trial names a model marker (the model's are {})",
                names.join(", ")
            ),
        ));
    }
    if !absent.is_empty() {
        input.notes.push(format!(
            "{name}: the trial lacks model markers {}; they count as missing in every \
             frame.",
            absent.join(", ")
        ));
    }
    Ok(map)
}

/// One trial's figures: per-frame RMS and every coordinate over time (deg or mm).
fn trial_series(
    model: &Model,
    name: &str,
    trial: &Trial,
    fit: &TrialFit,
    base: Option<&TrialFit>,
) -> TrialSeries {
    let per_frame = |f: &TrialFit| -> Vec<f64> {
        (0..f.frames.len())
            .map(|i| rms(f.errors[i].iter().copied()) * MM)
            .collect()
    };
    let coords = model
        .coordinates()
        .iter()
        .enumerate()
        .map(|(c, coord)| {
            let (unit, k) = match coord.kind {
                CoordKind::Rotational => ("deg", 180.0 / std::f64::consts::PI),
                CoordKind::Translational => ("mm", MM),
            };
            let series = |f: &TrialFit| f.coords.iter().map(|q| q[c] * k).collect();
            let joint = &model.joints()[coord.joint];
            CoordSeries {
                name: coord.name.clone(),
                joint: joint.name.clone(),
                root: joint.parent.is_none(),
                unit: unit.to_string(),
                fitted: series(fit),
                baseline: base.map(series),
            }
        })
        .collect();
    TrialSeries {
        name: name.to_string(),
        time: (0..trial.n_frames()).map(|f| trial.time(f)).collect(),
        baseline_rms_mm: base.map(per_frame),
        fitted_rms_mm: per_frame(fit),
        coords,
        unsolved_frames: fit.frames.iter().filter(|f| !f.solved()).count(),
    }
}

/// Every trial's marker distances per model marker (m), fitted and baseline.
struct MarkerErrors {
    fitted: Vec<Vec<f64>>,
    baseline: Vec<Vec<f64>>,
}

impl MarkerErrors {
    fn new(n_markers: usize) -> Self {
        MarkerErrors {
            fitted: vec![Vec::new(); n_markers],
            baseline: vec![Vec::new(); n_markers],
        }
    }

    fn add(&mut self, fit: &TrialFit, base: Option<&TrialFit>) {
        let push = |to: &mut Vec<Vec<f64>>, f: &TrialFit| {
            for errs in &f.errors {
                for (j, e) in errs.iter().enumerate() {
                    to[j].push(*e);
                }
            }
        };
        push(&mut self.fitted, fit);
        if let Some(b) = base {
            push(&mut self.baseline, b);
        }
    }

    fn per_marker(&self, model: &Model, baseline: bool) -> Vec<MarkerRms> {
        model
            .markers()
            .iter()
            .enumerate()
            .map(|(j, m)| MarkerRms {
                name: m.name.clone(),
                baseline_mm: baseline.then(|| rms(self.baseline[j].iter().copied()) * MM),
                fitted_mm: rms(self.fitted[j].iter().copied()) * MM,
            })
            .collect()
    }
}

/// The parameter table in display units (mm, degrees). `free` lists the indices the
/// calibration was allowed to change (`None` when not known).
pub fn parameter_rows(
    model: &Model,
    fitted: &[f64],
    baseline: Option<&[f64]>,
    free: Option<&[usize]>,
) -> Vec<ParamRow> {
    model
        .parameters()
        .iter()
        .enumerate()
        .map(|(i, par)| {
            let (unit, k) = (unit_name(par.unit), unit_scale(par.unit));
            ParamRow {
                name: par.name.clone(),
                group: par.group.clone(),
                unit: unit.to_string(),
                baseline: baseline.map(|b| b[i] * k),
                fitted: fitted[i] * k,
                lower: par.lower * k,
                upper: par.upper * k,
                free: free.map(|f| f.contains(&i)),
                interval: None,
            }
        })
        .collect()
}
