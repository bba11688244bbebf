//! Fills a [`ReportInput`] from a model, its fitted and baseline parameters and the trials:
//! inverse kinematics of every trial with each parameter vector ([`jointfit::ik::solve_trial`],
//! warm-started frame to frame), per-frame and per-marker RMS marker distances, the fitted
//! model's coordinates over time, and the parameter table. Model markers a trial lacks count
//! as missing in every frame of it (noted on the page), as they do in the fit.

use jointfit::ik::{rms, solve_trial, IkOptions, MarkerMap, TrialFit};
use jointfit::model::{CoordKind, Model};
use jointfit::trial::Trial;

use crate::data::{CoordSeries, MarkerRms, ParamRow, ReportInput, TrialSeries};
use crate::ReportError;

use jointfit::model::MM_PER_M as MM;

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
/// per trial and parameter vector).
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
    let mut fitted_err: Vec<Vec<f64>> = vec![Vec::new(); model.n_markers()];
    let mut base_err: Vec<Vec<f64>> = vec![Vec::new(); model.n_markers()];
    for (name, trial) in trials {
        // Model markers the trial lacks count as missing in every frame, as in the fit
        // (`calibrate` on a trial without the static-only markers), and are said in a note.
        let (map, absent) = MarkerMap::allowing_absent(model, trial.labels());
        if absent.len() == model.n_markers() {
            return Err(ReportError::Trial {
                trial: name.clone(),
                message: format!(
                    "no label of the trial names a model marker (the model's are {})",
                    model
                        .markers()
                        .iter()
                        .map(|m| m.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            });
        }
        if !absent.is_empty() {
            input.notes.push(format!(
                "{name}: the trial lacks model markers {}; they count as missing in every \
                 frame.",
                absent.join(", ")
            ));
        }
        let solve = |p: &[f64]| {
            solve_trial(model, p, trial, &map, ik).map_err(|e| ReportError::Trial {
                trial: name.clone(),
                message: e.to_string(),
            })
        };
        let fit = solve(fitted)?;
        done += 1;
        progress(done, passes);
        let base = baseline.map(solve).transpose()?;
        if base.is_some() {
            done += 1;
            progress(done, passes);
        }
        let per_frame = |f: &TrialFit| -> Vec<f64> {
            (0..f.frames.len()).map(|i| f.frame_rms(i) * MM).collect()
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
                let joint = &model.joints()[coord.joint.0];
                CoordSeries {
                    name: coord.name.clone(),
                    joint: joint.name.clone(),
                    root: joint.parent.is_none(),
                    unit: unit.to_string(),
                    fitted: series(&fit),
                    baseline: base.as_ref().map(series),
                }
            })
            .collect();
        let unsolved = fit.frames.iter().filter(|f| !f.solved()).count();
        if unsolved > 0 {
            input.notes.push(format!(
                "{name}: {unsolved} of {} frames could not be solved with the fitted model \
                 (their markers left a coordinate undetermined); they are gaps in the figures.",
                fit.frames.len()
            ));
        }
        for errs in &fit.errors {
            for (j, e) in errs.iter().enumerate() {
                fitted_err[j].push(*e);
            }
        }
        if let Some(b) = &base {
            for errs in &b.errors {
                for (j, e) in errs.iter().enumerate() {
                    base_err[j].push(*e);
                }
            }
        }
        input.trials.push(TrialSeries {
            name: name.clone(),
            time: (0..trial.n_frames()).map(|f| trial.time(f)).collect(),
            baseline_rms_mm: base.as_ref().map(per_frame),
            fitted_rms_mm: per_frame(&fit),
            coords,
            unsolved_frames: unsolved,
        });
    }
    input.markers = model
        .markers()
        .iter()
        .enumerate()
        .map(|(j, m)| MarkerRms {
            name: m.name.clone(),
            baseline_mm: baseline.map(|_| rms(base_err[j].iter().copied()) * MM),
            fitted_mm: rms(fitted_err[j].iter().copied()) * MM,
        })
        .collect();
    input.overall_rms_mm = (
        baseline.map(|_| rms(base_err.iter().flatten().copied()) * MM),
        rms(fitted_err.iter().flatten().copied()) * MM,
    );
    Ok(())
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
            let (unit, k) = (par.unit.display_suffix(), par.unit.display_scale());
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
