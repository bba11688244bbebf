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

Every bad argument raises :class:`JointfitError` naming the argument and what it accepts;
the warnings of one call come as one :class:`JointfitWarning` (a ``UserWarning``) whose
``details`` lists them all; Ctrl-C (Jupyter's interrupt) stops a fit within a fraction of a
second with ``KeyboardInterrupt``.
"""

import functools as _functools
import os as _os

from . import _jointfit
from ._jointfit import (
    BUILTIN_MODELS,
    MARKER_SET_PRESETS,
    Calibration,
    IkResult,
    JointfitError,
    JointfitWarning,
    Model,
    StreamingIK,
    Trial,
    Verdict,
    __version__,
    ik,
    personalize,
    scale,
    synthesize,
)


_DEFAULTED = {
    "method", "seed", "bootstrap", "threshold_mm", "threshold_deg", "starts",
    "fix_unidentifiable", "prior",
}


@_functools.wraps(_jointfit.calibrate)
def calibrate(model, trials, *args, **options):
    if args:
        raise JointfitError(
            "calibrate takes model and trials by position and its options by name "
            f"(got {len(args)} more positional arguments)"
        )
    if not isinstance(trials, (Trial, str, bytes, _os.PathLike)):
        try:
            trials = list(trials)
        except TypeError:
            pass  # refused with its message by the check below
    # None means the default for every option (the native defaults of the non-optional ones).
    options = {k: v for k, v in options.items() if v is not None or k not in _DEFAULTED}
    _jointfit._check_calibrate(model, trials, **options)
    try:
        return _jointfit.calibrate(model, trials, **options)
    except (TypeError, ValueError, OverflowError) as e:
        if e.__traceback__ is not None and e.__traceback__.tb_next is not None:
            raise  # raised by Python code the fit called (a progress callback)
        raise JointfitError(f"calibrate: {e}") from None


calibrate.__doc__ = (calibrate.__doc__ or "").rstrip() + '''

Every argument is checked first (a bad one raises JointfitError naming it and its range; None
means an option's default). ``progress``: None or False (none), True (a tqdm bar when tqdm is
installed, else lines on stderr) or a callable ``progress(stage, iteration, objective)``
(objective in m²; see ``jointfit._progress``). Ctrl-C raises KeyboardInterrupt within a
fraction of a second and stops the solver; the warnings of the fit come as one
JointfitWarning whose ``details`` lists them (also in ``Calibration.warnings``).'''


from ._batch import Job, batch  # noqa: E402  (Job checks its arguments with calibrate's)

__all__ = [
    "BUILTIN_MODELS",
    "MARKER_SET_PRESETS",
    "Calibration",
    "IkResult",
    "Job",
    "JointfitError",
    "JointfitWarning",
    "Model",
    "StreamingIK",
    "Trial",
    "Verdict",
    "__version__",
    "batch",
    "calibrate",
    "ik",
    "personalize",
    "scale",
    "synthesize",
]
