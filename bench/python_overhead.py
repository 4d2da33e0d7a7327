#!/usr/bin/env python3
"""The Python package's overhead: bootsurf.normals on N points against the C
library call it makes (bench/bench_normals_job.c: bsurf_normals_job in
memory, with a progress callback as the binding and the CLI have), on the
same points (a noisy random sphere, seed 1), alternating
C, Python, C, Python ... so that a shared machine's load hits both alike.

Prints every pair with wall and CPU time (every thread's; less inflated than
wall time when the machine is shared, since waiting for a core is not
counted) and the median ratios python / C (the target: within 5%).

The C program's points are put in the same kind of memory as the Python
array's: numpy advises arrays of 4 MiB or more for transparent huge pages
(madvise), and random reads of the points through huge pages cost
differently from 4 KiB pages (on some virtual machines 10-40% more, on others
less), which is the memory's cost, not the binding's. `--plain-c` compares
with points in ordinary malloc memory instead (docs/python.md, "Overhead").

Usage: PYTHONPATH=BUILD/python /usr/bin/python3 bench/python_overhead.py BUILD
       [N=1000000] [REPS=3] [THREADS=2] [K=30] [B=10] [--plain-c]
Not a test: nothing fails because a number is slow."""
import json
import statistics
import subprocess
import sys
import time

import numpy as np

import bootsurf


def numpy_uses_hugepages():
    try:
        return bool(np.core.multiarray._get_madvise_hugepage())
    except AttributeError:  # numpy < 1.20 never advised huge pages
        return False


def main():
    plain = "--plain-c" in sys.argv
    args = [a for a in sys.argv[1:] if a != "--plain-c"]
    build = args[0]
    n = int(float(args[1])) if len(args) > 1 else 1000000
    reps = int(args[2]) if len(args) > 2 else 3
    threads = int(args[3]) if len(args) > 3 else 2
    k = int(args[4]) if len(args) > 4 else 30
    b = int(args[5]) if len(args) > 5 else 10
    # the same points as bench_normals_job: generate + noise (level 0.5, seed 1)
    c = bootsurf.generate("sphere", points=n, sampling="random", seed=1, feature_width=0)
    pts = bootsurf.noise(c["points"], c["normals"])
    huge = 0 if plain else int(numpy_uses_hugepages() and pts.nbytes >= 4 << 20)
    print("C points in %s memory" % ("huge-page advised (as numpy's)" if huge else "plain"))
    wall, cpu = [], []
    for r in range(reps):
        out = subprocess.run([build + "/bench_normals_job", str(n), str(threads), str(k), str(b),
                              "1", str(huge)], capture_output=True, text=True, check=True).stdout
        cres = json.loads(out)
        fields = None  # the previous round's arrays are freed outside the timing
        c0, t0 = time.process_time(), time.perf_counter()
        fields, s = bootsurf.normals(pts, neighbors=k, bootstrap=b, threads=threads)
        py, py_cpu = time.perf_counter() - t0, time.process_time() - c0
        same = s["means"]["normal_var"] == cres["mean_normal_var"]
        wall.append(py / cres["seconds"])
        cpu.append(py_cpu / cres["cpu_seconds"])
        print("round %d: wall C %.3f s, Python %.3f s, ratio %.4f | CPU C %.3f s, Python %.3f s, "
              "ratio %.4f | same result: %s"
              % (r + 1, cres["seconds"], py, wall[-1], cres["cpu_seconds"], py_cpu, cpu[-1], same),
              flush=True)
    print("median ratios python / C over %d rounds (N = %d, K = %d, B = %d, %d threads): "
          "wall %.4f, CPU %.4f" % (reps, n, k, b, threads, statistics.median(wall),
                                   statistics.median(cpu)))


if __name__ == "__main__":
    main()
