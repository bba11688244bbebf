//! The report of a finished calibration, built from a [`Calibration`] and where it came
//! from ([`Provenance`]), whatever front end ran it.

use jointfit::ik::IkOptions;
use jointfit::model::Model;
use jointfit::trial::Trial;
use jointfit::workflow::calibration::Calibration;
use jointfit::workflow::Method;
use jointfit_app::present::CalibrationShown;

use crate::analyze::{analyze_with_progress, parameter_rows};
use crate::{Convergence, Interval, ReportError, ReportInput};

/// Where a calibration came from: shown in the report's settings table.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Provenance {
    /// The command (or call) that ran it.
    pub command_line: String,
    /// Input files and options, in order, e.g. `("subject model", "s1.toml")`.
    pub inputs: Vec<(String, String)>,
    pub version: String,
    /// When it ran, e.g. from [`crate::utc_now`].
    pub date: String,
}

/// What the random seed did in this calibration (the swarm, the extra starts, the
/// bootstrap), e.g. `7 (extra starts 2-3)`; "not used" only when nothing random ran.
pub fn seed_use(cal: &Calibration) -> String {
    let mut uses = Vec::new();
    if cal.method == Method::Pso {
        uses.push("particle swarm".to_string());
    }
    if cal.start_runs.len() > 1 {
        uses.push(format!("extra starts 2-{}", cal.start_runs.len()));
    }
    if cal
        .uncertainty
        .as_ref()
        .is_some_and(|u| u.bootstrap.is_some())
    {
        uses.push("block bootstrap".to_string());
    }
    if uses.is_empty() {
        format!(
            "{} (not used: one start of the {} method, no bootstrap)",
            cal.seed, cal.method
        )
    } else {
        format!("{} ({})", cal.seed, uses.join(", "))
    }
}

/// The report of `cal` (a calibration of `model` on `trials`, named for display):
/// figures from inverse kinematics with the start (`baseline_label`) and the fitted
/// parameters, the parameter table with the intervals, the convergence of the best start,
/// and the settings. `progress(done, total)` follows the inverse-kinematics passes.
#[allow(clippy::too_many_arguments)]
pub fn calibration_input(
    title: &str,
    baseline_label: &str,
    model: &Model,
    cal: &Calibration,
    trials: &[(String, &Trial)],
    provenance: &Provenance,
    seconds: f64,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<ReportInput, ReportError> {
    let mut input = ReportInput {
        title: title.to_string(),
        baseline_label: baseline_label.into(),
        fitted_label: "fitted model".into(),
        ..ReportInput::default()
    };
    analyze_with_progress(
        &mut input,
        model,
        &cal.fit.p,
        Some(&cal.start),
        trials,
        &IkOptions::default(),
        progress,
    )?;
    // The calibration's own marker RMS (the same definition, on the markers it used).
    let shown = CalibrationShown::of(cal);
    input.overall_rms_mm = (Some(shown.rms_before_mm), shown.rms_after_mm);
    let free: Vec<usize> = cal.free.iter().map(|id| id.0).collect();
    input.parameters = parameter_rows(model, &cal.fit.p, Some(&cal.start), Some(&free));
    // The 95 % intervals of the uncertainty analysis (mm/deg, as the report's table).
    for p in &shown.parameters {
        if let (Some(se), Some([lower, upper])) = (p.se, p.ci95) {
            input.set_interval(
                p.name,
                Interval {
                    se,
                    lower,
                    upper,
                    level: 0.95,
                },
            );
        }
    }
    input.trust = Some(crate::trust::Trust::from_calibration(cal));
    input.verdict = Some(cal.verdict.clone());
    input.convergence = Some(Convergence {
        method: cal.method.to_string(),
        stages: cal
            .convergence
            .iter()
            .map(|c| {
                (
                    c.stage.clone(),
                    jointfit_app::present::objectives_mm2(&c.objective),
                )
            })
            .collect(),
        iterations: cal.iterations,
        evaluations: cal.evaluations,
        converged: cal.converged,
        seconds,
        start: (cal.start_runs.len() > 1).then_some((cal.best_start, cal.start_runs.len())),
        termination: cal.termination.to_string(),
    });
    if cal.skipped_frames > 0 {
        input.notes.push(format!(
            "{} frames were left out of the calibration because a segment had too few markers.",
            cal.skipped_frames
        ));
    }
    let mut settings = vec![("command line".to_string(), provenance.command_line.clone())];
    settings.extend(provenance.inputs.iter().cloned());
    settings.push(("method".to_string(), cal.method.to_string()));
    settings.push((
        "starts".to_string(),
        if cal.start_runs.len() > 1 {
            format!(
                "{} (best: start {})",
                cal.start_runs.len(),
                cal.best_start + 1
            )
        } else {
            "1".to_string()
        },
    ));
    settings.push(("random seed".to_string(), seed_use(cal)));
    settings.push((
        "frames fitted".to_string(),
        format!("{} ({} skipped)", cal.frames, cal.skipped_frames),
    ));
    settings.push(("jointfit version".to_string(), provenance.version.clone()));
    settings.push(("date".to_string(), provenance.date.clone()));
    input.settings = settings;
    Ok(input)
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointfit::calibrate::params_for_groups;
    use jointfit::model::lower_limb::{lower_limb, Side};
    use jointfit::solver::NoObserver;
    use jointfit::workflow::calibration::calibrate;
    use jointfit::workflow::FitSettings;
    use jointfit_experiments::synth::{coordinates, markers, Motion};

    fn knee_fit(settings: &FitSettings) -> (Model, Calibration, Trial) {
        let model = Model::compile(&lower_limb(Side::Right)).unwrap();
        let p = model.nominal_params();
        let (trial, _) = markers(
            &model,
            &p,
            &coordinates(&model, Motion::Knee, 20).unwrap(),
            50.0,
            None,
        );
        let free = params_for_groups(&model, &["knee"]).unwrap();
        let start = jointfit::workflow::perturb(&model, &p, &[free[0].0], 10.0, 5.0, 1);
        let cal = calibrate(&model, &start, &[&trial], &free, settings, &mut NoObserver).unwrap();
        (model, cal, trial)
    }

    /// The seed drives `--starts` (and the bootstrap), so the report must
    /// not call it unused then; with one start of the joint method it is unused.
    #[test]
    fn the_seed_is_reported_as_used_when_it_drives_the_starts() {
        let several = FitSettings {
            starts: 3,
            seed: 7,
            ..FitSettings::default()
        };
        let (model, cal, trial) = knee_fit(&several);
        let text = seed_use(&cal);
        assert!(
            text.starts_with("7 (") && text.contains("extra starts"),
            "{text}"
        );
        assert!(!text.contains("not used"), "{text}");
        let input = calibration_input(
            "t",
            "start",
            &model,
            &cal,
            &[("knee".to_string(), &trial)],
            &Provenance::default(),
            0.5,
            &mut |_, _| {},
        )
        .unwrap();
        let row = input
            .settings
            .iter()
            .find(|(k, _)| k == "random seed")
            .unwrap();
        assert_eq!(row.1, text);
        // The convergence panel shows the winning start and says which.
        let c = input.convergence.as_ref().unwrap();
        assert_eq!(c.start, Some((cal.best_start, 3)));
        assert_eq!(c.iterations, cal.start_runs[cal.best_start].iterations);
        // The default's global phase draws its probe starts from the seed.
        let (_, cal, _) = knee_fit(&FitSettings::default());
        assert!(
            seed_use(&cal).contains("extra starts"),
            "{}",
            seed_use(&cal)
        );
        let local = FitSettings {
            probes: 0,
            ..FitSettings::default()
        };
        let (_, cal, _) = knee_fit(&local);
        assert!(seed_use(&cal).contains("not used"), "{}", seed_use(&cal));
    }
}
