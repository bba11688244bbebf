"""Trial and Model: reading against ezc3d, arrays in and out, save/load, pickling."""

import pickle

import numpy as np
import pytest

import jointfit as jf


def test_trial_from_arrays_round_trip_and_gaps():
    rng = np.random.default_rng(1)
    m = rng.normal(size=(5, 3, 3))
    m[2, 1, :] = np.nan
    m[3, 0, 1] = np.nan  # one NaN coordinate makes the whole sample missing
    t = jf.Trial.from_arrays(["A", "B", "C"], m, 100.0, first_frame=7)
    assert t.labels == ["A", "B", "C"]
    assert t.rate == 100.0 and t.first_frame == 7 and len(t) == 5
    out = t.markers
    assert out.dtype == np.float64 and out.shape == (5, 3, 3)
    assert np.isnan(out[2, 1]).all() and np.isnan(out[3, 0]).all()
    keep = ~np.isnan(out)
    assert np.array_equal(out[keep], m[keep])
    assert t.times[:2] == [0.0, 0.01]
    t2 = pickle.loads(pickle.dumps(t))
    assert t2.labels == t.labels and np.array_equal(t2.markers, out, equal_nan=True)
    assert t.select(["C", "A"]).labels == ["C", "A"]
    assert t2 == t
    m[4, 2, 0] = np.inf  # infinity is not a gap: refused, naming frame and marker
    with pytest.raises(jf.JointfitError, match="frame 4, marker C: position"):
        jf.Trial.from_arrays(["A", "B", "C"], m, 100.0)


def test_trial_from_arrays_errors():
    with pytest.raises(jf.JointfitError, match=r"2 labels for 3 marker columns"):
        jf.Trial.from_arrays(["A", "B"], np.zeros((4, 3, 3)), 100.0)
    with pytest.raises(jf.JointfitError, match=r"shape \(frames, markers, 3\)"):
        jf.Trial.from_arrays(["A"], np.zeros((4, 1, 2)), 100.0)
    with pytest.raises(jf.JointfitError, match=r'marker label "A" appears twice'):
        jf.Trial.from_arrays(["A", "A"], np.zeros((4, 2, 3)), 100.0)
    with pytest.raises(jf.JointfitError, match="rate must be a finite number greater than 0"):
        jf.Trial.from_arrays(["A"], np.zeros((4, 1, 3)), 0.0)


def test_read_c3d_equals_ezc3d(data_dir):
    import ezc3d  # an oracle of scripts/requirements.txt
    path = data_dir / "biobuddy_functional_vicon" / "Test_func_rknee.c3d"
    t = jf.Trial.read(path)  # up=None: as recorded
    c = ezc3d.c3d(str(path))
    labels = [l.split(":")[-1] for l in c["parameters"]["POINT"]["LABELS"]["value"]]
    assert t.labels == labels[: len(t.labels)]
    assert t.rate == pytest.approx(c["header"]["points"]["frame_rate"])
    pts = c["data"]["points"][:3, : len(t.labels), :].transpose(2, 1, 0) / 1000.0  # mm → m
    ours = t.markers
    both = ~np.isnan(ours) & ~np.isnan(pts)
    assert both.sum() > 0.9 * ours.size
    assert np.max(np.abs(ours[both] - pts[both])) < 1e-9
    # Z-up read rotated to Y-up: the vertical becomes the y axis.
    tz = jf.Trial.read(path, up="z")
    assert np.allclose(tz.markers[..., 1], ours[..., 2], equal_nan=True)


def test_model_load_save_parameters(tmp_path):
    m = jf.Model.load("lower-limb-right")
    p = m.parameters
    assert len(p) == 27 and len(m.coordinate_names) == 12
    assert set(m.groups) == {"hip", "knee", "ankle"}
    lo, hi = m.bounds["knee_thigh_superior"]
    assert lo < p["knee_thigh_superior"] < hi
    assert m.units["knee_thigh_frontal"] == "rad" and m.units["hip_thigh_lateral"] == "m"
    moved = m.with_parameters({"knee_thigh_superior": lo + 0.001})
    assert moved.parameters["knee_thigh_superior"] == lo + 0.001
    moved.save(tmp_path / "m.toml")
    back = jf.Model.load(tmp_path / "m.toml")
    assert back == moved and back.parameters == moved.parameters
    assert pickle.loads(pickle.dumps(moved)) == moved
    moved.save(tmp_path / "m.osim")
    text = (tmp_path / "m.osim").read_text()
    assert "<OpenSimDocument" in text and "CustomJoint" in text
    with pytest.raises(jf.JointfitError, match=r"unknown model file type \(expected .toml or .osim\)"):
        m.save(tmp_path / "m.json")
    with pytest.raises(jf.JointfitError, match="has no parameter"):
        m.with_parameters({"elbow": 1.0})


def test_model_errors_equal_the_cli(tmp_path, run_cli):
    code, _, err = run_cli("model", "show", "no-such-model")
    assert code != 0
    with pytest.raises(jf.JointfitError) as e:
        jf.Model.load("no-such-model")
    from conftest import cli_error

    assert str(e.value).rstrip("\n") == cli_error(err)
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nsegments = 3\n')
    code, _, err = run_cli("model", "show", bad)
    with pytest.raises(jf.JointfitError) as e:
        jf.Model.load(bad)
    assert str(e.value).rstrip("\n") == cli_error(err)
