//! `jointfit report <FITTED.toml> <TRIAL>... [--landmark <SUBJECT.toml>] -o <DIR>` and the
//! report of `jointfit calibrate ... --report <DIR>`: a self-contained `DIR/index.html`
//! (see the `jointfit-report` crate).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use jointfit::ik::IkOptions;
use jointfit::model::Model;
use jointfit::trial::Trial;
use jointfit::workflow::calibration::Calibration;
use jointfit_report::analyze::{analyze_with_progress, parameter_rows};
use jointfit_report::ReportInput;

use crate::common::{load_checked, Columns, TrialArgs, TrialJson};
use crate::progress::Progress;

#[derive(Args)]
pub struct ReportArgs {
    /// Fitted model (TOML written by `jointfit calibrate`, or any model file).
    pub model: String,
    /// Motion files (.trc or .c3d) to show the model on.
    #[arg(required = true)]
    pub trials: Vec<PathBuf>,
    /// The model before calibration (e.g. from `jointfit personalize`), for comparison.
    #[arg(long, value_name = "SUBJECT.toml")]
    pub landmark: Option<String>,
    #[command(flatten)]
    pub read: crate::common::TrialArgs,
    /// Low-pass filter cutoff in Hz (use the one the calibration used).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::validate::cutoff_hz)]
    pub filter: Option<f64>,
    /// Output directory; the report is DIR/index.html.
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
}

pub fn run(args: ReportArgs) -> Result<()> {
    let mut files = crate::output::Files::new().model("model", &args.model);
    for t in &args.trials {
        files = files.input("trial", t);
    }
    if let Some(l) = &args.landmark {
        files = files.model("--landmark", l);
    }
    files
        .output_in_dir("report", &args.output, "index.html")
        .check()?;
    let spec = jointfit_io::model_file::load_spec(&args.model)?;
    let model = jointfit_io::model_file::load_model(&args.model)?;
    let (trials, read) = load_trials(&args.trials, &args.read, &model, args.filter)?;
    let refs: Vec<&Trial> = trials.iter().map(|(_, t)| t).collect();
    let model = model_for_report(model, &args.trials, &refs)?;
    let fitted = model.nominal_params();
    let baseline = match &args.landmark {
        Some(path) => Some(params_by_name(&model, &args.model, path)?),
        None => None,
    };
    let mut input = ReportInput {
        title: spec.name.clone(),
        baseline_label: "landmark model".into(),
        fitted_label: "fitted model".into(),
        ..ReportInput::default()
    };
    let named: Vec<(String, &Trial)> = trials.iter().map(|(n, t)| (n.clone(), t)).collect();
    let mut bar = Progress::new("inverse kinematics", None).unit("passes");
    analyze_with_progress(
        &mut input,
        &model,
        &fitted,
        baseline.as_deref(),
        &named,
        &IkOptions::default(),
        &mut |done, total| {
            bar.set_total(Some(total as u64));
            bar.set(done as u64, "");
        },
    )?;
    bar.finish("");
    input.parameters = parameter_rows(&model, &fitted, baseline.as_deref(), None);
    let mut settings = vec![
        ("fitted model".to_string(), args.model.clone()),
        (
            "landmark model".to_string(),
            args.landmark.clone().unwrap_or_else(|| "not given".into()),
        ),
    ];
    settings.extend(trial_settings(
        &args.trials,
        &args.read,
        model.spec().lab_up,
        args.filter,
    ));
    input.settings = with_provenance(settings);
    input.data_checks = read.iter().map(TrialJson::to_report).collect();
    input.scaling = crate::scale_cmd::scaling_beside(Path::new(&args.model))?;
    let path = jointfit_report::write_report(&args.output, &input)
        .with_context(|| format!("writing the report to {}", args.output.display()))?;
    println!(
        "RMS marker distance: {}{:.2} mm with the fitted model",
        input
            .overall_rms_mm
            .0
            .map(|b| format!("{b:.2} mm with the landmark model, "))
            .unwrap_or_default(),
        input.overall_rms_mm.1
    );
    println!("wrote {}", path.display());
    Ok(())
}

/// The model as the report shows it on these trials, as `calibrate --report` does: every
/// model marker stays (one a trial lacks counts as missing in each of its frames, is said on
/// stderr and in a note, and has "n/a" in the per-marker figure), and coordinates no marker
/// determines are held at their defaults (said on stderr).
fn model_for_report(model: Model, paths: &[PathBuf], trials: &[&Trial]) -> Result<Model> {
    for (path, trial) in paths.iter().zip(trials) {
        let (_, absent) = jointfit::ik::MarkerMap::allowing_absent(&model, trial.labels());
        crate::common::warn_absent_markers(path, &absent);
    }
    let (held_model, held) = jointfit::ik::hold::hold_undetermined(&model, trials)?;
    if !held.is_empty() {
        eprintln!(
            "jointfit: warning: no marker determines {}; held at the model's default values",
            held.join(", ")
        );
    }
    Ok(held_model.unwrap_or(model))
}

/// The parameters of the model in `path`, in the order of `model`'s parameter vector.
fn params_by_name(model: &Model, model_path: &str, path: &str) -> Result<Vec<f64>> {
    let other = jointfit_io::model_file::load_model(path)?;
    model
        .parameters()
        .iter()
        .map(|par| match other.param_id(&par.name) {
            Some(id) => Ok(other.parameters()[id.0].nominal),
            None => bail!("{path}: has no parameter {:?} of {model_path}", par.name),
        })
        .collect()
}

/// A trial and its display name.
type NamedTrial = (String, Trial);

fn load_trials(
    paths: &[PathBuf],
    read: &TrialArgs,
    model: &jointfit::model::Model,
    filter: Option<f64>,
) -> Result<(Vec<NamedTrial>, Vec<TrialJson>)> {
    Ok(paths
        .iter()
        .map(|p| {
            let (trial, json, _) = load_checked(p, read, model, filter, Columns::All)?;
            Ok(((display_name(p), trial), json))
        })
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip())
}

pub fn display_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| p.display().to_string())
}

pub fn trial_settings(
    trials: &[PathBuf],
    read: &TrialArgs,
    lab_up: Option<jointfit::spatial::UpAxis>,
    filter: Option<f64>,
) -> Vec<(String, String)> {
    let up = match (read.up, lab_up) {
        (Some(u), _) => format!("{} (--up)", jointfit::spatial::UpAxis::from(u)),
        (None, Some(u)) => format!("{u} (the subject model's lab_up)"),
        (None, None) => "y".to_string(),
    };
    vec![
        (
            "trials".to_string(),
            trials
                .iter()
                .map(|t| t.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
        ),
        ("up axis".to_string(), up),
        (
            "filter".to_string(),
            match filter {
                Some(hz) => format!(
                    "{hz} Hz low-pass, zero-phase Butterworth (effective order 4: a 2nd-order \
                     design run forward and backward)"
                ),
                None => "none".to_string(),
            },
        ),
    ]
}

/// `settings` followed by the command line, jointfit version and date.
fn with_provenance(mut settings: Vec<(String, String)>) -> Vec<(String, String)> {
    settings.insert(0, ("command line".to_string(), command_line()));
    settings.push((
        "jointfit version".to_string(),
        env!("CARGO_PKG_VERSION").to_string(),
    ));
    settings.push(("date".to_string(), jointfit_report::utc_now()));
    settings
}

/// This process's command line, quoted for a POSIX shell where needed.
pub fn command_line() -> String {
    std::env::args()
        .enumerate()
        .map(|(i, a)| {
            if i == 0 {
                // The program as "jointfit", not the path it was started from.
                return "jointfit".to_string();
            }
            let plain = !a.is_empty()
                && a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c));
            if plain {
                a
            } else {
                format!("'{}'", a.replace('\'', r"'\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// The provenance of a report made by this process: its command line, `inputs`, the
/// jointfit version and the date.
pub fn provenance(inputs: Vec<(String, String)>) -> jointfit_report::calibration::Provenance {
    jointfit_report::calibration::Provenance {
        command_line: command_line(),
        inputs,
        version: env!("CARGO_PKG_VERSION").to_string(),
        date: jointfit_report::utc_now(),
    }
}

/// Writes the report of a finished calibration; returns the path of `index.html`.
#[allow(clippy::too_many_arguments)]
pub fn write_calibration_report(
    dir: &Path,
    model_name: &str,
    baseline_label: &str,
    model: &Model,
    trials: &[(String, &Trial)],
    cal: &Calibration,
    provenance: &jointfit_report::calibration::Provenance,
    seconds: f64,
    data_checks: &[crate::common::TrialJson],
    notes: &[String],
) -> Result<PathBuf> {
    let mut bar = Progress::new("report: inverse kinematics", None).unit("passes");
    let input = jointfit_report::calibration::calibration_input(
        &format!("{model_name} (fitted)"),
        baseline_label,
        model,
        cal,
        trials,
        provenance,
        seconds,
        &mut |done, total| {
            bar.set_total(Some(total as u64));
            bar.set(done as u64, "");
        },
    )?;
    bar.finish("");
    let mut input = input;
    input.data_checks = data_checks.iter().map(|t| t.to_report()).collect();
    input.notes.extend(notes.iter().cloned());
    input.scaling = crate::scale_cmd::scaling_of(&provenance.inputs)?;
    jointfit_report::write_report(dir, &input)
        .with_context(|| format!("writing the report to {}", dir.display()))
}
