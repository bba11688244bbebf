"""One calibration pipeline behind every front end: the command line's `calibrate`, its
`batch` and Python's `calibrate` fit the same parameters and reach the same verdict from the
same inputs, and Python calibrates an `.osim` given by path as the command line does."""

import json
import warnings

import jointfit as jf


def _same_parameters(a: jf.Model, b: jf.Model):
    pa, pb = a.parameters, b.parameters
    assert list(pa) == list(pb)
    diff = {k: (pa[k], pb[k]) for k in pa if pa[k] != pb[k]}
    assert not diff, f"differ: {diff}"


def _quiet_calibrate(*args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return jf.calibrate(*args, **kwargs)


def test_cli_batch_and_python_agree_on_a_real_walk(data_dir, run_cli, tmp_path):
    d = data_dir / "opensim_gait2392_subject01"
    subject, walk = tmp_path / "subject.toml", d / "subject01_walk1.trc"
    code, _, err = run_cli("personalize", d / "subject01_static.trc", "-o", subject)
    assert code == 0, err
    code, out, err = run_cli("calibrate", subject, walk, "--filter", "6", "-o",
                             tmp_path / "cli.toml", "--json")
    assert code == 0, err
    report = json.loads(out)
    manifest = tmp_path / "jobs.toml"
    manifest.write_text(f'[[job]]\nid = "walk"\nmodel = "{subject}"\ntrials = ["{walk}"]\n'
                        "filter = 6.0\n")
    code, _, err = run_cli("batch", manifest, "-o", tmp_path / "out")
    assert code == 0, err
    row = json.loads((tmp_path / "out" / "results.json").read_text())[0]
    cal = _quiet_calibrate(str(subject), [walk], filter=6.0)
    cli = jf.Model.load(tmp_path / "cli.toml")
    _same_parameters(cal.model, cli)
    _same_parameters(jf.Model.load(tmp_path / "out" / "models" / "walk.toml"), cli)
    assert cal.verdict.level == report["verdict"]["level"] == row["verdict"]
    assert cal.verdict.reasons == report["verdict"]["reasons"] == row["verdict_reasons"]


def test_python_calibrates_an_osim_path_as_the_cli(data_dir, run_cli, tmp_path):
    d = data_dir / "opensim_gait2392_subject01"
    osim, walk = d / "subject01_simbody.osim", d / "subject01_walk1.trc"
    code, _, err = run_cli("calibrate", osim, walk, "--joints", "hip_r,knee_r", "-o",
                           tmp_path / "cli.osim")
    assert code == 0, err
    by_path = _quiet_calibrate(osim, [walk], joints=["hip_r", "knee_r"])
    by_path.model.save(tmp_path / "py.osim")
    assert (tmp_path / "py.osim").read_text() == (tmp_path / "cli.osim").read_text()
    loaded = _quiet_calibrate(jf.Model.load(osim), [walk], joints=["hip_r", "knee_r"])
    assert loaded == by_path
