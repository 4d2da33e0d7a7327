#!/usr/bin/python3
"""compare — runs bootsurf and its peers (PCL, Open3D, CGAL) on the same inputs,
alternating programs, and prints one table per input. Called by
bench/normals_compare.sh, which builds everything and makes the inputs.

usage: /usr/bin/python3 compare.py --bootsurf BUILD/bootsurf --peers PEERS_DIR
           [--threads 2] [--reps 3] [--k 30] [--json-out FILE] [--work DIR]
           NAME=INPUT.ply [NAME=INPUT.ply ...]

Each INPUT.ply carries the ground-truth normals (nx ny nz): the output of
`bootsurf generate`/`sample` after `bootsurf noise`, which moves the points and
keeps their normals.

Per input, `--reps` rounds; in each round every program runs once, in an order
rotated by one from the previous round, so that slow phases of a shared machine
fall on different programs. Reported per program, medians over the rounds:

  compute s   the program's own monotonic timing of the computation, no file
              I/O: the kd-tree build, the neighbour search and the fits
              (bootsurf: bench/peers/normals_bootsurf, the library calls of the
              CLI; peers: see each peer's header comment).
  process s   wall time of the whole process as a user runs it, started and
              reaped by this script: start-up (Python + `import open3d` for
              Open3D), reading, computing, writing. bootsurf: the CLI
              `bootsurf normals ... -o OUT` (its JSON "seconds", the command
              without process start-up, is in the notes).
  compute CPU s  user + system CPU time of all threads over the same interval
              (getrusage): the work done, less sensitive than wall time to
              other jobs on a shared machine; CPU s / compute s = cores used.
  ratios      t(bootsurf) / t(peer) of the same round, median over rounds, for
              the corresponding methods: bootsurf PCA -B 0 against the PCA
              peers, bootsurf poly degree 2 -B 0 against CGAL jet degree 2.
              Below 1: bootsurf is faster.
  angles      unoriented angle errors against the truth, bench/peers/angle_error.py
              for every program (mean in radians, PGP5/PGP10 = share under 5/10
              degrees); also checked once against `bootsurf eval`.
  peak RSS    ru_maxrss of the process from wait4 in bench/peers/rss_exec (a
              small launcher: Linux passes a parent's RSS peak on to its
              children), bootsurf: the CLI process.
"""
import argparse
import json
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
from harness import last_json, run  # noqa: E402
PY = "/usr/bin/python3"  # python3-open3d is installed for Debian's interpreter only


def programs(a):
    """(id, program, method, group, cmd(in, out)). bootsurf runs twice per configuration:
    *_cli (the command, for process s) and *_lib (normals_bootsurf, for compute s)."""
    bs, pd, k, j = a.bootsurf, a.peers, str(a.k), str(a.threads)
    lib = os.path.join(pd, "normals_bootsurf")
    P = []
    for bid, meth, grp, extra in [
            ("bs_pca", "pca -B 0", "pca", ["--fit", "pca", "-B", "0"]),
            ("bs_pca_b50", "pca -B 50", "pca_b50", ["--fit", "pca", "-B", "50"]),
            ("bs_poly2", "poly d2 -B 0", "poly2", ["--fit", "poly", "-d", "2", "-B", "0"])]:
        P.append((bid + "_cli", "bootsurf", meth, grp,
                  lambda i, o, e=extra: [bs, "normals", i, "-o", o, "-k", k, "-j", j, "--json", "-q"] + e))
        P.append((bid + "_lib", "bootsurf", meth, grp,
                  lambda i, o, e=extra: [lib, i, "-o", o, "-k", k, "-j", j] + e))
    P.append(("pcl", "PCL 1.13", "NormalEstimationOMP", "pca",
              lambda i, o: [os.path.join(pd, "normals_pcl"), i, "-o", o, "-k", k, "-j", j]))
    P.append(("open3d", "Open3D 0.16", "estimate_normals KNN", "pca",
              lambda i, o: [PY, os.path.join(HERE, "normals_open3d.py"), i, "-o", o, "-k", k, "-j", j]))
    P.append(("cgal_pca", "CGAL 5.5", "pca_estimate_normals", "pca",
              lambda i, o: [os.path.join(pd, "normals_cgal"), i, "-o", o, "--method", "pca",
                            "-k", k, "-j", j]))
    P.append(("cgal_jet", "CGAL 5.5", "jet_estimate_normals d2", "poly2",
              lambda i, o: [os.path.join(pd, "normals_cgal"), i, "-o", o, "--method", "jet",
                            "-d", "2", "-k", k, "-j", j]))
    return P


def angle(res, truth):
    _, _, _, out = run([PY, os.path.join(HERE, "angle_error.py"), res, truth], res + ".ang", None)
    return last_json(out)


def max_normal_diff(a, b):
    import numpy as np
    from angle_error import read_fields
    na = read_fields(a, ["nx", "ny", "nz"])
    nb = read_fields(b, ["nx", "ny", "nz"])
    return float(np.abs(na - nb).max())


def fmt(x, spec, empty="-"):
    return empty if x is None else format(x, spec)


def one_input(a, name, path, env):
    P = programs(a)
    work = os.path.join(a.work, name)
    os.makedirs(work, exist_ok=True)
    res = {p[0]: {"wall": [], "rss": [], "cpu": [], "compute": [], "compute_cpu": [], "json": None}
           for p in P}
    load_before = os.getloadavg()
    t_start = time.monotonic()
    for r in range(a.reps):
        order = P[r % len(P):] + P[:r % len(P)]
        for pid, prog, meth, grp, cmd in order:
            out = os.path.join(work, pid + ".ply")
            wall, rss, cpu, text = run(cmd(path, out), out, env, a.launcher)
            js = last_json(text)
            d = res[pid]
            d["wall"].append(wall)
            d["rss"].append(rss)
            d["cpu"].append(cpu)
            d["compute"].append(js.get("seconds"))
            d["compute_cpu"].append(js.get("cpu_seconds"))
            d["json"] = js
            print("  [%s round %d] %-12s %-22s process %8.3f s  own %8.3f s" %
                  (name, r + 1, pid, meth, wall, js.get("seconds", float("nan"))),
                  file=sys.stderr, flush=True)
    load_after = os.getloadavg()
    npts = res["pcl"]["json"]["points"]
    truth = path

    # rows: bootsurf rows join the compute run (lib) and the CLI run
    rows = []
    bs_ref = {"pca": "bs_pca", "poly2": "bs_poly2"}
    for pid, prog, meth, grp, cmd in P:
        if pid.endswith("_cli"):
            continue
        if pid.endswith("_lib"):
            base = pid[:-4]
            comp, whole = res[pid], res[base + "_cli"]
            ang_file = os.path.join(work, base + "_cli.ply")
        else:
            base, comp, whole = pid, res[pid], res[pid]
            ang_file = os.path.join(work, pid + ".ply")
        ratio_c = ratio_w = ratio_cpu = None
        if not pid.startswith("bs_") and grp in bs_ref:
            b = bs_ref[grp]

            def ratio(x, y):  # per round (the same loop), then the median
                return statistics.median(u / v for u, v in zip(x, y))
            ratio_c = ratio(res[b + "_lib"]["compute"], comp["compute"])
            ratio_cpu = ratio(res[b + "_lib"]["compute_cpu"], comp["compute_cpu"])
            ratio_w = ratio(res[b + "_cli"]["wall"], whole["wall"])
        ang = angle(ang_file, truth)
        tc = statistics.median(comp["compute"])
        rows.append({
            "id": base, "program": prog, "method": meth, "compute_s": tc,
            "points_per_s": npts / tc, "ratio_compute": ratio_c,
            "compute_cpu_s": statistics.median(comp["compute_cpu"]), "ratio_compute_cpu": ratio_cpu,
            "process_cpu_s": statistics.median(whole["cpu"]),
            "process_s": statistics.median(whole["wall"]), "ratio_process": ratio_w,
            "cli_json_seconds": (statistics.median(res[base + "_cli"]["compute"])
                                 if pid.endswith("_lib") else None),
            "compute_runs": comp["compute"], "process_runs": whole["wall"],
            "peak_rss_kb": max(whole["rss"]), "peak_rss_kb_compute_run": max(comp["rss"]),
            "mean_rad": ang["mean_rad"], "median_rad": ang["median_rad"],
            "pgp5": ang["under5deg"], "pgp10": ang["under10deg"], "invalid": ang["invalid"],
            "peer_json": comp["json"]})

    # checks: library driver == CLI; angle_error.py == bootsurf eval
    checks = {}
    for b in ("bs_pca", "bs_pca_b50", "bs_poly2"):
        checks[b + " lib vs CLI max|dn|"] = max_normal_diff(os.path.join(work, b + "_lib.ply"),
                                                            os.path.join(work, b + "_cli.ply"))
    _, _, _, ev = run([a.bootsurf, "eval", os.path.join(work, "pcl.ply"), "--truth", truth, "--json", "-q"],
                   os.path.join(work, "eval"), env)
    ev = last_json(ev)["normals"]
    pcl_row = [x for x in rows if x["id"] == "pcl"][0]
    checks["PCL mean_rad: angle_error.py vs bootsurf eval"] = (pcl_row["mean_rad"], ev["mean_rad"])

    return {"input": name, "path": path, "points": npts, "k": a.k, "threads": a.threads,
            "reps": a.reps, "load_before": load_before, "load_after": load_after,
            "minutes": (time.monotonic() - t_start) / 60, "rows": rows, "checks": checks}


def print_table(t):
    print()
    print("### %s: %d points, K = %d, %d threads, median of %d rounds" %
          (t["input"], t["points"], t["k"], t["threads"], t["reps"]))
    print("load average (1/5/15 min) before %.2f %.2f %.2f, after %.2f %.2f %.2f; %.1f min" %
          (tuple(t["load_before"]) + tuple(t["load_after"]) + (t["minutes"],)))
    print()
    print("| program | method | compute s | points/s | bs/peer compute | compute CPU s | bs/peer CPU "
          "| process s | bs/peer process | mean angle rad | PGP5 | PGP10 | peak RSS MB |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in t["rows"]:
        print("| %s | %s | %.3f | %s | %s | %.3f | %s | %.3f | %s | %.5f | %.4f | %.4f | %.0f |" % (
            r["program"], r["method"], r["compute_s"], format(r["points_per_s"], ",.0f"),
            fmt(r["ratio_compute"], ".2f"), r["compute_cpu_s"], fmt(r["ratio_compute_cpu"], ".2f"),
            r["process_s"], fmt(r["ratio_process"], ".2f"),
            r["mean_rad"], r["pgp5"], r["pgp10"], r["peak_rss_kb"] / 1024))
    notes = []
    for r in t["rows"]:
        if r["cli_json_seconds"] is not None:
            notes.append("bootsurf %s: CLI JSON \"seconds\" (read + compute + write) %.3f s; "
                         "compute-run peak RSS %.0f MB" %
                         (r["method"], r["cli_json_seconds"], r["peak_rss_kb_compute_run"] / 1024))
        if r["invalid"]:
            notes.append("%s %s: %d invalid normals (counted as 90 degrees)" %
                         (r["program"], r["method"], r["invalid"]))
        pj = r["peer_json"] or {}
        if pj.get("peer") == "cgal" and not pj.get("tbb"):
            notes.append("CGAL ran sequentially (no TBB)")
    for k, v in t["checks"].items():
        notes.append("check %s: %s" % (k, v))
    print()
    for n in notes:
        print("- " + n)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bootsurf", required=True)
    ap.add_argument("--peers", required=True)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--k", type=int, default=30)
    ap.add_argument("--work", required=True)
    ap.add_argument("--json-out")
    ap.add_argument("inputs", nargs="+", help="NAME=INPUT.ply")
    a = ap.parse_args()
    a.launcher = os.path.join(a.peers, "rss_exec")
    env = dict(os.environ, OMP_NUM_THREADS=str(a.threads))
    tables = []
    for spec in a.inputs:
        name, path = spec.split("=", 1)
        print("== %s (%s)" % (name, path), file=sys.stderr, flush=True)
        t = one_input(a, name, path, env)
        print_table(t)
        sys.stdout.flush()
        tables.append(t)
    if a.json_out:
        with open(a.json_out, "w") as f:
            json.dump(tables, f, indent=1)


if __name__ == "__main__":
    main()
