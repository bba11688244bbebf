"""Labelled outputs: IK results as DataFrames with units and as .mot files OpenSim reads,
trials sliced by time and written as TRC, calibrations as parameter tables and HTML.

Oracles: OpenSim 4.6's own `Storage` reader for the .mot (angles in degrees, the trial's
time column); the model's coordinate kinds for the units (pelvis translations in metres,
every joint angle in radians, as the OpenSim model it exports declares); our TRC reader for
the written TRC (through its own parser of the file's text); XML parsing for the HTML.
"""

import math
import pickle
import warnings
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import jointfit as jf

from conftest import missing


@pytest.fixture(scope="module")
def fitted():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        trial, truth = jf.synthesize(frames=60, noise_mm=2.0, seed=4)
        ik = jf.ik(truth, trial)
        cal = jf.calibrate("lower-limb-right", [trial], joints="knee")
    return trial, truth, ik, cal


def test_units_name_every_coordinate(fitted):
    _, truth, ik, _ = fitted
    assert list(ik.units) == ik.coordinate_names == truth.coordinate_names
    for name, unit in ik.units.items():
        assert unit == ("m" if name in ("pelvis_tx", "pelvis_ty", "pelvis_tz") else "rad"), name


def test_dataframe_is_indexed_by_time_with_a_column_per_coordinate(fitted):
    pd = pytest.importorskip("pandas")
    trial, _, ik, _ = fitted
    df = ik.to_dataframe()
    assert isinstance(df, pd.DataFrame)
    assert df.index.name == "time"
    np.testing.assert_array_equal(df.index.to_numpy(), np.array(trial.times))
    assert list(df.columns) == ik.coordinate_names
    np.testing.assert_array_equal(df.to_numpy(), ik.coordinates)
    assert df.attrs["units"] == ik.units
    deg = ik.to_dataframe(degrees=True)
    k = ik.coordinate_names.index("knee_flexion")
    np.testing.assert_allclose(deg["knee_flexion"], np.degrees(ik.coordinates[:, k]), rtol=1e-15)
    np.testing.assert_array_equal(deg["pelvis_ty"], df["pelvis_ty"])
    assert deg.attrs["units"]["knee_flexion"] == "deg"


def test_xarray_when_installed(fitted):
    xr = pytest.importorskip("xarray")
    _, _, ik, _ = fitted
    da = ik.to_xarray()
    assert isinstance(da, xr.DataArray) and da.dims == ("time", "coordinate")
    np.testing.assert_array_equal(da.values, ik.coordinates)


def test_mot_written_by_write_mot_reads_back_in_opensim(fitted, tmp_path):
    try:
        import opensim
    except ImportError:
        missing("opensim (pip install opensim==4.6) for the .mot check")
    opensim.Logger.removeFileSink()  # no opensim.log in the working folder
    trial, _, ik, _ = fitted
    part = trial.between(0.3, 0.9)
    sub = jf.ik("lower-limb-right", part)
    path = tmp_path / "walk.mot"
    sub.write_mot(path)
    sto = opensim.Storage(str(path))
    assert sto.isInDegrees()
    times = opensim.ArrayDouble()
    sto.getTimeColumn(times)
    got_t = np.array([times.get(i) for i in range(times.getSize())])
    np.testing.assert_allclose(got_t, sub.times, rtol=0, atol=1e-12)
    assert got_t[0] == pytest.approx(0.3, abs=1e-12)
    labels = [sto.getColumnLabels().get(i) for i in range(sto.getColumnLabels().getSize())]
    assert labels == ["time"] + sub.coordinate_names
    for k, name in enumerate(sub.coordinate_names):
        col = opensim.ArrayDouble()
        sto.getDataColumn(name, col)
        got = np.array([col.get(i) for i in range(col.getSize())])
        want = sub.coordinates[:, k]
        if sub.units[name] == "rad":
            want = np.degrees(want)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12, err_msg=name)


def test_between_keeps_times_and_frame_numbers(fitted):
    trial, _, _, _ = fitted
    part = trial.between(0.2, 0.5)
    rate = trial.rate
    first = round(0.2 * rate)
    last = round(0.5 * rate)
    assert len(part) == last - first + 1
    assert part.first_frame == trial.first_frame + first
    np.testing.assert_allclose(part.times, np.array(trial.times[first : last + 1]), atol=0)
    np.testing.assert_array_equal(part.markers, trial.markers[first : last + 1])
    assert part.duration == pytest.approx(0.3)
    again = pickle.loads(pickle.dumps(part))
    assert again == part and again.times == part.times


def test_trial_equality_and_copy_semantics(fitted):
    trial, _, _, _ = fitted
    before = trial.markers
    m = trial.markers
    assert m is not before
    m[0, 0, 0] += 1.0  # a copy: the trial does not change
    np.testing.assert_array_equal(trial.markers, before)
    same = jf.Trial.from_arrays(trial.labels, trial.markers, trial.rate, first_frame=trial.first_frame)
    assert same == trial
    changed = jf.Trial.from_arrays(trial.labels, m, trial.rate, first_frame=trial.first_frame)
    assert changed != trial
    assert trial != "not a trial"


def test_write_trc_reads_back(fitted, tmp_path):
    trial, _, _, _ = fitted
    m = trial.markers
    m[5, 2] = np.nan  # a gap survives the round trip
    t = jf.Trial.from_arrays(trial.labels, m, trial.rate, first_frame=3)
    for units, tol in (("mm", 1e-8), ("m", 1e-5)):
        path = tmp_path / f"t_{units}.trc"
        t.write_trc(path, units=units)
        back = jf.Trial.read(path)
        assert back.labels == t.labels and back.rate == t.rate and back.first_frame == 3
        np.testing.assert_allclose(back.markers, t.markers, atol=tol, rtol=0)
        assert np.isnan(back.markers[5, 2]).all()


def test_calibration_table_and_html(fitted):
    pd = pytest.importorskip("pandas")
    _, _, _, cal = fitted
    df = cal.to_dataframe()
    assert isinstance(df, pd.DataFrame) and df.index.name == "parameter"
    assert list(df.index) == list(cal.parameters)
    for name, row in df.iterrows():
        assert row["fitted"] == cal.parameters[name]
        assert row["start"] == cal.start[name]
        ci = cal.intervals[name]
        if ci is None:
            assert math.isnan(row["ci95_low"])
        else:
            assert (row["ci95_low"], row["ci95_high"]) == ci
        assert row["group"] == "knee"
        assert row["unit"] in ("m", "rad")
    html = cal._repr_html_()
    root = ET.fromstring(html)  # well-formed
    text = "".join(root.itertext())
    for name in cal.parameters:
        assert name in text
    assert f"{cal.rms_after * 1e3:.2f} mm" in text


def test_the_verdict_is_in_the_calibration_and_its_html(fitted):
    """`Calibration.verdict` is the command line's verdict: a level of three and its reasons;
    the notebook view shows it."""
    _, _, _, cal = fitted
    v = cal.verdict
    assert v.level in ("ok", "caution", "reject")
    assert all(isinstance(r, str) and r for r in v.reasons)
    assert cal.to_dict()["verdict"]["level"] == v.level
    text = "".join(ET.fromstring(cal._repr_html_()).itertext())
    assert f"verdict: {v.level}" in text
