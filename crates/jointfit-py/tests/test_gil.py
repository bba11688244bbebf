"""The solves release the GIL: while two threads run `calibrate` and `ik`, a third Python
thread keeps running.

The oracle is the interpreter itself: a thread holding the GIL for a whole solve lets no
other Python code run between the two clock readings around the call (at most a tick or two
sneak in at the edges, when the interpreter switches threads just before the call or just
after it returns). So the ticking thread records when it ran, and the test counts its ticks
strictly inside each solve. This asserts *that* Python ran during the solves, not how fast
anything was.
"""

import threading
import time
import warnings

import jointfit as jf

# Ticks that can land inside a solve's clock readings even when the solve holds the GIL:
# a switch just before the call and one just before the closing reading.
EDGE_TICKS = 2


def test_python_runs_while_calibrate_and_ik_solve():
    generic = jf.Model.load("lower-limb-right")
    trial, truth = jf.synthesize(generic, motion="all", frames=400, noise_mm=5.0, seed=3)
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)  # sleeping releases the GIL; solving threads take it back

    spans = {}
    errors = []

    def solve(name, run):
        try:
            t0 = time.perf_counter()
            run()
            spans[name] = (t0, time.perf_counter())
        except BaseException as e:  # reported below, not lost in the thread
            errors.append(e)

    def fit():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            jf.calibrate(generic, [trial], joints="all", starts=2)

    def kinematics():
        for _ in range(3):
            jf.ik(truth, trial)

    ticker = threading.Thread(target=tick)
    ticker.start()
    solvers = [threading.Thread(target=solve, args=a) for a in (("calibrate", fit), ("ik", kinematics))]
    for s in solvers:
        s.start()
    for s in solvers:
        s.join()
    stop.set()
    ticker.join()
    assert not errors, errors
    for name, (t0, t1) in spans.items():
        inside = sum(1 for t in ticks if t0 < t < t1)
        assert inside > EDGE_TICKS, f"{name}: Python ran {inside} times during the solve"
