"""The user guide (docs/guide) cannot rot: every ```sh and ```python block of every chapter
runs, in order, in a fresh folder per chapter, and must succeed; blocks marked ```sh,data /
```python,data run on the shared data ($JOINTFIT_DATA) and are skipped without it (outside
CI). The command-line reference (cli.md) is `jointfit --help` of every command and the Python
reference (python-api.md) the package's signatures and docstrings: both are regenerated here
and must equal the files (JOINTFIT_UPDATE_GUIDE=1 rewrites them instead).
"""

import dataclasses
import inspect
import os
import pathlib
import re
import subprocess
import sys

import pytest

import jointfit as jf

from conftest import ROOT, in_ci, missing

GUIDE = ROOT / "docs" / "guide"
BLOCK = re.compile(r"^```(sh|python)(,data)?[ \t]*\n(.*?)^```[ \t]*$", re.S | re.M)
UPDATE = os.environ.get("JOINTFIT_UPDATE_GUIDE", "") not in ("", "0")


def chapters():
    """The chapters in SUMMARY.md order."""
    summary = (GUIDE / "SUMMARY.md").read_text()
    return [GUIDE / m for m in re.findall(r"\]\(([^)]+\.md)\)", summary)]


def test_every_chapter_in_the_summary_exists_and_every_file_is_listed():
    listed = chapters()
    for c in listed:
        assert c.is_file(), c
    on_disk = {p for p in GUIDE.glob("*.md") if p.name != "SUMMARY.md"}
    assert on_disk == set(listed), on_disk ^ set(listed)


@pytest.mark.parametrize("chapter", [c.name for c in chapters()])
def test_every_block_of_the_chapter_runs(chapter, cli, tmp_path):
    text = (GUIDE / chapter).read_text()
    blocks = BLOCK.findall(text)
    data = pathlib.Path(os.environ.get("JOINTFIT_DATA", ROOT.parent / "shared" / "data"))
    env = dict(os.environ)
    env["PATH"] = f"{cli.parent}{os.pathsep}{env.get('PATH', '')}"
    env["MPLBACKEND"] = "Agg"
    env["JOINTFIT_PROGRESS"] = "quiet"
    env["PYTHONWARNINGS"] = "ignore"
    have_data = data.is_dir()
    if have_data:
        env["JOINTFIT_DATA"] = str(data)
    skipped = 0
    for k, (lang, needs_data, code) in enumerate(blocks, start=1):
        if needs_data and not have_data:
            if in_ci():
                pytest.fail(f"no data at {data}; CI must have it")
            skipped += 1
            continue
        if lang == "sh":
            cmd = ["bash", "-euo", "pipefail", "-c", code]
        else:
            script = tmp_path / f"block{k}.py"
            script.write_text(code)
            cmd = [sys.executable, str(script)]
        p = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
        assert p.returncode == 0, (
            f"{chapter}, block {k} ({lang}) failed with status {p.returncode}:\n{code}\n"
            f"--- stdout\n{p.stdout[-3000:]}\n--- stderr\n{p.stderr[-3000:]}"
        )
    if skipped:
        print(f"skipped: {skipped} data blocks of {chapter} (no data at {data})")


def _help(cli, *args):
    p = subprocess.run([str(cli), *args, "--help"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    return p.stdout.rstrip() + "\n"


def _subcommands(help_text):
    """The subcommand names listed under `Commands:` (without `help`)."""
    names, inside = [], False
    for line in help_text.splitlines():
        if line.startswith("Commands:"):
            inside = True
            continue
        if inside:
            m = re.match(r"^  (\S+)\s", line)
            if not m:
                if line.strip() == "" or not line.startswith("  "):
                    break
                continue
            if m.group(1) != "help":
                names.append(m.group(1))
    return names


def cli_reference(cli):
    out = [
        "# Command-line reference",
        "",
        "<!-- Generated from `jointfit --help` of every command by",
        "     crates/jointfit-py/tests/test_guide.py (JOINTFIT_UPDATE_GUIDE=1 rewrites it). -->",
        "",
        "Every command, as `jointfit COMMAND --help` prints it.",
        "",
    ]

    def add(path):
        text = _help(cli, *path)
        title = " ".join(["jointfit", *path])
        out.extend([f"## `{title}`", "", "```text", text.rstrip(), "```", ""])
        for sub in _subcommands(text):
            add([*path, sub])

    add([])
    return "\n".join(out).rstrip() + "\n"


def _signature(obj):
    try:
        return str(inspect.signature(obj))
    except (TypeError, ValueError):
        return "(...)"


def _doc(obj):
    return inspect.cleandoc(obj.__doc__ or "").strip()


def python_reference():
    out = [
        "# Python API reference",
        "",
        "<!-- Generated from the docstrings and signatures of the installed package by",
        "     crates/jointfit-py/tests/test_guide.py (JOINTFIT_UPDATE_GUIDE=1 rewrites it). -->",
        "",
        "Type stubs ship with the package (`jointfit/_jointfit.pyi`), so editors complete and",
        "check these calls. SI units throughout: m, rad, s, Hz.",
        "",
        "## Module `jointfit`",
        "",
        _doc(jf),
        "",
    ]
    for name in sorted(jf.__all__, key=lambda n: (not inspect.isclass(getattr(jf, n)), n.lower())):
        obj = getattr(jf, name)
        if inspect.isclass(obj):
            out.extend([f"## class `{name}`", "", _doc(obj), ""])
            if dataclasses.is_dataclass(obj):
                out.extend([f"### `{name}{_signature(obj)}`", ""])
            for member, raw in sorted(vars(obj).items()):
                if member.startswith("_") and member != "_repr_html_":
                    continue
                doc = _doc(raw.__func__ if isinstance(raw, (staticmethod, classmethod)) else raw)
                if inspect.isdatadescriptor(raw) or isinstance(raw, property):
                    out.extend([f"### `{name}.{member}`", ""])
                elif callable(getattr(obj, member)) and not isinstance(raw, (int, float, str)):
                    out.extend([f"### `{name}.{member}{_signature(getattr(obj, member))}`", ""])
                else:
                    continue  # a dataclass field's default: in the signature above
                if doc:
                    out.extend([doc, ""])
        elif callable(obj):
            out.extend([f"## `{name}{_signature(obj)}`", "", _doc(obj), ""])
        else:
            out.extend([f"## `{name}`", "", f"`{obj!r}`", ""])
    return "\n".join(out).rstrip() + "\n"


@pytest.mark.parametrize("name", ["cli.md", "python-api.md"])
def test_generated_references_are_current(name, cli):
    want = cli_reference(cli) if name == "cli.md" else python_reference()
    path = GUIDE / name
    if UPDATE:
        path.write_text(want)
    have = path.read_text() if path.exists() else ""
    assert have == want, f"{path} is stale: JOINTFIT_UPDATE_GUIDE=1 pytest {__file__} rewrites it"
