//! OpenSim storage tables: `.mot` (joint angles, forces) and `.sto` (any time series).
//!
//! # The format
//!
//! A header of `key=value` lines and free text, closed by a line reading `endheader`; then a
//! row of tab-separated column labels whose first is `time`; then one row of numbers per time
//! step, tab-separated (older files pad numbers with blanks or separate them by blanks only).
//!
//! Header lines this module understands:
//!
//! * a first line without `=`: the table's name (OpenSim's `Storage` class writes it, e.g.
//!   `Coordinates`; OpenSim 4's `STOFileAdapter` leaves it out);
//! * `version=` (1 for `Storage`, 3 for `STOFileAdapter`; read and not otherwise used);
//! * `nRows=` and `nColumns=`: rows and columns below, `nColumns` counting `time`; the very
//!   old SIMM spellings `datarows N` and `datacolumns N` mean the same;
//! * `inDegrees=yes|no`: whether rotational columns are in degrees. Absent means `no`.
//!
//! Every other header line (`DataType=double`, `OpenSimVersion=…`, comments, blank lines) is
//! kept verbatim, less trailing blanks, in [`Table::extra_header`].
//!
//! Numbers are plain or in exponent notation. A missing value is written `NaN`; OpenSim's
//! `TimeSeriesTable` reads it, but its older `Storage` class does not: without any error it
//! misreads the first row holding one and drops every row after it (checked with OpenSim 4.6),
//! so tables meant for tools built on `Storage` should have no gaps.
//!
//! # Writing
//!
//! [`format_sto`]/[`write_sto`] write the `Storage` layout, which both OpenSim readers accept:
//!
//! ```text
//! <name>
//! version=1
//! nRows=<rows>
//! nColumns=<columns including time>
//! inDegrees=<yes|no>
//! <extra header lines>
//! endheader
//! time<TAB>label…
//! <numbers>
//! ```
//!
//! Each number is written in the shortest form that reads back as exactly the same `f64`
//! (plain notation, or exponent notation below 1e-5 and from 1e16 in magnitude), so a table
//! survives a write and a read bit for bit.

use std::path::Path;

use thiserror::Error;

mod write;
pub use write::{format_sto, write_sto, write_sto_to};

use crate::text::{decode, numbered_lines, parse_number};

/// A table of numbers against time, as OpenSim stores it.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// The name line (may be empty: then no name line is written).
    pub name: String,
    /// Column labels; the first is `time`.
    pub columns: Vec<String>,
    /// One row per time step, `columns.len()` values each; the first value is the time in
    /// seconds. NaN marks a missing value.
    pub rows: Vec<Vec<f64>>,
    /// Whether rotational columns are in degrees (`inDegrees=yes`).
    pub in_degrees: bool,
    /// Header lines other than the name, `version`, `nRows`, `nColumns`, `inDegrees` and
    /// `endheader`, in order, without line ends.
    pub extra_header: Vec<String>,
}

impl Table {
    /// An empty table with a `time` column followed by `labels`.
    pub fn new(name: &str, labels: &[&str], in_degrees: bool) -> Self {
        let mut columns = vec!["time".to_string()];
        columns.extend(labels.iter().map(|s| s.to_string()));
        Table {
            name: name.to_string(),
            columns,
            rows: Vec::new(),
            in_degrees,
            extra_header: Vec::new(),
        }
    }

    /// Index of a column by label.
    pub fn column_index(&self, label: &str) -> Option<usize> {
        self.columns.iter().position(|c| c == label)
    }

    /// One column's values, one per row.
    pub fn column(&self, label: &str) -> Option<Vec<f64>> {
        let i = self.column_index(label)?;
        Some(self.rows.iter().map(|r| r[i]).collect())
    }
}

/// Why a storage file could not be read; always names the file (see [`StoErrorKind`]).
#[derive(Debug, Error)]
#[error("{file}: {kind}")]
pub struct StoError {
    pub file: String,
    pub kind: StoErrorKind,
}

/// What is wrong with a storage file. Line numbers count from 1.
#[derive(Debug, Error)]
pub enum StoErrorKind {
    #[error("cannot read the file: {0}")]
    Io(std::io::Error),
    #[error("the file is empty")]
    Empty,
    #[error("no endheader line: the header never ends (not a .mot/.sto file, or cut short)")]
    NoEndHeader,
    #[error("line {line}: {key} should be {expected}, got {value:?}")]
    BadHeaderValue {
        line: usize,
        key: String,
        expected: &'static str,
        value: String,
    },
    #[error("the file ends after the header, without column labels")]
    NoColumnLabels,
    #[error("line {line}: the first column must be time, found {found:?}")]
    NoTimeColumn { line: usize, found: String },
    #[error("line {line}: column {column} has an empty label")]
    EmptyLabel { line: usize, column: usize },
    #[error("the header says nColumns={header} but line {line} has {labels} column labels")]
    ColumnCountMismatch {
        line: usize,
        header: usize,
        labels: usize,
    },
    #[error("line {line}: {found} values for {expected} columns")]
    CellCount {
        line: usize,
        expected: usize,
        found: usize,
    },
    #[error("line {line}, column {column:?}: not a number: {value:?}")]
    BadNumber {
        line: usize,
        column: String,
        value: String,
    },
    #[error("the header says nRows={header} but {rows} rows are present")]
    RowCountMismatch { header: usize, rows: usize },
}

/// Reads a `.mot`/`.sto` file (OpenSim 4 `STOFileAdapter` or older `Storage` layout).
pub fn read_sto(path: &Path) -> Result<Table, StoError> {
    let name = path.display().to_string();
    let bytes =
        crate::limits::read_bytes(path, crate::limits::TRIAL_BYTES, "motion").map_err(|e| {
            StoError {
                file: name.clone(),
                kind: StoErrorKind::Io(e),
            }
        })?;
    parse_sto(&decode(&bytes), &name)
}

/// Parses storage text (see [`read_sto`]); `name` is used in error messages.
pub fn parse_sto(text: &str, name: &str) -> Result<Table, StoError> {
    parse(text).map_err(|kind| StoError {
        file: name.to_string(),
        kind,
    })
}

/// Splits a row into cells: on tabs when there are any (cells may be padded), otherwise on
/// runs of blanks. Trailing empty cells (trailing tabs) are dropped.
fn cells(line: &str) -> Vec<&str> {
    let mut v: Vec<&str> = if line.contains('\t') {
        line.split('\t').map(str::trim).collect()
    } else {
        line.split_whitespace().collect()
    };
    while v.last().is_some_and(|c| c.is_empty()) {
        v.pop();
    }
    v
}

/// The header lines before `endheader`: the table's name, `inDegrees` and extra lines into
/// `table`; the row and column counts it declares.
fn parse_header(
    header: &[(usize, &str)],
    table: &mut Table,
) -> Result<(Option<usize>, Option<usize>), StoErrorKind> {
    let (mut n_rows, mut n_cols) = (None, None);
    for (i, &(line_no, raw)) in header.iter().enumerate() {
        let line = raw.trim_end();
        let count = |key: &str, v: &str| {
            v.trim()
                .parse::<usize>()
                .map_err(|_| StoErrorKind::BadHeaderValue {
                    line: line_no,
                    key: key.to_string(),
                    expected: "a whole number",
                    value: v.trim().to_string(),
                })
        };
        if let Some((key, value)) = line.split_once('=') {
            match key.trim() {
                "version" => {}
                "nRows" => n_rows = Some(count("nRows", value)?),
                "nColumns" => n_cols = Some(count("nColumns", value)?),
                "inDegrees" => {
                    table.in_degrees = match value.trim().to_ascii_lowercase().as_str() {
                        "yes" => true,
                        "no" => false,
                        _ => {
                            return Err(StoErrorKind::BadHeaderValue {
                                line: line_no,
                                key: "inDegrees".into(),
                                expected: "yes or no",
                                value: value.trim().to_string(),
                            })
                        }
                    }
                }
                _ => table.extra_header.push(line.to_string()),
            }
            continue;
        }
        let mut words = line.split_whitespace();
        match (words.next(), words.next(), words.next()) {
            (Some("datarows"), Some(v), None) => n_rows = Some(count("datarows", v)?),
            (Some("datacolumns"), Some(v), None) => n_cols = Some(count("datacolumns", v)?),
            _ if i == 0 => table.name = line.trim().to_string(),
            _ => table.extra_header.push(line.to_string()),
        }
    }
    Ok((n_rows, n_cols))
}

fn parse(text: &str) -> Result<Table, StoErrorKind> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    if text.trim().is_empty() {
        return Err(StoErrorKind::Empty);
    }
    let lines = numbered_lines(text);
    let end = lines
        .iter()
        .position(|(_, l)| l.trim().eq_ignore_ascii_case("endheader"))
        .ok_or(StoErrorKind::NoEndHeader)?;

    let mut table = Table {
        name: String::new(),
        columns: Vec::new(),
        rows: Vec::new(),
        in_degrees: false,
        extra_header: Vec::new(),
    };
    let (n_rows, n_cols) = parse_header(&lines[..end], &mut table)?;

    let mut body = lines[end + 1..]
        .iter()
        .filter(|(_, l)| !l.trim().is_empty());
    let &(label_line, labels) = body.next().ok_or(StoErrorKind::NoColumnLabels)?;
    table.columns = cells(labels).iter().map(|s| s.to_string()).collect();
    if !table.columns[0].eq_ignore_ascii_case("time") {
        return Err(StoErrorKind::NoTimeColumn {
            line: label_line,
            found: table.columns[0].clone(),
        });
    }
    if let Some(i) = table.columns.iter().position(|c| c.is_empty()) {
        return Err(StoErrorKind::EmptyLabel {
            line: label_line,
            column: i + 1,
        });
    }
    if let Some(h) = n_cols.filter(|&h| h != table.columns.len()) {
        return Err(StoErrorKind::ColumnCountMismatch {
            line: label_line,
            header: h,
            labels: table.columns.len(),
        });
    }
    for &(line_no, line) in body {
        let c = cells(line);
        if c.len() != table.columns.len() {
            return Err(StoErrorKind::CellCount {
                line: line_no,
                expected: table.columns.len(),
                found: c.len(),
            });
        }
        let row = c
            .iter()
            .zip(&table.columns)
            .map(|(v, label)| {
                parse_number(v).ok_or_else(|| StoErrorKind::BadNumber {
                    line: line_no,
                    column: label.clone(),
                    value: v.to_string(),
                })
            })
            .collect::<Result<Vec<f64>, _>>()?;
        table.rows.push(row);
    }
    if let Some(h) = n_rows.filter(|&h| h != table.rows.len()) {
        return Err(StoErrorKind::RowCountMismatch {
            header: h,
            rows: table.rows.len(),
        });
    }
    Ok(table)
}

/// Why a table could not be written.
#[derive(Debug, Error)]
pub enum StoWriteError {
    #[error("the first column must be labelled \"time\", found {found:?}")]
    NoTimeColumn { found: Option<String> },
    #[error("column {column} has label {label:?}, which a storage file cannot hold ({reason})")]
    BadLabel {
        column: usize,
        label: String,
        reason: &'static str,
    },
    #[error("the table name {0:?} must be one line without '='")]
    BadName(String),
    #[error("extra header line {0:?} would be misread (a line break, endheader or a key this writer sets)")]
    BadHeaderLine(String),
    #[error("row {row} has {found} values for {expected} columns")]
    RowLength {
        row: usize,
        expected: usize,
        found: usize,
    },
    #[error("row {row}: time {time} is not finite or not after the previous row's")]
    BadTime { row: usize, time: f64 },
    #[error(
        "row {row}, column {column:?}: {value} cannot be stored (OpenSim reads infinities as NaN)"
    )]
    Infinite {
        row: usize,
        column: String,
        value: f64,
    },
    #[error("{path}: cannot write: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
}

/// The coordinates table OpenSim's inverse kinematics writes (`.mot`): a `time` column, then
/// one column per model coordinate, rotations in degrees and translations in metres
/// (`inDegrees=yes`). `coords` holds one row of `n_q` values (rad, m) per frame of `trial`.
pub fn coordinates_table(
    model: &jointfit::model::Model,
    trial: &jointfit::trial::Trial,
    coords: &[Vec<f64>],
) -> Table {
    use jointfit::model::CoordKind;
    let names: Vec<&str> = model
        .coordinates()
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    let mut table = Table::new("Coordinates", &names, true);
    for (f, q) in coords.iter().enumerate() {
        let mut row = vec![trial.time(f)];
        row.extend(
            model
                .coordinates()
                .iter()
                .zip(q)
                .map(|(c, v)| match c.kind {
                    CoordKind::Rotational => v.to_degrees(),
                    CoordKind::Translational => *v,
                }),
        );
        table.rows.push(row);
    }
    table
}
