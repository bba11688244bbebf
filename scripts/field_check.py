#!/usr/bin/env python3
"""A new user's pass over every motion file of the shared data (notebook/field_check.md).

Every C3D and TRC file under $JOINTFIT_DATA gets `inspect`, `convert` and `markers suggest`
(the file as its own static trial). Where a subject model can be built (a lab's static trial
with a preset or the suggested marker set, or the walk itself as the static trial), the
subject's motion trials get `personalize`, `check`, `ik --json`, `calibrate` and `report`,
with default options, as the README's first steps show them.

Each run is judged on what a user sees:

* PANIC: exit status 101 or "panicked" on stderr (never acceptable);
* ERROR: a failure whose stderr has not exactly one `jointfit: error:` line, or has lines
  that do not start with `jointfit: ` (notes and warnings before the error are fine);
* refused: exit status 1/2 with one error line (the line is quoted);
* ok: exit status 0 (warnings counted, the first quoted);
* and a few sanity checks of the answer (SUSPECT): `ik` solving no frame or a mean frame RMS
  above 40 mm, `calibrate` ending with a larger RMS than it started with, `convert` writing
  fewer frames than `inspect` reports.

Usage (stdlib only; prints a Markdown table, writes scratch files under a temporary dir):
    JOINTFIT_DATA=/work/shared/data python3 scripts/field_check.py [path/to/jointfit] [--quick]
"""

import glob
import json
import os
import shlex
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
WALK_SET = os.path.join(HERE, "markersets", "opensim_test_walks.toml")

# Subjects: (name, static trial, marker set: preset, file or "suggest", extra personalize
# options, motion trials). Paths relative to $JOINTFIT_DATA.
SUBJECTS = [
    ("opencap", "opencap_expert1/static1.trc", "opencap", [],
     ["opencap_expert1/walking1.trc", "opencap_expert1/DJ1.trc"]),
    ("gait2392", "opensim_gait2392_subject01/subject01_static.trc", "gait2392", [],
     ["opensim_gait2392_subject01/subject01_walk1.trc"]),
    ("hamner", "opensim_hamner_subject02/subject02_static.trc", "gait2392", [],
     ["opensim_hamner_subject02/subject02_running.trc"]),
    ("jam", "opensim_jam_healthy/static1.trc", "jam", [],
     ["opensim_jam_healthy/overground_17.trc"]),
    ("jam-suggest", "opensim_jam_healthy/static1.trc", "suggest", [],
     ["opensim_jam_healthy/overground_17.trc"]),
    ("biobuddy", "biobuddy_functional_vicon/Test_func_anat.c3d", "suggest", [],
     ["biobuddy_functional_vicon/Test_func_rhip.c3d",
      "biobuddy_functional_vicon/Test_func_rknee.c3d",
      "biobuddy_functional_vicon/Test_func_lhip.c3d"]),
    ("biobuddy-pig", "biobuddy_functional_vicon/anatomical_posture.c3d", "plugin-gait-medial", [],
     ["biobuddy_functional_vicon/Test_func_rankle.c3d"]),
    ("qualisys", "c3d_reader/ezc3d/Qualisys.c3d", "suggest", ["--window", "0.02"],
     ["c3d_reader/ezc3d/Qualisys.c3d"]),
    ("walking2", "c3d_reader/opensim/walking2.c3d", WALK_SET, ["--window", "0.02"],
     ["c3d_reader/opensim/walking2.c3d"]),
    ("walking5", "c3d_reader/opensim/walking5.c3d", "suggest", ["--window", "0.02"],
     ["c3d_reader/opensim/walking5.c3d"]),
]


def run(cmd, timeout=600):
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, "", f"timed out after {timeout} s"
    return out.returncode, out.stdout, out.stderr


def judge(rc, err):
    lines = [l for l in err.splitlines() if l.strip()]
    if rc is None:
        return "TIMEOUT", err
    if rc == 101 or "panicked" in err:
        return "PANIC", err.strip().splitlines()[0] if err.strip() else ""
    errors = [l for l in lines if l.startswith("jointfit: error:")]
    stray = [l for l in lines if not l.startswith("jointfit: ")]
    if rc != 0:
        # One error line; notes and warnings before it are fine, stray lines are not.
        if len(errors) != 1 or stray:
            return f"ERROR ({len(errors)} error, {len(stray)} stray lines)", " / ".join(lines[:3])
        return "refused", errors[0][len("jointfit: error: "):]
    warnings = [l for l in lines if l.startswith("jointfit: warning:")]
    if warnings:
        return f"ok, {len(warnings)} warning(s)", warnings[0][len("jointfit: warning: "):]
    return "ok", ""


def short(text, n=160):
    text = text.replace("|", "\\|").replace("\n", " ")
    return text if len(text) <= n else text[: n - 1] + "…"


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    jointfit = args[0] if args else "jointfit"
    data = os.environ.get("JOINTFIT_DATA", "/work/shared/data")
    tmp = tempfile.mkdtemp(prefix="field-check-")
    rows = []

    def record(rel, cmd_words, rc, out, err, extra=""):
        verdict, detail = judge(rc, err)
        if extra:
            verdict = f"SUSPECT: {extra}; {verdict}"
        shown = " ".join(shlex.quote(w) for w in cmd_words[1:]).replace(data + "/", "$D/")
        shown = shown.replace(tmp + "/", "")
        rows.append((rel, shown, verdict, short(detail)))
        print(f"{rel}: {shown}: {verdict} {short(detail, 100)}", file=sys.stderr)
        return verdict

    files = sorted(
        glob.glob(os.path.join(data, "**", "*.[cC]3[dD]"), recursive=True)
        + glob.glob(os.path.join(data, "**", "*.trc"), recursive=True)
    )
    for path in files:
        rel = os.path.relpath(path, data)
        stem = rel.replace("/", "_").rsplit(".", 1)[0]
        cmd = [jointfit, "inspect", path, "--json"]
        rc, out, err = run(cmd)
        frames = None
        if rc == 0:
            try:
                frames = json.loads(out).get("frames")
            except ValueError:
                pass
        record(rel, cmd, rc, out, err)
        trc = os.path.join(tmp, stem + ".trc")
        cmd = [jointfit, "convert", path, trc]
        rc, out, err = run(cmd)
        extra = ""
        if rc == 0 and isinstance(frames, int):
            with open(trc) as f:
                written = sum(1 for _ in f) - 5
            if written < frames:
                extra = f"wrote {written} of {frames} frames"
        record(rel, cmd, rc, out, err, extra)
        cmd = [jointfit, "markers", "suggest", path, "-o", os.path.join(tmp, stem + "_set.toml")]
        rc, out, err = run(cmd)
        record(rel, cmd, rc, out, err)

    for name, static, markers, opts, motions in SUBJECTS:
        spath = os.path.join(data, static)
        if not os.path.exists(spath):
            print(f"skipped: no data ({static})", file=sys.stderr)
            continue
        if markers == "suggest":
            markers = os.path.join(tmp, name + "_set.toml")
            run([jointfit, "markers", "suggest", spath, "-o", markers])
        subject = os.path.join(tmp, name + ".toml")
        cmd = [jointfit, "personalize", spath, "--markers", markers, "-o", subject] + opts
        rc, out, err = run(cmd)
        if record(static, cmd, rc, out, err) not in ("ok",) and rc != 0:
            continue
        for motion in motions:
            mpath = os.path.join(data, motion)
            mstem = name + "_" + os.path.basename(motion).rsplit(".", 1)[0]
            cmd = [jointfit, "check", subject, mpath]
            rc, out, err = run(cmd)
            record(motion, cmd, rc, out, err)
            cmd = [jointfit, "ik", subject, mpath, "-o", os.path.join(tmp, mstem + ".mot"), "--json"]
            rc, out, err = run(cmd)
            extra = ""
            if rc == 0:
                s = json.loads(out)
                solved = s.get("solved_frames")
                rms = s.get("mean_frame_rms_mm")
                if solved == 0:
                    extra = "no frame solved"
                elif isinstance(rms, (int, float)) and rms > 40:
                    extra = f"mean frame RMS {rms:.1f} mm"
            record(motion, cmd, rc, out, err, extra)
            fitted = os.path.join(tmp, mstem + "_fitted.toml")
            cmd = [jointfit, "calibrate", subject, mpath, "-o", fitted, "--json"]
            rc, out, err = run(cmd)
            extra = ""
            if rc == 0:
                s = json.loads(out)
                before, after = s.get("rms_before_mm"), s.get("rms_after_mm")
                if isinstance(before, (int, float)) and isinstance(after, (int, float)):
                    if after > before + 1e-9:
                        extra = f"RMS {before:.2f} -> {after:.2f} mm"
            record(motion, cmd, rc, out, err, extra)
            if rc != 0:
                continue
            cmd = [jointfit, "report", fitted, mpath, "--landmark", subject, "-o",
                   os.path.join(tmp, mstem + "_report")]
            rc, out, err = run(cmd)
            record(motion, cmd, rc, out, err)

    print_tables(rows)
    bad = [r for r in rows if r[2].split(":")[0].split(" ")[0] in ("PANIC", "ERROR", "SUSPECT", "TIMEOUT")]
    print(f"\n{len(rows)} runs; {len(bad)} panics, multi-line errors, timeouts or suspect answers.")


def print_tables(rows):
    """Two Markdown tables: per file, the three reading commands (outcome, and the message
    when it is not a plain ok); then every run of the subject pipelines."""
    readers = {}
    order = []
    pipeline = []
    for file, shown, verdict, detail in rows:
        words = shown.split(" ")
        cmd = words[0] if words[0] != "markers" else "markers suggest"
        if cmd in ("inspect", "convert", "markers suggest"):
            if file not in readers:
                readers[file] = {}
                order.append(file)
            readers[file][cmd] = verdict + (f": {detail}" if detail else "")
        else:
            pipeline.append((file, shown, verdict, detail))
    print("| file | `inspect F --json` | `convert F OUT.trc` | `markers suggest F -o SET.toml` |")
    print("|---|---|---|---|")
    for f in order:
        r = readers[f]
        print(
            f"| {f} | {r.get('inspect', '')} | {r.get('convert', '')} "
            f"| {r.get('markers suggest', '')} |"
        )
    print()
    print("| motion file | command | outcome | first error or warning line |")
    print("|---|---|---|---|")
    for file, shown, verdict, detail in pipeline:
        print(f"| {file} | `{shown}` | {verdict} | {detail} |")


if __name__ == "__main__":
    main()
