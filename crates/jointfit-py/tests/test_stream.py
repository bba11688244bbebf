"""`jf.StreamingIK`: frames fed one at a time give `jf.ik`'s coordinates on the same frames
(bit for bit where `jf.ik` solves them in one warm-started run, within ten step tolerances
after the seeded start of its second chunk), samples rotated from the lab's vertical, and
bad frames refused without disturbing the stream."""

import warnings

import numpy as np
import pytest

import jointfit as jf

# Ten times the IK's step tolerance (1e-8 rad or m).
TOLERANCE = 1e-7


def streamed(model, trial, up="y"):
    s = jf.StreamingIK(model, trial.labels, up=up)
    rows = [s.update(m, time=t) for m, t in zip(trial.markers, trial.times)]
    return s, np.array(rows)


def test_stream_equals_ik_on_a_synthetic_walk():
    model = jf.Model.load("lower-limb-right")
    trial, _ = jf.synthesize(model, motion="all", frames=50, noise_mm=5.0, seed=2)
    result = jf.ik(model, trial)
    s, q = streamed(model, trial)
    assert s.coordinate_names == result.coordinate_names
    assert q.shape == result.coordinates.shape
    # 50 frames: jf.ik solves them as one warm-started run, as the stream does.
    assert np.array_equal(q, result.coordinates)
    assert s.solved and s.status == "converged"
    assert np.array_equal(s.errors, result.errors[-1])


def test_stream_equals_ik_on_walking1(data_dir):
    subject = jf.personalize(data_dir / "opencap_expert1" / "static1.trc", "opencap", side="right")
    trial = jf.Trial.read(data_dir / "opencap_expert1" / "walking1.trc", model=subject)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # markers of the trial the model does not use
        result = jf.ik(subject, trial)
        s, q = streamed(subject, trial)
    assert len(trial) == 143
    ref = result.coordinates
    # jf.ik cuts 143 frames into two chunks and seeds the second at frame 71.
    assert np.array_equal(q[:71], ref[:71])
    assert np.max(np.abs(q - ref)) < TOLERANCE


def test_stream_rotates_from_the_lab_vertical():
    model = jf.Model.load("lower-limb-left")
    trial, _ = jf.synthesize(model, motion="all", frames=40, noise_mm=5.0, seed=4)
    _, ref = streamed(model, trial)
    # The same markers as a Z-up laboratory records them: (x, y, z)_model = (x, z, -y)_lab.
    m = trial.markers
    lab = np.stack([m[..., 0], -m[..., 2], m[..., 1]], axis=-1)
    s = jf.StreamingIK(model, trial.labels, up="z")
    q = np.array([s.update(f) for f in lab])
    assert np.max(np.abs(q - ref)) < 1e-12


def test_unsolvable_and_bad_frames():
    model = jf.Model.load("lower-limb-right")
    trial, _ = jf.synthesize(model, motion="all", frames=10, noise_mm=0.0, seed=1)
    _, ref = streamed(model, trial)
    s = jf.StreamingIK(model, trial.labels, up="y")
    foot = [trial.labels.index(n) for n in ("RHEE", "RTOE", "RMT5")]
    for f, m in enumerate(trial.markers):
        if f == 5:
            gap = m.copy()
            gap[foot] = np.nan
            q = s.update(gap, time=trial.times[f] - 0.001)
            assert np.isnan(q).all() and not s.solved
            assert s.status.startswith("undetermined: ")
            with pytest.raises(jf.JointfitError, match=r"shape \(15, 3\)"):
                s.update(m[:-1], time=trial.times[f])
            with pytest.raises(jf.JointfitError, match="does not follow"):
                s.update(m, time=trial.times[f - 1])
        q = s.update(m, time=trial.times[f])
        # Across the unsolved frame the stream restarts from the last solution, as jf.ik does
        # across a gap: the same minimum within the tolerance.
        assert np.max(np.abs(q - ref[f])) < TOLERANCE
        if f < 5:
            assert np.array_equal(q, ref[f])
    with pytest.raises(jf.JointfitError, match="no label of the feed"):
        jf.StreamingIK(model, ["A", "B"])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        s = jf.StreamingIK(model, [l for l in trial.labels if l != "RTIP"])
    assert s.absent == ["RTIP"]
    assert any("RTIP" in str(w.message) for w in caught)
