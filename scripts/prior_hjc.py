"""The lab's own hip centre in a jointfit model's pelvis frame (held-out criterion (b)).

Some shared trials carry a lab hip-centre estimate as a virtual marker (OpenCap Expert1:
R_HJC/L_HJC, functional; OpenSim's walking2/5.c3d: RHJC/LHJC). Such a marker moves with the
pelvis markers, so per frame it is expressed in the frame the four pelvis markers span and
mapped into the model's pelvis segment frame through the same construction on the model's
pelvis marker positions (the model file's `[[markers]]`):

    origin = mid-ASIS, z = right ASIS - left ASIS, y = z x (mid-ASIS - mid-PSIS), x = y x z;
    h_model = O_m + R_m R_t^T (h_trial - O_t)

(R_t, O_t from the trial's markers in that frame, R_m, O_m from the model's), averaged over
the frames where the marker and the four pelvis markers are present. The mapping is exact
when the pelvis markers are rigid; the per-frame spread is returned with the mean.

Stdlib only (tomllib: Python >= 3.11).
"""
import math
import tomllib


def read_trc(path):
    """({label: [(x, y, z) or None per frame]}, metres per file unit)."""
    with open(path) as f:
        lines = f.read().splitlines()
    head = dict(zip(lines[1].split("\t"), lines[2].split("\t")))
    scale = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}[head.get("Units", "mm").strip()]
    names = [n.strip() for n in lines[3].split("\t")[2:] if n.strip()]
    data = {n: [] for n in names}
    for line in lines[5:]:
        cells = line.split("\t")
        if len(cells) < 2 or not cells[0].strip():
            continue
        for k, n in enumerate(names):
            try:
                p = tuple(float(v) * scale for v in cells[2 + 3 * k: 5 + 3 * k])
                ok = len(p) == 3 and all(math.isfinite(v) for v in p) and any(p)
            except ValueError:
                ok = False
            data[n].append(p if ok else None)
    return data


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def unit(a):
    n = math.sqrt(dot(a, a))
    return tuple(x / n for x in a)


def pelvis_frame(ra, la, rp, lp):
    """(origin, [x, y, z] axes) from the two ASIS and the two PSIS."""
    o = tuple((a + b) / 2 for a, b in zip(ra, la))
    mp = tuple((a + b) / 2 for a, b in zip(rp, lp))
    z = unit(sub(ra, la))
    y = unit(cross(z, sub(o, mp)))
    return o, [cross(y, z), y, z]


def load_model(model_path):
    """{marker: (segment, position in m)}, {parameter: nominal} and the joints of a model TOML."""
    with open(model_path, "rb") as f:
        spec = tomllib.load(f)
    markers = {m["name"]: (m["segment"], tuple(m["position"])) for m in spec.get("markers", [])}
    params = {p["name"]: p["nominal"] for p in spec.get("parameters", [])}
    return markers, params, spec.get("joints", [])


def lab_hjc_in_pelvis(model_path, trial, label, pelvis):
    """Mean position of trial marker `label` in the model's pelvis frame (m, x anterior,
    y superior, z right), its per-frame RMS spread (m) and the frame count, or None when no
    frame has it. `pelvis`: the labels of (right ASIS, left ASIS, right PSIS, left PSIS), in
    the trial and in the model."""
    markers, _, _ = load_model(model_path)
    om, rm = pelvis_frame(*(markers[n][1] for n in pelvis))
    pts = []
    for f, h in enumerate(trial[label]):
        ps = [trial[n][f] for n in pelvis]
        if h is None or any(p is None for p in ps):
            continue
        ot, rt = pelvis_frame(*ps)
        loc = [dot(a, sub(h, ot)) for a in rt]
        pts.append(tuple(om[i] + sum(rm[k][i] * loc[k] for k in range(3)) for i in range(3)))
    if not pts:
        return None
    mean = tuple(sum(p[i] for p in pts) / len(pts) for i in range(3))
    spread = math.sqrt(sum(dot(sub(p, mean), sub(p, mean)) for p in pts) / len(pts))
    return mean, spread, len(pts)


def hip_centre(model_path):
    """The model's hip centre in its pelvis frame (m, x anterior, y superior, z right): the
    hip joint's parent offset, whose lateral parameter a left leg stores with scale -1."""
    _, params, joints = load_model(model_path)
    for j in joints:
        off = j.get("parent_offset", {})
        if off.get("tx") != "hip_pelvis_anterior":
            continue
        out = []
        for k in ("tx", "ty", "tz"):
            v = off[k]
            out.append(params[v] if isinstance(v, str) else v.get("scale", 1.0) * params[v["param"]])
        return tuple(out)
    raise KeyError(f"{model_path}: no joint with the parent offset hip_pelvis_*")
