#!/usr/bin/env python3
"""Frames solved before/after on every shared trial with gaps.

For each trial and leg: personalize a subject model (from the trial's own static trial when
the lab has one, else from the stillest complete stretch of the walk itself: `personalize
--static WALK --window W`, which picks the window of least marker motion among the frames
where every landmark is present), then count, per frame, from the presence of the model's
markers (the trial as `jointfit convert` writes it, so presence is what `ik` sees):

* old rule: every segment with markers has at least 3 present (the per-segment count that
  `ik` used before the chain-rank rule);
* determined: pelvis >= 2, thigh >= 2, shank >= 1, foot >= 2 present (the held-out
  condition's definition of frames whose coordinates the present markers determine);

and runs `jointfit ik --json` three times: as is (the chain-rank rule), with
`--fill-gaps N` (gaps of at most 0.5 s filled, the longest the checks offer to fill), and with `--hold-undetermined`. Prints a
Markdown table (the one in notebook/frames_solved.md) and, per run, the share of determined
frames that were solved.

Usage (stdlib only):
    JOINTFIT_DATA=/work/shared/data python3 scripts/frames_table.py [path/to/jointfit]
"""

import json
import math
import os
import subprocess
import sys
import tempfile
import tomllib

HERE = os.path.dirname(os.path.abspath(__file__))
WALK_SET = os.path.join(HERE, "markersets", "opensim_test_walks.toml")

# (trial relative to $JOINTFIT_DATA, marker set (a preset, a file, or "suggest": what
# `jointfit markers suggest` proposes from the trial), static trial or None: the trial itself)
TRIALS = [
    ("c3d_reader/ezc3d/Qualisys.c3d", "suggest", None),
    ("c3d_reader/btk/Gait.c3d", "suggest", None),
    ("c3d_reader/opensim/walking2.c3d", WALK_SET, None),
    ("c3d_reader/opensim/walking5.c3d", WALK_SET, None),
    ("trc_reader/opensim/dataWithBlanksForMissingMarkers.trc", WALK_SET, None),
    (
        "opensim_hamner_subject02/subject02_running.trc",
        "gait2392",
        "opensim_hamner_subject02/subject02_static.trc",
    ),
]
SEGMENTS = ["pelvis", "thigh", "shank", "foot"]
DETERMINED = {"pelvis": 2, "thigh": 2, "shank": 1, "foot": 2}


def run(cmd):
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: {out.stderr.strip()}")
    return out.stdout


def presence(trc_path):
    """{file frame: set of present labels} of a TRC written by `jointfit convert`."""
    with open(trc_path) as f:
        lines = f.read().splitlines()
    labels = lines[3].split("\t")[2:]
    names = [l for l in labels if l.strip()]
    frames = {}
    for line in lines[5:]:
        cells = line.split("\t")
        if len(cells) < 2 or not cells[0].strip():
            continue
        frame = int(float(cells[0]))
        here = set()
        for k, name in enumerate(names):
            xyz = cells[2 + 3 * k : 5 + 3 * k]
            try:
                if len(xyz) == 3 and all(math.isfinite(float(v)) for v in xyz):
                    here.add(name)
            except ValueError:
                pass
        frames[frame] = here
    return frames


def solved_frames(summary, all_frames):
    unsolved = set()
    for r in summary["unsolved"]:
        unsolved.update(range(r["first_frame"], r["last_frame"] + 1))
    return {f for f in all_frames if f not in unsolved}


def main():
    jointfit = sys.argv[1] if len(sys.argv) > 1 else "jointfit"
    data = os.environ.get("JOINTFIT_DATA", "/work/shared/data")
    tmp = tempfile.mkdtemp(prefix="frames-table-")
    rows = []
    totals = {}
    for rel, markers, static in TRIALS:
        path = os.path.join(data, rel)
        if not os.path.exists(path):
            print(f"skipped: no data ({rel})", file=sys.stderr)
            continue
        stem = os.path.basename(rel).rsplit(".", 1)[0]
        if markers == "suggest":
            markers = os.path.join(tmp, stem + "_set.toml")
            run([jointfit, "markers", "suggest", path, "-o", markers])
        trc = os.path.join(tmp, stem + ".trc")
        run([jointfit, "convert", path, trc])
        present = presence(trc)
        for side in ["right", "left"]:
            subject = os.path.join(tmp, f"{stem}_{side}.toml")
            cmd = [jointfit, "personalize", "--markers", markers, "--side", side]
            cmd += ["-o", subject]
            if static is None:
                cmd += ["--static", path, "--window", "0.02"]
            else:
                cmd += ["--static", os.path.join(data, static)]
            run(cmd)
            with open(subject, "rb") as f:
                spec = tomllib.load(f)
            by_segment = {s: [] for s in SEGMENTS}
            for m in spec["markers"]:
                by_segment.setdefault(m["segment"], []).append(m["name"])

            def count(frame, seg):
                return sum(1 for n in by_segment[seg] if n in present[frame])

            frames = sorted(present)
            old = [f for f in frames if all(count(f, s) >= 3 for s in SEGMENTS)]
            determined = {
                f for f in frames if all(count(f, s) >= k for s, k in DETERMINED.items())
            }
            rate_frames = max(1, round(0.5 * rate_of(trc)))
            runs = {}
            for label, extra in [
                ("chain", []),
                ("fill", ["--fill-gaps", str(rate_frames)]),
                ("hold", ["--hold-undetermined"]),
            ]:
                mot = os.path.join(tmp, f"{stem}_{side}_{label}.mot")
                out = run([jointfit, "ik", subject, path, "-o", mot, "--json"] + extra)
                runs[label] = solved_frames(json.loads(out), frames)
            row = {
                "trial": rel,
                "side": side,
                "frames": len(frames),
                "old": len(old),
                "determined": len(determined),
                "chain": len(runs["chain"]),
                "chain_of_determined": len(runs["chain"] & determined),
                "fill": len(runs["fill"]),
                "fill_n": rate_frames,
                "hold": len(runs["hold"]),
            }
            rows.append(row)
            for k in ["frames", "old", "determined", "chain", "chain_of_determined"]:
                totals[k] = totals.get(k, 0) + row[k]
    print(
        "| trial | leg | frames | old rule (>= 3 per segment) | determined (2/2/1/2) "
        "| solved now (chain rank) | of the determined | --fill-gaps N (N) "
        "| --hold-undetermined |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        share = 100.0 * r["chain_of_determined"] / max(1, r["determined"])
        print(
            f"| {r['trial']} | {r['side']} | {r['frames']} | {r['old']} | {r['determined']} "
            f"| {r['chain']} | {r['chain_of_determined']} ({share:.1f} %) "
            f"| {r['fill']} ({r['fill_n']}) | {r['hold']} |"
        )
    if totals:
        share = 100.0 * totals["chain_of_determined"] / max(1, totals["determined"])
        print(
            f"\nall: {totals['frames']} frames, old rule {totals['old']}, determined "
            f"{totals['determined']}, solved now {totals['chain']}, of the determined "
            f"{totals['chain_of_determined']} ({share:.1f} %)"
        )


def rate_of(trc_path):
    with open(trc_path) as f:
        lines = f.read().splitlines()
    keys = lines[1].split("\t")
    values = lines[2].split("\t")
    return float(values[keys.index("DataRate")])


if __name__ == "__main__":
    main()
