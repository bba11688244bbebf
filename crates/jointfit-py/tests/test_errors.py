"""Bad calls: every one raises jointfit.JointfitError, promptly, naming the argument and
what it accepts (the command line's limits: crates/jointfit-cli/src/validate.rs and
FitOptions::check in crates/jointfit-app/src/fit.rs).

The oracle is the documented contract: the exception type, the argument's name and range in
the message, and that nothing was computed (each call returns within a second, including
those whose argument would allocate hundreds of gigabytes if it were accepted).
"""

import math
import time
import warnings

import numpy as np
import pytest

import jointfit as jf

NAN = float("nan")


@pytest.fixture(scope="module")
def data():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        trial, model = jf.synthesize(frames=20, noise_mm=0, seed=2)
    return trial, model


def _inf_markers(trial):
    m = trial.markers
    m[3, 5, 1] = np.inf
    return m


# (name, call(trial, model), text the message must contain)
BAD_CALLS = [
    ("synthesize seed=-1", lambda t, m: jf.synthesize(seed=-1),
     "seed must be a whole number from 0 to 18446744073709551615 (got -1)"),
    ("synthesize frames=-5", lambda t, m: jf.synthesize(frames=-5),
     "frames must be a whole number from 1 to 100000 (got -5)"),
    ("synthesize frames=10**10", lambda t, m: jf.synthesize(frames=10**10),
     "frames must be a whole number from 1 to 100000"),
    ("synthesize frames=0", lambda t, m: jf.synthesize(frames=0), "frames must be"),
    ("synthesize frames=2.5", lambda t, m: jf.synthesize(frames=2.5), "frames must be a whole number"),
    ("synthesize noise_mm=NaN", lambda t, m: jf.synthesize(noise_mm=NAN),
     "noise_mm must be a finite number from 0 to 1000 mm"),
    ("synthesize rate=1e9", lambda t, m: jf.synthesize(rate=1e9),
     "rate must be a finite number greater than 0 and at most 100000 Hz"),
    ("synthesize rate=0", lambda t, m: jf.synthesize(rate=0), "rate must be"),
    ("synthesize perturb=2", lambda t, m: jf.synthesize(perturb=2), "perturb must be a finite number from 0 to 1"),
    ("synthesize motion='run'", lambda t, m: jf.synthesize(motion="run"), 'motion must be one of "hip"'),
    ("synthesize model=5", lambda t, m: jf.synthesize(model=5), "a model must be a jointfit.Model"),
    ("calibrate seed=-1", lambda t, m: jf.calibrate(m, t, seed=-1), "seed must be a whole number from 0"),
    ("calibrate starts=-1", lambda t, m: jf.calibrate(m, t, starts=-1), "starts must be a whole number from 1 to 1000"),
    ("calibrate starts=0", lambda t, m: jf.calibrate(m, t, starts=0), "starts must be"),
    ("calibrate one frame", lambda t, m: jf.calibrate(m, jf.Trial.from_arrays(t.labels, t.markers[:1], 50)),
     "1 frame: a calibration needs a motion"),
    ("calibrate a still trial", lambda t, m: jf.calibrate(m, jf.Trial.from_arrays(t.labels, np.repeat(t.markers[:1], 5, axis=0), 50)),
     "a still trial says nothing about the joints"),
    ("calibrate unknown labels", lambda t, m: jf.calibrate(m, jf.Trial.from_arrays([f"x{i}" for i in range(len(t.labels))], t.markers, 50)),
     "none of the model's"),
    ("calibrate filter=1e-9", lambda t, m: jf.calibrate(m, t, filter=1e-9), "filter must be None or a finite cutoff of at least 0.1 Hz"),
    ("calibrate filter=100 above Nyquist", lambda t, m: jf.calibrate(m, t, filter=100), "below the Nyquist frequency"),
    ("calibrate method='newton'", lambda t, m: jf.calibrate(m, t, method="newton"), 'method must be one of "joint", "gradient", "pso"'),
    ("calibrate bootstrap=10**6", lambda t, m: jf.calibrate(m, t, bootstrap=10**6), "bootstrap must be a whole number from 0 to 2000"),
    ("calibrate max_iter=0", lambda t, m: jf.calibrate(m, t, max_iter=0), "max_iter must be a whole number from 1 to 10000"),
    ("calibrate threshold_mm=NaN", lambda t, m: jf.calibrate(m, t, threshold_mm=NAN), "threshold_mm must be a finite number greater than 0"),
    ("calibrate marker_noise_mm=-1", lambda t, m: jf.calibrate(m, t, marker_noise_mm=-1), "marker_noise_mm must be a finite number greater than 0 and at most 1000 mm"),
    ("calibrate prior='flat'", lambda t, m: jf.calibrate(m, t, prior="flat"), 'prior must be one of "model", "none"'),
    ("calibrate joints='elbow'", lambda t, m: jf.calibrate(m, t, joints="elbow"), 'unknown parameter group "elbow"'),
    ("calibrate joints=3", lambda t, m: jf.calibrate(m, t, joints=3), "joints must be a list of strings"),
    ("calibrate trials=[]", lambda t, m: jf.calibrate(m, []), "trials must hold at least one trial"),
    ("calibrate trials=5", lambda t, m: jf.calibrate(m, 5), "trials must be a jointfit.Trial, a path or a list of them"),
    ("calibrate trials=[5]", lambda t, m: jf.calibrate(m, [5]), "a trial must be a jointfit.Trial or a path"),
    ("calibrate model=5", lambda t, m: jf.calibrate(5, t), "a model must be a jointfit.Model"),
    ("calibrate up='w'", lambda t, m: jf.calibrate(m, t, up="w"), 'up must be "y", "-y", "z", "-z", "x" or "-x"'),
    ("calibrate fix_unidentifiable='yes'", lambda t, m: jf.calibrate(m, t, fix_unidentifiable="yes"), "fix_unidentifiable must be True or False"),
    ("calibrate progress=3", lambda t, m: jf.calibrate(m, t, progress=3), "progress must be None, True, False or a callable"),
    ("calibrate unknown keyword", lambda t, m: jf.calibrate(m, t, foo=1), "unexpected keyword argument 'foo'"),
    ("ik filter=1e-9", lambda t, m: jf.ik(m, t, filter=1e-9), "filter must be None or a finite cutoff of at least 0.1 Hz"),
    ("ik trial=None", lambda t, m: jf.ik(m, None), "a trial must be a jointfit.Trial or a path"),
    ("ik missing file", lambda t, m: jf.ik(m, "/nonexistent/walk.c3d"), "cannot read /nonexistent/walk.c3d"),
    ("Trial.from_arrays infinite marker", lambda t, m: jf.Trial.from_arrays(t.labels, _inf_markers(t), 50),
     "frame 3, marker " + "RTHA" + ": position"),
    ("Trial.from_arrays markers='abc'", lambda t, m: jf.Trial.from_arrays(t.labels, "abc", 50), "markers must be an array of real numbers of shape (frames, markers, 3)"),
    ("Trial.from_arrays complex markers", lambda t, m: jf.Trial.from_arrays(t.labels, t.markers.astype(complex), 50), "markers must be an array of real numbers"),
    ("Trial.from_arrays 2-D markers", lambda t, m: jf.Trial.from_arrays(t.labels, t.markers[0], 50), "markers must have shape (frames, markers, 3)"),
    ("Trial.from_arrays rate=NaN", lambda t, m: jf.Trial.from_arrays(t.labels, t.markers, NAN), "rate must be a finite number greater than 0"),
    ("Trial.from_arrays rate=1e9", lambda t, m: jf.Trial.from_arrays(t.labels, t.markers, 1e9), "at most 100000 Hz"),
    ("Trial.from_arrays labels='abc'", lambda t, m: jf.Trial.from_arrays("abc", t.markers, 50), "labels must be a list of strings"),
    ("Trial.from_arrays millimetres as metres", lambda t, m: jf.Trial.from_arrays(t.labels, t.markers * 1e6, 50), "the units or the data are wrong"),
    ("Trial.from_arrays first_frame=2**70", lambda t, m: jf.Trial.from_arrays(t.labels, t.markers, 50, first_frame=2**70), "first_frame must be a whole number"),
    ("Trial.filtered(1e-9)", lambda t, m: t.filtered(1e-9), "cutoff must be None or a finite cutoff of at least 0.1 Hz"),
    ("Trial.filtered('x')", lambda t, m: t.filtered("x"), "cutoff must be"),
    ("Trial.between(1, 0)", lambda t, m: t.between(1, 0), "t1 must not be earlier than t0"),
    ("Trial.between outside", lambda t, m: t.between(100, 200), "no frame between 100 s and 200 s"),
    ("Trial.between(NaN, 1)", lambda t, m: t.between(NAN, 1), "t0 must be a finite time in seconds"),
    ("Trial.select('RASI')", lambda t, m: t.select("RASI"), "labels must be a list of strings"),
    ("Trial.repair(fill_gaps=-1)", lambda t, m: t.repair(fill_gaps=-1), "fill_gaps must be a whole number from 0"),
    ("Trial.read(3)", lambda t, m: jf.Trial.read(3), "path must be a path (str or os.PathLike)"),
    ("Trial.read filter=NaN", lambda t, m: jf.Trial.read("walk.c3d", filter=NAN), "filter must be None or a finite cutoff"),
    ("Trial.write_trc decimals=99", lambda t, m: t.write_trc("x.trc", decimals=99), "decimals must be a whole number from 0 to 15"),
    ("Model.load(3)", lambda t, m: jf.Model.load(3), "path_or_builtin must be a path"),
    ("Model.with_parameters NaN", lambda t, m: m.with_parameters({"hip_pelvis_anterior": NAN}), 'values["hip_pelvis_anterior"] must be a finite number'),
    ("Model.with_parameters list", lambda t, m: m.with_parameters([1, 2]), "values must be a dict"),
    ("personalize markers=3", lambda t, m: jf.personalize(t, 3), "markers must be a marker-set preset"),
    ("personalize window=-1", lambda t, m: jf.personalize(t, "plugin-gait", window=-1), "window must be a finite number greater than 0 and at most 3600 s"),
    ("personalize side='middle'", lambda t, m: jf.personalize(t, "plugin-gait", side="middle"), 'side must be one of "both", "right", "left"'),
    ("Job starts=-1", lambda t, m: jf.Job(model=m, trials=[t], starts=-1), "starts must be a whole number from 1 to 1000"),
    ("Job seed='a'", lambda t, m: jf.Job(model=m, trials=[t], seed="a"), "seed must be a whole number"),
    ("Job trials=5", lambda t, m: jf.Job(model=m, trials=5), "trials must be a jointfit.Trial, a path or a list"),
    ("Job filter=1e-9", lambda t, m: jf.Job(model=m, trials=[t], filter=1e-9), "filter must be None or a finite cutoff"),
    ("IkResult.to_dataframe(degrees='yes')", lambda t, m: jf.ik(m, t).to_dataframe(degrees="yes"), "degrees must be True or False"),
    ("IkResult.write_mot(5)", lambda t, m: jf.ik(m, t).write_mot(5), "path must be a path"),
    ("batch of non-jobs", lambda t, m: jf.batch([1], progress=False), "batch takes jointfit.Job objects"),
    ("batch(5)", lambda t, m: jf.batch(5), "jobs must be a list of jointfit.Job objects"),
    ("batch client=5", lambda t, m: jf.batch([jf.Job(model=m, trials=[t])], client=5), "client must be None"),
    ("Job joints='elbow'", lambda t, m: jf.Job(model=m, trials=[t], joints="elbow"), 'unknown parameter group "elbow"'),
    ("Job joints=['knee', 5]", lambda t, m: jf.Job(model="lower-limb-right", trials=[t], joints=["knee", 5]), "joints must be a list of strings"),
    ("calibrate seed=2**64", lambda t, m: jf.calibrate(m, t, seed=2**64), "seed must be a whole number from 0 to 18446744073709551615"),
    ("calibrate params on a non-.osim model", lambda t, m: jf.calibrate(m, t, params=["x"]), "params selects offset frames of a model loaded from an .osim file"),
    ("Trial.from_arrays ragged lists", lambda t, m: jf.Trial.from_arrays(["A"], [[[1, 2, 3]], [[1, 2]]], 50), "markers must be an array of real numbers"),
    ("Trial.from_arrays times of the wrong length", lambda t, m: jf.Trial.from_arrays(t.labels, t.markers, 50, times=[1, 2]), "times: 2 time stamps for 20 frames"),
    ("Model.with_parameters unknown name", lambda t, m: m.with_parameters({"nope": 0.0}), 'has no parameter "nope"'),
]


@pytest.mark.parametrize("name,call,needle", BAD_CALLS, ids=[c[0] for c in BAD_CALLS])
def test_bad_call_raises_jointfit_error_naming_the_argument(data, name, call, needle):
    trial, model = data
    start = time.monotonic()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(jf.JointfitError) as e:
            call(trial, model)
    assert needle in str(e.value), str(e.value)
    assert "\n" not in str(e.value)
    assert time.monotonic() - start < 5.0, name


def test_at_least_thirty_bad_calls_are_listed():
    assert len(BAD_CALLS) >= 30


def test_float32_int_and_list_markers_are_converted(data):
    trial, _ = data
    m = trial.markers
    exact = jf.Trial.from_arrays(trial.labels, m, trial.rate, first_frame=trial.first_frame)
    assert exact == trial
    f32 = jf.Trial.from_arrays(trial.labels, m.astype(np.float32), trial.rate)
    np.testing.assert_array_equal(f32.markers, m.astype(np.float32).astype(np.float64))
    mm = np.round(m * 1000)
    ints = jf.Trial.from_arrays(trial.labels, mm.astype(np.int64), trial.rate)
    np.testing.assert_array_equal(ints.markers, mm)
    listed = jf.Trial.from_arrays(trial.labels, m.tolist(), trial.rate, first_frame=1)
    assert listed == trial
    assert jf.Trial.from_arrays(trial.labels, m.tolist(), trial.rate) != trial  # first frame 0


def test_a_nan_coordinate_makes_the_whole_sample_missing(data):
    trial, _ = data
    m = trial.markers
    m[2, 4, 0] = np.nan
    t = jf.Trial.from_arrays(trial.labels, m, trial.rate)
    assert np.isnan(t.markers[2, 4]).all()
    assert not np.isnan(t.markers[2, 3]).any()


def test_a_model_without_markers_is_an_error_not_a_panic(data):
    trial, model = data
    text = model.to_toml()
    bare = jf.Model.from_toml(text[: text.index("[[markers]]")])
    assert bare.marker_names == []
    for call in (lambda: jf.synthesize(bare), lambda: jf.ik(bare, trial),
                 lambda: jf.calibrate(bare, trial)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with pytest.raises(jf.JointfitError):
                call()


def test_sequential_batch_keeps_the_other_results_when_one_job_is_bad(data):
    trial, model = data
    good = jf.Job(model=model, trials=[trial], joints="knee", name="good")
    bad = jf.Job(model=model, trials=[trial], joints="knee", name="bad")
    bad.starts = -1  # changed after the job was built: refused when it runs
    other = jf.Job(model=model, trials=[trial], joints="hip", name="other")
    results = jf.batch([good, bad, other], progress=False)
    assert isinstance(results[0], jf.Calibration)
    assert isinstance(results[1], jf.JointfitError)
    assert "starts must be a whole number from 1 to 1000 (got -1)" in str(results[1])
    assert isinstance(results[2], jf.Calibration)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert results[0] == good.run()
        assert results[2] == other.run()


def test_none_means_the_default(data):
    trial, model = data
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = jf.calibrate(model, trial, joints="knee", method=None, seed=None, starts=None)
        b = jf.calibrate(model, trial, joints="knee")
    assert a == b


def test_numpy_scalars_are_accepted_where_numbers_are(data):
    trial, model = data
    t, _ = jf.synthesize(frames=np.int64(12), rate=np.float32(60.0), seed=np.uint8(3), noise_mm=0)
    assert len(t) == 12 and t.rate == 60.0
    assert math.isclose(t.times[1], 1 / 60)
