//! The data section: frames of 3D points followed by analog samples.
//!
//! Frame `i` starts at `data_offset + i · frame_bytes`. It holds, for each of the `n` points,
//! four words `x, y, z, r`, then `analog_values` analog words (samples × channels, channel
//! fastest). Words are 16-bit integers when POINT:SCALE > 0 and 32-bit floats (in the file's
//! float format) when POINT:SCALE < 0.
//!
//! - Integer storage: coordinate = word × POINT:SCALE, in POINT:UNITS.
//! - Float storage: coordinate = word (already in POINT:UNITS; the scale only sizes residuals).
//! - The fourth word `r` (a float holding an integer value in float files) is the
//!   "residual/camera word": negative ⇒ the sample is invalid; otherwise its low byte times
//!   |POINT:SCALE| is the residual (0 means interpolated or filtered) and bits 8–14 are the mask
//!   of cameras that saw the point.
//!   A float residual word above 32767 cannot be a 16-bit word: the sample stays valid, its
//!   residual is NaN and its camera mask 0.
//! - In addition, this reader treats an exact (0, 0, 0) and any non-finite coordinate as
//!   missing: several writers mark gaps that way with a non-negative residual word.
//! - Analog value = (word − ANALOG:OFFSET[c]) × ANALOG:SCALE[c] × ANALOG:GEN_SCALE; integer
//!   words are unsigned when ANALOG:FORMAT is "UNSIGNED" (and the offset is then read unsigned).

use nalgebra::Vector3;

use super::floats::Processor;

/// Where the samples are and how they are stored; every size here has been checked against the
/// file length by the caller.
#[derive(Debug, Clone)]
pub(crate) struct Layout {
    pub processor: Processor,
    pub float: bool,
    /// |POINT:SCALE|.
    pub scale: f64,
    /// Metres per point unit.
    pub metres_per_unit: f64,
    pub n_points: usize,
    /// Analog words per frame (all channels, all samples).
    pub analog_values: usize,
    pub n_channels: usize,
    pub data_offset: usize,
    pub n_frames: usize,
}

impl Layout {
    pub fn word_bytes(&self) -> usize {
        if self.float {
            4
        } else {
            2
        }
    }
    pub fn frame_bytes(&self) -> usize {
        (4 * self.n_points + self.analog_values) * self.word_bytes()
    }
}

/// Marks a valid sample whose residual word cannot be decoded.
const WORD_UNKNOWN: i64 = -1;

/// Decoded 3D samples, frame-major (`[frame · n_points + point]`).
pub(crate) struct PointSamples {
    pub positions: Vec<Vector3<f64>>,
    pub residuals: Vec<f64>,
    pub camera_masks: Vec<u8>,
}

/// Decodes the 3D samples. `bytes` must hold every frame (checked by the caller).
pub(crate) fn decode_points(bytes: &[u8], l: &Layout) -> PointSamples {
    let total = l.n_frames * l.n_points;
    let mut positions = Vec::with_capacity(total);
    let mut residuals = Vec::with_capacity(total);
    let mut camera_masks = Vec::with_capacity(total);
    let frame_bytes = l.frame_bytes();
    let point_bytes = 4 * l.word_bytes();
    let nan = Vector3::repeat(f64::NAN);
    for f in 0..l.n_frames {
        let start = l.data_offset + f * frame_bytes;
        let frame = &bytes[start..start + l.n_points * point_bytes];
        for p in frame.chunks_exact(point_bytes) {
            let (xyz, word) = if l.float {
                let v = |i: usize| l.processor.f32([p[i], p[i + 1], p[i + 2], p[i + 3]]);
                let r = v(12);
                // The residual word is an integer stored as a float; NaN counts as invalid.
                // A value beyond 16 bits (a writer that stored two raw 16-bit words there,
                // e.g. sample admarche2: bytes 00 7F 00 7F ≈ 1.7e38) is valid but carries no
                // decodable residual: marked by WORD_UNKNOWN.
                let word = if r > 32767.0 {
                    Some(WORD_UNKNOWN)
                } else if r >= 0.0 {
                    Some(r as i64)
                } else {
                    None
                };
                let xyz = Vector3::new(f64::from(v(0)), f64::from(v(4)), f64::from(v(8)));
                (xyz, word)
            } else {
                let v = |i: usize| l.processor.i16([p[i], p[i + 1]]);
                let r = v(6);
                let word = if r >= 0 { Some(i64::from(r)) } else { None };
                let xyz = Vector3::new(f64::from(v(0)), f64::from(v(2)), f64::from(v(4))) * l.scale;
                (xyz, word)
            };
            let valid = word.is_some()
                && xyz.iter().all(|c| c.is_finite())
                && !(xyz.x == 0.0 && xyz.y == 0.0 && xyz.z == 0.0);
            match word {
                Some(WORD_UNKNOWN) if valid => {
                    positions.push(xyz * l.metres_per_unit);
                    residuals.push(f64::NAN);
                    camera_masks.push(0);
                }
                Some(w) if valid => {
                    positions.push(xyz * l.metres_per_unit);
                    residuals.push((w & 0xff) as f64 * l.scale * l.metres_per_unit);
                    camera_masks.push(((w >> 8) & 0x7f) as u8);
                }
                _ => {
                    positions.push(nan);
                    residuals.push(f64::NAN);
                    camera_masks.push(0);
                }
            }
        }
    }
    PointSamples {
        positions,
        residuals,
        camera_masks,
    }
}

/// Per-channel analog conversion.
pub(crate) struct AnalogScaling {
    pub unsigned: bool,
    pub offsets: Vec<f64>,
    /// SCALE[c] × GEN_SCALE.
    pub scales: Vec<f64>,
}

/// Decodes the analog samples, sample-major (`[sample · n_channels + channel]`), scaled.
/// Words beyond `n_channels · samples` in a frame (if any) are ignored.
pub(crate) fn decode_analog(bytes: &[u8], l: &Layout, s: &AnalogScaling) -> Vec<f64> {
    let nc = l.n_channels;
    if nc == 0 || l.analog_values == 0 {
        return Vec::new();
    }
    let per_frame = l.analog_values / nc;
    let mut out = Vec::with_capacity(l.n_frames * per_frame * nc);
    let wb = l.word_bytes();
    let frame_bytes = l.frame_bytes();
    for f in 0..l.n_frames {
        let start = l.data_offset + f * frame_bytes + 4 * l.n_points * wb;
        let words = &bytes[start..start + per_frame * nc * wb];
        for (i, w) in words.chunks_exact(wb).enumerate() {
            let c = i % nc;
            let raw = if l.float {
                f64::from(l.processor.f32([w[0], w[1], w[2], w[3]]))
            } else if s.unsigned {
                f64::from(l.processor.u16([w[0], w[1]]))
            } else {
                f64::from(l.processor.i16([w[0], w[1]]))
            };
            out.push((raw - s.offsets[c]) * s.scales[c]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout(float: bool, n_points: usize, n_frames: usize) -> Layout {
        Layout {
            processor: Processor::Intel,
            float,
            scale: 0.5,
            metres_per_unit: 1e-3,
            n_points,
            analog_values: 2,
            n_channels: 1,
            data_offset: 0,
            n_frames,
        }
    }

    #[test]
    fn integer_points_residuals_and_gaps() {
        let mut b = Vec::new();
        // Point 0: valid, residual byte 4, cameras 0x21.
        for w in [100i16, -200, 300, 0x2104] {
            b.extend_from_slice(&w.to_le_bytes());
        }
        // Point 1: negative residual word.
        for w in [1i16, 2, 3, -1] {
            b.extend_from_slice(&w.to_le_bytes());
        }
        // Point 2: (0, 0, 0) with a valid residual word.
        for w in [0i16, 0, 0, 5] {
            b.extend_from_slice(&w.to_le_bytes());
        }
        for w in [10i16, 20] {
            b.extend_from_slice(&w.to_le_bytes());
        }
        let l = Layout {
            n_points: 3,
            ..layout(false, 3, 1)
        };
        let s = decode_points(&b, &l);
        assert_eq!(s.positions[0], Vector3::new(0.05, -0.1, 0.15));
        assert_eq!(s.residuals[0], 4.0 * 0.5e-3);
        assert_eq!(s.camera_masks[0], 0x21);
        assert!(s.positions[1].x.is_nan() && s.residuals[1].is_nan());
        assert!(s.positions[2].x.is_nan());
        let a = decode_analog(
            &b,
            &l,
            &AnalogScaling {
                unsigned: false,
                offsets: vec![2.0],
                scales: vec![0.5],
            },
        );
        assert_eq!(a, [4.0, 9.0]);
    }

    #[test]
    fn float_points_residual_word_is_an_integer_value() {
        let mut b = Vec::new();
        for v in [
            1000.0f32, 2000.0, 3000.0, 8450.0, 1.0, 2.0, 3.0, -1.0, 4.0, 5.0, 6.0, 1.7e38,
        ] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        for v in [7.0f32, 8.0] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let l = layout(true, 3, 1);
        let s = decode_points(&b, &l);
        assert_eq!(s.positions[2], Vector3::new(4e-3, 5e-3, 6e-3));
        assert!(s.residuals[2].is_nan());
        assert_eq!(s.positions[0], Vector3::new(1.0, 2.0, 3.0));
        // 8450 = 0x2102: residual byte 2, cameras 0x21.
        assert_eq!(s.residuals[0], 2.0 * 0.5e-3);
        assert_eq!(s.camera_masks[0], 0x21);
        assert!(s.positions[1].x.is_nan());
    }
}
