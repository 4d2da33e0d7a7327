#!/usr/bin/python3
"""knn_open3d — all-K-nearest-neighbour search with Open3D 0.16, for comparison
with bootsurf's bsurf_knn_all (bench/peers/knn_bootsurf.c).

usage: /usr/bin/python3 knn_open3d.py INPUT.ply -o CHECK.f64 [-k 50] [-j 2] [--api core|legacy]

--api core (default): open3d.core.nns.NearestNeighborSearch over a Float64
    tensor of the points: knn_index() ("seconds_build"), then one batched
    knn_search(all points, K) ("seconds_search"), C++ end to end (Open3D's
    nanoflann-based NanoFlannIndex, parallel over the queries). Returns N x K
    int64 indices and N x K double squared distances.
--api legacy: open3d.geometry.KDTreeFlann (FLANN) over a PointCloud
    ("seconds_build"), then search_knn_vector_3d(point, K) for every point in a
    Python loop ("seconds_search"), which is what the Python API offers for the
    KDTreeFlann; one call per point, single-threaded (the GIL), the results
    copied into N x K numpy arrays. Its time is mostly Python's per-call cost,
    not FLANN's search.

The query point is in the cloud, so it is among its K (distance 0): the same K
as bootsurf's. "seconds" = build + search. Not timed: importing open3d, reading
the PLY, writing CHECK.f64.

Threads: OMP_NUM_THREADS is set to -j before open3d loads; the core search
runs on Open3D's parallel loop (TBB in 0.16 builds, which has no thread cap
from Python: it uses every core, 2 on the benchmark machine, which is -j there;
the JSON's cpu_seconds / seconds shows the cores used).

CHECK.f64: per point the sum and the largest of its K squared distances, as
n x 2 little-endian doubles (bench/peers/bs_driver.h's format).
"""
import argparse
import json
import os
import resource
import sys
import time

def parse(argv):
    ap = argparse.ArgumentParser(prog="knn_open3d.py")
    ap.add_argument("input")
    ap.add_argument("-o", dest="out", required=True)
    ap.add_argument("-k", type=int, default=50)
    ap.add_argument("-j", dest="threads", type=int, default=2)
    ap.add_argument("--api", choices=("core", "legacy"), default="core")
    o = ap.parse_args(argv[1:])
    if o.k < 1 or o.threads < 1:
        ap.error("K and THREADS must be >= 1")
    return o


def cpu():
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def main():
    o = parse(sys.argv)
    os.environ["OMP_NUM_THREADS"] = str(o.threads)  # before open3d loads libgomp
    import numpy as np
    import open3d as o3d
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    sys.dont_write_bytecode = True  # no __pycache__ in the source tree
    from angle_error import read_fields
    xyz = np.ascontiguousarray(read_fields(o.input, ["x", "y", "z"]), dtype=np.float64)
    n, k = xyz.shape[0], o.k
    if k > n:
        sys.exit("knn_open3d: K = %d > %d points" % (k, n))

    if o.api == "core":
        pts = o3d.core.Tensor(xyz)  # Float64, CPU:0
        c0, t0 = cpu(), time.monotonic()
        nns = o3d.core.nns.NearestNeighborSearch(pts)
        if not nns.knn_index():
            sys.exit("knn_open3d: knn_index failed")
        t1 = time.monotonic()
        _, d2 = nns.knn_search(pts, k)
        t2 = time.monotonic()
        c1 = cpu()
        dist2 = d2.numpy()
        method = "core.nns.NearestNeighborSearch knn_search (batched)"
    else:
        pcd = o3d.geometry.PointCloud()
        pcd.points = o3d.utility.Vector3dVector(xyz)
        idx = np.empty((n, k), dtype=np.int64)
        dist2 = np.empty((n, k), dtype=np.float64)
        c0, t0 = cpu(), time.monotonic()
        tree = o3d.geometry.KDTreeFlann(pcd)
        t1 = time.monotonic()
        search = tree.search_knn_vector_3d
        for i in range(n):
            _, ii, dd = search(xyz[i], k)
            idx[i] = ii
            dist2[i] = dd
        t2 = time.monotonic()
        c1 = cpu()
        method = "geometry.KDTreeFlann search_knn_vector_3d (Python loop)"

    rows = np.empty((n, 2), dtype="<f8")
    rows[:, 0] = dist2.sum(axis=1)
    rows[:, 1] = dist2.max(axis=1)
    rows.tofile(o.out)
    print(json.dumps({
        "peer": "open3d", "version": o3d.__version__, "method": method, "api": o.api, "k": k,
        "threads": o.threads, "points": int(n), "seconds": round(t2 - t0, 6),
        "seconds_build": round(t1 - t0, 6), "seconds_search": round(t2 - t1, 6),
        "cpu_seconds": round(c1 - c0, 6),
        "peak_rss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
        "timed": "index build + search of every point"}))


if __name__ == "__main__":
    main()
