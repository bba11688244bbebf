"""OpenSim 4.x side of the `jointfit scale` measurements.

    python scale_compare.py scaletool SETUP.xml GENERIC.osim MARKERSET.xml|- STATIC.trc OUT.osim
        OpenSim's ScaleTool from an existing setup with the files replaced (absolute paths);
        prints the applied scale factors {"body": [sx, sy, sz]}.
    python scale_compare.py ik MODEL.osim TRIAL.trc OUTDIR
        OpenSim's InverseKinematicsTool over the whole trial (samples of (0, 0, 0) made
        gaps), every model marker recorded in the trial with weight 1 (no coordinate tasks), accuracy 1e-5; prints the mean and
        the largest per-frame marker RMS and the largest marker error (m).
Each answer is one line "@@" + JSON.
"""
import json
import os
import sys
import xml.etree.ElementTree as ET

import opensim as osim


def scaletool(setup, generic, markerset, static, out):
    tool = osim.ScaleTool(setup)
    base = os.path.dirname(os.path.abspath(setup))

    def rel(p):  # the tool resolves every file against the setup's directory
        return os.path.relpath(os.path.abspath(p), base)

    generic, static, out = rel(generic), rel(static), rel(out)
    if markerset != "-":
        markerset = rel(markerset)
    gm = tool.getGenericModelMaker()
    gm.setModelFileName(generic)
    if markerset != "-":
        gm.setMarkerSetFileName(markerset)
    scale_file = out + ".scaleset.xml"
    ms = tool.getModelScaler()
    ms.setMarkerFileName(static)
    ms.setOutputModelFileName("")
    ms.setOutputScaleFileName(scale_file)
    mp = tool.getMarkerPlacer()
    mp.setMarkerFileName(static)
    mp.setOutputModelFileName(out)
    mp.setOutputMotionFileName("")
    if not tool.run():
        raise RuntimeError("ScaleTool.run() returned false")
    factors = {}
    for sc in ET.parse(os.path.join(base, scale_file)).getroot().iter("Scale"):
        factors[sc.findtext("segment").strip()] = [float(x) for x in sc.findtext("scales").split()]
    print("@@" + json.dumps({"factors": factors}))


def is_zero(v):
    return v.get(0) == 0.0 and v.get(1) == 0.0 and v.get(2) == 0.0


def recorded(table, name):
    col = table.getDependentColumn(name)
    return any(not is_zero(col[i]) and col[i].get(0) == col[i].get(0) for i in range(col.size()))


def without_zero_samples(table, path):
    """Writes the trial with every (0, 0, 0) sample made a gap: capture software writes
    zeros for a marker it did not see, and OpenSim's reader would take them for a marker at
    the lab origin (jointfit's reader treats them as gaps)."""
    nan = float("nan")
    for name in table.getColumnLabels():
        col = table.updDependentColumn(name)
        for i in range(col.size()):
            if is_zero(col[i]):
                col[i] = osim.Vec3(nan, nan, nan)
    osim.TRCFileAdapter.write(table, path)
    return path


def ik(model_path, trc, out_dir):
    os.makedirs(out_dir, exist_ok=True)
    model = osim.Model(model_path)
    model.initSystem()
    table = osim.TimeSeriesTableVec3(trc)
    trc = without_zero_samples(table, os.path.join(out_dir, "markers.trc"))
    labels = {n for n in table.getColumnLabels() if recorded(table, n)}
    times = table.getIndependentColumn()
    tool = osim.InverseKinematicsTool()
    tool.setName("ik")
    tool.setModel(model)
    tool.setMarkerDataFileName(trc)
    tool.set_accuracy(1e-5)
    tool.setStartTime(times[0])
    tool.setEndTime(times[-1])
    used = []
    for k in range(model.getMarkerSet().getSize()):
        name = model.getMarkerSet().get(k).getName()
        if name in labels:
            task = osim.IKMarkerTask()
            task.setName(name)
            task.setWeight(1.0)
            task.setApply(True)
            tool.upd_IKTaskSet().cloneAndAppend(task)
            used.append(name)
    tool.setResultsDir(out_dir)
    tool.setOutputMotionFileName(os.path.join(out_dir, "ik.mot"))
    tool.set_report_errors(True)
    if not tool.run():
        raise RuntimeError("InverseKinematicsTool.run() returned false")
    err = osim.TimeSeriesTable(os.path.join(out_dir, "ik_ik_marker_errors.sto"))
    rms = list(err.getDependentColumn("marker_error_RMS").to_numpy())
    mx = list(err.getDependentColumn("marker_error_max").to_numpy())
    print("@@" + json.dumps({"mean_rms": sum(rms) / len(rms), "max_rms": max(rms),
                             "max_error": max(mx), "markers": len(used), "frames": len(rms)}))


if __name__ == "__main__":
    {"scaletool": scaletool, "ik": ik}[sys.argv[1]](*sys.argv[2:])
