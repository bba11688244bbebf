//! The data rows of a TRC file (line 6 on): parsed in chunks of lines on every thread.

use nalgebra::Vector3;

use super::blocks::Block;
use super::{TrcErrorKind, TrcNote};
use crate::text::parse_number;

/// Counts samples of one kind and remembers the first.
#[derive(Default)]
pub(super) struct Tally {
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
    /// Adds the samples of `later`, counted after these.
    fn append(&mut self, later: Tally) {
        self.count += later.count;
        if self.first.is_none() {
            self.first = later.first;
        }
    }
    pub(super) fn into_note(
        self,
        make: impl FnOnce(usize, usize, String) -> TrcNote,
    ) -> Option<TrcNote> {
        self.first
            .map(|(line, marker)| make(self.count, line, marker))
    }
}

/// Why the data rows were not read: an error of the file, or a block that is not UTF-8 (the
/// caller then reads the whole text as `text::decode` does).
pub(super) enum Stop {
    Error(TrcErrorKind),
    NotUtf8,
}

/// Where the blocks of data lines come from: a text in memory, or a file read block by block
/// (`stream.rs`).
pub(super) trait BlockSource: Sync {
    /// How many blocks.
    fn count(&self) -> usize;
    /// Calls `f` with block `i`.
    fn with_block<R>(&self, i: usize, f: impl FnOnce(Block<'_>) -> R) -> Result<R, Stop>;
}

impl BlockSource for [Block<'_>] {
    fn count(&self) -> usize {
        self.len()
    }
    fn with_block<R>(&self, i: usize, f: impl FnOnce(Block<'_>) -> R) -> Result<R, Stop> {
        Ok(f(self[i]))
    }
}

/// The rows of all blocks, joined: what `read.rs::finish` needs of them.
pub(super) struct Parsed {
    /// Positions of the kept markers, row by row.
    pub(super) positions: Vec<Vector3<f64>>,
    pub(super) times: Vec<f64>,
    /// (line, frame number, printed precision of the time) of each row, for the time check.
    pub(super) time_cells: Vec<(usize, i64, f64)>,
    pub(super) first_frame: Option<i64>,
    pub(super) zero: Tally,
    pub(super) partial: Tally,
}

/// Parses the blocks of data lines (`blocks.rs`; the first is line `first_line` of the file)
/// on every thread, each with its lines numbered from 0, then joins them in order, adding
/// the lines of the blocks before: the same rows, notes and first error (in line order,
/// frame-number jumps between blocks included) as one pass over the lines. A block that
/// stops at an error has counted its lines only that far, but no block after it is used.
pub(super) fn read_rows<S: BlockSource + ?Sized>(
    source: &S,
    first_line: usize,
    labels: &[String],
    keep: &[bool],
    scale: f64,
) -> Result<Parsed, Stop> {
    use rayon::prelude::*;
    type Chunk<'a> = (Rows<'a>, Option<TrcErrorKind>, usize);
    let chunks: Vec<Result<Chunk<'_>, Stop>> = (0..source.count())
        .into_par_iter()
        .map(|i| {
            source.with_block(i, |block| {
                let mut rows = Rows::new(labels, keep, scale);
                // About 9 bytes a cell: a first guess that saves most reallocations.
                let guess = block.text.len() / (9 * (2 + 3 * labels.len())).max(1);
                rows.positions.reserve(guess * rows.kept);
                let mut lines = 0;
                for (line_no, line) in block.lines() {
                    lines = line_no + 1;
                    if line.trim().is_empty() {
                        continue;
                    }
                    if let Err(e) = rows.push(line_no, line) {
                        return (rows, Some(e), lines);
                    }
                }
                (rows, None, lines)
            })
        })
        .collect();
    // The blocks in order, up to the first error; their line numbers moved to the file's.
    let mut used: Vec<Rows<'_>> = Vec::with_capacity(chunks.len());
    let mut last_frame: Option<i64> = None;
    let mut before = first_line;
    for chunk in chunks {
        let (mut rows, error, lines) = chunk?;
        rows.shift_lines(before);
        if let (Some(previous), Some(found)) = (last_frame, rows.first_frame) {
            if previous.checked_add(1) != Some(found) {
                return Err(Stop::Error(TrcErrorKind::FrameNumberJump {
                    line: rows.first_line,
                    previous,
                    found,
                }));
            }
        }
        if let Some(e) = error {
            return Err(Stop::Error(super::blocks::shift_error(e, before)));
        }
        last_frame = rows.last_frame.or(last_frame);
        before += lines;
        used.push(rows);
    }
    Ok(join(used))
}

impl From<TrcErrorKind> for Stop {
    fn from(e: TrcErrorKind) -> Self {
        Stop::Error(e)
    }
}

/// The blocks' rows as one: the positions (most of the bytes) are copied into place on
/// every thread, the rest in order.
fn join(blocks: Vec<Rows<'_>>) -> Parsed {
    use rayon::prelude::*;
    let total: usize = blocks.iter().map(|r| r.positions.len()).sum();
    let mut positions: Vec<Vector3<f64>> = Vec::with_capacity(total);
    {
        // Disjoint parts of the new vector's spare room, one per block, in order.
        let mut room = &mut positions.spare_capacity_mut()[..total];
        let mut parts = Vec::with_capacity(blocks.len());
        for rows in &blocks {
            let (part, rest) = room.split_at_mut(rows.positions.len());
            parts.push(part);
            room = rest;
        }
        parts
            .into_par_iter()
            .zip(blocks.par_iter())
            .for_each(|(part, rows)| {
                for (slot, p) in part.iter_mut().zip(&rows.positions) {
                    slot.write(*p);
                }
            });
    }
    // SAFETY: the parts cover the first `total` slots exactly (their lengths sum to `total`)
    // and every slot of every part was written above.
    unsafe { positions.set_len(total) };
    let rows: usize = blocks.iter().map(|r| r.times.len()).sum();
    let mut out = Parsed {
        positions,
        times: Vec::with_capacity(rows),
        time_cells: Vec::with_capacity(rows),
        first_frame: None,
        zero: Tally::default(),
        partial: Tally::default(),
    };
    for b in blocks {
        if out.first_frame.is_none() {
            out.first_frame = b.first_frame;
        }
        out.times.extend(b.times);
        out.time_cells.extend(b.time_cells);
        out.zero.append(b.zero);
        out.partial.append(b.partial);
    }
    out
}

/// Accumulates data rows.
pub(super) struct Rows<'a> {
    /// Every marker's label, in file order.
    pub(super) labels: &'a [String],
    /// Whether each marker's columns are read (its positions kept).
    pub(super) keep: &'a [bool],
    /// How many markers are kept.
    pub(super) kept: usize,
    /// `keep` as runs of kept and skipped markers (`fast::runs`).
    runs: Vec<(bool, usize)>,
    pub(super) scale: f64,
    /// Positions of the kept markers, row by row.
    pub(super) positions: Vec<Vector3<f64>>,
    pub(super) times: Vec<f64>,
    /// (line, frame number, printed precision of the time) of each row, for the time check.
    pub(super) time_cells: Vec<(usize, i64, f64)>,
    pub(super) first_frame: Option<i64>,
    /// The line of the first row.
    pub(super) first_line: usize,
    pub(super) last_frame: Option<i64>,
    pub(super) zero: Tally,
    pub(super) partial: Tally,
}

impl<'a> Rows<'a> {
    fn new(labels: &'a [String], keep: &'a [bool], scale: f64) -> Self {
        Rows {
            labels,
            keep,
            kept: keep.iter().filter(|&&k| k).count(),
            runs: super::fast::runs(keep),
            scale,
            positions: Vec::new(),
            times: Vec::new(),
            time_cells: Vec::new(),
            first_frame: None,
            first_line: 0,
            last_frame: None,
            zero: Tally::default(),
            partial: Tally::default(),
        }
    }

    /// Reads one data row: by the fast path when it can (`fast.rs`), else by [`Rows::push_checked`].
    fn push(&mut self, line_no: usize, line: &str) -> Result<(), TrcErrorKind> {
        let before = self.positions.len();
        let Some(row) = super::fast::row(line, &self.runs, self.scale, &mut self.positions) else {
            self.positions.truncate(before);
            return self.push_checked(line_no, line);
        };
        if let Some(prev) = self.last_frame {
            if prev.checked_add(1) != Some(row.frame) {
                self.positions.truncate(before);
                return Err(TrcErrorKind::FrameNumberJump {
                    line: line_no,
                    previous: prev,
                    found: row.frame,
                });
            }
        }
        if self.first_frame.is_none() {
            self.first_frame = Some(row.frame);
            self.first_line = line_no;
        }
        self.last_frame = Some(row.frame);
        self.times.push(row.time);
        self.time_cells
            .push((line_no, row.frame, 10f64.powi(-row.time_decimals)));
        Ok(())
    }

    /// Reads one data row with every check and message (the general path).
    fn push_checked(&mut self, line_no: usize, line: &str) -> Result<(), TrcErrorKind> {
        let n = self.labels.len();
        let cells = split_tabs(line, 2 + 3 * n);
        let frame_text = cells[0].trim();
        let frame = parse_frame_number(frame_text).ok_or_else(|| TrcErrorKind::BadFrameNumber {
            line: line_no,
            value: frame_text.to_string(),
        })?;
        if let Some(prev) = self.last_frame {
            if prev.checked_add(1) != Some(frame) {
                return Err(TrcErrorKind::FrameNumberJump {
                    line: line_no,
                    previous: prev,
                    found: frame,
                });
            }
        }
        if self.first_frame.is_none() {
            self.first_frame = Some(frame);
            self.first_line = line_no;
        }
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
                marker: self.labels.get(k).cloned().unwrap_or_default(),
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
            if !self.keep[k] {
                continue;
            }
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

    /// Moves every line number by `by` (from a block's numbering to the file's).
    fn shift_lines(&mut self, by: usize) {
        self.first_line += by;
        for cell in &mut self.time_cells {
            cell.0 += by;
        }
        for tally in [&mut self.zero, &mut self.partial] {
            if let Some((line, _)) = &mut tally.first {
                *line += by;
            }
        }
    }
}

impl Parsed {
    /// Compares the Time column with `first time + i / rate`; a note for the first row off by
    /// more than half a frame plus the printed precision.
    pub(super) fn check_times(&self, rate: f64) -> Option<TrcNote> {
        self.check_first_times(rate, self.times.len())
    }

    /// [`Self::check_times`] on the first `n` rows only.
    pub(super) fn check_first_times(&self, rate: f64, n: usize) -> Option<TrcNote> {
        let t0 = *self.times.first()?;
        let res0 = self.time_cells.first()?.2;
        let rows = self.times.iter().zip(&self.time_cells).take(n);
        for (i, (&t, &(line, frame, res))) in rows.enumerate() {
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

/// The tab-separated cells of `line` (as `line.split('\t')`), with room for `expected`. A
/// byte loop: TRC cells are short, and a search call per cell costs more than the scan.
fn split_tabs(line: &str, expected: usize) -> Vec<&str> {
    let mut cells = Vec::with_capacity(expected + 1);
    let mut start = 0;
    for (i, &b) in line.as_bytes().iter().enumerate() {
        if b == b'\t' {
            // Tabs are ASCII, so both ends are character boundaries.
            cells.push(&line[start..i]);
            start = i + 1;
        }
    }
    cells.push(&line[start..]);
    cells
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
    10f64.powi(exp.saturating_sub(decimals))
}

#[cfg(test)]
#[path = "rows_tests.rs"]
mod tests;
