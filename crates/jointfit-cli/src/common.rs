//! Shared pieces of the subcommands: the up-axis option and reading trials with warnings.
//!
//! Commands that read trials for a subject model (`ik`, `calibrate`, `check`, `report`) take
//! the same trial options ([`TrialArgs`], flattened into their arguments) and read through
//! [`load_for_model`]: the vertical is `--up`, else the model's `lab_up`, else `y`; a trial
//! whose marker layout says another axis is up is reported as rotated.

use std::path::Path;

use anyhow::Result;
use clap::ValueEnum;
use jointfit::trial::{Trial, UpAxis};
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

/// The trial options of the commands that read trials for a subject model.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct TrialArgs {
    /// Which axis of the file points up (default: the subject model's `lab_up`, recorded by
    /// `personalize`; else y).
    #[arg(long, value_enum)]
    pub up: Option<Up>,
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
}

/// Reads `path` for `model` ([`TrialArgs`]; module docs): the vertical from `--up`, the
/// model's `lab_up` or `y`, a warning when the markers say another axis is up, then filtering.
pub fn load_for_model(
    path: &Path,
    args: &TrialArgs,
    model: &jointfit::model::Model,
    filter_hz: Option<f64>,
) -> Result<Loaded> {
    let (trial, mut notes) = jointfit_io::trial_file::read_trial_noted(path)?;
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
    notes.extend(jointfit::vertical::rotation_warning(&trial, up, &given));
    for note in &notes {
        eprintln!("jointfit: warning: {}: {note}", path.display());
    }
    let trial = prepare(trial, path, up, filter_hz)?;
    Ok(Loaded {
        trial,
        up,
        up_source,
        notes,
    })
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

/// Prints warnings on stderr and fails on the first error.
pub fn report_findings(findings: &[jointfit::checks::Finding], path: &Path) -> Result<()> {
    use jointfit::checks::Severity;
    for f in findings.iter().filter(|f| f.severity == Severity::Warning) {
        eprintln!(
            "jointfit: check: {}: {}: {}",
            path.display(),
            f.kind.as_str(),
            f.message
        );
    }
    if let Some(f) = findings.iter().find(|f| f.severity == Severity::Error) {
        anyhow::bail!("{}: {}", path.display(), f.message);
    }
    Ok(())
}
