"""OpenSim 4.x oracle of `jointfit_io::osim_scale`.

    python osim_scale_check.py scale GENERIC.osim FACTORS.json MASS OUT.osim [keep|grow]
        OpenSim's own Model::scale (keep: preserve mass distribution, the default; grow:
        masses scale with the factors' product; MASS <= 0: no total mass) with the per-body
        factors {"body": [sx, sy, sz]}, written to OUT.osim.
    python osim_scale_check.py dump MODEL.osim
        What scaling changes, as OpenSim reads the file: bodies (mass, mass centre, inertia),
        body origins in ground at the default pose, offset frame translations, markers,
        path points (location at the default pose), wrap object sizes, muscle fibre and tendon
        lengths and whether each muscle wraps. One JSON line prefixed with "@@".
"""
import json
import sys

import opensim as osim


def vec(v):
    return [v[0], v[1], v[2]]


def scale(generic, factors_path, mass, out, masses="keep"):
    model = osim.Model(generic)
    state = model.initSystem()
    with open(factors_path) as f:
        factors = json.load(f)
    scale_set = osim.ScaleSet()
    for body, s in factors.items():
        sc = osim.Scale()
        sc.setSegmentName(body)
        sc.setScaleFactors(osim.Vec3(*s))
        sc.setApply(True)
        scale_set.cloneAndAppend(sc)
    model.scale(state, scale_set, masses == "keep", float(mass))
    model.printToXML(out)
    print("@@" + json.dumps({"written": out}))


def dump(path):
    model = osim.Model(path)
    state = model.initSystem()
    model.realizePosition(state)
    out = {"bodies": {}, "origins": {}, "frames": {}, "markers": {}, "points": {},
           "wraps": {}, "muscles": {}}
    for b in model.getBodySet():
        i = b.getInertia()
        m, p = i.getMoments(), i.getProducts()
        out["bodies"][b.getName()] = {
            "mass": b.getMass(),
            "mass_center": vec(b.getMassCenter()),
            "inertia": [m[0], m[1], m[2], p[0], p[1], p[2]],
        }
        out["origins"][b.getName()] = vec(b.getPositionInGround(state))
        for k in range(b.getWrapObjectSet().getSize()):
            w = b.getWrapObjectSet().get(k)
            d = {"translation": vec(w.get_translation())}
            kind = w.getConcreteClassName()
            if kind == "WrapCylinder":
                c = osim.WrapCylinder.safeDownCast(w)
                d["size"] = [c.get_radius(), c.get_length()]
            elif kind == "WrapSphere":
                d["size"] = [osim.WrapSphere.safeDownCast(w).get_radius()]
            elif kind == "WrapEllipsoid":
                d["size"] = vec(osim.WrapEllipsoid.safeDownCast(w).get_dimensions())
            elif kind == "WrapTorus":
                t = osim.WrapTorus.safeDownCast(w)
                d["size"] = [t.get_inner_radius(), t.get_outer_radius()]
            out["wraps"][b.getName() + "/" + w.getName()] = d
    for f in model.getComponentsList():
        if f.getConcreteClassName() == "PhysicalOffsetFrame":
            o = osim.PhysicalOffsetFrame.safeDownCast(f)
            out["frames"][o.getAbsolutePathString()] = vec(o.get_translation())
    for mk in model.getMarkerSet():
        out["markers"][mk.getName()] = vec(mk.get_location())
    for mu in model.getMuscles():
        path = osim.GeometryPath.safeDownCast(mu.getPath())
        pts = path.getPathPointSet()
        for k in range(pts.getSize()):
            p = pts.get(k)
            out["points"][mu.getName() + "/" + p.getName()] = vec(p.getLocation(state))
        out["muscles"][mu.getName()] = {
            "optimal_fiber_length": mu.getOptimalFiberLength(),
            "tendon_slack_length": mu.getTendonSlackLength(),
            "wraps": path.getWrapSet().getSize(),
            "length": path.getLength(state),
        }
    print("@@" + json.dumps(out))


if __name__ == "__main__":
    if sys.argv[1] == "scale":
        scale(*sys.argv[2:7])
    elif sys.argv[1] == "dump":
        dump(sys.argv[2])
    else:
        sys.exit("usage: osim_scale_check.py scale|dump ...")
