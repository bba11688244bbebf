//! Calibration reports a person wants to open: one self-contained HTML page
//! (`DIR/index.html`) with inline SVG figures, written atomically.
//!
//! * [`data`]: what the page shows, in display units ([`ReportInput`]); any command can
//!   fill it.
//! * [`analyze`]: fills marker errors, joint angles and the parameter table from a model, its
//!   fitted and baseline parameters and the trials (inverse kinematics with each).
//! * [`svg`]: hand-written line and bar charts (nice ticks, log axes, gaps, legends).
//! * [`html`]: the page (inline CSS, system fonts, no scripts, nothing fetched from the
//!   network, every piece of text from files escaped; also well-formed XML).
//! * [`trust`]: where each parameter's information came from and the anatomical checks.

pub mod analyze;
pub mod calibration;
pub mod check;
pub mod data;
pub mod data_checks;
pub mod html;
pub mod svg;
pub mod trust;

use std::path::{Path, PathBuf};

pub use data::{Convergence, CoordSeries, Interval, MarkerRms, ParamRow, ReportInput, TrialSeries};

#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("{trial}: {message}")]
    Trial { trial: String, message: String },
    #[error("{path}: exists and is not a directory (a report is written to DIR/index.html)")]
    NotADirectory { path: String },
    #[error("{path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
}

/// Refuses a report directory that is an existing file; front ends call it before a long
/// computation whose report goes there ([`write_report`] calls it too).
pub fn check_dir(dir: &Path) -> Result<(), ReportError> {
    if dir.exists() && !dir.is_dir() {
        return Err(ReportError::NotADirectory {
            path: dir.display().to_string(),
        });
    }
    Ok(())
}

/// Writes `dir/index.html` (creating `dir` if needed) atomically; returns the file's path.
pub fn write_report(dir: &Path, input: &ReportInput) -> Result<PathBuf, ReportError> {
    let io = |path: &Path| {
        let path = path.display().to_string();
        move |source| ReportError::Io { path, source }
    };
    check_dir(dir)?;
    jointfit_io::staging::create_dir_all(dir).map_err(io(dir))?;
    let path = dir.join("index.html");
    jointfit_io::atomic::write_atomic(&path, html::render(input).as_bytes()).map_err(io(&path))?;
    Ok(path)
}

/// The current UTC date and time as `YYYY-MM-DD HH:MM UTC` (no time-zone database needed).
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs() as i64)
        .unwrap_or(0);
    utc_from_unix(secs)
}

/// `YYYY-MM-DD HH:MM UTC` of a Unix time (days-to-civil of Howard Hinnant's date algorithms).
pub fn utc_from_unix(secs: i64) -> String {
    let days = secs.div_euclid(86_400);
    let rem = secs.rem_euclid(86_400);
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + (m <= 2) as i64;
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02} UTC",
        rem / 3600,
        (rem % 3600) / 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn civil_dates() {
        assert_eq!(utc_from_unix(0), "1970-01-01 00:00 UTC");
        assert_eq!(utc_from_unix(951_782_400), "2000-02-29 00:00 UTC");
        assert_eq!(utc_from_unix(1_795_437_000), "2026-11-23 12:30 UTC");
        assert_eq!(utc_from_unix(-86_400), "1969-12-31 00:00 UTC");
    }
}
