#!/usr/bin/env python3
"""OpenSim as a test oracle for jointfit-io's TRC and .mot/.sto code.

Usage:
  opensim_oracle.py sto-read FILE...    read each file with opensim.TimeSeriesTable and
                                        opensim.Storage and print what they found
  opensim_oracle.py sto-write DIR       write tables with OpenSim's own writers into DIR and
                                        print the values that were put in
  opensim_oracle.py trc-read FILE...    read each file with opensim.TimeSeriesTableVec3
  opensim_oracle.py ik-setup SETUP MOT  run OpenSim's InverseKinematicsTool from the setup file
                                        SETUP as `opensim-cmd run-tool` does (run it in the
                                        directory the setup's model_file is relative to), its
                                        motion written to MOT instead of output_motion_file, no
                                        marker-error file; prints the frames and the seconds
  opensim_oracle.py objective SETUP MOT...
                                        the weighted IK objective of the setup, per frame of
                                        each motion: OpenSim's own goal (Simbody Assembler),
                                        sum_j w_j |x_j - m_j|^2 / (2 sum_j w_j)
                                        + sum_c w_c (q_c - ref_c)^2 / 2,
                                        with OpenSim's kinematics, its reading of the setup's
                                        task set and marker file, the coordinate references as
                                        populateReferences builds them

Every result line starts with "@@" (OpenSim logs to the same stream) and holds tab-separated
fields; numbers are printed with repr(), which reads back exactly.
"""
import math
import os
import sys

import opensim as osim


def out(*fields):
    print("@@" + "\t".join(str(f) for f in fields))


def num(v):
    return repr(float(v))


def sto_read(paths):
    for path in paths:
        out("FILE", path)
        try:
            t = osim.TimeSeriesTable(path)
            out("TST", "labels", "time", *t.getColumnLabels())
            keys = list(t.getTableMetaDataKeys())
            deg = t.getTableMetaDataAsString("inDegrees") if "inDegrees" in keys else ""
            out("TST", "inDegrees", deg)
            out("TST", "rows", t.getNumRows())
            times = t.getIndependentColumn()
            m = t.getMatrix().to_numpy() if t.getNumRows() > 0 else []
            for i in range(t.getNumRows()):
                out("TST", "row", num(times[i]), *[num(v) for v in m[i]])
        except Exception as e:  # report, the Rust test decides
            out("TST", "error", str(e).replace("\n", " "))
        try:
            s = osim.Storage(path)
            labels = s.getColumnLabels()
            out("STORAGE", "name", s.getName())
            out("STORAGE", "labels", *[labels.get(i) for i in range(labels.getSize())])
            out("STORAGE", "inDegrees", "yes" if s.isInDegrees() else "no")
            out("STORAGE", "rows", s.getSize())
            for i in range(s.getSize()):
                sv = s.getStateVector(i)
                d = sv.getData()
                out("STORAGE", "row", num(sv.getTime()), *[num(d.get(j)) for j in range(d.getSize())])
        except Exception as e:
            out("STORAGE", "error", str(e).replace("\n", " "))


def sto_write(directory):
    labels = ["hip_flexion_r", "knee_angle_r", "pelvis_tx"]
    rows = []
    for i in range(7):
        t = i / 60.0
        rows.append((t, [30.0 * math.sin(t * 7.1) + 1e-7 * i, -1.0 / 3.0 * i, 1e-12 * (i + 1)]))
    # TimeSeriesTable through OpenSim 4's STOFileAdapter (version=3 header, no name line).
    table = osim.TimeSeriesTable()
    table.setColumnLabels(labels)
    for t, vals in rows:
        r = osim.RowVector(len(vals))
        for j, v in enumerate(vals):
            r[j] = v
        table.appendRow(t, r)
    table.addTableMetaDataString("inDegrees", "yes")
    adapter_path = os.path.join(directory, "opensim_adapter.sto")
    osim.STOFileAdapter.write(table, adapter_path)
    out("WROTE", adapter_path)
    # The same values through the older Storage writer (version=1 header with a name line).
    storage = osim.Storage()
    storage.setName("Coordinates")
    col = osim.ArrayStr()
    for name in ["time"] + labels:
        col.append(name)
    storage.setColumnLabels(col)
    for t, vals in rows:
        v = osim.Vector(len(vals), 0.0)
        for j, x in enumerate(vals):
            v.set(j, x)
        storage.append(t, v)
    storage.setInDegrees(True)
    storage_path = os.path.join(directory, "opensim_storage.mot")
    storage.printResult(storage, "opensim_storage", directory, -1, ".mot")
    out("WROTE", storage_path)
    out("VALUES", "labels", "time", *labels)
    for t, vals in rows:
        out("VALUES", "row", num(t), *[num(v) for v in vals])


def trc_read(paths):
    for path in paths:
        out("FILE", path)
        try:
            t = osim.TimeSeriesTableVec3(path)
        except Exception as e:
            out("ERROR", str(e).replace("\n", " "))
            continue
        keys = list(t.getTableMetaDataKeys())
        out("units", t.getTableMetaDataAsString("Units") if "Units" in keys else "")
        out("rate", t.getTableMetaDataAsString("DataRate") if "DataRate" in keys else "")
        out("labels", *t.getColumnLabels())
        out("rows", t.getNumRows())
        times = t.getIndependentColumn()
        flat = t.flatten()
        m = flat.getMatrix().to_numpy() if t.getNumRows() > 0 else []
        for i in range(t.getNumRows()):
            out("row", num(times[i]), *[num(v) for v in m[i]])


def ik_setup(setup, mot):
    import time
    tool = osim.InverseKinematicsTool(setup)
    tool.setOutputMotionFileName(os.path.abspath(mot))
    tool.set_report_errors(False)
    start = time.perf_counter()
    if not tool.run():
        raise RuntimeError("InverseKinematicsTool.run() returned false")
    out("SECONDS", num(time.perf_counter() - start))
    out("MOT", os.path.abspath(mot))


def in_setup_dir(setup, path):
    """A path of the setup as OpenSim reads it: relative to the setup file's directory."""
    return path if os.path.isabs(path) else os.path.join(os.path.dirname(os.path.abspath(setup)), path)


def unset(v):
    return v.strip() in ("", "Unassigned")


def setup_references(setup, model):
    """The marker weights (name -> w, None: every marker weight 1) and the coordinate references
    (name -> (weight, function of time)) of InverseKinematicsTool::populateReferences."""
    tool = osim.InverseKinematicsTool(setup, False)
    tasks = tool.getIKTaskSet()
    coord_functions = None
    coord_file = tool.getCoordinateFileName() if hasattr(tool, "getCoordinateFileName") else tool.get_coordinate_file()
    if not unset(coord_file):
        storage = osim.Storage(in_setup_dir(setup, coord_file))
        model.getSimbodyEngine().convertDegreesToRadians(storage)
        coord_functions = osim.GCVSplineSet(5, storage)
    weights = {}
    coords = {}
    cs = model.getCoordinateSet()
    for i in range(tasks.getSize()):
        task = tasks.get(i)
        if not task.getApply():
            continue
        ct = osim.IKCoordinateTask.safeDownCast(task)
        if ct is not None:
            kind = ct.getValueType()
            name = ct.getName()
            if kind == osim.IKCoordinateTask.FromFile:
                f = coord_functions.get(name)
                coords[name] = (ct.getWeight(), lambda t, f=f: f.calcValue(osim.Vector(1, t)))
            elif kind == osim.IKCoordinateTask.ManualValue:
                v = ct.getValue()
                coords[name] = (ct.getWeight(), lambda t, v=v: v)
            else:
                v = cs.get(name).getDefaultValue()
                coords[name] = (ct.getWeight(), lambda t, v=v: v)
            continue
        mt = osim.IKMarkerTask.safeDownCast(task)
        if mt is not None:
            weights[mt.getName()] = mt.getWeight()
    marker_file = in_setup_dir(setup, tool.getMarkerDataFileName())
    return (weights if weights else None), coords, marker_file


def objective(setup, mots):
    model = osim.Model(osim.InverseKinematicsTool(setup, False).get_model_file())
    state = model.initSystem()
    weights, coords, marker_file = setup_references(setup, model)
    table = osim.TimeSeriesTableVec3(marker_file)
    keys = list(table.getTableMetaDataKeys())
    units = table.getTableMetaDataAsString("Units").strip() if "Units" in keys else "m"
    scale = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}[units]
    labels = list(table.getColumnLabels())
    ms = model.getMarkerSet()
    cs = model.getCoordinateSet()
    tracked = []
    for i in range(ms.getSize()):
        name = ms.get(i).getName()
        if name not in labels:
            continue
        w = 1.0 if weights is None else weights.get(name)
        if w is None:
            continue
        tracked.append((ms.get(i), labels.index(name), w))
    for path in mots:
        mot = osim.TimeSeriesTable(path)
        mkeys = list(mot.getTableMetaDataKeys())
        deg = "inDegrees" in mkeys and mot.getTableMetaDataAsString("inDegrees").strip() == "yes"
        columns = list(mot.getColumnLabels())
        names = [n for n in columns if cs.contains(n)]
        out("FILE", path)
        for r in range(mot.getNumRows()):
            t = mot.getIndependentColumn()[r]
            row = mot.getRowAtIndex(r)
            for n in names:
                c = cs.get(n)
                v = row[columns.index(n)]
                if deg and c.getMotionType() == osim.Coordinate.Rotational:
                    v = math.radians(v)
                if not c.getLocked(state):
                    c.setValue(state, v, False)
            model.realizePosition(state)
            data = table.getRowAtIndex(table.getNearestRowIndexForTime(t))
            total_w = 0.0
            markers = 0.0
            for m, col, w in tracked:
                p = data[col]
                obs = [p.get(0) * scale, p.get(1) * scale, p.get(2) * scale]
                if any(math.isnan(x) for x in obs):
                    continue
                x = m.getLocationInGround(state)
                markers += w * sum((x.get(k) - obs[k]) ** 2 for k in range(3))
                total_w += w
            goal = markers / (2 * total_w) if total_w > 0 else 0.0
            for name, (w, f) in coords.items():
                c = cs.get(name)
                if c.getLocked(state):
                    continue
                goal += w * (c.getValue(state) - f(t)) ** 2 / 2
            out("FRAME", num(t), num(goal))


def main(argv):
    osim.Logger.setLevelString("error")
    osim.Logger.removeFileSink()  # no opensim.log in the caller's directory
    if len(argv) < 2:
        sys.exit(__doc__)
    mode, args = argv[1], argv[2:]
    if mode == "sto-read":
        sto_read(args)
    elif mode == "sto-write":
        sto_write(args[0])
    elif mode == "trc-read":
        trc_read(args)
    elif mode == "ik-setup":
        ik_setup(args[0], args[1])
    elif mode == "objective":
        objective(args[0], args[1:])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main(sys.argv)
