//! `jointfit check <SUBJECT.toml> <TRIAL> [--joints ..] [--up ..] [--json]`: before a fit,
//! what can this trial determine?
//!
//! Inverse kinematics with the subject's nominal (landmark) parameters gives each joint's
//! range of motion per axis; the reduced normal matrix at the nominal parameters (the Fisher
//! information of the joint parameters with every frame's coordinates projected out, see
//! `jointfit::calibrate::uncertainty`) predicts each parameter's 95 % interval. The residual
//! variance at the nominal model includes its misfit, so the prediction is conservative.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;
use jointfit::calibrate::params_for_groups;
use jointfit::calibrate::uncertainty::Identifiability;
use jointfit::calibrate::uncertainty::UncertaintyOptions;
use jointfit::model::spec::Unit;
use jointfit::workflow::predict::Prediction;
use jointfit_app::present::{mm, PredictionShown};
use serde::Serialize;

use crate::common::{load_checked, Columns, TrialJson};

#[derive(Args)]
pub struct CheckArgs {
    /// Subject model (TOML file or built-in name).
    pub model: String,
    /// Motion file (.trc or .c3d).
    pub trial: PathBuf,
    /// Parameter groups a calibration would fit: comma-separated hip, knee, ankle, or all;
    /// with an .osim model, the joints whose offset frames it would personalize (`hip_r,knee_r`).
    #[arg(long, default_value = "all", value_delimiter = ',')]
    pub joints: Vec<String>,
    #[command(flatten)]
    pub read: crate::common::TrialArgs,
    /// Low-pass filter cutoff in Hz.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::validate::cutoff_hz)]
    pub filter: Option<f64>,
    /// Flag length parameters whose predicted 95 % half-width exceeds this (mm).
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true, value_parser = crate::validate::positive)]
    pub threshold_mm: f64,
    /// Flag angle parameters whose predicted 95 % half-width exceeds this (deg).
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true, value_parser = crate::validate::positive)]
    pub threshold_deg: f64,
    /// Assumed skin-artifact noise, standard deviation per axis (mm). Default: estimated from
    /// the residuals of IK with the nominal model, which include the model's misfit (so the
    /// prediction errs on the side of flagging).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::validate::noise_mm)]
    pub noise_mm: Option<f64>,
    /// Print a JSON report on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `check --json`: the trial and what [`jointfit::workflow::predict::predict`] found.
#[derive(Serialize)]
pub struct CheckReport<'a> {
    pub trial: String,
    /// The trial as read: vertical, reader notes, repairs and data checks.
    pub read: TrialJson,
    #[serde(flatten)]
    pub check: PredictionShown<'a>,
}

pub fn run(args: CheckArgs) -> Result<()> {
    let model = load(&args)?;
    let (trial, read, _) =
        load_checked(&args.trial, &args.read, &model, args.filter, Columns::All)?;
    let model = crate::common::model_for_trials(model, &[&trial], "the check")?;
    let free = if jointfit_io::model_file::is_osim(Path::new(&args.model)) {
        (0..model.parameters().len())
            .map(jointfit::model::ParamId)
            .collect()
    } else {
        let groups: Vec<&str> = args.joints.iter().map(|s| s.as_str()).collect();
        params_for_groups(&model, &groups)?
    };
    let opts = UncertaintyOptions {
        assumed_sigma_m: args
            .noise_mm
            .map(|v| jointfit_app::present::from_shown(v, Unit::Metre)),
        ..jointfit_app::fit::uncertainty_options(args.threshold_mm, args.threshold_deg, 0, 1)
    };
    let prediction = jointfit::workflow::predict::predict(
        &model,
        &model.nominal_params(),
        &[&trial],
        &free,
        &opts,
    )?;
    let report = CheckReport {
        trial: args.trial.display().to_string(),
        read,
        check: PredictionShown::of(&prediction),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_check(&report.trial, &prediction);
    }
    Ok(())
}

/// The model; for an `.osim`, the offset frames of the joints `--joints` names become its
/// parameters, as `calibrate MODEL.osim --joints …` would fit them.
fn load(args: &CheckArgs) -> Result<jointfit::model::Model> {
    let path = Path::new(&args.model);
    if !jointfit_io::model_file::is_osim(path) {
        return Ok(jointfit_io::model_file::load_model(&args.model)?);
    }
    let osim = jointfit_io::osim_read::read_osim(path)?;
    let joints: Vec<String> = args
        .joints
        .iter()
        .filter(|j| *j != "all")
        .cloned()
        .collect();
    let spec = jointfit_app::osim::selection_spec(&osim, &joints, &[])
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.model))?;
    Ok(jointfit::model::Model::compile(&spec)?)
}

fn print_check(trial: &str, r: &Prediction) {
    println!(
        "{}: {} frames ({} skipped), RMS marker distance with the nominal model {:.2} mm \
         (every frame and marker, as calibrate, ik and report print it)",
        trial,
        r.frames,
        r.skipped_frames,
        mm(r.ik_rms)
    );
    println!("\nrange of motion (IK, nominal model)");
    let mut t = crate::table::Table::new(&["joint", "coordinate", "unit", "min", "max", "range"]);
    for c in &r.ranges {
        t.row(vec![
            c.joint.clone(),
            c.name.clone(),
            c.unit.clone(),
            format!("{:.1}", c.min),
            format!("{:.1}", c.max),
            format!("{:.1}", c.range),
        ]);
    }
    print!("{}", t.render());
    let u = &r.prediction;
    println!(
        "\npredicted 95% intervals at the nominal parameters (σ = {:.2} mm {}; widest of white, HAC, jackknife)",
        mm(u.sigma),
        if u.sigma_assumed {
            "as given"
        } else {
            "from the nominal model's residuals, which include its misfit: conservative"
        }
    );
    let mut t = crate::table::Table::new(&[
        "group",
        "parameter",
        "unit",
        "±95%",
        "trial alone ±",
        "determined",
    ]);
    let width = |h: Option<f64>| h.map_or("∞".to_string(), |h| format!("{h:.2}"));
    for p in &u.params {
        t.row(vec![
            p.group.clone(),
            p.name.clone(),
            p.unit.clone(),
            width(p.half_width),
            width(p.status_half_width),
            match p.status {
                Identifiability::Determined => "yes",
                Identifiability::Poor => "POOR",
                Identifiability::Undetermined => "NO",
            }
            .to_string(),
        ]);
    }
    print!("{}", t.render());
    println!(
        "(\"determined\" compares \"trial alone ±\" with the thresholds: the Fisher half-width \
         of the trial's information alone, pooled noise and time correlation; \"±95%\" is the \
         interval, the widest estimator's, and may be narrower or wider: docs/identifiability.md)"
    );
    for p in u.flagged() {
        println!(
            "{}: {}",
            p.name,
            p.reason.as_deref().unwrap_or("poorly determined")
        );
    }
    for w in &u.weak_directions {
        println!("weak combination: {}", w.description);
    }
    println!(
        "\nthis trial is predicted to determine {} of {} parameters (thresholds {} mm, {} deg)",
        r.determined.len(),
        u.params.len(),
        mm(u.threshold_m),
        u.threshold_rad.to_degrees()
    );
}
