//! `jointfit ik <SUBJECT.toml> <TRIAL> -o <OUT.mot> [--errors <ERR.csv>] [--filter HZ] [--json]`,
//! and `jointfit ik --setup <ik_setup.xml>` (an OpenSim `InverseKinematicsTool` setup: its
//! model, marker file, task weights, coordinate tasks, time range and output; `setup.rs`).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use jointfit::ik::trial_fit::TrialFit;
use jointfit::ik::IkOptions;
use jointfit::model::custom::MotionType;
use jointfit::model::Model;
use jointfit::trial::Trial;
use jointfit::workflow::WorkflowError;
use jointfit_app::present::MM_PER_M;
use jointfit_io::sto::{write_sto, Table};
use serde::Serialize;

use crate::common::{load_for_model, report_findings, CheckJson, Columns, TrialJson};

#[derive(Args)]
pub struct IkArgs {
    /// Subject model (TOML file, OpenSim .osim or built-in name); with --setup, replaces the
    /// setup's model_file.
    #[arg(required_unless_present = "setup")]
    pub model: Option<String>,
    /// Motion file (.trc or .c3d); with --setup, replaces the setup's marker_file.
    #[arg(required_unless_present = "setup")]
    pub trial: Option<PathBuf>,
    /// Joint angles as an OpenSim .mot (degrees, metres); with --setup, replaces the setup's
    /// output_motion_file.
    #[arg(short, long, required_unless_present = "setup")]
    pub output: Option<PathBuf>,
    /// An OpenSim InverseKinematicsTool setup file (OpenSim 3.x or 4.x): solves OpenSim's
    /// weighted objective with its marker weights and coordinate tasks over its time range and
    /// writes the motion (and the marker errors) where it says (docs/opensim.md).
    #[arg(long, value_name = "IK_SETUP.xml")]
    pub setup: Option<PathBuf>,
    /// With --setup: reject gross marker errors after the fit as `ik` does without a setup
    /// (OpenSim does not).
    #[arg(long, requires = "setup")]
    pub reject_outliers: bool,
    /// Per-frame and per-marker distance errors (mm) as CSV.
    #[arg(long)]
    pub errors: Option<PathBuf>,
    /// Low-pass filter cutoff in Hz (zero-phase Butterworth, effective order 4).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::validate::cutoff_hz)]
    pub filter: Option<f64>,
    #[command(flatten)]
    pub read: crate::common::TrialArgs,
    /// Solve frames whose markers leave some coordinates undetermined by holding those at
    /// the previous frame's values (instead of leaving the frame out).
    #[arg(long)]
    pub hold_undetermined: bool,
    /// Keep every marker sample that is finite and within 1 km (no gross-error rejection
    /// after the fit; OpenSim's behaviour).
    #[arg(long)]
    pub keep_outliers: bool,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
pub(crate) struct Summary {
    frames: usize,
    solved_frames: usize,
    /// Runs of frames not solved (file frame numbers, inclusive) and why.
    unsolved: Vec<UnsolvedJson>,
    /// Frames solved with coordinates held at the previous frame's values.
    held_frames: usize,
    /// Marker samples rejected as gross errors.
    rejected: Vec<RejectedJson>,
    /// Data-check findings (warnings; errors stop the command), with the option that
    /// repairs each.
    pub(crate) checks: Vec<CheckJson>,
    /// The trial as read: vertical, reader notes, repairs (and the checks again).
    pub(crate) trial: Option<TrialJson>,
    /// The marker RMS every command prints ([`jointfit::workflow::marker_rms::marker_rms`]: every fitted frame and
    /// present marker, the calibration's inverse kinematics); `None` for a model without
    /// joint parameters or an `.osim` setup.
    pub(crate) rms_mm: Option<f64>,
    /// Mean and largest of the per-frame RMS of this command's inverse kinematics.
    pub(crate) mean_frame_rms_mm: f64,
    pub(crate) max_frame_rms_mm: f64,
    marker_rms_mm: Vec<(String, f64)>,
    solve_seconds: f64,
    frames_per_second: f64,
}

#[derive(Serialize)]
struct UnsolvedJson {
    first_frame: i64,
    last_frame: i64,
    frames: usize,
    reason: String,
}

#[derive(Serialize)]
struct RejectedJson {
    frame: i64,
    marker: String,
}

pub fn run(args: IkArgs) -> Result<()> {
    if args.setup.is_some() {
        return crate::ik_setup::run(args);
    }
    let (Some(model_name), Some(trial_path), Some(output)) = (
        args.model.as_deref(),
        args.trial.as_deref(),
        args.output.as_deref(),
    ) else {
        bail!("ik needs MODEL, TRIAL and -o OUTPUT (or --setup IK_SETUP.xml)");
    };
    let mut files = crate::output::Files::new()
        .model("model", model_name)
        .input("trial", trial_path)
        .output("output", output);
    if let Some(e) = &args.errors {
        files = files.output("--errors", e);
    }
    files.check()?;
    let model = jointfit_io::model_file::load_model(model_name)?;
    // The data checks run in `solve`: the units check first (an error stops the command
    // before the IK), the others alongside the IK, the moved-cluster check after it, from its
    // fit when it is the IK the check would run.
    let loaded = load_for_model(
        trial_path,
        &args.read,
        &model,
        args.filter,
        Columns::ForModel,
    )?;
    let trial = &loaded.trial;
    let opts = IkOptions::with_rules(args.hold_undetermined, !args.keep_outliers);
    let solved = solve(&model, trial, trial_path, model_name, &opts, false)?;
    let model = solved.held_model.as_ref().unwrap_or(&model);
    let seconds = solved.seconds;
    let findings = solved.findings;
    let fit = solved.fit;
    let trial_json = TrialJson::new(trial_path, &loaded, &findings);
    write_sto(output, &angles_table(model, trial, &fit))
        .with_context(|| format!("writing {}", output.display()))?;
    if let Some(path) = &args.errors {
        jointfit_io::atomic::write_atomic(path, errors_csv(model, trial, &fit).as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let mut summary = summarize(model, trial, &fit, seconds);
    if !(summary.mean_frame_rms_mm.is_finite() && summary.max_frame_rms_mm.is_finite()) {
        bail!(
            "{}: inverse kinematics gave non-finite marker errors; nothing written",
            trial_path.display()
        );
    }
    // A model without joint parameters (an .osim read as it is) has no calibration, so no
    // RMS of its definition: the per-frame figures only.
    summary.rms_mm =
        jointfit::workflow::marker_rms::marker_rms(model, &model.nominal_params(), &[trial])
            .ok()
            .map(|r| jointfit_app::present::mm(r.rms));
    summary.checks = findings.iter().map(CheckJson::from).collect();
    summary.trial = Some(trial_json);
    print_summary(&summary, args.json, seconds, output)
}

/// The summary on stdout: JSON, or the lines and the per-marker table.
pub(crate) fn print_summary(
    summary: &Summary,
    json: bool,
    seconds: f64,
    output: &std::path::Path,
) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!(
            "{} frames ({} solved) in {:.3} s ({:.0} frames/s)",
            summary.frames, summary.solved_frames, seconds, summary.frames_per_second
        );
        if let Some(rms) = summary.rms_mm {
            println!(
                "RMS marker distance: {rms:.2} mm (every frame and marker, as check, calibrate \
                 and report print it)"
            );
        }
        println!(
            "RMS marker error per frame: mean {:.2} mm, max {:.2} mm",
            summary.mean_frame_rms_mm, summary.max_frame_rms_mm
        );
        if let Some(line) = unsolved_line(summary) {
            println!("{line}");
        }
        if summary.held_frames > 0 {
            println!(
                "{} frames solved with undetermined coordinates held at the previous frame's values",
                summary.held_frames
            );
        }
        if let Some(line) = rejected_line(&summary.rejected) {
            println!("{line}");
        }
        let mut t = crate::table::Table::new(&["marker", "RMS mm"]);
        for (name, v) in &summary.marker_rms_mm {
            t.row(vec![name.clone(), format!("{v:.2}")]);
        }
        print!("{}", t.render());
        println!("wrote {}", output.display());
    }
    Ok(())
}

/// What `ik` computes between reading the trial and writing its files ([`solve`]).
pub struct Solved {
    /// The model the IK ran on when some coordinates were held at their defaults (no marker
    /// of the trial determines them); `None`: the model given.
    pub held_model: Option<Model>,
    pub fit: TrialFit,
    /// The data-check findings (the checks before the IK, then the moved-cluster check),
    /// already printed.
    pub findings: Vec<jointfit::checks::Finding>,
    /// Wall time of the IK itself (s).
    pub seconds: f64,
}

/// The work of `jointfit ik` on a trial read from `path` (named in messages, with the model's
/// name `model_name`): the units check (its error stops the command before the IK), then
/// the inverse kinematics with the other data checks alongside (`rayon::join`: the checks
/// take the second core while the IK's chunks are not using it), then the moved-cluster check
/// from the IK's fit. Warnings are printed on stderr in the order they always were: the
/// checks', the held coordinates', the absent markers', the moved clusters'; with `quiet`
/// nothing is printed (errors still stop). `bench`'s `ik_io` times this same function.
pub fn solve(
    model: &Model,
    trial: &Trial,
    path: &std::path::Path,
    model_name: &str,
    opts: &IkOptions,
    quiet: bool,
) -> Result<Solved> {
    let report_findings = |findings: &[jointfit::checks::Finding], path: &std::path::Path| {
        if quiet {
            match findings
                .iter()
                .find(|f| f.severity == jointfit::checks::Severity::Error)
            {
                Some(f) => bail!("{}: {}", path.display(), f.message),
                None => Ok(()),
            }
        } else {
            report_findings(findings, path)
        }
    };
    let (map, _) = jointfit::ik::MarkerMap::allowing_absent(model, trial.labels());
    if let Some(units) = jointfit::checks::check_scale(trial) {
        report_findings(&[units], path)?;
    }
    if !model
        .markers()
        .iter()
        .any(|m| trial.labels().contains(&m.name))
    {
        bail!(
            "{}: no marker of the trial is a marker of the model {} ({} model markers); nothing \
             written",
            path.display(),
            model_name,
            model.markers().len()
        );
    }
    // Coordinates no marker of the trial determines (a toe joint without toe markers) stay
    // at their defaults, as in OpenSim's IK, and are said so.
    let (held_model, held) = jointfit::ik::hold::hold_undetermined(model, &[trial])?;
    let checked_model = model;
    let ik_model = held_model.as_ref().unwrap_or(checked_model);
    // Markers the file lacks altogether are missing in every frame; frames whose present
    // markers leave a coordinate undetermined are reported as unsolved, as for gaps.
    let p = ik_model.nominal_params();
    let ((run, seconds), mut findings) = rayon::join(
        || {
            let start = Instant::now();
            let run = jointfit::workflow::ik::ik_trial(ik_model, &p, trial, opts);
            (run, start.elapsed().as_secs_f64())
        },
        || jointfit::checks::check_trial_before_ik(checked_model, trial, &map),
    );
    report_findings(&findings, path)?;
    if !held.is_empty() && !quiet {
        eprintln!(
            "jointfit: warning: {}: no marker determines {}; held at the model's default values",
            path.display(),
            held.join(", ")
        );
    }
    let run = match run {
        Ok(run) => run,
        Err(e @ WorkflowError::NoFrameSolved { .. }) => {
            bail!("{}: {e}; nothing written", path.display())
        }
        Err(e) => return Err(e).with_context(|| path.display().to_string()),
    };
    if !quiet {
        crate::common::warn_absent_markers(path, &run.absent);
    }
    let fit = run.fit;
    let offsets = if held.is_empty() {
        jointfit::checks::offsets::check_offsets(checked_model, trial, &map, Some((&p, opts, &fit)))
    } else {
        // The IK ran on the model with coordinates held: not the check's.
        jointfit::checks::offsets::check_offsets(checked_model, trial, &map, None)
    };
    report_findings(&offsets, path)?;
    findings.extend(offsets);
    Ok(Solved {
        held_model,
        fit,
        findings,
        seconds,
    })
}

pub(crate) fn summarize(model: &Model, trial: &Trial, fit: &TrialFit, seconds: f64) -> Summary {
    let rms: Vec<f64> = (0..fit.frames.len())
        .map(|f| jointfit::ik::trial_fit::rms(fit.errors[f].iter().copied()))
        .filter(|v| !v.is_nan())
        .collect();
    let first = trial.first_frame();
    let unsolved = fit
        .unsolved_ranges()
        .into_iter()
        .map(|r| UnsolvedJson {
            first_frame: first + r.first as i64,
            last_frame: first + r.last as i64,
            frames: r.last - r.first + 1,
            reason: r.reason,
        })
        .collect();
    let rejected = fit
        .frames
        .iter()
        .enumerate()
        .flat_map(|(f, fr)| {
            fr.rejected.iter().map(move |&j| RejectedJson {
                frame: first + f as i64,
                marker: model.markers()[j].name.clone(),
            })
        })
        .collect();
    Summary {
        frames: fit.frames.len(),
        solved_frames: rms.len(),
        unsolved,
        held_frames: fit
            .frames
            .iter()
            .filter(|f| f.solved() && !f.held.is_empty())
            .count(),
        rejected,
        checks: Vec::new(),
        trial: None,
        rms_mm: None,
        mean_frame_rms_mm: rms.iter().sum::<f64>() / rms.len().max(1) as f64 * MM_PER_M,
        max_frame_rms_mm: rms.iter().cloned().fold(0.0, f64::max) * MM_PER_M,
        marker_rms_mm: model
            .markers()
            .iter()
            .enumerate()
            .map(|(j, m)| {
                let errors = fit.errors.iter().map(|e| e[j]);
                (
                    m.name.clone(),
                    jointfit::ik::trial_fit::rms(errors) * MM_PER_M,
                )
            })
            .collect(),
        solve_seconds: seconds,
        frames_per_second: fit.frames.len() as f64 / seconds.max(1e-12),
    }
}

/// One line for every unsolved frame: `not solved: 7 frames: 40–45 (why), 80 (why)`.
fn unsolved_line(summary: &Summary) -> Option<String> {
    if summary.unsolved.is_empty() {
        return None;
    }
    let total: usize = summary.unsolved.iter().map(|r| r.frames).sum();
    let runs: Vec<String> = summary
        .unsolved
        .iter()
        .map(|r| {
            if r.first_frame == r.last_frame {
                format!("{} ({})", r.first_frame, r.reason)
            } else {
                format!("{}-{} ({})", r.first_frame, r.last_frame, r.reason)
            }
        })
        .collect();
    Some(format!(
        "not solved: {total} frames (file frame numbers): {}",
        runs.join(", ")
    ))
}

/// One line for the rejected samples: counts per marker with the first frame of each.
fn rejected_line(rejected: &[RejectedJson]) -> Option<String> {
    if rejected.is_empty() {
        return None;
    }
    let mut per_marker: Vec<(&str, usize, i64)> = Vec::new();
    for r in rejected {
        match per_marker.iter_mut().find(|(m, _, _)| *m == r.marker) {
            Some(e) => e.1 += 1,
            None => per_marker.push((&r.marker, 1, r.frame)),
        }
    }
    let parts: Vec<String> = per_marker
        .iter()
        .map(|(m, n, f)| format!("{m} in {n} frames (first {f})"))
        .collect();
    Some(format!(
        "rejected as gross errors: {} samples: {}",
        rejected.len(),
        parts.join(", ")
    ))
}

/// Coordinates per frame in OpenSim's `.mot` convention: degrees for rotational
/// coordinates (OpenSim's motion type), locked and coupled coordinates included.
pub fn angles_table(model: &Model, trial: &Trial, fit: &TrialFit) -> Table {
    let names: Vec<&str> = model
        .coordinates()
        .iter()
        .map(|c| c.name.as_str())
        .chain(model.dependents().iter().map(|d| d.name.as_str()))
        .collect();
    let unit = |motion: MotionType, v: f64| match motion {
        MotionType::Rotational => v.to_degrees(),
        MotionType::Translational | MotionType::Coupled => v,
    };
    let mut table = Table::new("Coordinates", &names, true);
    for (f, q) in fit.coords.iter().enumerate() {
        let mut row = vec![trial.time(f)];
        row.extend(
            model
                .coordinates()
                .iter()
                .zip(q)
                .map(|(c, v)| unit(c.motion, *v)),
        );
        row.extend(
            model
                .dependents()
                .iter()
                .map(|d| unit(d.motion, d.value(q))),
        );
        table.rows.push(row);
    }
    table
}

pub(crate) fn errors_csv(model: &Model, trial: &Trial, fit: &TrialFit) -> String {
    let mut out = String::from("frame,time,rms_mm");
    for m in model.markers() {
        out.push(',');
        out.push_str(&jointfit_io::csv::field(&format!("{}_mm", m.name)));
    }
    out.push('\n');
    let cell = |v: f64| {
        if v.is_nan() {
            String::new()
        } else {
            format!("{:.4}", v * MM_PER_M)
        }
    };
    for f in 0..fit.frames.len() {
        out.push_str(&format!(
            "{},{:.6},{}",
            trial.first_frame() + f as i64,
            trial.time(f),
            cell(jointfit::ik::trial_fit::rms(fit.errors[f].iter().copied()))
        ));
        for e in &fit.errors[f] {
            out.push(',');
            out.push_str(&cell(*e));
        }
        out.push('\n');
    }
    out
}
