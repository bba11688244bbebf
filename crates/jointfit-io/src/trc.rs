//! TRC marker files (the "track row column" text format of Motion Analysis, read and written by
//! OpenSim, BTK/Mokka, Cortex, OpenCap and others).
//!
//! # The format
//!
//! A TRC file is tab-separated text with five header lines followed by one row per frame:
//!
//! 1. `PathFileType`, a format number (4), the coordinate order `(X/Y/Z)` and usually the name
//!    of the file as it was first written. Only the leading keyword is checked.
//! 2. The names of the values on line 3: `DataRate CameraRate NumFrames NumMarkers Units
//!    OrigDataRate OrigDataStartFrame OrigNumFrames`, matched to them by position.
//!    `DataRate` (Hz, the rate of the rows below), `NumFrames`, `NumMarkers` and `Units` are
//!    required; the camera rate and the three `Orig*` values describe the recording the file
//!    was cut from and are kept in [`TrcHeader`] but not used.
//! 3. Those values. Padding blanks around a value are ignored. When lines 2 and 3 hold the same
//!    number of non-empty cells but not at the same places (doubled tabs, as in the files of
//!    OpenSim's own pipelines), the non-empty cells are paired in order, as OpenSim 4.6 does;
//!    otherwise by position, so that a blank optional value stays blank. `NumFrames` and
//!    `NumMarkers` may be written as whole decimals (`100.0`).
//! 4. `Frame#`, `Time`, then one label per marker. Labels usually sit in every third cell with
//!    two empty cells after each (one cell per coordinate); some writers (an older OpenSim
//!    exporter) place them differently, so when the every-third-cell layout does not hold the
//!    non-empty cells are taken in order and a [`TrcNote::LabelsNotAligned`] is returned.
//!    Surrounding blanks are removed from labels.
//! 5. Coordinate names `X1 Y1 Z1 X2 …`; only their number (three per marker) is checked.
//!
//! Blank lines may follow; then each data row holds the frame number, the time in seconds and
//! three coordinates per marker in the unit of line 3 (`mm`, `cm` or `m`, any letter case).
//! Numbers may be plain or in exponent notation (`-2.73E-01`) and padded with blanks.
//!
//! # Gaps
//!
//! A marker is missing in a frame when its cells are empty (or hold only blanks), hold `NaN`
//! in any letter case, or are all exactly zero (several exporters write `0 0 0` for a marker
//! they lost; a real marker never sits at the laboratory origin to five decimals). All three
//! become NaN in the [`Trial`]. If only some coordinates of a sample are missing, the whole
//! sample is treated as missing and a [`TrcNote::PartialSamples`] says so.
//!
//! # Inconsistent files: what is trusted
//!
//! * Rows beyond `NumFrames`: the rows are trusted, [`TrcNote::MoreRowsThanHeader`].
//! * Fewer rows than `NumFrames`: the file is taken as cut short, [`TrcErrorKind::MissingFrames`].
//! * `NumMarkers` different from the number of labels: [`TrcErrorKind::MarkerCountMismatch`]
//!   (which columns belong to which marker is then unknowable; OpenSim refuses such files too).
//! * Frame numbers must count up by one from the first row, which gives
//!   [`Trial::first_frame`].
//! * The `Time` column must agree with `DataRate` (within half a frame plus the precision the
//!   times are printed with). When it does not, but is evenly spaced at another rate (a file
//!   resampled without updating its header, e.g. OpenSim's own exports of walking2/5.c3d:
//!   every 10th frame, DataRate still 250 Hz), the trial takes the Time column's rate, as
//!   OpenSim's reader does, with a [`TrcNote::RateFromTimeColumn`]. Otherwise
//!   [`read_trc`]/[`parse_trc`] refuse the file ([`TrcErrorKind::TimeMismatch`]): the trial's
//!   rate would be wrong. [`read_trc_file`]/[`parse_trc_file`] accept it with a
//!   [`TrcNote::TimeDisagreesWithRate`] and return the times as written in [`TrcFile::times`].
//! * Otherwise the trial keeps the Time column as its time stamps ([`Trial::time`]; OpenSim
//!   copies them into its results), unless they do not strictly increase: then times are
//!   frame index / `DataRate` and a [`TrcNote::TimeNotIncreasing`] says so.
//! * A data row with too few cells, or with a non-blank cell beyond the last marker, is an
//!   error naming the line and the marker.
//!
//! # Reading some markers only
//!
//! [`read_trc_selected`]/[`parse_trc_selected`] parse the coordinates of the markers a
//! filter accepts and step over the other markers' cells (the commands that fit a model read
//! its markers this way). Everything else is checked as in a full read, and the kept values
//! are the same bits. Data rows are read by a one-pass byte parser for the common case
//! (`trc/fast.rs`) and by the general, fully checked path (`trc/rows.rs`) for any row it
//! does not handle; both give the same values (`docs/io.md`).
//!
//! # Writing
//!
//! [`format_trc`]/[`write_trc`] write the layout above with `\n` line ends: rate written so it
//! reads back exactly, `Frame#` counting from [`Trial::first_frame`], `Time` =
//! [`Trial::time`] (the source's time stamps, else frame index / rate), coordinates in the
//! chosen unit with a fixed number of decimals, and missing samples as empty cells. Reading
//! the file back gives the trial rounded to the written precision, and a second write gives
//! the same bytes. A sample that rounds to `0 0 0` at the chosen precision is written as a
//! gap, because that is how it would read back.

use std::path::Path;

use jointfit::trial::Trial;
use thiserror::Error;

use crate::text::decode;

mod blocks;
mod fast;
mod read;
mod rows;
#[cfg(any(unix, windows))]
mod stream;
mod write;

pub use write::{format_trc, write_trc, TrcWriteError, TrcWriteOptions};

/// Length unit of a TRC file's coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrcUnits {
    Millimetres,
    Centimetres,
    Metres,
}

impl TrcUnits {
    /// Metres per file unit.
    pub fn to_metres(self) -> f64 {
        match self {
            TrcUnits::Millimetres => 1e-3,
            TrcUnits::Centimetres => 1e-2,
            TrcUnits::Metres => 1.0,
        }
    }
    /// File units per metre (exact for mm, cm, m).
    fn per_metre(self) -> f64 {
        match self {
            TrcUnits::Millimetres => 1e3,
            TrcUnits::Centimetres => 1e2,
            TrcUnits::Metres => 1.0,
        }
    }
    /// The spelling used in the header.
    pub fn as_str(self) -> &'static str {
        match self {
            TrcUnits::Millimetres => "mm",
            TrcUnits::Centimetres => "cm",
            TrcUnits::Metres => "m",
        }
    }
    fn parse(s: &str) -> Option<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "mm" => Some(TrcUnits::Millimetres),
            "cm" => Some(TrcUnits::Centimetres),
            "m" => Some(TrcUnits::Metres),
            _ => None,
        }
    }
}

/// The values of a TRC file's header lines, as written.
#[derive(Debug, Clone, PartialEq)]
pub struct TrcHeader {
    /// Fourth field of line 1 (the name the file was first written under), may be empty.
    pub file_name: String,
    /// `DataRate`: rate of the rows, Hz.
    pub data_rate: f64,
    pub camera_rate: Option<f64>,
    /// `NumFrames` as written (the rows present may be more; see the module docs).
    pub num_frames: usize,
    pub num_markers: usize,
    pub units: TrcUnits,
    pub orig_data_rate: Option<f64>,
    pub orig_data_start_frame: Option<i64>,
    pub orig_num_frames: Option<usize>,
}

/// Something odd about a file that did not stop it from being read.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TrcNote {
    #[error("the header says {header} frames but {rows} rows are present; all rows were read")]
    MoreRowsThanHeader { header: usize, rows: usize },
    #[error(
        "line {line}: frame {frame} has time {found} s but DataRate implies {expected} s; \
         the trial uses DataRate"
    )]
    TimeDisagreesWithRate {
        line: usize,
        frame: i64,
        expected: f64,
        found: f64,
    },
    #[error(
        "DataRate is {} Hz but the Time column is evenly spaced at {} Hz (a resampled \
         file?); the trial uses the Time column's times and rate, as OpenSim does",
        rate_text(*.header),
        rate_text(*.column)
    )]
    RateFromTimeColumn { header: f64, column: f64 },
    #[error(
        "line {line}: frame {frame} has time {found} s, not after the previous row's; the \
         trial's times are frame / DataRate"
    )]
    TimeNotIncreasing { line: usize, frame: i64, found: f64 },
    #[error("line {line}: labels are not in every third cell; they were taken in order")]
    LabelsNotAligned { line: usize },
    #[error("line {line}: {count} labels had surrounding blanks, which were removed")]
    TrimmedLabels { line: usize, count: usize },
    #[error(
        "{count} samples were exactly (0, 0, 0) and were read as missing (first: line {first_line}, \
         marker {marker:?})"
    )]
    ZeroSamples {
        count: usize,
        first_line: usize,
        marker: String,
    },
    #[error(
        "{count} samples had only some coordinates missing and were read as missing (first: line \
         {first_line}, marker {marker:?})"
    )]
    PartialSamples {
        count: usize,
        first_line: usize,
        marker: String,
    },
}

/// A TRC file as read: the trial plus what the file said about itself.
#[derive(Debug, Clone, PartialEq)]
pub struct TrcFile {
    /// Positions in metres, gaps as NaN, rate = `DataRate`, first frame = first `Frame#`.
    pub trial: Trial,
    pub header: TrcHeader,
    /// The `Time` column as written, seconds, one per frame.
    pub times: Vec<f64>,
    pub notes: Vec<TrcNote>,
}

/// Why a TRC file could not be read; always names the file (see [`TrcErrorKind`]).
#[derive(Debug, Error)]
#[error("{file}: {kind}")]
pub struct TrcError {
    /// The path or name the caller gave for the text.
    pub file: String,
    pub kind: TrcErrorKind,
}

/// What is wrong with a TRC file. Line numbers count from 1.
#[derive(Debug, Error)]
pub enum TrcErrorKind {
    #[error("cannot read the file: {0}")]
    Io(std::io::Error),
    #[error("the file is empty")]
    Empty,
    #[error("not a TRC file: line 1 should start with PathFileType but is {found:?}")]
    NotTrc { found: String },
    #[error("the file ends at line {line}, before {expected}")]
    Truncated { line: usize, expected: &'static str },
    #[error("line 2 has no {key} field")]
    MissingHeaderKey { key: &'static str },
    #[error("line {line}: {key} should be a number but is {value:?}")]
    BadHeaderValue {
        line: usize,
        key: &'static str,
        value: String,
    },
    #[error("line {line}: DataRate must be a positive number of Hz, got {value:?}")]
    BadRate { line: usize, value: String },
    #[error("line {line}: unknown units {units:?} (expected mm, cm or m)")]
    UnknownUnits { line: usize, units: String },
    #[error("line {line}: expected the marker labels row starting with Frame#, found {found:?}")]
    BadLabelsRow { line: usize, found: String },
    #[error(
        "line {line}: the header says NumMarkers = {header} but the labels row names {labels} \
         markers"
    )]
    MarkerCountMismatch {
        line: usize,
        header: usize,
        labels: usize,
    },
    #[error("line {line}: marker {marker} has an empty label (after {previous:?})")]
    EmptyLabel {
        line: usize,
        marker: usize,
        previous: Option<String>,
    },
    #[error("line {line}: label {label:?} is used by markers {first} and {second}")]
    DuplicateLabel {
        line: usize,
        label: String,
        first: usize,
        second: usize,
    },
    #[error("line {line}: expected {expected} coordinate names (X/Y/Z per marker), found {found}")]
    CoordinateRowMismatch {
        line: usize,
        expected: usize,
        found: usize,
    },
    #[error("line {line}: frame number should be an integer, got {value:?}")]
    BadFrameNumber { line: usize, value: String },
    #[error(
        "line {line}: frame number {found} follows frame {previous} (rows must count up by one)"
    )]
    FrameNumberJump {
        line: usize,
        previous: i64,
        found: i64,
    },
    #[error("line {line}: time should be a finite number, got {value:?}")]
    BadTime { line: usize, value: String },
    #[error(
        "line {line}: row ends after {found} cells, inside marker {marker:?} ({expected} cells \
         expected)"
    )]
    TooFewValues {
        line: usize,
        marker: String,
        expected: usize,
        found: usize,
    },
    #[error(
        "line {line}: cell {column} holds {value:?} after the last marker ({last_marker:?}); the \
         row has more values than labelled markers"
    )]
    ExtraValues {
        line: usize,
        column: usize,
        value: String,
        last_marker: String,
    },
    #[error("line {line}, cell {column} (marker {marker:?}): not a number: {value:?}")]
    BadNumber {
        line: usize,
        column: usize,
        marker: String,
        value: String,
    },
    #[error("the header says {header} frames but only {rows} rows are present (file cut short?)")]
    MissingFrames { header: usize, rows: usize },
    #[error(
        "line {line}: frame {frame} has time {found} s but DataRate implies {expected} s; the \
         Time column and DataRate disagree (read_trc_file accepts this with a note)"
    )]
    TimeMismatch {
        line: usize,
        frame: i64,
        expected: f64,
        found: f64,
    },
}

/// Reads a TRC file into a [`Trial`] (metres, gaps as NaN). Notes are dropped, except that a
/// `Time` column disagreeing with `DataRate` is an error; use [`read_trc_file`] to see them.
pub fn read_trc(path: &Path) -> Result<Trial, TrcError> {
    strict(read_trc_file(path)?, &path.display().to_string())
}

/// Parses TRC text (see [`read_trc`]); `name` is used in error messages.
pub fn parse_trc(text: &str, name: &str) -> Result<Trial, TrcError> {
    strict(parse_trc_file(text, name)?, name)
}

/// A rate as short text: plain for everyday values, in exponent form outside 1e-3..1e6 Hz
/// (a header may hold 1e300; a message must not print 300 digits).
fn rate_text(v: f64) -> String {
    if (1e-3..1e6).contains(&v.abs()) {
        v.to_string()
    } else {
        format!("{v:e}")
    }
}

pub(crate) fn strict(file: TrcFile, name: &str) -> Result<Trial, TrcError> {
    for note in &file.notes {
        if let TrcNote::TimeDisagreesWithRate {
            line,
            frame,
            expected,
            found,
        } = *note
        {
            return Err(TrcError {
                file: name.to_string(),
                kind: TrcErrorKind::TimeMismatch {
                    line,
                    frame,
                    expected,
                    found,
                },
            });
        }
    }
    Ok(file.trial)
}

/// Which markers a selective read keeps: called once per label of line 4.
pub type Select<'s> = &'s dyn Fn(&str) -> bool;

/// Reads a TRC file with its header, times and notes.
pub fn read_trc_file(path: &Path) -> Result<TrcFile, TrcError> {
    read_trc_selected(path, None)
}

/// Reads a TRC file like [`read_trc_file`], parsing the coordinates of only the markers
/// `select` accepts (all when `None`); the trial holds those markers, in file order.
/// A selection that accepts no marker of the file reads them all.
///
/// The header, the labels and every row's frame number, time and number of cells are checked
/// as in a full read, and the kept markers' values are the same bits; the cells of the other
/// markers are stepped over unread, so a bad number there is not an error, and the notes on
/// zero and partial samples count the kept markers only. Commands that fit a model read its
/// markers this way: most of a full-body file's columns are markers the model does not have.
pub fn read_trc_selected(path: &Path, select: Option<Select>) -> Result<TrcFile, TrcError> {
    read_trc_in_blocks(path, select, blocks::BLOCK_BYTES)
}

/// [`read_trc_selected`] with blocks of `block` bytes: a file of two blocks or more is read
/// block by block on every thread (`trc/stream.rs`), a smaller one (or one that path leaves)
/// whole. The result does not depend on `block` (tests compare).
pub(crate) fn read_trc_in_blocks(
    path: &Path,
    select: Option<Select>,
    block: usize,
) -> Result<TrcFile, TrcError> {
    let name = path.display().to_string();
    let fail = |kind| TrcError {
        file: name.clone(),
        kind,
    };
    #[cfg(any(unix, windows))]
    {
        let file = std::fs::File::open(path).map_err(|e| fail(TrcErrorKind::Io(e)))?;
        crate::limits::check_size(&file, crate::limits::TRIAL_BYTES, "motion")
            .map_err(|e| fail(TrcErrorKind::Io(e)))?;
        let len = file
            .metadata()
            .map_err(|e| fail(TrcErrorKind::Io(e)))?
            .len();
        if let Some(read) = stream::read(&file, len, select, block) {
            return read.map_err(fail);
        }
    }
    let bytes = crate::limits::read_bytes(path, crate::limits::TRIAL_BYTES, "motion")
        .map_err(|e| fail(TrcErrorKind::Io(e)))?;
    // Valid UTF-8 (nearly every file) is used in place, without a copy.
    let text = String::from_utf8(bytes).unwrap_or_else(|e| decode(e.as_bytes()));
    read::parse_in_blocks(&text, select, block).map_err(fail)
}

/// Parses TRC text with its header, times and notes; `name` is used in error messages.
pub fn parse_trc_file(text: &str, name: &str) -> Result<TrcFile, TrcError> {
    parse_trc_selected(text, name, None)
}

/// Parses TRC text keeping only the markers `select` accepts (see [`read_trc_selected`]).
pub fn parse_trc_selected(
    text: &str,
    name: &str,
    select: Option<Select>,
) -> Result<TrcFile, TrcError> {
    read::parse(text, select).map_err(|kind| TrcError {
        file: name.to_string(),
        kind,
    })
}

/// The header fields of line 2, in the order writers put them.
const HEADER_KEYS: [&str; 8] = [
    "DataRate",
    "CameraRate",
    "NumFrames",
    "NumMarkers",
    "Units",
    "OrigDataRate",
    "OrigDataStartFrame",
    "OrigNumFrames",
];
