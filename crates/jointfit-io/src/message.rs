//! Error messages on one line, as the command line prints them after `jointfit: error: ` and
//! the Python package raises them (`jointfit.JointfitError`): one implementation for both.

/// Longest token kept whole in an error message (a quoted input, a path, a number).
pub const MAX_TOKEN_CHARS: usize = 80;
/// Longest error message.
pub const MAX_MESSAGE_CHARS: usize = 1000;

/// The error and its causes on one line, each cause said once: a cause whose text the
/// message already holds (thiserror types that print their source, wrapped by anyhow
/// contexts) is skipped. Whitespace runs become one space; see [`tidy`].
pub fn one_line(causes: impl IntoIterator<Item = String>) -> String {
    let mut msg = String::new();
    for s in causes {
        let s = s.split_whitespace().collect::<Vec<_>>().join(" ");
        if s.is_empty() || msg.contains(&s) {
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&s);
    }
    tidy(&msg)
}

/// A one-line message with numbers of more than 24 characters in scientific notation,
/// tokens longer than [`MAX_TOKEN_CHARS`] elided in the middle, and the whole capped at
/// [`MAX_MESSAGE_CHARS`].
pub fn tidy(msg: &str) -> String {
    let tokens: Vec<String> = msg
        .split(' ')
        .map(|t| {
            let core = t.trim_end_matches([',', ';', ':', ')', '.']);
            let tail = &t[core.len()..];
            if core.len() > 24 {
                if let Ok(v) = core.parse::<f64>() {
                    return format!("{v:e}{tail}");
                }
            }
            let n = t.chars().count();
            if n > MAX_TOKEN_CHARS {
                let head: String = t.chars().take(60).collect();
                let end: String = t.chars().skip(n - 16).collect();
                format!("{head}…[{} characters]…{end}", n - 76)
            } else {
                t.to_string()
            }
        })
        .collect();
    let out = tokens.join(" ");
    if out.chars().count() > MAX_MESSAGE_CHARS {
        let cut: String = out.chars().take(MAX_MESSAGE_CHARS).collect();
        format!("{cut}…")
    } else {
        out
    }
}

/// The message of `e` and its `source()` chain on one line (see [`one_line`]).
pub fn of_error(e: &(dyn std::error::Error + 'static)) -> String {
    let mut causes = vec![e.to_string()];
    let mut cur = e.source();
    while let Some(s) = cur {
        causes.push(s.to_string());
        cur = s.source();
    }
    one_line(causes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn causes_once_whitespace_folded() {
        let m = one_line([
            "a.toml: line 2: bad".to_string(),
            "bad".into(),
            "x\n  |\n y".into(),
        ]);
        assert_eq!(m, "a.toml: line 2: bad: x | y");
        let e = crate::model_file::load_model("no-such-model").unwrap_err();
        assert_eq!(of_error(&e), e.to_string());
    }
}
