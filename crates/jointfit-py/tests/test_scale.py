"""`jf.scale`: a generic OpenSim model scaled to a subject, against the command line's
`jointfit scale` on the same inputs (the same pipeline must give the same model, factors
and markers), and against OpenSim 4.6 loading the written model (its total mass is the
requested one, every marker sits where the result says).

Data: the OpenSim gait2392 tutorial (generic model, marker set, static trial) in
$JOINTFIT_DATA; without it (or without the binary, or OpenSim for the last test) the tests
are skipped outside CI.
"""

import json

import pytest

import jointfit as jf

from conftest import cli_error

TUTORIAL = "opensim_gait2392_subject01"
MASS = 72.6


@pytest.fixture(scope="module")
def inputs(data_dir):
    d = data_dir / TUTORIAL
    return {
        "model": d / "gait2392_thelen2003muscle.osim",
        "static": d / "subject01_static.trc",
        "markerset": d / "gait2392_Scale_MarkerSet.xml",
    }


@pytest.fixture(scope="module")
def both(inputs, run_cli, tmp_path_factory):
    """(Python's result, the CLI's JSON report, the CLI's written model text)."""
    out = tmp_path_factory.mktemp("scale")
    py_out = out / "py.osim"
    res = jf.scale(str(inputs["model"]), str(inputs["static"]), markerset=str(inputs["markerset"]),
                   mass=MASS, time_range=(1.0, 2.0), output=str(py_out))
    cli_out = out / "cli.osim"
    code, stdout, stderr = run_cli(
        "scale", inputs["model"], inputs["static"], "--markerset", inputs["markerset"],
        "--mass", MASS, "--time-range", 1, 2, "-o", cli_out, "--json")
    assert code == 0, stderr
    return res, json.loads(stdout), cli_out.read_text(), py_out.read_text()


def test_python_and_the_command_line_write_the_same_model(both):
    res, _, cli_text, py_text = both
    assert res["osim"] == cli_text
    assert py_text == cli_text


def test_python_and_the_command_line_report_the_same_factors_and_markers(both):
    res, report, _, _ = both
    assert res["scale_factors"].keys() == report["scale_factors"].keys()
    for body, f in res["scale_factors"].items():
        assert f == pytest.approx(report["scale_factors"][body], rel=0, abs=1e-12), body
    cli_markers = {m["name"]: m for m in report["markers"]}
    assert len(res["markers"]) == len(cli_markers)
    for m in res["markers"]:
        c = cli_markers[m["name"]]
        assert m["body"] == c["body"]
        assert m["position"] == pytest.approx(c["location"], abs=1e-12)
        assert [1000 * x for x in m["moved"]] == pytest.approx(c["moved_mm"], abs=1e-9)
    assert 1000 * res["rms"] == pytest.approx(report["rms_mm"], abs=1e-9)
    assert res["total_mass"] == pytest.approx(MASS, abs=1e-12)
    groups = {g["name"]: g for g in report["groups"]}
    for g in res["groups"]:
        assert g["factors"] == pytest.approx(groups[g["name"]]["factors"], abs=1e-12)
        assert g["sd"] == pytest.approx(groups[g["name"]]["sd"], abs=1e-12)


def test_the_written_model_loads_in_opensim_with_the_reported_markers(both, tmp_path):
    osim = pytest.importorskip("opensim")
    res, _, _, py_text = both
    path = tmp_path / "subject.osim"
    path.write_text(py_text)
    model = osim.Model(str(path))
    state = model.initSystem()
    assert model.getTotalMass(state) == pytest.approx(MASS, rel=1e-12)
    markers = model.getMarkerSet()
    for m in res["markers"]:
        loc = markers.get(m["name"]).get_location()
        assert [loc[0], loc[1], loc[2]] == pytest.approx(m["position"], abs=1e-12), m["name"]


def test_a_missing_static_trial_is_the_command_lines_error(inputs, run_cli, tmp_path):
    missing = tmp_path / "absent.trc"
    with pytest.raises(jf.JointfitError) as e:
        jf.scale(str(inputs["model"]), str(missing), markerset=str(inputs["markerset"]))
    code, _, stderr = run_cli("scale", inputs["model"], missing, "--markerset",
                              inputs["markerset"], "-o", tmp_path / "x.osim")
    assert code != 0
    assert str(e.value) == cli_error(stderr)
    assert "absent.trc" in str(e.value)


def test_an_unknown_prior_is_refused_by_name(inputs):
    with pytest.raises(jf.JointfitError, match='prior must be "anthropometric" or "none"'):
        jf.scale(str(inputs["model"]), str(inputs["static"]), prior="weak")
