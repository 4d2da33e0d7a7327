#!/usr/bin/env python3
"""The Python package's overhead: bootsurf.normals on N points against the C
library call it makes (bench/bench_normals_job.c: bsurf_normals_job in
memory, with a progress callback as the binding and the CLI have), on the
same points (a noisy random sphere, seed 1), alternating
C, Python, C, Python ... so that a shared machine's load hits both alike.
Prints every pair and the median ratio python / C (the target: within 5%).

Usage: PYTHONPATH=BUILD/python /usr/bin/python3 bench/python_overhead.py BUILD
       [N=1000000] [REPS=3] [THREADS=2] [K=30] [B=10]
Not a test: nothing fails because a number is slow."""
import json
import statistics
import subprocess
import sys
import time

import bootsurf


def main():
    build = sys.argv[1]
    n = int(float(sys.argv[2])) if len(sys.argv) > 2 else 1000000
    reps = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    threads = int(sys.argv[4]) if len(sys.argv) > 4 else 2
    k = int(sys.argv[5]) if len(sys.argv) > 5 else 30
    b = int(sys.argv[6]) if len(sys.argv) > 6 else 10
    # the same points as bench_normals_job: generate + noise (level 0.5, seed 1)
    c = bootsurf.generate("sphere", points=n, sampling="random", seed=1, feature_width=0)
    pts = bootsurf.noise(c["points"], c["normals"])
    ratios = []
    for r in range(reps):
        out = subprocess.run([build + "/bench_normals_job", str(n), str(threads), str(k), str(b)],
                             capture_output=True, text=True, check=True).stdout
        cres = json.loads(out)
        t0 = time.perf_counter()
        fields, s = bootsurf.normals(pts, neighbors=k, bootstrap=b, threads=threads)
        py = time.perf_counter() - t0
        same = s["means"]["normal_var"] == cres["mean_normal_var"]
        ratios.append(py / cres["seconds"])
        print("round %d: C %.3f s, Python %.3f s, ratio %.4f, same result: %s"
              % (r + 1, cres["seconds"], py, ratios[-1], same), flush=True)
    print("median ratio python / C over %d rounds (N = %d, K = %d, B = %d, %d threads): %.4f"
          % (reps, n, k, b, threads, statistics.median(ratios)))


if __name__ == "__main__":
    main()
