//! `jointfit inspect` and `jointfit convert`: look into a motion file, turn it into a TRC.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use jointfit::trial::Trial;
use jointfit_io::trc::{write_trc, TrcUnits, TrcWriteOptions};
use serde::Serialize;

use crate::common::{load_trial, Up};
use crate::table::Table;

#[derive(Args)]
pub struct InspectArgs {
    /// Motion file (.trc or .c3d)
    file: PathBuf,
    /// Print the summary as JSON
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct ConvertArgs {
    /// Motion file to read (.trc or .c3d)
    input: PathBuf,
    /// TRC file to write (replaced atomically)
    output: PathBuf,
    /// Low-pass filter cutoff in Hz (zero-phase Butterworth, effective order 4)
    #[arg(long, allow_negative_numbers = true, value_parser = crate::validate::cutoff_hz)]
    filter: Option<f64>,
    /// Which axis of the input points up; the output is Y-up (OpenSim's convention).
    /// Default: detected from the marker layout (head and pelvis above the feet), else y
    #[arg(long, alias = "rotate", value_enum)]
    up: Option<Up>,
    /// Units of the written file
    #[arg(long, value_enum, default_value = "mm")]
    units: UnitsArg,
    /// Digits after the decimal point
    #[arg(long, default_value_t = 5, allow_negative_numbers = true, value_parser = crate::validate::decimals)]
    decimals: usize,
    /// Keep only these markers (comma-separated labels, in this order)
    #[arg(long, value_delimiter = ',')]
    markers: Vec<String>,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum UnitsArg {
    Mm,
    Cm,
    M,
}

#[derive(Serialize)]
struct MarkerSummary {
    label: String,
    missing_percent: f64,
    longest_gap_frames: usize,
}

#[derive(Serialize)]
struct Summary {
    file: String,
    format: &'static str,
    /// Units the file stores its positions in (jointfit works in metres).
    units: String,
    rate_hz: f64,
    frames: usize,
    first_frame: i64,
    duration_s: f64,
    markers: Vec<MarkerSummary>,
    /// Header details that did not stop the file from being read.
    notes: Vec<String>,
    /// C3D only: analog channels and their rate.
    analog_channels: Option<usize>,
    analog_rate_hz: Option<f64>,
}

fn format_of(path: &Path) -> Result<&'static str> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .as_deref()
    {
        Some("trc") => Ok("TRC"),
        Some("c3d") => Ok("C3D"),
        _ => bail!(
            "{}: unknown motion file type (expected .trc or .c3d)",
            path.display()
        ),
    }
}

fn markers_of(trial: &Trial) -> Vec<MarkerSummary> {
    (0..trial.labels().len())
        .map(|m| {
            let (missing, longest) = trial.gap_stats(m);
            MarkerSummary {
                label: trial.labels()[m].clone(),
                missing_percent: 100.0 * missing,
                longest_gap_frames: longest,
            }
        })
        .collect()
}

pub fn inspect(args: InspectArgs) -> Result<()> {
    let path = &args.file;
    let format = format_of(path)?;
    let (units, notes, analog_channels, analog_rate_hz) = if format == "TRC" {
        let f = jointfit_io::trc::read_trc_file(path)?;
        let notes = f.notes.iter().map(|n| n.to_string()).collect();
        (f.header.units.as_str().to_string(), notes, None, None)
    } else {
        let c = jointfit_io::c3d::read_c3d(path)?;
        let analog = (c.analog.n_channels() > 0).then(|| c.analog_rate());
        (
            c.point_units().to_string(),
            c.warnings.clone(),
            Some(c.analog.n_channels()),
            analog,
        )
    };
    let trial = jointfit_io::trial_file::read_trial(path)?;
    crate::validate::check_trial(path, &trial)?;
    let summary = Summary {
        file: path.display().to_string(),
        format,
        units,
        rate_hz: trial.rate(),
        frames: trial.n_frames(),
        first_frame: trial.first_frame(),
        duration_s: trial.n_frames() as f64 / trial.rate(),
        markers: markers_of(&trial),
        notes,
        analog_channels,
        analog_rate_hz,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
        return Ok(());
    }
    println!("{} ({})", summary.file, summary.format);
    println!(
        "{} frames from frame {} at {} Hz ({:.3} s), units {}, {} markers",
        summary.frames,
        summary.first_frame,
        summary.rate_hz,
        summary.duration_s,
        if summary.units.trim().is_empty() {
            // A C3D without POINT:UNITS is read as millimetres (and a note says so).
            "mm (assumed: none declared)"
        } else {
            summary.units.as_str()
        },
        summary.markers.len()
    );
    if let Some(n) = summary.analog_channels {
        match summary.analog_rate_hz {
            Some(rate) => println!("{n} analog channels at {rate} Hz"),
            None => println!("no analog channels"),
        }
    }
    for note in &summary.notes {
        println!("note: {note}");
    }
    let mut table = Table::new(&["marker", "missing %", "longest gap (frames)"]);
    for m in &summary.markers {
        table.row(vec![
            m.label.clone(),
            format!("{:.1}", m.missing_percent),
            m.longest_gap_frames.to_string(),
        ]);
    }
    print!("{}", table.render());
    Ok(())
}

pub fn convert(args: ConvertArgs) -> Result<()> {
    crate::output::Files::new()
        .input("input", &args.input)
        .output("output", &args.output)
        .check()?;
    format_of(&args.input)?;
    let (up, detected) = crate::common::up_or_detected(&args.input, args.up)?;
    let mut trial = load_trial(&args.input, up, args.filter)?;
    if !args.markers.is_empty() {
        let names: Vec<&str> = args.markers.iter().map(String::as_str).collect();
        trial = trial
            .select(&names)
            .with_context(|| format!("{}: --markers", args.input.display()))?;
    }
    let options = TrcWriteOptions {
        units: match args.units {
            UnitsArg::Mm => TrcUnits::Millimetres,
            UnitsArg::Cm => TrcUnits::Centimetres,
            UnitsArg::M => TrcUnits::Metres,
        },
        decimals: args.decimals,
    };
    write_trc(&args.output, &trial, &options)?;
    println!(
        "wrote {} ({} markers, {} frames at {} Hz{}{})",
        args.output.display(),
        trial.labels().len(),
        trial.n_frames(),
        trial.rate(),
        args.filter
            .map_or(String::new(), |hz| format!(", low-pass {hz} Hz")),
        detected.map_or(String::new(), |d| format!("; up axis detected: {d}"))
    );
    let up = jointfit::spatial::UpAxis::from(up);
    if up != jointfit::spatial::UpAxis::Y {
        // A subject personalized from the lab's files records `lab_up` = this axis, which
        // later commands apply to every trial: this file is no longer in that frame.
        println!(
            "rotated from {up} up to Y up (OpenSim's convention): a subject personalized from \
             the lab's original files has lab_up {up}, so read this file with --up y"
        );
    }
    Ok(())
}
