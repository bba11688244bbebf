//! `jointfit calibrate <SUBJECT.toml> <TRIAL>... --joints <LIST> --method <M> -o <FITTED.toml>`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use jointfit::calibrate::joint::{solve_joint_observed, JointOptions};
use jointfit::calibrate::pso::{solve_pso, PsoOptions};
use jointfit::calibrate::uncertainty::{
    analyze, unidentifiable_subset, Identifiability, Uncertainty, UncertaintyOptions,
};
use jointfit::calibrate::varpro::{solve_varpro_observed, VarProOptions};
use jointfit::calibrate::{params_for_groups, Fit, Problem};
use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::ParamId;
use jointfit::model::{Model, Unit};
use jointfit::trial::Trial;
use serde::Serialize;

use crate::common::{load_trial, Up, MM};

/// The outer optimizer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Joint sparse Levenberg–Marquardt over all frames and parameters (fast default).
    Joint,
    /// Two-level Gauss-Newton on the reduced (variable-projection) Jacobian.
    Gradient,
    /// Particle swarm (global), then polished by the joint solver.
    Pso,
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
    pub method: Method,
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
}

#[derive(Serialize)]
pub struct ParamReport {
    pub name: String,
    pub group: String,
    pub unit: &'static str,
    pub start: f64,
    pub fitted: f64,
    pub change: f64,
    /// Standard error (same unit), from `uncertainty_method`; `None`: not determined.
    pub se: Option<f64>,
    /// 95 % interval (same unit).
    pub ci95: Option<[f64; 2]>,
    /// `determined`, `poor` or `undetermined`.
    pub identifiability: Option<Identifiability>,
    pub uncertainty_method: Option<jointfit::calibrate::uncertainty::SeMethod>,
}

#[derive(Serialize)]
pub struct Report {
    pub method: Method,
    pub frames: usize,
    pub skipped_frames: usize,
    pub free_parameters: usize,
    pub parameters: Vec<ParamReport>,
    pub rms_before_mm: f64,
    pub rms_after_mm: f64,
    pub marker_rms_before_mm: Vec<(String, f64)>,
    pub marker_rms_after_mm: Vec<(String, f64)>,
    pub cost_before: f64,
    pub cost_after: f64,
    pub iterations: usize,
    pub evaluations: usize,
    pub converged: bool,
    pub seconds: f64,
    /// The objective after every outer iteration, per optimizer stage (for the HTML report).
    pub convergence: Vec<ConvergenceStage>,
    /// Uncertainty and identifiability of the free parameters (see `jointfit::calibrate::uncertainty`).
    pub uncertainty: Option<Uncertainty>,
    /// Parameters held at their starting values by `--fix-unidentifiable`.
    pub fixed_unidentifiable: Vec<String>,
    /// Several starts (`--starts N`): the optima they reached.
    pub multistart: Option<MultiStart>,
}

/// One optimizer stage (e.g. the particle swarm, then its polish).
#[derive(Debug, Clone, Serialize)]
pub struct ConvergenceStage {
    pub stage: String,
    /// `e_inner` (mm²) at the start of the stage, then after each of its iterations.
    pub objective_mm2: Vec<f64>,
}

/// Per-model-marker RMS distance (m) for parameters `p` and per-frame coordinates.
fn per_marker_rms(prob: &Problem, p: &[f64], qs: &[Vec<f64>]) -> Vec<f64> {
    let model = prob.model;
    let mut kin = KinData::new(model);
    let mut sums = vec![(0.0, 0usize); model.n_markers()];
    for (targets, q) in prob.frames.iter().zip(qs) {
        forward_kinematics(model, p, q, Want::POSITIONS, &mut kin);
        for j in 0..model.n_markers() {
            if !targets[j].x.is_nan() {
                sums[j].0 += (targets[j] - kin.markers[j]).norm_squared();
                sums[j].1 += 1;
            }
        }
    }
    sums.iter()
        .map(|(s, n)| {
            if *n == 0 {
                f64::NAN
            } else {
                (s / *n as f64).sqrt()
            }
        })
        .collect()
}

/// Runs one calibration on trials already in memory (no uncertainty analysis).
#[allow(dead_code)] // library-style entry point for subcommands that need no intervals
pub fn calibrate(
    model: &Model,
    start: Vec<f64>,
    trials: &[&Trial],
    groups: &[&str],
    method: Method,
    seed: u64,
) -> Result<(Fit, Report)> {
    let free = params_for_groups(model, groups)?;
    calibrate_params(model, start, trials, &free, method, seed, 1)
}

/// [`calibrate`] with the free parameters given by id.
pub fn calibrate_params(
    model: &Model,
    start: Vec<f64>,
    trials: &[&Trial],
    free: &[ParamId],
    method: Method,
    seed: u64,
    starts: usize,
) -> Result<(Fit, Report)> {
    let prob = Problem::new(model, start.clone(), free, trials)?;
    let clock = Instant::now();
    let q0 = prob.initial_coords(&start);
    let s0 = prob.to_scaled(&start);
    let mut ws = jointfit::ik::IkWorkspace::new(model);
    let mut q_before = q0.clone();
    let cost_before = prob.inner(&start, &mut q_before, &mut ws);
    // Progress on stderr (see `progress`) and the objective per stage for the report.
    let mut bars = crate::progress::StageProgress::new("iterations");
    let mut convergence: Vec<ConvergenceStage> = Vec::new();
    let mut step = |stage: &str, iteration: usize, expected: Option<usize>, cost: f64| {
        let mm2 = cost * MM * MM;
        let msg = format!("objective {mm2:.1} mm²");
        bars.step(stage, iteration as u64, expected.map(|n| n as u64), &msg);
        match convergence.last_mut() {
            Some(c) if c.stage == stage => c.objective_mm2.push(mm2),
            _ => convergence.push(ConvergenceStage {
                stage: stage.to_string(),
                objective_mm2: vec![mm2],
            }),
        }
    };
    let fit = match method {
        Method::Joint => {
            let stage = "joint Levenberg-Marquardt";
            step(stage, 0, None, cost_before);
            let opts = JointOptions::default();
            solve_joint_observed(&prob, &s0, q0, &opts, |i, c| step(stage, i, None, c))
        }
        Method::Gradient => {
            let stage = "two-level Gauss-Newton";
            step(stage, 0, None, cost_before);
            let opts = VarProOptions::default();
            solve_varpro_observed(&prob, &s0, q0, &opts, |i, c| step(stage, i, None, c))
        }
        Method::Pso => {
            let opts = PsoOptions {
                seed,
                ..PsoOptions::default()
            };
            // The swarm usually runs to its budget: a bar with an ETA.
            let max = Some(opts.max_iterations);
            let swarm = solve_pso(&prob, &q0, &opts, |i, c| step("particle swarm", i, max, c));
            let stage = "joint Levenberg-Marquardt polish";
            step(stage, 0, None, swarm.cost);
            let mut polished = solve_joint_observed(
                &prob,
                &swarm.s,
                swarm.coords.clone(),
                &JointOptions::default(),
                |i, c| step(stage, i, None, c),
            );
            polished.iterations += swarm.iterations;
            polished.evaluations += swarm.evaluations;
            polished
        }
    };
    bars.finish();
    let (fit, multistart) = if starts > 1 && method != Method::Pso {
        let (best, summary) = multi_start(&prob, &start, fit, starts, seed, method);
        (best, Some(summary))
    } else {
        (fit, None)
    };
    let seconds = clock.elapsed().as_secs_f64();
    let names = |v: Vec<f64>| -> Vec<(String, f64)> {
        model
            .markers()
            .iter()
            .zip(v)
            .map(|(m, r)| (m.name.clone(), r * MM))
            .collect()
    };
    let parameters = prob
        .free
        .iter()
        .map(|&i| {
            let par = &model.parameters()[i];
            let (unit, k) = match par.unit {
                Unit::Metre => ("mm", MM),
                Unit::Radian => ("deg", 180.0 / std::f64::consts::PI),
            };
            ParamReport {
                name: par.name.clone(),
                group: par.group.clone(),
                unit,
                start: start[i] * k,
                fitted: fit.p[i] * k,
                change: (fit.p[i] - start[i]) * k,
                se: None,
                ci95: None,
                identifiability: None,
                uncertainty_method: None,
            }
        })
        .collect();
    let report = Report {
        method,
        frames: prob.frames.len(),
        skipped_frames: prob.skipped.len(),
        free_parameters: prob.n_free(),
        parameters,
        rms_before_mm: prob.marker_rms(&start, &q_before) * MM,
        rms_after_mm: prob.marker_rms(&fit.p, &fit.coords) * MM,
        marker_rms_before_mm: names(per_marker_rms(&prob, &start, &q_before)),
        marker_rms_after_mm: names(per_marker_rms(&prob, &fit.p, &fit.coords)),
        cost_before,
        cost_after: fit.cost,
        iterations: fit.iterations,
        evaluations: fit.evaluations,
        converged: fit.converged,
        seconds,
        convergence,
        uncertainty: None,
        fixed_unidentifiable: Vec::new(),
        multistart,
    };
    Ok((fit, report))
}

/// What several starts found (`--starts N`).
#[derive(Debug, Clone, Serialize)]
pub struct MultiStart {
    pub starts: usize,
    /// Final objective of every start (mm²); start 0 is the given start.
    pub objective_mm2: Vec<f64>,
    /// Starts whose objective is within 1e-9 (relative) of the best.
    pub reached_best: usize,
    /// Per free parameter: the range (max − min) of its fitted value over the starts
    /// (mm or deg).
    pub spread: Vec<(String, f64)>,
}

/// Refits from `starts − 1` further starting points, the start moved by up to ±20 mm and
/// ±10° on every free parameter (uniform, seeded by `seed`), and keeps the lowest
/// objective. The noisy problem can have local minima (Reinbolt et al. 2005 used a global
/// swarm for that reason); the spread of the optima tells how much it matters here.
fn multi_start(
    prob: &Problem,
    start: &[f64],
    first: Fit,
    starts: usize,
    seed: u64,
    method: Method,
) -> (Fit, MultiStart) {
    let mut fits = vec![first];
    for k in 1..starts {
        let restart = jointfit_experiments::protocol::FitSettings::default();
        let p0 = jointfit_experiments::synth::restart_point(
            prob.model,
            start,
            &prob.free,
            restart.restart_mm,
            restart.restart_deg,
            seed,
            k,
        );
        let q0 = prob.initial_coords(&p0);
        let s0 = prob.to_scaled(&p0);
        fits.push(match method {
            Method::Gradient => {
                solve_varpro_observed(prob, &s0, q0, &VarProOptions::default(), |_, _| {})
            }
            _ => solve_joint_observed(prob, &s0, q0, &JointOptions::default(), |_, _| {}),
        });
    }
    let best = (0..fits.len())
        .min_by(|&a, &b| fits[a].cost.total_cmp(&fits[b].cost))
        .expect("at least one start");
    let best_cost = fits[best].cost;
    let spread = prob
        .free
        .iter()
        .map(|&i| {
            let par = &prob.model.parameters()[i];
            let k = match par.unit {
                Unit::Metre => MM,
                Unit::Radian => 180.0 / std::f64::consts::PI,
            };
            let (lo, hi) = fits
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), f| {
                    (lo.min(f.p[i]), hi.max(f.p[i]))
                });
            (par.name.clone(), (hi - lo) * k)
        })
        .collect();
    let summary = MultiStart {
        starts,
        objective_mm2: fits.iter().map(|f| f.cost * MM * MM).collect(),
        reached_best: fits
            .iter()
            .filter(|f| f.cost - best_cost <= 1e-9 * best_cost)
            .count(),
        spread,
    };
    (fits.swap_remove(best), summary)
}

/// Uncertainty settings from the command line.
pub fn uncertainty_options(
    threshold_mm: f64,
    threshold_deg: f64,
    bootstrap: usize,
    seed: u64,
) -> UncertaintyOptions {
    UncertaintyOptions {
        threshold_m: threshold_mm / MM,
        threshold_rad: threshold_deg.to_radians(),
        bootstrap_replicates: bootstrap,
        seed,
        ..UncertaintyOptions::default()
    }
}

/// Adds the uncertainty of `fit` (free parameters `free`, same trials and start) to `report`.
pub fn attach_uncertainty(
    model: &Model,
    start: &[f64],
    trials: &[&Trial],
    free: &[ParamId],
    fit: &Fit,
    opts: &UncertaintyOptions,
    report: &mut Report,
) -> Result<()> {
    let prob = Problem::new(model, start.to_vec(), free, trials)?;
    let u = analyze(&prob, fit, opts);
    for (row, pu) in report.parameters.iter_mut().zip(&u.params) {
        row.se = pu.se;
        row.ci95 = pu.ci;
        row.identifiability = Some(pu.status);
        row.uncertainty_method = Some(pu.method);
    }
    report.uncertainty = Some(u);
    Ok(())
}

/// Calibrates, analyses the uncertainty and, with `fix_unidentifiable`, refits with the
/// parameters the trials cannot determine held at their starting values.
#[allow(clippy::too_many_arguments)]
pub fn calibrate_with_uncertainty(
    model: &Model,
    start: Vec<f64>,
    trials: &[&Trial],
    groups: &[&str],
    method: Method,
    seed: u64,
    opts: &UncertaintyOptions,
    fix_unidentifiable: bool,
    starts: usize,
) -> Result<(Fit, Report)> {
    let mut free = params_for_groups(model, groups)?;
    let (mut fit, mut report) =
        calibrate_params(model, start.clone(), trials, &free, method, seed, starts)?;
    let mut fixed = Vec::new();
    // Subset selection plans on the reduced normal matrix of the current fit; a refit moves
    // the optimum a little, so the selection is repeated (at most three rounds).
    for _ in 0..if fix_unidentifiable { 3 } else { 0 } {
        let prob = Problem::new(model, start.clone(), &free, trials)?;
        let drop = unidentifiable_subset(&prob, &fit, opts);
        if drop.is_empty() {
            break;
        }
        if drop.len() == free.len() {
            bail!(
                "no parameter of {} can be determined from these trials within the thresholds; \
                 nothing left to fit",
                groups.join(",")
            );
        }
        fixed.extend(
            drop.iter()
                .map(|&k| model.parameters()[free[k].0].name.clone()),
        );
        free = free
            .iter()
            .enumerate()
            .filter(|(k, _)| !drop.contains(k))
            .map(|(_, id)| *id)
            .collect();
        (fit, report) =
            calibrate_params(model, start.clone(), trials, &free, method, seed, starts)?;
    }
    attach_uncertainty(model, &start, trials, &free, &fit, opts, &mut report)?;
    report.fixed_unidentifiable = fixed;
    Ok((fit, report))
}

pub fn print_report(report: &Report) {
    println!(
        "{:?}: {} free parameters, {} frames ({} skipped), {} iterations, {} evaluations, {:.3} s{}",
        report.method,
        report.free_parameters,
        report.frames,
        report.skipped_frames,
        report.iterations,
        report.evaluations,
        report.seconds,
        if report.converged { "" } else { " (not converged)" }
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
            "{} starts: {} reached the best objective (to 1e-9); objectives {:.3} to {:.3} mm²",
            ms.starts, ms.reached_best, lo, hi
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
    if let Some(u) = &report.uncertainty {
        print_uncertainty_notes(u, &report.fixed_unidentifiable);
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
    let model = jointfit_io::model_file::load_model(&args.model)?;
    let mut start = model.nominal_params();
    if let Some(seed) = &args.seed_from {
        let earlier = jointfit_io::model_file::load_model(seed)?;
        for (i, par) in model.parameters().iter().enumerate() {
            match earlier.param_id(&par.name) {
                Some(id) => {
                    start[i] = earlier.parameters()[id.0]
                        .nominal
                        .clamp(par.lower, par.upper)
                }
                None => bail!(
                    "{seed}: has no parameter {:?} of the subject model",
                    par.name
                ),
            }
        }
    }
    let trials: Vec<Trial> = args
        .trials
        .iter()
        .map(|t| load_trial(t, args.up, args.filter))
        .collect::<Result<_>>()?;
    let refs: Vec<&Trial> = trials.iter().collect();
    let groups: Vec<&str> = args.joints.iter().map(|s| s.as_str()).collect();
    let opts = uncertainty_options(
        args.threshold_mm,
        args.threshold_deg,
        args.bootstrap,
        args.seed,
    );
    let (fit, report) = calibrate_with_uncertainty(
        &model,
        start.clone(),
        &refs,
        &groups,
        args.method,
        args.seed,
        &opts,
        args.fix_unidentifiable,
        args.starts as usize,
    )?;
    if !report.converged && !args.accept_unconverged {
        if args.json {
            println!("{}", serde_json::to_string_pretty(&report)?);
        } else {
            print_report(&report);
        }
        return Err(crate::output::Unconverged("the calibration".into()).into());
    }
    let mut fitted = model.spec_with_nominal(&fit.p);
    fitted.name = format!("{} (fitted)", spec.name);
    jointfit_io::model_file::save_spec(&args.output, &fitted)
        .with_context(|| format!("writing {}", args.output.display()))?;
    let html = match &args.report {
        Some(dir) => Some(crate::report_cmd::write_calibration_report(
            dir, &args, &spec.name, &model, &start, &refs, &fit, &report,
        )?),
        None => None,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_report(&report);
        println!("wrote {}", args.output.display());
        if let Some(path) = html {
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}
