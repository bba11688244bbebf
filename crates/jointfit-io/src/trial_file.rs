//! Motion files by extension: `.trc` (and `.c3d`), returned as a [`Trial`] in metres.

use std::path::Path;

use jointfit::trial::Trial;
use thiserror::Error;

#[derive(Debug, Error)]
pub enum TrialFileError {
    #[error(transparent)]
    Trc(#[from] crate::trc::TrcError),
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
    Err(TrialFileError::Other {
        path: path.display().to_string(),
        message: "C3D reading is not available in this build".into(),
    })
}
