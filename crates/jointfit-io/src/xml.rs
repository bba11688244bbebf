//! Escaping of text for XML and HTML: one escaper for the OpenSim model writer
//! ([`crate::osim`]) and the HTML/SVG report (`jointfit-report`).
//!
//! The five markup characters become entity references (`'` as the numeric `&#39;`, which
//! HTML 4, HTML 5 and XML all read); control characters other than tab and newline, which
//! XML 1.0 forbids in documents (W3C XML 1.0, §2.2 "Characters"), become U+FFFD.

/// Escapes text for element content and for single- or double-quoted attribute values.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c if c.is_control() && c != '\n' && c != '\t' => out.push('\u{fffd}'),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup_quotes_and_control_characters() {
        assert_eq!(
            escape(r#"<a href="x">R&L's</a>"#),
            "&lt;a href=&quot;x&quot;&gt;R&amp;L&#39;s&lt;/a&gt;"
        );
        assert_eq!(escape("a<b&\"c'>"), "a&lt;b&amp;&quot;c&#39;&gt;");
        assert_eq!(escape("a\u{1}b\tc\nd"), "a\u{fffd}b\tc\nd");
    }
}
