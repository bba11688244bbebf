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
//! 3. Those values. Padding blanks around a value are ignored.
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
//!   times are printed with). [`read_trc`]/[`parse_trc`] refuse a file where it does not
//!   ([`TrcErrorKind::TimeMismatch`]): the trial's rate would be wrong. [`read_trc_file`]/
//!   [`parse_trc_file`] accept it with a [`TrcNote::TimeDisagreesWithRate`] and return the
//!   times as written in [`TrcFile::times`].
//! * A data row with too few cells, or with a non-blank cell beyond the last marker, is an
//!   error naming the line and the marker.
//!
//! # Writing
//!
//! [`format_trc`]/[`write_trc`] write the layout above with `\n` line ends: rate written so it
//! reads back exactly, `Frame#` counting from [`Trial::first_frame`], `Time` = frame index /
//! rate, coordinates in the chosen unit with a fixed number of decimals, and missing samples as
//! empty cells. Reading the file back gives the trial rounded to the written precision, and a
//! second write gives the same bytes. A present sample that rounds to `0 0 0` would read back
//! as missing.

use std::path::Path;

use jointfit::trial::Trial;
use nalgebra::Vector3;
use thiserror::Error;

use crate::atomic::write_atomic;
use crate::text::{decode, numbered_lines, parse_number};

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

fn strict(file: TrcFile, name: &str) -> Result<Trial, TrcError> {
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

/// Reads a TRC file with its header, times and notes.
pub fn read_trc_file(path: &Path) -> Result<TrcFile, TrcError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| TrcError {
        file: name.clone(),
        kind: TrcErrorKind::Io(e),
    })?;
    parse_trc_file(&decode(&bytes), &name)
}

/// Parses TRC text with its header, times and notes; `name` is used in error messages.
pub fn parse_trc_file(text: &str, name: &str) -> Result<TrcFile, TrcError> {
    parse(text).map_err(|kind| TrcError {
        file: name.to_string(),
        kind,
    })
}

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

fn parse(text: &str) -> Result<TrcFile, TrcErrorKind> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    if text.trim().is_empty() {
        return Err(TrcErrorKind::Empty);
    }
    let lines = numbered_lines(text);
    let line_at = |i: usize, expected: &'static str| {
        lines
            .get(i)
            .map(|&(_, l)| l)
            .ok_or(TrcErrorKind::Truncated {
                line: lines.len(),
                expected,
            })
    };

    let first = line_at(0, "the header")?;
    let Some(rest) = first.trim_start().strip_prefix("PathFileType") else {
        return Err(TrcErrorKind::NotTrc {
            found: first.chars().take(60).collect(),
        });
    };
    let file_name = rest
        .split('\t')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .nth(2)
        .unwrap_or("")
        .to_string();

    let keys = line_at(1, "the header field names (line 2)")?;
    let values = line_at(2, "the header values (line 3)")?;
    let mut notes = Vec::new();
    let mut header = parse_header(keys, values)?;
    header.file_name = file_name;
    let n = header.num_markers;

    let labels_line = line_at(3, "the marker labels (line 4)")?;
    let coords_line = line_at(4, "the coordinate names (line 5)")?;
    let labels = parse_labels(labels_line, n, &mut notes)?;
    let coords = coords_line
        .split('\t')
        .filter(|c| !c.trim().is_empty())
        .count();
    if coords != 3 * n {
        return Err(TrcErrorKind::CoordinateRowMismatch {
            line: 5,
            expected: 3 * n,
            found: coords,
        });
    }

    let scale = header.units.to_metres();
    let mut data = Rows::new(&labels, scale);
    for &(line_no, line) in &lines[5..] {
        if line.trim().is_empty() {
            continue;
        }
        data.push(line_no, line)?;
    }
    let rows = data.times.len();
    if rows < header.num_frames {
        return Err(TrcErrorKind::MissingFrames {
            header: header.num_frames,
            rows,
        });
    }
    if rows > header.num_frames {
        notes.push(TrcNote::MoreRowsThanHeader {
            header: header.num_frames,
            rows,
        });
    }
    if let Some(note) = data.check_times(header.data_rate) {
        notes.push(note);
    }
    notes.extend(
        std::mem::take(&mut data.zero).into_note(|count, first_line, marker| {
            TrcNote::ZeroSamples {
                count,
                first_line,
                marker,
            }
        }),
    );
    notes.extend(
        std::mem::take(&mut data.partial).into_note(|count, first_line, marker| {
            TrcNote::PartialSamples {
                count,
                first_line,
                marker,
            }
        }),
    );
    let Rows {
        positions,
        times,
        first_frame,
        ..
    } = data;
    let first_frame = first_frame.or(header.orig_data_start_frame).unwrap_or(1);
    let trial = Trial::new(labels, header.data_rate, first_frame, positions).map_err(|e| {
        // Labels and rate were validated above; keep a precise message if that ever changes.
        TrcErrorKind::BadRate {
            line: 3,
            value: e.to_string(),
        }
    })?;
    Ok(TrcFile {
        trial,
        header,
        times,
        notes,
    })
}

fn parse_header(keys: &str, values: &str) -> Result<TrcHeader, TrcErrorKind> {
    let values: Vec<&str> = values.split('\t').map(str::trim).collect();
    let mut found: [Option<&str>; 8] = [None; 8];
    for (i, key) in keys.split('\t').map(str::trim).enumerate() {
        if let Some(k) = HEADER_KEYS.iter().position(|h| h.eq_ignore_ascii_case(key)) {
            found[k] = Some(values.get(i).copied().unwrap_or(""));
        }
    }
    let required = |k: usize| {
        found[k].ok_or(TrcErrorKind::MissingHeaderKey {
            key: HEADER_KEYS[k],
        })
    };
    let count = |k: usize| -> Result<usize, TrcErrorKind> {
        let v = required(k)?;
        v.parse::<usize>()
            .map_err(|_| TrcErrorKind::BadHeaderValue {
                line: 3,
                key: HEADER_KEYS[k],
                value: v.to_string(),
            })
    };
    let rate_text = required(0)?;
    let data_rate = match parse_number(rate_text) {
        Some(r) if r.is_finite() && r > 0.0 => r,
        _ => {
            return Err(TrcErrorKind::BadRate {
                line: 3,
                value: rate_text.to_string(),
            })
        }
    };
    let num_frames = count(2)?;
    let num_markers = count(3)?;
    let units_text = required(4)?;
    let units = TrcUnits::parse(units_text).ok_or_else(|| TrcErrorKind::UnknownUnits {
        line: 3,
        units: units_text.to_string(),
    })?;
    let optional_f64 = |k: usize| found[k].and_then(parse_number).filter(|v| v.is_finite());
    Ok(TrcHeader {
        file_name: String::new(),
        data_rate,
        camera_rate: optional_f64(1),
        num_frames,
        num_markers,
        units,
        orig_data_rate: optional_f64(5),
        orig_data_start_frame: found[6].and_then(|v| v.parse().ok()),
        orig_num_frames: found[7].and_then(|v| v.parse().ok()),
    })
}

/// Reads the labels row (line 4) for `n` markers.
fn parse_labels(
    line: &str,
    n: usize,
    notes: &mut Vec<TrcNote>,
) -> Result<Vec<String>, TrcErrorKind> {
    let cells: Vec<&str> = line.split('\t').collect();
    let first = cells[0].trim();
    if !first.eq_ignore_ascii_case("Frame#") {
        return Err(TrcErrorKind::BadLabelsRow {
            line: 4,
            found: line.chars().take(60).collect(),
        });
    }
    let named: Vec<(usize, &str)> = cells
        .iter()
        .enumerate()
        .skip(2)
        .filter(|(_, c)| !c.trim().is_empty())
        .map(|(i, c)| (i, *c))
        .collect();
    let aligned = named.iter().all(|&(i, _)| (i - 2) % 3 == 0);
    let mut labels: Vec<String> = Vec::with_capacity(n);
    if aligned {
        let slots = named.last().map_or(0, |&(i, _)| (i - 2) / 3 + 1);
        for k in 0..slots.min(n) {
            match cells
                .get(2 + 3 * k)
                .map(|c| c.trim())
                .filter(|c| !c.is_empty())
            {
                Some(l) => labels.push(l.to_string()),
                None => {
                    return Err(TrcErrorKind::EmptyLabel {
                        line: 4,
                        marker: k + 1,
                        previous: labels.last().cloned(),
                    })
                }
            }
        }
    } else {
        notes.push(TrcNote::LabelsNotAligned { line: 4 });
        labels.extend(named.iter().map(|(_, c)| c.trim().to_string()));
    }
    if named.len() != n {
        return Err(TrcErrorKind::MarkerCountMismatch {
            line: 4,
            header: n,
            labels: named.len(),
        });
    }
    let trimmed = named.iter().filter(|(_, c)| c.trim() != *c).count();
    if trimmed > 0 {
        notes.push(TrcNote::TrimmedLabels {
            line: 4,
            count: trimmed,
        });
    }
    for (j, l) in labels.iter().enumerate() {
        if let Some(i) = labels[..j].iter().position(|x| x == l) {
            return Err(TrcErrorKind::DuplicateLabel {
                line: 4,
                label: l.clone(),
                first: i + 1,
                second: j + 1,
            });
        }
    }
    Ok(labels)
}

/// Counts samples of one kind and remembers the first.
#[derive(Default)]
struct Tally {
    count: usize,
    first: Option<(usize, String)>,
}

impl Tally {
    fn add(&mut self, line: usize, marker: &str) {
        self.count += 1;
        if self.first.is_none() {
            self.first = Some((line, marker.to_string()));
        }
    }
    fn into_note(self, make: impl FnOnce(usize, usize, String) -> TrcNote) -> Option<TrcNote> {
        self.first
            .map(|(line, marker)| make(self.count, line, marker))
    }
}

/// Accumulates data rows.
struct Rows<'a> {
    labels: &'a [String],
    scale: f64,
    positions: Vec<Vector3<f64>>,
    times: Vec<f64>,
    /// (line, frame number, printed precision of the time) of each row, for the time check.
    time_cells: Vec<(usize, i64, f64)>,
    first_frame: Option<i64>,
    last_frame: Option<i64>,
    zero: Tally,
    partial: Tally,
}

impl<'a> Rows<'a> {
    fn new(labels: &'a [String], scale: f64) -> Self {
        Rows {
            labels,
            scale,
            positions: Vec::new(),
            times: Vec::new(),
            time_cells: Vec::new(),
            first_frame: None,
            last_frame: None,
            zero: Tally::default(),
            partial: Tally::default(),
        }
    }

    fn push(&mut self, line_no: usize, line: &str) -> Result<(), TrcErrorKind> {
        let n = self.labels.len();
        let cells: Vec<&str> = line.split('\t').collect();
        let frame_text = cells[0].trim();
        let frame = parse_frame_number(frame_text).ok_or_else(|| TrcErrorKind::BadFrameNumber {
            line: line_no,
            value: frame_text.to_string(),
        })?;
        if let Some(prev) = self.last_frame {
            if frame != prev + 1 {
                return Err(TrcErrorKind::FrameNumberJump {
                    line: line_no,
                    previous: prev,
                    found: frame,
                });
            }
        }
        self.first_frame.get_or_insert(frame);
        self.last_frame = Some(frame);
        let time_text = cells.get(1).map_or("", |c| c.trim());
        let time = parse_number(time_text)
            .filter(|t| t.is_finite())
            .ok_or_else(|| TrcErrorKind::BadTime {
                line: line_no,
                value: time_text.to_string(),
            })?;
        self.times.push(time);
        self.time_cells
            .push((line_no, frame, resolution(time_text)));

        let expected = 2 + 3 * n;
        if cells.len() < expected {
            let k = (cells.len().max(2) - 2) / 3;
            return Err(TrcErrorKind::TooFewValues {
                line: line_no,
                marker: self.labels[k].clone(),
                expected,
                found: cells.len(),
            });
        }
        if let Some((i, c)) = cells
            .iter()
            .enumerate()
            .skip(expected)
            .find(|(_, c)| !c.trim().is_empty())
        {
            return Err(TrcErrorKind::ExtraValues {
                line: line_no,
                column: i + 1,
                value: c.trim().to_string(),
                last_marker: self.labels.last().cloned().unwrap_or_default(),
            });
        }
        for (k, label) in self.labels.iter().enumerate() {
            let mut xyz = [f64::NAN; 3];
            let mut missing = 0;
            for (j, v) in xyz.iter_mut().enumerate() {
                let col = 2 + 3 * k + j;
                let text = cells[col].trim();
                if text.is_empty() {
                    missing += 1;
                    continue;
                }
                let x = parse_number(text).ok_or_else(|| TrcErrorKind::BadNumber {
                    line: line_no,
                    column: col + 1,
                    marker: label.clone(),
                    value: text.to_string(),
                })?;
                if x.is_finite() {
                    *v = x * self.scale;
                } else {
                    missing += 1;
                }
            }
            let p = if missing > 0 {
                if missing < 3 {
                    self.partial.add(line_no, label);
                }
                Vector3::repeat(f64::NAN)
            } else if xyz == [0.0; 3] {
                self.zero.add(line_no, label);
                Vector3::repeat(f64::NAN)
            } else {
                Vector3::from(xyz)
            };
            self.positions.push(p);
        }
        Ok(())
    }

    /// Compares the Time column with `first time + i / rate`; a note for the first row off by
    /// more than half a frame plus the printed precision.
    fn check_times(&self, rate: f64) -> Option<TrcNote> {
        let t0 = *self.times.first()?;
        let res0 = self.time_cells.first()?.2;
        for (i, (&t, &(line, frame, res))) in self.times.iter().zip(&self.time_cells).enumerate() {
            let expected = t0 + i as f64 / rate;
            // Both times are rounded to their printed precision; the first is taken to be
            // printed like this row (a shortest-form writer prints it as a bare `0`).
            let tol = 0.5 / rate + res.min(res0) / 2.0 + res / 2.0 + 1e-9 * expected.abs();
            if (t - expected).abs() > tol {
                return Some(TrcNote::TimeDisagreesWithRate {
                    line,
                    frame,
                    expected,
                    found: t,
                });
            }
        }
        None
    }
}

/// Frame numbers are integers; some writers print them as `12.0`.
fn parse_frame_number(s: &str) -> Option<i64> {
    if let Ok(v) = s.parse::<i64>() {
        return Some(v);
    }
    let v: f64 = s.parse().ok()?;
    (v.is_finite() && v.fract() == 0.0 && v.abs() < 9e15).then_some(v as i64)
}

/// The value of one unit in the last printed digit of a number (`4.983` → 0.001).
fn resolution(s: &str) -> f64 {
    let s = s.trim();
    let (mantissa, exp) = match s.find(['e', 'E']) {
        Some(i) => (&s[..i], s[i + 1..].parse::<i32>().unwrap_or(0)),
        None => (s, 0),
    };
    let decimals = mantissa.find('.').map_or(0, |i| mantissa.len() - i - 1) as i32;
    10f64.powi(exp - decimals)
}

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
    let nm = trial.n_markers();
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
        let frame = first + f as i64;
        let time = f as f64 / rate;
        out.push_str(&format!("{frame}\t{time:.time_decimals$}"));
        for p in trial.frame(f) {
            if p.iter().all(|v| v.is_finite()) {
                for v in p.iter() {
                    out.push_str(&format!("\t{:.d$}", v * per_metre));
                }
            } else {
                out.push_str("\t\t\t");
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
