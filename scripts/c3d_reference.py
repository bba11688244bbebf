#!/usr/bin/env python3
"""Reference dumps of C3D files read by two independent Python readers (ezc3d, c3d).

Usage: c3d_reference.py OUT_DIR FILE...

For every FILE (index i, in the order given) and every reader that can read it, writes
    OUT_DIR/{i}_{reader}_points.f64   frames x points x 3, little-endian f64, millimetres
                                      (converted with the reader's own POINT:UNITS; NaN where
                                      the reader itself says the sample is missing)
    OUT_DIR/{i}_{reader}_analog.f64   samples x channels, little-endian f64, scaled by the reader
    OUT_DIR/{i}_c3d_residual.f64      frames x points, the `c3d` package's residual (file units
                                      converted to mm), -1 where it says invalid
and one OUT_DIR/index.json: a list with, per file, {"path", "ezc3d": meta, "c3d": meta}, where
meta is {"error": "..."} when the reader failed, else frame/point/analog counts, labels, rates,
first frame and units as that reader reports them.

Conventions of the readers, recorded here and normalised by the Rust test, not here:
- ezc3d sets x, y, z to NaN when the residual word is negative; it does not treat an exact
  (0, 0, 0) as missing. Its header first frame is 0-based. Its "residuals" are the camera-mask
  byte times |POINT:SCALE| (it swaps the two bytes), so they are not dumped.
- c3d returns x, y, z as float32 (integer files: raw * |POINT:SCALE|) and residual -1 for an
  invalid sample (negative residual word or non-finite coordinate); it never treats (0, 0, 0) as
  missing. Its labels come from POINT:LABELS only (not LABELS2...).
"""

import json
import multiprocessing
import os
import sys
import warnings

import numpy as np

UNIT_TO_MM = {"mm": 1.0, "m": 1000.0, "cm": 10.0}


def unit_factor(units):
    words = (units or "").split()
    u = words[0].lower() if words else ""
    return UNIT_TO_MM.get(u, 1.0)


def write(path, array):
    np.ascontiguousarray(array, dtype="<f8").tofile(path)


def read_ezc3d(path, out_prefix):
    import ezc3d

    c = ezc3d.c3d(path)
    point = c["parameters"].get("POINT", {})
    analog = c["parameters"].get("ANALOG", {})

    def value(group, name, default):
        try:
            return group[name]["value"]
        except (KeyError, TypeError):
            return default

    units_v = value(point, "UNITS", [])
    units = str(units_v[0]) if len(units_v) else ""
    pts = c["data"]["points"]  # 4 x points x frames
    xyz = np.transpose(pts[:3], (2, 1, 0)) * unit_factor(units)  # frames x points x 3
    write(out_prefix + "_points.f64", xyz)
    an = c["data"]["analogs"]  # 1 x channels x samples
    an2 = np.transpose(an[0], (1, 0)) if an.size else np.zeros((0, 0))
    write(out_prefix + "_analog.f64", an2)
    rate_v = value(point, "RATE", [])
    header = c["header"]
    return {
        "frames": int(xyz.shape[0]),
        "points": int(xyz.shape[1]),
        "first_frame": int(header["points"]["first_frame"]) + 1,
        "rate": float(rate_v[0]) if len(rate_v) else float(header["points"]["frame_rate"]),
        "labels": [str(s) for s in value(point, "LABELS", [])],
        "units": units,
        "analog_channels": int(an2.shape[1]) if an2.ndim == 2 else 0,
        "analog_samples": int(an2.shape[0]) if an2.ndim == 2 else 0,
        "analog_labels": [str(s) for s in value(analog, "LABELS", [])],
    }


def read_c3d(path, out_prefix):
    import c3d

    with open(path, "rb") as handle, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reader = c3d.Reader(handle)
        units = ""
        p = reader.get("POINT:UNITS")
        if p is not None:
            try:
                units = p.string_value
            except Exception:  # noqa: BLE001 - a reader quirk is recorded, not fatal
                units = ""
        f = unit_factor(units)
        xyz, missing, resid, analog = [], [], [], []
        for _, points, an in reader.read_frames():
            invalid = points[:, 3] < 0
            c = points[:, :3].astype(np.float64) * f
            c[invalid] = np.nan
            xyz.append(c)
            r = points[:, 3].astype(np.float64)
            r[~invalid] *= f
            resid.append(r)
            if an.size:
                analog.append(np.asarray(an, dtype=np.float64).T)
        n_points = int(reader.point_used)
        xyz = np.array(xyz).reshape((-1, n_points, 3))
        resid = np.array(resid).reshape((-1, n_points))
        analog = np.concatenate(analog, axis=0) if analog else np.zeros((0, 0))
        write(out_prefix + "_points.f64", xyz)
        write(out_prefix + "_residual.f64", resid)
        write(out_prefix + "_analog.f64", analog)
        try:
            labels = [str(s).strip() for s in reader.point_labels]
        except Exception:  # noqa: BLE001
            labels = []
        try:
            alabels = [str(s).strip() for s in reader.analog_labels]
        except Exception:  # noqa: BLE001
            alabels = []
        return {
            "frames": int(xyz.shape[0]),
            "points": n_points,
            "first_frame": int(reader.first_frame),
            "rate": float(reader.point_rate),
            "labels": labels,
            "units": units,
            "analog_channels": int(analog.shape[1]) if analog.ndim == 2 else 0,
            "analog_samples": int(analog.shape[0]) if analog.ndim == 2 else 0,
            "analog_labels": alabels,
        }


# ezc3d spends tens of seconds (allocating) before rejecting some malformed files; each
# reader runs in a child process and is given up on after this many seconds.
TIME_LIMIT_S = 10


def _child(fn, path, prefix, conn):
    try:
        conn.send(fn(path, prefix))
    except BaseException as e:  # noqa: BLE001 - every failure is data for the test
        conn.send({"error": f"{type(e).__name__}: {e}"[:300]})


def run_limited(fn, path, prefix):
    parent, child = multiprocessing.Pipe(duplex=False)
    proc = multiprocessing.Process(target=_child, args=(fn, path, prefix, child))
    proc.start()
    child.close()
    if parent.poll(TIME_LIMIT_S):
        try:
            result = parent.recv()
        except EOFError:
            result = {"error": f"reader process died (exit code {proc.exitcode})"}
    else:
        proc.kill()
        result = {"error": f"Timeout: no answer within {TIME_LIMIT_S} s"}
    proc.join()
    if proc.exitcode not in (0, None) and "error" not in result:
        result = {"error": f"reader process died (exit code {proc.exitcode})"}
    return result


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    index = []
    for i, path in enumerate(sys.argv[2:]):
        entry = {"path": path}
        for name, fn in (("ezc3d", read_ezc3d), ("c3d", read_c3d)):
            entry[name] = run_limited(fn, path, os.path.join(out, f"{i}_{name}"))
        index.append(entry)
    with open(os.path.join(out, "index.json"), "w") as f:
        json.dump(index, f, indent=1)


if __name__ == "__main__":
    main()
