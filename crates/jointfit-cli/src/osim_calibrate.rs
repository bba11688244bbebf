//! `jointfit calibrate MODEL.osim TRIALS... --joints J1,J2 [--params ...] -o OUT.osim|.toml`:
//! the output of the pipeline's `.osim` fit ([`jointfit_app::osim`]), written back:
//! OUT.osim is the input file with only the fitted offset values replaced; OUT.toml the
//! parameterized jointfit model at the fitted values.

use anyhow::{Context, Result};
use jointfit::workflow::redundant::Redundancy;
use jointfit_app::osim::OsimFit;
use jointfit_app::present::{CalibrationShown, HeldJointShown};
use serde::Serialize;

use crate::calibrate_cmd::{
    gates, named_trials, print_report, print_written, CalibrateArgs, Prepared,
};

/// `calibrate MODEL.osim --json`: the calibration, the held redundant parameters, the wall
/// time of the fit.
#[derive(Serialize)]
struct Report<'a> {
    #[serde(flatten)]
    calibration: CalibrationShown<'a>,
    held_redundant: &'a [Redundancy],
    prior_conflict: &'a [jointfit::workflow::conflict::JointConflict],
    held_joints: Vec<HeldJointShown<'a>>,
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

/// Prints the personalization (text or `--json`).
fn print(args: &CalibrateArgs, fit: &OsimFit, seconds: f64) -> Result<()> {
    if args.json {
        let report = Report {
            calibration: CalibrationShown::of(&fit.result.calibration),
            held_redundant: &fit.result.held_redundant,
            prior_conflict: &fit.result.prior_conflict,
            held_joints: fit
                .result
                .held_joints
                .iter()
                .map(HeldJointShown::of)
                .collect(),
            absent_markers: &fit.absent_markers,
            held_coordinates: &fit.held_coordinates,
            seconds,
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
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
    let cal = &fit.result.calibration;
    print_report(cal, seconds, args.verbose);
    crate::calibrate_text::print_verdict(&cal.verdict);
    Ok(())
}

/// Writes the fitted model: OUT.osim the user's file with the fitted offsets, OUT.toml the
/// parameterized model at the fitted values (with the default priors: overrides apply to
/// this run only).
fn write_fitted(args: &CalibrateArgs, prepared: &Prepared, fit: &OsimFit) -> Result<()> {
    let osim = prepared
        .given
        .osim
        .as_deref()
        .expect("an .osim calibration keeps its file");
    if jointfit_io::model_file::is_osim(&args.output) {
        let text = fit.osim_text(osim)?;
        jointfit_io::atomic::write_atomic(&args.output, text.as_bytes())
            .with_context(|| format!("writing {}", args.output.display()))?;
    } else {
        let spec = prepared.given.model.spec();
        let mut fit = fit.clone();
        fit.spec = spec.clone();
        let mut fitted = fit.fitted_spec();
        fitted.name = format!("{} (fitted)", spec.name);
        jointfit_io::model_file::save_spec(&args.output, &fitted)
            .with_context(|| format!("writing {}", args.output.display()))?;
    }
    Ok(())
}

/// `--report`: the HTML report of the personalization.
fn write_report(
    args: &CalibrateArgs,
    prepared: &Prepared,
    fit: &OsimFit,
    seconds: f64,
) -> Result<Option<std::path::PathBuf>> {
    let Some(dir) = &args.report else {
        return Ok(None);
    };
    let mut inputs = vec![
        ("subject model".to_string(), args.model.clone()),
        (
            "fitted model".to_string(),
            args.output.display().to_string(),
        ),
        (
            "personalized offsets".to_string(),
            joint_items(args)
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
        prepared.subject.model.spec().lab_up,
        args.filter,
    ));
    Ok(Some(crate::report_cmd::write_calibration_report(
        dir,
        &prepared.given.model.spec().name,
        "OpenSim model",
        &fit.model,
        &named_trials(&args.trials, &prepared.trials),
        &fit.result.calibration,
        &crate::report_cmd::provenance(inputs),
        seconds,
        &prepared.read,
        &crate::calibrate_cmd::conflict_notes(&fit.result.prior_conflict),
    )?))
}

/// Gates, writes (the fitted model, `--report`) and prints a personalization.
pub fn finish(
    args: &CalibrateArgs,
    prepared: &Prepared,
    fit: &OsimFit,
    seconds: f64,
) -> Result<()> {
    let print = || print(args, fit, seconds);
    gates(args, &fit.result.calibration, print)?;
    write_fitted(args, prepared, fit)?;
    let html = write_report(args, prepared, fit, seconds)?;
    print()?;
    print_written(args, html.as_deref());
    Ok(())
}
