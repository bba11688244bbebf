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
    #[error("{path}: filtering at {hz} Hz: {source}")]
    Filter {
        path: String,
        hz: f64,
        #[source]
        source: jointfit_signal::SignalError,
    },
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

/// Reads a motion file like [`read_trial`] and returns, with the trial, what the reader
/// noticed and decided (TRC notes, C3D warnings: assumed units, rows beyond the header's
/// count, a data section shorter than the frames declared, …), one sentence each, for the
/// caller to show wherever the trial is used.
pub fn read_trial_noted(path: &Path) -> Result<(Trial, Vec<String>), TrialFileError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("trc") => {
            let file = crate::trc::read_trc_file(path)?;
            let notes = file.notes.iter().map(|n| n.to_string()).collect();
            Ok((
                crate::trc::strict(file, &path.display().to_string())?,
                notes,
            ))
        }
        Some("c3d") => {
            let c3d = crate::c3d::read_c3d(path)?;
            let notes = c3d.warnings.clone();
            Ok((c3d_trial(path, &c3d)?, notes))
        }
        _ => Err(TrialFileError::UnknownType(path.display().to_string())),
    }
}

/// Reads a motion file like [`read_trial_noted`], keeping only the markers `select` accepts
/// (all when `None`), in file order. A TRC file's other columns are not parsed
/// ([`crate::trc::read_trc_selected`]: most of the reading time of a full-body file whose
/// model uses a third of its markers); a C3D file is read whole and its other markers dropped.
pub fn read_trial_selected(
    path: &Path,
    select: Option<crate::trc::Select>,
) -> Result<(Trial, Vec<String>), TrialFileError> {
    let Some(keep) = select else {
        return read_trial_noted(path);
    };
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    if ext.as_deref() == Some("trc") {
        let file = crate::trc::read_trc_selected(path, Some(keep))?;
        let notes = file.notes.iter().map(|n| n.to_string()).collect();
        return Ok((
            crate::trc::strict(file, &path.display().to_string())?,
            notes,
        ));
    }
    let (trial, notes) = read_trial_noted(path)?;
    let names: Vec<&str> = trial
        .labels()
        .iter()
        .map(String::as_str)
        .filter(|l| keep(l))
        .collect();
    if names.is_empty() {
        // As for TRC files: a selection that keeps no marker keeps them all.
        return Ok((trial, notes));
    }
    let trial = trial.select(&names).map_err(|e| TrialFileError::Other {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    Ok((trial, notes))
}

fn read_c3d(path: &Path) -> Result<Trial, TrialFileError> {
    c3d_trial(path, &crate::c3d::read_c3d(path)?)
}

fn c3d_trial(path: &Path, c3d: &crate::c3d::C3d) -> Result<Trial, TrialFileError> {
    let trial = c3d.to_trial().map_err(|e| TrialFileError::Other {
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
    )?
    .with_times(trial.times().map(<[f64]>::to_vec))
}

/// How [`load_trial`] prepares a motion file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoadOptions {
    /// Which lab axis points up in the file; the trial is rotated to Y up.
    pub up: jointfit::spatial::UpAxis,
    /// Low-pass cutoff (Hz) of the zero-phase Butterworth filter; `None`: unfiltered.
    pub filter_hz: Option<f64>,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            up: jointfit::spatial::UpAxis::Y,
            filter_hz: None,
        }
    }
}

/// Filtering moved a marker by more than 2 cm somewhere in the trial.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterWarning {
    pub path: String,
    pub marker: String,
    /// Largest displacement by the filter (m).
    pub moved_m: f64,
}

impl std::fmt::Display for FilterWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: filtering moved marker {} by {:.1} mm",
            self.path,
            self.marker,
            self.moved_m * 1e3
        )
    }
}

/// Reads a motion file ([`read_trial`]) and prepares it ([`prepare_trial`]).
pub fn load_trial(
    path: &Path,
    options: &LoadOptions,
) -> Result<(Trial, Vec<FilterWarning>), TrialFileError> {
    prepare_trial(read_trial(path)?, path, options)
}

/// Rotates a trial read from `path` to Y up and low-pass filters it when asked; returns it
/// with a warning for every marker the filter moved by more than 2 cm.
pub fn prepare_trial(
    mut trial: Trial,
    path: &Path,
    options: &LoadOptions,
) -> Result<(Trial, Vec<FilterWarning>), TrialFileError> {
    trial.rotate(&jointfit::spatial::up_axis_rotation(options.up));
    let mut warnings = Vec::new();
    if let Some(hz) = options.filter_hz {
        let lp = jointfit_signal::LowPass {
            cutoff_hz: hz,
            ..jointfit_signal::LowPass::default()
        };
        let (filtered, report) = jointfit_signal::filter_trial(&trial, &lp).map_err(|source| {
            TrialFileError::Filter {
                path: path.display().to_string(),
                hz,
                source,
            }
        })?;
        warnings.extend(report.moved_more_than(0.02).map(|m| FilterWarning {
            path: path.display().to_string(),
            marker: m.label.clone(),
            moved_m: m.max_displacement_m,
        }));
        trial = filtered;
    }
    Ok((trial, warnings))
}
