//! Shared pieces of the subcommands: the up-axis option and reading trials with warnings.

use std::path::Path;

use anyhow::Result;
use clap::ValueEnum;
use jointfit::trial::{Trial, UpAxis};
use jointfit_io::trial_file::{LoadOptions, TrialFileError};

/// Which lab axis points up in the input file.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Up {
    Y,
    Z,
    #[value(name = "-z")]
    NegZ,
}

impl From<Up> for UpAxis {
    fn from(u: Up) -> UpAxis {
        match u {
            Up::Y => UpAxis::Y,
            Up::Z => UpAxis::Z,
            Up::NegZ => UpAxis::NegZ,
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
    let options = LoadOptions {
        up: up.into(),
        filter_hz,
    };
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
