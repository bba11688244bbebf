//! The 512-byte C3D header (block 1).
//!
//! Layout, in 16-bit words counted from 1 (bytes `2(k−1)..2k`), numbers in the file's processor
//! format (see [`super::floats`]):
//!
//! | word | content |
//! |---|---|
//! | 1 | byte 1: first block of the parameter section; byte 2: key 0x50 |
//! | 2 | number of 3D points per frame |
//! | 3 | analog values per 3D frame (channels × samples per frame) |
//! | 4 | first frame number (1-based) |
//! | 5 | last frame number (saturates at 65535 for long trials) |
//! | 6 | maximum interpolation gap |
//! | 7–8 | POINT scale factor (float; negative ⇒ 3D and analog samples are floats) |
//! | 9 | first block of the data section |
//! | 10 | analog samples per 3D frame |
//! | 11–12 | 3D frame rate (float, Hz) |
//!
//! The rest (label/range section pointer, events) is not needed to read the samples.
//! The header cannot be decoded before the processor type is known, which lives in the
//! parameter section; byte 1 (the parameter block) is a single byte and needs no byte order.

use super::floats::Processor;

/// Size of the header and of every C3D block, in bytes.
pub const BLOCK: usize = 512;

/// The fields of the header that matter for reading the file.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// First 512-byte block (1-based) of the parameter section.
    pub parameter_block: u8,
    /// Second byte of the file; 0x50 in a standard file (not checked).
    pub key: u8,
    /// Number of 3D points per frame (word 2).
    pub point_count: u16,
    /// Analog values per 3D frame, all channels × all samples (word 3).
    pub analog_values_per_frame: u16,
    /// First frame number (word 4, 1-based by convention).
    pub first_frame: u16,
    /// Last frame number (word 5); saturates at 65535 in long trials.
    pub last_frame: u16,
    /// Maximum interpolation gap in frames (word 6).
    pub max_gap: u16,
    /// 3D scale factor (words 7–8); negative means float storage.
    pub scale: f32,
    /// First 512-byte block (1-based) of the data section (word 9).
    pub data_block: u16,
    /// Analog samples per channel per 3D frame (word 10).
    pub analog_samples_per_frame: u16,
    /// 3D frame rate in Hz (words 11–12).
    pub frame_rate: f32,
}

impl Header {
    /// Decodes the header from the first 512 bytes (`bytes.len() >= 512` is checked by the
    /// caller) in the given processor format.
    pub(crate) fn decode(bytes: &[u8; BLOCK], processor: Processor) -> Self {
        let w = |k: usize| processor.u16([bytes[2 * (k - 1)], bytes[2 * (k - 1) + 1]]);
        let f = |k: usize| {
            let i = 2 * (k - 1);
            processor.f32([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]])
        };
        Self {
            parameter_block: bytes[0],
            key: bytes[1],
            point_count: w(2),
            analog_values_per_frame: w(3),
            first_frame: w(4),
            last_frame: w(5),
            max_gap: w(6),
            scale: f(7),
            data_block: w(9),
            analog_samples_per_frame: w(10),
            frame_rate: f(11),
        }
    }

    /// Number of frames the header declares (`last − first + 1`, 0 if last < first).
    pub fn frame_count(&self) -> usize {
        if self.last_frame >= self.first_frame {
            usize::from(self.last_frame - self.first_frame) + 1
        } else {
            0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decodes_intel_and_mips() {
        let mut b = [0u8; BLOCK];
        b[0] = 2;
        b[1] = 0x50;
        b[2..4].copy_from_slice(&26u16.to_le_bytes());
        b[6..8].copy_from_slice(&1u16.to_le_bytes());
        b[8..10].copy_from_slice(&450u16.to_le_bytes());
        b[12..16].copy_from_slice(&(-0.1f32).to_le_bytes());
        b[16..18].copy_from_slice(&11u16.to_le_bytes());
        b[20..24].copy_from_slice(&50f32.to_le_bytes());
        let h = Header::decode(&b, Processor::Intel);
        assert_eq!((h.point_count, h.first_frame, h.last_frame), (26, 1, 450));
        assert_eq!((h.scale, h.data_block, h.frame_rate), (-0.1, 11, 50.0));
        assert_eq!(h.frame_count(), 450);

        let mut m = [0u8; BLOCK];
        m[2..4].copy_from_slice(&26u16.to_be_bytes());
        m[20..24].copy_from_slice(&50f32.to_be_bytes());
        let h = Header::decode(&m, Processor::Mips);
        assert_eq!((h.point_count, h.frame_rate), (26, 50.0));
        assert_eq!(h.frame_count(), 1);
    }
}
