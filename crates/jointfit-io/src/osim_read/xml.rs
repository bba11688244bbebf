//! Small helpers over `roxmltree` for OpenSim documents: child lookup, numbers, positions.

use roxmltree::Node;

use super::Fail;

/// The first element child with this tag.
pub(crate) fn child<'a, 'i>(node: Node<'a, 'i>, tag: &str) -> Option<Node<'a, 'i>> {
    node.children()
        .find(|c| c.is_element() && c.tag_name().name() == tag)
}

/// Element children.
pub(crate) fn elements<'a, 'i>(node: Node<'a, 'i>) -> impl Iterator<Item = Node<'a, 'i>> {
    node.children().filter(|c| c.is_element())
}

/// The `name` attribute (empty when absent).
pub(crate) fn name<'a>(node: Node<'a, '_>) -> &'a str {
    node.attribute("name").unwrap_or("")
}

/// `Tag "name"` for error messages.
pub(crate) fn label(node: Node) -> String {
    format!("{} {:?}", node.tag_name().name(), name(node))
}

/// The text of a child element, trimmed, comments beside it set aside (`None` when the child
/// is absent; the first piece when comments split it, see [`crate::xml::value_piece`]).
pub(crate) fn text<'a>(node: Node<'a, '_>, tag: &str) -> Option<&'a str> {
    child(node, tag).map(|c| {
        let piece = match crate::xml::value_piece(c) {
            Ok(p) => p,
            Err(_) => c.children().find(|t| t.is_text()),
        };
        piece.and_then(|t| t.text()).unwrap_or("").trim()
    })
}

/// Whitespace-separated numbers of a child element.
pub(crate) fn numbers(node: Node, tag: &str) -> Result<Vec<f64>, Fail> {
    let Some(c) = child(node, tag) else {
        return Err(Fail::at(node, format!("missing <{tag}>")));
    };
    parse_numbers(c)
}

/// Whitespace-separated numbers of an element's own text, comments beside them set aside; an
/// element whose numbers a comment splits is refused, as OpenSim refuses it
/// ([`crate::xml::value_piece`]).
pub(crate) fn parse_numbers(c: Node) -> Result<Vec<f64>, Fail> {
    let tag = c.tag_name().name();
    let piece = crate::xml::value_piece(c)
        .map_err(|n| Fail::at(c, crate::xml::split_value_message(tag, n)))?;
    piece
        .and_then(|t| t.text())
        .unwrap_or("")
        .split_whitespace()
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| Fail::at(c, format!("<{tag}>: {t:?} is not a number")))
        })
        .collect()
}

pub(crate) fn number(node: Node, tag: &str) -> Result<f64, Fail> {
    let v = numbers(node, tag)?;
    match v.as_slice() {
        [x] => Ok(*x),
        _ => Err(Fail::at(
            node,
            format!("<{tag}> needs one number, has {}", v.len()),
        )),
    }
}

pub(crate) fn vec3(node: Node, tag: &str) -> Result<[f64; 3], Fail> {
    let v = numbers(node, tag)?;
    match v.as_slice() {
        [x, y, z] => Ok([*x, *y, *z]),
        _ => Err(Fail::at(
            node,
            format!("<{tag}> needs three numbers, has {}", v.len()),
        )),
    }
}

/// A boolean child (`true`/`false`, absent: `default`).
pub(crate) fn flag(node: Node, tag: &str, default: bool) -> Result<bool, Fail> {
    match text(node, tag) {
        None => Ok(default),
        Some("true") => Ok(true),
        Some("false") => Ok(false),
        Some(other) => Err(Fail::at(
            node,
            format!("<{tag}>: {other:?} is not true or false"),
        )),
    }
}

/// The last component of an OpenSim component path (`/bodyset/femur_r` → `femur_r`).
pub(crate) fn path_leaf(path: &str) -> &str {
    path.trim().rsplit('/').next().unwrap_or("").trim()
}
