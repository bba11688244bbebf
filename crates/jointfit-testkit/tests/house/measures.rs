//! The seven house measures, each a list of findings (its length is the number).

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::Path;

use regex::Regex;

use crate::paths::{paths_after, use_tree};
use crate::source::{item_end, lex, text_files, RustFile};

/// Lines between these two markers hold a check's own word list and are not searched.
const WORD_LIST_BEGIN: &str = "house-words: begin";
const WORD_LIST_END: &str = "house-words: end";

// house-words: begin
/// Words that speak of how the code was made rather than of what it does.
const PROCESS_WORDS: [&str; 5] = [
    r"(?i)\bstop\s+#?\d+\b",
    r"(?i)\bengineers?\b",
    r"(?i:\bbriefs\b)|\b[Bb]rief\s+[A-Z]\b|(?i:\b(?:the|this|that|my|your|our|each|per|its)\s+brief\s*(?:[.,;:)!?]|$))",
    r"(?i)\bhelpers?(?:'s)?\s+(?:session|agent|branch|worktree)s?\b|\b(?:another|other|each|every|one)\s+helpers?\s*(?:[.,;:)!?]|$)",
    r"(?i)\bissues?\s+#?\d+\b",
];
/// Dates, searched in comments and prose only (a date in a string literal is test data).
const DATE: &str = r"\b20\d\d-[01]\d-[0-3]\d\b|(?i:\b\d{1,2}\s+(?:jan|feb|mar|apr|may|jun|jul|aug|sep|oct|nov|dec)[a-z]*\.?\s+20\d\d\b)|(?i:\b(?:jan|feb|mar|apr|may|jun|jul|aug|sep|oct|nov|dec)[a-z]*\.?\s+\d{1,2},?\s+20\d\d\b)";
/// Phrases that tell the story of the work (which revision, which machine load, what came
/// before) instead of the method or the current behaviour.
const HISTORY_PHRASES: [&str; 7] = [
    r"(?i)\bthis branch\b",
    r"(?i)\bmain\W{0,2} at\b",
    r"(?i)\bload average\b|\bat load\b|\bload [0-9]",
    r"(?i)\brevisions? [0-9]+",
    r"(?i)\bstop-[0-9]+",
    r"(?i)\bbefore this change\b|\b(?:before|after) the (?:fix|change|merge)\b|\bafter merging\b",
    r"(?i)\bearlier runs?\b|\bsuperseded\b|\bformerly\b|\btried (?:again|once more)\b",
];
/// A word of hex digits as long as a commit hash (abbreviated or full).
const HEX_WORD: &str = r"\b[0-9a-f]{7,40}\b";
// house-words: end

/// Files whose whole text is prose, where a date may stand anywhere.
const PROSE: [&str; 4] = [".md", ".txt", ".rst", ".ipynb"];

/// `path:line: match` for each process word or date of work in the repository's text files.
pub fn process_words(root: &Path) -> Vec<String> {
    let words: Vec<Regex> = PROCESS_WORDS
        .iter()
        .map(|w| Regex::new(w).unwrap())
        .collect();
    let date = Regex::new(DATE).unwrap();
    let mut found = Vec::new();
    for (path, text) in text_files(root, ".") {
        let lines: Vec<&str> = text.lines().collect();
        let dated = dated_text(&path, &text);
        let mut listed = false;
        for (n, line) in lines.iter().enumerate() {
            if line.contains(WORD_LIST_BEGIN) || line.contains(WORD_LIST_END) {
                listed = line.contains(WORD_LIST_BEGIN);
                continue;
            }
            if listed {
                continue;
            }
            let hits = words.iter().filter_map(|w| w.find(line));
            let dates = dated.get(n).and_then(|d| date.find(d));
            for hit in hits.chain(dates) {
                found.push(format!("{path}:{}: {}", n + 1, hit.as_str()));
            }
        }
    }
    found
}

/// For each line of `text`, the part where a date would be a date of work: all of a prose
/// file, the comments of Rust, the text after `#` elsewhere.
fn dated_text(path: &str, text: &str) -> Vec<String> {
    if PROSE.iter().any(|e| path.ends_with(e)) {
        text.lines().map(str::to_string).collect()
    } else if path.ends_with(".rs") {
        lex(text).into_iter().map(|l| l.comment).collect()
    } else {
        text.lines()
            .map(|l| {
                l.split_once('#')
                    .map(|(_, c)| c.to_string())
                    .unwrap_or_default()
            })
            .collect()
    }
}

/// A hex word that reads as a commit: it has a digit and a letter, and it is not `e` and
/// digits (an article number such as PLoS ONE's `e0295152`).
fn is_commit_hash(word: &str) -> bool {
    let has_digit = word.chars().any(|c| c.is_ascii_digit());
    let has_letter = word.chars().any(|c| ('a'..='f').contains(&c));
    let article = word.starts_with('e') && word[1..].chars().all(|c| c.is_ascii_digit());
    has_digit && has_letter && !article
}

/// The history phrases and commit hashes of one line of prose.
fn history_hits(phrases: &[Regex], hex_word: &Regex, line: &str) -> Vec<String> {
    let hits = phrases.iter().filter_map(|p| p.find(line));
    let hashes = hex_word
        .find_iter(line)
        .filter(|m| is_commit_hash(m.as_str()));
    hits.chain(hashes).map(|m| m.as_str().to_string()).collect()
}

fn history_patterns() -> (Vec<Regex>, Regex) {
    let phrases = HISTORY_PHRASES
        .iter()
        .map(|p| Regex::new(p).unwrap())
        .collect();
    (phrases, Regex::new(HEX_WORD).unwrap())
}

/// `path:line: phrase` for each history phrase (the list above) and each commit hash in the
/// text files under `docs/` and in `README.md`.
pub fn history_phrases(root: &Path) -> Vec<String> {
    let (phrases, hex_word) = history_patterns();
    let readme = text_files(root, ".")
        .into_iter()
        .filter(|(path, _)| path == "README.md");
    let mut found = Vec::new();
    for (path, text) in text_files(root, "docs").into_iter().chain(readme) {
        for (n, line) in text.lines().enumerate() {
            for hit in history_hits(&phrases, &hex_word, line) {
                found.push(format!("{path}:{}: {hit}", n + 1));
            }
        }
    }
    found
}

/// `lines path name` for each function whose body spans more than 100 lines, from the `fn`
/// line to its closing brace, anywhere under `crates/`, longest first.
pub fn long_functions(files: &[RustFile]) -> Vec<String> {
    let head = Regex::new(r"^\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?fn\s+(\w+)")
        .unwrap();
    let mut found = Vec::new();
    for file in files {
        for (i, line) in file.lines.iter().enumerate() {
            let Some(name) = head.captures(&line.bare).map(|c| c[6].to_string()) else {
                continue;
            };
            if let Some(end) = item_end(&file.lines, i) {
                if end - i + 1 > 100 {
                    found.push((end - i + 1, file.path.clone(), name));
                }
            }
        }
    }
    found.sort_by(|a, b| b.cmp(a));
    found
        .into_iter()
        .map(|(n, path, name)| format!("{n} {path} {name}"))
        .collect()
}

/// `path: item` for each public item of the core library outside test code: every `pub`
/// fn/struct/enum/const/static/type/trait/mod (methods included) and every name a `pub use`
/// re-exports.
pub fn core_public_items(files: &[RustFile]) -> Vec<String> {
    let item = Regex::new(
        r#"\bpub\s+(?:(?:const|async|unsafe|extern\s+"")\s+)*(fn|struct|enum|static|type|trait|mod|union)\s+(\w+)|\bpub\s+const\s+(\w+)\s*:"#,
    )
    .unwrap();
    let reexport = Regex::new(r"\bpub\s+use\s+([^;]*);").unwrap();
    let mut found = Vec::new();
    for file in files
        .iter()
        .filter(|f| f.path.starts_with("crates/jointfit/src/"))
    {
        let code: Vec<&str> = file.shipped_lines().map(|l| l.bare.as_str()).collect();
        let code = code.join("\n");
        for c in item.captures_iter(&code) {
            let (kind, name) = match (c.get(1), c.get(2), c.get(3)) {
                (Some(k), Some(n), _) => (k.as_str(), n.as_str()),
                (_, _, Some(n)) => ("const", n.as_str()),
                _ => continue,
            };
            found.push(format!("{}: {kind} {name}", file.path));
        }
        for c in reexport.captures_iter(&code) {
            for name in use_tree(&c[1]) {
                found.push(format!("{}: use {name}", file.path));
            }
        }
    }
    found
}

/// Modules whose calls make an application workflow (fitting, inverse kinematics,
/// calibration, scaling fits), by crate.
const WORKFLOW_PATHS: [(&str, &[&str]); 2] = [
    ("jointfit", &["workflow", "calibrate", "ik"]),
    ("jointfit_scale", &["fit"]),
];
const WORKFLOW_FNS: [&str; 1] = ["fit_scale"];

/// `path: crate::path` for each module of `jointfit-io` that names a fit, IK or calibration
/// function or module of the core, or the scaling fit, outside test code.
pub fn io_workflow(files: &[RustFile]) -> Vec<String> {
    let mut found = Vec::new();
    for file in files
        .iter()
        .filter(|f| f.path.starts_with("crates/jointfit-io/src/"))
    {
        let code: Vec<&str> = file.shipped_lines().map(|l| l.bare.as_str()).collect();
        let code = code.join("\n");
        let named: BTreeSet<String> = WORKFLOW_PATHS
            .iter()
            .flat_map(|(krate, modules)| {
                paths_after(&code, krate)
                    .into_iter()
                    .filter(|p| {
                        let first = p.split("::").next().unwrap_or("");
                        modules.contains(&first)
                            || WORKFLOW_FNS
                                .iter()
                                .any(|f| p.rsplit("::").next() == Some(f))
                    })
                    .map(move |p| format!("{krate}::{p}"))
            })
            .collect();
        if !named.is_empty() {
            let named: Vec<String> = named.into_iter().collect();
            found.push(format!("{}: {}", file.path, named.join(", ")));
        }
    }
    found
}

/// The crates linked into the `jointfit` binary: the CLI and, recursively, its path
/// dependencies (`[dependencies]` only).
fn binary_crates(root: &Path) -> BTreeSet<String> {
    let dep = Regex::new(r#"path\s*=\s*"\.\./([\w-]+)""#).unwrap();
    let mut crates = BTreeSet::new();
    let mut todo = vec!["jointfit-cli".to_string()];
    while let Some(name) = todo.pop() {
        if !crates.insert(name.clone()) {
            continue;
        }
        let manifest = fs::read_to_string(root.join("crates").join(&name).join("Cargo.toml"))
            .unwrap_or_default();
        let deps = manifest
            .split("\n[")
            .find(|s| s.starts_with("dependencies]"))
            .unwrap_or("");
        todo.extend(dep.captures_iter(deps).map(|c| c[1].to_string()));
    }
    crates
}

/// `path:line: code` for each line of the binary's non-test code that reaches into the
/// source tree: `CARGO_MANIFEST_DIR`, a path under `scripts/`, or running `git`.
pub fn binary_source_paths(root: &Path, files: &[RustFile]) -> Vec<String> {
    let tree = Regex::new(r#"CARGO_MANIFEST_DIR|scripts/|Command::new\(\s*"git"\s*\)"#).unwrap();
    let dirs: Vec<String> = binary_crates(root)
        .iter()
        .map(|c| format!("crates/{c}/src/"))
        .collect();
    let mut found = Vec::new();
    for file in files
        .iter()
        .filter(|f| dirs.iter().any(|d| f.path.starts_with(d)))
    {
        for (n, line) in file.lines.iter().enumerate() {
            if !file.test && !line.test && tree.is_match(&line.code) {
                found.push(format!("{}:{}: {}", file.path, n + 1, line.code.trim()));
            }
        }
    }
    found
}

/// The core's top-level modules, and for each, the others its non-test code names (with the
/// first file that does).
fn core_module_graph(files: &[RustFile]) -> BTreeMap<String, BTreeMap<String, String>> {
    let prefix = "crates/jointfit/src/";
    let declared = Regex::new(r"^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)").unwrap();
    let lib = files.iter().find(|f| f.path == format!("{prefix}lib.rs"));
    let modules: BTreeSet<String> = lib
        .map(|l| {
            l.shipped_lines()
                .filter_map(|x| declared.captures(&x.bare).map(|c| c[1].to_string()))
                .collect()
        })
        .unwrap_or_default();
    let mut graph: BTreeMap<String, BTreeMap<String, String>> = modules
        .iter()
        .map(|m| (m.clone(), BTreeMap::new()))
        .collect();
    for file in files
        .iter()
        .filter(|f| f.path.starts_with(prefix) && !f.test)
    {
        let rel = file.path[prefix.len()..]
            .trim_end_matches(".rs")
            .trim_end_matches("/mod");
        let own: Vec<&str> = rel.split('/').collect();
        let Some(from) = graph.get_mut(own[0]) else {
            continue;
        };
        let code: Vec<&str> = file.shipped_lines().map(|l| l.bare.as_str()).collect();
        let code = code.join("\n");
        let by_crate = paths_after(&code, "crate")
            .into_iter()
            .filter_map(|p| p.split("::").next().map(str::to_string));
        let by_super = paths_after(&code, "super").into_iter().filter_map(|p| {
            let segments: Vec<&str> = p.split("::").collect();
            let ups = 1 + segments.iter().take_while(|s| **s == "super").count();
            let inside = own.len().checked_sub(ups)?;
            Some(if inside == 0 {
                segments.get(ups - 1)?.to_string()
            } else {
                own[0].to_string()
            })
        });
        for to in by_crate.chain(by_super) {
            if to != own[0] && modules.contains(&to) {
                from.entry(to).or_insert_with(|| file.path.clone());
            }
        }
    }
    graph
}

/// Each set of the core's top-level modules that depend on each other in a cycle, as
/// `a -> b (file), …` over its edges; the number of modules in cycles is the measure.
pub fn core_cycles(files: &[RustFile]) -> (usize, Vec<String>) {
    let graph = core_module_graph(files);
    let names: Vec<&String> = graph.keys().collect();
    let n = names.len();
    let index = |m: &str| names.iter().position(|x| *x == m);
    let mut reach = vec![vec![false; n]; n];
    for (a, deps) in &graph {
        for b in deps.keys() {
            reach[index(a).unwrap()][index(b).unwrap()] = true;
        }
    }
    for k in 0..n {
        for i in 0..n {
            for j in 0..n {
                reach[i][j] |= reach[i][k] && reach[k][j];
            }
        }
    }
    let mut seen = vec![false; n];
    let (mut in_cycles, mut cycles) = (0, Vec::new());
    for i in 0..n {
        let members: Vec<usize> = (0..n)
            .filter(|&j| j == i || reach[i][j] && reach[j][i])
            .collect();
        if seen[i] || members.len() < 2 {
            continue;
        }
        members.iter().for_each(|&j| seen[j] = true);
        in_cycles += members.len();
        let mut edges = Vec::new();
        for &a in &members {
            for (b, file) in &graph[names[a]] {
                if members.contains(&index(b).unwrap()) {
                    edges.push(format!("{} -> {b} ({file})", names[a]));
                }
            }
        }
        cycles.push(edges.join(", "));
    }
    (in_cycles, cycles)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn history_phrases_are_found_and_method_prose_is_not() {
        let (phrases, hex_word) = history_patterns();
        let hits = |line: &str| history_hits(&phrases, &hex_word, line);
        assert_eq!(
            hits("before = `main` at 830fb48, after = this branch").len(),
            3
        );
        assert_eq!(hits("measured at load 8.6 (load average 12)"), ["at load"]);
        assert_eq!(
            hits("Tried again at revision 23, the stop-24 table"),
            ["revision 23", "stop-24", "Tried again"]
        );
        assert_eq!(
            hits("Superseded after the fix; an earlier run"),
            ["after the fix", "Superseded"]
        );
        for method in [
            "PLoS ONE 18:e0295152; studylib.net doc 10720131",
            "the RMS before/after the fit, a load of 3 files, the main joint at the hip",
            "a 7-digit number 1234567 and a word like deadbeef or facade",
            "the branch of the tree; revisions of the model; reload 5 times",
        ] {
            assert!(hits(method).is_empty(), "{method}: {:?}", hits(method));
        }
    }
}
