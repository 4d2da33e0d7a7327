#!/usr/bin/python3
"""normals_open3d — Open3D's PointCloud.estimate_normals with KNN, for comparison
with `bootsurf normals --fit pca -B 0`.

usage: /usr/bin/python3 normals_open3d.py INPUT.ply -o OUTPUT.ply [-k 30] [-j 2]

Run it with Debian's /usr/bin/python3: python3-open3d is installed for that
interpreter only.

Timed (monotonic clock): estimate_normals(KDTreeSearchParamKNN(K)) alone, which
builds Open3D's KDTreeFlann (single-threaded) and then, in an OpenMP loop,
searches the K nearest neighbours of every point and fits its plane. Not timed:
importing open3d, reading the PLY (numpy), building the PointCloud, writing.

Neighbourhood: KDTreeFlann::SearchKNN(K) over the cloud itself returns the
query point among the K, so K = 30 here is bootsurf's K = 30. Open3D computes the
covariance in double from raw sums (x x^T / K - mean mean^T) and solves it
with its closed-form 3x3 eigen solver (FastEigen3x3).

Threads: Open3D 0.16 has no thread-count API in Python; its OpenMP loops obey
OMP_NUM_THREADS, which this script sets before importing open3d.
"""
import json
import os
import resource
import sys
import time


def parse(argv):
    o = {"in": None, "out": None, "k": 30, "threads": 2}
    i = 1
    while i < len(argv):
        a = argv[i]
        if a in ("-o", "-k", "-j") and i + 1 < len(argv):
            v = argv[i + 1]
            i += 2
            if a == "-o":
                o["out"] = v
            elif a == "-k":
                o["k"] = int(v)
            else:
                o["threads"] = int(v)
        elif a.startswith("-") or o["in"] is not None:
            sys.exit("usage: normals_open3d.py INPUT.ply -o OUTPUT.ply [-k 30] [-j 2]")
        else:
            o["in"] = a
            i += 1
    if not o["in"] or not o["out"] or o["k"] < 3 or o["threads"] < 1:
        sys.exit("usage: normals_open3d.py INPUT.ply -o OUTPUT.ply [-k 30] [-j 2]")
    return o


def read_xyz(path):
    """Vertex x y z (float64, n x 3) of a binary or ascii PLY: the harness's
    shared reader (angle_error.py, beside this file)."""
    import numpy as np
    from angle_error import read_fields
    return np.ascontiguousarray(read_fields(path, ["x", "y", "z"]))


def write_xyz_normals(path, xyz, nrm, comment):
    import numpy as np
    n = xyz.shape[0]
    data = np.empty((n, 6), dtype="<f8")
    data[:, :3] = xyz
    data[:, 3:] = nrm
    head = ("ply\nformat binary_little_endian 1.0\ncomment %s\nelement vertex %d\n"
            "property double x\nproperty double y\nproperty double z\n"
            "property double nx\nproperty double ny\nproperty double nz\nend_header\n"
            % (comment, n))
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(head.encode("ascii"))
        data.tofile(f)
    os.replace(tmp, path)


def main():
    o = parse(sys.argv)
    os.environ["OMP_NUM_THREADS"] = str(o["threads"])  # before open3d loads libgomp
    import numpy as np
    import open3d as o3d
    try:
        o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    except AttributeError:
        pass
    xyz = read_xyz(o["in"])
    pcd = o3d.geometry.PointCloud()
    pcd.points = o3d.utility.Vector3dVector(xyz)
    param = o3d.geometry.KDTreeSearchParamKNN(knn=o["k"])

    ru0 = resource.getrusage(resource.RUSAGE_SELF)
    t0 = time.monotonic()
    pcd.estimate_normals(search_param=param)
    secs = time.monotonic() - t0
    ru1 = resource.getrusage(resource.RUSAGE_SELF)
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)

    nrm = np.asarray(pcd.normals)
    write_xyz_normals(o["out"], xyz, nrm, "normals_open3d estimate_normals")
    print(json.dumps({
        "peer": "open3d", "version": o3d.__version__, "method": "pca", "k": o["k"],
        "threads": o["threads"], "points": int(xyz.shape[0]), "seconds": round(secs, 6),
        "cpu_seconds": round(cpu, 6),
        "peak_rss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
        "timed": "estimate_normals incl. KDTreeFlann build"}))


if __name__ == "__main__":
    main()
