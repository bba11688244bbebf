//! Writing TRC text (see the parent module for the layout).

use std::fmt::Write;
use std::path::Path;

use jointfit::trial::Trial;
use thiserror::Error;

use super::{TrcUnits, HEADER_KEYS};
use crate::atomic::write_atomic;

/// How [`format_trc`] writes coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrcWriteOptions {
    pub units: TrcUnits,
    /// Digits after the decimal point (at most 15).
    pub decimals: usize,
}

impl Default for TrcWriteOptions {
    /// Millimetres with 5 decimals (10 nm), as most exporters write.
    fn default() -> Self {
        TrcWriteOptions {
            units: TrcUnits::Millimetres,
            decimals: 5,
        }
    }
}

/// Why a trial could not be written as TRC.
#[derive(Debug, Error)]
pub enum TrcWriteError {
    #[error("marker {marker} has label {label:?}, which a TRC file cannot hold ({reason})")]
    BadLabel {
        marker: usize,
        label: String,
        reason: &'static str,
    },
    #[error("{decimals} decimals requested; at most 15 are meaningful")]
    TooManyDecimals { decimals: usize },
    #[error("{path}: cannot write: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
}

/// Formats a trial as TRC text (see the module docs). `file_name` goes on line 1.
pub fn format_trc(
    trial: &Trial,
    file_name: &str,
    options: &TrcWriteOptions,
) -> Result<String, TrcWriteError> {
    if options.decimals > 15 {
        return Err(TrcWriteError::TooManyDecimals {
            decimals: options.decimals,
        });
    }
    for (k, label) in trial.labels().iter().enumerate() {
        let reason = if label.trim().is_empty() {
            Some("empty")
        } else if label.contains(['\t', '\n', '\r']) {
            Some("contains a tab or line break")
        } else if label.trim() != label {
            Some("leading or trailing blanks would be lost")
        } else {
            None
        };
        if let Some(reason) = reason {
            return Err(TrcWriteError::BadLabel {
                marker: k + 1,
                label: label.clone(),
                reason,
            });
        }
    }
    let rate = trial.rate();
    let nf = trial.n_frames();
    let nm = trial.labels().len();
    let units = options.units.as_str();
    let first = trial.first_frame();
    let name: String = file_name
        .chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect();
    // Enough decimals that consecutive times differ visibly at any rate.
    let time_decimals = (rate.log10().ceil().max(0.0) as usize + 3).max(6);
    let per_metre = options.units.per_metre();
    let d = options.decimals;

    let mut out = String::with_capacity(64 + nf * (16 + nm * 3 * (d + 6)));
    out.push_str(&format!("PathFileType\t4\t(X/Y/Z)\t{name}\n"));
    out.push_str(&HEADER_KEYS.join("\t"));
    out.push('\n');
    out.push_str(&format!(
        "{rate}\t{rate}\t{nf}\t{nm}\t{units}\t{rate}\t{first}\t{nf}\n"
    ));
    out.push_str("Frame#\tTime");
    for l in trial.labels() {
        out.push_str(&format!("\t{l}\t\t"));
    }
    out.push_str("\n\t");
    for k in 1..=nm {
        out.push_str(&format!("\tX{k}\tY{k}\tZ{k}"));
    }
    out.push_str("\n\n");
    for f in 0..nf {
        let frame = first.saturating_add(f as i64);
        let time = trial.time(f);
        // Writing to a String cannot fail.
        let _ = write!(out, "{frame}\t{time:.time_decimals$}");
        for p in trial.frame(f) {
            let present = p.iter().all(|v| v.is_finite());
            let start = out.len();
            for v in p.iter() {
                let _ = write!(out, "\t{:.d$}", v * per_metre);
            }
            // A sample printed as 0 0 0 (only zeros, points and signs) would read back as a
            // gap: write it as one. Gaps are written `NaN`, not as blank cells: OpenSim 4.6's
            // reader drops a row's trailing blank cells and then refuses the file when the
            // last marker has a gap ("Unexpected number of columns").
            let zero = out.as_bytes()[start..]
                .iter()
                .all(|c| matches!(c, b'\t' | b'0' | b'.' | b'-'));
            if !present || zero {
                out.truncate(start);
                out.push_str("\tNaN\tNaN\tNaN");
            }
        }
        out.push('\n');
    }
    Ok(out)
}

/// Writes a trial as a TRC file, atomically (see [`write_atomic`]).
pub fn write_trc(
    path: &Path,
    trial: &Trial,
    options: &TrcWriteOptions,
) -> Result<(), TrcWriteError> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let text = format_trc(trial, &name, options)?;
    write_atomic(path, text.as_bytes()).map_err(|source| TrcWriteError::Io {
        path: path.display().to_string(),
        source,
    })
}
