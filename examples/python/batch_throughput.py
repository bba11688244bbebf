"""Throughput of `jointfit.batch` on a Dask LocalCluster with 1 and 2 workers.

Run:  python examples/python/batch_throughput.py [JOBS] [FRAMES]

Makes JOBS synthetic full-leg trials (FRAMES frames, 5 mm skin noise, each subject's
parameters moved from nominal), fits all 27 parameters of each on 1 and then 2 worker
processes, prints jobs per second and checks that both runs equal the sequential one.
Each solve uses every core (rayon) unless RAYON_NUM_THREADS=1 is set: with it, the workers
and not the solver hold the cores. Figures from this machine are in the README.
"""

import sys
import time

from dask.distributed import Client, LocalCluster

import jointfit as jf


def main(n_jobs: int, frames: int) -> None:
    jobs = []
    for seed in range(1, n_jobs + 1):
        trial, _ = jf.synthesize(motion="all", frames=frames, noise_mm=5.0, seed=seed)
        jobs.append(jf.Job(model="lower-limb-right", trials=[trial], name=f"subject{seed}"))
    t0 = time.perf_counter()
    sequential = jf.batch(jobs, progress=False)
    print(f"sequential in this process: {n_jobs / (time.perf_counter() - t0):.2f} jobs/s")
    for workers in (1, 2):
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster, Client(cluster) as client:
            jf.batch(jobs[:workers], client=client, progress=False)  # workers warm
            t0 = time.perf_counter()
            results = jf.batch(jobs, client=client, progress=False)
            seconds = time.perf_counter() - t0
        same = all(a == b for a, b in zip(results, sequential))
        print(f"{workers} worker(s): {n_jobs} jobs in {seconds:.2f} s = "
              f"{n_jobs / seconds:.2f} jobs/s; equal to sequential: {same}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 8,
         int(sys.argv[2]) if len(sys.argv) > 2 else 150)
