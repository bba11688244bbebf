//! Motion files by extension: `.trc` (and `.c3d`), returned as a [`Trial`] in metres.

use std::path::Path;

use jointfit::trial::Trial;
use thiserror::Error;

#[derive(Debug, Error)]
pub enum TrialFileError {
    #[error(transparent)]
    Trc(#[from] crate::trc::TrcError),
    #[error(transparent)]
    C3d(#[from] crate::c3d::C3dError),
    #[error("{0}: unknown motion file type (expected .trc or .c3d)")]
    UnknownType(String),
    #[error("{path}: {message}")]
    Other { path: String, message: String },
}

/// Reads a motion file, choosing the reader by extension (case-insensitive).
pub fn read_trial(path: &Path) -> Result<Trial, TrialFileError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("trc") => Ok(crate::trc::read_trc(path)?),
        Some("c3d") => read_c3d(path),
        _ => Err(TrialFileError::UnknownType(path.display().to_string())),
    }
}

fn read_c3d(path: &Path) -> Result<Trial, TrialFileError> {
    let trial = crate::c3d::read_c3d(path)?
        .to_trial()
        .map_err(|e| TrialFileError::Other {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
    strip_subject_prefix(trial).map_err(|e| TrialFileError::Other {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

/// Vicon Nexus writes `Subject:RASI` when a subject is named; when every label carries the
/// same `prefix:`, it is dropped so that models and marker sets can use the plain labels.
fn strip_subject_prefix(trial: Trial) -> Result<Trial, jointfit::trial::TrialError> {
    let prefix = match trial.labels().first().and_then(|l| l.split_once(':')) {
        Some((p, _)) => format!("{p}:"),
        None => return Ok(trial),
    };
    if !trial.labels().iter().all(|l| l.starts_with(&prefix)) {
        return Ok(trial);
    }
    let labels = trial
        .labels()
        .iter()
        .map(|l| l[prefix.len()..].to_string())
        .collect();
    Trial::new(
        labels,
        trial.rate(),
        trial.first_frame(),
        trial.positions().to_vec(),
    )
}
