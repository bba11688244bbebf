"""Batches of calibrations: sequentially in this process, or on a Dask cluster.

A :class:`Job` holds everything one :func:`jointfit.calibrate` call needs; :func:`batch`
runs a list of them and returns the results in job order. Every solve is deterministic, so
the results on a cluster equal the sequential ones bit for bit. A job that fails yields its
:class:`jointfit.JointfitError` (an exception *instance*, not raised) in its place; the
other jobs are unaffected.

On a workstation::

    from dask.distributed import Client, LocalCluster
    with LocalCluster(n_workers=4, threads_per_worker=1) as cluster, Client(cluster) as client:
        results = jf.batch(jobs, client=client)

On a university cluster with SLURM (dask-jobqueue; each worker needs jointfit installed and
the trial files on a shared file system, or Trial objects sent by value)::

    from dask_jobqueue import SLURMCluster
    cluster = SLURMCluster(cores=8, processes=8, memory="16GB", walltime="02:00:00",
                           job_extra_directives=["--partition=compute"])
    cluster.scale(jobs=4)                     # 4 SLURM jobs × 8 workers
    with Client(cluster) as client:
        results = jf.batch(jobs, client=client)

A running scheduler can be given by address instead: ``batch(jobs, client="tcp://host:8786")``.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import warnings
from typing import Any, List, Optional, Sequence, Union

from . import _jointfit
from ._jointfit import Calibration, JointfitError, Model, Trial

PathLike = Union[str, "os.PathLike[str]"]


@dataclasses.dataclass
class Job:
    """One calibration: the arguments of :func:`jointfit.calibrate`.

    ``model`` is a :class:`Model`, a model TOML path or a built-in name; ``trials`` a list of
    :class:`Trial` objects (sent by value) or paths (read where the job runs, so they must be
    reachable from the workers). ``name`` labels the job in progress output.

    The arguments are checked when the job is built, with the limits of
    :func:`jointfit.calibrate` (a bad one raises :class:`JointfitError` there, naming it);
    trial files are read only when the job runs.
    """

    model: Union[Model, PathLike]
    trials: Sequence[Union[Trial, PathLike]]
    up: Optional[str] = None
    joints: Optional[Union[str, Sequence[str]]] = None
    method: str = "joint"
    filter: Optional[float] = None
    seed: int = 1
    bootstrap: int = 0
    threshold_mm: float = 5.0
    threshold_deg: float = 5.0
    starts: int = 1
    fix_unidentifiable: bool = False
    prior: str = "model"
    marker_noise_mm: Optional[float] = None
    max_iter: Optional[int] = None
    name: Optional[str] = None
    accept_rejected: bool = False

    def __post_init__(self) -> None:
        if isinstance(self.trials, (str, bytes, os.PathLike, Trial)):
            self.trials = [self.trials]
        elif not isinstance(self.trials, (list, tuple)):
            try:
                self.trials = list(self.trials)
            except TypeError:
                raise JointfitError(
                    "trials must be a jointfit.Trial, a path or a list of them, "
                    f"not {type(self.trials).__name__}"
                ) from None
        if self.name is not None and not isinstance(self.name, str):
            raise JointfitError(f"name must be None or a str, not {type(self.name).__name__}")
        _jointfit._check_calibrate(self.model, list(self.trials), **self._options())

    def _options(self) -> dict:
        joints = list(self.joints) if isinstance(self.joints, (list, tuple)) else self.joints
        return dict(
            joints=joints,
            method=self.method,
            up=self.up,
            filter=self.filter,
            seed=self.seed,
            bootstrap=self.bootstrap,
            threshold_mm=self.threshold_mm,
            threshold_deg=self.threshold_deg,
            starts=self.starts,
            fix_unidentifiable=self.fix_unidentifiable,
            prior=self.prior,
            marker_noise_mm=self.marker_noise_mm,
            max_iter=self.max_iter,
            accept_rejected=self.accept_rejected,
        )

    def run(self) -> Calibration:
        """Runs the calibration here and now (raises :class:`JointfitError` on failure)."""
        from . import calibrate

        trials = [os.fspath(t) if isinstance(t, os.PathLike) else t for t in self.trials]
        model = os.fspath(self.model) if isinstance(self.model, os.PathLike) else self.model
        return calibrate(model, trials, **self._options())


Result = Union[Calibration, BaseException]


def _run_job(job: Job) -> Result:
    """Runs one job; its failure (any exception but an interrupt) is returned, not raised
    (warnings stay in the result)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return job.run()
    except Exception as e:  # noqa: BLE001  (the job's own failure, whatever it is)
        return e


def _label(job: Job, index: int) -> str:
    return job.name if job.name else f"job {index}"


def _report(done: int, total: int, label: str, result: Result, progress: bool) -> None:
    if not progress:
        return
    status = "ok" if isinstance(result, Calibration) else f"failed: {result}"
    sys.stderr.write(f"jointfit batch: {done}/{total} done ({label}: {status})\n")
    sys.stderr.flush()


def batch(
    jobs: Sequence[Job],
    client: Any = None,
    progress: bool = True,
) -> List[Result]:
    """Runs ``jobs`` and returns their results in job order.

    Each result is a :class:`Calibration`, or, for a job that failed, the exception
    (a :class:`JointfitError` with the command line's message; on a cluster also whatever
    the cluster raised, e.g. a lost worker). With ``client=None`` the jobs run one after the
    other in this process; with a ``dask.distributed.Client`` (or a scheduler address) they
    run on its workers, one task per job. ``progress`` writes one line per finished job to
    stderr.
    """
    try:
        jobs = list(jobs)
    except TypeError:
        raise JointfitError(f"jobs must be a list of jointfit.Job objects, not {type(jobs).__name__}") from None
    if client is not None and not isinstance(client, str) and not hasattr(client, "submit"):
        raise JointfitError(
            "client must be None (run here), a scheduler address or a dask.distributed.Client, "
            f"not {type(client).__name__}"
        )
    for j in jobs:
        if not isinstance(j, Job):
            raise JointfitError(f"batch takes jointfit.Job objects, not {type(j).__name__}")
    if client is None:
        results: List[Result] = []
        for k, job in enumerate(jobs):
            r = _run_job(job)
            results.append(r)
            _report(k + 1, len(jobs), _label(job, k), r, progress)
        return results
    from dask.distributed import Client, as_completed

    own = None
    if isinstance(client, str):
        client = own = Client(client)
    try:
        futures = [client.submit(_run_job, job, pure=False) for job in jobs]
        index = {f.key: k for k, f in enumerate(futures)}
        out: List[Optional[Result]] = [None] * len(jobs)
        for done, fut in enumerate(as_completed(futures), start=1):
            k = index[fut.key]
            try:
                r = fut.result()
            except Exception as e:  # the cluster's own failure (worker lost, ...)
                r = e
            out[k] = r
            _report(done, len(jobs), _label(jobs[k], k), r, progress)
        return [r for r in out]  # type: ignore[misc]
    finally:
        if own is not None:
            own.close()
