#!/usr/bin/env python3
"""House measures of the repository (Python standard library only).

Measures on the source tree, with the definitions of `crates/jointfit-testkit/tests/house/`
(the Rust test that holds each number to a ceiling; this script is its independent twin):

* process words: words that tell how the code was made rather than what it does, and dates
  of work (in comments and prose only), in every text file;
* functions over 100 lines: a `fn` whose body spans more than 100 lines from the `fn` line to
  its closing brace, anywhere under `crates/`;
* core public items: each `pub` fn/struct/enum/const/static/type/trait/mod of
  `crates/jointfit/src` outside `#[cfg(test)]` code (methods included), plus each name a
  `pub use` re-exports;
* io workflow modules: modules of `crates/jointfit-io/src` that name the core's `workflow`,
  `calibrate` or `ik`, or the scaling fit of `jointfit-scale` (`fit`, `fit_scale`) outside
  test code;
* binary source-tree paths: lines of the non-test code linked into the `jointfit` binary that
  name `CARGO_MANIFEST_DIR`, a path under `scripts/`, or run `git`;
* core modules in cycles: top-level modules of the core that lie on a dependency cycle
  (`crate::` and `super::` paths of non-test code);
* history phrases in the user docs: phrases that tell the story of the work instead of the
  method or the current behaviour, in every text file under `docs/` and in `README.md`:
  commit hashes in prose (7 to 40 hex digits with at least one digit and one letter; an
  article number such as PLoS ONE's `e0295152`, `e` and digits only, is not one), "this
  branch", "main at", "load average" / "at load" / "load N", "revision N", "stop-N",
  "before this change", "before/after the fix", "after merging", "earlier run",
  "superseded", "formerly", "tried again". Machine load belongs to a measurement's log, a
  revision to git; a comparison that supports a design choice names both options and the
  command that measures them.

Usage (from anywhere; the repository is this script's parent directory):
    python3 scripts/house_metrics.py            # the seven numbers
    python3 scripts/house_metrics.py -v         # and what makes each up
    python3 scripts/house_metrics.py --json     # one line `@@{...}` with the numbers
"""

import json
import os
import re
import sys

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
SKIPPED_DIRS = {"target", ".git", ".venv", "out", "node_modules", "__pycache__", ".pytest_cache"}

WORD_LIST_BEGIN = "house-words: begin"
WORD_LIST_END = "house-words: end"
# house-words: begin
PROCESS_WORDS = [
    r"(?i)\bstop\s+#?\d+\b",
    r"(?i)\bengineers?\b",
    r"(?i:\bbriefs\b)|\b[Bb]rief\s+[A-Z]\b|(?i:\b(?:the|this|that|my|your|our|each|per|its)\s+brief\s*(?:[.,;:)!?]|$))",
    r"(?i)\bhelpers?(?:'s)?\s+(?:session|agent|branch|worktree)s?\b|\b(?:another|other|each|every|one)\s+helpers?\s*(?:[.,;:)!?]|$)",
    r"(?i)\bissues?\s+#?\d+\b",
]
MONTH = r"(?:jan|feb|mar|apr|may|jun|jul|aug|sep|oct|nov|dec)[a-z]*\.?"
DATE = (
    r"\b20\d\d-[01]\d-[0-3]\d\b"
    r"|(?i:\b\d{1,2}\s+" + MONTH + r"\s+20\d\d\b)"
    r"|(?i:\b" + MONTH + r"\s+\d{1,2},?\s+20\d\d\b)"
)
HISTORY_PHRASES = [
    r"(?i)\bthis branch\b",
    r"(?i)\bmain\W{0,2} at\b",
    r"(?i)\bload average\b|\bat load\b|\bload [0-9]",
    r"(?i)\brevisions? [0-9]+",
    r"(?i)\bstop-[0-9]+",
    r"(?i)\bbefore this change\b|\b(?:before|after) the (?:fix|change|merge)\b|\bafter merging\b",
    r"(?i)\bearlier runs?\b|\bsuperseded\b|\bformerly\b|\btried (?:again|once more)\b",
]
HEX_WORD = r"\b[0-9a-f]{7,40}\b"
# house-words: end
PROSE = (".md", ".txt", ".rst", ".ipynb")

FN_HEAD = re.compile(r"^\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?fn\s+(\w+)")
PUB_ITEM = re.compile(
    r'\bpub\s+(?:(?:const|async|unsafe|extern\s+"")\s+)*(fn|struct|enum|static|type|trait|mod|union)\s+(\w+)'
    r"|\bpub\s+const\s+(\w+)\s*:"
)
PUB_USE = re.compile(r"\bpub\s+use\s+([^;]*);")
WORKFLOW_PATHS = {"jointfit": ("workflow", "calibrate", "ik"), "jointfit_scale": ("fit",)}
WORKFLOW_FNS = ("fit_scale",)
SOURCE_TREE = re.compile(r'CARGO_MANIFEST_DIR|scripts/|Command::new\(\s*"git"\s*\)')


def text_files(top):
    """(relative path, text) of every text file below `top`, sorted."""
    out = []
    for here, dirs, files in os.walk(os.path.join(ROOT, top)):
        dirs[:] = [d for d in dirs if d not in SKIPPED_DIRS]
        for name in files:
            if name.endswith(".log"):
                continue  # run logs (OpenSim writes one where it runs), not source
            path = os.path.join(here, name)
            try:
                with open(path, encoding="utf-8") as f:
                    text = f.read()
            except (UnicodeDecodeError, OSError):
                continue
            if "\0" not in text:
                out.append((os.path.relpath(path, ROOT).replace(os.sep, "/"), text))
    return sorted(out)


class Line:
    """One line of Rust: code (comments removed), bare code (literal contents removed), comment."""

    def __init__(self):
        self.code, self.bare, self.comment, self.test = [], [], [], False

    def done(self):
        self.code, self.bare, self.comment = "".join(self.code), "".join(self.bare), "".join(self.comment)
        return self


def char_literal_end(c, i):
    """Index of the `'` closing a character literal opened at `i`, or None for a lifetime."""
    nxt = c[i + 1] if i + 1 < len(c) else ""
    after = c[i + 2] if i + 2 < len(c) else ""
    if nxt == "\\" and after == "u":
        end = next((k for k in range(i + 3, len(c)) if c[k] == "'"), None)
    elif nxt == "\\":
        end = i + 5 if after == "x" else i + 3
    elif after == "'":
        end = i + 2
    else:
        return None
    return end if end is not None and end < len(c) and c[end] == "'" else None


def lex_code(c, i, cur):
    """One step in code: (next index, new state)."""
    ch, nxt = c[i], (c[i + 1] if i + 1 < len(c) else "")
    if ch == "/" and nxt in "/*" and nxt:
        return i + 2, ("line",) if nxt == "/" else ("block", 1)
    if ch == '"':
        cur.code.append('"')
        cur.bare.append('"')
        return i + 1, ("str",)
    after_ident = i > 0 and (c[i - 1].isalnum() or c[i - 1] == "_")
    if not after_ident and (ch == "r" or (ch == "b" and nxt == "r")):
        start = i + 2 if ch == "b" else i + 1
        hashes = 0
        while start + hashes < len(c) and c[start + hashes] == "#":
            hashes += 1
        if start + hashes < len(c) and c[start + hashes] == '"':
            cur.code.append("".join(c[i : start + hashes + 1]))
            cur.bare.append('"')
            return start + hashes + 1, ("raw", hashes)
    if ch == "'":
        end = char_literal_end(c, i)
        if end is not None:
            cur.code.append("".join(c[i : end + 1]))
            cur.bare.append("' '")
            return end + 1, ("code",)
    cur.code.append(ch)
    cur.bare.append(ch)
    return i + 1, ("code",)


def lex(text):
    """Rust text as Lines (strings, raw strings, chars, nested block comments understood)."""
    c, lines, cur, state, i = list(text), [], Line(), ("code",), 0
    while i < len(c):
        ch, nxt = c[i], (c[i + 1] if i + 1 < len(c) else "")
        if ch == "\n":
            lines.append(cur.done())
            cur = Line()
            state = ("code",) if state[0] == "line" else state
            i += 1
        elif state[0] == "code":
            i, state = lex_code(c, i, cur)
        elif state[0] == "line":
            cur.comment.append(ch)
            i += 1
        elif state[0] == "block":
            if ch + nxt in ("/*", "*/"):
                depth = state[1] + (1 if ch == "/" else -1)
                state = ("block", depth) if depth else ("code",)
                i += 2
            else:
                cur.comment.append(ch)
                i += 1
        elif state[0] == "str":
            cur.code.append(ch)
            if ch == "\\" and nxt and nxt != "\n":
                cur.code.append(nxt)
                i += 1
            elif ch == '"':
                cur.bare.append('"')
                state = ("code",)
            i += 1
        else:
            hashes = state[1]
            cur.code.append(ch)
            if ch == '"' and "".join(c[i + 1 : i + 1 + hashes]) == "#" * hashes:
                cur.code.append("#" * hashes)
                cur.bare.append('"')
                state = ("code",)
                i += hashes
            i += 1
    lines.append(cur.done())
    return lines


def item_end(lines, start):
    """Line of the brace closing the first `{` from `start`, or None when `;` comes first."""
    depth, opened = 0, False
    for j in range(start, len(lines)):
        for ch in lines[j].bare:
            if ch == "{":
                depth, opened = depth + 1, True
            elif ch == "}":
                depth -= 1
            elif ch == ";" and not opened and depth == 0:
                return None
            if opened and depth <= 0:
                return j
    return None


def module_files(path, name, path_attr):
    """Files that may hold module `name` declared in `path`."""
    folder = os.path.dirname(path)
    if path_attr:
        return [os.path.normpath(os.path.join(folder, path_attr))]
    stem = os.path.splitext(os.path.basename(path))[0]
    base = folder if stem in ("mod", "lib", "main") else os.path.join(folder, stem)
    return [os.path.join(base, name + ".rs"), os.path.join(base, name, "mod.rs")]


def mark_test_items(path, lines):
    """Marks `#[cfg(test)]` items as test code; returns the files of test modules declared."""
    modules, i = [], 0
    while i < len(lines):
        attr = lines[i].bare.strip()
        if not (attr.startswith("#[cfg(test)]") or attr.startswith("#[cfg(all(test")):
            i += 1
            continue
        same_line = attr[len("#[cfg(test)]") :].strip() != "" and attr.startswith("#[cfg(test)]")
        j, path_attr = (i if same_line else i + 1), None
        while not same_line and j < len(lines) and lines[j].bare.lstrip().startswith("#["):
            m = re.search(r'path = "([^"]*)"', lines[j].code)
            path_attr = m.group(1) if m else path_attr
            j += 1
        end = item_end(lines, j)
        if end is None:
            end = j
            decl = lines[min(j, len(lines) - 1)].bare.strip().rstrip(";")
            if "mod " in decl:
                modules += module_files(path, decl.rsplit("mod ", 1)[1].strip(), path_attr)
        for line in lines[i : min(end, len(lines) - 1) + 1]:
            line.test = True
        i = end + 1
    return modules


class RustFile:
    def __init__(self, path, text):
        self.path, self.lines = path, lex(text)
        self.test = any(d in path for d in ("/tests/", "/benches/", "/examples/", "/fuzz/"))
        self.test = self.test or text.lstrip().startswith("#![cfg(test)]")

    def shipped(self):
        return [] if self.test else [l for l in self.lines if not l.test]

    def shipped_code(self):
        return "\n".join(l.bare for l in self.shipped())


def rust_files():
    files = [RustFile(p, t) for p, t in text_files("crates") if p.endswith(".rs")]
    test_modules = set()
    for f in files:
        test_modules.update(mark_test_items(f.path, f.lines))
    test_dirs = [re.sub(r"(/mod)?\.rs$", "", m) + "/" for m in test_modules]
    for f in files:
        if f.path in test_modules or any(f.path.startswith(d) for d in test_dirs):
            f.test = True
    return files


def tokens(text):
    """Identifiers, `:` (for `::`), `{`, `}`, `,`, `*` of a use tree, up to anything else."""
    out, depth, i = [], 0, 0
    while i < len(text):
        ch = text[i]
        if ch.isspace():
            i += 1
        elif ch.isalnum() or ch == "_":
            m = re.match(r"\w+", text[i:])
            out.append(m.group(0))
            i += len(m.group(0))
        elif ch == ":":
            if text[i + 1 : i + 2] != ":":
                break
            out.append(":")
            i += 2
        elif ch in "{},*" and (depth > 0 or ch in "{*"):
            depth += {"{": 1, "}": -1}.get(ch, 0)
            out.append(ch)
            i += 1
            if depth == 0 and ch == "}":
                break
        else:
            break
    return out


def tree(tok, pos, base, out):
    """One use tree at tok[pos:] under `base`; returns the position after it."""
    path = base
    while pos < len(tok):
        t = tok[pos]
        if t == "{":
            pos += 1
            while pos < len(tok) and tok[pos] != "}":
                pos = tree(tok, pos, path, out)
                if pos >= len(tok) or tok[pos] != ",":
                    break
                pos += 1
            if pos < len(tok) and tok[pos] == "}":
                pos += 1
            return pos
        if t in (",", "}", ":", "as"):
            break
        path = path + "::" + t if path else t
        pos += 1
        if pos < len(tok) and tok[pos] == ":":
            pos += 1
            continue
        if pos < len(tok) and tok[pos] == "as":
            pos += 2
        break
    if path != base:
        out.append(path)
    return pos


def use_tree(text):
    out = []
    tree(tokens(text), 0, "", out)
    return out


def paths_after(code, prefix):
    """Paths following each `prefix::` (not part of a longer name), use trees expanded."""
    out = []
    for m in re.finditer(re.escape(prefix) + "::", code):
        before = code[m.start() - 1] if m.start() else ""
        if before and (before.isalnum() or before in "_:"):
            continue
        tree(tokens(code[m.end() :]), 0, "", out)
    return out


def process_words():
    words = [re.compile(w) for w in PROCESS_WORDS]
    date = re.compile(DATE)
    found = []
    for path, text in text_files("."):
        lines = text.splitlines()
        if path.endswith(PROSE):
            dated = lines
        elif path.endswith(".rs"):
            dated = [l.comment for l in lex(text)]
        else:
            dated = [l.split("#", 1)[1] if "#" in l else "" for l in lines]
        listed = False
        for n, line in enumerate(lines):
            if WORD_LIST_BEGIN in line or WORD_LIST_END in line:
                listed = WORD_LIST_BEGIN in line
                continue
            if listed:
                continue
            hits = [w.search(line) for w in words] + [date.search(dated[n]) if n < len(dated) else None]
            found += [f"{path}:{n + 1}: {h.group(0)}" for h in hits if h]
    return found


def is_commit_hash(word):
    """A hex word that reads as a commit: a digit and a letter, and not `e` + digits."""
    has_digit = any(c.isdigit() for c in word)
    has_letter = any(c in "abcdef" for c in word)
    article = word[0] == "e" and word[1:].isdigit()
    return has_digit and has_letter and not article


def history_phrases():
    phrases = [re.compile(p) for p in HISTORY_PHRASES]
    hex_word = re.compile(HEX_WORD)
    docs = text_files("docs") + [(p, t) for p, t in text_files(".") if p == "README.md"]
    found = []
    for path, text in docs:
        for n, line in enumerate(text.splitlines()):
            hits = [m.group(0) for m in (p.search(line) for p in phrases) if m]
            hits += [m.group(0) for m in hex_word.finditer(line) if is_commit_hash(m.group(0))]
            found += [f"{path}:{n + 1}: {h}" for h in hits]
    return found


def long_functions(files):
    found = []
    for f in files:
        for i, line in enumerate(f.lines):
            m = FN_HEAD.match(line.bare)
            end = item_end(f.lines, i) if m else None
            if end is not None and end - i + 1 > 100:
                found.append((end - i + 1, f.path, m.group(6)))
    return [f"{n} {p} {name}" for n, p, name in sorted(found, reverse=True)]


def core_public_items(files):
    found = []
    for f in files:
        if not f.path.startswith("crates/jointfit/src/"):
            continue
        code = f.shipped_code()
        for m in PUB_ITEM.finditer(code):
            kind, name = (m.group(1), m.group(2)) if m.group(1) else ("const", m.group(3))
            found.append(f"{f.path}: {kind} {name}")
        for m in PUB_USE.finditer(code):
            found += [f"{f.path}: use {name}" for name in use_tree(m.group(1))]
    return found


def is_workflow(crate, path):
    parts = path.split("::")
    return parts[0] in WORKFLOW_PATHS[crate] or parts[-1] in WORKFLOW_FNS


def io_workflow(files):
    found = []
    for f in files:
        if f.path.startswith("crates/jointfit-io/src/"):
            code = f.shipped_code()
            named = sorted(
                {f"{c}::{p}" for c in WORKFLOW_PATHS for p in paths_after(code, c) if is_workflow(c, p)}
            )
            if named:
                found.append(f"{f.path}: {', '.join(named)}")
    return found


def binary_crates():
    crates, todo = set(), ["jointfit-cli"]
    while todo:
        name = todo.pop()
        if name in crates:
            continue
        crates.add(name)
        with open(os.path.join(ROOT, "crates", name, "Cargo.toml"), encoding="utf-8") as f:
            sections = f.read().split("\n[")
        deps = next((s for s in sections if s.startswith("dependencies]")), "")
        todo += re.findall(r'path\s*=\s*"\.\./([\w-]+)"', deps)
    return crates


def binary_source_paths(files):
    dirs = tuple(f"crates/{c}/src/" for c in sorted(binary_crates()))
    return [
        f"{f.path}:{n + 1}: {l.code.strip()}"
        for f in files
        if f.path.startswith(dirs) and not f.test
        for n, l in enumerate(f.lines)
        if not l.test and SOURCE_TREE.search(l.code)
    ]


def core_module_graph(files):
    prefix = "crates/jointfit/src/"
    lib = next(f for f in files if f.path == prefix + "lib.rs")
    decl = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)")
    modules = {m.group(1) for l in lib.shipped() for m in [decl.match(l.bare)] if m}
    graph = {m: {} for m in modules}
    for f in files:
        if not f.path.startswith(prefix) or f.test:
            continue
        own = re.sub(r"(/mod)?\.rs$", "", f.path[len(prefix) :]).split("/")
        if own[0] not in graph:
            continue
        code = f.shipped_code()
        targets = [p.split("::")[0] for p in paths_after(code, "crate")]
        for p in paths_after(code, "super"):
            segments = p.split("::")
            ups = 1 + next((k for k, s in enumerate(segments) if s != "super"), len(segments))
            inside = len(own) - ups
            if inside == 0 and ups - 1 < len(segments):
                targets.append(segments[ups - 1])
            elif inside > 0:
                targets.append(own[0])
        for to in targets:
            if to != own[0] and to in modules:
                graph[own[0]].setdefault(to, f.path)
    return graph


def core_cycles(files):
    graph = core_module_graph(files)
    names = sorted(graph)
    reach = {a: set(graph[a]) for a in names}
    for k in names:
        for i in names:
            if k in reach[i]:
                reach[i] |= reach[k]
    seen, in_cycles, cycles = set(), 0, []
    for a in names:
        members = [b for b in names if b == a or (b in reach[a] and a in reach[b])]
        if a in seen or len(members) < 2:
            continue
        seen.update(members)
        in_cycles += len(members)
        edges = [f"{x} -> {y} ({graph[x][y]})" for x in members for y in sorted(graph[x]) if y in members]
        cycles.append(", ".join(edges))
    return in_cycles, cycles


def measure():
    files = rust_files()
    in_cycles, cycles = core_cycles(files)
    return {
        "process_words": process_words(),
        "long_functions": long_functions(files),
        "core_public_items": core_public_items(files),
        "io_workflow_modules": io_workflow(files),
        "binary_source_tree_paths": binary_source_paths(files),
        "core_modules_in_cycles": (in_cycles, cycles),
        "history_phrases": history_phrases(),
    }


def main(argv):
    found = measure()
    count = {k: v[0] if isinstance(v, tuple) else len(v) for k, v in found.items()}
    if "--json" in argv:
        print("@@" + json.dumps(count, sort_keys=True))
        return 0
    for key, findings in found.items():
        print(f"{key.replace('_', ' ')}: {count[key]}")
        if "-v" in argv:
            for line in findings[1] if isinstance(findings, tuple) else findings:
                print(f"  {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
