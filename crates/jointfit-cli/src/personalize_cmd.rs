//! `jointfit personalize`: a static trial + a marker set → a subject model TOML
//! (the anatomical-landmark method, [`jointfit_landmarks`]).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{ArgGroup, Args, ValueEnum};
use jointfit::model::lower_limb::Side;
use jointfit::trial::Trial;
use jointfit_landmarks::auto::ChosenSet;
use jointfit_landmarks::bilateral::personalize_sides;
use jointfit_landmarks::bilateral::PersonalizedModel;
use jointfit_landmarks::bilateral::Sides;
use jointfit_landmarks::functional::apply::FunctionalTrials;
use jointfit_landmarks::keypoints::personalize_keypoints;
use jointfit_landmarks::keypoints::KeypointSet;
use jointfit_landmarks::keypoints::KEYPOINT_PRESET_NAMES;
use jointfit_landmarks::markerset::MarkerSet;
use jointfit_landmarks::markerset::PRESET_NAMES;
use jointfit_landmarks::{HipCentreMethod, PersonalizeOptions};

use crate::personalize_summary::{BothSummary, HjcComparison, LabCentres, Summary};

use crate::common::{load_trial, Up};

#[derive(Args)]
#[command(group(ArgGroup::new("static_input").required(true).args(["static_file", "static_trial"])))]
pub struct PersonalizeArgs {
    /// Static standing trial (.trc or .c3d).
    #[arg(value_name = "STATIC")]
    static_file: Option<PathBuf>,
    /// The static trial as an option (the same as the positional STATIC; give one of them).
    #[arg(long = "static", value_name = "FILE")]
    static_trial: Option<PathBuf>,
    /// Marker set: a TOML file, a preset (gait2392, opencap, opencap-video, jam, plugin-gait,
    /// plugin-gait-sacr, plugin-gait-medial, plugin-gait-basic, rajagopal; docs/markersets.md),
    /// a video keypoint set (keypoints, keypoints-shoulders: hip, knee and ankle keypoints as
    /// joint centres) or auto: the preset whose labels the static trial carries, else the set
    /// `markers suggest` proposes (the default).
    #[arg(long, value_name = "MAP.toml|PRESET|auto", default_value = "auto")]
    markers: String,
    /// Subject measurements (Plug-in Gait's knee and ankle widths, leg length, …): a Vicon
    /// .vsk file, or NAME=MM pairs separated by commas (knee_width_r=105,leg_length_l=880;
    /// names in docs/markersets.md). Repeatable; later values override earlier ones, and both
    /// override the C3D's PROCESSING group.
    #[arg(long = "subject", value_name = "FILE.vsk|NAME=MM,…")]
    subject: Vec<String>,
    /// Joint centres stored in the static trial to compare ours with, as JOINT=LABEL pairs
    /// for the right leg (hip, knee, ankle), e.g. hip=RFEP,knee=RFEO,ankle=RTIO (Vicon's
    /// Plug-in Gait outputs); the left leg's labels swap the R/L prefix.
    #[arg(long = "compare-jc", value_name = "JOINT=LABEL,…")]
    compare_jc: Option<String>,
    /// Which legs to model: both (one model, pelvis shared, 54 parameters; falls back to the
    /// one leg whose markers the trial carries, with a warning) or one (27 parameters).
    #[arg(long, value_enum, default_value = "both")]
    side: SideArg,
    /// The laboratory's vertical axis; the trial is rotated to the model's Y-up frame.
    /// Default: detected from the static trial's marker layout (head and pelvis above the
    /// feet), else y. Recorded in the model as `lab_up` for every later command.
    #[arg(long, value_enum)]
    up: Option<Up>,
    /// Hip-centre regression (default: davis when the static trial needs Plug-in Gait's
    /// chord function, having no medial knee or ankle markers, and the leg length is given;
    /// else bell).
    #[arg(long, value_enum)]
    hip: Option<HipArg>,
    /// Length of the averaged static window (s).
    #[arg(long, default_value_t = 1.0, value_name = "SECONDS", allow_negative_numbers = true, value_parser = crate::validate::positive)]
    window: f64,
    /// Model name written into the file (default: the output file's stem).
    #[arg(long)]
    name: Option<String>,
    /// A marker of the trial holding another hip-centre estimate (e.g. OpenCap's R_HJC):
    /// prints its distance from ours, averaged over the same window. Repeatable.
    #[arg(long = "compare-hjc", value_name = "LABEL")]
    compare_hjc: Vec<String>,
    /// Functional hip trial (circumduction / star arcs): the hip centre by SCoRE
    /// (Ehrig et al. 2006) replaces the regression as nominal value and prior mean.
    #[arg(long, value_name = "FILE")]
    functional_hip: Option<PathBuf>,
    /// Functional knee trial (flexion-extension): the knee axis by SARA (Ehrig et al. 2007)
    /// replaces the epicondylar axis as nominal value and prior mean.
    #[arg(long, value_name = "FILE")]
    functional_knee: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
    /// Write the model even when its thigh, shank or pelvis measures are outside adult ranges
    /// (otherwise: exit status 5, nothing written).
    #[arg(long)]
    accept_rejected: bool,
    /// Output model file (TOML), written atomically.
    #[arg(short = 'o', long = "output", value_name = "SUBJECT.toml")]
    output: PathBuf,
}

#[derive(Clone, Copy, ValueEnum)]
enum SideArg {
    Both,
    Right,
    Left,
}

#[derive(Clone, Copy, ValueEnum)]
enum HipArg {
    Bell,
    Harrington,
    Davis,
}

/// The marker set of `--markers`: a TOML file or a preset (also `bench --markers`).
pub(crate) fn load_marker_set(arg: &str) -> Result<MarkerSet> {
    let path = Path::new(arg);
    if path.exists() {
        let text =
            jointfit_io::limits::read_text(path, jointfit_io::limits::DOCUMENT_BYTES, "marker set")
                .with_context(|| format!("{}: cannot read", path.display()))?;
        return Ok(MarkerSet::from_toml(&text, &path.display().to_string())?);
    }
    if PRESET_NAMES.contains(&arg) {
        return Ok(MarkerSet::preset(arg)?);
    }
    bail!(
        "{arg:?} is neither a marker-set file nor a preset ({})",
        PRESET_NAMES.join(", ")
    )
}

/// What to try when the static trial lacks labels of the chosen marker set: the presets
/// other than `chosen` whose every label (for one of the legs asked) the trial has, else
/// `markers suggest`. Said before the error's details, which may be cut short.
fn preset_hint(labels: &[String], chosen: &str, sides: Sides, static_name: &str) -> String {
    let legs: &[Side] = match sides {
        Sides::Both => &[Side::Right, Side::Left],
        Sides::One(Side::Right) => &[Side::Right],
        Sides::One(Side::Left) => &[Side::Left],
    };
    let fits: Vec<&str> = PRESET_NAMES
        .into_iter()
        .filter(|name| *name != chosen)
        .filter(|name| {
            let Ok(set) = MarkerSet::preset(name).map(|s| s.resolve(labels)) else {
                return false;
            };
            legs.iter().any(|&side| {
                set.roles(side)
                    .is_ok_and(|roles| roles.iter().all(|(_, l)| labels.contains(l)))
            })
        })
        .collect();
    match fits.first() {
        Some(first) => format!(
            " (the trial's labels fit the preset{} {}: --markers {first})",
            if fits.len() > 1 { "s" } else { "" },
            fits.join(", ")
        ),
        None => format!(
            " (no preset fits its labels; `jointfit markers suggest {static_name}` proposes a \
             marker set from them)"
        ),
    }
}

/// The subject model's body measurements against adult ranges
/// ([`jointfit::plausibility::anthropometry`]): outside one, the static trial, its units or the
/// marker map is wrong, and nothing is written (exit status 5) unless `accept`.
fn refuse_implausible(static_name: &str, model: &PersonalizedModel, accept: bool) -> Result<()> {
    let compiled = jointfit::model::Model::compile(model.spec())?;
    let bad: Vec<String> =
        jointfit::plausibility::anthropometry(&compiled, &compiled.nominal_params())
            .iter()
            .filter(|m| !m.ok())
            .map(jointfit_app::present::implausible_measure)
            .collect();
    if bad.is_empty() {
        return Ok(());
    }
    let cause = format!(
        "{static_name}: the subject model is not a plausible adult leg: {}; check the static \
         trial's units and the marker map",
        bad.join("; ")
    );
    if accept {
        eprintln!("jointfit: warning: {cause} (kept: --accept-rejected)");
        return Ok(());
    }
    Err(crate::output::Rejected(cause).into())
}

pub fn run(mut args: PersonalizeArgs) -> Result<()> {
    // clap's group guarantees exactly one of the two spellings.
    let Some(static_trial) = args.static_file.take().or(args.static_trial.take()) else {
        bail!("personalize: no static trial (give it as STATIC or --static FILE)");
    };
    check_files(&args, &static_trial)?;
    // Recorded in the model as `lab_up`; said in the error context if personalize fails.
    let (up, _) = crate::common::up_or_detected(&static_trial, args.up)?;
    let trial = load_trial(&static_trial, up, None)?;
    let scale: Vec<_> = jointfit::checks::check_scale(&trial).into_iter().collect();
    crate::common::report_findings(&scale, &static_trial)?;
    let chosen = choose_set(&args.markers, &trial, &static_trial)?;
    let static_name = static_trial.display().to_string();
    let mut model = personalize(&args, &trial, &chosen, up, &static_trial)?;
    let spec = model.spec_mut();
    spec.description = format!("{}; from {static_name}", spec.description);
    spec.lab_up = Some(up.into());

    let compare = compare_hjc(&args.compare_hjc, &trial, &model, &static_name)?;
    // Joint centres in the file's own lab frame, and against the stored ones asked for.
    let centres = crate::personalize_subject::centres_lab(&model, up);
    let jc_compare = match &args.compare_jc {
        Some(spec) => crate::personalize_subject::compare_jc(&model, &trial, up, spec)
            .with_context(|| format!("{static_name}: --compare-jc"))?,
        None => Vec::new(),
    };

    refuse_implausible(&static_name, &model, args.accept_rejected)?;
    jointfit_io::atomic::write_atomic(&args.output, model.spec().to_toml().as_bytes())
        .with_context(|| format!("{}: cannot write", args.output.display()))?;
    let set_name = match &chosen {
        ChosenSet::Markers(s) => s.name.clone(),
        ChosenSet::Keypoints(k) => k.name.clone(),
    };
    let mut legs: Vec<Summary> = model
        .legs()
        .into_iter()
        .zip(compare)
        .map(|((side, r), c)| Summary::of(r, &set_name, side, &static_name, &args.output, c))
        .collect();
    let centres = LabCentres::new(centres, jc_compare);
    let (json, text) = match &model {
        PersonalizedModel::Both(b) => {
            let s = BothSummary::of(b, &static_name, &args.output, legs, centres);
            (serde_json::to_string_pretty(&s)?, s.render())
        }
        PersonalizedModel::One(..) => {
            let s = legs.remove(0).with_centres(centres);
            (serde_json::to_string_pretty(&s)?, s.render())
        }
    };
    if args.json {
        println!("{json}");
    } else {
        print!("{text}");
    }
    Ok(())
}

/// The input and output files exist and can be read or written.
fn check_files(args: &PersonalizeArgs, static_trial: &Path) -> Result<()> {
    let mut files = crate::output::Files::new()
        .input("static trial", static_trial)
        .model("marker set", &args.markers);
    for (what, trial) in [
        ("--functional-hip trial", &args.functional_hip),
        ("--functional-knee trial", &args.functional_knee),
    ] {
        if let Some(t) = trial {
            files = files.input(what, t);
        }
    }
    files.output("output", &args.output).check()?;
    crate::output::check_model_extension(&args.output, &["toml"])
}

/// The marker set `--markers` names: `auto` (chosen from the static trial's labels, the
/// reason said on stderr), a keypoint preset, or a marker-set file or preset.
fn choose_set(markers: &str, trial: &Trial, static_trial: &Path) -> Result<ChosenSet> {
    if markers == "auto" {
        let choice = jointfit_landmarks::auto::choose(trial, "auto")
            .with_context(|| format!("{}: --markers auto", static_trial.display()))?;
        eprintln!("jointfit: {}: {}", static_trial.display(), choice.reason);
        for note in &choice.notes {
            eprintln!("jointfit: note: {note}");
        }
        Ok(choice.set)
    } else if KEYPOINT_PRESET_NAMES.contains(&markers) {
        Ok(ChosenSet::Keypoints(Box::new(KeypointSet::preset(
            markers,
        )?)))
    } else {
        Ok(ChosenSet::Markers(Box::new(load_marker_set(markers)?)))
    }
}

/// The personalization options of the command line, the static trial and the chosen set.
fn options(
    args: &PersonalizeArgs,
    trial: &Trial,
    chosen: &ChosenSet,
    static_trial: &Path,
) -> Result<PersonalizeOptions> {
    let subject = crate::personalize_subject::measurements(static_trial, &args.subject)?;
    let name = args.name.clone().unwrap_or_else(|| {
        args.output
            .file_stem()
            .map_or("subject".into(), |s| s.to_string_lossy().into_owned())
    });
    let hip_centre = match args.hip {
        Some(HipArg::Bell) => HipCentreMethod::Bell,
        Some(HipArg::Harrington) => HipCentreMethod::Harrington,
        Some(HipArg::Davis) => HipCentreMethod::Davis,
        // Plug-in Gait's hip where the trial needs its chord function (no medial markers).
        None if matches!(chosen, ChosenSet::Markers(set)
            if set.resolve(trial.labels()).uses_chord())
            && subject.mean_leg_length().is_some() =>
        {
            HipCentreMethod::Davis
        }
        None => HipCentreMethod::Bell,
    };
    Ok(PersonalizeOptions {
        hip_centre,
        window_seconds: args.window,
        name,
        subject,
        ..PersonalizeOptions::default()
    })
}

/// The personalized model of the static trial (and the functional trials), errors said with
/// the reading options and a hint of what to give instead; a warning goes to stderr.
fn personalize(
    args: &PersonalizeArgs,
    trial: &Trial,
    chosen: &ChosenSet,
    up: Up,
    static_trial: &Path,
) -> Result<PersonalizedModel> {
    let static_name = static_trial.display().to_string();
    let opts = options(args, trial, chosen, static_trial)?;
    let sides = match args.side {
        SideArg::Both => Sides::Both,
        SideArg::Right => Sides::One(Side::Right),
        SideArg::Left => Sides::One(Side::Left),
    };
    let load = |p: &Option<PathBuf>| p.as_ref().map(|p| load_trial(p, up, None)).transpose();
    let (hip_trial, knee_trial) = (load(&args.functional_hip)?, load(&args.functional_knee)?);
    let func = FunctionalTrials {
        hip: hip_trial.as_ref(),
        knee: knee_trial.as_ref(),
        ..FunctionalTrials::default()
    };
    let outcome = match chosen {
        ChosenSet::Markers(set) => personalize_sides(trial, set, sides, &opts, &func),
        ChosenSet::Keypoints(k) => {
            if func.hip.is_some() || func.knee.is_some() {
                bail!(
                    "functional trials need a marker set, not the keypoint set {:?}",
                    k.name
                );
            }
            personalize_keypoints(trial, k, sides, &opts)
        }
    };
    // A static trial without the set's labels: name the presets that fit them instead.
    let hint = match &outcome {
        Err(jointfit_landmarks::LandmarkError::MissingMarkers { .. }) => {
            preset_hint(trial.labels(), &args.markers, sides, &static_name)
        }
        _ => String::new(),
    };
    // A missing subject measurement: say how to give one after the message.
    let outcome = outcome.map_err(|e| match e {
        jointfit_landmarks::LandmarkError::MissingMeasurement { .. } => {
            anyhow::anyhow!("{e}{}", crate::personalize_subject::HINT)
        }
        e => anyhow::Error::new(e),
    });
    let outcome = outcome.with_context(|| {
        let up = up
            .to_possible_value()
            .map_or("?".into(), |v| v.get_name().to_string());
        let functional: Vec<String> = [&args.functional_hip, &args.functional_knee]
            .into_iter()
            .flatten()
            .map(|p| p.display().to_string())
            .collect();
        let with = if functional.is_empty() {
            String::new()
        } else {
            format!(" with functional trial(s) {}", functional.join(", "))
        };
        format!("{static_name} (read with --up={up}){with}: cannot personalize{hint}")
    })?;
    if let Some(w) = &outcome.warning {
        eprintln!("warning: {static_name}: {w}");
    }
    Ok(outcome.model)
}

/// Each `--compare-hjc` label against the hip centre of the leg nearest to it (pelvis
/// frame, mm), per leg of `model`.
fn compare_hjc(
    labels: &[String],
    trial: &Trial,
    model: &PersonalizedModel,
    static_name: &str,
) -> Result<Vec<Vec<HjcComparison>>> {
    let mut compare: Vec<Vec<HjcComparison>> = model.legs().iter().map(|_| Vec::new()).collect();
    for label in labels {
        let c = trial
            .index_of(label)
            .with_context(|| format!("{static_name}: --compare-hjc"))?;
        let mut best: Option<(usize, HjcComparison)> = None;
        for (k, (side, r)) in model.legs().into_iter().enumerate() {
            let w = &r.report.window;
            let pts: Vec<_> = (w.first..w.end()).filter_map(|f| trial.get(f, c)).collect();
            if pts.is_empty() {
                bail!("{static_name}: marker {label:?} is missing throughout the static window");
            }
            let mean = pts.iter().sum::<nalgebra::Vector3<f64>>() / pts.len() as f64;
            let d = r.frames.pelvis.rot.transpose() * (mean - r.report.hip_centre);
            let row = HjcComparison {
                marker: label.clone(),
                distance_mm: d.norm() * 1e3,
                delta_mm: [d.x * 1e3, d.y * 1e3, side.sign() * d.z * 1e3],
            };
            if best
                .as_ref()
                .is_none_or(|(_, b)| row.distance_mm < b.distance_mm)
            {
                best = Some((k, row));
            }
        }
        if let Some((k, row)) = best {
            compare[k].push(row);
        }
    }
    Ok(compare)
}
