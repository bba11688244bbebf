"""The public names: every documented one exists, the type stubs describe exactly what
the native module has, everything public carries a docstring."""

import ast
import inspect
import pathlib

import jointfit as jf
import jointfit._jointfit as native

STUB = pathlib.Path(jf.__file__).with_name("_jointfit.pyi")


def test_issue_names_exist():
    assert callable(jf.Trial.read) and callable(jf.Trial.from_arrays)
    for attr in ("labels", "rate", "markers"):
        assert isinstance(getattr(jf.Trial, attr), property) or hasattr(jf.Trial, attr)
    assert callable(jf.Model.load) and callable(jf.Model.save)
    assert hasattr(jf.Model, "parameters")
    for attr in ("coordinates", "coordinate_names", "rms", "solved"):
        assert hasattr(jf.IkResult, attr)
    for attr in ("model", "parameters", "intervals", "rms_before", "rms_after", "to_dict"):
        assert hasattr(jf.Calibration, attr)
    for f in (jf.personalize, jf.ik, jf.calibrate, jf.batch):
        assert callable(f)
    job = jf.Job(model="lower-limb-right", trials=["walk.c3d"], up=None, joints=None, method="joint")
    assert job.method == "joint"
    assert py_typed().exists()


def py_typed():
    return pathlib.Path(jf.__file__).with_name("py.typed")


def _stub_names():
    tree = ast.parse(STUB.read_text())
    top, members = set(), {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            top.add(node.name)
            members[node.name] = {
                n.name for n in node.body if isinstance(n, ast.FunctionDef)
            }
        elif isinstance(node, ast.FunctionDef):
            top.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            top.add(node.target.id)
    return top, members


def test_stubs_match_the_native_module():
    top, members = _stub_names()
    public = {n for n in dir(native) if not n.startswith("__") or n == "__version__"}
    public -= {"_jointfit"}
    assert top == public, (top ^ public)
    for cls, names in members.items():
        actual = {n for n in vars(getattr(native, cls)) if not n.startswith("_")}
        stubbed = {n for n in names if not n.startswith("_") or n == "__len__"} - {"__len__"}
        assert stubbed == actual, (cls, stubbed ^ actual)


def test_public_api_is_documented():
    for name in jf.__all__:
        obj = getattr(jf, name)
        if inspect.isclass(obj) or callable(obj):
            assert obj.__doc__ and obj.__doc__.strip(), name
    for cls in (jf.Trial, jf.Model, jf.Calibration, jf.IkResult):
        for n, v in vars(cls).items():
            if not n.startswith("_"):
                assert getattr(v, "__doc__", None), f"{cls.__name__}.{n}"
