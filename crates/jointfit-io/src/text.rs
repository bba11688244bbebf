//! Small helpers shared by the text formats (TRC, .mot/.sto): decoding, line splitting,
//! number parsing and number formatting.

/// Decodes file bytes as UTF-8, falling back to Latin-1 (one byte, one character) so that a
/// label written by an old Windows exporter never makes a file unreadable. A leading UTF-8
/// byte-order mark is dropped.
pub(crate) fn decode(bytes: &[u8]) -> String {
    let text = match std::str::from_utf8(bytes) {
        Ok(s) => s.to_string(),
        Err(_) => bytes.iter().map(|&b| b as char).collect(),
    };
    match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    }
}

/// Splits text into lines numbered from 1, accepting LF, CRLF and bare CR line ends. A final
/// line end does not start another (empty) line.
pub(crate) fn numbered_lines(text: &str) -> Vec<(usize, &str)> {
    let sep = if text.contains('\n') { '\n' } else { '\r' };
    let mut lines: Vec<&str> = text
        .split(sep)
        .map(|l| l.strip_suffix('\r').unwrap_or(l))
        .collect();
    if text.ends_with(sep) {
        lines.pop();
    }
    if text.is_empty() {
        lines.clear();
    }
    lines
        .into_iter()
        .enumerate()
        .map(|(i, l)| (i + 1, l))
        .collect()
}

/// Parses one numeric cell (surrounding blanks allowed). Accepts decimal and exponent
/// notation and `nan`/`inf` in any letter case, with an optional sign.
pub(crate) fn parse_number(cell: &str) -> Option<f64> {
    let s = cell.trim();
    plain_decimal(s).or_else(|| s.parse::<f64>().ok())
}

/// Exact powers of ten as `f64` (every one up to 10²² is representable).
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// The fast path of decimal parsing (Clinger 1990, "How to read floating point numbers
/// accurately", PLDI): `[sign] digits [. digits]` whose digits form an integer `m < 2⁵³` with
/// at most 22 after the point is `±m / 10^k` with both operands exact, so one IEEE division
/// gives the correctly rounded value, the same bits as the standard parser. `None` for
/// anything else (exponents, longer mantissas, words), which the standard parser then reads.
fn plain_decimal(s: &str) -> Option<f64> {
    let b = s.as_bytes();
    let (neg, digits) = match b.first()? {
        b'-' => (true, &b[1..]),
        b'+' => (false, &b[1..]),
        _ => (false, b),
    };
    const LIMIT: u64 = 1 << 53;
    let mut m: u64 = 0;
    let mut any = false;
    let mut point = false;
    let mut after = 0usize;
    for &c in digits {
        match c {
            b'0'..=b'9' => {
                m = m * 10 + u64::from(c - b'0');
                if m >= LIMIT {
                    return None;
                }
                any = true;
                if point {
                    after += 1;
                }
            }
            b'.' if !point => point = true,
            _ => return None,
        }
    }
    if !any || after >= POW10.len() {
        return None;
    }
    let v = m as f64 / POW10[after];
    Some(if neg { -v } else { v })
}

/// Formats a finite number so that parsing the text gives back exactly the same `f64`, in
/// plain notation where that is readable and exponent notation for very small or large
/// magnitudes.
pub(crate) fn format_shortest(v: f64) -> String {
    let mut out = String::new();
    push_shortest(&mut out, v);
    out
}

/// [`format_shortest`] appended to `out` (no intermediate string).
pub(crate) fn push_shortest(out: &mut String, v: f64) {
    use std::fmt::Write;
    let a = v.abs();
    // Writing to a String cannot fail.
    let _ = if v == 0.0 || (1e-5..1e16).contains(&a) {
        write!(out, "{v}")
    } else {
        write!(out, "{v:e}")
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_endings() {
        assert_eq!(numbered_lines("a\r\nb\r\n"), vec![(1, "a"), (2, "b")]);
        assert_eq!(numbered_lines("a\nb"), vec![(1, "a"), (2, "b")]);
        assert_eq!(numbered_lines("a\rb\r"), vec![(1, "a"), (2, "b")]);
        assert_eq!(
            numbered_lines("a\n\nb\n"),
            vec![(1, "a"), (2, ""), (3, "b")]
        );
        assert!(numbered_lines("").is_empty());
    }

    /// The fast path gives the standard parser's bits on plain decimals of every length
    /// (seeded pseudo-random digits, signs, points), and leaves the rest to it.
    #[test]
    fn plain_decimals_match_the_standard_parser() {
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for _ in 0..200_000 {
            let r = next();
            let len = 1 + (r % 19) as usize;
            let mut t = String::new();
            match (r >> 8) % 3 {
                0 => t.push('-'),
                1 => t.push('+'),
                _ => {}
            }
            let dot = (r >> 16) as usize % (len + 2);
            for i in 0..len {
                if i == dot {
                    t.push('.');
                }
                t.push(char::from(b'0' + (next() % 10) as u8));
            }
            let expected = t.parse::<f64>().unwrap();
            assert_eq!(
                parse_number(&t).map(f64::to_bits),
                Some(expected.to_bits()),
                "{t}"
            );
        }
        for t in [
            "1e3",
            "-2.5E-2",
            "inf",
            "-nan",
            "12345678901234567890.5",
            "1.2.3",
            ".",
            "-",
        ] {
            assert_eq!(
                parse_number(t).map(|v| v.to_bits()),
                t.parse::<f64>().ok().map(|v| v.to_bits()),
                "{t}"
            );
        }
    }

    #[test]
    fn numbers() {
        assert_eq!(parse_number(" -2.73E-01 "), Some(-0.273));
        assert!(parse_number("NaN").unwrap().is_nan());
        assert!(parse_number("nAn").unwrap().is_nan());
        assert!(parse_number("  -nan").unwrap().is_nan());
        assert_eq!(parse_number("1e5"), Some(1e5));
        assert_eq!(parse_number(""), None);
        assert_eq!(parse_number("1,5"), None);
    }

    #[test]
    fn shortest_round_trips() {
        for v in [
            0.0,
            -0.0,
            0.1,
            1.0 / 3.0,
            -4.762_815_29,
            1e-300,
            123_456_789_012_345_680.0,
            f64::MIN_POSITIVE,
            f64::MAX,
            5e-324,
            1e-5,
            9.999_999e-6,
        ] {
            let s = format_shortest(v);
            let back: f64 = s.parse().unwrap();
            assert_eq!(back.to_bits(), v.to_bits(), "{v} -> {s}");
        }
        assert_eq!(format_shortest(0.5), "0.5");
        assert_eq!(format_shortest(1e-300), "1e-300");
    }

    #[test]
    fn latin1_fallback() {
        assert_eq!(decode(b"caf\xe9"), "café");
        assert_eq!(decode("\u{feff}x".as_bytes()), "x");
    }
}
