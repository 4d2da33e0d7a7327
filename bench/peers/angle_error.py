#!/usr/bin/python3
"""angle_error — unoriented normal angle errors of a result against ground truth.

usage: /usr/bin/python3 angle_error.py RESULT.ply TRUTH.ply

RESULT and TRUTH list the same points in the same order (PLY with nx ny nz of
any scalar type, binary or ascii). Prints one JSON line with the definitions of
`bootsurf eval --truth` (DESIGN.md): the angle between the lines of the two
normals, acos(|n . t| / (|n| |t|)) in [0, pi/2], its mean, median and rms in
radians, the mean in degrees, and the fractions under 5 and 10 degrees (PCPNet's
PGP5/PGP10). A result normal that is zero or not finite counts as pi/2 (and in
"invalid"). The comparison harness uses this script for every program, bootsurf
included, so all rows are measured by the same code; it also checks once that
`bootsurf eval` gives the same numbers.
"""
import json
import sys

import numpy as np

PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
             "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
             "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
             "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


def read_fields(path, names):
    """The named vertex properties as float64 columns (n x len(names))."""
    with open(path, "rb") as f:
        if f.readline().strip() != b"ply":
            raise ValueError(path + ": not a PLY file")
        fmt, n, props, in_vertex = None, 0, [], False
        while True:
            line = f.readline()
            if not line:
                raise ValueError(path + ": no end_header")
            w = line.decode("ascii", "replace").split()
            if not w:
                continue
            if w[0] == "format":
                fmt = w[1]
            elif w[0] == "element":
                in_vertex = w[1] == "vertex"
                if in_vertex:
                    n = int(w[2])
            elif w[0] == "property" and in_vertex:
                if w[1] == "list":
                    raise ValueError(path + ": list property in vertex")
                props.append((w[2], PLY_TYPES[w[1]]))
            elif w[0] == "end_header":
                break
        pnames = [p[0] for p in props]
        for c in names:
            if c not in pnames:
                raise ValueError("%s: no property %s" % (path, c))
        if fmt == "ascii":
            data = np.loadtxt(f, max_rows=n, ndmin=2)
            return data[:, [pnames.index(c) for c in names]].astype(np.float64)
        end = "<" if fmt == "binary_little_endian" else ">"
        dt = np.dtype([(a, end + t) for a, t in props])
        out = np.empty((n, len(names)), dtype=np.float64)
        block = 65536  # blocks of rows: the peak RSS holds no copy of the whole file
        for s in range(0, n, block):
            rec = np.fromfile(f, dtype=dt, count=min(block, n - s))
            if rec.shape[0] != min(block, n - s):
                raise ValueError(path + ": short binary data")
            for j, c in enumerate(names):
                out[s:s + rec.shape[0], j] = rec[c]
    return out


def angle_errors(res, tru):
    """Unoriented angles (radians) between the rows of res and tru; invalid -> pi/2."""
    nr = np.linalg.norm(res, axis=1)
    nt = np.linalg.norm(tru, axis=1)
    ok = np.isfinite(nr) & (nr > 0) & (nt > 0)
    c = np.zeros(res.shape[0])
    c[ok] = np.abs(np.einsum("ij,ij->i", res[ok], tru[ok])) / (nr[ok] * nt[ok])
    ang = np.arccos(np.clip(c, 0.0, 1.0))
    ang[~ok] = np.pi / 2
    return ang, int((~ok).sum())


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: angle_error.py RESULT.ply TRUTH.ply")
    res = read_fields(sys.argv[1], ["nx", "ny", "nz"])
    tru = read_fields(sys.argv[2], ["nx", "ny", "nz"])
    if res.shape != tru.shape:
        sys.exit("angle_error: %d points in the result, %d in the truth" % (res.shape[0], tru.shape[0]))
    a, invalid = angle_errors(res, tru)
    print(json.dumps({
        "points": int(a.size), "invalid": invalid,
        "mean_rad": float(a.mean()), "median_rad": float(np.median(a)),
        "rms_rad": float(np.sqrt((a * a).mean())), "mean_deg": float(np.degrees(a.mean())),
        "under5deg": float((a < np.radians(5.0)).mean()),
        "under10deg": float((a < np.radians(10.0)).mean())}))


if __name__ == "__main__":
    main()
