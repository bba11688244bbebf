#!/usr/bin/env python3
"""OpenSim as a test oracle for jointfit-io's TRC and .mot/.sto code.

Usage:
  opensim_oracle.py sto-read FILE...    read each file with opensim.TimeSeriesTable and
                                        opensim.Storage and print what they found
  opensim_oracle.py sto-write DIR       write tables with OpenSim's own writers into DIR and
                                        print the values that were put in
  opensim_oracle.py trc-read FILE...    read each file with opensim.TimeSeriesTableVec3

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


def main(argv):
    osim.Logger.setLevelString("error")
    if len(argv) < 2:
        sys.exit(__doc__)
    mode, args = argv[1], argv[2:]
    if mode == "sto-read":
        sto_read(args)
    elif mode == "sto-write":
        sto_write(args[0])
    elif mode == "trc-read":
        trc_read(args)
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main(sys.argv)
