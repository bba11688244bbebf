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
    cell.trim().parse::<f64>().ok()
}

/// Formats a finite number so that parsing the text gives back exactly the same `f64`, in
/// plain notation where that is readable and exponent notation for very small or large
/// magnitudes.
pub(crate) fn format_shortest(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || (1e-5..1e16).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
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
