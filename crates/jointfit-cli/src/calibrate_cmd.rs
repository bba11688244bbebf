//! `jointfit calibrate <SUBJECT.toml> <TRIAL>... --joints <LIST> --method <M> -o <FITTED.toml>`:
//! reads the files, runs [`jointfit::workflow::calibrate`], prints and writes the results.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use jointfit::calibrate::params_for_groups;
use jointfit::calibrate::uncertainty::{Identifiability, Uncertainty};
use jointfit::trial::Trial;
use jointfit::workflow::{
    self, uncertainty_options, Calibration, FitSettings, Method, Observer, Termination,
};
use serde::Serialize;

use crate::common::{load_trial, Up};

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
    /// Parameter groups to fit: comma-separated hip, knee, ankle, or all.
    #[arg(long, default_value = "all", value_delimiter = ',')]
    pub joints: Vec<String>,
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
    /// Extra starts of the default's global phase (joint method, one start): each runs a few
    /// iterations and the two most promising are finished (0: one local fit from the start).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(0..=1000))]
    pub probes: u64,
    #[arg(long, value_enum, default_value = "y")]
    pub up: Up,
    /// Print a JSON report on stdout.
    #[arg(long)]
    pub json: bool,
    /// Also write an HTML report (figures, parameter table, settings) to DIR/index.html.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Flag length parameters whose 95 % interval half-width exceeds this (mm).
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true, value_parser = crate::validate::positive)]
    pub threshold_mm: f64,
    /// Flag angle parameters whose 95 % interval half-width exceeds this (deg).
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true, value_parser = crate::validate::positive)]
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
    #[arg(long, value_name = "MM")]
    pub marker_noise_mm: Option<f64>,
    /// Override prior SDs: NAME=VALUE, NAME a group (hip, knee, ankle, all) or parameter,
    /// VALUE in mm or deg; e.g. knee=5mm,knee=3deg,hip_pelvis_lateral=8mm.
    #[arg(long, value_delimiter = ',', value_name = "NAME=VALUE")]
    pub prior_sd: Vec<String>,
}

/// `calibrate --json`: the calibration and the wall time.
#[derive(Serialize)]
pub struct Report<'a> {
    #[serde(flatten)]
    pub calibration: &'a Calibration,
    pub seconds: f64,
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
    }
    fn iteration(&mut self, iteration: usize, objective: f64) {
        let mm2 = objective * jointfit::model::MM_PER_M * jointfit::model::MM_PER_M;
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

/// The settings of a run from the command line.
pub fn fit_settings(args: &CalibrateArgs) -> FitSettings {
    FitSettings {
        method: args.method.into(),
        seed: args.seed,
        starts: args.starts as usize,
        probes: args.probes as usize,
        uncertainty: Some(uncertainty_options(
            args.threshold_mm,
            args.threshold_deg,
            args.bootstrap,
            args.seed,
        )),
        fix_unidentifiable: args.fix_unidentifiable,
        priors: args.prior != crate::prior_args::PriorArg::None,
        marker_noise: args
            .marker_noise_mm
            .map(|mm| mm * jointfit::model::M_PER_MM),
        ..FitSettings::default()
    }
}

pub fn print_report(report: &Calibration, seconds: f64) {
    println!(
        "{}: {} free parameters, {} frames ({} skipped), {} iterations, {} evaluations, {:.3} s{}",
        report.method,
        report.free_parameters,
        report.frames,
        report.skipped_frames,
        report.iterations,
        report.evaluations,
        seconds,
        match report.termination {
            Termination::Converged => String::new(),
            t => format!(" (not converged: {t})"),
        }
    );
    if let Some(ms) = &report.multistart {
        let lo = ms
            .objective_mm2
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        let hi = ms
            .objective_mm2
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        println!(
            "{} starts: {} reached the best objective (to 1e-9); objectives {:.3} to {:.3} mm²; \
             kept start {}",
            ms.starts,
            ms.reached_best,
            lo,
            hi,
            report.best_start + 1
        );
        let mut wide: Vec<&(String, f64)> = ms.spread.iter().filter(|(_, r)| *r > 0.1).collect();
        wide.sort_by(|a, b| b.1.total_cmp(&a.1));
        if !wide.is_empty() {
            let list: Vec<String> = wide
                .iter()
                .take(6)
                .map(|(n, r)| format!("{n} {r:.1}"))
                .collect();
            println!(
                "  largest spread of the optima over the starts (mm or deg): {}",
                list.join(", ")
            );
        }
    }
    if let Some(g) = &report.global {
        let list: Vec<String> = g
            .finished
            .iter()
            .zip(&g.finished_objective_mm2)
            .map(|(k, c)| format!("start {k} {c:.3}"))
            .collect();
        println!(
            "global phase: {} starts probed ({} iterations each), finished: {} mm²",
            g.starts,
            g.probe_iterations,
            list.join(", ")
        );
    }
    if let Some(w) = &report.global_warning {
        eprintln!("jointfit: warning: {w}");
    }
    let mut t = crate::table::Table::new(&[
        "group",
        "parameter",
        "unit",
        "start",
        "fitted",
        "change",
        "±95%",
        "95% CI",
        "determined",
    ]);
    for p in &report.parameters {
        let hw = p.ci95.map(|c| 0.5 * (c[1] - c[0]));
        t.row(vec![
            p.group.clone(),
            p.name.clone(),
            p.unit.to_string(),
            format!("{:.2}", p.start),
            format!("{:.2}", p.fitted),
            format!("{:.2}", p.change),
            match (hw, &p.identifiability) {
                (Some(h), _) => format!("{h:.2}"),
                (None, Some(_)) => "∞".to_string(),
                (None, None) => "-".to_string(),
            },
            p.ci95
                .map_or("-".to_string(), |c| format!("[{:.2}, {:.2}]", c[0], c[1])),
            match p.identifiability {
                Some(Identifiability::Determined) => "yes".to_string(),
                Some(Identifiability::Poor) => "POOR".to_string(),
                Some(Identifiability::Undetermined) => "NO".to_string(),
                None => "-".to_string(),
            },
        ]);
    }
    print!("{}", t.render());
    match (&report.uncertainty, report.prior_noise_mm) {
        (Some(u), None) => print_uncertainty_notes(u, &report.fixed_unidentifiable),
        (_, Some(noise)) => print_prior_summary(report, noise),
        (None, None) => {}
    }
    for c in report.plausibility.iter().filter(|c| !c.ok) {
        eprintln!(
            "jointfit: warning: implausible {}: {:.1} {u} > {:.1} {u} ({:.1} {u} outside; {})",
            c.check,
            c.value,
            c.limit,
            c.excess(),
            c.parameters.join(", "),
            u = c.unit
        );
    }
    println!(
        "RMS marker distance: {:.2} mm before, {:.2} mm after ({:.0}% lower)",
        report.rms_before_mm,
        report.rms_after_mm,
        100.0 * (1.0 - report.rms_after_mm / report.rms_before_mm)
    );
    let mut t = crate::table::Table::new(&["marker", "before mm", "after mm"]);
    for ((name, b), (_, a)) in report
        .marker_rms_before_mm
        .iter()
        .zip(&report.marker_rms_after_mm)
    {
        t.row(vec![name.clone(), format!("{b:.2}"), format!("{a:.2}")]);
    }
    print!("{}", t.render());
}

/// With a prior: which parameters the trial determined, and the weighting noise.
fn print_prior_summary(report: &Calibration, noise_mm: f64) {
    println!(
        "maximum a posteriori fit: priors from the model file, marker noise σ = {noise_mm:.2} \
         mm ({}); intervals include the prior",
        if report.prior_noise_estimated {
            "estimated from the residuals"
        } else {
            "given"
        }
    );
    let rows: Vec<(String, String, Option<jointfit::calibrate::prior::Source>)> = report
        .parameters
        .iter()
        .map(|p| (p.group.clone(), p.name.clone(), p.source))
        .collect();
    for line in crate::prior_args::summary(&rows) {
        println!("  {line}");
    }
}

/// How the intervals were made, the warnings for flagged parameters, the weak combinations.
pub fn print_uncertainty_notes(u: &Uncertainty, fixed: &[String]) {
    let mut methods: Vec<String> = Vec::new();
    for p in &u.params {
        let m = format!("{:?}", p.method).to_lowercase();
        if !methods.contains(&m) {
            methods.push(m);
        }
    }
    println!(
        "95% intervals: the widest of white-noise (σ = {:.2} mm, {} dof), Newey-West HAC (bandwidth {}){}{}; widest came from: {}",
        u.sigma_mm,
        u.dof,
        u.hac_bandwidth.map_or("-".into(), |b| format!("{b:.1} frames")),
        u.jackknife_blocks
            .map_or(String::new(), |k| format!(", {k}-block jackknife (t, {} dof)", k - 1)),
        u.bootstrap.as_ref().map_or(String::new(), |b| format!(
            ", block bootstrap ({} replicates of {}-frame blocks, seed {})",
            b.replicates, b.block_length, b.seed
        )),
        methods.join(", ")
    );
    for p in u.flagged() {
        let hw = p
            .half_width
            .map_or("unbounded".to_string(), |h| format!("±{h:.1} {}", p.unit));
        eprintln!(
            "jointfit: warning: {} {} by this trial ({hw} > {} {}): {}",
            p.name,
            if p.status == Identifiability::Undetermined {
                "not determined"
            } else {
                "poorly determined"
            },
            if p.unit == "mm" {
                u.threshold_mm
            } else {
                u.threshold_deg
            },
            p.unit,
            p.reason.as_deref().unwrap_or("")
        );
    }
    for w in &u.weak_directions {
        println!("weak combination: {}", w.description);
    }
    if !fixed.is_empty() {
        println!(
            "held at their starting values (--fix-unidentifiable): {}",
            fixed.join(", ")
        );
    } else if u.flagged().next().is_some() {
        println!("(rerun with --fix-unidentifiable to hold the flagged parameters at their starting values)");
    }
}

pub fn run(args: CalibrateArgs) -> Result<()> {
    let mut files = crate::output::Files::new().model("model", &args.model);
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
    files.check()?;
    let spec = jointfit_io::model_file::load_spec(&args.model)?;
    let input_model = jointfit_io::model_file::load_model(&args.model)?;
    let mut fit_spec = input_model.spec().clone();
    crate::prior_args::apply(&mut fit_spec, args.prior, &args.prior_sd)?;
    if let Some(mm) = args.marker_noise_mm {
        if !(mm.is_finite() && mm > 0.0) {
            anyhow::bail!("--marker-noise-mm must be a positive number of millimetres, got {mm}");
        }
    }
    let model = jointfit::model::Model::compile(&fit_spec)?;
    let start = match &args.seed_from {
        Some(seed) => {
            let earlier = jointfit_io::model_file::load_model(seed)?;
            workflow::transfer_params(&model, &earlier, seed)?
        }
        None => model.nominal_params(),
    };
    let trials: Vec<Trial> = args
        .trials
        .iter()
        .map(|t| load_trial(t, args.up, args.filter))
        .collect::<Result<_>>()?;
    for (trial, path) in trials.iter().zip(&args.trials) {
        crate::common::run_checks(&model, trial, path)?;
    }
    let refs: Vec<&Trial> = trials.iter().collect();
    let groups: Vec<&str> = args.joints.iter().map(|s| s.as_str()).collect();
    let free = params_for_groups(&model, &groups)?;
    let clock = Instant::now();
    let mut observer = ProgressObserver::new();
    let cal = workflow::calibrate(
        &model,
        &start,
        &refs,
        &free,
        &fit_settings(&args),
        &mut observer,
    )?;
    observer.finish();
    let seconds = clock.elapsed().as_secs_f64();
    let print = |cal: &Calibration| -> Result<()> {
        if args.json {
            let report = Report {
                calibration: cal,
                seconds,
            };
            println!("{}", serde_json::to_string_pretty(&report)?);
        } else {
            print_report(cal, seconds);
        }
        Ok(())
    };
    if !cal.converged && !args.accept_unconverged {
        print(&cal)?;
        return Err(
            crate::output::Unconverged(format!("the calibration ({})", cal.termination)).into(),
        );
    }
    // The fitted model keeps the input file's priors (overrides apply to this run only).
    let mut fitted = input_model.spec_with_nominal(&cal.fit.p);
    fitted.name = format!("{} (fitted)", spec.name);
    jointfit_io::model_file::save_spec(&args.output, &fitted)
        .with_context(|| format!("writing {}", args.output.display()))?;
    let html = match &args.report {
        Some(dir) => Some(crate::report_cmd::write_calibration_report(
            dir,
            &spec.name,
            baseline_label(&args),
            &model,
            &named_trials(&args.trials, &refs),
            &cal,
            &provenance(&args),
            seconds,
        )?),
        None => None,
    };
    print(&cal)?;
    if !args.json {
        println!("wrote {}", args.output.display());
        if let Some(path) = html {
            println!("wrote {}", path.display());
        }
    }
    Ok(())
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

fn named_trials<'t>(paths: &[PathBuf], trials: &[&'t Trial]) -> Vec<(String, &'t Trial)> {
    paths
        .iter()
        .map(|p| crate::report_cmd::display_name(p))
        .zip(trials.iter().copied())
        .collect()
}

/// The files and options of this run, for the report's settings table.
fn provenance(args: &CalibrateArgs) -> jointfit_report::calibration::Provenance {
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
        args.up,
        args.filter,
    ));
    crate::report_cmd::provenance(inputs)
}
