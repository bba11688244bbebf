//! Escaping of text for XML and HTML: one escaper for the OpenSim model writer
//! ([`crate::osim`]) and the HTML/SVG report (`jointfit-report`); and the text OpenSim reads
//! as an element's value ([`value_piece`]).
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

/// The one text piece of an element that OpenSim (Simbody's `Xml`) reads as its value: the
/// text that is not blank once comments and processing instructions are set aside.
/// `<location> <!-- c --> 1 2 3</location>` has the value `" 1 2 3"` (OpenSim 4.6 reads the
/// three numbers); `Ok(None)` when the element holds no such text. An element whose text a
/// comment splits into several non-blank pieces (`<x>1 2<!-- c --> 3</x>`) is not a value
/// to OpenSim ("Element <x> is not a value element"), which refuses the file:
/// `Err(pieces)`, the number of pieces.
pub fn value_piece<'a, 'i>(
    node: roxmltree::Node<'a, 'i>,
) -> Result<Option<roxmltree::Node<'a, 'i>>, usize> {
    let mut pieces = node
        .children()
        .filter(|c| c.is_text() && c.text().is_some_and(|t| !t.trim().is_empty()));
    let first = pieces.next();
    match pieces.count() {
        0 => Ok(first),
        more => Err(more + 1),
    }
}

/// The message for [`value_piece`]'s refusal.
pub fn split_value_message(tag: &str, pieces: usize) -> String {
    format!(
        "<{tag}>: comments split its text into {pieces} pieces; OpenSim reads such an element \
         as no value and refuses the file too: remove the comments from inside <{tag}>"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_piece_sets_comments_aside_and_refuses_split_text() {
        let cases: [(&str, Result<Option<&str>, usize>); 8] = [
            ("<x>1 2 3</x>", Ok(Some("1 2 3"))),
            ("<x> <!-- c --> 1 2 3</x>", Ok(Some(" 1 2 3"))),
            ("<x>1 2 3 <!-- c --> </x>", Ok(Some("1 2 3 "))),
            ("<x><?pi x?>1 2 3</x>", Ok(Some("1 2 3"))),
            ("<x>1 2<!-- c --> 3</x>", Err(2)),
            ("<x>1<!--a-->2<!--b-->3</x>", Err(3)),
            ("<x><!-- only --></x>", Ok(None)),
            ("<x/>", Ok(None)),
        ];
        for (xml, want) in cases {
            let doc = roxmltree::Document::parse(xml).unwrap();
            let got = value_piece(doc.root_element()).map(|t| t.and_then(|t| t.text()));
            assert_eq!(got, want, "{xml}");
        }
    }

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
