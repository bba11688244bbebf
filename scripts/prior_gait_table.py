#!/usr/bin/env python3
"""Default (MAP) vs --prior none calibrate on the shared gait trials (issue 12 "must show").

Usage: scripts/prior_gait_table.py JOINTFIT_BINARY DATA_DIR [WORK_DIR] [-- EXTRA CALIBRATE ARGS]
Prints a markdown table per trial, side and prior setting: hip-centre displacement and
lateral offset against the held-out limit (a) 0.9 x half the inter-ASIS width, knee-axis
change, marker RMS before/after and its reduction (c: >= 15 %), the marker noise sigma that
weighed the prior, and the implausible checks.
"""
import json, math, os, subprocess, sys

B, D = sys.argv[1], sys.argv[2]
EXTRA = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ARGV = sys.argv[:sys.argv.index("--")] if "--" in sys.argv else sys.argv
W = ARGV[3] if len(ARGV) > 3 else "/tmp/jointfit-prior-table"
os.makedirs(W, exist_ok=True)

SUBJECTS = [
    ("opencap", "opencap_expert1/static1.trc", "opencap",
     ["walking1.trc", "walking2.trc", "walking3.trc", "squats1.trc"]),
    ("gait2392", "opensim_gait2392_subject01/subject01_static.trc", "gait2392",
     ["subject01_walk1.trc"]),
    ("hamner", "opensim_hamner_subject02/subject02_static.trc", "gait2392",
     ["subject02_running.trc"]),
]

def run(args):
    r = subprocess.run([B] + args, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"failed: {' '.join(args)}\n{r.stderr}")
    return r.stdout

def axis(rx, ry):
    rx, ry = math.radians(rx), math.radians(ry)
    return (math.sin(ry), -math.sin(rx) * math.cos(ry), math.cos(rx) * math.cos(ry))

def angle(a, b):
    d = sum(x * y for x, y in zip(a, b))
    return math.degrees(math.acos(max(-1.0, min(1.0, d))))

print("| trial | side | prior | σ mm | hip shift mm | hip lateral mm (start → fit) | (a) 0.9·PW/2 mm | knee axis change deg (thigh) | RMS before → after mm (c: lower by) | implausible |")
print("|---|---|---|---|---|---|---|---|---|---|")
for name, static, preset, trials in SUBJECTS:
  for side in ["right", "left"]:
    model = os.path.join(W, f"{name}-{side}.toml")
    run(["personalize", "--static", os.path.join(D, static), "--markers", preset,
         "--side", side, "-o", model])
    for t in trials:
        path = os.path.join(D, os.path.dirname(static), t)
        for prior in ["model", "none"]:
            out = os.path.join(W, f"{name}-{side}-{t}-{prior}.toml")
            rep = json.loads(run(["calibrate", model, path, "--filter", "6", "--prior", prior,
                                  "--json", "-o", out] + (EXTRA if prior == "model" else [])))
            p = {r["name"]: r for r in rep["parameters"]}
            d = [p[f"hip_pelvis_{a}"]["change"] for a in ("anterior", "superior", "lateral")]
            shift = math.sqrt(sum(x * x for x in d))
            lat = p["hip_pelvis_lateral"]
            ka = angle(axis(p["knee_thigh_frontal"]["start"], p["knee_thigh_transverse"]["start"]),
                       axis(p["knee_thigh_frontal"]["fitted"], p["knee_thigh_transverse"]["fitted"]))
            checks = rep["plausibility"]
            limit = next((c["limit"] for c in checks if c["check"].startswith("hip centre lateral")), float("nan"))
            bad = [c["check"].split(":")[0].split(" (")[0] + f" +{c['value'] - c['limit']:.1f}"
                   for c in checks if not c["ok"]]
            sigma = rep["prior_noise_mm"]
            sig = "-" if sigma is None else f"{sigma:.2f}"
            ok_a = "ok" if lat["fitted"] <= limit else "FAIL"
            red = 100.0 * (1.0 - rep["rms_after_mm"] / rep["rms_before_mm"])
            print(f"| {name} {t} | {side} | {prior} | {sig} | {shift:.1f} | {lat['start']:.1f} → {lat['fitted']:.1f} | {limit:.1f} {ok_a} | {ka:.1f} | {rep['rms_before_mm']:.2f} → {rep['rms_after_mm']:.2f} ({red:.0f} %) | {'; '.join(bad) or '-'} |")
