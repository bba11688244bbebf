"""jointfit: patient-specific joint parameters of leg models from motion capture.

The two-level optimization of Reinbolt et al. (2005), J Biomech 38:621-626,
doi:10.1016/j.jbiomech.2004.03.031, solved with variable projection / a joint sparse
Levenberg-Marquardt in Rust. SI units throughout (metres, radians, seconds); marker arrays
are float64 (frames, markers, 3) with NaN for gaps.

Quick start::

    import jointfit as jf
    trial, truth = jf.synthesize(noise_mm=5, seed=1)       # or jf.Trial.read("walk.c3d", up="z")
    cal = jf.calibrate("lower-limb-right", [trial], joints=["knee"])
    print(cal.parameters, cal.intervals, cal.rms_before, cal.rms_after)
    cal.model.save("subject_fitted.osim")

Many subjects: ``jf.batch([jf.Job(model=..., trials=[...]), ...], client=None)``, or with a
``dask.distributed.Client`` on a workstation or a cluster.
"""

from ._jointfit import (
    BUILTIN_MODELS,
    MARKER_SET_PRESETS,
    Calibration,
    IkResult,
    JointfitError,
    Model,
    Trial,
    __version__,
    calibrate,
    ik,
    personalize,
    scale,
    synthesize,
)
from ._batch import Job, batch

__all__ = [
    "BUILTIN_MODELS",
    "MARKER_SET_PRESETS",
    "Calibration",
    "IkResult",
    "Job",
    "JointfitError",
    "Model",
    "Trial",
    "__version__",
    "batch",
    "calibrate",
    "ik",
    "personalize",
    "scale",
    "synthesize",
]
