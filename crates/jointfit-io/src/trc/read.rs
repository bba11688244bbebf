//! Reading TRC text (see the parent module for the format and the policy on odd files).

use jointfit::trial::Trial;

use super::blocks::{blocks, head, separator, BLOCK_BYTES};
use super::rows::{read_rows, Parsed, Stop};
use super::{Select, TrcErrorKind, TrcFile, TrcHeader, TrcNote, TrcUnits, HEADER_KEYS};
use crate::text::parse_number;

/// Parses TRC text; only the markers `select` accepts (all when `None`) are read and kept.
pub(super) fn parse(text: &str, select: Option<Select>) -> Result<TrcFile, TrcErrorKind> {
    parse_in_blocks(text, select, BLOCK_BYTES)
}

/// [`parse`] with the data rows cut into blocks of at least `block_bytes` bytes (`blocks.rs`):
/// the result does not depend on it (tests compare one block with many).
pub(super) fn parse_in_blocks(
    text: &str,
    select: Option<Select>,
    block_bytes: usize,
) -> Result<TrcFile, TrcErrorKind> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    if text.trim().is_empty() {
        return Err(TrcErrorKind::Empty);
    }
    // The header's five lines; the data rows are cut into blocks of lines, numbered and parsed
    // in parallel (`blocks.rs`, `rows.rs`).
    let sep = separator(text);
    let (lines, data) = head(text, sep, 5);
    let head = parse_head(&lines, select)?;
    let rows = read_rows(
        blocks(data, sep, block_bytes).as_slice(),
        6,
        &head.labels,
        &head.keep,
        head.scale,
    )
    .map_err(|stop| match stop {
        Stop::Error(e) => e,
        // Text in memory is already a `str`.
        Stop::NotUtf8 => TrcErrorKind::Io(std::io::Error::other("not UTF-8")),
    })?;
    finish(head, rows)
}

/// What the five header lines say: the header, the labels, which markers are read, the
/// unit's scale and the notes so far.
pub(super) struct Head {
    pub(super) header: TrcHeader,
    pub(super) labels: Vec<String>,
    pub(super) keep: Vec<bool>,
    pub(super) scale: f64,
    notes: Vec<TrcNote>,
}

/// Reads the header lines (`lines`: the first five of the text, numbered from 1; fewer when
/// the text has fewer).
pub(super) fn parse_head(
    lines: &[(usize, &str)],
    select: Option<Select>,
) -> Result<Head, TrcErrorKind> {
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
        // n equals the number of labels on line 4 here, so 3 * n cannot overflow.
        return Err(TrcErrorKind::CoordinateRowMismatch {
            line: 5,
            expected: 3 * n,
            found: coords,
        });
    }

    let scale = header.units.to_metres();
    let mut keep: Vec<bool> = labels.iter().map(|l| select.is_none_or(|s| s(l))).collect();
    // A selection that keeps no marker reads them all: a trial has at least one marker, and
    // the caller then says which of its markers the file lacks.
    if !keep.contains(&true) {
        keep.fill(true);
    }
    Ok(Head {
        header,
        labels,
        keep,
        scale,
        notes,
    })
}

/// The file from its header and data rows: the row count against the header, the time
/// checks, the notes and the trial.
pub(super) fn finish(head: Head, mut data: Parsed) -> Result<TrcFile, TrcErrorKind> {
    let Head {
        header,
        labels,
        keep,
        mut notes,
        ..
    } = head;
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
    let (rate, keep_times) = time_column(&data, header.data_rate, &mut notes);
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
    let Parsed {
        positions,
        times,
        first_frame,
        ..
    } = data;
    let first_frame = first_frame.or(header.orig_data_start_frame).unwrap_or(1);
    let labels: Vec<String> = labels
        .into_iter()
        .zip(&keep)
        .filter_map(|(l, &k)| k.then_some(l))
        .collect();
    let stamps = keep_times.then(|| times.clone());
    let trial = Trial::new(labels, rate, first_frame, positions)
        .and_then(|t| t.with_times(stamps))
        .map_err(|e| {
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

/// The trial's rate, and whether the Time column becomes its time stamps: when it agrees
/// with DataRate and strictly increases (OpenSim copies it into its results), or when it is
/// evenly spaced at another rate (then the column's rate); a note says which.
fn time_column(data: &Parsed, header_rate: f64, notes: &mut Vec<TrcNote>) -> (f64, bool) {
    let mut keep_times = true;
    let mut rate = header_rate;
    if let Some(note) = data.check_times(header_rate) {
        // A file resampled without updating its header (OpenSim's own exports of walking2/5
        // keep every 10th frame and DataRate 250 Hz): when the Time column is evenly spaced
        // at another rate, OpenSim uses the Time column, and so does the trial (its time
        // stamps as written, its rate the column's).
        // The last row may be off the grid: a file resampled by keeping every k-th frame
        // and the original last frame (OpenSim's walking5 export: last step 8 ms, not 40).
        let n = data.times.len().saturating_sub(1);
        match column_rate(&data.times).filter(|&r| data.check_first_times(r, n).is_none()) {
            Some(r) => {
                // Equal rates: only the last row is off the grid, its time kept as written.
                if (r - header_rate).abs() > 1e-9 * r {
                    notes.push(TrcNote::RateFromTimeColumn {
                        header: header_rate,
                        column: r,
                    });
                }
                rate = r;
            }
            None => {
                notes.push(note);
                keep_times = false;
            }
        }
    } else if let Some(i) = (1..data.times.len()).find(|&i| data.times[i] <= data.times[i - 1]) {
        let (line, frame, _) = data.time_cells[i];
        notes.push(TrcNote::TimeNotIncreasing {
            line,
            frame,
            found: data.times[i],
        });
        keep_times = false;
    }
    (rate, keep_times)
}

fn parse_header(keys: &str, values: &str) -> Result<TrcHeader, TrcErrorKind> {
    let keys: Vec<&str> = keys.split('\t').map(str::trim).collect();
    let values: Vec<&str> = values.split('\t').map(str::trim).collect();
    // Doubled or blank separators (OpenSim's own pipeline files have them on line 3): when
    // the two lines hold the same number of non-empty cells but not at the same places, they
    // are paired in order, as OpenSim does. Otherwise cells pair by position, so a blank
    // optional value stays blank.
    fn compact<'a>(cells: &[&'a str]) -> Vec<&'a str> {
        cells.iter().copied().filter(|c| !c.is_empty()).collect()
    }
    let misplaced = keys
        .iter()
        .zip(values.iter().chain(std::iter::repeat(&"")))
        .any(|(k, v)| k.is_empty() != v.is_empty());
    if misplaced && compact(&keys).len() == compact(&values).len() {
        return pair_header(&compact(&keys), &compact(&values));
    }
    pair_header(&keys, &values)
}

fn pair_header(keys: &[&str], values: &[&str]) -> Result<TrcHeader, TrcErrorKind> {
    let mut found: [Option<&str>; 8] = [None; 8];
    for (i, key) in keys.iter().enumerate() {
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
        // `100.0` is a count too (OpenSim reads it; its pipeline files write it).
        v.parse::<usize>()
            .ok()
            .or_else(|| {
                parse_number(v)
                    .filter(|x| x.fract() == 0.0 && *x >= 0.0 && *x < 1e15)
                    .map(|x| x as usize)
            })
            .ok_or_else(|| TrcErrorKind::BadHeaderValue {
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
    let mut labels: Vec<String> = Vec::new();
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

/// The rate of an evenly spaced Time column, one over its median step (rounded to a whole
/// number of Hz when within 1e-6 of one: printed times lose digits; the median, because a
/// resampled file may end on the original last frame, off the grid); `None` for fewer than
/// two rows or times that do not increase.
fn column_rate(times: &[f64]) -> Option<f64> {
    if times.len() < 2 || times.windows(2).any(|w| w[1] <= w[0]) {
        return None;
    }
    let mut steps: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    let r = 1.0 / steps[steps.len() / 2];
    if !(r.is_finite() && r > 0.0) {
        return None;
    }
    Some(if (r - r.round()).abs() <= 1e-6 * r {
        r.round()
    } else {
        r
    })
}
