//! CSV fields as RFC 4180 (section 2, rules 5–7) has them: a field holding a comma, a double
//! quote, a line break or surrounding spaces is enclosed in double quotes, and a double quote
//! inside it is doubled. Marker labels from C3D and TRC files may hold any of these.

use std::borrow::Cow;

/// `s` as one CSV field, quoted only when it must be.
pub fn field(s: &str) -> Cow<'_, str> {
    let needs = s.contains([',', '"', '\n', '\r']) || s.trim() != s;
    if needs {
        Cow::Owned(format!("\"{}\"", s.replace('"', "\"\"")))
    } else {
        Cow::Borrowed(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quotes_only_when_needed() {
        assert_eq!(field("RASI"), "RASI");
        assert_eq!(field("a,b"), "\"a,b\"");
        assert_eq!(field("say \"hi\""), "\"say \"\"hi\"\"\"");
        assert_eq!(field("two\nlines"), "\"two\nlines\"");
        assert_eq!(field(" pad"), "\" pad\"");
        assert_eq!(field(""), "");
    }
}
