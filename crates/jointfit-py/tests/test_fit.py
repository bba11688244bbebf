"""personalize, ik, calibrate: against the command line (bit for bit), known synthetic
truth, and the command line's error messages."""

import pickle
import warnings

import numpy as np
import pytest

import jointfit as jf
from conftest import cli_error


def _same_parameters(a: jf.Model, b: jf.Model):
    pa, pb = a.parameters, b.parameters
    assert list(pa) == list(pb)
    diff = {k: (pa[k], pb[k]) for k in pa if pa[k] != pb[k]}
    assert not diff, f"differ: {diff}"


@pytest.fixture(scope="module")
def opencap(data_dir, run_cli, tmp_path_factory):
    """OpenCap's expert subject: a subject model from the static trial, by the CLI."""
    d = data_dir / "opencap_expert1"
    out = tmp_path_factory.mktemp("opencap")
    subject = out / "subject.toml"
    code, _, err = run_cli("personalize", "--static", d / "static1.trc", "--markers", "opencap",
                           "--side", "right", "-o", subject)
    assert code == 0, err
    return d, out, subject


def test_personalize_equals_cli(opencap):
    d, _, subject = opencap
    ours = jf.personalize(d / "static1.trc", markers="opencap", side="right", name="subject")
    cli = jf.Model.load(subject)
    _same_parameters(ours, cli)
    assert ours.marker_names == cli.marker_names
    # A Trial object gives the same model as its path.
    again = jf.personalize(jf.Trial.read(d / "static1.trc"), markers="opencap", side="right",
                           name="subject")
    _same_parameters(again, cli)


def test_personalize_default_is_both_legs_as_on_the_cli(opencap, run_cli):
    """Without a side, Python and the command line build the same bilateral model; each leg
    matches its one-sided personalization up to the subject's sway between the one-sided
    static window and the common one of both legs (0.5 mm or 0.01 rad, as on the CLI)."""
    d, out, _ = opencap
    both = out / "both.toml"
    code, _, err = run_cli("personalize", "--static", d / "static1.trc", "--markers", "opencap",
                           "-o", both)
    assert code == 0, err
    ours = jf.personalize(d / "static1.trc", markers="opencap", name="both")
    _same_parameters(ours, jf.Model.load(both))
    assert len(ours.parameters) == 54
    for side, s in (("right", "_r"), ("left", "_l")):
        one = jf.personalize(d / "static1.trc", markers="opencap", side=side)
        for name, v in one.parameters.items():
            tol = 5e-4 if one.units[name] == "m" else 1e-2
            assert abs(ours.parameters[name + s] - v) <= tol, name


def test_personalize_one_leg_trial_falls_back_with_a_warning(data_dir):
    trial = jf.Trial.read(data_dir / "opencap_expert1" / "static1.trc")
    keep = [n for n in trial.labels if not n.startswith("L_")]
    with pytest.warns(UserWarning, match="none of the left leg's markers"):
        model = jf.personalize(trial.select(keep), markers="opencap")
    assert len(model.parameters) == 27


@pytest.mark.parametrize(
    "joints,method,filt,trials",
    [
        (["knee"], "joint", None, ["walking1.trc"]),
        (None, "joint", 6.0, ["walking1.trc", "squats1.trc"]),
        ("hip,ankle", "gradient", None, ["walking2.trc"]),
    ],
)
def test_calibrate_equals_cli_bit_for_bit(opencap, run_cli, joints, method, filt, trials):
    d, out, subject = opencap
    fitted = out / f"fitted_{method}_{len(trials)}.toml"
    args = ["calibrate", subject, *[d / t for t in trials], "--method", method, "-o", fitted]
    if joints is not None:
        args += ["--joints", joints if isinstance(joints, str) else ",".join(joints)]
    if filt is not None:
        args += ["--filter", filt]
    code, _, err = run_cli(*args)
    assert code == 0, err
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = jf.calibrate(jf.Model.load(subject), [str(d / t) for t in trials],
                           joints=joints, method=method, filter=filt)
    cli = jf.Model.load(fitted)
    _same_parameters(cal.model, cli)
    # The free parameters reported are the fitted ones; the rest kept their start.
    for name, v in cal.parameters.items():
        assert cli.parameters[name] == v
    assert cal.rms_after <= cal.rms_before
    assert set(cal.intervals) == set(cal.parameters)


# Every calibrate option a user expects, through `calibrate` and through `Job`/`batch`,
# against `jointfit calibrate` with the same options (the subject model has priors).
@pytest.mark.parametrize(
    "kwargs,flags",
    [
        (dict(starts=3, seed=7), ["--starts", "3", "--seed", "7"]),
        (dict(prior="none", fix_unidentifiable=True),
         ["--prior", "none", "--fix-unidentifiable"]),
        (dict(marker_noise_mm=3.0, bootstrap=3, seed=5, threshold_mm=4.0),
         ["--marker-noise-mm", "3", "--bootstrap", "3", "--seed", "5", "--threshold-mm", "4"]),
        (dict(max_iter=2, method="gradient"), ["--max-iter", "2", "--method", "gradient"]),
    ],
)
def test_calibrate_options_equal_cli(opencap, run_cli, kwargs, flags):
    d, out, subject = opencap
    trial = d / "walking1.trc"
    fitted = out / f"fitted_{'_'.join(flags).replace('-', '')}.toml"
    code, _, err = run_cli("calibrate", subject, trial, "--joints", "knee", "--filter", "6",
                           *flags, "-o", fitted, "--accept-unconverged")
    assert code == 0, err
    cli = jf.Model.load(fitted)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = jf.calibrate(jf.Model.load(subject), [str(trial)], joints=["knee"], filter=6.0,
                           **kwargs)
        job = jf.Job(model=str(subject), trials=[str(trial)], joints=["knee"], filter=6.0,
                     **kwargs)
        [batched] = jf.batch([job], progress=False)
    _same_parameters(cal.model, cli)
    _same_parameters(batched.model, cli)
    if "max_iter" in kwargs:
        assert not cal.converged


def test_option_limits_are_the_cli_ones():
    for bad, needle in [(dict(starts=0), "starts"), (dict(starts=1001), "1000"),
                        (dict(bootstrap=2001), "2000"), (dict(max_iter=0), "max_iter"),
                        (dict(marker_noise_mm=float("nan")), "marker_noise_mm"),
                        (dict(prior="flat"), "prior")]:
        with pytest.raises(jf.JointfitError, match=needle):
            jf.calibrate("lower-limb-right", [], **bad)


def test_calibrate_c3d_from_another_lab_equals_cli(data_dir, run_cli, tmp_path):
    """Vicon C3D (Z down-up convention of that lab: up = -z), plugin-gait markers."""
    d = data_dir / "biobuddy_functional_vicon"
    subject, fitted = tmp_path / "bb.toml", tmp_path / "bb_knee.toml"
    code, _, err = run_cli("personalize", "--static", d / "Test_func_anat.c3d", "--markers",
                           "plugin-gait", "--side", "right", "--up=-z", "-o", subject)
    assert code == 0, err
    model = jf.personalize(d / "Test_func_anat.c3d", markers="plugin-gait", side="right", up="-z",
                           name="bb")
    _same_parameters(model, jf.Model.load(subject))
    code, _, err = run_cli("calibrate", subject, d / "Test_func_rknee.c3d", "--up=-z",
                           "--joints", "knee", "-o", fitted)
    assert code == 0, err
    trial = jf.Trial.read(d / "Test_func_rknee.c3d", up="-z")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = jf.calibrate(model, [trial], joints=["knee"])
    _same_parameters(cal.model, jf.Model.load(fitted))


def test_osim_calibration_warns_of_the_joints_the_cli_flags(data_dir, run_cli, tmp_path):
    """The prior-data conflict step on a user's OpenSim model: the flagged joints of the
    command's JSON, one warning line each, in the Python result."""
    import json

    d = data_dir / "opencap_expert1"
    joints = ["hip_r", "walker_knee_r", "hip_l", "walker_knee_l"]
    code, out, err = run_cli("calibrate", d / "hand_scaled.osim", d / "squats1.trc", "--joints",
                             ",".join(joints), "-o", tmp_path / "fit.osim", "--json")
    assert code == 0, err
    flagged = [c["joint"] for c in json.loads(out)["prior_conflict"] if c["flagged"]]
    assert flagged, "squats1 contradicts the hand-scaled right knee (chi2 ~ 49 on 9 dof)"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = jf.calibrate(jf.Model.load(d / "hand_scaled.osim"), [jf.Trial.read(d / "squats1.trc")],
                           joints=joints)
    lines = [w for w in cal.warnings if w.startswith("prior–data conflict at the ")]
    assert sorted(w.split(":")[0].rsplit(" ", 1)[1] for w in lines) == sorted(flagged), lines


def test_calibrate_recovers_synthetic_truth():
    trial, truth = jf.synthesize(motion="knee", frames=60, noise_mm=0.0, perturb=0.3, seed=4)
    # Start from the truth everywhere but the knee, which starts at nominal.
    nominal = jf.Model.load("lower-limb-right").parameters
    start = truth.with_parameters({k: nominal[k] for k in truth.groups["knee"]})
    cal = jf.calibrate(start, trial, joints="knee")
    assert cal.rms_before > 1e-3 and cal.rms_after < 1e-7
    for k, v in cal.parameters.items():
        assert abs(v - truth.parameters[k]) < 1e-6, k
    d = cal.to_dict()
    assert d["method"] == "joint" and len(d["parameters"]) == 9
    assert jf.Model.from_toml(d["model"]) == cal.model
    assert pickle.loads(pickle.dumps(cal)) == cal


def test_noisy_truth_inside_intervals():
    trial, truth = jf.synthesize(motion="knee", frames=100, noise_mm=3.0, perturb=0.3, seed=5)
    nominal = jf.Model.load("lower-limb-right").parameters
    start = truth.with_parameters({k: nominal[k] for k in truth.groups["knee"]})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = jf.calibrate(start, [trial], joints=["knee"])
    inside = sum(lo <= truth.parameters[k] <= hi
                 for k, iv in cal.intervals.items() if iv is not None for lo, hi in [iv])
    assert inside >= 7, cal.intervals  # 95 % intervals: most of the 9 contain the truth


def test_ik_noiseless_is_exact_and_equals_cli(tmp_path, run_cli):
    trial, truth = jf.synthesize(motion="all", frames=50, noise_mm=0.0, seed=3)
    r = jf.ik(truth, trial)
    assert r.coordinates.shape == (50, 12) and r.coordinate_names == truth.coordinate_names
    assert r.solved.all() and r.rms.shape == (50,)
    assert np.max(r.rms) < 1e-8
    assert r.errors.shape == (50, len(truth.marker_names))
    # The command line's IK of a trial it synthesized: the same angles as ours from its .mot
    # (degrees, as many digits as the file keeps).
    jf_trc, truth_toml = tmp_path / "t.trc", tmp_path / "truth.toml"
    code, _, err = run_cli("synth", "lower-limb-right", "--motion", "all", "--frames", 50,
                           "--noise", "skin", "-o", jf_trc, "--truth", truth_toml)
    assert code == 0, err
    truth = jf.Model.load(truth_toml)
    mot = tmp_path / "t.mot"
    code, _, err = run_cli("ik", truth_toml, jf_trc, "-o", mot)
    assert code == 0, err
    lines = mot.read_text().splitlines()
    start = lines.index("endheader") + 1
    header = lines[start].split("\t")
    table = np.array([[float(x) for x in l.split("\t")] for l in lines[start + 1:]])
    ours = jf.ik(truth, jf.Trial.read(jf_trc))
    for k, name in enumerate(ours.coordinate_names):
        col = table[:, header.index(name)]
        v = ours.coordinates[:, k]
        v = np.degrees(v) if not name.endswith(("_tx", "_ty", "_tz")) else v
        assert np.allclose(col, v, atol=1e-9, rtol=0), name


def test_errors_carry_the_cli_messages(opencap, run_cli, tmp_path):
    d, out, subject = opencap
    walk = d / "walking1.trc"
    cases = [
        (["calibrate", subject, walk, "--joints", "elbow", "-o", out / "x.toml"],
         lambda: jf.calibrate(jf.Model.load(subject), [walk], joints=["elbow"])),
        (["calibrate", subject, tmp_path / "missing.trc", "-o", out / "x.toml"],
         lambda: jf.calibrate(str(subject), [str(tmp_path / "missing.trc")])),
        (["calibrate", subject, tmp_path / "walk.xyz", "-o", out / "x.toml"],
         lambda: jf.calibrate(str(subject), [str(tmp_path / "walk.xyz")])),
        (["calibrate", "no-such-model", walk, "-o", out / "x.toml"],
         lambda: jf.calibrate("no-such-model", [walk])),
        (["personalize", "--static", walk, "--markers", "no-such-set", "--side", "right", "-o",
          out / "p.toml"],
         lambda: jf.personalize(walk, markers="no-such-set")),
    ]
    for args, call in cases:
        code, _, err = run_cli(*args)
        assert code != 0
        with pytest.raises(jf.JointfitError) as e:
            call()
        assert str(e.value) == cli_error(err), args


def test_argument_errors():
    t, _ = jf.synthesize(frames=10, noise_mm=0)
    with pytest.raises(jf.JointfitError, match='method must be one of "joint", "gradient", "pso"'):
        jf.calibrate("lower-limb-right", [t], method="newton")
    with pytest.raises(jf.JointfitError, match='up must be "y", "-y", "z", "-z", "x" or "-x"'):
        jf.Trial.read("x.trc", up="w")
    with pytest.raises(jf.JointfitError, match="a trial must be a jointfit.Trial or a path"):
        jf.ik("lower-limb-right", 3)
    with pytest.raises(jf.JointfitError, match='side must be one of "both", "right", "left"'):
        jf.personalize(t, markers="opencap", side="middle")
