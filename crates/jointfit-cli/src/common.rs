//! Shared pieces of the subcommands: the up-axis option and reading trials with warnings.
//!
//! Commands that read trials for a subject model (`ik`, `calibrate`, `check`, `report`) take
//! the same trial options ([`TrialArgs`], flattened into their arguments) and read through
//! [`load_for_model`]: the vertical is `--up`, else the model's `lab_up`, else `y`; a trial
//! whose marker layout says another axis is up is reported as rotated.

use std::path::Path;

use anyhow::{bail, Context, Result};
use clap::ValueEnum;
use jointfit::spatial::UpAxis;
use jointfit::trial::Trial;
use jointfit_io::trial_file::{LoadOptions, TrialFileError};

/// Which lab axis points up in the input file.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Up {
    Y,
    #[value(name = "-y")]
    NegY,
    Z,
    #[value(name = "-z")]
    NegZ,
    X,
    #[value(name = "-x")]
    NegX,
}

impl From<UpAxis> for Up {
    fn from(u: UpAxis) -> Up {
        match u {
            UpAxis::Y => Up::Y,
            UpAxis::NegY => Up::NegY,
            UpAxis::Z => Up::Z,
            UpAxis::NegZ => Up::NegZ,
            UpAxis::X => Up::X,
            UpAxis::NegX => Up::NegX,
        }
    }
}

impl From<Up> for UpAxis {
    fn from(u: Up) -> UpAxis {
        match u {
            Up::Y => UpAxis::Y,
            Up::NegY => UpAxis::NegY,
            Up::Z => UpAxis::Z,
            Up::NegZ => UpAxis::NegZ,
            Up::X => UpAxis::X,
            Up::NegX => UpAxis::NegX,
        }
    }
}

/// Reads a motion file, checks it is plausible, rotates it to Y up and low-pass filters it
/// when asked ([`jointfit_io::trial_file::prepare_trial`]), printing its warnings on stderr.
pub fn load_trial(path: &Path, up: Up, filter_hz: Option<f64>) -> Result<Trial> {
    let (trial, notes) = jointfit_io::trial_file::read_trial_noted(path)?;
    crate::validate::check_trial(path, &trial)?;
    for note in notes {
        eprintln!("jointfit: warning: {}: {note}", path.display());
    }
    prepare(trial, path, up.into(), filter_hz)
}

/// `up` when given, else the lab's vertical detected from `path`'s marker layout
/// ([`jointfit::vertical::detect_up`]), else y with a warning on stderr. The second value
/// describes a detection ("z (from 20 labelled markers, 3° off the axis)") for the caller
/// to say once its work succeeded.
pub fn up_or_detected(path: &Path, up: Option<Up>) -> Result<(Up, Option<String>)> {
    if let Some(up) = up {
        return Ok((up, None));
    }
    let (raw, _) = jointfit_io::trial_file::read_trial_noted(path)?;
    Ok(match jointfit::vertical::detect_up(&raw) {
        Some(d) => (Up::from(d.up), Some(d.to_string())),
        None => {
            eprintln!(
                "jointfit: warning: {}: cannot tell the up axis from the marker labels; \
                 assuming y (pass --up)",
                path.display()
            );
            (Up::Y, None)
        }
    })
}

/// The trial options of the commands that read trials for a subject model.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct TrialArgs {
    /// Which axis of the file points up (default: the subject model's `lab_up`, recorded by
    /// `personalize`; else y).
    #[arg(long, value_enum)]
    pub up: Option<Up>,
    /// Leave this marker out (e.g. one re-attached between the static and this trial).
    /// Repeatable.
    #[arg(long = "exclude-marker", value_name = "NAME")]
    pub exclude_marker: Vec<String>,
    /// Exchange two labels, in the whole trial or from file frame F on (`A,B@F`) or in frames
    /// F–L (`A,B@F-L`), as the data checks suggest. Repeatable.
    #[arg(long = "swap-labels", value_name = "A,B[@F[-L]]")]
    pub swap_labels: Vec<String>,
    /// Fill gaps of at most N frames: rigid-body fill from the segment's other markers, cubic
    /// spline where the segment has too few (`jointfit::repair`).
    #[arg(long = "fill-gaps", value_name = "N", default_value_t = 0)]
    pub fill_gaps: usize,
}

impl TrialArgs {
    /// The repairs asked for ([`jointfit::repair::RepairOptions`]).
    pub fn repairs(&self) -> Result<jointfit::repair::RepairOptions> {
        let swaps: Vec<jointfit::repair::Swap> = self
            .swap_labels
            .iter()
            .map(|s| s.parse::<jointfit::repair::Swap>())
            .collect::<Result<_, _>>()?;
        crate::validate::distinct_swaps(&swaps)?;
        Ok(jointfit::repair::RepairOptions {
            exclude: self.exclude_marker.clone(),
            swaps,
            fill_gaps: self.fill_gaps,
        })
    }
}

/// A trial read for a subject model, with what the reading noticed.
pub struct Loaded {
    pub trial: Trial,
    /// The lab's vertical the trial was rotated from.
    pub up: UpAxis,
    /// Where `up` came from: `--up`, `model` or `default`.
    pub up_source: &'static str,
    /// The file reader's notes (short data, assumed units, extra rows) and the vertical's
    /// warnings, one sentence each (also printed on stderr).
    pub notes: Vec<String>,
    /// What [`jointfit::repair::repair`] did, one sentence each (also printed on stderr).
    pub repairs: Vec<String>,
}

/// Which markers of a trial a command reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Columns {
    /// Every marker (commands that show or check the whole file).
    All,
    /// The model's markers: the IK and the calibration use no others, and a TRC file's other
    /// columns are then not parsed (`docs/io.md`). The data checks and the vertical's
    /// warning then look at these markers only. Every marker when repairs are asked for
    /// (`--exclude-marker`, `--swap-labels`, `--fill-gaps` name or report markers of the
    /// whole file).
    ForModel,
}

/// Reads `path` for `model` ([`TrialArgs`]; module docs): the vertical from `--up`, the
/// model's `lab_up` or `y`, a warning when the markers say another axis is up, then filtering.
/// `columns` says which markers are read ([`Columns`]).
pub fn load_for_model(
    path: &Path,
    args: &TrialArgs,
    model: &jointfit::model::Model,
    filter_hz: Option<f64>,
    columns: Columns,
) -> Result<Loaded> {
    if model.markers().is_empty() {
        bail!(
            "model \"{}\" has no markers, so no trial can be fitted to it",
            model.spec().name
        );
    }
    let options = args.repairs()?;
    let no_repairs = options == jointfit::repair::RepairOptions::default();
    let names: std::collections::HashSet<&str> =
        model.markers().iter().map(|m| m.name.as_str()).collect();
    let keep = |label: &str| names.contains(label);
    let select: Option<jointfit_io::trc::Select> =
        (columns == Columns::ForModel && no_repairs).then_some(&keep);
    let (trial, mut notes) = jointfit_io::trial_file::read_trial_selected(path, select)?;
    crate::validate::check_trial(path, &trial)?;
    let (up, up_source) = match (args.up, model.spec().lab_up) {
        (Some(u), _) => (u.into(), "--up"),
        (None, Some(u)) => (u, "model"),
        (None, None) => (UpAxis::Y, "default"),
    };
    let given = match up_source {
        "--up" => format!("--up {up}"),
        "model" => format!("up {up} from the subject model's lab_up"),
        _ => format!("up {up} (the default)"),
    };
    notes.extend(
        jointfit_app::present::rotation_warning(&trial, up, &given).map(|(w, axis)| {
            format!("{w}; pass --up {axis} if that is right")
                + &converted_hint(path, &trial, up_source)
        }),
    );
    for note in &notes {
        eprintln!("jointfit: warning: {}: {note}", path.display());
    }
    let mut trial = prepare(trial, path, up, None)?;
    let mut repairs = Vec::new();
    if !no_repairs {
        let (fixed, actions) = jointfit::repair::repair(&trial, Some(model), &options)
            .with_context(|| path.display().to_string())?;
        for a in &actions {
            eprintln!("jointfit: {}: repair: {a}", path.display());
        }
        repairs = actions.iter().map(|a| a.to_string()).collect();
        trial = fixed;
    }
    if filter_hz.is_some() {
        trial = prepare(trial, path, UpAxis::Y, filter_hz)?;
    }
    Ok(Loaded {
        trial,
        up,
        up_source,
        notes,
        repairs,
    })
}

/// The end of a rotation warning for a Y-up TRC read with a subject whose lab is not Y-up:
/// most likely `jointfit convert` (or another tool) already rotated it to OpenSim's Y up, so
/// the subject's `lab_up`, which describes the lab's raw files, does not apply to it.
fn converted_hint(path: &Path, trial: &Trial, up_source: &str) -> String {
    let is_trc = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("trc"));
    let y_up = jointfit::vertical::detect_up(trial).is_some_and(|d| d.up == UpAxis::Y);
    if up_source == "model" && is_trc && y_up {
        " (a TRC written by `jointfit convert` is already Y-up, OpenSim's convention: read it \
         with --up y, or give the command the lab's original file)"
            .to_string()
    } else {
        String::new()
    }
}

/// Rotates from `up` to Y up and filters, printing the filter's warnings.
fn prepare(trial: Trial, path: &Path, up: UpAxis, filter_hz: Option<f64>) -> Result<Trial> {
    let options = LoadOptions { up, filter_hz };
    let (trial, warnings) = match jointfit_io::trial_file::prepare_trial(trial, path, &options) {
        Ok(ok) => ok,
        Err(TrialFileError::Filter { path, hz, source }) => {
            return Err(anyhow::Error::new(source).context(format!("{path}: --filter {hz} Hz")))
        }
        Err(e) => return Err(e.into()),
    };
    for w in warnings {
        eprintln!("jointfit: warning: {w}");
    }
    Ok(trial)
}

/// Runs the data checks of `trial` against `model` ([`jointfit::checks`]): warnings go to
/// stderr, one line each; an error (e.g. wrong units) stops the command. Returns the findings.
pub fn run_checks(
    model: &jointfit::model::Model,
    trial: &Trial,
    path: &Path,
) -> Result<Vec<jointfit::checks::Finding>> {
    let (map, _) = jointfit::ik::MarkerMap::allowing_absent(model, trial.labels());
    let findings = jointfit::checks::check_trial(model, trial, &map);
    report_findings(&findings, path)?;
    Ok(findings)
}

/// Prints warnings on stderr (with the option that repairs each, if any) and fails on the
/// first error.
pub fn report_findings(findings: &[jointfit::checks::Finding], path: &Path) -> Result<()> {
    use jointfit::checks::Severity;
    // At most two lines of one kind per trial, then how many more (`--json` lists them all):
    // a units error or another session's static trial otherwise reads as dozens of lines.
    let mut shown: Vec<(jointfit::checks::CheckKind, usize)> = Vec::new();
    let warnings: Vec<&jointfit::checks::Finding> = findings
        .iter()
        .filter(|f| f.severity == Severity::Warning)
        .collect();
    for f in &warnings {
        let count = match shown.iter_mut().find(|(k, _)| *k == f.kind) {
            Some((_, n)) => {
                *n += 1;
                *n
            }
            None => {
                shown.push((f.kind, 1));
                1
            }
        };
        if count > 2 {
            continue;
        }
        let fix = f
            .fix
            .as_ref()
            .map_or(String::new(), |x| format!(" (to repair: {x})"));
        eprintln!(
            "jointfit: check: {}: {}: {}{fix}",
            path.display(),
            f.kind,
            f.message
        );
    }
    for (kind, n) in shown.iter().filter(|(_, n)| *n > 2) {
        eprintln!(
            "jointfit: check: {}: {}: and {} more such findings (--json lists them)",
            path.display(),
            kind,
            n - 2
        );
    }
    if let Some(f) = findings.iter().find(|f| f.severity == Severity::Error) {
        anyhow::bail!("{}: {}", path.display(), f.message);
    }
    Ok(())
}

/// One data-check finding in `--json` output.
#[derive(serde::Serialize, Debug, Clone)]
pub struct CheckJson {
    pub kind: String,
    pub severity: &'static str,
    pub message: String,
    /// The option that repairs it, if one does.
    pub fix: Option<String>,
}

impl From<&jointfit::checks::Finding> for CheckJson {
    fn from(f: &jointfit::checks::Finding) -> Self {
        CheckJson {
            kind: f.kind.to_string(),
            severity: match f.severity {
                jointfit::checks::Severity::Warning => "warning",
                jointfit::checks::Severity::Error => "error",
            },
            message: f.message.clone(),
            fix: f.fix.clone(),
        }
    }
}

/// What reading one trial noticed and did, for `--json` output: the vertical and where it
/// came from, the reader's notes, the repairs and the data checks.
#[derive(serde::Serialize, Debug, Clone)]
pub struct TrialJson {
    pub path: String,
    pub up: String,
    /// `--up`, `model` (the subject model's `lab_up`) or `default`.
    pub up_from: &'static str,
    pub reader_notes: Vec<String>,
    pub repairs: Vec<String>,
    pub checks: Vec<CheckJson>,
}

impl TrialJson {
    pub fn new(path: &Path, loaded: &Loaded, findings: &[jointfit::checks::Finding]) -> Self {
        TrialJson {
            path: path.display().to_string(),
            up: loaded.up.to_string(),
            up_from: loaded.up_source,
            reader_notes: loaded.notes.clone(),
            repairs: loaded.repairs.clone(),
            checks: findings.iter().map(CheckJson::from).collect(),
        }
    }
}

impl TrialJson {
    /// The same, for the HTML report's "Data checks" section.
    pub fn to_report(&self) -> jointfit_report::data_checks::TrialChecks {
        use jointfit_report::data_checks::{CheckRow, TrialChecks};
        let up_from = match self.up_from {
            "--up" => "--up",
            "model" => "the subject model's lab_up",
            _ => "the default",
        };
        TrialChecks {
            trial: crate::report_cmd::display_name(Path::new(&self.path)),
            up: format!("{} ({up_from})", self.up),
            notes: self.reader_notes.clone(),
            repairs: self.repairs.clone(),
            findings: self
                .checks
                .iter()
                .map(|c| CheckRow {
                    kind: c.kind.to_string(),
                    severity: c.severity.to_string(),
                    message: c.message.clone(),
                    fix: c.fix.clone(),
                })
                .collect(),
        }
    }
}

/// Prints the one-line warning for model markers a trial lacks altogether (`absent`): the
/// fits count them as missing in every frame.
pub fn warn_absent_markers(path: &Path, absent: &[String]) {
    if !absent.is_empty() {
        eprintln!(
            "jointfit: warning: {}: lacks model markers {}; they count as missing in every frame",
            path.display(),
            absent.join(", ")
        );
    }
}

/// Reads a trial for `model` ([`load_for_model`]) and runs the data checks ([`run_checks`]).
pub fn load_checked(
    path: &Path,
    args: &TrialArgs,
    model: &jointfit::model::Model,
    filter_hz: Option<f64>,
    columns: Columns,
) -> Result<(Trial, TrialJson, Vec<jointfit::checks::Finding>)> {
    let loaded = load_for_model(path, args, model, filter_hz, columns)?;
    let findings = run_checks(model, &loaded.trial, path)?;
    let json = TrialJson::new(path, &loaded, &findings);
    Ok((loaded.trial, json, findings))
}

/// The model as `ik` and `calibrate` use it on these trials: model markers no trial has are
/// left out (a user's OpenSim model often carries more markers than a trial, e.g. the
/// static-only medial knee and ankle markers), and coordinates no remaining marker determines
/// (toes without toe markers) are held at their defaults. Both are said on stderr.
pub fn model_for_trials(
    model: jointfit::model::Model,
    trials: &[&Trial],
    what: &str,
) -> Result<jointfit::model::Model> {
    let absent: Vec<String> = model
        .markers()
        .iter()
        .filter(|m| trials.iter().all(|t| !t.labels().contains(&m.name)))
        .map(|m| m.name.clone())
        .collect();
    let model = if absent.is_empty() {
        model
    } else {
        eprintln!(
            "jointfit: warning: the trials lack model markers {}; left out of {what}",
            absent.join(", ")
        );
        let mut spec = model.spec().clone();
        spec.markers.retain(|m| !absent.contains(&m.name));
        jointfit::model::Model::compile(&spec)?
    };
    let (held_model, held) = jointfit::ik::hold::hold_undetermined(&model, trials)?;
    if !held.is_empty() {
        eprintln!(
            "jointfit: warning: no marker determines {}; held at the model's default values",
            held.join(", ")
        );
    }
    Ok(held_model.unwrap_or(model))
}
