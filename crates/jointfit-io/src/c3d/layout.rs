//! Where the samples are: data start, point count, analog words per frame, frame count.
//!
//! Real files contradict themselves; the rules (also in the [`super`] module docs) are:
//! - Data start: header word 9, unless it points outside the file or at the parameter
//!   section, then POINT:DATA_START.
//! - Analog words per frame: header word 3, unless ANALOG:USED × samples per frame (header
//!   word 10, else ANALOG:RATE / POINT:RATE) differs and fits the declared frames into the
//!   data section more exactly (sample MotionMonitorC3D: header 16, ANALOG:USED 16 × 7 = 112,
//!   and 112 fills the data section to the byte).
//! - Point count: POINT:USED, unless only the header's count fits the declared frames into
//!   the data section (sample kyowadengyo: POINT:USED 12, header 11; with 12 the later frames'
//!   coordinates are analog words).
//! - Frame count: see [`super`]; a data section that stops mid-frame is
//!   [`C3dError::Truncated`]. A header whose last frame is 65535 (its 16-bit word saturated)
//!   with no parameter declaring more, over a data section that holds more frames, is read to
//!   the end of the data: the count comes from the data size, less the zero padding of the
//!   last 512-byte block, with a warning naming both counts.
//!
//! Every size here is checked against the byte length before anything is allocated.

use super::data::Layout;
use super::header::{Header, BLOCK};
use super::parameters::{ParamData, Parameter, Parameters};
use super::{C3dError, Processor};

/// Layout plus the frame numbering.
pub(crate) struct Resolved {
    pub layout: Layout,
    pub first_frame: i64,
}

/// Inputs that do not depend on the data layout.
pub(crate) struct Known<'a> {
    /// The whole file.
    pub bytes: &'a [u8],
    pub len: usize,
    pub header: &'a Header,
    pub params: &'a Parameters,
    pub processor: Processor,
    pub section_start: usize,
    pub declared_blocks: u8,
    pub float: bool,
    pub scale: f32,
    pub metres_per_unit: f64,
}

/// Decides the data layout, pushing a warning for every contradiction resolved.
pub(crate) fn resolve(k: &Known<'_>, warnings: &mut Vec<String>) -> Result<Resolved, C3dError> {
    let data_offset = data_offset(k, warnings)?;
    let sizes = Sizes {
        data_bytes: k.len.saturating_sub(data_offset),
        word_bytes: if k.float { 4 } else { 2 },
        declared_frames: k.header.frame_count(),
    };
    let analog = analog_words(k, &sizes, warnings);
    let n_points = point_count(k, &sizes, analog.values, warnings);
    if !k.float && n_points > 0 && !(k.scale.is_finite() && k.scale > 0.0) {
        return Err(C3dError::BadScale(k.scale));
    }
    let mut layout = Layout {
        processor: k.processor,
        float: k.float,
        scale: f64::from(k.scale.abs()),
        metres_per_unit: k.metres_per_unit,
        n_points,
        analog_values: analog.values,
        n_channels: analog.channels,
        data_offset,
        n_frames: 0,
    };
    let first_frame = first_frame(k);
    layout.n_frames = frame_count(k, bytes_of(k, &layout), first_frame, warnings)?;
    Ok(Resolved {
        layout,
        first_frame,
    })
}

/// Byte counts every later stage compares against.
struct Sizes {
    /// Bytes from the data start to the end of the file.
    data_bytes: usize,
    /// 2 (integer storage) or 4 (float storage).
    word_bytes: usize,
    /// The header's `last − first + 1`.
    declared_frames: usize,
}

impl Sizes {
    /// Bytes left over when the declared frames of `words` words fill the data section;
    /// `None` when they do not fit.
    fn slack(&self, words: usize) -> Option<usize> {
        words
            .checked_mul(self.word_bytes * self.declared_frames)
            .and_then(|b| self.data_bytes.checked_sub(b))
    }
}

/// Where the data section starts: header word 9, else POINT:DATA_START.
fn data_offset(k: &Known<'_>, warnings: &mut Vec<String>) -> Result<usize, C3dError> {
    let (len, header, section_start) = (k.len, k.header, k.section_start);
    let section_end = section_start + BLOCK * usize::from(k.declared_blocks.max(1));
    let header_start = usize::from(header.data_block).saturating_sub(1) * BLOCK;
    let param_start = k
        .params
        .get("POINT", "DATA_START")
        .and_then(Parameter::u16)
        .map(|b| usize::from(b).saturating_sub(1) * BLOCK);
    let usable = |s: usize| s >= BLOCK && s < len.max(BLOCK + 1) && s != section_start;
    let data_offset = if usable(header_start) {
        if let Some(p) = param_start.filter(|&p| p != header_start) {
            warnings.push(format!(
                "POINT:DATA_START (byte {p}) differs from the header (byte {header_start}); \
                 used the header"
            ));
        }
        header_start
    } else if let Some(p) = param_start.filter(|&p| usable(p)) {
        warnings.push(format!(
            "header data block {} is unusable; used POINT:DATA_START",
            header.data_block
        ));
        p
    } else {
        return Err(C3dError::DataStart {
            block: usize::from(header.data_block),
            len,
        });
    };
    if data_offset < section_end && data_offset > section_start {
        warnings.push("the data section starts inside the declared parameter blocks".into());
    }
    Ok(data_offset)
}

/// Analog words per frame and the channels they hold.
struct AnalogWords {
    values: usize,
    channels: usize,
}

/// Samples of each analog channel per 3D frame: header word 10, else ANALOG:RATE / POINT:RATE
/// when that is a whole number (0 when neither says).
fn analog_samples_per_frame(k: &Known<'_>) -> usize {
    let get = |g: &str, p: &str| k.params.get(g, p);
    let point_rate = get("POINT", "RATE")
        .and_then(Parameter::f64)
        .unwrap_or(f64::from(k.header.frame_rate));
    match usize::from(k.header.analog_samples_per_frame) {
        0 => get("ANALOG", "RATE")
            .and_then(Parameter::f64)
            .map(|r| r / point_rate)
            .filter(|s| s.is_finite() && *s >= 1.0 && s.fract() == 0.0 && *s <= 65535.0)
            .map_or(0, |s| s as usize),
        s => s,
    }
}

/// Analog words per frame: header word 3, unless ANALOG:USED × samples per frame fits the data
/// section more exactly; channels: ANALOG:USED when it divides the words.
fn analog_words(k: &Known<'_>, sizes: &Sizes, warnings: &mut Vec<String>) -> AnalogWords {
    let get = |g: &str, p: &str| k.params.get(g, p);
    let points_guess = get("POINT", "USED")
        .and_then(Parameter::u16)
        .map_or(usize::from(k.header.point_count), usize::from);
    let header_values = usize::from(k.header.analog_values_per_frame);
    let used_channels = get("ANALOG", "USED")
        .and_then(Parameter::u16)
        .map(usize::from);
    let samples_per_frame = analog_samples_per_frame(k);
    let values =
        match used_channels.map(|c| c * samples_per_frame) {
            Some(p) if p != header_values => {
                let fit = |v: usize| sizes.slack(4 * points_guess + v);
                let better = match (fit(p), fit(header_values)) {
                    (Some(a), Some(b)) => a < b,
                    (Some(_), None) => true,
                    _ => false,
                };
                let chosen = if better { p } else { header_values };
                warnings.push(format!(
                "the header says {header_values} analog words per frame, ANALOG:USED × samples \
                 per frame {p}; used {chosen}, which fits the data section {}",
                if better { "more exactly" } else { "at least as well" }
            ));
                chosen
            }
            _ => header_values,
        };
    let channels = match used_channels {
        _ if values == 0 => 0,
        Some(c) if c > 0 && values % c == 0 => c,
        c => {
            let derived = values / samples_per_frame.max(1);
            warnings.push(format!(
                "ANALOG:USED ({c:?}) does not divide the {values} analog words per frame; read \
                 {derived} channels"
            ));
            derived
        }
    };
    AnalogWords { values, channels }
}

/// Point count: POINT:USED, unless only the header's count fits the declared frames.
fn point_count(
    k: &Known<'_>,
    sizes: &Sizes,
    analog_values: usize,
    warnings: &mut Vec<String>,
) -> usize {
    let header_points = usize::from(k.header.point_count);
    let used_points = k
        .params
        .get("POINT", "USED")
        .and_then(Parameter::u16)
        .map(usize::from);
    let fits_declared = |n: usize| sizes.slack(4 * n + analog_values).is_some();
    match used_points {
        Some(n) if n != header_points => {
            if !fits_declared(n) && fits_declared(header_points) {
                warnings.push(format!(
                    "POINT:USED is {n} but the header says {header_points} points, and only \
                     {header_points} fit the declared frames into the data section; used \
                     {header_points}"
                ));
                header_points
            } else {
                warnings.push(format!(
                    "POINT:USED is {n} but the header says {header_points} points; used POINT:USED"
                ));
                n
            }
        }
        Some(n) => n,
        None => header_points,
    }
}

/// TRIAL:ACTUAL_START_FIELD (two 16-bit words, low first), else header word 4.
fn first_frame(k: &Known<'_>) -> i64 {
    match k
        .params
        .get("TRIAL", "ACTUAL_START_FIELD")
        .and_then(Parameter::u16s)
    {
        Some(w) if w.len() >= 2 => i64::from(w[0]) + (i64::from(w[1]) << 16),
        _ => i64::from(k.header.first_frame),
    }
}

/// Frame counts the parameters declare, with the parameter's name: TRIAL:ACTUAL_END_FIELD,
/// POINT:LONG_FRAMES, POINT:FRAMES.
fn declared_by_parameters(k: &Known<'_>, first_frame: i64) -> Vec<(String, usize)> {
    let get = |g: &str, p: &str| k.params.get(g, p);
    let mut candidates: Vec<(String, usize)> = Vec::new();
    if let Some(w) = get("TRIAL", "ACTUAL_END_FIELD").and_then(Parameter::u16s) {
        if w.len() >= 2 {
            let end = i64::from(w[0]) + (i64::from(w[1]) << 16);
            let n = end - first_frame + 1;
            if n > 0 {
                candidates.push(("TRIAL:ACTUAL_END_FIELD".into(), n as usize));
            }
        }
    }
    for name in ["LONG_FRAMES", "FRAMES"] {
        if let Some(v) = get("POINT", name) {
            let n = match &v.data {
                ParamData::Int(w) => w.first().map(|&x| f64::from(x as u16)),
                _ => v.f64(),
            };
            if let Some(n) = n.filter(|n| n.is_finite() && *n > 0.0 && n.fract() == 0.0) {
                candidates.push((format!("POINT:{name}"), n as usize));
            }
        }
    }
    candidates
}

/// The data section as frames: where it starts, how long a frame is, how many fit.
struct FrameBytes<'a> {
    bytes: &'a [u8],
    data_offset: usize,
    frame_bytes: usize,
    /// Complete frames in the data section.
    available: usize,
}

fn bytes_of<'a>(k: &Known<'a>, layout: &Layout) -> FrameBytes<'a> {
    let frame_bytes = layout.frame_bytes();
    FrameBytes {
        bytes: k.bytes,
        data_offset: layout.data_offset,
        frame_bytes,
        available: k
            .len
            .saturating_sub(layout.data_offset)
            .checked_div(frame_bytes)
            .unwrap_or(usize::MAX),
    }
}

impl FrameBytes<'_> {
    /// The complete frames of the data section, less trailing frames that lie wholly in the
    /// zero padding of the file's last 512-byte block.
    fn stored(&self) -> usize {
        let padding_from = self.bytes.len().saturating_sub(BLOCK);
        let mut n = self.available;
        while n > 0 {
            let start = self.data_offset + (n - 1) * self.frame_bytes;
            let frame = &self.bytes[start..start + self.frame_bytes];
            if start < padding_from || frame.iter().any(|&b| b != 0) {
                break;
            }
            n -= 1;
        }
        n
    }
}

/// The number of frames to read (see [`super`] for the rules).
fn frame_count(
    k: &Known<'_>,
    data: FrameBytes<'_>,
    first_frame: i64,
    warnings: &mut Vec<String>,
) -> Result<usize, C3dError> {
    let declared_header = k.header.frame_count();
    let candidates = declared_by_parameters(k, first_frame);
    if data.frame_bytes == 0 {
        // No points and no analog words: nothing to read, and no byte count to check a
        // parameter's frame count against; keep the header's (at most 65536).
        return Ok(declared_header);
    }
    let available = data.available;
    let fits = |n: usize| n <= available;
    if fits(declared_header) {
        // Header fits; a parameter may declare more (16-bit header overflow).
        if let Some((name, n)) = candidates
            .iter()
            .filter(|(_, n)| *n > declared_header && fits(*n))
            .max_by_key(|(_, n)| *n)
        {
            warnings.push(format!(
                "the header declares {declared_header} frames, {name} {n}; read {n}"
            ));
            return Ok(*n);
        }
        return Ok(saturated_header_count(k, &data, declared_header, warnings));
    }
    // The header declares more frames than the data section holds: believe a parameter
    // that fits; else, if the data end cleanly (at a frame boundary or a whole number of
    // blocks), read the frames that are there, else the file is truncated.
    let len = k.len;
    let clean_end = len.is_multiple_of(BLOCK)
        || len
            .saturating_sub(data.data_offset)
            .checked_rem(data.frame_bytes)
            == Some(0);
    match candidates
        .iter()
        .filter(|(_, n)| fits(*n))
        .max_by_key(|(_, n)| *n)
    {
        Some((name, n)) => {
            warnings.push(format!(
                "the header declares {declared_header} frames but the data section holds \
                 {available}; read {n} from {name}"
            ));
            Ok(*n)
        }
        None if clean_end => {
            warnings.push(format!(
                "the file declares {declared_header} frames but its data section ends \
                 cleanly after {available}; read {available}"
            ));
            Ok(available)
        }
        None => Err(C3dError::Truncated {
            declared: declared_header,
            available,
            frame_bytes: data.frame_bytes,
        }),
    }
}

/// A header whose last frame is 65535 cannot declare more; when no parameter declares more
/// either but the data section stores more frames, they are all read (as the data size
/// says), never cut at the header's count.
fn saturated_header_count(
    k: &Known<'_>,
    data: &FrameBytes<'_>,
    declared_header: usize,
    warnings: &mut Vec<String>,
) -> usize {
    if k.header.last_frame != u16::MAX {
        return declared_header;
    }
    let stored = data.stored();
    if stored <= declared_header {
        return declared_header;
    }
    warnings.push(format!(
        "the header's last frame is 65535 (the largest it can hold) and no parameter declares \
         more frames (TRIAL:ACTUAL_END_FIELD, POINT:LONG_FRAMES), but the data section stores \
         {stored}; read {stored}, counted from the data size"
    ));
    stored
}
