#!/usr/bin/env python3
"""The speed ratios on every shared subject with a static and a gait trial: `jointfit bench`
on each (notebook/performance_fit.md, "Any subject").

Usage: bench_subjects.py JOINTFIT DATA [WORKDIR] [--only NAME,NAME] [--fit-only N]

For every subject below it runs
    jointfit bench SUBJECT-OPTIONS --json --long-frames 0 --rss-frames 0 --io-frames 0
(the synthetic long-fit and RSS figures do not depend on the subject) and prints one Markdown
row: frames, markers, free parameters, OpenSim's IK solver time, jointfit's whole-trial IK on
every thread and on one, the ratio OpenSim IK / jointfit IK (goal >= 100), the 27-parameter
fit and the ratio fit / OpenSim IK (goal <= 0.2), and the command. With --fit-only N, each
subject's fit is then run N more times alone (`bench --fit-only N`) and its iterations and
fastest time printed, to tell whether iterations or the cost of one dominate.

Subjects without a static trial (the OpenSim C3D walks) are personalized from the trial's own
stillest 0.02 s first (`personalize --window 0.02`, as scripts/prior_gait_table.py does),
then timed with `bench --model`. Needs JOINTFIT_PYTHON (OpenSim 4.6) for the OpenSim columns.
"""
import json
import os
import subprocess
import sys

ARGS = [a for a in sys.argv[1:] if not a.startswith("--")]
OPTS = sys.argv[1:]
B, D = ARGS[0], ARGS[1]
W = ARGS[2] if len(ARGS) > 2 else "/tmp/jointfit-bench-subjects"
os.makedirs(W, exist_ok=True)
ONLY = OPTS[OPTS.index("--only") + 1].split(",") if "--only" in OPTS else None
FIT_ONLY = int(OPTS[OPTS.index("--fit-only") + 1]) if "--fit-only" in OPTS else 0
WALK_SET = os.path.join(os.path.dirname(os.path.abspath(__file__)), "markersets",
                        "opensim_test_walks.toml")
QUICK = ["--long-frames", "0", "--rss-frames", "0", "--io-frames", "0"]


def d(p):
    return os.path.join(D, p)


def static(stat, trial, markers, side="right"):
    return [], ["--static", d(stat), "--trial", d(trial), "--markers", markers, "--side", side]


def own_window(trial, markers, side="right"):
    """No static trial: personalize from the trial's stillest 0.02 s, then bench --model."""
    out = os.path.join(W, os.path.basename(trial) + f"-{side}.toml")
    setup = ["personalize", "--static", d(trial), "--markers", markers, "--side", side,
             "--window", "0.02", "-o", out]
    return setup, ["--model", out, "--trial", d(trial)]


def osim(model, trial, side="right"):
    return [], ["--model", d(model), "--trial", d(trial), "--side", side]


# (name, (setup command or [], bench options))
SUBJECTS = [
    ("opencap walking1",
     static("opencap_expert1/static1.trc", "opencap_expert1/walking1.trc", "opencap")),
    ("opencap walking1 left",
     static("opencap_expert1/static1.trc", "opencap_expert1/walking1.trc", "opencap", "left")),
    ("gait2392 subject01 walk1",
     static("opensim_gait2392_subject01/subject01_static.trc",
            "opensim_gait2392_subject01/subject01_walk1.trc", "gait2392")),
    ("Hamner subject02 running",
     static("opensim_hamner_subject02/subject02_static.trc",
            "opensim_hamner_subject02/subject02_running.trc", "gait2392")),
    ("JAM healthy overground walk",
     static("opensim_jam_healthy/static1.trc", "opensim_jam_healthy/overground_17.trc", "jam")),
    ("OpenSim C3D walking2",
     own_window("c3d_reader/opensim/walking2.c3d", WALK_SET)),
    ("OpenSim C3D walking5",
     own_window("c3d_reader/opensim/walking5.c3d", WALK_SET)),
    # No gait trial: the functional right-hip trial (circumduction), not a gait.
    ("biobuddy functional right hip (not gait)",
     static("biobuddy_functional_vicon/anatomical_posture.c3d",
            "biobuddy_functional_vicon/Test_func_rhip.c3d", "plugin-gait-medial")),
    ("gait2392 subject01 walk1, .osim",
     osim("opensim_gait2392_subject01/subject01_simbody.osim",
          "opensim_gait2392_subject01/subject01_walk1.trc")),
    ("opencap walking1, hand_scaled.osim",
     osim("opencap_expert1/hand_scaled.osim", "opencap_expert1/walking1.trc")),
]


def run(args):
    r = subprocess.run([B] + args, capture_output=True, text=True)
    if r.returncode != 0:
        lines = r.stderr.strip().splitlines()
        return RuntimeError(lines[-1] if lines else f"exit {r.returncode}")
    return r.stdout


def shown(args):
    here = os.path.dirname(os.path.abspath(__file__))
    return "jointfit " + " ".join(
        a.replace(D, "$JOINTFIT_DATA").replace(W, "$W").replace(here, "scripts") for a in args)


print("| subject | frames | markers | free p | OpenSim IK ms | jointfit IK ms (2 thr / 1) "
      "| OpenSim/jointfit IK (2 thr / 1) | fit ms | fit / OpenSim IK | command |")
print("|---|---|---|---|---|---|---|---|---|---|")
fits = []
for name, (setup, options) in SUBJECTS:
    if ONLY and not any(o in name for o in ONLY):
        continue
    if setup:
        r = run(setup)
        if isinstance(r, Exception):
            print(f"| {name} | setup failed: {r} |||||||| `{shown(setup)}` |")
            continue
    out = run(["bench"] + options + ["--json"] + QUICK)
    cmd = f"`{shown(['bench'] + options)}`"
    if setup:
        cmd = f"`{shown(setup)}`; " + cmd
    if isinstance(out, Exception):
        print(f"| {name} | failed: {out} |||||||| {cmd} |")
        continue
    v = json.loads(out)
    frames = v["frames"]
    ik2 = v["ik_trial_us_per_frame"] * frames / 1e3
    ik1 = v["ik_trial_1_thread_us_per_frame"] * frames / 1e3
    os_ms = v["opensim"]["solver_ms"] if v.get("opensim") else None
    ratio = (f"{v['opensim_ik_over_jointfit_ik']:.0f} / "
             f"{v['opensim_ik_over_jointfit_ik_1_thread']:.0f}") if os_ms else "n/a"
    fit = f"{v['fit_over_opensim_ik']:.3f}" if os_ms else "n/a"
    os_txt = f"{os_ms:.0f}" if os_ms else "n/a"
    print(f"| {name} | {frames} | {v['markers']} | {v['parameters']} | {os_txt} "
          f"| {ik2:.2f} / {ik1:.2f} | {ratio} | {v['joint_27_ms']:.0f} | {fit} | {cmd} |",
          flush=True)
    fits.append((name, options))

if FIT_ONLY:
    print()
    print("| subject | fit iterations (all starts) | fastest fit ms | ms per iteration |")
    print("|---|---|---|---|")
    for name, options in fits:
        out = run(["bench"] + options + ["--fit-only", str(FIT_ONLY)])
        if isinstance(out, Exception):
            print(f"| {name} | failed: {out} |||")
            continue
        line = next(l for l in out.splitlines() if l.startswith("calibrate 27, joint:"))
        its = line.split("(")[1].split(" iterations")[0]
        starts = line.split("all starts ")[1].split(",")[0]
        best = float(out.splitlines()[-1].split(": ")[1].split(" ms")[0])
        print(f"| {name} | {its} ({starts}) | {best:.0f} | {best / int(starts):.1f} |",
              flush=True)
