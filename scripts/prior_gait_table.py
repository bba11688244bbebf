#!/usr/bin/env python3
"""Default (MAP) vs --prior none vs --refine-markers calibrate on the shared gait trials
(the gait table and the held-out check).

Usage: scripts/prior_gait_table.py JOINTFIT_BINARY DATA_DIR [WORK_DIR] [-- EXTRA CALIBRATE ARGS]
(PRIOR_TABLE_ONLY=opencap,opensim-c3d limits the subjects; PRIOR_TABLE_HIP=bell|harrington
chooses personalize's hip regression, default: personalize's own default;
PRIOR_TABLE_SETTINGS=model,none,refine the settings.)
Prints a markdown table per trial, side and setting: hip-centre displacement and lateral
offset against the held-out limit (a) 0.9 x half the inter-ASIS width, (b) the distance of
the landmark model's and of the fitted hip centre from the lab's own hip-centre marker (where
the trial has one; `prior_hjc.py`), pass when the fit is no further than the landmark model
+ 5 mm, knee-axis change, marker RMS before/after and its reduction (c: >= 15 %), the marker
noise sigma that weighed the prior, and the implausible checks. EXTRA ARGS go to every
calibrate (e.g. --marker-prior-sd-mm 15). Stdlib only.
"""
import json, math, os, subprocess, sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from prior_hjc import hip_centre, lab_hjc_in_pelvis, read_trc  # noqa: E402

B, D = sys.argv[1], sys.argv[2]
EXTRA = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ARGV = sys.argv[:sys.argv.index("--")] if "--" in sys.argv else sys.argv
W = ARGV[3] if len(ARGV) > 3 else "/tmp/jointfit-prior-table"
os.makedirs(W, exist_ok=True)
WALK_SET = os.path.join(os.path.dirname(os.path.abspath(__file__)), "markersets",
                        "opensim_test_walks.toml")
OPENCAP_PELVIS = ("r.ASIS", "L.ASIS", "r.PSIS", "L.PSIS")
C3D_PELVIS = ("RASI", "LASI", "RPSI", "LPSI")

# (name, static trial or None: each trial personalized from its own stillest 0.02 s, marker
# set, trials, pelvis labels (right/left ASIS, right/left PSIS), lab hip-centre label per side)
SUBJECTS = [
    ("opencap", "opencap_expert1/static1.trc", "opencap",
     ["walking1.trc", "walking2.trc", "walking3.trc", "walkingTS1.trc", "walkingTO1.trc",
      "walkingTI1.trc", "squats1.trc", "squatsAsym1.trc", "DJ1.trc", "DJ2.trc", "STS1.trc"],
     OPENCAP_PELVIS, {"right": "R_HJC", "left": "L_HJC"}),
    ("gait2392", "opensim_gait2392_subject01/subject01_static.trc", "gait2392",
     ["subject01_walk1.trc"], None, None),
    ("hamner", "opensim_hamner_subject02/subject02_static.trc", "gait2392",
     ["subject02_running.trc"], None, None),
    ("opensim-c3d", None, WALK_SET,
     ["c3d_reader/opensim/walking2.c3d", "c3d_reader/opensim/walking5.c3d"],
     C3D_PELVIS, {"right": "RHJC", "left": "LHJC"}),
]
SETTINGS = [("model", []), ("none", []), ("refine", ["--refine-markers"])]


def run(args):
    r = subprocess.run([B] + args, capture_output=True, text=True)
    return r.stdout if r.returncode == 0 else RuntimeError(r.stderr.strip().splitlines()[-1])


def axis(rx, ry):
    rx, ry = math.radians(rx), math.radians(ry)
    return (math.sin(ry), -math.sin(rx) * math.cos(ry), math.cos(rx) * math.cos(ry))


def angle(a, b):
    d = sum(x * y for x, y in zip(a, b))
    return math.degrees(math.acos(max(-1.0, min(1.0, d))))


def lab_distance(model, trial, label, pelvis):
    """Distance (mm) of the model's hip centre from the lab marker, in the model's pelvis."""
    got = lab_hjc_in_pelvis(model, trial, label, pelvis)
    return None if got is None else math.dist(got[0], hip_centre(model)) * 1e3


def personalize(static, preset, side, out, own_window):
    args = ["personalize", "--static", static, "--markers", preset, "--side", side, "-o", out]
    hip = os.environ.get("PRIOR_TABLE_HIP")
    r = run(args + (["--window", "0.02"] if own_window else []) + (["--hip", hip] if hip else []))
    if isinstance(r, Exception):
        sys.exit(f"failed: {' '.join(args)}\n{r}")


print("| trial | side | setting | σ mm | hip shift mm | hip lateral mm (start → fit) | (a) 0.9·PW/2 mm "
      "| (b) lab HJC mm (landmark → fit) | knee axis change deg (thigh) "
      "| RMS before → after mm (c: lower by) | implausible | prior conflict χ²/dof (τ; * flagged) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
ONLY = os.environ.get("PRIOR_TABLE_ONLY")
for name, static, preset, trials, pelvis, labels in SUBJECTS:
    if ONLY and name not in ONLY.split(","):
        continue
    for side in ["right", "left"]:
        model = os.path.join(W, f"{name}-{side}.toml")
        if static:
            personalize(os.path.join(D, static), preset, side, model, False)
        for t in trials:
            path = os.path.join(D, os.path.dirname(static), t) if static else os.path.join(D, t)
            if not static:
                personalize(path, preset, side, model, True)
            trc = None
            if labels:
                trc_path = path
                if not path.endswith(".trc"):
                    trc_path = os.path.join(W, os.path.basename(path) + ".trc")
                    if isinstance(run(["convert", path, trc_path]), Exception):
                        sys.exit(f"failed: convert {path}")
                trc = read_trc(trc_path)
            short = os.path.basename(t)
            for setting, args in SETTINGS:
                if os.environ.get("PRIOR_TABLE_SETTINGS", setting).find(setting) < 0:
                    continue
                out = os.path.join(W, f"{name}-{side}-{short}-{setting}.toml")
                prior = "none" if setting == "none" else "model"
                rep = run(["calibrate", model, path, "--filter", "6", "--prior", prior,
                           "--json", "-o", out] + args + EXTRA)
                if isinstance(rep, Exception):
                    print(f"| {name} {short} | {side} | {setting} | failed: {rep} |||||||||")
                    continue
                rep = json.loads(rep)
                p = {r["name"]: r for r in rep["parameters"]}
                d = [p[f"hip_pelvis_{a}"]["change"] for a in ("anterior", "superior", "lateral")]
                shift = math.sqrt(sum(x * x for x in d))
                lat = p["hip_pelvis_lateral"]
                ka = angle(axis(p["knee_thigh_frontal"]["start"], p["knee_thigh_transverse"]["start"]),
                           axis(p["knee_thigh_frontal"]["fitted"], p["knee_thigh_transverse"]["fitted"]))
                checks = rep["plausibility"]
                limit = next((c["limit"] for c in checks
                              if c["check"].startswith("hip centre lateral")), float("nan"))
                bad = [c["check"].split(":")[0].split(" (")[0] + f" +{c['value'] - c['limit']:.1f}"
                       for c in checks if not c["ok"]]
                sigma = rep["prior_noise_mm"]
                sig = "-" if sigma is None else f"{sigma:.2f}"
                ok_a = "ok" if lat["fitted"] <= limit else "FAIL"
                b = "-"
                if trc is not None:
                    d0 = lab_distance(model, trc, labels[side], pelvis)
                    d1 = lab_distance(out, trc, labels[side], pelvis)
                    if d0 is not None and d1 is not None:
                        b = f"{d0:.1f} → {d1:.1f} {'ok' if d1 <= d0 + 5 else 'FAIL'}"
                red = 100.0 * (1.0 - rep["rms_after_mm"] / rep["rms_before_mm"])
                conf = ", ".join(
                    f"{c['joint']} {c['chi2'] / max(c['dof'], 1):.1f}/{c['dof']} "
                    f"({c['tau']:.2f}{'*' if c['flagged'] else ''})"
                    for c in rep.get("prior_conflict", [])) or "-"
                print(f"| {name} {short} | {side} | {setting} | {sig} | {shift:.1f} "
                      f"| {lat['start']:.1f} → {lat['fitted']:.1f} | {limit:.1f} {ok_a} | {b} | {ka:.1f} "
                      f"| {rep['rms_before_mm']:.2f} → {rep['rms_after_mm']:.2f} ({red:.0f} %) "
                      f"| {'; '.join(bad) or '-'} | {conf} |", flush=True)
