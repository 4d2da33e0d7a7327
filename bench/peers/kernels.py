#!/usr/bin/python3
"""kernels — two side-by-side comparisons of bench/run.sh, and its summary.

usage: /usr/bin/python3 kernels.py knn   --bootsurf BUILD/bootsurf --peers PEERS_DIR --work DIR
           [--threads 2] [--reps 3] [--k 50] [--no-legacy] [--json-out FILE] NAME=INPUT.ply
       /usr/bin/python3 kernels.py error --bootsurf BUILD/bootsurf --peers PEERS_DIR --work DIR
           [--threads 2] [--reps 3] [--k 50] [--bootstrap 50] [--degree 3] [--jet-degrees 3]
           [--json-out FILE] NAME=INPUT.ply
       /usr/bin/python3 kernels.py summary [--normals F] [--knn F] [--error F] [--smooth F]

knn: all-K-nearest neighbours of every point of INPUT (the point itself
    among its K), tree build included and also reported apart:
      bootsurf     bench/peers/knn_bootsurf (bsurf_knn_build + bsurf_knn_all)
      nanoflann    bench/peers/knn_nanoflann (KDTreeSingleIndexAdaptor, knnSearch
                   per point in an OpenMP loop), the queries in the tree's leaf order
                   and, a second row, in input order (what a plain loop over the file does)
      Open3D core  bench/peers/knn_open3d.py --api core: core.nns.NearestNeighborSearch,
                   one batched knn_search (C++)
      Open3D legacy  knn_open3d.py --api legacy: geometry.KDTreeFlann and
                   search_knn_vector_3d per point in a Python loop (--no-legacy: skipped)
    Check: every program's per-point sum and largest of the K squared distances
    equal bootsurf's (relative difference; the neighbour sets agree when they do).

error: `bootsurf error` (K, B, degree) beside CGAL's jet_estimate_normals with
    the same K (CGAL's k = K - 1: it adds the point) and each --jet-degrees:
      bootsurf lib  bench/peers/error_bootsurf (bsurf_neighbors_build +
                    bsurf_estimate_error, no file I/O): compute s
      bootsurf CLI  `bootsurf error -o OUT --json`: process s, peak RSS
      CGAL jet dD   bench/peers/normals_cgal --method jet -d D: compute s incl. its k-d tree
    Ratio: bootsurf's B fits per point over one CGAL jet pass (one fit per point):
    how many CGAL jet passes the bootstrap costs. Target line: the bootstrap
    error in <= 10 s at 1,000,000 points (scaled linearly at other N).
    Accuracy: CGAL's jet normals against the truth, beside `bootsurf normals
    --fit poly -d D -B 0` (the single fit the bootstrap resamples, same K; run once,
    untimed); and the library driver's err_632plus against the CLI's.

Both: --reps rounds, each running every program once in an order rotated by one
(bench/peers/harness.py), medians; ratios are taken in the same round, then the
median. Threads: -j for everyone (Open3D via OMP_NUM_THREADS).

summary: the JSON files of the four parts (normals: compare.py --json-out;
knn, error: this script's; smooth: smooth_compare.py --bench --json-out) into one
table of the issue's targets, ratio bootsurf / peer, met or not.
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
from harness import last_json, load_now, log, median_ratio, rounds, run  # noqa: E402

PY = "/usr/bin/python3"  # python3-open3d is installed for Debian's interpreter only
TARGET_ERROR_S_AT_1M = 10.0


def med(xs):
    return statistics.median(xs)


def fmt(x, spec, empty="-"):
    return empty if x is None else format(x, spec)


def mb(kb):
    return kb / 1024.0


def collect(a, P, path, work, env):
    """Runs the programs P = [(id, cmd(in, out)), ...] in rounds; returns
    {id: {"own": [json...], "wall": [...], "rss": [...], "cpu": [...]}}."""
    os.makedirs(work, exist_ok=True)
    cmds = dict(P)
    res = {pid: {"own": [], "wall": [], "rss": [], "cpu": []} for pid, _ in P}

    def one(pid, r):
        out = os.path.join(work, pid + a.out_ext.get(pid, ".ply"))
        wall, rss, cpu, text = run(cmds[pid](path, out), out, env, a.launcher)
        js = last_json(text)
        d = res[pid]
        d["own"].append(js)
        d["wall"].append(wall)
        d["rss"].append(rss)
        d["cpu"].append(cpu)
        log("  [round %d] %-16s process %8.3f s  own %8.3f s" %
            (r + 1, pid, wall, js.get("seconds", float("nan"))))

    rounds([pid for pid, _ in P], a.reps, one)
    return res


def series(d, key):
    return [js[key] for js in d["own"]]


# ---------------------------------------------------------------- knn

def knn(a, name, path, env):
    import numpy as np
    pd, k, j = a.peers, str(a.k), str(a.threads)
    o3d = os.path.join(HERE, "knn_open3d.py")
    P = [("bootsurf", lambda i, o: [os.path.join(pd, "knn_bootsurf"), i, "-o", o, "-k", k, "-j", j]),
         ("nanoflann", lambda i, o: [os.path.join(pd, "knn_nanoflann"), i, "-o", o, "-k", k, "-j", j,
                                     "--method", "tree"]),
         ("nanoflann_input", lambda i, o: [os.path.join(pd, "knn_nanoflann"), i, "-o", o, "-k", k, "-j", j,
                                           "--method", "input"]),
         ("open3d_core", lambda i, o: [PY, o3d, i, "-o", o, "-k", k, "-j", j, "--api", "core"])]
    if not a.no_legacy:
        P.append(("open3d_legacy", lambda i, o: [PY, o3d, i, "-o", o, "-k", k, "-j", j, "--api", "legacy"]))
    labels = {"bootsurf": ("bootsurf", "bsurf_knn_build + bsurf_knn_all"),
              "nanoflann": ("nanoflann", "KDTreeSingleIndexAdaptor, knnSearch per point in tree order (OpenMP)"),
              "nanoflann_input": ("nanoflann", "KDTreeSingleIndexAdaptor, knnSearch per point in input order (OpenMP)"),
              "open3d_core": ("Open3D", "core.nns.NearestNeighborSearch knn_search, batched (C++)"),
              "open3d_legacy": ("Open3D", "KDTreeFlann search_knn_vector_3d, Python loop")}
    a.out_ext = {pid: ".f64" for pid, _ in P}
    work = os.path.join(a.work, "knn_" + name)
    load_before, t_start = load_now(), time.monotonic()
    res = collect(a, P, path, work, env)
    load_after = load_now()
    ref = np.fromfile(os.path.join(work, "bootsurf.f64")).reshape(-1, 2)
    bs = res["bootsurf"]
    rows = []
    for pid, _ in P:
        d = res[pid]
        js = d["own"][-1]
        chk = np.fromfile(os.path.join(work, pid + ".f64")).reshape(-1, 2)
        if chk.shape != ref.shape:
            rel, differ = float("inf"), ref.shape[0]
        else:
            r = np.abs(chk - ref) / np.maximum(np.abs(ref), 1e-300)
            rel, differ = float(r.max()), int((r > 1e-9).any(axis=1).sum())
        is_bs = pid == "bootsurf"
        tot, bld, sea, cpu = (series(d, x) for x in ("seconds", "seconds_build", "seconds_search",
                                                      "cpu_seconds"))
        rows.append({
            "id": pid, "program": ("%s %s" % (labels[pid][0], js.get("version", ""))).strip(),
            "method": labels[pid][1], "build_s": med(bld), "search_s": med(sea), "compute_s": med(tot),
            "compute_cpu_s": med(cpu), "points_per_s": js["points"] / med(tot),
            "process_s": med(d["wall"]), "peak_rss_kb": max(d["rss"]),
            "ratio_compute": None if is_bs else median_ratio(series(bs, "seconds"), tot),
            "ratio_search": None if is_bs else median_ratio(series(bs, "seconds_search"), sea),
            "ratio_cpu": None if is_bs else median_ratio(series(bs, "cpu_seconds"), cpu),
            "ratio_process": None if is_bs else median_ratio(bs["wall"], d["wall"]),
            "compute_runs": tot, "max_rel_diff": rel, "rows_differing": differ, "json": js})
    t = {"part": "knn", "input": name, "path": path, "points": int(ref.shape[0]), "k": a.k,
         "threads": a.threads, "reps": a.reps, "load_before": load_before, "load_after": load_after,
         "minutes": (time.monotonic() - t_start) / 60, "rows": rows}
    print()
    print("### All-kNN alone: %s, %d points, K = %d (the point included), %d threads, median of %d "
          "rounds" % (name, t["points"], a.k, a.threads, a.reps))
    print_load(t)
    print()
    print("| program | method | build s | search s | total s | points/s | bs/peer total | bs/peer search "
          "| CPU s | bs/peer CPU | process s | peak RSS MB | distances vs bootsurf |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for r in rows:
        agree = "(reference)" if r["id"] == "bootsurf" else (
            "equal (max rel. %.1e)" % r["max_rel_diff"] if r["rows_differing"] == 0 else
            "**%d points differ** (max rel. %.1e)" % (r["rows_differing"], r["max_rel_diff"]))
        print("| %s | %s | %.3f | %.3f | %.3f | %s | %s | %s | %.3f | %s | %.3f | %.0f | %s |" % (
            r["program"], r["method"], r["build_s"], r["search_s"], r["compute_s"],
            format(r["points_per_s"], ",.0f"), fmt(r["ratio_compute"], ".2f"),
            fmt(r["ratio_search"], ".2f"), r["compute_cpu_s"], fmt(r["ratio_cpu"], ".2f"),
            r["process_s"], mb(r["peak_rss_kb"]), agree))
    print()
    for r in rows:
        print("- %s %s: runs total %s" % (r["program"], r["method"],
                                          ", ".join("%.3f" % x for x in r["compute_runs"])))
        if r["id"] == "nanoflann_input":
            print("  (the same search as the row above, the points queried in file order: the difference is "
                  "cache misses; Open3D's rows query in file order too)")
        if r["id"] == "open3d_core":
            print("  (Open3D's core search runs its own parallel loop; CPU s / total s = %.2f cores)" %
                  (r["compute_cpu_s"] / r["compute_s"]))
        if r["id"] == "open3d_legacy":
            print("  (one Python call per point: the time is mostly the interpreter's, single-threaded)")
    return t


# ---------------------------------------------------------------- error

def error(a, name, path, env):
    import numpy as np
    from angle_error import read_fields
    bsx, pd, k, j = a.bootsurf, a.peers, str(a.k), str(a.threads)
    B, D = str(a.bootstrap), str(a.degree)
    P = [("bs_lib", lambda i, o: [os.path.join(pd, "error_bootsurf"), i, "-o", o, "-k", k, "-B", B,
                                  "-d", D, "-j", j]),
         ("bs_cli", lambda i, o: [bsx, "error", i, "-o", o, "-k", k, "-B", B, "-d", D, "-j", j,
                                  "--json", "-q"])]
    for jd in a.jet_degrees:
        P.append(("cgal_jet%d" % jd, lambda i, o, jd=jd: [os.path.join(pd, "normals_cgal"), i, "-o", o,
                                                          "--method", "jet", "-d", str(jd), "-k", k,
                                                          "-j", j]))
    a.out_ext = {}
    work = os.path.join(a.work, "error_" + name)
    load_before, t_start = load_now(), time.monotonic()
    res = collect(a, P, path, work, env)
    load_after = load_now()
    npts = res["bs_lib"]["own"][-1]["points"]

    # accuracy: CGAL's jet normals and bootsurf's single polynomial fit, same K and degree (untimed)
    def angle(res_ply):
        _, _, _, out = run([PY, os.path.join(HERE, "angle_error.py"), res_ply, path], res_ply + ".ang", None)
        return last_json(out)

    acc = {}
    for jd in a.jet_degrees:
        ref = os.path.join(work, "bs_poly%d.ply" % jd)
        run([bsx, "normals", path, "-o", ref, "--fit", "poly", "-d", str(jd), "-B", "0", "-k", k, "-j", j,
             "-q"], ref, env)
        acc[jd] = (angle(os.path.join(work, "cgal_jet%d.ply" % jd)), angle(ref))
    e_lib = read_fields(os.path.join(work, "bs_lib.ply"), ["err_632plus"])
    e_cli = read_fields(os.path.join(work, "bs_cli.ply"), ["err_632plus"])
    lib_cli = float(np.abs(e_lib - e_cli).max())

    lib, cli = res["bs_lib"], res["bs_cli"]
    rows = []
    for pid, _ in P:
        if pid == "bs_cli":
            continue
        d = res[pid]
        whole = cli if pid == "bs_lib" else d  # bootsurf: compute s of the library, process s of the CLI
        js = d["own"][-1]
        row = {"id": pid, "compute_s": med(series(d, "seconds")),
               "compute_cpu_s": med(series(d, "cpu_seconds")), "process_s": med(whole["wall"]),
               "process_cpu_s": med(whole["cpu"]), "peak_rss_kb": max(whole["rss"]),
               "compute_runs": series(d, "seconds"), "process_runs": whole["wall"], "json": js}
        if pid == "bs_lib":
            row.update({"program": "bootsurf", "degree": a.degree,
                        "method": "error -k %d -B %d -d %d" % (a.k, a.bootstrap, a.degree),
                        "cli_json_seconds": med(series(cli, "seconds")),
                        "peak_rss_kb_compute_run": max(d["rss"])})
        else:
            jd = int(pid[len("cgal_jet"):])
            row.update({
                "program": "CGAL %s" % js["version"], "method": "jet_estimate_normals, degree %d" % jd,
                "degree": jd, "passes_compute": median_ratio(series(lib, "seconds"), series(d, "seconds")),
                "passes_cpu": median_ratio(series(lib, "cpu_seconds"), series(d, "cpu_seconds")),
                "passes_process": median_ratio(cli["wall"], d["wall"]),
                "mean_rad": acc[jd][0]["mean_rad"], "pgp5": acc[jd][0]["under5deg"],
                "bs_poly_mean_rad": acc[jd][1]["mean_rad"], "bs_poly_pgp5": acc[jd][1]["under5deg"]})
        rows.append(row)
    target = TARGET_ERROR_S_AT_1M * npts / 1e6
    t_err = rows[0]["compute_s"]
    t = {"part": "error", "input": name, "path": path, "points": npts, "k": a.k, "bootstrap": a.bootstrap,
         "degree": a.degree, "threads": a.threads, "reps": a.reps, "load_before": load_before,
         "load_after": load_after, "minutes": (time.monotonic() - t_start) / 60, "rows": rows,
         "target_s": target, "target_met": t_err <= target, "lib_vs_cli_max_abs": lib_cli,
         "neighbors_s": med(series(lib, "seconds_neighbors")),
         "estimate_s": med(series(lib, "seconds_estimate")),
         "mean_err_632plus_h": lib["own"][-1]["mean_err_632plus_h"]}
    print()
    print("### Bootstrap error beside CGAL's jet fit: %s, %d points, K = %d, B = %d, degree %d, "
          "%d threads, median of %d rounds" % (name, npts, a.k, a.bootstrap, a.degree, a.threads, a.reps))
    print_load(t)
    print()
    print("| program | method | compute s | points/s | compute CPU s | process s | process CPU s "
          "| peak RSS MB | bootstrap / jet pass, compute | CPU | process | mean angle rad | PGP5 |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print("| %s | %s | %.3f | %s | %.3f | %.3f | %.3f | %.0f | %s | %s | %s | %s | %s |" % (
            r["program"], r["method"], r["compute_s"], format(npts / r["compute_s"], ",.0f"),
            r["compute_cpu_s"], r["process_s"], r["process_cpu_s"], mb(r["peak_rss_kb"]),
            fmt(r.get("passes_compute"), ".2f"), fmt(r.get("passes_cpu"), ".2f"),
            fmt(r.get("passes_process"), ".2f"), fmt(r.get("mean_rad"), ".5f"), fmt(r.get("pgp5"), ".4f")))
    print()
    print("- target: bootstrap error (K = %d, B = %d, degree %d) in <= %.0f s at 1,000,000 points%s: "
          "%.2f s (neighbourhoods %.2f s + estimation %.2f s): **%s**" % (
              a.k, a.bootstrap, a.degree, TARGET_ERROR_S_AT_1M,
              "" if npts == 1000000 else " (here %.2f s, scaled to %d points)" % (target, npts),
              t_err, t["neighbors_s"], t["estimate_s"], "met" if t["target_met"] else "not met"))
    print("- \"bootstrap / jet pass\": bootsurf's %d fits per point (plus the estimators) over one CGAL "
          "jet pass (one fit per point), same round, median: how many CGAL jet passes the bootstrap costs"
          % a.bootstrap)
    for r in rows:
        if "bs_poly_mean_rad" in r:
            print("- accuracy, degree %d, K = %d: CGAL jet mean angle %.5f rad (PGP5 %.4f); bootsurf's "
                  "single fit (`bootsurf normals --fit poly -d %d -B 0`, untimed) %.5f rad (PGP5 %.4f)" % (
                      r["degree"], a.k, r["mean_rad"], r["pgp5"], r["degree"], r["bs_poly_mean_rad"],
                      r["bs_poly_pgp5"]))
    b = rows[0]
    print("- bootsurf: compute s = error_bootsurf (the library calls of the command, no file I/O); "
          "process s, process CPU s and peak RSS = the command `bootsurf error -o OUT` (its JSON \"seconds\", "
          "read + compute + write: %.3f s; the library run's peak RSS %.0f MB)" %
          (b["cli_json_seconds"], mb(b["peak_rss_kb_compute_run"])))
    print("- bootsurf: mean err_632plus %.4f h; check library driver vs CLI, err_632plus max |diff| %.3g"
          % (t["mean_err_632plus_h"], lib_cli))
    for r in rows:
        print("- %s %s: runs compute %s; process %s" % (
            r["program"], r["method"], ", ".join("%.3f" % x for x in r["compute_runs"]),
            ", ".join("%.3f" % x for x in r["process_runs"])))
    return t


def print_load(t):
    print("load average (1/5/15 min) before %.2f %.2f %.2f, after %.2f %.2f %.2f; %.1f min" %
          (tuple(t["load_before"]) + tuple(t["load_after"]) + (t["minutes"],)))


# ---------------------------------------------------------------- summary

def summary(a):
    """One row per target of the performance issue, from whatever parts ran."""
    lines = []  # (target, input, measured, goal text, met text, note)

    def add(what, inp, ratio, goal, met, note="", points=1000000):
        # the targets are set at 1,000,000 points: elsewhere the verdict is in brackets
        m = "-" if met is None else ("yes" if met else "**no**")
        if met is not None and points != 1000000:
            m = "(%s)" % m.strip("*")
            note = "; ".join(x for x in (note, "target set at 1M points") if x)
        lines.append((what, inp, ratio, goal, m, note))

    if a.normals:
        for t in json.load(open(a.normals)):
            by = {r["id"]: r for r in t["rows"]}
            for pid, what, goal in (("open3d", "PCA normals K=%d / Open3D estimate_normals" % t["k"], 0.5),
                                    ("pcl", "PCA normals K=%d / PCL NormalEstimationOMP" % t["k"], 0.5),
                                    ("cgal_pca", "PCA normals K=%d / CGAL pca_estimate_normals" % t["k"], None),
                                    ("cgal_jet", "quadratic normals K=%d / CGAL jet_estimate_normals d2"
                                     % t["k"], 0.2)):
                if pid in by:
                    r = by[pid]["ratio_compute"]
                    add(what, "%s (%d)" % (t["input"], t["points"]), "%.2f" % r,
                        "<= %.1f" % goal if goal else "report", None if goal is None else r <= goal,
                        points=t["points"])
    if a.error:
        for t in json.load(open(a.error)):
            inp = "%s (%d)" % (t["input"], t["points"])
            add("bootstrap error K=%d B=%d d%d, compute s" % (t["k"], t["bootstrap"], t["degree"]), inp,
                "%.2f s" % t["rows"][0]["compute_s"], "<= %.2f s" % t["target_s"], t["target_met"],
                "" if t["points"] == 1000000 else "10 s at 1M scaled to N", points=t["points"])
            for r in t["rows"]:
                if "passes_compute" in r:
                    add("bootstrap error / CGAL jet_estimate_normals d%d (jet passes)" % r["degree"], inp,
                        "%.2f" % r["passes_compute"], "report (\"a few\")", None)
    if a.smooth:
        t = json.load(open(a.smooth))
        r = t["ratios"].get("bs_multipass/cgal_jet")
        if r:
            add("smooth multipass / CGAL jet_smooth_point_set, K=%d" % t["k"],
                "%s (%d)" % (t["input"], t["points"]), "%.2f" % r[0], "< 1", r[0] < 1, points=t["points"])
    if a.knn:
        for t in json.load(open(a.knn)):
            for r in t["rows"]:
                if r["ratio_compute"] is not None:
                    add("all-kNN K=%d / %s %s" % (t["k"], r["program"], r["method"]),
                        "%s (%d)" % (t["input"], t["points"]),
                        "%.2f (search %.2f)" % (r["ratio_compute"], r["ratio_search"]), "report", None,
                        "" if r["rows_differing"] == 0 else "%d points differ" % r["rows_differing"])
    print()
    print("### Summary: bootsurf / peer, same run, same inputs, same thread count; below 1: bootsurf is "
          "faster")
    print()
    print("| target | input (points) | measured | goal | met | note |")
    print("|---|---|---:|---|---|---|")
    for line in lines:
        print("| %s | %s | %s | %s | %s | %s |" % line)
    if not lines:
        print("| (no part ran) | | | | | |")


# ---------------------------------------------------------------- main

def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="part", required=True)
    for name in ("knn", "error"):
        p = sub.add_parser(name)
        p.add_argument("--bootsurf", required=True)
        p.add_argument("--peers", required=True)
        p.add_argument("--work", required=True)
        p.add_argument("--threads", type=int, default=2)
        p.add_argument("--reps", type=int, default=3)
        p.add_argument("--k", type=int, default=50)
        p.add_argument("--json-out")
        p.add_argument("inputs", nargs="+", help="NAME=INPUT.ply")
        if name == "knn":
            p.add_argument("--no-legacy", action="store_true",
                           help="skip Open3D's KDTreeFlann Python loop")
        else:
            p.add_argument("--bootstrap", type=int, default=50)
            p.add_argument("--degree", type=int, default=3)
            p.add_argument("--jet-degrees", default="3", help="CGAL jet degrees, comma-separated")
    p = sub.add_parser("summary")
    for f in ("normals", "knn", "error", "smooth"):
        p.add_argument("--" + f)
    a = ap.parse_args()
    if a.part == "summary":
        summary(a)
        return
    if a.part == "error":
        a.jet_degrees = [int(x) for x in a.jet_degrees.split(",") if x]
    a.launcher = os.path.join(a.peers, "rss_exec")
    env = dict(os.environ, OMP_NUM_THREADS=str(a.threads))
    tables = []
    for spec in a.inputs:
        name, path = spec.split("=", 1)
        log("== %s %s (%s)" % (a.part, name, path))
        tables.append((knn if a.part == "knn" else error)(a, name, path, env))
        sys.stdout.flush()
    if a.json_out:
        with open(a.json_out, "w") as f:
            json.dump(tables, f, indent=1)


if __name__ == "__main__":
    main()
