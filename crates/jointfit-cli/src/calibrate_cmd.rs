//! `jointfit calibrate <SUBJECT.toml|MODEL.osim> <TRIAL>... --joints <LIST> -o <FITTED>`:
//! parses the options into the calibration pipeline's ([`jointfit_app::FitOptions`]), runs
//! its stages (model, trials with this command's repairs and data checks, fit), prints and
//! writes the results.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use jointfit::solver::Observer;
use jointfit::trial::Trial;
use jointfit::workflow::calibration::Calibration;
use jointfit::workflow::{self, Method};
use jointfit_app::present::{
    CalibrationShown, EnvelopeShown, MarkerDecisionShown, RefinedMarkerShown,
};
use jointfit_app::{Detail, FitOptions, ModelSource, Subject};
use serde::Serialize;

use crate::common::{load_checked, Columns, TrialJson};

/// The outer optimizer (the command line's names for [`jointfit::workflow::Method`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// Joint sparse Levenberg–Marquardt over all frames and parameters (fast default).
    Joint,
    /// Two-level Gauss-Newton on the reduced (variable-projection) Jacobian.
    Gradient,
    /// Particle swarm (global), then polished by the joint solver.
    Pso,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Method {
        match m {
            MethodArg::Joint => Method::Joint,
            MethodArg::Gradient => Method::Gradient,
            MethodArg::Pso => Method::Pso,
        }
    }
}

#[derive(Args)]
pub struct CalibrateArgs {
    /// Subject model (TOML file or built-in name).
    pub model: String,
    /// Motion files (.trc or .c3d); parameters are shared across them.
    #[arg(required = true)]
    pub trials: Vec<PathBuf>,
    /// Parameter groups to fit: comma-separated hip, knee, ankle, or all. On a bilateral
    /// model (`lower-limb`, `personalize --side both`) `hip` frees both hips, `hip_r` or
    /// `hip_l` one side (likewise knee, ankle). With an .osim model: the joints whose parent
    /// and child offset frames to personalize (hip_r,knee_r).
    #[arg(long, default_value = "all", value_delimiter = ',')]
    pub joints: Vec<String>,
    /// .osim model only: offset scalars to personalize, JOINT[.parent|.child[.translation|
    /// .orientation[.x|.y|.z]]], e.g. hip_r.parent.translation,knee_r.child.orientation.z.
    #[arg(long, value_delimiter = ',', value_name = "SELECTION")]
    pub params: Vec<String>,
    #[arg(long, value_enum, default_value = "joint")]
    pub method: MethodArg,
    /// Fitted model (TOML). It may be the subject model file itself only with --force.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Allow --output to replace the subject model file (an in-place update).
    #[arg(long)]
    pub force: bool,
    /// Keep a fit that did not converge and exit 0 (otherwise: exit status 3, nothing written).
    #[arg(long)]
    pub accept_unconverged: bool,
    /// Fit and write even when the verdict is `reject` (trials whose marker placement does
    /// not match the model's, an implausible result); otherwise: exit status 5, nothing
    /// written. The verdict and its reasons are still printed.
    #[arg(long)]
    pub accept_rejected: bool,
    /// Marker weights of an OpenSim IK task set (an IKTaskSet file or an IK setup file): the
    /// fit weighs each marker as OpenSim's IK with these tasks does (a marker task not applied
    /// or absent weighs 0).
    #[arg(long, value_name = "TASKS.xml")]
    pub weights: Option<PathBuf>,
    /// Print every flagged parameter with why, and the weak parameter combinations (by
    /// default: one line per joint).
    #[arg(long, short)]
    pub verbose: bool,
    /// Outer iteration limit (1 to 10000; default: the solver's, 200). A fit that reaches it
    /// has not converged (see --accept-unconverged).
    #[arg(long, value_name = "N", value_parser = crate::validate::iterations)]
    pub max_iter: Option<usize>,
    /// Start from the parameters of an earlier fit (same model structure).
    #[arg(long)]
    pub seed_from: Option<String>,
    /// Low-pass filter cutoff in Hz.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::validate::cutoff_hz)]
    pub filter: Option<f64>,
    /// Random seed of the particle swarm and of the extra starts.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Fit from this many starts (the given one and seeded moves of up to ±20 mm / ±10°),
    /// keep the best and report the spread of the optima (joint and gradient methods).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub starts: u64,
    #[command(flatten)]
    pub read: crate::common::TrialArgs,
    /// Extra starts of the default's global phase (joint method, one start): each runs a few
    /// iterations and the two most promising are finished (0: one local fit from the start).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(0..=1000))]
    pub probes: u64,
    /// Print a JSON report on stdout.
    #[arg(long)]
    pub json: bool,
    /// Also write an HTML report (figures, parameter table, settings) to DIR/index.html.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Flag length parameters whose 95 % interval half-width exceeds this (mm).
    #[arg(long, default_value_t = jointfit_app::fit::THRESHOLD_MM, allow_negative_numbers = true, value_parser = crate::validate::positive)]
    pub threshold_mm: f64,
    /// Flag angle parameters whose 95 % interval half-width exceeds this (deg).
    #[arg(long, default_value_t = jointfit_app::fit::THRESHOLD_DEG, allow_negative_numbers = true, value_parser = crate::validate::positive)]
    pub threshold_deg: f64,
    /// Moving-block bootstrap replicates for the intervals (0: white, HAC and jackknife only;
    /// at most 2000, each is a refit).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true, value_parser = crate::validate::bootstrap)]
    pub bootstrap: usize,
    /// Refit with the parameters this trial cannot determine held at their starting
    /// (landmark/nominal) values (subset selection on the reduced normal matrix).
    #[arg(long)]
    pub fix_unidentifiable: bool,
    /// Parameter priors: `model` (the model file's prior_sd/prior_mean, written by
    /// personalize: a maximum a posteriori fit) or `none` (Reinbolt's unregularized fit).
    #[arg(long, value_enum, default_value = "model")]
    pub prior: crate::prior_args::PriorArg,
    /// Marker noise SD (mm) that weighs the prior against the markers (default: estimated
    /// from the residuals of the fit).
    #[arg(long, value_name = "MM", allow_negative_numbers = true, value_parser = crate::validate::noise_mm)]
    pub marker_noise_mm: Option<f64>,
    /// Override prior SDs: NAME=VALUE, NAME a group (hip, knee, ankle, all) or parameter,
    /// VALUE in mm or deg; e.g. knee=5mm,knee=3deg,hip_pelvis_lateral=8mm.
    #[arg(long, value_delimiter = ',', value_name = "NAME=VALUE")]
    pub prior_sd: Vec<String>,
    /// Also fit each tracking marker's position in its segment (with a prior around the
    /// static-trial position); the fitted model carries the refined markers.
    #[arg(long)]
    pub refine_markers: bool,
    /// Prior SD (mm per axis) of a refined marker position (with --refine-markers).
    #[arg(long, value_name = "MM", default_value_t = 10.0, allow_negative_numbers = true, value_parser = crate::validate::positive)]
    pub marker_prior_sd_mm: f64,
    /// Markers the default marker policy leaves as they are (comma-separated). The policy
    /// (with a prior) refines the position of a marker that sits differently in the motion
    /// trial than in the static trial and leaves out one the IK rejects in many frames.
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    pub keep_markers: Vec<String>,
    /// Turn the default marker policy off (markers as the static trial placed them).
    #[arg(long)]
    pub no_marker_policy: bool,
    /// Do not bound the hip centre medial to the ASIS (the default with a prior bounds
    /// hip_pelvis_lateral at 0.9 × half the inter-ASIS width less 1 mm).
    #[arg(long)]
    pub no_envelope: bool,
    /// Keep every joint's prior as the model file gives it, even where the trial disagrees
    /// with it by more than its SD allows (the default widens that joint's prior).
    #[arg(long)]
    pub no_prior_conflict: bool,
}

/// `calibrate --json`: the calibration and the wall time.
#[derive(Serialize)]
pub struct Report<'a> {
    #[serde(flatten)]
    pub calibration: CalibrationShown<'a>,
    /// `--refine-markers`: how far each marker moved, and which marker offsets trade off
    /// with which joint parameters.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub refined_markers: Vec<RefinedMarkerShown<'a>>,
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    pub marker_trade_offs: &'a [workflow::refine::TradeOff],
    /// The default marker policy's decisions (refined or left-out markers, with why).
    pub marker_decisions: Vec<MarkerDecisionShown<'a>>,
    /// The anatomical envelope's bounds, `active` when the fit ended on one.
    pub envelope: Vec<EnvelopeShown<'a>>,
    /// With a prior: each joint's prior–data conflict (χ², dof, p, the type-II ML prior
    /// scale τ) and whether its prior was widened by τ.
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    pub prior_conflict: &'a [workflow::conflict::JointConflict],
    /// With a prior: the short summary the text output prints (which joints the trial
    /// determined, which the prior held, which trial would determine them).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub information_summary: Vec<String>,
    pub seconds: f64,
    /// Each trial as read: vertical, reader notes, repairs and data checks.
    pub trials_read: &'a [TrialJson],
}

/// Progress of the optimizer stages on stderr (see `progress`).
pub struct ProgressObserver {
    bars: crate::progress::StageProgress,
    stage: String,
    budget: Option<usize>,
}

impl ProgressObserver {
    pub fn new() -> ProgressObserver {
        ProgressObserver {
            bars: crate::progress::StageProgress::new("iterations"),
            stage: String::new(),
            budget: None,
        }
    }

    pub fn finish(&mut self) {
        self.bars.finish();
    }
}

impl Observer for ProgressObserver {
    fn stage_started(&mut self, stage: &str, budget: Option<usize>) {
        self.stage = stage.to_string();
        self.budget = budget;
        if budget.is_some() && stage.starts_with(jointfit::workflow::calibration::UNCERTAINTY_STAGE)
        {
            // Bootstrap refits, not counted one by one (they run in parallel): say it began.
            self.bars.announce(stage);
        }
    }
    fn iteration(&mut self, iteration: usize, objective: f64) {
        let mm2 = objective * jointfit_app::present::MM_PER_M * jointfit_app::present::MM_PER_M;
        let msg = format!("objective {mm2:.1} mm²");
        let stage = self.stage.clone();
        self.bars.step(
            &stage,
            iteration as u64,
            self.budget.map(|n| n as u64),
            &msg,
        );
    }
}

/// The pipeline's options of a run from the command line: with no options, the options whose
/// settings are `FitOptions::default().settings()` (the settings `jointfit bench` times).
pub fn fit_options(args: &CalibrateArgs) -> FitOptions {
    FitOptions {
        joints: args.joints.clone(),
        method: args.method.into(),
        seed: args.seed,
        threshold_mm: args.threshold_mm,
        threshold_deg: args.threshold_deg,
        bootstrap: args.bootstrap,
        starts: args.starts as usize,
        fix_unidentifiable: args.fix_unidentifiable,
        priors: args.prior != crate::prior_args::PriorArg::None,
        marker_noise_mm: args.marker_noise_mm,
        max_iterations: args.max_iter,
        accept_rejected: args.accept_rejected,
        probes: args.probes as usize,
        refine_markers_mm: args.refine_markers.then_some(args.marker_prior_sd_mm),
        anatomical_envelope: !args.no_envelope,
        marker_policy: !args.no_marker_policy,
        keep_markers: args.keep_markers.clone(),
        prior_conflict: !args.no_prior_conflict,
        params: args.params.clone(),
    }
}

use crate::calibrate_text::information_summary;
pub use crate::calibrate_text::print_report;

/// Refuses outputs that are inputs (`files` holds the model already): the trials,
/// `--seed-from`, the fitted model (in place only with `--force`) and the report.
pub fn check_files(args: &CalibrateArgs, mut files: crate::output::Files) -> Result<()> {
    for t in &args.trials {
        files = files.input("trial", t);
    }
    if let Some(s) = &args.seed_from {
        files = files.model("--seed-from", s);
    }
    files = files.output_in_place("output", &args.output, args.force);
    if let Some(dir) = &args.report {
        files = files.output_in_dir("--report", dir, "index.html");
    }
    if let Some(w) = &args.weights {
        files = files.input("--weights", w);
    }
    files.check()?;
    Ok(())
}

/// `--weights`: the task set's marker weights written into `spec` (a warning names applied
/// tasks of markers the model lacks, which OpenSim ignores too).
pub fn apply_weights(
    args: &CalibrateArgs,
    spec: &mut jointfit::model::spec::ModelSpec,
) -> Result<()> {
    if let Some(path) = &args.weights {
        let unknown = jointfit_io::osim_setup::read_task_set(path)?.apply_marker_weights(spec);
        if !unknown.is_empty() {
            eprintln!(
                "jointfit: warning: {}: marker tasks of markers the model lacks (ignored): {}",
                path.display(),
                unknown.join(", ")
            );
        }
    }
    Ok(())
}

/// `--marker-noise-mm`, when given, is a positive finite number.
pub fn check_marker_noise(args: &CalibrateArgs) -> Result<()> {
    if let Some(mm) = args.marker_noise_mm {
        if !(mm.is_finite() && mm > 0.0) {
            anyhow::bail!("--marker-noise-mm must be a positive number of millimetres, got {mm}");
        }
    }
    Ok(())
}

/// Reads and checks every trial of `args` for `model` ([`load_checked`]): the trials and
/// what their reading found, in the order given.
pub fn load_trials(
    args: &CalibrateArgs,
    model: &jointfit::model::Model,
) -> Result<(Vec<Trial>, Vec<TrialJson>)> {
    Ok(args
        .trials
        .iter()
        .map(|t| {
            load_checked(t, &args.read, model, args.filter, Columns::ForModel)
                .map(|(t, j, _)| (t, j))
        })
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip())
}

/// The read and prepare stages as this command runs them: the model as read (the fitted
/// model keeps its priors), the model to fit (with `--prior-sd` overrides and `--weights`),
/// the start (`--seed-from`) and the trials (repairs, data checks).
pub struct Prepared {
    pub given: Subject,
    pub subject: Subject,
    pub start: Option<Vec<f64>>,
    pub trials: Vec<Trial>,
    pub read: Vec<TrialJson>,
}

/// The model of `args` as read, then as fitted: the priors and weights of this run applied.
fn prepare_model(args: &CalibrateArgs, opts: &FitOptions) -> Result<(Subject, Subject)> {
    let source = ModelSource::read(&args.model)?;
    let given = jointfit_app::load_subject(&source, opts).map_err(|e| match e {
        jointfit_app::Error::Selection(e) => anyhow::anyhow!("{}: {e}", args.model),
        e => e.into(),
    })?;
    let mut fit_spec = given.model.spec().clone();
    crate::prior_args::apply(&mut fit_spec, args.prior, &args.prior_sd)?;
    apply_weights(args, &mut fit_spec)?;
    check_marker_noise(args)?;
    let subject = Subject {
        model: jointfit::model::Model::compile(&fit_spec)?,
        osim: given.osim.clone(),
    };
    Ok((given, subject))
}

/// Reads the model, the start and the trials of `args` ([`Prepared`]).
pub fn prepare(args: &CalibrateArgs, opts: &FitOptions) -> Result<Prepared> {
    let (given, subject) = prepare_model(args, opts)?;
    crate::validate::model_markers("--keep-markers", &args.keep_markers, &subject.model)?;
    let start = match &args.seed_from {
        Some(seed) => {
            let earlier = jointfit_io::model_file::load_model(seed)?;
            Some(jointfit::workflow::ik::transfer_params(
                &subject.model,
                &earlier,
                seed,
            )?)
        }
        None => None,
    };
    let (trials, read) = load_trials(args, &subject.model)?;
    for (path, trial) in args.trials.iter().zip(&trials) {
        jointfit_app::check_markers(&path.display().to_string(), trial, &subject.model)
            .map_err(anyhow::Error::msg)?;
        jointfit_app::check_motion(&path.display().to_string(), trial)
            .map_err(anyhow::Error::msg)?;
    }
    if subject.osim.is_none() {
        for (path, trial) in args.trials.iter().zip(&trials) {
            let (_, absent) =
                jointfit::ik::MarkerMap::allowing_absent(&subject.model, trial.labels());
            crate::common::warn_absent_markers(path, &absent);
        }
    }
    Ok(Prepared {
        given,
        subject,
        start,
        trials,
        read,
    })
}

pub fn run(args: CalibrateArgs) -> Result<()> {
    let osim = jointfit_io::model_file::is_osim(Path::new(&args.model));
    if !osim && !args.params.is_empty() {
        anyhow::bail!(
            "--params selects offset frames of an .osim model; {} is not one (use --joints)",
            args.model
        );
    }
    let files = match osim {
        true => crate::output::Files::new().input("model", Path::new(&args.model)),
        false => crate::output::Files::new().model("model", &args.model),
    };
    check_files(&args, files)?;
    let formats: &[&str] = if osim { &["osim", "toml"] } else { &["toml"] };
    crate::output::check_model_extension(&args.output, formats)?;
    let opts = fit_options(&args);
    let prepared = prepare(&args, &opts)?;
    let refs: Vec<&Trial> = prepared.trials.iter().collect();
    let clock = Instant::now();
    let mut observer = ProgressObserver::new();
    let fitted = jointfit_app::fit(
        &prepared.subject,
        prepared.start.clone(),
        &refs,
        &opts,
        &mut observer,
    )
    .map_err(|e| crate::calibrate_text::refusal(e, &args.trials))?;
    observer.finish();
    let seconds = clock.elapsed().as_secs_f64();
    match &fitted.detail {
        Detail::Native(refined) => finish(&args, &prepared, refined, seconds),
        Detail::Osim(fit) => crate::osim_calibrate::finish(&args, &prepared, fit, seconds),
    }
}

/// Prints the calibration of a jointfit model (text or `--json`).
fn print(
    args: &CalibrateArgs,
    refined: &workflow::refine::RefinedCalibration,
    seconds: f64,
    read: &[TrialJson],
) -> Result<()> {
    let cal = &refined.calibration;
    if args.json {
        let report = Report {
            calibration: CalibrationShown::of(cal),
            refined_markers: refined.markers.iter().map(RefinedMarkerShown::of).collect(),
            marker_trade_offs: &refined.trade_offs,
            marker_decisions: refined
                .marker_decisions
                .iter()
                .map(MarkerDecisionShown::of)
                .collect(),
            envelope: refined.envelope.iter().map(EnvelopeShown::of).collect(),
            prior_conflict: &refined.conflict,
            information_summary: information_summary(cal),
            seconds,
            trials_read: read,
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        crate::calibrate_text::print_policy(&refined.marker_decisions, &refined.envelope);
        print_report(cal, seconds, args.verbose);
        crate::prior_args::print_refinement(&refined.markers, &refined.trade_offs);
        crate::calibrate_text::print_verdict(&cal.verdict);
    }
    Ok(())
}

/// The gates of a finished fit: an unconverged fit (unless `--accept-unconverged`) and a
/// rejected one (unless `--accept-rejected`) are printed, then refused.
pub fn gates(
    args: &CalibrateArgs,
    cal: &Calibration,
    print: impl Fn() -> Result<()>,
) -> Result<()> {
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
    Ok(())
}

/// Gates, writes (the fitted model, `--report`) and prints the calibration of a jointfit
/// model.
fn finish(
    args: &CalibrateArgs,
    prepared: &Prepared,
    refined: &workflow::refine::RefinedCalibration,
    seconds: f64,
) -> Result<()> {
    let cal = &refined.calibration;
    let print = || print(args, refined, seconds, &prepared.read);
    gates(args, cal, print)?;
    // The fitted model keeps the input file's priors (overrides apply to this run only).
    // Refined markers (if any) replace the input's.
    let input_model = &prepared.given.model;
    let mut fitted = input_model.spec_with_nominal(&cal.fit.p[..input_model.parameters().len()]);
    fitted.markers = refined.fitted.markers.clone();
    fitted.name = format!("{} (fitted)", input_model.spec().name);
    jointfit_io::model_file::save_spec(&args.output, &fitted)
        .with_context(|| format!("writing {}", args.output.display()))?;
    let html = match &args.report {
        Some(dir) => Some(crate::report_cmd::write_calibration_report(
            dir,
            &input_model.spec().name,
            baseline_label(args),
            &refined.model,
            &named_trials(&args.trials, &prepared.trials),
            cal,
            &provenance(args, prepared.subject.model.spec().lab_up),
            seconds,
            &prepared.read,
            &conflict_notes(&refined.conflict),
        )?),
        None => None,
    };
    print()?;
    print_written(args, html.as_deref());
    Ok(())
}

/// The files written, unless `--json`.
pub fn print_written(args: &CalibrateArgs, report: Option<&Path>) {
    if !args.json {
        println!("wrote {}", args.output.display());
        if let Some(path) = report {
            println!("wrote {}", path.display());
        }
    }
}

/// The report's notes of the prior–data conflict step: one per flagged joint.
pub(crate) fn conflict_notes(conflicts: &[workflow::conflict::JointConflict]) -> Vec<String> {
    jointfit_app::fit::conflict_lines(conflicts)
        .into_iter()
        .map(|l| format!("{l}."))
        .collect()
}

/// What the report compares the fit with.
fn baseline_label(args: &CalibrateArgs) -> &'static str {
    if args.seed_from.is_some() {
        "start (earlier fit)"
    } else if Path::new(&args.model).is_file() {
        "landmark model"
    } else {
        "nominal model"
    }
}

pub fn named_trials<'t>(paths: &[PathBuf], trials: &'t [Trial]) -> Vec<(String, &'t Trial)> {
    paths
        .iter()
        .map(|p| crate::report_cmd::display_name(p))
        .zip(trials.iter())
        .collect()
}

/// The files and options of this run, for the report's settings table.
fn provenance(
    args: &CalibrateArgs,
    lab_up: Option<jointfit::spatial::UpAxis>,
) -> jointfit_report::calibration::Provenance {
    let mut inputs = vec![
        ("subject model".to_string(), args.model.clone()),
        (
            "start parameters".to_string(),
            args.seed_from
                .clone()
                .map(|s| format!("from {s}"))
                .unwrap_or_else(|| "the subject model's values".into()),
        ),
        (
            "fitted model".to_string(),
            args.output.display().to_string(),
        ),
        ("parameter groups".to_string(), args.joints.join(", ")),
    ];
    inputs.extend(crate::report_cmd::trial_settings(
        &args.trials,
        &args.read,
        lab_up,
        args.filter,
    ));
    crate::report_cmd::provenance(inputs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Wrap {
        #[command(flatten)]
        args: CalibrateArgs,
    }

    /// `jointfit calibrate SUBJECT TRIAL -o OUT` runs the default options' settings (through
    /// the pipeline's one option → settings mapping), the
    /// settings `jointfit bench` times (a changed option default would make the bench time
    /// something else than the command).
    #[test]
    fn the_command_with_no_options_runs_the_command_default() {
        let w =
            Wrap::try_parse_from(["calibrate", "s.toml", "walk.trc", "-o", "fit.toml"]).unwrap();
        assert_eq!(
            fit_options(&w.args).settings(),
            FitOptions::default().settings()
        );
    }
}
