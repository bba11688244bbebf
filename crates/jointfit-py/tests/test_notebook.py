"""Notebook use: Ctrl-C stops a fit, progress reaches a callback, one warning per call.

Oracles: the clock and the process's CPU time around a real SIGINT sent to a child
interpreter (the interrupt must arrive within a second, and the solver must stop burning
CPU afterwards); the fit's own result for the progress values (the last reported objective
is the calibration's final cost; an undisturbed fit with progress equals one without, bit
for bit); the calibration's `warnings` for the one summarized warning.
"""

import math
import os
import signal
import subprocess
import sys
import time
import warnings

import pytest

import jointfit as jf

CHILD = r"""
import sys, time, warnings
import jointfit as jf
warnings.simplefilter("ignore")
trial, _ = jf.synthesize(frames=600, noise_mm=5, seed=1)
print("ready", flush=True)
try:
    jf.calibrate("lower-limb-right", [trial], method="pso", starts=50)
    print("finished", flush=True)
except KeyboardInterrupt:
    print("interrupted", flush=True)
    time.sleep(2.0)  # the solver ends its current outer iteration, then unwinds
    c0 = time.process_time()
    time.sleep(2.0)
    print(f"cpu {time.process_time() - c0:.3f}", flush=True)
"""


def test_ctrl_c_stops_a_long_fit_within_a_second():
    p = subprocess.Popen([sys.executable, "-c", CHILD], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "ready"
        time.sleep(1.5)  # the fit is running (it takes minutes)
        sent = time.monotonic()
        p.send_signal(signal.SIGINT)
        line = p.stdout.readline().strip()
        latency = time.monotonic() - sent
        assert line == "interrupted"
        assert latency < 1.0, f"KeyboardInterrupt {latency:.2f} s after SIGINT"
        cpu = float(p.stdout.readline().split()[1])
        # Two seconds of an idle interpreter: a solver still running would use ~2 s of CPU.
        assert cpu < 0.5, f"the solver kept running after the interrupt ({cpu} s CPU in 2 s)"
        assert p.wait(timeout=30) == 0
    finally:
        if p.poll() is None:
            p.kill()
    print(f"Ctrl-C latency {latency * 1e3:.0f} ms")


@pytest.fixture(scope="module")
def trial():
    t, _ = jf.synthesize(frames=60, noise_mm=5, seed=1)
    return t


def test_progress_reports_stages_and_the_objective(trial):
    events = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = jf.calibrate("lower-limb-right", [trial], progress=lambda *e: events.append(e))
        plain = jf.calibrate("lower-limb-right", [trial])
    assert cal == plain
    assert all(isinstance(s, str) and isinstance(i, int) for s, i, _ in events)
    iterations = [(s, i, c) for s, i, c in events if i > 0]
    assert iterations, events
    for s, i, c in iterations:
        assert math.isfinite(c) and c > 0
    # Within a stage the iterations count up from 1 and Levenberg-Marquardt never goes up.
    stages = {}
    for s, i, c in iterations:
        stages.setdefault(s, []).append((i, c))
    for s, seq in stages.items():
        assert [i for i, _ in seq] == list(range(1, len(seq) + 1)), s
        assert all(b <= a for (_, a), (_, b) in zip(seq, seq[1:])), s
    assert iterations[-1][2] == cal.to_dict()["cost_after"]


def test_progress_true_shows_a_bar_and_changes_nothing(trial, capsys):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = jf.calibrate("lower-limb-right", [trial], joints="knee", progress=True)
        b = jf.calibrate("lower-limb-right", [trial], joints="knee", progress=False)
    assert a == b


def test_an_exception_in_the_callback_stops_the_fit(trial):
    class Stop(Exception):
        pass

    def cb(stage, iteration, objective):
        if iteration == 2:
            raise Stop(stage)

    with pytest.raises(Stop):
        jf.calibrate("lower-limb-right", [trial], progress=cb)


def test_the_warnings_of_one_fit_come_as_one_warning(trial):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cal = jf.calibrate("lower-limb-right", [trial])
    ours = [w for w in caught if issubclass(w.category, jf.JointfitWarning)]
    assert len(cal.warnings) > 1
    assert len(ours) == 1 and len(caught) == 1
    w = ours[0]
    assert issubclass(w.category, UserWarning)
    assert w.message.details == cal.warnings
    assert str(w.message).startswith(f"{len(cal.warnings)} warnings; the first: {cal.warnings[0]}")
    assert os.path.basename(w.filename) == os.path.basename(__file__)  # points at the caller
