//! Paths named in Rust code: `prefix::a::{b, c::d}` expanded to `a::b`, `a::c::d`.

/// The paths that follow each `prefix::` in `code` (a `prefix` preceded by an identifier
/// character is part of another name), use trees expanded, `as` renames dropped.
pub fn paths_after(code: &str, prefix: &str) -> Vec<String> {
    let needle = format!("{prefix}::");
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(at) = code[from..].find(&needle) {
        let start = from + at;
        from = start + needle.len();
        let before = code[..start].chars().next_back();
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
            continue;
        }
        let tokens = tokens(&code[from..]);
        let mut pos = 0;
        tree(&tokens, &mut pos, "", &mut out);
    }
    out
}

/// Identifiers, `*`, `{`, `}`, `,` and `::` (as `:`), up to the first other character.
fn tokens(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut chars = text.chars().peekable();
    let mut depth = 0usize;
    while let Some(&c) = chars.peek() {
        if c.is_whitespace() {
            chars.next();
        } else if c.is_alphanumeric() || c == '_' {
            let mut ident = String::new();
            while let Some(&c) = chars.peek().filter(|c| c.is_alphanumeric() || **c == '_') {
                ident.push(c);
                chars.next();
            }
            out.push(ident);
        } else if c == ':' {
            chars.next();
            if chars.next_if_eq(&':').is_none() {
                break;
            }
            out.push(":".into());
        } else if "{},*".contains(c) && (depth > 0 || c == '{' || c == '*') {
            depth = match c {
                '{' => depth + 1,
                '}' => depth - 1,
                _ => depth,
            };
            out.push(c.to_string());
            chars.next();
            if depth == 0 && c == '}' {
                break;
            }
        } else {
            break;
        }
    }
    out
}

/// The leaf paths of one use tree (`a::{b, c::d as e}` → `a::b`, `a::c::d`).
pub fn use_tree(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    tree(&tokens(text), &mut 0, "", &mut out);
    out
}

/// One use tree at `tokens[*pos..]` under `base`: `seg::seg::{tree, …}`, `seg as name`, `*`.
fn tree(tokens: &[String], pos: &mut usize, base: &str, out: &mut Vec<String>) {
    let at = |pos: usize| tokens.get(pos).map(String::as_str);
    let mut path = base.to_string();
    loop {
        match at(*pos) {
            Some("{") => {
                *pos += 1;
                while !matches!(at(*pos), Some("}") | None) {
                    tree(tokens, pos, &path, out);
                    if at(*pos) != Some(",") {
                        break;
                    }
                    *pos += 1;
                }
                if at(*pos) == Some("}") {
                    *pos += 1;
                }
                return;
            }
            Some(segment) if ![",", "}", ":", "as"].contains(&segment) => {
                if !path.is_empty() {
                    path.push_str("::");
                }
                path.push_str(segment);
                *pos += 1;
                match at(*pos) {
                    Some(":") => *pos += 1,
                    Some("as") => {
                        *pos += 2;
                        break;
                    }
                    _ => break,
                }
            }
            _ => break,
        }
    }
    if path != base {
        out.push(path);
    }
}

#[cfg(test)]
mod tests {
    use super::paths_after;

    #[test]
    fn use_trees_expand_to_leaf_paths() {
        let code = "use jointfit::{scale::{fit_scale, ScaleFit as F}, ik}; let x = jointfit::workflow::run(a);";
        assert_eq!(
            paths_after(code, "jointfit"),
            ["scale::fit_scale", "scale::ScaleFit", "ik", "workflow::run"]
        );
        assert!(paths_after("use my_jointfit::ik;", "jointfit").is_empty());
        assert_eq!(paths_after("crate::a::*;", "crate"), ["a::*"]);
    }
}
