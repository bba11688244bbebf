"""jointfit from Python in one page, on data the package makes itself (as `jointfit demo`).

Run:  python examples/python/quickstart.py [OUTPUT_DIR]

1. Synthesize a trial of the built-in right leg whose knee and ankle axes are moved from
   their nominal places ("the patient"), with skin-artifact noise.
2. Calibrate the knee and ankle parameters from the generic model and compare with the truth.
3. Inverse kinematics with the fitted model; save it as TOML and as an OpenSim model.
4. A batch of three "subjects" (sequential here; pass a dask.distributed Client to scale out).
"""

import pathlib
import sys
import tempfile
import warnings

import numpy as np

import jointfit as jf


def make_patient(generic: jf.Model, seed: int, groups=("knee", "ankle")) -> jf.Model:
    """The generic leg with the parameters of `groups` moved (up to 40 % of each bound)."""
    _, moved = jf.synthesize(generic, frames=1, noise_mm=0.0, perturb=0.4, seed=seed)
    names = [n for g in groups for n in generic.groups[g]]
    return generic.with_parameters({n: moved.parameters[n] for n in names})


def main(out: pathlib.Path) -> None:
    generic = jf.Model.load("lower-limb-right")
    patient = make_patient(generic, seed=7)
    # Markers of the patient along hip, knee and ankle motion, 5 mm skin artifact.
    trial, _ = jf.synthesize(patient, motion="all", frames=150, noise_mm=5.0, perturb=0.0, seed=7)
    print(trial, "markers array:", trial.markers.shape)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # short trial: some ankle parameters are flagged
        cal = jf.calibrate(generic, [trial], joints=["knee", "ankle"])
    print(cal)
    print(f"{'parameter':28} {'true':>9} {'fitted':>9} {'95% interval':>22}")
    for name, value in cal.parameters.items():
        k = 1e3 if generic.units[name] == "m" else 180 / np.pi
        iv = cal.intervals[name]
        iv_text = "-" if iv is None else f"[{iv[0] * k:8.2f}, {iv[1] * k:8.2f}]"
        print(f"{name:28} {patient.parameters[name] * k:9.2f} {value * k:9.2f} {iv_text:>22}")
    print(f"(mm or deg) RMS marker distance {cal.rms_before * 1e3:.2f} → {cal.rms_after * 1e3:.2f} mm")

    result = jf.ik(cal.model, trial)
    knee = result.coordinate_names.index("knee_flexion")
    print(f"IK: {int(result.solved.sum())}/{len(result.solved)} frames, mean RMS "
          f"{np.nanmean(result.rms) * 1e3:.2f} mm, knee flexion "
          f"{np.degrees(result.coordinates[:, knee].min()):.0f}..{np.degrees(result.coordinates[:, knee].max()):.0f} deg")

    out.mkdir(parents=True, exist_ok=True)
    cal.model.save(out / "fitted.toml")
    cal.model.save(out / "fitted.osim")
    print("wrote", out / "fitted.toml", "and", out / "fitted.osim")

    jobs = []
    for seed in (1, 2, 3):
        t, _ = jf.synthesize(make_patient(generic, seed, ["knee"]), motion="knee", frames=60,
                             noise_mm=3.0, perturb=0.0, seed=seed)
        jobs.append(jf.Job(model="lower-limb-right", trials=[t], joints=["knee"], name=f"subject{seed}"))
    results = jf.batch(jobs)  # jf.batch(jobs, client=dask.distributed.Client(...)) on a cluster
    for job, r in zip(jobs, results):
        print(job.name, r)


if __name__ == "__main__":
    main(pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else pathlib.Path(tempfile.mkdtemp()))
