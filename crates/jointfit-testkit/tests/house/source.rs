//! The repository as the house measures read it: which files there are, and each Rust file
//! split into code (comments removed; string contents kept or blanked) and comments, with the
//! lines that are compiled only for tests marked.

use std::collections::HashSet;
use std::fs;
use std::path::{Path, PathBuf};

/// Directory names never read: build output, virtual environments, caches, version control.
const SKIPPED_DIRS: [&str; 7] = [
    "target",
    ".git",
    ".venv",
    "out",
    "node_modules",
    "__pycache__",
    ".pytest_cache",
];

/// The workspace root (two levels above this crate).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Every text file below `dir` (relative to `root`, `/`-separated, sorted), without build
/// output, virtual environments, caches and run logs; a file with a NUL byte or that is not
/// UTF-8 is not text.
pub fn text_files(root: &Path, dir: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    walk(root, &root.join(dir), &mut out);
    out.sort();
    out
}

fn walk(root: &Path, dir: &Path, out: &mut Vec<(String, String)>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        if path.is_dir() {
            if !SKIPPED_DIRS.contains(&name.as_str()) {
                walk(root, &path, out);
            }
        } else if name.ends_with(".log") {
            // Run logs (OpenSim writes one where it runs), not source.
        } else if let Ok(text) = fs::read_to_string(&path) {
            if !text.contains('\0') {
                let rel = path.strip_prefix(root).unwrap_or(&path);
                let rel = rel.to_string_lossy().replace('\\', "/");
                out.push((rel.trim_start_matches("./").to_string(), text));
            }
        }
    }
}

/// One line of a Rust file.
#[derive(Debug, Clone, Default)]
pub struct Line {
    /// The code, comments removed, string literals as written.
    pub code: String,
    /// The code with the contents of string and character literals removed (quotes kept).
    pub bare: String,
    /// The text of the comments on the line.
    pub comment: String,
    /// Compiled only for tests (`#[cfg(test)]` items and their bodies).
    pub test: bool,
}

/// A Rust source file.
#[derive(Debug, Clone)]
pub struct RustFile {
    /// Path relative to the workspace root, `/`-separated.
    pub path: String,
    pub lines: Vec<Line>,
    /// The whole file is test code: under `tests/`, `benches/`, `examples/`, `fuzz/`, or a
    /// module declared under `#[cfg(test)]`.
    pub test: bool,
}

impl RustFile {
    /// The lines compiled into the library or binary (none for a test file).
    pub fn shipped_lines(&self) -> impl Iterator<Item = &Line> {
        self.lines.iter().filter(move |l| !self.test && !l.test)
    }
}

/// Lexer states.
enum State {
    Code,
    LineComment,
    BlockComment(usize),
    Str,
    RawStr(usize),
}

/// Splits `text` into lines of code and comment (string, raw-string, character and nested
/// block-comment literals understood; a `'` starts a character literal only when one
/// character or an escape is followed by `'`, otherwise it is a lifetime).
pub fn lex(text: &str) -> Vec<Line> {
    let c: Vec<char> = text.chars().collect();
    let mut lines = Vec::new();
    let mut cur = Line::default();
    let mut state = State::Code;
    let mut i = 0;
    while i < c.len() {
        let ch = c[i];
        let next = c.get(i + 1).copied();
        if ch == '\n' {
            lines.push(std::mem::take(&mut cur));
            if matches!(state, State::LineComment) {
                state = State::Code;
            }
            i += 1;
            continue;
        }
        match state {
            State::Code => {
                i = lex_code(&c, i, &mut cur, &mut state);
                continue;
            }
            State::LineComment => cur.comment.push(ch),
            State::BlockComment(depth) => {
                if ch == '/' && next == Some('*') {
                    state = State::BlockComment(depth + 1);
                    cur.comment.push_str("/*");
                    i += 2;
                    continue;
                }
                if ch == '*' && next == Some('/') {
                    state = if depth == 1 {
                        State::Code
                    } else {
                        State::BlockComment(depth - 1)
                    };
                    i += 2;
                    continue;
                }
                cur.comment.push(ch);
            }
            State::Str => {
                cur.code.push(ch);
                if ch == '\\' {
                    if let Some(n) = next.filter(|&n| n != '\n') {
                        cur.code.push(n);
                        i += 2;
                        continue;
                    }
                } else if ch == '"' {
                    cur.bare.push('"');
                    state = State::Code;
                }
            }
            State::RawStr(hashes) => {
                cur.code.push(ch);
                if ch == '"' && (1..=hashes).all(|k| c.get(i + k) == Some(&'#')) {
                    cur.code.extend(std::iter::repeat_n('#', hashes));
                    cur.bare.push('"');
                    state = State::Code;
                    i += 1 + hashes;
                    continue;
                }
            }
        }
        i += 1;
    }
    lines.push(cur);
    lines
}

/// One step in code: returns the index of the next character to read.
fn lex_code(c: &[char], i: usize, cur: &mut Line, state: &mut State) -> usize {
    let ch = c[i];
    let next = c.get(i + 1).copied();
    let after_ident = i > 0 && (c[i - 1].is_alphanumeric() || c[i - 1] == '_');
    if ch == '/' && next == Some('/') {
        *state = State::LineComment;
        return i + 2;
    }
    if ch == '/' && next == Some('*') {
        *state = State::BlockComment(1);
        return i + 2;
    }
    if ch == '"' {
        cur.code.push('"');
        cur.bare.push('"');
        *state = State::Str;
        return i + 1;
    }
    if !after_ident && (ch == 'r' || (ch == 'b' && next == Some('r'))) {
        let start = if ch == 'b' { i + 2 } else { i + 1 };
        let hashes = c[start.min(c.len())..]
            .iter()
            .take_while(|&&h| h == '#')
            .count();
        if c.get(start + hashes) == Some(&'"') {
            let opening: String = c[i..=start + hashes].iter().collect();
            cur.code.push_str(&opening);
            cur.bare.push('"');
            *state = State::RawStr(hashes);
            return start + hashes + 1;
        }
    }
    if ch == '\'' {
        let end = match (next, c.get(i + 2)) {
            (Some('\\'), Some('u')) => (i + 3..c.len()).find(|&k| c[k] == '\''),
            (Some('\\'), Some('x')) => Some(i + 5),
            (Some('\\'), _) => Some(i + 3),
            (_, Some('\'')) => Some(i + 2),
            _ => None,
        }
        .filter(|&end| c.get(end) == Some(&'\''));
        if let Some(end) = end {
            let literal: String = c[i..=end].iter().collect();
            cur.code.push_str(&literal);
            cur.bare.push_str("' '");
            return end + 1;
        }
    }
    cur.code.push(ch);
    cur.bare.push(ch);
    i + 1
}

/// Index of the line holding the brace that closes the first `{` at or after `start`, when
/// a `{` comes before a `;` ends the item.
pub fn item_end(lines: &[Line], start: usize) -> Option<usize> {
    let mut depth = 0i64;
    let mut opened = false;
    for (j, line) in lines.iter().enumerate().skip(start) {
        for ch in line.bare.chars() {
            match ch {
                '{' => {
                    depth += 1;
                    opened = true;
                }
                '}' => depth -= 1,
                ';' if !opened && depth == 0 => return None,
                _ => {}
            }
            if opened && depth <= 0 {
                return Some(j);
            }
        }
    }
    None
}

/// Marks the `#[cfg(test)]` items of `lines` as test code and returns the files of the
/// modules declared under it (`mod name;`, with `#[path]` understood), as paths relative to
/// the workspace root.
fn mark_test_items(path: &str, lines: &mut [Line]) -> Vec<String> {
    let mut modules = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let attr = lines[i].bare.trim().to_string();
        if !(attr.starts_with("#[cfg(test)]") || attr.starts_with("#[cfg(all(test")) {
            i += 1;
            continue;
        }
        let same_line = !attr.trim_start_matches("#[cfg(test)]").trim().is_empty();
        let mut j = if same_line { i } else { i + 1 };
        let mut path_attr = None;
        while !same_line && j < lines.len() && lines[j].bare.trim_start().starts_with("#[") {
            if let Some(p) = lines[j].code.split("path = \"").nth(1) {
                path_attr = p.split('"').next().map(str::to_string);
            }
            j += 1;
        }
        let end = match item_end(lines, j) {
            Some(end) => end,
            None => {
                if let Some(name) = declared_module(&lines[j.min(lines.len() - 1)].bare) {
                    modules.extend(module_files(path, &name, path_attr.as_deref()));
                }
                j
            }
        };
        let last = end.min(lines.len() - 1);
        for line in &mut lines[i..=last] {
            line.test = true;
        }
        i = end + 1;
    }
    modules
}

/// `name` of a `mod name;` declaration.
fn declared_module(bare: &str) -> Option<String> {
    let rest = bare.trim().trim_end_matches(';');
    let name = rest.rsplit("mod ").next()?.trim();
    (rest.contains("mod ") && !name.is_empty()).then(|| name.to_string())
}

/// The files that may hold module `name` declared in `path`.
fn module_files(path: &str, name: &str, path_attr: Option<&str>) -> Vec<String> {
    let file = Path::new(path);
    let dir = file.parent().unwrap_or(Path::new(""));
    if let Some(p) = path_attr {
        return vec![dir.join(p).to_string_lossy().into_owned()];
    }
    let stem = file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let base = if ["mod", "lib", "main"].contains(&stem.as_str()) {
        dir.to_path_buf()
    } else {
        dir.join(&stem)
    };
    vec![
        base.join(format!("{name}.rs"))
            .to_string_lossy()
            .into_owned(),
        base.join(name)
            .join("mod.rs")
            .to_string_lossy()
            .into_owned(),
    ]
}

/// Every Rust file under `crates/`, lexed, with its test code marked.
pub fn rust_files(root: &Path) -> Vec<RustFile> {
    let mut files: Vec<RustFile> = text_files(root, "crates")
        .into_iter()
        .filter(|(path, _)| path.ends_with(".rs"))
        .map(|(path, text)| {
            let test = ["/tests/", "/benches/", "/examples/", "/fuzz/"]
                .iter()
                .any(|d| path.contains(d))
                || text.trim_start().starts_with("#![cfg(test)]");
            RustFile {
                lines: lex(&text),
                path,
                test,
            }
        })
        .collect();
    let mut test_modules = HashSet::new();
    for file in &mut files {
        let path = file.path.clone();
        test_modules.extend(mark_test_items(&path, &mut file.lines));
    }
    let test_dirs: Vec<String> = test_modules
        .iter()
        .map(|m| {
            m.trim_end_matches("/mod.rs")
                .trim_end_matches(".rs")
                .to_string()
                + "/"
        })
        .collect();
    for file in &mut files {
        if test_modules.contains(&file.path) || test_dirs.iter().any(|d| file.path.starts_with(d)) {
            file.test = true;
        }
    }
    files
}

#[cfg(test)]
mod tests {
    use super::{item_end, lex, mark_test_items};

    #[test]
    fn literals_and_comments_are_told_apart() {
        let lines = lex("let a = \"{ // }\"; // c {\nlet b = '{'; let l: &'static str = r#\"}\"#; /* x\n { */ f('\\'');");
        assert_eq!(lines[0].bare, "let a = \"\"; ");
        assert_eq!(lines[0].code, "let a = \"{ // }\"; ");
        assert_eq!(lines[0].comment, " c {");
        assert_eq!(lines[1].bare, "let b = ' '; let l: &'static str = \"\"; ");
        assert_eq!(lines[1].comment, " x");
        assert_eq!(lines[2].bare, " f(' ');");
    }

    #[test]
    fn items_end_at_their_closing_brace_or_have_none() {
        let lines = lex("fn f() {\n    let s = \"}\";\n    if x { y }\n}\nfn g();");
        assert_eq!(item_end(&lines, 0), Some(3));
        assert_eq!(item_end(&lines, 4), None);
    }

    #[test]
    fn cfg_test_items_and_module_files_are_test_code() {
        let mut lines = lex("pub fn a() {}\n#[cfg(test)]\nmod tests {\n    pub fn b() {}\n}\n#[cfg(test)]\n#[path = \"x_tests.rs\"]\nmod x;\npub fn c() {}");
        let modules = mark_test_items("crates/k/src/m/mod.rs", &mut lines);
        let test: Vec<bool> = lines.iter().map(|l| l.test).collect();
        assert_eq!(
            test,
            [false, true, true, true, true, true, true, true, false]
        );
        assert_eq!(modules, ["crates/k/src/m/x_tests.rs"]);
    }
}
