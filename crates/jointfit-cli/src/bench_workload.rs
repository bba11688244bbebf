//! What `jointfit bench` times: a subject model and a gait trial (the workload).
//!
//! * `--static S --trial T --markers SET [--side right|left] [--up AXIS]`: the subject
//!   personalized from the static trial as `jointfit personalize` does by default (the
//!   library's [`personalize`], Bell's hip centre, a 1 s window, the lab's vertical detected
//!   from the static trial's layout unless `--up`, recorded as the model's `lab_up`), one leg
//!   (right unless `--side`), then T read for it (TRC or C3D).
//! * `--model SUBJECT.toml --trial T`: a subject model file (or built-in name) and a trial,
//!   read as `jointfit ik` reads it (`--up`, else the model's `lab_up`, else y).
//! * `--model MODEL.osim --trial T`: a user's OpenSim model with the offset frames of one
//!   leg's hip, knee and ankle as parameters (`calibrate MODEL.osim --joints hip_r,knee_r,
//!   ankle_r`; `--side left` for `_l`; a leg's only joint whose name has the word, such as
//!   `walker_knee_r`, when there is no `knee_r`). Every selected offset scalar is free: the
//!   bench's fit does not hold the redundant ones as `calibrate MODEL.osim` does.
//! * Nothing: OpenCap's `opencap_expert1/{static1,walking1}.trc` with the `opencap` preset,
//!   right leg, up y (the figures of `notebook/performance.md`); without the shared data a
//!   synthetic gait of the built-in leg stands in, and the source says so.
//!
//! In every case the model is the one `ik` and `calibrate` run on these trials
//! ([`crate::common::model_for_trials`]: model markers the trial lacks left out, coordinates
//! no marker determines held). OpenSim's IK is timed on the same model and trial
//! ([`crate::bench_perf::opensim_ik`]): the jointfit model exported to `.osim` (the user's
//! file itself for an `.osim` model: its offsets are the nominal values), and the trial file
//! itself when it is a TRC read without rotation, else a temporary TRC of the markers as
//! jointfit holds them (rotated to Y up, metres).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{ArgGroup, Args, ValueEnum};
use jointfit::ik::IkOptions;
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::Model;
use jointfit::spatial::UpAxis;
use jointfit::trial::Trial;
use jointfit_experiments::synth;
use jointfit_landmarks::{personalize, PersonalizeOptions};

use crate::common::{load_for_model, model_for_trials, Columns, TrialArgs, Up};

/// The subject options of `jointfit bench` (flattened into its arguments).
#[derive(Args, Clone, Default)]
#[command(group(ArgGroup::new("subject").args(["static_trial", "model"])))]
pub struct SubjectArgs {
    /// Static trial (.trc or .c3d) to personalize the timed subject from, as `jointfit
    /// personalize` does by default (with --markers; one leg, --side).
    #[arg(long = "static", value_name = "FILE", requires_all = ["trial", "markers"])]
    pub static_trial: Option<PathBuf>,
    /// The timed subject as a model: a subject TOML (from `personalize`), a built-in name, or
    /// an OpenSim .osim whose hip, knee and ankle offsets of one leg (--side) are fitted.
    #[arg(long, value_name = "SUBJECT.toml|MODEL.osim", requires = "trial")]
    pub model: Option<String>,
    /// Gait trial to time (.trc or .c3d), with --static or --model.
    #[arg(long, value_name = "FILE", requires = "subject")]
    pub trial: Option<PathBuf>,
    /// Marker set of --static: a TOML file or a preset (as `personalize --markers`).
    #[arg(long, value_name = "MAP.toml|PRESET", requires = "static_trial")]
    pub markers: Option<String>,
    /// The leg to personalize (--static) or whose offsets to fit (--model MODEL.osim);
    /// default right.
    #[arg(long, value_enum, requires = "subject")]
    pub side: Option<BenchSide>,
    /// The laboratory's vertical axis in the files (default: detected from the static trial;
    /// with --model the model's lab_up, else y).
    #[arg(long, value_enum, requires = "subject")]
    pub up: Option<Up>,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum BenchSide {
    Right,
    Left,
}

impl From<BenchSide> for Side {
    fn from(s: BenchSide) -> Side {
        match s {
            BenchSide::Right => Side::Right,
            BenchSide::Left => Side::Left,
        }
    }
}

/// The model and trial OpenSim's IK is timed on.
pub struct OpenSimInput {
    /// The user's `.osim` file, when the model was read from one; else the jointfit model is
    /// exported.
    pub osim: Option<PathBuf>,
    /// The trial file, when OpenSim can read it as jointfit holds it (a TRC read without
    /// rotation); else a temporary TRC of the trial is written.
    pub trc: Option<PathBuf>,
}

/// The subject and trial to time, where they came from, and what OpenSim gets.
pub struct Workload {
    pub model: Model,
    pub trial: Trial,
    pub source: String,
    /// `None`: the synthetic stand-in (nothing for OpenSim to compare).
    pub opensim: Option<OpenSimInput>,
}

fn default_dir(data: Option<PathBuf>) -> PathBuf {
    data.or_else(|| std::env::var_os("JOINTFIT_DATA").map(PathBuf::from))
        .unwrap_or_else(|| PathBuf::from("../shared/data"))
        .join("opencap_expert1")
}

/// The workload of `args` (module docs); `data` is the shared data directory of the default.
pub fn workload(args: &SubjectArgs, data: Option<PathBuf>) -> Result<Workload> {
    let side: Side = args.side.unwrap_or(BenchSide::Right).into();
    match (&args.static_trial, &args.model, &args.trial) {
        (Some(stat), None, Some(trial)) => {
            let markers = args
                .markers
                .as_deref()
                .context("--static needs --markers")?;
            from_static(stat, markers, side, args.up, trial)
        }
        (None, Some(model), Some(trial)) => from_model(model, args.side, args.up, trial),
        (None, None, None) => {
            let dir = default_dir(data);
            let (stat, walk) = (dir.join("static1.trc"), dir.join("walking1.trc"));
            if stat.exists() && walk.exists() {
                from_static(&stat, "opencap", Side::Right, Some(Up::Y), &walk)
            } else {
                synthetic(&dir)
            }
        }
        // clap's `requires` rules out the rest.
        _ => bail!("bench: give --trial with --static (and --markers) or with --model"),
    }
}

/// `--static`: personalized as `jointfit personalize --side SIDE` does by default.
fn from_static(
    stat: &Path,
    markers: &str,
    side: Side,
    up: Option<Up>,
    trial: &Path,
) -> Result<Workload> {
    let set = crate::personalize_cmd::load_marker_set(markers)?;
    let (up, _) = crate::common::up_or_detected(stat, up)?;
    let static_trial = crate::common::load_trial(stat, up, None)?;
    let subject = personalize(&static_trial, &set, side, &PersonalizeOptions::default())
        .with_context(|| {
            format!(
                "{}: cannot personalize (--markers {markers})",
                stat.display()
            )
        })?;
    let mut spec = subject.spec;
    spec.lab_up = Some(up.into());
    let model = Model::compile(&spec)?;
    let side_name = if side == Side::Right { "right" } else { "left" };
    let what = format!(
        "the {side_name} leg personalized from {} (--markers {markers})",
        stat.display()
    );
    for_trial(model, trial, Some(up), None, &what)
}

/// `--model`: a subject TOML, a built-in name or an `.osim` file.
fn from_model(
    name: &str,
    side: Option<BenchSide>,
    up: Option<Up>,
    trial: &Path,
) -> Result<Workload> {
    if !jointfit_io::model_file::is_osim(Path::new(name)) {
        if side.is_some() {
            bail!("{name}: --side applies to --static or an .osim --model, not to a subject model");
        }
        let model = jointfit_io::model_file::load_model(name)?;
        return for_trial(model, trial, up, None, &format!("model {name}"));
    }
    let path = Path::new(name);
    if !path.exists() {
        bail!("{name}: no such model file");
    }
    let osim = jointfit_io::osim_read::read_osim(path)?;
    let suffix = match side.map_or(Side::Right, Side::from) {
        Side::Right => "r",
        Side::Left => "l",
    };
    // hip_r, knee_r, ankle_r; or the one joint of the leg named after each (walker_knee_r).
    let joints: Vec<String> = ["hip", "knee", "ankle"]
        .iter()
        .map(|word| {
            let plain = format!("{word}_{suffix}");
            let named: Vec<&str> = osim
                .spec
                .joints
                .iter()
                .map(|j| j.name.as_str())
                .filter(|n| n.ends_with(&format!("_{suffix}")) && n.contains(word))
                .collect();
            match named.as_slice() {
                [one] if osim.spec.joints.iter().all(|j| j.name != plain) => one.to_string(),
                _ => plain,
            }
        })
        .collect();
    let spec = jointfit_app::osim::selection_spec(&osim, &joints, &[])
        .map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let model = Model::compile(&spec).with_context(|| name.to_string())?;
    let what = format!("{name} (offsets of {} fitted)", joints.join(", "));
    let absolute = std::path::absolute(path).with_context(|| name.to_string())?;
    for_trial(model, trial, up, Some(absolute), &what)
}

/// `trial` read for `model` (as `jointfit ik` reads it, every column), the model reduced to
/// the markers the trial has, and OpenSim's inputs.
fn for_trial(
    model: Model,
    path: &Path,
    up: Option<Up>,
    osim: Option<PathBuf>,
    what: &str,
) -> Result<Workload> {
    let read = TrialArgs {
        up,
        ..TrialArgs::default()
    };
    let loaded = load_for_model(path, &read, &model, None, Columns::All)?;
    let trial = loaded.trial;
    let common = model
        .markers()
        .iter()
        .filter(|m| trial.labels().contains(&m.name))
        .count();
    if common == 0 {
        bail!(
            "{}: no marker of the trial is a marker of {what} ({} model markers, e.g. {}); \
             nothing to time",
            path.display(),
            model.markers().len(),
            model.markers().first().map_or("none", |m| m.name.as_str())
        );
    }
    let model = model_for_trials(model, &[&trial], "the bench")?;
    let (trial, frames) = solvable_span(&model, trial, path, what)?;
    let is_trc = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("trc"));
    // OpenSim runs in a scratch folder: the path made absolute.
    let trc = match is_trc && loaded.up == UpAxis::Y && frames.is_empty() {
        true => Some(std::path::absolute(path).with_context(|| path.display().to_string())?),
        false => None,
    };
    Ok(Workload {
        model,
        trial,
        source: format!("{}{frames} with {what}", path.display()),
        opensim: Some(OpenSimInput { osim, trc }),
    })
}

/// The frames from the first to the last that jointfit's IK solves (from the model's
/// nominal parameters): a trial whose subject walks into and out of the capture volume has
/// frames without the model's markers at its ends, which jointfit leaves unsolved and
/// OpenSim's IK cannot take (a frame without markers stops its assembler). Returns the trial
/// cut to them and, when cut, a note (" frames F–L of N").
fn solvable_span(model: &Model, trial: Trial, path: &Path, what: &str) -> Result<(Trial, String)> {
    let p = model.nominal_params();
    let fit = jointfit::workflow::ik::ik_trial(model, &p, &trial, &IkOptions::default())
        .with_context(|| format!("{} with {what}", path.display()))?
        .fit;
    let solved = |q: &&Vec<f64>| q.first().is_some_and(|x| x.is_finite());
    let first = fit.coords.iter().position(|q| solved(&q));
    let last = fit.coords.iter().rposition(|q| solved(&q));
    let (Some(first), Some(last)) = (first, last) else {
        bail!(
            "{}: no frame of the trial can be solved with {what}; nothing to time",
            path.display()
        );
    };
    let n = trial.n_frames();
    if first == 0 && last + 1 == n {
        return Ok((trial, String::new()));
    }
    let note = format!(
        " frames {}–{} of {n} (the others lack the model's markers)",
        first + 1,
        last + 1
    );
    Ok((trial.slice_frames(first, last + 1), note))
}

/// The synthetic stand-in when the default subject's files are not at `dir`.
fn synthetic(dir: &Path) -> Result<Workload> {
    let model = Model::compile(&lower_limb(Side::Right))?;
    let p = model.nominal_params();
    let coords = synth::coordinates(&model, synth::Motion::All, 150)?;
    let (trial, _) = synth::markers(
        &model,
        &p,
        &coords,
        100.0,
        Some(&synth::SkinNoise::default()),
    );
    Ok(Workload {
        model,
        trial,
        source: format!(
            "synthetic 150-frame motion of lower-limb-right with skin noise \
             (no shared data at {})",
            dir.display()
        ),
        opensim: None,
    })
}
