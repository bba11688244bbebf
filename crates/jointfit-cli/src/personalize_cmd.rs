//! `jointfit personalize`: a static trial + a marker set → a subject model TOML
//! (the anatomical-landmark method, [`jointfit::landmarks`]).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{ArgGroup, Args, ValueEnum};
use jointfit::landmarks::functional::FunctionalTrials;
use jointfit::landmarks::{
    personalize_sides, HipCentreMethod, MarkerSet, PersonalizeOptions, PersonalizedModel, Sides,
    PRESET_NAMES,
};
use jointfit::model::lower_limb::Side;

use crate::personalize_summary::{BothSummary, HjcComparison, Summary};

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
    /// Marker set: a TOML file or a preset (gait2392, opencap, jam, plugin-gait, plugin-gait-basic,
    /// plugin-gait-sacr, rajagopal; docs/markersets.md).
    #[arg(long, value_name = "MAP.toml|PRESET")]
    markers: String,
    /// Which legs to model: both (one model, pelvis shared, 54 parameters; falls back to the
    /// one leg whose markers the trial carries, with a warning) or one (27 parameters).
    #[arg(long, value_enum, default_value = "both")]
    side: SideArg,
    /// The laboratory's vertical axis; the trial is rotated to the model's Y-up frame.
    /// Default: detected from the static trial's marker layout (head and pelvis above the
    /// feet), else y. Recorded in the model as `lab_up` for every later command.
    #[arg(long, value_enum)]
    up: Option<Up>,
    /// Hip-centre regression.
    #[arg(long, value_enum, default_value = "bell")]
    hip: HipArg,
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
}

/// The marker set of `--markers`: a TOML file or a preset (also `bench --markers`).
pub(crate) fn load_marker_set(arg: &str) -> Result<MarkerSet> {
    let path = Path::new(arg);
    if path.exists() {
        let text = std::fs::read_to_string(path)
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
            let Ok(set) = MarkerSet::preset(name) else {
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

pub fn run(mut args: PersonalizeArgs) -> Result<()> {
    // clap's group guarantees exactly one of the two spellings.
    let Some(static_trial) = args.static_file.take().or(args.static_trial.take()) else {
        bail!("personalize: no static trial (give it as STATIC or --static FILE)");
    };
    let mut files = crate::output::Files::new()
        .input("static trial", &static_trial)
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
    let set = load_marker_set(&args.markers)?;
    // Recorded in the model as `lab_up`; said in the error context if personalize fails.
    let (up, _) = crate::common::up_or_detected(&static_trial, args.up)?;
    let trial = load_trial(&static_trial, up, None)?;
    let scale: Vec<_> = jointfit::checks::check_scale(&trial).into_iter().collect();
    crate::common::report_findings(&scale, &static_trial)?;
    let sides = match args.side {
        SideArg::Both => Sides::Both,
        SideArg::Right => Sides::One(Side::Right),
        SideArg::Left => Sides::One(Side::Left),
    };
    let name = args.name.clone().unwrap_or_else(|| {
        args.output
            .file_stem()
            .map_or("subject".into(), |s| s.to_string_lossy().into_owned())
    });
    let opts = PersonalizeOptions {
        hip_centre: match args.hip {
            HipArg::Bell => HipCentreMethod::Bell,
            HipArg::Harrington => HipCentreMethod::Harrington,
        },
        window_seconds: args.window,
        name,
        ..PersonalizeOptions::default()
    };
    let static_name = static_trial.display().to_string();
    let load = |p: &Option<PathBuf>| p.as_ref().map(|p| load_trial(p, up, None)).transpose();
    let (hip_trial, knee_trial) = (load(&args.functional_hip)?, load(&args.functional_knee)?);
    let func = FunctionalTrials {
        hip: hip_trial.as_ref(),
        knee: knee_trial.as_ref(),
        ..FunctionalTrials::default()
    };
    let outcome = personalize_sides(&trial, &set, sides, &opts, &func);
    // A static trial without the set's labels: name the presets that fit them instead.
    let hint = match &outcome {
        Err(jointfit::landmarks::LandmarkError::MissingMarkers { .. }) => {
            preset_hint(trial.labels(), &args.markers, sides, &static_name)
        }
        _ => String::new(),
    };
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
    let mut model = outcome.model;
    let spec = model.spec_mut();
    spec.description = format!("{}; from {static_name}", spec.description);
    spec.lab_up = Some(up.into());

    // Each --compare-hjc label against the hip centre of the leg nearest to it.
    let mut compare: Vec<Vec<HjcComparison>> = model.legs().iter().map(|_| Vec::new()).collect();
    for label in &args.compare_hjc {
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

    jointfit_io::atomic::write_atomic(&args.output, model.spec().to_toml().as_bytes())
        .with_context(|| format!("{}: cannot write", args.output.display()))?;
    let mut legs: Vec<Summary> = model
        .legs()
        .into_iter()
        .zip(compare)
        .map(|((side, r), c)| Summary::of(r, &set, side, &static_name, &args.output, c))
        .collect();
    let (json, text) = match &model {
        PersonalizedModel::Both(b) => {
            let s = BothSummary::of(b, &static_name, &args.output, legs);
            (serde_json::to_string_pretty(&s)?, s.render())
        }
        PersonalizedModel::One(..) => {
            let s = legs.remove(0);
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
