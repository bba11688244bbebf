//! `jointfit stream <MODEL> [--up AXIS] [--hold-undetermined] [--keep-outliers]`: inverse
//! kinematics of a live marker feed, a line in and a line out per frame (`docs/streaming.md`).
//!
//! Input on standard input, tab-separated, one line per line end (LF or CRLF):
//! * line 1: the marker labels (a Vicon `Subject:` prefix shared by all is dropped);
//! * every later line: the time (s), then x, y, z of each marker in label order, in mm in the
//!   laboratory frame; an empty cell or `NaN` in any of a marker's three makes it missing.
//!   Blank lines are skipped.
//!
//! Output on standard output, tab-separated, every answer flushed before the stream waits for
//! input (see [`serve`]):
//! * line 1: `time` and the coordinate names in model order (locked and coupled coordinates
//!   after them), the columns of `jointfit ik`'s `.mot`;
//! * one line per input frame: its time and the coordinates, degrees for rotations and metres
//!   for translations as in the `.mot`; `NaN` in every coordinate when the frame cannot be
//!   solved (its markers leave a coordinate undetermined, or the fit failed), and the stream
//!   goes on.
//!
//! A malformed line ends the stream with a one-line error naming the line (exit status 1).
//! At the end of the input one summary line goes to standard error.

use std::io::{BufRead, Read, Write};

use anyhow::{bail, Context, Result};
use clap::Args;
use jointfit::ik::stream::StreamingIk;
use jointfit::ik::{FrameStatus, IkOptions};
use jointfit::model::custom::MotionType;
use jointfit::model::Model;
use jointfit::spatial::UpAxis;
use jointfit_app::present::M_PER_MM;
use nalgebra::Vector3;

use crate::common::Up;

#[derive(Args)]
pub struct StreamArgs {
    /// Subject model (TOML file, OpenSim .osim or built-in name).
    pub model: String,
    /// Which laboratory axis points up in the feed (default: the subject model's `lab_up`,
    /// recorded by `personalize`; else y).
    #[arg(long, value_enum)]
    pub up: Option<Up>,
    /// Solve frames whose markers leave some coordinates undetermined by holding those at
    /// the previous frame's values (instead of a line of NaN).
    #[arg(long)]
    pub hold_undetermined: bool,
    /// Keep every marker sample that is finite and within 1 km (no gross-error rejection
    /// after the fit; OpenSim's behaviour).
    #[arg(long)]
    pub keep_outliers: bool,
}

/// Longest input line accepted (bytes): far above any marker set (1000 markers take about
/// 40 kB), and a bound on the memory a feed without line ends can take.
const MAX_LINE_BYTES: u64 = 1 << 20;

pub fn run(args: StreamArgs) -> Result<()> {
    let model = jointfit_io::model_file::load_model(&args.model)?;
    let up = match (args.up, model.spec().lab_up) {
        (Some(u), _) => u.into(),
        (None, Some(u)) => u,
        (None, None) => UpAxis::Y,
    };
    let opts = IkOptions::with_rules(args.hold_undetermined, !args.keep_outliers);
    let stdin = std::io::stdin();
    let stdout = std::io::stdout();
    let mut input = std::io::BufReader::with_capacity(1 << 16, stdin.lock());
    let mut out = std::io::BufWriter::with_capacity(1 << 16, stdout.lock());
    let summary = serve(&model, up, &opts, &mut input, &mut out)?;
    eprintln!("jointfit: stream: {}", summary.line());
    Ok(())
}

/// What a stream did, for its closing line.
#[derive(Debug, Default)]
pub struct Summary {
    pub frames: usize,
    pub solved: usize,
    /// The first frame not solved: its input line and why.
    pub first_unsolved: Option<(usize, String)>,
}

impl Summary {
    fn line(&self) -> String {
        let mut s = format!("{} frames, {} solved", self.frames, self.solved);
        if let Some((line, why)) = &self.first_unsolved {
            s.push_str(&format!(
                "; {} not solved (NaN lines; the first on input line {line}: {why})",
                self.frames - self.solved
            ));
        }
        s
    }
}

/// The protocol of the module docs between `input` and `output`, with `model` (coordinates
/// it leaves undetermined locked at their defaults, as `ik` does) in a laboratory whose
/// vertical is `up`. Warnings go to standard error. Returns at the end of the input.
///
/// Each answer is flushed before the stream reads further, unless the next frame's line has
/// already arrived: frames that queue up (they arrive faster than they are solved) are
/// answered in one write, and no answer ever waits for input.
pub fn serve<R: Read>(
    model: &Model,
    up: UpAxis,
    opts: &IkOptions,
    input: &mut std::io::BufReader<R>,
    output: &mut impl Write,
) -> Result<Summary> {
    let mut reader = Lines::new(input);
    let Some((_, first)) = reader.next()? else {
        bail!("standard input is empty: the first line must be the tab-separated marker labels");
    };
    let labels = parse_labels(first)?;
    let mut stream = StreamingIk::new(model, &labels, up, *opts)
        .context("standard input line 1 (the marker labels)")?;
    let setup = stream.last();
    if !setup.held.is_empty() {
        eprintln!(
            "jointfit: warning: stream: no marker of the feed determines {}; held at the model's \
             default values",
            setup.held.join(", ")
        );
    }
    if !setup.absent.is_empty() {
        eprintln!(
            "jointfit: warning: stream: the feed lacks model markers {}; they count as missing \
             in every frame",
            setup.absent.join(", ")
        );
    }
    let columns = Columns::new(stream.model().clone());
    let mut text = String::new();
    columns.header(&mut text);
    write_line(output, &text, true)?;
    let mut markers = vec![Vector3::zeros(); labels.len()];
    let mut summary = Summary::default();
    while let Some((number, line)) = reader.next()? {
        if line.trim().is_empty() {
            continue;
        }
        let time = parse_frame(line, &labels, &mut markers)
            .with_context(|| format!("standard input line {number}"))?;
        let frame = stream
            .update(time, &markers)
            .with_context(|| format!("standard input line {number}"))?;
        text.clear();
        columns.row(&mut text, time, frame.coords);
        write_line(output, &text, !reader.has_line())?;
        summary.frames += 1;
        let fit = frame.fit.expect("a frame was solved");
        if fit.solved() {
            summary.solved += 1;
        } else if summary.first_unsolved.is_none() {
            summary.first_unsolved = Some((number, reason(&fit.status)));
        }
    }
    Ok(summary)
}

/// Why a frame was not solved, in the words of `ik`'s summary.
fn reason(status: &FrameStatus) -> String {
    match status {
        FrameStatus::Undetermined { coordinate } => format!("{coordinate} undetermined"),
        FrameStatus::Diverged => "diverged".into(),
        other => format!("{other:?}"),
    }
}

/// Writes `text`, then flushes when `flush`.
fn write_line(output: &mut impl Write, text: &str, flush: bool) -> Result<()> {
    output
        .write_all(text.as_bytes())
        .and_then(|()| if flush { output.flush() } else { Ok(()) })
        .context("cannot write to standard output")
}

/// Input lines with their numbers (from 1), each at most [`MAX_LINE_BYTES`], without the
/// line end; one buffer for the whole stream.
struct Lines<'a, R> {
    input: &'a mut R,
    bytes: Vec<u8>,
    number: usize,
}

impl<'a, R: Read> Lines<'a, std::io::BufReader<R>> {
    /// Whether a whole further line is already read into the buffer (so the next
    /// [`Lines::next`] does not wait).
    fn has_line(&self) -> bool {
        self.input.buffer().contains(&b'\n')
    }
}

impl<'a, R: BufRead> Lines<'a, R> {
    fn new(input: &'a mut R) -> Self {
        Lines {
            input,
            bytes: Vec::new(),
            number: 0,
        }
    }

    fn next(&mut self) -> Result<Option<(usize, &str)>> {
        self.bytes.clear();
        self.number += 1;
        let n = self.number;
        let read = Read::take(&mut *self.input, MAX_LINE_BYTES + 1)
            .read_until(b'\n', &mut self.bytes)
            .with_context(|| format!("reading standard input line {n}"))?;
        if read == 0 {
            return Ok(None);
        }
        if self.bytes.len() as u64 > MAX_LINE_BYTES {
            bail!("standard input line {n} is longer than {MAX_LINE_BYTES} bytes");
        }
        let mut line = &self.bytes[..];
        line = line.strip_suffix(b"\n").unwrap_or(line);
        line = line.strip_suffix(b"\r").unwrap_or(line);
        std::str::from_utf8(line)
            .map(|l| Some((n, l)))
            .map_err(|_| anyhow::anyhow!("standard input line {n} is not UTF-8 text"))
    }
}

/// The labels of line 1: tab-separated, blanks around each trimmed, a `Subject:` prefix
/// shared by every label dropped (as the trial readers drop it).
fn parse_labels(line: &str) -> Result<Vec<String>> {
    let mut labels: Vec<String> = line.split('\t').map(|l| l.trim().to_string()).collect();
    if let Some(k) = labels.iter().position(|l| l.is_empty()) {
        bail!(
            "standard input line 1: label {} is empty (the first line must be the tab-separated \
             marker labels)",
            k + 1
        );
    }
    if let Some((prefix, _)) = labels[0].split_once(':') {
        let prefix = format!("{prefix}:");
        if labels
            .iter()
            .all(|l| l.starts_with(&prefix) && l.len() > prefix.len())
        {
            for l in &mut labels {
                l.drain(..prefix.len());
            }
        }
    }
    if let Some(t) = labels.iter().position(|l| l.parse::<f64>().is_ok()) {
        bail!(
            "standard input line 1: label {} is the number {:?}: the first line must be the \
             marker labels, not a frame",
            t + 1,
            labels[t]
        );
    }
    Ok(labels)
}

/// Reads one frame line into `markers` (metres, laboratory frame; NaN where missing) and
/// returns its time.
fn parse_frame(line: &str, labels: &[String], markers: &mut [Vector3<f64>]) -> Result<f64> {
    let mut cells = line.split('\t');
    let time_cell = cells.next().unwrap_or("").trim();
    let time: f64 = time_cell
        .parse()
        .ok()
        .filter(|t: &f64| t.is_finite())
        .with_context(|| format!("the time is not a number: {time_cell:?}"))?;
    let mut count = 1;
    for (j, label) in labels.iter().enumerate() {
        let mut xyz = [f64::NAN; 3];
        let mut missing = false;
        for (axis, v) in xyz.iter_mut().enumerate() {
            let Some(cell) = cells.next() else {
                bail!(
                    "{count} cells, expected {} (the time, then x y z of each of the {} markers)",
                    1 + 3 * labels.len(),
                    labels.len()
                );
            };
            count += 1;
            let cell = cell.trim();
            if cell.is_empty() || cell.eq_ignore_ascii_case("nan") {
                missing = true;
                continue;
            }
            *v = cell.parse::<f64>().map_err(|_| {
                anyhow::anyhow!(
                    "marker {label}, {}: not a number: {cell:?}",
                    ["x", "y", "z"][axis]
                )
            })?;
        }
        markers[j] = if missing {
            Vector3::repeat(f64::NAN)
        } else {
            Vector3::new(xyz[0], xyz[1], xyz[2]) * M_PER_MM
        };
    }
    let extra = cells.count();
    if extra > 0 {
        bail!(
            "{} cells, expected {} (the time, then x y z of each of the {} markers)",
            count + extra,
            1 + 3 * labels.len(),
            labels.len()
        );
    }
    Ok(time)
}

/// The output columns: the `.mot` columns of `jointfit ik` (`ik_cmd::angles_table`).
struct Columns {
    model: Model,
}

impl Columns {
    fn new(model: Model) -> Self {
        Columns { model }
    }

    fn header(&self, out: &mut String) {
        out.push_str("time");
        let names = self.model.coordinates().iter().map(|c| c.name.as_str());
        let dependents = self.model.dependents().iter().map(|d| d.name.as_str());
        for name in names.chain(dependents) {
            out.push('\t');
            out.push_str(name);
        }
        out.push('\n');
    }

    fn row(&self, out: &mut String, time: f64, q: &[f64]) {
        push_number(out, time);
        let unit = |motion: MotionType, v: f64| match motion {
            MotionType::Rotational => v.to_degrees(),
            MotionType::Translational | MotionType::Coupled => v,
        };
        for (c, &v) in self.model.coordinates().iter().zip(q) {
            out.push('\t');
            push_number(out, unit(c.motion, v));
        }
        for d in self.model.dependents() {
            out.push('\t');
            push_number(out, unit(d.motion, d.value(q)));
        }
        out.push('\n');
    }
}

/// A number as the `.mot` writer prints it: the shortest text that reads back to the same
/// value (plain from 1e-5 to 1e16, else exponent notation), `NaN` when missing.
fn push_number(out: &mut String, v: f64) {
    use std::fmt::Write;
    let _ = if v.is_nan() {
        write!(out, "NaN")
    } else if v == 0.0 || (1e-5..1e16).contains(&v.abs()) {
        write!(out, "{v}")
    } else {
        write!(out, "{v:e}")
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(names: &[&str]) -> Vec<String> {
        names.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn frame_cells_in_mm_with_missing_markers() {
        let l = labels(&["A", "B", "C"]);
        let mut m = vec![Vector3::zeros(); 3];
        let t = parse_frame("0.25\t1000\t-2\t3.5\t\t4\t5\tNaN\t1\t2", &l, &mut m).unwrap();
        assert_eq!(t, 0.25);
        assert_eq!(m[0], Vector3::new(1.0, -0.002, 0.0035));
        assert!(m[1].iter().all(|v| v.is_nan()));
        assert!(m[2].iter().all(|v| v.is_nan()));
    }

    #[test]
    fn malformed_frames_say_what_is_wrong() {
        let l = labels(&["A", "B"]);
        let mut m = vec![Vector3::zeros(); 2];
        let e = |line: &str, m: &mut Vec<Vector3<f64>>| {
            format!("{:#}", parse_frame(line, &l, m).unwrap_err())
        };
        assert_eq!(
            e("0.1\t1\t2\t3\t4\t5", &mut m),
            "6 cells, expected 7 (the time, then x y z of each of the 2 markers)"
        );
        assert_eq!(
            e("0.1\t1\t2\t3\t4\t5\t6\t7", &mut m),
            "8 cells, expected 7 (the time, then x y z of each of the 2 markers)"
        );
        assert_eq!(
            e("0.1\t1\t2\t3\t4\tfive\t6", &mut m),
            "marker B, y: not a number: \"five\""
        );
        assert_eq!(
            e("\t1\t2\t3\t4\t5\t6", &mut m),
            "the time is not a number: \"\""
        );
        assert_eq!(
            e("inf\t1\t2\t3\t4\t5\t6", &mut m),
            "the time is not a number: \"inf\""
        );
    }

    #[test]
    fn labels_lose_a_shared_subject_prefix() {
        assert_eq!(
            parse_labels("S1:RASI\tS1:LASI").unwrap(),
            labels(&["RASI", "LASI"])
        );
        assert_eq!(
            parse_labels("S1:RASI\tLASI").unwrap(),
            labels(&["S1:RASI", "LASI"])
        );
        let e = parse_labels("RASI\t\tLASI").unwrap_err().to_string();
        assert!(e.contains("label 2 is empty"), "{e}");
        let e = parse_labels("0.0\t1\t2").unwrap_err().to_string();
        assert!(e.contains("not a frame"), "{e}");
    }

    #[test]
    fn numbers_print_as_the_mot_writer_prints_them() {
        let mut s = String::new();
        for v in [0.0, 1.5, -12.25, 1e-7, 3e20, f64::NAN] {
            push_number(&mut s, v);
            s.push(' ');
        }
        assert_eq!(s, "0 1.5 -12.25 1e-7 3e20 NaN ");
        // The same text as the .mot writer for a row of values.
        let table = jointfit_io::sto::Table {
            rows: vec![vec![0.01, 1.0 / 3.0, -2.0e-6, 123456.789]],
            ..jointfit_io::sto::Table::new("t", &["a", "b", "c"], true)
        };
        let text = jointfit_io::sto::format_sto(&table).unwrap();
        let mut row = String::new();
        for (i, v) in table.rows[0].iter().enumerate() {
            if i > 0 {
                row.push('\t');
            }
            push_number(&mut row, *v);
        }
        assert!(text.ends_with(&format!("{row}\n")), "{text}\n{row}");
    }
}
