#!/usr/bin/env python3
"""Held-out criterion (b) by proxy on biobuddy_functional_vicon.

The Vicon functional trials come without a lab hip-centre estimate (the gait trials that have
one are in prior_gait_table.py), so (b) ("no further from the lab's hip centre than the
landmark model was, + 5 mm") is checked against the functional (SCoRE) hip centre of the same
subject: personalize with Bell, personalize with
--functional-hip, calibrate the Bell model on each functional trial and compare distances.

Usage: scripts/prior_functional_check.py JOINTFIT_BINARY DATA_DIR [WORK_DIR] [-- EXTRA ARGS]
EXTRA ARGS go to the default (MAP) calibrate only (e.g. --refine-markers).
"""
import json, math, os, re, subprocess, sys

EXTRA = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ARGV = sys.argv[:sys.argv.index("--")] if "--" in sys.argv else sys.argv
B, D = ARGV[1], os.path.join(ARGV[2], "biobuddy_functional_vicon")
W = ARGV[3] if len(ARGV) > 3 else "/tmp/jointfit-functional-check"
os.makedirs(W, exist_ok=True)
AXES = ("anterior", "superior", "lateral")

def run(args):
    return subprocess.run([B] + args, capture_output=True, text=True)

def nominal(path, name):
    m = re.search(r'name = "%s"\n(?:.*\n){0,3}?nominal = ([-0-9.e]+)' % name, open(path).read())
    return float(m.group(1)) * 1000

print("| side | trial | prior | landmark → SCoRE mm | fit → SCoRE mm | (b) | hip lateral / (a) limit mm | RMS before → after mm (c) |")
print("|---|---|---|---|---|---|---|---|")
for side in ["right", "left"]:
    s = side[0]
    bell, func = os.path.join(W, f"bell-{side}.toml"), os.path.join(W, f"score-{side}.toml")
    base = ["personalize", "--static", f"{D}/Test_func_anat.c3d", "--markers", "plugin-gait-medial",
            "--up=-z", "--side", side]
    for args in [base + ["-o", bell], base + ["--functional-hip", f"{D}/Test_func_{s}hip.c3d", "-o", func]]:
        r = run(args)
        if r.returncode != 0:
            sys.exit(r.stderr)
    score = [nominal(func, f"hip_pelvis_{a}") for a in AXES]
    d0 = math.dist(score, [nominal(bell, f"hip_pelvis_{a}") for a in AXES])
    for trial in [f"Test_func_{s}hip.c3d", f"Test_func_{s}knee.c3d", f"Test_func_{s}ankle.c3d"]:
        for prior in ["model", "none"]:
            r = run(["calibrate", bell, f"{D}/{trial}", "--up=-z", "--prior", prior, "--json",
                     "-o", os.path.join(W, "fit.toml")] + (EXTRA if prior == "model" else []))
            if r.returncode != 0:
                print(f"| {side} | {trial} | {prior} | {d0:.1f} | failed: {r.stderr.strip().splitlines()[-1][:80]} | | | |")
                continue
            j = json.loads(r.stdout)
            p = {q["name"]: q for q in j["parameters"]}
            fit = [p[f"hip_pelvis_{a}"]["fitted"] for a in AXES]
            lim = next(c["limit"] for c in j["plausibility"] if c["check"].startswith("hip centre lateral"))
            d1 = math.dist(score, fit)
            red = 100 * (1 - j["rms_after_mm"] / j["rms_before_mm"])
            print(f"| {side} | {trial} | {prior} | {d0:.1f} | {d1:.1f} | {'ok' if d1 <= d0 + 5 else 'FAIL'} | "
                  f"{fit[2]:.1f} / {lim:.1f} | {j['rms_before_mm']:.2f} → {j['rms_after_mm']:.2f} ({red:.0f} %) |")
