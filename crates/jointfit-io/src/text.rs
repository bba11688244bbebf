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
pub(crate) const POW10: [f64; 23] = [
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
///
/// The digits come from `zmij` (Schubfach: the shortest digit string that reads back as the
/// same `f64`, the one nearest the exact value when several are as short), laid out as Rust's
/// `{}` and `{:e}` lay out the shortest digits of their own algorithm (Grisu with Dragon4
/// fallback). The two differ only when the exact value lies halfway between two shortest
/// candidates (zmij rounds the tie to even, the standard library up): the exact value then
/// has at most 18 significant digits, which only integers and short binary fractions have
/// (`m·2^q` with `q < 0` has exactly `-q` decimals), and those are left to the standard
/// library. The same text, several times faster (`docs/io.md`; the unit test compares both
/// on millions of values).
pub(crate) fn push_shortest(out: &mut String, v: f64) {
    use std::fmt::Write;
    let plain = (1e-5..1e16).contains(&v.abs());
    if !v.is_finite() || v == 0.0 || short_exact_decimal(v) {
        // Writing to a String cannot fail.
        let _ = if plain || v == 0.0 || !v.is_finite() {
            write!(out, "{v}")
        } else {
            write!(out, "{v:e}")
        };
        return;
    }
    let mut buf = zmij::Buffer::new();
    let text = buf.format_finite(v);
    let (neg, text) = match text.strip_prefix('-') {
        Some(t) => (true, t),
        None => (false, text),
    };
    let (mantissa, exp) = match text.find(['e', 'E']) {
        Some(i) => (&text[..i], text[i + 1..].parse::<i32>().unwrap_or(0)),
        None => (text, 0),
    };
    // The digits without the point, and where the point sits: value = 0.DIGITS × 10^point.
    let mut digits = [0u8; 24];
    let mut n = 0;
    let mut point = mantissa.find('.').unwrap_or(mantissa.len()) as i32 + exp;
    for &c in mantissa.as_bytes() {
        if c == b'.' {
            continue;
        }
        if n == 0 && c == b'0' {
            point -= 1;
            continue;
        }
        digits[n] = c;
        n += 1;
    }
    while n > 1 && digits[n - 1] == b'0' {
        n -= 1;
    }
    // Nonzero finite values have 1 to 17 significant digits.
    let digits = std::str::from_utf8(&digits[..n]).unwrap_or("0");
    if neg {
        out.push('-');
    }
    if plain {
        let n = n as i32;
        if point <= 0 {
            out.push_str("0.");
            (0..-point).for_each(|_| out.push('0'));
            out.push_str(digits);
        } else if point >= n {
            out.push_str(digits);
            (0..point - n).for_each(|_| out.push('0'));
        } else {
            out.push_str(&digits[..point as usize]);
            out.push('.');
            out.push_str(&digits[point as usize..]);
        }
    } else {
        out.push_str(&digits[..1]);
        if n > 1 {
            out.push('.');
            out.push_str(&digits[1..]);
        }
        // Exponent notation is rare in these files; the standard formatter is fine for it.
        let _ = write!(out, "e{}", point - 1);
    }
}

/// Whether the exact decimal expansion of finite nonzero `v` may have at most 18 significant
/// digits (then a shortest-digits tie is possible). `v = m·2^q` (odd `m`) with `q < 0` has
/// exactly `-q` decimals, the last nonzero, so `L + 1 - q` significant digits where `10^L ≤
/// |v|`; `L ≥ ⌊e·log₁₀2⌋` for `|v| ≥ 2^e` (78913 / 2¹⁸ just below log₁₀2). Integers count as
/// short; subnormals (over 700 digits) do not.
fn short_exact_decimal(v: f64) -> bool {
    let bits = v.to_bits();
    let field = ((bits >> 52) & 0x7ff) as i32;
    if field == 0 {
        return false;
    }
    let m = bits & ((1 << 52) - 1) | 1 << 52;
    let q = field - 1075 + m.trailing_zeros() as i32;
    let low_l = ((field - 1023) * 78913) >> 18;
    q >= 0 || low_l + 1 - q <= 18
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

    /// The old formatting, by the standard library alone: the oracle of `push_shortest`.
    fn std_shortest(v: f64) -> String {
        let a = v.abs();
        if v == 0.0 || (1e-5..1e16).contains(&a) || !v.is_finite() {
            format!("{v}")
        } else {
            format!("{v:e}")
        }
    }

    /// Same text as the standard library's shortest formatting: random bit patterns (every
    /// magnitude), random decimals of the sizes joint angles and times have, edge cases.
    #[test]
    fn shortest_matches_the_standard_formatting() {
        let mut x: u64 = 0x2545_F491_4F6C_DD1D;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let check = |v: f64| {
            assert_eq!(
                format_shortest(v),
                std_shortest(v),
                "{:e} ({:#x})",
                v,
                v.to_bits()
            );
        };
        for _ in 0..1_000_000 {
            check(f64::from_bits(next()));
            let r = next();
            let scale = [1e-6, 1e-3, 1.0, 57.29577951308232, 1e3, 1e15][(r % 6) as usize];
            check(((r >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * scale);
            // Short decimals (times, rounded angles).
            check((r % 2_000_001) as f64 / 1000.0 - 1000.0);
        }
        for v in [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.1,
            1e-5,
            -1e-5,
            9.999_999_999_999_999e-6,
            1e16,
            9.999e15,
            1e15,
            123.456,
            5e-324,
            f64::MIN_POSITIVE,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            1e21,
            1e22,
            1e23,
            0.3,
            2.0f64.powi(53),
            100.0,
        ] {
            check(v);
        }
    }

    #[test]
    fn latin1_fallback() {
        assert_eq!(decode(b"caf\xe9"), "café");
        assert_eq!(decode("\u{feff}x".as_bytes()), "x");
    }
}
