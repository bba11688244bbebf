//! `jointfit ik --setup ik_setup.xml`: an OpenSim `InverseKinematicsTool` setup run as
//! OpenSim runs it (docs/opensim.md).
//!
//! The setup is read by [`jointfit_io::osim_setup`]; this file turns it into the core's plain
//! data: the model's marker weights (the setup's `IKMarkerTask`s), one
//! [`jointfit::ik::CoordinateTask`] per applied `IKCoordinateTask` with its target in every
//! frame, the frames of the time range, and OpenSim's handling of what the markers leave
//! undetermined (such a coordinate stays where it was: at its default in the first frame, at
//! the previous frame's value after). It solves the trial with [`jointfit::ik::trial_fit::solve_trial`]
//! without gross-error rejection (`--reject-outliers` asks for it), and writes the motion to
//! `output_motion_file` and, when the setup reports errors, OpenSim's
//! `<name>_ik_marker_errors.sto` to `results_directory`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use jointfit::ik::trial_fit::solve_trial;
use jointfit::ik::trial_fit::TrialFit;
use jointfit::ik::{CoordinateTask, IkOptions, MarkerMap};
use jointfit::model::custom::MotionType;
use jointfit::model::functions::{Function, FunctionSpec};
use jointfit::model::Model;
use jointfit::trial::Trial;
use jointfit_io::osim_setup::{read_ik_setup, IkSetup, IkTaskSet, TaskValue};
use jointfit_io::sto::{read_sto, write_sto, Table};

use crate::common::{load_for_model, report_findings, CheckJson, Columns, TrialJson};
use crate::ik_cmd::{angles_table, errors_csv, print_summary, summarize, IkArgs};

pub fn run(args: IkArgs) -> Result<()> {
    let setup_path = args.setup.clone().expect("--setup given");
    let setup = read_ik_setup(&setup_path)?;
    let (model_path, trial_path, output) = input_paths(&args, &setup, &setup_path)?;
    let errors_sto = if setup.report_errors {
        errors_file(&setup, &setup_path)?
    } else {
        None
    };
    let outputs = [
        ("output", Some(output.as_path())),
        ("--errors", args.errors.as_deref()),
        ("results_directory", errors_sto.as_deref()),
    ];
    check_files(&model_path, &setup_path, &trial_path, &outputs)?;
    let given = jointfit_io::model_file::load_model(&model_path)?;
    let model = weighted_model(&given, &setup.tasks, &setup_path)?;
    let loaded = load_for_model(
        &trial_path,
        &args.read,
        &model,
        args.filter,
        Columns::ForModel,
    )?;
    let (first, last) = frame_range(&loaded.trial, setup.time_range).with_context(|| {
        format!(
            "{}: time_range {} {}",
            setup_path.display(),
            setup.time_range[0],
            setup.time_range[1]
        )
    })?;
    let trial = loaded.trial.slice_frames(first, last + 1);
    if !model
        .markers()
        .iter()
        .any(|m| m.weight > 0.0 && trial.labels().contains(&m.name))
    {
        bail!(
            "{}: no marker of the trial is a tracked marker of the model {}; nothing written",
            trial_path.display(),
            model_path
        );
    }
    let tasks = coordinate_tasks(&model, &setup, &trial)?;
    let (mut map, absent) = MarkerMap::allowing_absent(&model, trial.labels());
    map.coordinate_tasks = tasks;
    if let Some(units) = jointfit::checks::check_scale(&trial) {
        report_findings(&[units], &trial_path)?;
    }
    let findings = jointfit::checks::check_trial_before_ik(&model, &trial, &map);
    report_findings(&findings, &trial_path)?;
    let tracked_absent: Vec<String> = absent
        .into_iter()
        .filter(|n| {
            model
                .markers()
                .iter()
                .any(|m| &m.name == n && m.weight > 0.0)
        })
        .collect();
    crate::common::warn_absent_markers(&trial_path, &tracked_absent);
    let opts = ik_options(args.reject_outliers);
    let p = model.nominal_params();
    let start = Instant::now();
    let fit = solve_trial(&model, &p, &trial, &map, &opts)
        .with_context(|| trial_path.display().to_string())?;
    let seconds = start.elapsed().as_secs_f64();
    if !fit.frames.iter().any(|f| f.solved()) {
        bail!(
            "{}: no frame could be solved; nothing written",
            trial_path.display()
        );
    }
    write_results(
        &model,
        &trial,
        &fit,
        &output,
        errors_sto.as_deref(),
        args.errors.as_deref(),
    )?;
    let mut summary = summarize(&model, &trial, &fit, seconds);
    if !(summary.mean_frame_rms_mm.is_finite() && summary.max_frame_rms_mm.is_finite()) {
        bail!(
            "{}: inverse kinematics gave non-finite marker errors",
            trial_path.display()
        );
    }
    summary.checks = findings.iter().map(CheckJson::from).collect();
    summary.trial = Some(TrialJson::new(&trial_path, &loaded, &findings));
    if let Some(path) = &errors_sto {
        if !args.json {
            println!("wrote {}", path.display());
        }
    }
    print_summary(&summary, args.json, seconds, &output)
}

/// The inputs exist and the outputs (those given) can be written.
fn check_files(
    model: &str,
    setup: &Path,
    trial: &Path,
    outputs: &[(&str, Option<&Path>)],
) -> Result<()> {
    let mut files = crate::output::Files::new()
        .model("model", model)
        .input("setup", setup)
        .input("trial", trial);
    for (what, path) in outputs {
        if let Some(path) = path {
            files = files.output(what, path);
        }
    }
    files.check()
}

/// OpenSim's inverse kinematics: a coordinate no goal depends on stays where it was;
/// outlying markers are rejected only when asked.
fn ik_options(reject_outliers: bool) -> IkOptions {
    IkOptions {
        hold_undetermined: true,
        outlier_distance: if reject_outliers {
            IkOptions::default().outlier_distance
        } else {
            f64::INFINITY
        },
        ..IkOptions::default()
    }
}

/// The model, the trial and the output: from the command line, else from the setup file
/// (whose named files must exist).
fn input_paths(
    args: &IkArgs,
    setup: &IkSetup,
    setup_path: &Path,
) -> Result<(String, PathBuf, PathBuf)> {
    let model_path = match (&args.model, setup.model_path()) {
        (Some(m), _) => m.clone(),
        (None, Some(p)) => {
            if !p.exists() {
                bail!(
                    "{}: model_file {:?} not found (looked in the working directory and in {}); \
                     give the model as the first argument",
                    setup_path.display(),
                    setup.model_file.as_deref().unwrap_or(""),
                    setup.dir().display()
                );
            }
            p.display().to_string()
        }
        (None, None) => bail!(
            "{}: no model_file; give the model as the first argument",
            setup_path.display()
        ),
    };
    let trial_path = match (&args.trial, setup.marker_path()) {
        (Some(t), _) => t.clone(),
        (None, Some(p)) => {
            if !p.exists() {
                bail!(
                    "{}: marker_file {:?} not found ({}); give the trial as the second argument",
                    setup_path.display(),
                    setup.marker_file.as_deref().unwrap_or(""),
                    p.display()
                );
            }
            p
        }
        (None, None) => bail!(
            "{}: no marker_file; give the trial as the second argument",
            setup_path.display()
        ),
    };
    let output = match (&args.output, setup.output_path()) {
        (Some(o), _) => o.clone(),
        (None, Some(p)) => p,
        (None, None) => bail!(
            "{}: no output_motion_file; give one with -o",
            setup_path.display()
        ),
    };
    Ok((model_path, trial_path, output))
}

/// The coordinates (`output`), OpenSim's marker errors file and the `--errors` table.
fn write_results(
    model: &Model,
    trial: &Trial,
    fit: &TrialFit,
    output: &Path,
    errors_sto: Option<&Path>,
    errors_csv_path: Option<&Path>,
) -> Result<()> {
    write_sto(output, &angles_table(model, trial, fit))
        .with_context(|| format!("writing {}", output.display()))?;
    if let Some(path) = errors_sto {
        write_sto(path, &marker_errors_table(model, trial, fit))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(path) = errors_csv_path {
        jointfit_io::atomic::write_atomic(path, errors_csv(model, trial, fit).as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// Where OpenSim writes the marker errors: `<name>_ik_marker_errors.sto` in the results
/// directory, which is made when its parent exists (OpenSim's `IO::makeDir` makes one
/// level). A results directory that cannot be made (a setup from another machine, its path
/// absolute there) is said and skipped: the motion is the result.
fn errors_file(setup: &IkSetup, setup_path: &Path) -> Result<Option<PathBuf>> {
    let dir = setup.results_path();
    if !dir.is_dir() {
        let parent_exists = match dir.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.is_dir(),
            _ => true,
        };
        if !parent_exists {
            eprintln!(
                "jointfit: warning: {}: results_directory {:?} does not exist here; the marker \
                 errors are not written",
                setup_path.display(),
                setup.results_directory.as_deref().unwrap_or("")
            );
            return Ok(None);
        }
        std::fs::create_dir(&dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    Ok(Some(
        dir.join(format!("{}_ik_marker_errors.sto", setup.name)),
    ))
}

/// `model` with the marker weights of `tasks` ([`IkTaskSet::apply_marker_weights`]). A task
/// naming no model marker is ignored, as OpenSim ignores it, with a warning.
pub fn weighted_model(model: &Model, tasks: &IkTaskSet, setup: &Path) -> Result<Model> {
    let mut spec = model.spec().clone();
    let unknown = tasks.apply_marker_weights(&mut spec);
    if !unknown.is_empty() {
        eprintln!(
            "jointfit: warning: {}: IKMarkerTask {} name no marker of the model; ignored",
            setup.display(),
            unknown.join(", ")
        );
    }
    Ok(Model::compile(&spec)?)
}

/// The frames of `range` (s) as OpenSim's IK picks them: the rows nearest to the start and to
/// the end, each clamped to the trial's times. Errors when the trial has no frame.
fn frame_range(trial: &Trial, range: [f64; 2]) -> Result<(usize, usize)> {
    let n = trial.n_frames();
    if n == 0 {
        bail!("the trial has no frame");
    }
    let (t0, t1) = (trial.time(0), trial.time(n - 1));
    let nearest = |t: f64| {
        let t = t.clamp(t0, t1);
        (0..n)
            .min_by(|&a, &b| {
                (trial.time(a) - t)
                    .abs()
                    .total_cmp(&(trial.time(b) - t).abs())
            })
            .expect("n > 0")
    };
    let (first, last) = (nearest(range[0]), nearest(range[1]));
    if last < first {
        bail!("no frame of the trial lies in it");
    }
    Ok((first, last))
}

/// One [`CoordinateTask`] per applied `IKCoordinateTask` of a coordinate in `q`, with its
/// target in every frame of `trial`. Tasks of locked and coupled coordinates are dropped (OpenSim
/// drops those of locked coordinates); a coordinate the model lacks is an error, as in
/// OpenSim.
pub fn coordinate_tasks(
    model: &Model,
    setup: &IkSetup,
    trial: &Trial,
) -> Result<Vec<CoordinateTask>> {
    let mut file: Option<(PathBuf, Table)> = None;
    let mut out = Vec::new();
    for task in setup.tasks.applied_coordinates() {
        let where_ = || format!("{}, line {}", setup.tasks.path.display(), task.line);
        let Some(c) = model.coordinates().iter().position(|c| c.name == task.name) else {
            if model.dependents().iter().any(|d| d.name == task.name) {
                continue;
            }
            bail!(
                "{}: IKCoordinateTask {:?}: the model has no such coordinate",
                where_(),
                task.name
            );
        };
        let coord = &model.coordinates()[c];
        let values = match &task.value {
            TaskValue::Default => vec![coord.default; trial.n_frames()],
            TaskValue::Manual(v) => vec![*v; trial.n_frames()],
            TaskValue::FromFile => {
                if file.is_none() {
                    let Some(path) = setup.coordinate_path() else {
                        bail!(
                            "{}: IKCoordinateTask {:?} takes its value from_file but the setup \
                             has no coordinate_file",
                            where_(),
                            task.name
                        );
                    };
                    let table = read_sto(&path)
                        .with_context(|| format!("{}: coordinate_file", setup.path.display()))?;
                    file = Some((path, table));
                }
                let (path, table) = file.as_ref().expect("read above");
                from_file(table, path, &task.name, coord.motion, trial)?
            }
        };
        out.push(CoordinateTask {
            coordinate: c,
            weight: task.weight,
            values,
        });
    }
    Ok(out)
}

/// A coordinate's column of a coordinate file at the trial's frame times: the interpolating
/// natural quintic spline through the column (OpenSim's `GCVSplineSet` of degree 5 at zero
/// error variance), degrees converted to radians for rotational coordinates when the file is
/// in degrees (OpenSim's `convertDegreesToRadians`).
fn from_file(
    table: &Table,
    path: &Path,
    name: &str,
    motion: MotionType,
    trial: &Trial,
) -> Result<Vec<f64>> {
    let Some(col) = table.columns.iter().position(|c| c == name) else {
        bail!("{}: no column {name:?}", path.display());
    };
    let scale = if table.in_degrees && motion == MotionType::Rotational {
        1f64.to_radians()
    } else {
        1.0
    };
    let (x, y): (Vec<f64>, Vec<f64>) = table
        .rows
        .iter()
        .filter(|r| r[0].is_finite() && r[col].is_finite())
        .map(|r| (r[0], r[col] * scale))
        .unzip();
    let f = Function::try_from(&FunctionSpec::GcvSpline { degree: 5, x, y })
        .map_err(|e| anyhow::anyhow!("{}: column {name:?}: {e}", path.display()))?;
    Ok((0..trial.n_frames())
        .map(|i| f.eval(trial.time(i)).0)
        .collect())
}

/// OpenSim's `<name>_ik_marker_errors.sto`: per frame the total squared error (m²), the RMS
/// and the largest marker error (m) over the tracked markers present in the frame.
fn marker_errors_table(model: &Model, trial: &Trial, fit: &TrialFit) -> Table {
    let mut table = Table::new(
        "Model Marker Errors from IK",
        &[
            "total_squared_error",
            "marker_error_RMS",
            "marker_error_max",
        ],
        false,
    );
    for (f, errors) in fit.errors.iter().enumerate() {
        let d: Vec<f64> = errors
            .iter()
            .zip(model.markers())
            .filter(|(e, m)| e.is_finite() && m.weight > 0.0)
            .map(|(e, _)| *e)
            .collect();
        let total: f64 = d.iter().map(|e| e * e).sum();
        let rms = if d.is_empty() {
            0.0
        } else {
            (total / d.len() as f64).sqrt()
        };
        let max = d.iter().cloned().fold(0.0, f64::max);
        let row = if fit.frames[f].solved() {
            vec![trial.time(f), total, rms, max]
        } else {
            vec![trial.time(f), f64::NAN, f64::NAN, f64::NAN]
        };
        table.rows.push(row);
    }
    table
}
