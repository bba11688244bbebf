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
//!   [`C3dError::Truncated`].
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
    let (len, header, float, scale) = (k.len, k.header, k.float, k.scale);
    let get = |g: &str, p: &str| k.params.get(g, p);
    let section_start = k.section_start;
    let word_bytes = if float { 4 } else { 2 };
    let declared_frames = header.frame_count();

    // Data start.
    let section_end = section_start + BLOCK * usize::from(k.declared_blocks.max(1));
    let header_start = usize::from(header.data_block).saturating_sub(1) * BLOCK;
    let param_start = get("POINT", "DATA_START")
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

    let data_bytes = len.saturating_sub(data_offset);
    // Bytes left over when `frames` frames of `words` words fill the data section; None when
    // they do not fit.
    let slack = |words: usize| {
        words
            .checked_mul(word_bytes * declared_frames)
            .and_then(|b| data_bytes.checked_sub(b))
    };

    // Analog words per frame.
    let header_points = usize::from(header.point_count);
    let used_points = get("POINT", "USED")
        .and_then(Parameter::u16)
        .map(usize::from);
    let points_guess = used_points.unwrap_or(header_points);
    let header_values = usize::from(header.analog_values_per_frame);
    let used_channels = get("ANALOG", "USED")
        .and_then(Parameter::u16)
        .map(usize::from);
    let point_rate = get("POINT", "RATE")
        .and_then(Parameter::f64)
        .unwrap_or(f64::from(header.frame_rate));
    let samples_per_frame = match usize::from(header.analog_samples_per_frame) {
        0 => get("ANALOG", "RATE")
            .and_then(Parameter::f64)
            .map(|r| r / point_rate)
            .filter(|s| s.is_finite() && *s >= 1.0 && s.fract() == 0.0 && *s <= 65535.0)
            .map_or(0, |s| s as usize),
        s => s,
    };
    let param_values = used_channels.map(|c| c * samples_per_frame);
    let analog_values =
        match param_values {
            Some(p) if p != header_values => {
                let fit = |v: usize| slack(4 * points_guess + v);
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
    let n_channels = match used_channels {
        _ if analog_values == 0 => 0,
        Some(c) if c > 0 && analog_values % c == 0 => c,
        c => {
            let derived = analog_values / samples_per_frame.max(1);
            warnings.push(format!(
                "ANALOG:USED ({c:?}) does not divide the {analog_values} analog words per \
                 frame; read {derived} channels"
            ));
            derived
        }
    };

    // Point count: POINT:USED, unless only the header's count fits the declared frames.
    let fits_declared = |n: usize| slack(4 * n + analog_values).is_some();
    let n_points = match used_points {
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
    };
    if !float && n_points > 0 && !(scale.is_finite() && scale > 0.0) {
        return Err(C3dError::BadScale(scale));
    }

    let mut layout = Layout {
        processor: k.processor,
        float,
        scale: f64::from(scale.abs()),
        metres_per_unit: k.metres_per_unit,
        n_points,
        analog_values,
        n_channels,
        data_offset,
        n_frames: 0,
    };
    let frame_bytes = layout.frame_bytes();
    let available = (len.saturating_sub(data_offset))
        .checked_div(frame_bytes)
        .unwrap_or(usize::MAX);

    // Frames.
    let first_frame = match get("TRIAL", "ACTUAL_START_FIELD").and_then(Parameter::u16s) {
        Some(w) if w.len() >= 2 => i64::from(w[0]) + (i64::from(w[1]) << 16),
        _ => i64::from(header.first_frame),
    };
    let declared_header = declared_frames;
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
    if frame_bytes == 0 {
        // No points and no analog words: nothing to read, and no byte count to check a
        // parameter's frame count against; keep the header's (at most 65536).
        return Ok(Resolved {
            layout: Layout {
                n_frames: declared_header,
                ..layout
            },
            first_frame,
        });
    }
    let fits = |n: usize| n <= available;
    let n_frames = if fits(declared_header) {
        // Header fits; a parameter may declare more (16-bit header overflow).
        match candidates
            .iter()
            .filter(|(_, n)| *n > declared_header && fits(*n))
            .max_by_key(|(_, n)| *n)
        {
            Some((name, n)) => {
                warnings.push(format!(
                    "the header declares {declared_header} frames, {name} {n}; read {n}"
                ));
                *n
            }
            None => declared_header,
        }
    } else {
        // The header declares more frames than the data section holds: believe a parameter
        // that fits; else, if the data end cleanly (at a frame boundary or a whole number of
        // blocks), read the frames that are there, else the file is truncated.
        let clean_end =
            len % BLOCK == 0 || len.saturating_sub(data_offset).checked_rem(frame_bytes) == Some(0);
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
                *n
            }
            None if clean_end => {
                warnings.push(format!(
                    "the file declares {declared_header} frames but its data section ends \
                     cleanly after {available}; read {available}"
                ));
                available
            }
            None => {
                return Err(C3dError::Truncated {
                    declared: declared_header,
                    available,
                    frame_bytes,
                })
            }
        }
    };
    layout.n_frames = n_frames;

    Ok(Resolved {
        layout,
        first_frame,
    })
}
