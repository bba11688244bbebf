"""A notebook session as a script: files → Trial → IK → DataFrame → plot → .mot OpenSim reads.

    python examples/python/notebook_walkthrough.py [OUTPUT_DIR]

Runs on data it makes (a synthetic walk of the built-in leg written as a TRC file, as a lab's
exporter would); with real files, replace the first step by your static and motion trials.
Each step is a notebook cell. pandas is needed; matplotlib draws the plot and OpenSim
(`pip install opensim`) checks the .mot when they are installed.
"""

import pathlib
import sys
import warnings

import jointfit as jf

out = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "walkthrough_out")
out.mkdir(parents=True, exist_ok=True)

# %% 1. Files: a walking trial as TRC and the subject's model (here: made up, with its truth).
trial, subject = jf.synthesize("lower-limb-right", motion="all", frames=200, rate=100.0,
                               noise_mm=4.0, seed=11)
trial.write_trc(out / "walk.trc")
subject.save(out / "subject.toml")

# %% 2. Read them back, as from the lab: Y-up metres, low-pass filtered at 6 Hz.
walk = jf.Trial.read(out / "walk.trc", filter=6.0)
model = jf.Model.load(out / "subject.toml")
print(walk, "|", model)

# %% 3. Calibrate the knee and ankle against the walk; progress as a bar when tqdm is there.
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    cal = jf.calibrate(jf.Model.load("lower-limb-right"), [walk], joints=["knee", "ankle"],
                       progress=True)
if caught:
    print(f"1 JointfitWarning summarizing {len(caught[0].message.details)} notes")
print(cal)
table = cal.to_dataframe()
print(table[["fitted", "ci95_low", "ci95_high", "identifiability"]].to_string())
(out / "calibration.html").write_text(cal._repr_html_())

# %% 4. Inverse kinematics with the fitted model: a DataFrame indexed by time.
ik = jf.ik(cal.model, walk)
angles = ik.to_dataframe(degrees=True)
print(angles[["hip_flexion", "knee_flexion", "ankle_dorsiflexion"]].describe().round(1))
print(f"marker RMS per frame: median {1e3 * float(sorted(ik.rms)[len(ik.rms) // 2]):.1f} mm")

# %% 5. Plot (in a notebook: just `angles.plot(...)`).
try:
    import matplotlib

    matplotlib.use("Agg")
    ax = angles.plot(y=["hip_flexion", "knee_flexion", "ankle_dorsiflexion"])
    ax.set_ylabel("angle (deg)")
    ax.figure.savefig(out / "angles.png", dpi=100)
    print("wrote", out / "angles.png")
except ImportError:
    print("matplotlib not installed: no plot")

# %% 6. The .mot for OpenSim, and the model as an .osim.
ik.write_mot(out / "walk.mot")
cal.model.save(out / "fitted.osim")
try:
    import opensim

    opensim.Logger.removeFileSink()  # no opensim.log in the working folder
    sto = opensim.Storage(str(out / "walk.mot"))
    knee = opensim.ArrayDouble()
    sto.getDataColumn("knee_flexion", knee)
    worst = max(abs(knee.get(i) - angles["knee_flexion"].iloc[i]) for i in range(knee.getSize()))
    print(f"OpenSim reads walk.mot: {sto.getSize()} rows, knee flexion equal to {worst:.1e} deg")
except ImportError:
    print("opensim not installed: walk.mot not checked")
print("wrote", out / "walk.mot", "and", out / "fitted.osim")
