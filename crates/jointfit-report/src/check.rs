//! A strict checker for the pages this crate writes: well-formed XML (the page is written as
//! polyglot HTML), a tree to query, and the offline rule (nothing that would be fetched).
//!
//! Used by this crate's tests and by the CLI's end-to-end tests; small enough to read in one
//! sitting, and independent of the writer so that it catches the writer's mistakes.

use std::collections::HashSet;

/// An element: name, attributes, children and its own text (entities decoded).
#[derive(Debug, Clone, Default)]
pub struct Element {
    pub name: String,
    pub attrs: Vec<(String, String)>,
    pub children: Vec<Element>,
    pub text: String,
}

impl Element {
    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }

    /// Every element of the subtree (this one first), depth first.
    pub fn descendants(&self) -> Vec<&Element> {
        let mut out = vec![self];
        for c in &self.children {
            out.extend(c.descendants());
        }
        out
    }

    pub fn find_all(&self, name: &str) -> Vec<&Element> {
        self.descendants()
            .into_iter()
            .filter(|e| e.name == name)
            .collect()
    }

    pub fn by_id(&self, id: &str) -> Option<&Element> {
        self.descendants()
            .into_iter()
            .find(|e| e.attr("id") == Some(id))
    }

    /// All text of the subtree: this element's own text, then its children's in order (text
    /// mixed with child elements is not interleaved).
    pub fn all_text(&self) -> String {
        let mut s = self.text.clone();
        for c in &self.children {
            s.push_str(&c.all_text());
        }
        s
    }
}

/// Parses the page: an optional `<!DOCTYPE ...>`, then exactly one root element. Errors
/// say what is wrong and at which byte offset.
pub fn parse(doc: &str) -> Result<Element, String> {
    let b = doc.as_bytes();
    let mut i = 0;
    let skip_ws = |i: &mut usize| {
        while *i < b.len() && b[*i].is_ascii_whitespace() {
            *i += 1;
        }
    };
    skip_ws(&mut i);
    if doc[i..].starts_with("<!DOCTYPE") {
        i += doc[i..].find('>').ok_or("unterminated DOCTYPE")? + 1;
    }
    let mut stack: Vec<Element> = vec![Element::default()];
    while i < b.len() {
        if doc[i..].starts_with("<!--") {
            i += doc[i..]
                .find("-->")
                .ok_or(format!("unterminated comment at {i}"))?
                + 3;
        } else if doc[i..].starts_with("</") {
            let end = i + doc[i..]
                .find('>')
                .ok_or(format!("unterminated end tag at {i}"))?;
            let name = doc[i + 2..end].trim();
            let el = stack.pop().ok_or("stack underflow")?;
            if el.name != name || stack.is_empty() {
                return Err(format!(
                    "end tag </{name}> at {i} does not close <{}>",
                    el.name
                ));
            }
            stack.last_mut().expect("parent").children.push(el);
            i = end + 1;
        } else if b[i] == b'<' {
            let (el, self_closing, next) = start_tag(doc, i)?;
            i = next;
            if self_closing {
                stack.last_mut().expect("parent").children.push(el);
            } else {
                stack.push(el);
            }
        } else {
            let end = doc[i..].find('<').map(|k| i + k).unwrap_or(b.len());
            let text = decode(&doc[i..end], i)?;
            if doc[i..end].contains('>') {
                return Err(format!("unescaped '>' in text at {i}"));
            }
            if stack.len() == 1 && !text.trim().is_empty() {
                return Err(format!("text outside the root element at {i}"));
            }
            stack.last_mut().expect("parent").text.push_str(&text);
            i = end;
        }
    }
    if stack.len() != 1 {
        return Err(format!(
            "unclosed element <{}>",
            stack.last().map(|e| e.name.as_str()).unwrap_or("")
        ));
    }
    let mut doc_node = stack.pop().expect("document");
    if doc_node.children.len() != 1 {
        return Err(format!(
            "{} root elements, expected one",
            doc_node.children.len()
        ));
    }
    Ok(doc_node.children.remove(0))
}

fn is_name_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == ':' || c == '.'
}

fn start_tag(doc: &str, at: usize) -> Result<(Element, bool, usize), String> {
    let b = doc.as_bytes();
    let mut i = at + 1;
    let start = i;
    while i < b.len() && is_name_char(b[i] as char) {
        i += 1;
    }
    if i == start {
        return Err(format!("'<' not starting a tag at {at}"));
    }
    let mut el = Element {
        name: doc[start..i].to_string(),
        ..Element::default()
    };
    let mut seen = HashSet::new();
    loop {
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        if i >= b.len() {
            return Err(format!("unterminated tag <{}> at {at}", el.name));
        }
        if doc[i..].starts_with("/>") {
            return Ok((el, true, i + 2));
        }
        if b[i] == b'>' {
            return Ok((el, false, i + 1));
        }
        let ns = i;
        while i < b.len() && is_name_char(b[i] as char) {
            i += 1;
        }
        if i == ns {
            return Err(format!("bad attribute in <{}> at {i}", el.name));
        }
        let name = doc[ns..i].to_string();
        if !doc[i..].starts_with("=\"") {
            return Err(format!(
                "attribute {name} of <{}> at {i} is not name=\"value\"",
                el.name
            ));
        }
        i += 2;
        let end = i + doc[i..]
            .find('"')
            .ok_or(format!("unterminated attribute {name} at {i}"))?;
        let raw = &doc[i..end];
        if raw.contains('<') {
            return Err(format!("'<' inside attribute {name} at {i}"));
        }
        let value = decode(raw, i)?;
        if !seen.insert(name.clone()) {
            return Err(format!(
                "duplicate attribute {name} in <{}> at {at}",
                el.name
            ));
        }
        el.attrs.push((name, value));
        i = end + 1;
    }
}

/// Decodes the five XML entities and numeric references; any other `&` is an error.
fn decode(s: &str, at: usize) -> Result<String, String> {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(k) = rest.find('&') {
        out.push_str(&rest[..k]);
        let semi = rest[k..]
            .find(';')
            .ok_or(format!("bare '&' at {}", at + k))?;
        let ent = &rest[k + 1..k + semi];
        let c = match ent {
            "amp" => '&',
            "lt" => '<',
            "gt" => '>',
            "quot" => '"',
            "apos" => '\'',
            _ if ent.starts_with("#x") => u32::from_str_radix(&ent[2..], 16)
                .ok()
                .and_then(char::from_u32)
                .ok_or(format!("bad reference &{ent}; at {}", at + k))?,
            _ if ent.starts_with('#') => ent[1..]
                .parse::<u32>()
                .ok()
                .and_then(char::from_u32)
                .ok_or(format!("bad reference &{ent}; at {}", at + k))?,
            _ => return Err(format!("unknown entity &{ent}; at {}", at + k)),
        };
        out.push(c);
        rest = &rest[k + semi + 1..];
    }
    out.push_str(rest);
    Ok(out)
}

/// Elements and attributes that would load something, and where they are. An empty list
/// means the page opens offline with nothing fetched: no scripts, no links, images,
/// frames or objects, no `src`/`href` attributes, no `url(...)` other than to an element of
/// the page (`url(#id)`), no `@import`, no `http(s)://` anywhere.
pub fn external_references(root: &Element, raw: &str) -> Vec<String> {
    let mut found = Vec::new();
    for e in root.descendants() {
        if matches!(
            e.name.as_str(),
            "script"
                | "link"
                | "img"
                | "image"
                | "iframe"
                | "object"
                | "embed"
                | "use"
                | "video"
                | "audio"
                | "source"
                | "base"
        ) {
            found.push(format!("<{}> element", e.name));
        }
        for (k, v) in &e.attrs {
            if k == "src" || k == "href" || k.ends_with(":href") || k == "srcset" {
                found.push(format!("{k}=\"{v}\" on <{}>", e.name));
            }
            if k.starts_with("on") {
                found.push(format!("event handler {k} on <{}>", e.name));
            }
        }
    }
    let lower = raw.to_ascii_lowercase();
    for pat in ["http://", "https://", "@import", "//fonts", "@font-face"] {
        if lower.contains(pat) {
            found.push(format!("{pat} in the page"));
        }
    }
    let mut rest = lower.as_str();
    while let Some(k) = rest.find("url(") {
        let after = rest[k + 4..].trim_start_matches(['"', '\'']);
        if !after.starts_with('#') {
            found.push(format!("url({}…", &after[..after.len().min(20)]));
        }
        rest = &rest[k + 4..];
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_well_formed_and_decodes() {
        let e = parse("<!DOCTYPE html>\n<a x=\"1 &amp; 2\"><b/>t &lt;&#233;&#xe9;</a>").unwrap();
        assert_eq!(e.name, "a");
        assert_eq!(e.attr("x"), Some("1 & 2"));
        assert_eq!(e.children[0].name, "b");
        assert_eq!(e.text, "t <éé");
    }

    #[test]
    fn rejects_malformed() {
        for bad in [
            "<a><b></a></b>",
            "<a>",
            "<a>x & y</a>",
            "<a x=1></a>",
            "<a x=\"1\" x=\"2\"></a>",
            "<a>1 > 0</a>",
            "<a></a><b></b>",
            "<a>&nbsp;</a>",
            "<a x=\"<\"></a>",
        ] {
            assert!(parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn finds_external_references() {
        let raw = "<html><head><style>a{background:url(x.png)}</style></head>\
                   <body><svg><g clip-path=\"url(#c1)\"/><image href=\"a.png\"/></svg></body></html>";
        let root = parse(raw).unwrap();
        let found = external_references(&root, raw);
        assert_eq!(found.len(), 3, "{found:?}");
        let ok = "<html><body><svg><g clip-path=\"url(#c1)\"/></svg></body></html>";
        assert!(external_references(&parse(ok).unwrap(), ok).is_empty());
    }
}
