//! `jointfit calibrate MODEL.osim TRIALS... --joints J1,J2 [--params ...] -o OUT.osim|.toml`:
//! the user's OpenSim model personalized ([`jointfit_io::osim_read::workflow`]) and written
//! back: OUT.osim is the input file with only the fitted offset values replaced; OUT.toml the
//! parameterized jointfit model at the fitted values.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use jointfit::trial::Trial;
use jointfit::workflow::{self, Calibration, HeldCalibration, Redundancy};
use jointfit_io::osim_read::{read_osim, workflow as osim_workflow};
use serde::Serialize;

use crate::calibrate_cmd::{
    check_files, check_marker_noise, fit_settings, load_trials, print_report, CalibrateArgs,
    ProgressObserver,
};

/// `calibrate MODEL.osim --json`: the calibration, the held redundant parameters, the wall
/// time of the fit.
#[derive(Serialize)]
struct Report<'a> {
    #[serde(flatten)]
    result: &'a HeldCalibration,
    /// Model markers the trials lack (left out of the fit).
    absent_markers: &'a [String],
    /// Coordinates the markers cannot determine, held at their defaults.
    held_coordinates: &'a [String],
    seconds: f64,
}

/// The joints named with `--joints` (its default `all` names none: an `.osim` has no groups).
fn joint_items(args: &CalibrateArgs) -> Vec<String> {
    if args.joints == ["all"] {
        vec![]
    } else {
        args.joints.clone()
    }
}

fn print_held(held: &[Redundancy]) {
    for r in held {
        if r.with.is_empty() {
            println!(
                "held at its start value (redundant: the joint's coordinates absorb it): {}",
                r.parameter
            );
        } else {
            println!(
                "held at its start value (redundant with {}): {}",
                r.with.join(", "),
                r.parameter
            );
        }
    }
}

pub fn run(args: CalibrateArgs) -> Result<()> {
    check_files(
        &args,
        crate::output::Files::new().input("model", Path::new(&args.model)),
    )?;
    let osim = read_osim(Path::new(&args.model))?;
    let spec = osim_workflow::selection_spec(&osim, &joint_items(&args), &args.params)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.model))?;
    let mut fit_spec = spec.clone();
    crate::prior_args::apply(&mut fit_spec, args.prior, &args.prior_sd)?;
    crate::calibrate_cmd::apply_weights(&args, &mut fit_spec)?;
    check_marker_noise(&args)?;
    let model = jointfit::model::Model::compile(&fit_spec)?;
    let start = match &args.seed_from {
        Some(seed) => {
            let earlier = jointfit_io::model_file::load_model(seed)?;
            Some(workflow::transfer_params(&model, &earlier, seed)?)
        }
        None => None,
    };
    let (trials, read) = load_trials(&args, &model)?;
    let refs: Vec<&Trial> = trials.iter().collect();
    let clock = Instant::now();
    let mut observer = ProgressObserver::new();
    let fit =
        osim_workflow::personalize(&fit_spec, start, &refs, &fit_settings(&args), &mut observer)
            .map_err(|e| match e {
                osim_workflow::OsimFitError::Workflow(w) => {
                    crate::calibrate_text::refusal(w, &args.trials)
                }
                e => e.into(),
            })?;
    observer.finish();
    let seconds = clock.elapsed().as_secs_f64();
    let cal: &Calibration = &fit.result.calibration;
    let print = || -> Result<()> {
        if args.json {
            let report = Report {
                result: &fit.result,
                absent_markers: &fit.absent_markers,
                held_coordinates: &fit.held_coordinates,
                seconds,
            };
            println!("{}", serde_json::to_string_pretty(&report)?);
        } else {
            if !fit.absent_markers.is_empty() {
                println!(
                    "model markers not in the trials (left out of the fit): {}",
                    fit.absent_markers.join(", ")
                );
            }
            if !fit.held_coordinates.is_empty() {
                println!(
                    "coordinates no marker of the trials determines (held at their defaults): {}",
                    fit.held_coordinates.join(", ")
                );
            }
            print_held(&fit.result.held_redundant);
            print_report(cal, seconds, args.verbose);
            crate::calibrate_text::print_verdict(&cal.verdict);
        }
        Ok(())
    };
    if !cal.converged && !args.accept_unconverged {
        print()?;
        return Err(
            crate::output::Unconverged(format!("the calibration ({})", cal.termination)).into(),
        );
    }
    if let Err(e) = crate::calibrate_text::gate(&cal.verdict, args.accept_rejected) {
        print()?;
        return Err(e);
    }
    if jointfit_io::model_file::is_osim(&args.output) {
        let text = fit.osim_text(&osim)?;
        jointfit_io::atomic::write_atomic(&args.output, text.as_bytes())
            .with_context(|| format!("writing {}", args.output.display()))?;
    } else {
        // The fitted model keeps the default priors (overrides apply to this run only).
        let mut fit = fit.clone();
        fit.spec = spec.clone();
        let mut fitted = fit.fitted_spec();
        fitted.name = format!("{} (fitted)", spec.name);
        jointfit_io::model_file::save_spec(&args.output, &fitted)
            .with_context(|| format!("writing {}", args.output.display()))?;
    }
    let html = match &args.report {
        Some(dir) => {
            let named: Vec<(String, &Trial)> = args
                .trials
                .iter()
                .map(|p| crate::report_cmd::display_name(p))
                .zip(refs.iter().copied())
                .collect();
            let mut inputs = vec![
                ("subject model".to_string(), args.model.clone()),
                (
                    "fitted model".to_string(),
                    args.output.display().to_string(),
                ),
                (
                    "personalized offsets".to_string(),
                    joint_items(&args)
                        .iter()
                        .chain(&args.params)
                        .cloned()
                        .collect::<Vec<_>>()
                        .join(", "),
                ),
            ];
            inputs.extend(crate::report_cmd::trial_settings(
                &args.trials,
                &args.read,
                model.spec().lab_up,
                args.filter,
            ));
            Some(crate::report_cmd::write_calibration_report(
                dir,
                &spec.name,
                "OpenSim model",
                &fit.model,
                &named,
                cal,
                &crate::report_cmd::provenance(inputs),
                seconds,
                &read,
                &crate::calibrate_cmd::conflict_notes(&fit.result.prior_conflict),
            )?)
        }
        None => None,
    };
    print()?;
    if !args.json {
        println!("wrote {}", args.output.display());
        if let Some(path) = html {
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}
