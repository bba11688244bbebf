#!/usr/bin/env python3
"""scipy.signal reference values for jointfit's Butterworth filter (crates/jointfit-signal).

Two modes:

  filter_reference.py < request.json > answer.json
      What the Rust tests run live (through $JOINTFIT_PYTHON). The request is a JSON object with
      optional lists
        "butter":      [{"order": n, "cutoff_hz": f, "rate_hz": fs}, ...]
        "sosfiltfilt": [{"order": n, "cutoff_hz": f, "rate_hz": fs, "x": [...],
                         "padlen": null or int}, ...]
      and the answer has the same keys: the `sos` arrays of butter(n, f/(fs/2), output='sos'),
      and sosfiltfilt(that sos, x, padlen=padlen), plus "scipy" (the version).

  filter_reference.py --fixture PATH
      Writes the small offline reference file that the tests also check (committed in the
      repository), from deterministic inputs defined below.
"""

import json
import sys

import numpy as np
import scipy
from scipy import signal


def design(case):
    wn = case["cutoff_hz"] / (case["rate_hz"] / 2)
    return signal.butter(case["order"], wn, output="sos")


def answer(request):
    out = {"scipy": scipy.__version__}
    out["butter"] = [design(c).tolist() for c in request.get("butter", [])]
    out["sosfiltfilt"] = [
        signal.sosfiltfilt(design(c), np.asarray(c["x"], dtype=float), padlen=c.get("padlen")).tolist()
        for c in request.get("sosfiltfilt", [])
    ]
    return out


def fixture():
    """Deterministic inputs: a slow sine with an offset plus a fast deterministic wiggle."""
    rate = 100.0
    cases_butter = [
        {"order": n, "cutoff_hz": f, "rate_hz": rate} for n in range(1, 9) for f in (6.0, 20.0)
    ]
    cases_filt = []
    for order, length, padlen in ((1, 40, None), (2, 60, None), (4, 40, None), (2, 8, 7)):
        i = np.arange(length)
        x = 0.8 + 0.03 * np.sin(2 * np.pi * 1.3 * i / rate + 0.4) + 0.002 * np.sin(0.37 * i * i)
        cases_filt.append(
            {"order": order, "cutoff_hz": 6.0, "rate_hz": rate, "x": x.tolist(), "padlen": padlen}
        )
    request = {"butter": cases_butter, "sosfiltfilt": cases_filt}
    ans = answer(request)
    return {
        "made_by": "scripts/filter_reference.py --fixture",
        "scipy": ans["scipy"],
        "butter": [dict(c, sos=s) for c, s in zip(cases_butter, ans["butter"])],
        "sosfiltfilt": [dict(c, y=y) for c, y in zip(cases_filt, ans["sosfiltfilt"])],
    }


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--fixture":
        with open(sys.argv[2], "w") as f:
            json.dump(fixture(), f, indent=1)
            f.write("\n")
    elif len(sys.argv) == 1:
        json.dump(answer(json.load(sys.stdin)), sys.stdout)
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
