"""Shared fixtures: the real data, the command-line binary (the oracle for equality tests).

Outside CI a missing resource skips the test with a "skipped: ..." reason; in CI (env CI
set) it fails, as the Rust tests do.
"""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]


def in_ci() -> bool:
    return os.environ.get("CI", "") not in ("", "0", "false")


def missing(what: str):
    if in_ci():
        pytest.fail(f"{what} is missing; CI must have it")
    pytest.skip(f"skipped: {what}")


@pytest.fixture(scope="session")
def data_dir() -> pathlib.Path:
    d = pathlib.Path(os.environ.get("JOINTFIT_DATA", ROOT.parent / "shared" / "data"))
    if not d.is_dir():
        missing(f"no data at {d} (set JOINTFIT_DATA)")
    return d


@pytest.fixture(scope="session")
def cli() -> pathlib.Path:
    exe = pathlib.Path(os.environ.get("JOINTFIT_BIN", ROOT / "target" / "release" / "jointfit"))
    if not exe.is_file():
        missing(f"no jointfit binary at {exe} (cargo build --release -p jointfit-cli, or set JOINTFIT_BIN)")
    return exe


@pytest.fixture(scope="session")
def run_cli(cli):
    """Runs the binary; returns (returncode, stdout, stderr)."""

    def run(*args):
        p = subprocess.run([str(cli), *map(str, args)], capture_output=True, text=True)
        return p.returncode, p.stdout, p.stderr

    return run


def cli_error(stderr: str) -> str:
    """The command line's error message: everything after 'jointfit: error: ' (warnings
    before it dropped), without the final newline."""
    key = "jointfit: error: "
    assert stderr.count(key) == 1, stderr
    return stderr[stderr.index(key) + len(key) :].rstrip("\n")
