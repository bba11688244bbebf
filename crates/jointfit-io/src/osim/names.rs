//! OpenSim component names: which are valid, the sanitized model name, and text safe inside
//! an XML comment.

use jointfit::model::Model;

use super::OsimError;

/// Checks every name that becomes an OpenSim component name or path step.
pub(super) fn check_names(model: &Model) -> Result<(), OsimError> {
    let lists: [(&'static str, Vec<&str>); 4] = [
        (
            "segment",
            model.segments().iter().map(|s| s.name.as_str()).collect(),
        ),
        (
            "joint",
            model.joints().iter().map(|s| s.name.as_str()).collect(),
        ),
        (
            "coordinate",
            model
                .coordinates()
                .iter()
                .map(|s| s.name.as_str())
                .collect(),
        ),
        (
            "marker",
            model.markers().iter().map(|s| s.name.as_str()).collect(),
        ),
    ];
    for (kind, names) in lists {
        for name in names {
            if !valid_name(name) {
                return Err(OsimError::BadName {
                    kind,
                    name: name.to_string(),
                });
            }
        }
    }
    Ok(())
}

pub(super) fn invalid_char(c: char) -> bool {
    matches!(c, '\\' | '/' | '*' | '+') || c.is_whitespace() || c.is_control()
}

pub(super) fn valid_name(name: &str) -> bool {
    !name.is_empty() && name != "." && name != ".." && !name.chars().any(invalid_char)
}

pub(super) fn sanitize(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| if invalid_char(c) { '_' } else { c })
        .collect();
    if valid_name(&s) {
        s
    } else {
        "jointfit_model".to_string()
    }
}

/// Text that may sit inside `<!-- … -->`: no `--` and no control characters but newlines.
pub(super) fn comment_safe(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        if c == '-' && out.ends_with('-') {
            out.push(' ');
        }
        if c.is_control() && c != '\n' {
            out.push(' ');
        } else {
            out.push(c);
        }
    }
    if out.ends_with('-') {
        out.push(' ');
    }
    out
}
