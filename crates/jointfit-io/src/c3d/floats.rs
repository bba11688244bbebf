//! Byte order and number formats of the three C3D processor types.
//!
//! The processor type is byte 4 of the parameter section: 84 = Intel (little-endian integers,
//! IEEE-754 floats), 85 = DEC/VAX (little-endian integers, VAX F-floats), 86 = SGI/MIPS
//! (big-endian integers and IEEE-754 floats). Everything multi-byte in the file (header words,
//! parameter offsets and values, 3D and analog samples) follows that one processor type.
//!
//! VAX F-float: 32 bits stored as two little-endian 16-bit words, the first holding the sign,
//! the 8-bit exponent (excess 128) and the top 7 fraction bits, the second the low 16 fraction
//! bits. The value is `(-1)^s · 0.1f · 2^(e−128)` with a hidden leading 1 after the binary point,
//! i.e. `1.f · 2^(e−129)`: the same bit pattern as IEEE single once the two words are swapped,
//! divided by 4 (IEEE's bias is 127). An exponent field of 0 means zero (the sign bit set
//! there is VAX's "reserved operand", read as NaN).

/// The processor type recorded in the parameter section, which fixes the byte order and
/// float format of the whole file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Processor {
    /// 84: Intel, little-endian, IEEE-754 floats.
    Intel,
    /// 85: DEC (VAX, PDP-11), little-endian integers, VAX F-floats.
    Dec,
    /// 86: SGI/MIPS, big-endian, IEEE-754 floats.
    Mips,
}

impl Processor {
    /// The processor for a parameter-section code byte (84, 85 or 86).
    pub fn from_code(code: u8) -> Option<Self> {
        match code {
            84 => Some(Self::Intel),
            85 => Some(Self::Dec),
            86 => Some(Self::Mips),
            _ => None,
        }
    }

    /// The code byte stored in the file (84, 85 or 86).
    pub fn code(self) -> u8 {
        match self {
            Self::Intel => 84,
            Self::Dec => 85,
            Self::Mips => 86,
        }
    }

    /// A 16-bit unsigned word from its two file bytes.
    #[inline]
    pub(crate) fn u16(self, b: [u8; 2]) -> u16 {
        match self {
            Self::Mips => u16::from_be_bytes(b),
            _ => u16::from_le_bytes(b),
        }
    }

    /// A 16-bit signed word from its two file bytes.
    #[inline]
    pub(crate) fn i16(self, b: [u8; 2]) -> i16 {
        self.u16(b) as i16
    }

    /// A 32-bit float from its four file bytes.
    #[inline]
    pub(crate) fn f32(self, b: [u8; 4]) -> f32 {
        match self {
            Self::Intel => f32::from_le_bytes(b),
            Self::Mips => f32::from_be_bytes(b),
            Self::Dec => vax_to_f32(b),
        }
    }
}

/// Converts a VAX F-float, given as its four bytes in file order, to an IEEE-754 single.
///
/// Every VAX F value is representable in IEEE single precision (VAX's range is narrower at the
/// top and only reaches IEEE's subnormals at the bottom), so the conversion is exact.
#[inline]
pub fn vax_to_f32(b: [u8; 4]) -> f32 {
    // Swap the two 16-bit words: the result has IEEE's sign/exponent/fraction layout.
    let bits = u32::from_le_bytes([b[2], b[3], b[0], b[1]]);
    let exponent = (bits >> 23) & 0xff;
    let sign = bits & 0x8000_0000;
    if exponent == 0 {
        return if sign != 0 { f32::NAN } else { 0.0 };
    }
    if exponent > 2 {
        // Same fraction, exponent lowered by 2 (÷ 4): exact, no rounding.
        f32::from_bits(bits - (2 << 23))
    } else {
        // Result is an IEEE subnormal: compute in f64 (exact), then narrow (exact too,
        // since the value has at most 24 significant bits and lies above 2^-149).
        let fraction = f64::from((bits & 0x007f_ffff) | 0x0080_0000);
        let magnitude = fraction * 2f64.powi(exponent as i32 - 129 - 23);
        let v = magnitude as f32;
        if sign != 0 {
            -v
        } else {
            v
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Encodes an IEEE value as VAX bytes (for tests; only for normal values).
    fn to_vax(x: f32) -> [u8; 4] {
        if x == 0.0 {
            return [0; 4];
        }
        let bits = x.to_bits() + (2 << 23);
        let le = bits.to_le_bytes();
        [le[2], le[3], le[0], le[1]]
    }

    #[test]
    fn vax_known_values() {
        // 1.0 in VAX F: word0 = 0x4080, word1 = 0x0000 (bytes 80 40 00 00).
        assert_eq!(vax_to_f32([0x80, 0x40, 0, 0]), 1.0);
        assert_eq!(vax_to_f32([0x80, 0xC0, 0, 0]), -1.0);
        // 0.5: exponent 128.
        assert_eq!(vax_to_f32([0x00, 0x40, 0, 0]), 0.5);
        assert_eq!(vax_to_f32([0, 0, 0, 0]), 0.0);
        assert!(vax_to_f32([0, 0x80, 0, 0]).is_nan());
        for x in [1e-30_f32, 3.25, -123.456, 1e30, 0.083333336] {
            assert_eq!(vax_to_f32(to_vax(x)), x);
        }
    }

    #[test]
    fn vax_tiny_values_are_subnormal_and_exact() {
        // Exponent field 1: 1.f × 2^-128, fraction 0 → 2^-128.
        let b = [0x80, 0x00, 0, 0];
        assert_eq!(vax_to_f32(b), f32::from_bits(1 << 21)); // 2^-128
        let b = [0x00, 0x81, 0, 0];
        assert_eq!(vax_to_f32(b), -f32::from_bits(1 << 22)); // -2^-127
    }

    #[test]
    fn byte_orders() {
        assert_eq!(Processor::Intel.u16([1, 2]), 0x0201);
        assert_eq!(Processor::Dec.u16([1, 2]), 0x0201);
        assert_eq!(Processor::Mips.u16([1, 2]), 0x0102);
        assert_eq!(Processor::Mips.i16([0xff, 0xfe]), -2);
        assert_eq!(Processor::Mips.f32(1.5f32.to_be_bytes()), 1.5);
        assert_eq!(Processor::Intel.f32(1.5f32.to_le_bytes()), 1.5);
        assert_eq!(Processor::Dec.f32(to_vax(1.5)), 1.5);
        for c in [84, 85, 86] {
            assert_eq!(Processor::from_code(c).unwrap().code(), c);
        }
        assert_eq!(Processor::from_code(83), None);
    }
}
