#!/usr/bin/env python3
"""OpenSim 4.6 as the oracle for jointfit's .osim export (crates/jointfit-io/src/osim.rs).

Usage: osim_check.py MODE < request.json
  fk    {"model": OSIM, "coordinates": [NAME...], "poses": [[VALUE...]...]}
        loads the model (opensim.Model + initSystem), reports its bodies, joints,
        coordinates and markers as OpenSim sees them, and for every pose (values in the
        order of "coordinates", rad or m) the marker positions in ground.
  ik    {"model": OSIM, "trc": TRC, "out_dir": DIR, "weights": {MARKER: W}, "accuracy": A,
         "repeat": N (optional, default 1: times are the best of N runs)}
        runs OpenSim's InverseKinematicsTool over the whole trial (every marker of
        "weights" as an IKMarkerTask with that weight, no filtering) and times tool.run();
        reports its coordinates per frame (rad or m) and the marker distances from the
        trial that OpenSim's own kinematics gives at them. Also times the tool's solver
        alone (InverseKinematicsSolver: assemble, then track frame by frame).
  mot   {"model": OSIM, "mot": MOT, "trc": TRC}
        reads a .mot with opensim.TimeSeriesTable and opensim.Storage, converts degrees
        to radians for rotational coordinates as OpenSim does, and reports the values and
        the marker distances from the trial at them.

  functions {"functions": [{"type": T, "x": [...], "y": [...], "degree": D}...], "at": [X...]}
        builds each OpenSim function (SimmSpline, GCVSpline, PiecewiseLinearFunction) and
        reports its value and first derivative at every X.

The answer is one line "@@" + JSON on stdout (OpenSim logs to the same stream). Marker
distances use the trial markers as OpenSim reads them (TimeSeriesTableVec3, converted to
metres from the file's Units); a marker missing in a frame gives null. A sample of exactly
(0, 0, 0) is missing too, as jointfit reads it (a gap, the convention of C3D and of many TRC
exporters). OpenSim itself takes (0, 0, 0) in a TRC as a position (only blank or NaN fields are
missing), so `ik` runs OpenSim's IK on a copy of the trial with those samples set to NaN
(`gaps_as_nan`): both programs then fit the same observations.
"""
import json
import math
import os
import sys
import time

import opensim as osim


def answer(obj):
    print("@@" + json.dumps(obj))


def vec(v):
    return [v.get(0), v.get(1), v.get(2)]


def load(path):
    model = osim.Model(path)
    state = model.initSystem()
    return model, state


def model_summary(model):
    bodies = [model.getBodySet().get(i).getName() for i in range(model.getBodySet().getSize())]
    joints = []
    for i in range(model.getJointSet().getSize()):
        j = model.getJointSet().get(i)
        joints.append({
            "name": j.getName(),
            "type": j.getConcreteClassName(),
            "parent": j.getParentFrame().findBaseFrame().getName(),
            "child": j.getChildFrame().findBaseFrame().getName(),
            "coordinates": [j.get_coordinates(k).getName() for k in range(j.numCoordinates())],
        })
    coords = []
    cs = model.getCoordinateSet()
    for i in range(cs.getSize()):
        c = cs.get(i)
        mt = c.getMotionType()
        coords.append({
            "name": c.getName(),
            "joint": c.getJoint().getName(),
            "motion_type": {osim.Coordinate.Rotational: "rotational",
                            osim.Coordinate.Translational: "translational"}.get(mt, "coupled"),
            "range": [c.getRangeMin(), c.getRangeMax()],
            "default": c.getDefaultValue(),
            "clamped": c.getDefaultClamped(),
            "locked": c.getDefaultLocked(),
        })
    markers = []
    ms = model.getMarkerSet()
    for i in range(ms.getSize()):
        m = ms.get(i)
        markers.append({
            "name": m.getName(),
            "parent": m.getParentFrame().getName(),
            "location": vec(m.get_location()),
        })
    return {"bodies": bodies, "joints": joints, "coordinates": coords, "markers": markers,
            "forces": model.getForceSet().getSize(), "muscles": model.getMuscles().getSize()}


def set_pose(model, state, names, values):
    cs = model.getCoordinateSet()
    for name, v in zip(names, values):
        cs.get(name).setValue(state, v, False)
    model.realizePosition(state)


def marker_positions(model, state):
    ms = model.getMarkerSet()
    return [vec(ms.get(i).getLocationInGround(state)) for i in range(ms.getSize())]


def fk(req):
    model, state = load(req["model"])
    out = model_summary(model)
    out["positions"] = []
    out["body_poses"] = []
    out["qerr"] = []
    for pose in req["poses"]:
        set_pose(model, state, req["coordinates"], pose)
        out["positions"].append(marker_positions(model, state))
        if req.get("bodies"):
            out["body_poses"].append(body_poses(model, state))
            qerr = state.getQErr()
            out["qerr"].append(max([abs(qerr.get(i)) for i in range(qerr.size())] + [0.0]))
    answer(out)


def body_poses(model, state):
    out = {}
    bs = model.getBodySet()
    for i in range(bs.getSize()):
        b = bs.get(i)
        x = b.getTransformInGround(state)
        r = x.R()
        out[b.getName()] = vec(x.p()) + [r.get(a, c) for a in range(3) for c in range(3)]
    return out


def functions(req):
    out = []
    for spec in req["functions"]:
        kind = spec["type"]
        if kind == "GCVSpline":
            f = osim.GCVSpline()
            f.setDegree(spec["degree"])
        else:
            f = getattr(osim, kind)()
        for a, b in zip(spec["x"], spec["y"]):
            f.addPoint(a, b)
        vals = []
        for t in req["at"]:
            v = osim.Vector(1, t)
            vals.append([f.calcValue(v), f.calcDerivative(osim.StdVectorInt([0]), v)])
        out.append(vals)
    answer({"values": out})


def read_trc(path):
    """Trial markers as OpenSim reads them, in metres: (times, labels, frames of [x,y,z]|None)."""
    t = osim.TimeSeriesTableVec3(path)
    keys = list(t.getTableMetaDataKeys())
    units = t.getTableMetaDataAsString("Units") if "Units" in keys else "m"
    scale = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}[units.strip()]
    labels = list(t.getColumnLabels())
    times = list(t.getIndependentColumn())
    frames = []
    for i in range(t.getNumRows()):
        row = t.getRowAtIndex(i)
        pts = []
        for j in range(len(labels)):
            p = row[j]
            xyz = [p.get(0) * scale, p.get(1) * scale, p.get(2) * scale]
            missing = any(math.isnan(c) for c in xyz) or all(c == 0.0 for c in xyz)
            pts.append(None if missing else xyz)
        frames.append(pts)
    return times, labels, frames


def gaps_as_nan(path, out_dir):
    """The trial with every (0, 0, 0) sample set to NaN, which OpenSim's IK skips (a marker
    with no data in a frame gets no task there). Returns the path to use: `path` itself when
    no sample is (0, 0, 0), else a copy written to `out_dir`."""
    t = osim.TimeSeriesTableVec3(path)
    nan = osim.Vec3(math.nan, math.nan, math.nan)
    changed = 0
    for i in range(t.getNumRows()):
        row = t.updRowAtIndex(i)
        for j in range(t.getNumColumns()):
            p = row[j]
            if p.get(0) == 0.0 and p.get(1) == 0.0 and p.get(2) == 0.0:
                row[j] = nan
                changed += 1
    if changed == 0:
        return path
    out = os.path.join(out_dir, "trial_gaps_as_nan.trc")
    osim.TRCFileAdapter.write(t, out)
    return out


def frame_index(times, t):
    best = min(range(len(times)), key=lambda i: abs(times[i] - t))
    if abs(times[best] - t) > 1e-6:
        raise RuntimeError(f"time {t} is not a frame of the trial")
    return best


def marker_errors(model, state, names, rows, trc):
    """Per row (time, [values]): OpenSim marker-to-trial distances in model marker order."""
    times, labels, frames = trc
    ms = model.getMarkerSet()
    out = []
    for t, values in rows:
        set_pose(model, state, names, values)
        pts = frames[frame_index(times, t)]
        errs = []
        for i in range(ms.getSize()):
            m = ms.get(i)
            target = pts[labels.index(m.getName())] if m.getName() in labels else None
            if target is None:
                errs.append(None)
                continue
            x = vec(m.getLocationInGround(state))
            errs.append(math.sqrt(sum((a - b) ** 2 for a, b in zip(x, target))))
        out.append(errs)
    return out


def table_rows(model, table, in_degrees):
    """Coordinate names and (time, SI values) rows of a coordinates table."""
    labels = list(table.getColumnLabels())
    cs = model.getCoordinateSet()
    names = [n for n in labels if cs.contains(n)]
    cols = [labels.index(n) for n in names]
    rot = [cs.get(n).getMotionType() == osim.Coordinate.Rotational for n in names]
    times = list(table.getIndependentColumn())
    rows = []
    for i in range(table.getNumRows()):
        r = table.getRowAtIndex(i)
        vals = [r[c] for c in cols]
        if in_degrees:
            vals = [math.radians(v) if is_rot else v for v, is_rot in zip(vals, rot)]
        rows.append((times[i], vals))
    return labels, names, rows


def ik(req):
    model, state = load(req["model"])
    trc = read_trc(req["trc"])
    trc_path = gaps_as_nan(req["trc"], req["out_dir"])
    tool = osim.InverseKinematicsTool()
    tool.setModel(model)
    tool.setMarkerDataFileName(trc_path)
    tool.set_accuracy(req["accuracy"])
    tool.setStartTime(trc[0][0])
    tool.setEndTime(trc[0][-1])
    tasks = tool.upd_IKTaskSet()
    for name, w in req["weights"].items():
        task = osim.IKMarkerTask()
        task.setName(name)
        task.setWeight(w)
        task.setApply(True)
        tasks.cloneAndAppend(task)
    out_dir = req["out_dir"]
    mot = os.path.join(out_dir, "opensim_ik.mot")
    tool.setResultsDir(out_dir)
    tool.setOutputMotionFileName(mot)
    tool.set_report_errors(False)
    seconds = math.inf
    for _ in range(req.get("repeat", 1)):  # best of `repeat`: the machine may be busy
        start = time.perf_counter()
        ok = tool.run()
        seconds = min(seconds, time.perf_counter() - start)
        if not ok:
            raise RuntimeError("InverseKinematicsTool.run() returned false")
    table = osim.TimeSeriesTable(mot)
    keys = list(table.getTableMetaDataKeys())
    deg = "inDegrees" in keys and table.getTableMetaDataAsString("inDegrees").strip() == "yes"
    model2, state2 = load(req["model"])
    _, names, rows = table_rows(model2, table, deg)
    solver_seconds, solver_last = min(
        (solver_loop(req, trc_path, trc[0]) for _ in range(req.get("repeat", 1))),
        key=lambda r: r[0])
    answer({
        "seconds": seconds,
        "solver_seconds": solver_seconds,
        "solver_last_q": [solver_last[n] for n in names],
        "frames": len(rows),
        "coordinates": names,
        "times": [t for t, _ in rows],
        "q": [v for _, v in rows],
        "errors": marker_errors(model2, state2, names, rows, trc),
        "markers": [model2.getMarkerSet().get(i).getName()
                    for i in range(model2.getMarkerSet().getSize())],
        "mot": mot,
        "trc_used": trc_path,
    })


def solver_loop(req, trc_path, times):
    """The solver inside the tool, timed alone: InverseKinematicsSolver.assemble on the first
    frame, track on each next one (no file output). Returns (seconds, last frame's q by name)."""
    model, state = load(req["model"])
    weights = osim.SetMarkerWeights()
    for name, w in req["weights"].items():
        weights.cloneAndAppend(osim.MarkerWeight(name, w))
    markers = osim.MarkersReference(trc_path, weights)
    solver = osim.InverseKinematicsSolver(
        model, markers, osim.SimTKArrayCoordinateReference(), math.inf)
    solver.setAccuracy(req["accuracy"])
    start = time.perf_counter()
    state.setTime(times[0])
    solver.assemble(state)
    for t in times[1:]:
        state.setTime(t)
        solver.track(state)
    seconds = time.perf_counter() - start
    cs = model.getCoordinateSet()
    return seconds, {cs.get(i).getName(): cs.get(i).getValue(state) for i in range(cs.getSize())}


def mot(req):
    model, state = load(req["model"])
    table = osim.TimeSeriesTable(req["mot"])
    keys = list(table.getTableMetaDataKeys())
    deg = table.getTableMetaDataAsString("inDegrees").strip() if "inDegrees" in keys else ""
    labels, names, rows = table_rows(model, table, deg == "yes")
    storage = osim.Storage(req["mot"])
    # Storage's own conversion to radians, for a second reading of the same file.
    if storage.isInDegrees():
        model.getSimbodyEngine().convertDegreesToRadians(storage)
    slabels = storage.getColumnLabels()
    slabels = [slabels.get(i) for i in range(slabels.getSize())]
    srows = []
    for i in range(storage.getSize()):
        sv = storage.getStateVector(i)
        d = sv.getData()
        by_label = {slabels[j + 1]: d.get(j) for j in range(d.getSize())}
        srows.append([by_label[n] for n in names])
    answer({
        "labels": labels,
        "inDegrees": deg,
        "coordinates": names,
        "times": [t for t, _ in rows],
        "q": [v for _, v in rows],
        "storage_q": srows,
        "errors": marker_errors(model, state, names, rows, read_trc(req["trc"])),
        "markers": [model.getMarkerSet().get(i).getName()
                    for i in range(model.getMarkerSet().getSize())],
    })


def main(argv):
    osim.Logger.setLevelString("error")
    osim.Logger.removeFileSink()  # no opensim.log in the caller's directory
    if len(argv) != 2 or argv[1] not in ("fk", "ik", "mot", "functions"):
        sys.exit(__doc__)
    req = json.load(sys.stdin)
    {"fk": fk, "ik": ik, "mot": mot, "functions": functions}[argv[1]](req)


if __name__ == "__main__":
    main(sys.argv)
