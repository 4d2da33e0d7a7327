#!/usr/bin/python3
"""position_error — distance of smoothed points to an ANALYTIC surface, in units of h.

usage: /usr/bin/python3 position_error.py RESULT.ply --shape sphere|cube --h H
           [--truth TRUTH.ply]

The shapes are those of `bootsurf generate`: the unit sphere (radius 1, centre 0)
and the cube [-1, 1]^3 (edge 2). Distance = |signed distance function| of the
shape at each RESULT point; printed as one JSON line: mean, rms and max divided
by H (pass the truth's h, `bootsurf info TRUTH --json`), and, when --truth has a
`feature` field (the cube), the same for its feature = 1 and feature = 0 points
(RESULT and TRUTH: the same points in the same order).

It checks the smoothing peers by themselves and cross-checks `bootsurf eval`'s
"position" section on the analytic inputs (bench/smooth_compare.sh notes); the
comparison's table itself uses `bootsurf eval` for every row.
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True
from angle_error import read_fields  # noqa: E402


def distance(p, shape):
    if shape == "sphere":
        return np.abs(np.linalg.norm(p, axis=1) - 1.0)
    q = np.abs(p) - 1.0  # cube [-1, 1]^3: sdf = |max(q, 0)| + min(max_i q_i, 0)
    return np.abs(np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0))


def summary(d, h):
    if d.size == 0:
        return {"points": 0}
    return {"points": int(d.size), "mean_h": float(d.mean() / h),
            "rms_h": float(np.sqrt((d * d).mean()) / h), "max_h": float(d.max() / h)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("result")
    ap.add_argument("--shape", required=True, choices=["sphere", "cube"])
    ap.add_argument("--h", type=float, required=True)
    ap.add_argument("--truth")
    a = ap.parse_args()
    p = read_fields(a.result, ["x", "y", "z"])
    d = distance(p, a.shape)
    out = {"shape": a.shape, "h": a.h, **summary(d, a.h)}
    if a.truth:
        try:
            f = read_fields(a.truth, ["feature"])[:, 0]
        except ValueError:
            f = None
        if f is not None:
            if f.size != d.size:
                sys.exit("position_error: %d points in the result, %d in the truth" % (d.size, f.size))
            out["feature"] = summary(d[f != 0], a.h)
            out["non_feature"] = summary(d[f == 0], a.h)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
