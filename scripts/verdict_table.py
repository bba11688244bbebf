#!/usr/bin/env python3
"""The verdict of every default fit of the shared gait trials.

    scripts/verdict_table.py target/release/jointfit /work/shared/data [WORKDIR]

The trials and models of `scripts/prior_gait_table.py` (each dataset's preset, each side;
the OpenSim C3D walks personalized from their own stillest 0.02 s); `calibrate --filter 6
--json` with no other option. Prints a Markdown table: exit status, verdict level, reasons.
"""
import json, os, subprocess, sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
B, D = sys.argv[1], sys.argv[2]
W = sys.argv[3] if len(sys.argv) > 3 else "/tmp/jointfit-verdict-table"
os.makedirs(W, exist_ok=True)
WALK_SET = os.path.join(os.path.dirname(os.path.abspath(__file__)), "markersets",
                        "opensim_test_walks.toml")
SUBJECTS = [
    ("opencap", "opencap_expert1/static1.trc", "opencap",
     ["walking1.trc", "walking2.trc", "walking3.trc", "walkingTS1.trc", "walkingTO1.trc",
      "walkingTI1.trc", "squats1.trc", "squatsAsym1.trc", "DJ1.trc", "DJ2.trc", "STS1.trc"]),
    ("gait2392", "opensim_gait2392_subject01/subject01_static.trc", "gait2392",
     ["subject01_walk1.trc"]),
    ("hamner", "opensim_hamner_subject02/subject02_static.trc", "gait2392",
     ["subject02_running.trc"]),
    ("opensim-c3d", None, WALK_SET,
     ["c3d_reader/opensim/walking2.c3d", "c3d_reader/opensim/walking5.c3d"]),
]


def run(args):
    return subprocess.run([B] + args, capture_output=True, text=True)


def personalize(static, preset, side, out, own_window):
    args = ["personalize", "--static", static, "--markers", preset, "--side", side, "-o", out]
    r = run(args + (["--window", "0.02"] if own_window else []))
    if r.returncode != 0:
        sys.exit(f"failed: {' '.join(args)}\n{r.stderr}")


print("| trial | side | exit | verdict | reasons |")
print("|---|---|---|---|---|")
for name, static, preset, trials in SUBJECTS:
    for side in ["right", "left"]:
        model = os.path.join(W, f"{name}-{side}.toml")
        if static:
            personalize(os.path.join(D, static), preset, side, model, False)
        for t in trials:
            path = os.path.join(D, os.path.dirname(static), t) if static else os.path.join(D, t)
            if not static:
                personalize(path, preset, side, model, True)
            out = os.path.join(W, f"{name}-{side}-{os.path.basename(t)}.toml")
            r = run(["calibrate", model, path, "--filter", "6", "--json", "-o", out])
            try:
                v = json.loads(r.stdout)["verdict"]
                level, reasons = v["level"], "; ".join(v["reasons"]) or "-"
            except (ValueError, KeyError):
                level, reasons = "-", (r.stderr.strip().splitlines() or ["?"])[-1]
            print(f"| {name} {os.path.basename(t)} | {side} | {r.returncode} | {level} | "
                  f"{reasons} |", flush=True)
