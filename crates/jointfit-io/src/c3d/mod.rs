//! C3D motion-capture files: 3D marker trajectories, analog channels and their parameters.
//!
//! A C3D file is a sequence of 512-byte blocks: a header (block 1, see [`header`]), a
//! parameter section (see [`parameters`]) and a data section (see the `data` module),
//! in one of three number formats (see [`floats`]). The reference is the C3D user guide
//! (C3D.ORG, "The C3D File Format User Guide", Motion Lab Systems, 2008).
//!
//! [`parse_c3d`] returns a [`C3d`]: the header fields, every parameter (queryable by group and
//! name), the 3D points in metres with missing samples as NaN, and the scaled analog channels.
//! [`C3d::to_trial`] gives the [`Trial`] the solvers consume.
//!
//! # Which field wins when the file contradicts itself
//!
//! - Storage (integer or float) and the residual scale: POINT:SCALE, else header words 7–8.
//!   When the two scales differ in an integer file the reader refuses it
//!   ([`C3dError::ScaleMismatch`]): the scale multiplies every coordinate and the file does not
//!   say which is right. (In float files it only scales residuals: POINT:SCALE is used, with a
//!   warning only when the two disagree on the storage, i.e. on the sign.)
//! - Point count: POINT:USED, else header word 2; but when they differ and only the header's
//!   count fits the declared frames into the data section, the header's (sample kyowadengyo).
//! - Analog words per frame: header word 3, unless ANALOG:USED × samples per frame differs and
//!   fills the data section more exactly (sample MotionMonitorC3D). Channels: ANALOG:USED.
//! - Frame count: the header's `last − first + 1`, unless a parameter declares more frames and
//!   the data section holds them (header word 5 saturates at 65535), or the header declares
//!   more frames than the data section holds and a parameter declares a count that fits (the
//!   largest such is used). Parameters: TRIAL:ACTUAL_END_FIELD (two 16-bit words, low first,
//!   giving a 32-bit last frame), POINT:LONG_FRAMES, POINT:FRAMES. First frame:
//!   TRIAL:ACTUAL_START_FIELD, else header word 4. A header whose last frame is 65535 (the
//!   largest word 5 holds) with no parameter declaring more is read to the end of the data
//!   section: the count comes from the data size, less the zero padding of the last block
//!   (as the bytes say; ezc3d 1.5 and `c3d` stop at 65,535 frames there).
//! - Frame rate: POINT:RATE, else header words 11–12; when both are there and differ,
//!   POINT:RATE (what editing software updates), with a warning naming both.
//! - Repeated point labels are kept as stored in [`Points`]; a warning names each.
//! - Data start: header word 9, unless it points outside the file or at the parameter
//!   section, then POINT:DATA_START.
//! - Units: POINT:UNITS `mm`, `cm` or `m` (case-insensitive; long names accepted); a missing or
//!   blank value is read as millimetres (the usual default) with a warning; any other value is
//!   an error ([`C3dError::UnknownUnits`]), since guessing would scale the data wrongly.
//!
//! Every such choice that departs from the plain reading is listed in [`C3d::warnings`].
//! A data section shorter than the frames declared is read up to its last complete frame, with
//! a warning, only when it ends cleanly (at a frame boundary or on a 512-byte block boundary):
//! some writers declare more frames than they store (sample Optotrak: 1149 declared, 29 stored,
//! which ezc3d and `c3d` read the same way). A data section that stops in the middle of a
//! frame and of a block is an error ([`C3dError::Truncated`]).
//!
//! # Missing samples
//!
//! A sample is missing (NaN) when its residual word is negative, when a coordinate is not
//! finite, or when it is exactly (0, 0, 0). See the `data` module for the residual word.

mod data;
pub mod floats;
pub mod header;
mod layout;
pub mod parameters;
pub mod point_types;
pub mod processing;
#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};

use jointfit::trial::{Trial, TrialError};
use nalgebra::Vector3;
use thiserror::Error;

pub use floats::Processor;
pub use header::Header;
pub use parameters::{Group, ParamData, Parameter, Parameters};

use data::AnalogScaling;
use header::BLOCK;

/// Why a C3D file could not be read.
#[derive(Debug, Error)]
pub enum C3dError {
    /// The file could not be read from disk.
    #[error("cannot read {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Any other error, with the file it happened in.
    #[error("{path}: {source}")]
    InFile {
        path: PathBuf,
        #[source]
        source: Box<C3dError>,
    },
    /// Fewer bytes than the 512-byte header.
    #[error("{len} bytes is too short for a C3D file (the header alone is 512 bytes)")]
    TooShort { len: usize },
    /// Header byte 1 points the parameter section outside the file (or is 0).
    #[error("the header puts the parameter section at block {block}, outside the {len}-byte file")]
    ParameterBlock { block: u8, len: usize },
    /// The processor byte of the parameter section is not 84, 85 or 86.
    #[error("unknown processor type {0} (expected 84 Intel, 85 DEC or 86 SGI/MIPS)")]
    UnknownProcessor(u8),
    /// The point scale factor cannot be used (integer data need a finite, non-zero scale).
    #[error("POINT:SCALE {0} is zero or not finite")]
    BadScale(f32),
    /// Integer 3D data whose header scale (words 7–8) and POINT:SCALE disagree: the two give
    /// coordinates differing by their ratio and the file does not say which is right.
    #[error(
        "integer 3D data with two different scale factors: header {header}, POINT:SCALE \
         {parameter}"
    )]
    ScaleMismatch { header: f32, parameter: f32 },
    /// POINT:UNITS holds something that is not a known length unit.
    #[error("POINT:UNITS is {0:?}, not a length unit this reader knows (mm, cm, m)")]
    UnknownUnits(String),
    /// Neither the header nor POINT:DATA_START give a data section inside the file.
    #[error("the data section start (block {block}) lies outside the {len}-byte file")]
    DataStart { block: usize, len: usize },
    /// The data section is shorter than the frames the file declares.
    #[error(
        "the file declares {declared} frames of {frame_bytes} bytes but its data section holds \
         only {available} complete frames"
    )]
    Truncated {
        declared: usize,
        available: usize,
        frame_bytes: usize,
    },
    /// The point data cannot form a [`Trial`] (e.g. a point rate of 0).
    #[error("cannot build a trial: {0}")]
    Trial(#[from] TrialError),
}

/// 3D point trajectories, ready for a [`Trial`].
#[derive(Debug, Clone, PartialEq)]
pub struct Points {
    /// Labels from POINT:LABELS, LABELS2, … trimmed, one per point (empty where the file has
    /// fewer labels than points; duplicates kept as stored).
    pub labels: Vec<String>,
    /// Descriptions from POINT:DESCRIPTIONS, DESCRIPTIONS2, … (may be shorter than `labels`).
    pub descriptions: Vec<String>,
    /// Frame rate in Hz (POINT:RATE, else the header); 0 in analog-only files.
    pub rate: f64,
    /// Number of the first frame as the file counts it.
    pub first_frame: i64,
    /// Number of frames.
    pub n_frames: usize,
    /// Positions, frame-major `[frame · n_points + point]`, metres, lab frame; NaN where missing.
    pub positions: Vec<Vector3<f64>>,
    /// Residuals, same layout, metres; NaN where missing; 0 marks interpolated/filtered samples.
    pub residuals: Vec<f64>,
    /// Camera masks (bit k: camera k+1 saw the point), same layout; 0 where missing.
    pub camera_masks: Vec<u8>,
}

impl Points {
    /// Number of points per frame.
    pub fn n_points(&self) -> usize {
        self.labels.len()
    }
}

/// Analog channels.
#[derive(Debug, Clone, PartialEq)]
pub struct Analog {
    /// Labels from ANALOG:LABELS, LABELS2, … (empty where missing).
    pub labels: Vec<String>,
    /// Units from ANALOG:UNITS, … (may be shorter than `labels`).
    pub units: Vec<String>,
    /// Sampling rate in Hz.
    pub rate: f64,
    /// Samples of each channel per 3D frame.
    pub samples_per_frame: usize,
    /// Values, sample-major `[sample · n_channels + channel]`, in ANALOG:UNITS after
    /// (value − OFFSET) × SCALE × GEN_SCALE.
    pub samples: Vec<f64>,
}

impl Analog {
    /// Number of channels.
    pub fn n_channels(&self) -> usize {
        self.labels.len()
    }
    /// Number of samples per channel.
    pub fn n_samples(&self) -> usize {
        self.samples
            .len()
            .checked_div(self.labels.len())
            .unwrap_or(0)
    }
}

/// A decoded C3D file.
#[derive(Debug, Clone, PartialEq)]
pub struct C3d {
    /// Number format of the file.
    pub processor: Processor,
    /// The header as stored.
    pub header: Header,
    /// Whether 3D and analog samples are stored as floats (POINT:SCALE < 0).
    pub float_storage: bool,
    /// POINT:UNITS as stored (trimmed), `""` when absent.
    pub units: String,
    /// Every group and parameter.
    pub parameters: Parameters,
    /// 3D points.
    pub points: Points,
    /// Analog channels.
    pub analog: Analog,
    /// Where the file departs from the standard and what the reader did about it.
    pub warnings: Vec<String>,
}

impl C3d {
    /// First frame number.
    pub fn first_frame(&self) -> i64 {
        self.points.first_frame
    }
    /// Last frame number (`first_frame + n_frames − 1`).
    pub fn last_frame(&self) -> i64 {
        self.points.first_frame + self.points.n_frames as i64 - 1
    }
    /// 3D frame rate in Hz.
    pub fn point_rate(&self) -> f64 {
        self.points.rate
    }
    /// Analog sampling rate in Hz.
    pub fn analog_rate(&self) -> f64 {
        self.analog.rate
    }
    /// POINT:UNITS as stored (positions in [`Points`] are always metres).
    pub fn point_units(&self) -> &str {
        &self.units
    }
    /// Point descriptions (POINT:DESCRIPTIONS…).
    pub fn descriptions(&self) -> &[String] {
        &self.points.descriptions
    }

    /// The markers as a [`Trial`]: every point except the computed outputs (angles, forces,
    /// moments, powers; [`point_types`]). Labels are made unique and non-empty: an empty label
    /// becomes `POINT<k>` (1-based), a repeated one gets `_2`, `_3`, … appended (the reader's
    /// warnings name every repeated label).
    ///
    /// # Errors
    /// [`C3dError::Trial`] when the point rate is not positive (analog-only files).
    pub fn to_trial(&self) -> Result<Trial, C3dError> {
        let outputs = point_types::output_points(&self.parameters, &self.points.labels);
        let n = self.points.n_points();
        let keep: Vec<usize> = (0..n).filter(|i| !outputs.contains(i)).collect();
        let mut seen = std::collections::HashSet::new();
        let mut labels = Vec::with_capacity(keep.len());
        for &i in &keep {
            let l = &self.points.labels[i];
            let base = if l.is_empty() {
                format!("POINT{}", i + 1)
            } else {
                l.clone()
            };
            let mut name = base.clone();
            let mut k = 2;
            while !seen.insert(name.clone()) {
                name = format!("{base}_{k}");
                k += 1;
            }
            labels.push(name);
        }
        let positions = if keep.len() == n {
            self.points.positions.clone()
        } else {
            self.points
                .positions
                .chunks(n.max(1))
                .flat_map(|frame| keep.iter().map(move |&i| frame[i]))
                .collect()
        };
        Ok(Trial::new(
            labels,
            self.points.rate,
            self.points.first_frame,
            positions,
        )?)
    }
}

/// Reads a C3D file from disk; errors name the file.
pub fn read_c3d(path: &Path) -> Result<C3d, C3dError> {
    let bytes = crate::limits::read_bytes(path, crate::limits::TRIAL_BYTES, "motion").map_err(
        |source| C3dError::Io {
            path: path.to_path_buf(),
            source,
        },
    )?;
    parse_c3d(&bytes).map_err(|e| C3dError::InFile {
        path: path.to_path_buf(),
        source: Box::new(e),
    })
}

/// Metres per unit for a POINT:UNITS value; `None` when unknown.
fn metres_per_unit(units: &str) -> Option<f64> {
    match units.to_ascii_lowercase().as_str() {
        "mm" | "millimeter" | "millimeters" | "millimetre" | "millimetres" => Some(1e-3),
        "cm" | "centimeter" | "centimeters" | "centimetre" | "centimetres" => Some(1e-2),
        "m" | "meter" | "meters" | "metre" | "metres" => Some(1.0),
        _ => None,
    }
}

/// Decodes a whole C3D file held in memory.
pub fn parse_c3d(bytes: &[u8]) -> Result<C3d, C3dError> {
    let len = bytes.len();
    let head: &[u8; BLOCK] = bytes
        .get(..BLOCK)
        .and_then(|h| h.try_into().ok())
        .ok_or(C3dError::TooShort { len })?;
    let block = head[0];
    let section_start = usize::from(block).saturating_sub(1) * BLOCK;
    if block == 0 || section_start + 4 > len {
        return Err(C3dError::ParameterBlock { block, len });
    }
    let section = parameters::parse_section(bytes, section_start).map_err(|e| match e {
        parameters::SectionError::Outside { .. } => C3dError::ParameterBlock { block, len },
        parameters::SectionError::Processor(p) => C3dError::UnknownProcessor(p),
    })?;
    let processor = section.processor;
    let header = Header::decode(head, processor);
    let params = section.parameters;
    let mut warnings = section.warnings;

    let scale = point_scale(&header, &params, &mut warnings)?;
    let float = scale < 0.0;
    let (units, metres) = point_units(&params, &mut warnings)?;
    let resolved = layout::resolve(
        &layout::Known {
            bytes,
            len,
            header: &header,
            params: &params,
            processor,
            section_start,
            declared_blocks: section.declared_blocks,
            float,
            scale,
            metres_per_unit: metres,
        },
        &mut warnings,
    )?;
    let layout = resolved.layout;
    let rate = point_rate(&header, &params, &mut warnings);
    let points = read_points(bytes, &layout, &params, resolved.first_frame, rate);
    note_labels(&params, &points.labels, &mut warnings);
    let analog = read_analog(bytes, &layout, &params, rate);
    Ok(C3d {
        processor,
        header,
        float_storage: float,
        units,
        points,
        analog,
        parameters: params,
        warnings,
    })
}

/// The point scale: POINT:SCALE, else header words 7–8 (see the module docs for when the two
/// disagree).
fn point_scale(
    header: &Header,
    params: &Parameters,
    warnings: &mut Vec<String>,
) -> Result<f32, C3dError> {
    let Some(s) = params.get("POINT", "SCALE").and_then(Parameter::f64) else {
        return Ok(header.scale);
    };
    let s = s as f32;
    if s != header.scale {
        if s > 0.0 && (header.scale - s).abs() > 1e-6 * s.abs() {
            // Integer data: the scale multiplies every coordinate, and nothing in the file
            // says which of the two is right.
            return Err(C3dError::ScaleMismatch {
                header: header.scale,
                parameter: s,
            });
        }
        // Both negative (float storage either way): the scale multiplies only the residuals,
        // which the reader uses for their sign, so nothing read changes (every Vicon Nexus
        // file has header −1, POINT:SCALE −0.01: no note).
        if !(s < 0.0 && header.scale < 0.0) {
            warnings.push(format!(
                "POINT:SCALE is {s} but the header says {}; used POINT:SCALE",
                header.scale
            ));
        }
    }
    Ok(s)
}

/// POINT:UNITS as stored and metres per unit (millimetres, with a warning, when blank).
fn point_units(params: &Parameters, warnings: &mut Vec<String>) -> Result<(String, f64), C3dError> {
    let units = params
        .get("POINT", "UNITS")
        .and_then(Parameter::string)
        .unwrap_or_default();
    if units.is_empty() {
        warnings.push("POINT:UNITS is missing or blank; read as mm".into());
        return Ok((units, 1e-3));
    }
    let metres = metres_per_unit(&units).ok_or_else(|| C3dError::UnknownUnits(units.clone()))?;
    Ok((units, metres))
}

/// The 3D frame rate: POINT:RATE, else header words 11–12. When both are there and differ,
/// POINT:RATE is used (writers that edit a file, e.g. to resample it, update the parameter;
/// the header's rate is what the capture started with) and the difference is noted.
fn point_rate(header: &Header, params: &Parameters, warnings: &mut Vec<String>) -> f64 {
    let header_rate = f64::from(header.frame_rate);
    let Some(rate) = params.get("POINT", "RATE").and_then(Parameter::f64) else {
        return header_rate;
    };
    let differ = (rate - header_rate).abs() > 1e-6 * rate.abs().max(header_rate.abs());
    if differ && header_rate.is_finite() && header_rate > 0.0 {
        warnings.push(format!(
            "the header's frame rate is {header_rate} Hz but POINT:RATE is {rate} Hz; used \
             POINT:RATE (the parameter is what editing software updates)"
        ));
    }
    rate
}

/// The 3D points of the data section, with their labels and descriptions.
fn read_points(
    bytes: &[u8],
    layout: &data::Layout,
    params: &Parameters,
    first_frame: i64,
    rate: f64,
) -> Points {
    let samples = data::decode_points(bytes, layout);
    let mut labels = params.strings_continued("POINT", "LABELS");
    labels.resize(layout.n_points, String::new());
    Points {
        labels,
        descriptions: params.strings_continued("POINT", "DESCRIPTIONS"),
        rate,
        first_frame,
        n_frames: layout.n_frames,
        positions: samples.positions,
        residuals: samples.residuals,
        camera_masks: samples.camera_masks,
    }
}

/// Notes about the point labels: fewer labels than points, computed outputs among them, and
/// labels that repeat (one line naming each repeated label and how [`C3d::to_trial`] renames
/// its repeats).
fn note_labels(params: &Parameters, labels: &[String], warnings: &mut Vec<String>) {
    let stored = params.strings_continued("POINT", "LABELS").len();
    if stored < labels.len() {
        warnings.push(format!("{stored} point labels for {} points", labels.len()));
    }
    let outputs = point_types::output_points(params, labels);
    if !outputs.is_empty() {
        warnings.push(point_types::note(&outputs, labels));
    }
    let mut counts: Vec<(&str, usize)> = Vec::new();
    for l in labels.iter().filter(|l| !l.is_empty()) {
        match counts.iter_mut().find(|(name, _)| name == l) {
            Some((_, n)) => *n += 1,
            None => counts.push((l, 1)),
        }
    }
    let repeated: Vec<String> = counts
        .iter()
        .filter(|(_, n)| *n > 1)
        .map(|(name, n)| format!("{name} ×{n} (read as {name}, {name}_2, …)"))
        .collect();
    if !repeated.is_empty() {
        warnings.push(format!("repeated point labels: {}", repeated.join(", ")));
    }
}

/// The analog channels of the data section, scaled as ANALOG:OFFSET, SCALE and GEN_SCALE say.
fn read_analog(bytes: &[u8], layout: &data::Layout, params: &Parameters, rate: f64) -> Analog {
    let get = |g: &str, p: &str| params.get(g, p);
    let n_channels = layout.n_channels;
    let unsigned = get("ANALOG", "FORMAT")
        .and_then(Parameter::string)
        .is_some_and(|f| f.eq_ignore_ascii_case("UNSIGNED"));
    let per_channel = |name: &str, default: f64, as_unsigned: bool| -> Vec<f64> {
        let mut v = match get("ANALOG", name) {
            Some(p) if as_unsigned => p
                .u16s()
                .map(|w| w.into_iter().map(f64::from).collect())
                .unwrap_or_default(),
            Some(p) => p.f64s().unwrap_or_default(),
            None => Vec::new(),
        };
        v.resize(n_channels, default);
        v
    };
    let gen_scale = get("ANALOG", "GEN_SCALE")
        .and_then(Parameter::f64)
        .unwrap_or(1.0);
    let scaling = AnalogScaling {
        unsigned: unsigned && !layout.float,
        offsets: per_channel("OFFSET", 0.0, unsigned),
        scales: per_channel("SCALE", 1.0, false)
            .into_iter()
            .map(|s| s * gen_scale)
            .collect(),
    };
    let samples = data::decode_analog(bytes, layout, &scaling);
    let samples_per_frame = layout.analog_values.checked_div(n_channels).unwrap_or(0);
    let mut labels = params.strings_continued("ANALOG", "LABELS");
    labels.resize(n_channels, String::new());
    let analog_rate = get("ANALOG", "RATE")
        .and_then(Parameter::f64)
        .unwrap_or(rate * samples_per_frame as f64);
    Analog {
        labels,
        units: params.strings_continued("ANALOG", "UNITS"),
        rate: analog_rate,
        samples_per_frame,
        samples,
    }
}
