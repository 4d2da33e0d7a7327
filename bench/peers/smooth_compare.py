#!/usr/bin/python3
"""smooth_compare — runs `bootsurf smooth` (naive, bilateral, multipass) and the
smoothing peers (CGAL jet_smooth_point_set, CGAL bilateral_smooth_point_set, PCL
MovingLeastSquares) on the same noisy inputs and prints the tables. Called by
bench/smooth_compare.sh, which builds the peers and makes the inputs.

usage: /usr/bin/python3 smooth_compare.py --bootsurf BUILD/bootsurf --peers PEERS_DIR --work DIR
           [--threads 2] [--k 50] [--seed 1] [--reps 3] [--bench] [--peers-only]
           [--json-out FILE] [--methods naive,bilateral,multipass] [--peer-methods jet,bilateral,mls]
           --input NAME NOISE NOISY.ply TRUTH.ply SURFACE|- [--input ...]

Quality mode (default): every program once per input; each output (and the
noisy input itself, the "before" row) is evaluated by
`bootsurf eval OUT --truth TRUTH [--surface SURFACE] --json` ("position": mean,
rms, max distance to the true surface in units of h, overall and, when the truth
has a `feature` field, for its feature and non-feature points). One table.

Bench mode (--bench): one input (the 1M-point sphere); --reps rounds, every
program once per round in an order rotated by one each round; medians of
compute s (each program's own timing without file I/O: bootsurf's JSON
"compute_seconds", the peers' "seconds"), points/s, process s (wall of the
whole process, start-up and file I/O included), CPU s, peak RSS, and the ratios
t(bootsurf method) / t(peer) taken in the same round, then the median.

--peers-only: no bootsurf smooth rows (for testing the peer half before
`bootsurf smooth` exists); when `bootsurf eval` has no "position" section yet,
the analytic inputs (names starting with sphere/cube) are measured by
position_error.py instead and the mesh inputs get "-".
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
PY = "/usr/bin/python3"


def programs(a):
    """(id, program, method, kind, cmd(in, out)); kind "bs" or "peer". --methods and
    --peer-methods choose the rows (all by default)."""
    bs, pd, k, j, seed = a.bootsurf, a.peers, str(a.k), str(a.threads), str(a.seed)
    P = []
    if not a.peers_only:
        for m in a.methods:
            P.append(("bs_" + m, "bootsurf", m + " (defaults)", "bs",
                      lambda i, o, m=m: [bs, "smooth", i, "-o", o, "--method", m, "-j", j,
                                         "--seed", seed, "--json", "-q"]))
    cg = os.path.join(pd, "smooth_cgal")
    if "jet" in a.peer_methods:
        P.append(("cgal_jet", "CGAL 5.5", "jet_smooth_point_set d2", "peer",
                  lambda i, o: [cg, i, "-o", o, "--method", "jet", "-d", "2", "-k", k, "-j", j]))
    if "bilateral" in a.peer_methods:
        P.append(("cgal_bilateral", "CGAL 5.5", "bilateral_smooth_point_set 25deg x3", "peer",
                  lambda i, o: [cg, i, "-o", o, "--method", "bilateral", "--sharpness", "25",
                                "--iterations", "3", "-k", k, "-j", j]))
    if "mls" in a.peer_methods:
        P.append(("pcl_mls", "PCL 1.13", "MovingLeastSquares d2", "peer",
                  lambda i, o: [os.path.join(pd, "smooth_pcl"), i, "-o", o, "-d", "2", "-k", k,
                                "-j", j]))
    return P


def own_seconds(js, kind):
    return js.get("compute_seconds") if kind == "bs" else js.get("seconds")


class Evaluator:
    def __init__(self, a, env):
        self.a, self.env = a, env
        self.h_cache = {}
        self.fallback_used = False

    def analytic(self, res, truth, name):
        """position_error.py's numbers (analytic sphere/cube), or None for other inputs."""
        shape = next((s for s in ("sphere", "cube") if name.startswith(s)), None)
        if not shape:
            return None
        if truth not in self.h_cache:
            _, _, _, info = run([self.a.bootsurf, "info", truth, "--json", "-q"], res + ".info", self.env)
            self.h_cache[truth] = last_json(info)["h"]
        _, _, _, pe = run([PY, os.path.join(HERE, "position_error.py"), res, "--shape", shape,
                           "--h", repr(self.h_cache[truth]), "--truth", truth], res + ".pe", None)
        return last_json(pe)

    def __call__(self, res, truth, surface, name, tag):
        cmd = [self.a.bootsurf, "eval", res, "--truth", truth, "--json", "-q"]
        if surface:
            cmd += ["--surface", surface]
        try:
            _, _, _, out = run(cmd, res + ".eval", self.env)
            ev = last_json(out)
        except RuntimeError:
            if not self.a.peers_only:
                raise
            ev = {}  # an eval without the position section: nothing else to score here
        if "position" in ev:
            return ev["position"], ev
        if not self.a.peers_only:
            raise RuntimeError("bootsurf eval printed no \"position\" section for " + res)
        pe = self.analytic(res, truth, name)
        self.fallback_used = self.fallback_used or pe is not None
        return pe, ev


def fmt(x, spec=".3f"):
    return "-" if x is None else format(x, spec)


def part(pos, key, stat):
    if pos is None:
        return None
    d = pos if key is None else pos.get(key)
    if not isinstance(d, dict):
        return None
    return d.get(stat)


def quality(a, env, ev):
    P = programs(a)
    rows, notes = [], []
    checked = False
    for name, noise, noisy, truth, surface in a.input:
        surface = None if surface == "-" else surface
        work = os.path.join(a.work, "%s_noise%s" % (name, noise))
        os.makedirs(work, exist_ok=True)
        print("== %s noise %s" % (name, noise), file=sys.stderr, flush=True)
        h_noted = False
        pos, full = ev(noisy, truth, surface, name, "before")
        rows.append({"input": name, "noise": noise, "program": "noisy input", "method": "before",
                     "position": pos, "compute_s": None, "process_s": None, "json": None})
        for pid, prog, meth, kind, cmd in P:
            out = os.path.join(work, pid + ".ply")
            wall, rss, cpu, text = run(cmd(noisy, out), out, env, a.launcher)
            js = last_json(text)
            pos, full = ev(out, truth, surface, name, pid)
            print("  %-16s %-38s compute %8.3f s  process %8.3f s  mean %s h" %
                  (pid, meth, own_seconds(js, kind) or float("nan"), wall,
                   fmt(part(pos, None, "mean_h"), ".4f")), file=sys.stderr, flush=True)
            rows.append({"input": name, "noise": noise, "program": prog, "method": meth, "id": pid,
                         "position": pos, "compute_s": own_seconds(js, kind), "process_s": wall,
                         "peak_rss_kb": rss, "json": js,
                         "normals": full.get("normals", {}).get("mean_rad") if isinstance(
                             full.get("normals"), dict) else None})
            if pid == "cgal_jet" and not checked and not ev.fallback_used:
                pe = ev.analytic(out, truth, name)
                if pe and pos:
                    checked = True
                    notes.append("check %s noise %s, CGAL jet: bootsurf eval mean_h %.6f rms_h %.6f, "
                                 "position_error.py (analytic) mean_h %.6f rms_h %.6f" %
                                 (name, noise, pos["mean_h"], pos["rms_h"], pe["mean_h"], pe["rms_h"]))
            if pid == "pcl_mls":
                notes.append("%s noise %s: PCL MLS radius %.4g (mean %.1f points inside), dropped %d "
                             "of %d points (kept at their input position), polynomial not fitted "
                             "(fewer than 30 inside) at %.2f%% of a sample" %
                             (name, noise, js["radius"], js["mean_inside_radius"], js["dropped"],
                              js["points"], 100 * js["plane_only_share"]))
            if pid == "cgal_bilateral" and js.get("unoriented"):
                notes.append("%s noise %s: CGAL mst_orient_normals left %d points unoriented" %
                             (name, noise, js["unoriented"]))
            if kind == "bs" and not h_noted:
                h = js.get("h")
                if h and pos and "h" in pos and abs(pos["h"] - h) > 0.05 * h:
                    notes.append("%s noise %s: h of bootsurf smooth's JSON (moved_*_h) %.4g is the noisy "
                                 "input's spacing; eval's h (the table's unit) %.4g is the truth's" %
                                 (name, noise, h, pos["h"]))
                    h_noted = True
    print()
    print("### Smoothing: distance to the true surface in units of h (bootsurf eval), K = %d, "
          "%d threads" % (a.k, a.threads))
    print()
    print("| input | noise | program | method | mean h | RMS h | feature mean h | feature RMS h "
          "| non-feature mean h | non-feature RMS h | compute s | process s |")
    print("|---|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        p = r["position"]
        print("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            r["input"], r["noise"], r["program"], r["method"],
            fmt(part(p, None, "mean_h"), ".4f"), fmt(part(p, None, "rms_h"), ".4f"),
            fmt(part(p, "feature", "mean_h"), ".4f"), fmt(part(p, "feature", "rms_h"), ".4f"),
            fmt(part(p, "non_feature", "mean_h"), ".4f"), fmt(part(p, "non_feature", "rms_h"), ".4f"),
            fmt(r["compute_s"]), fmt(r["process_s"])))
    if ev.fallback_used:
        notes.append("bootsurf eval has no position section yet: sphere/cube rows measured by "
                      "bench/peers/position_error.py (analytic surface), mesh rows '-'")
    print()
    for n in notes:
        print("- " + n)
    return {"mode": "quality", "k": a.k, "threads": a.threads, "rows": rows, "notes": notes}


def bench(a, env, ev):
    P = programs(a)
    if len(a.input) != 1:
        raise SystemExit("smooth_compare: --bench takes one --input")
    name, noise, noisy, truth, surface = a.input[0]
    surface = None if surface == "-" else surface
    work = os.path.join(a.work, "bench_%s_noise%s" % (name, noise))
    os.makedirs(work, exist_ok=True)
    res = {p[0]: {"compute": [], "wall": [], "cpu": [], "rss": [], "json": None} for p in P}
    load_before = os.getloadavg()
    t_start = time.monotonic()
    for r in range(a.reps):
        order = P[r % len(P):] + P[:r % len(P)]
        for pid, prog, meth, kind, cmd in order:
            out = os.path.join(work, pid + ".ply")
            wall, rss, cpu, text = run(cmd(noisy, out), out, env, a.launcher)
            js = last_json(text)
            d = res[pid]
            d["compute"].append(own_seconds(js, kind))
            d["wall"].append(wall)
            d["cpu"].append(cpu)
            d["rss"].append(rss)
            d["json"] = js
            print("  [round %d] %-16s %-38s compute %8.3f s  process %8.3f s" %
                  (r + 1, pid, meth, own_seconds(js, kind), wall), file=sys.stderr, flush=True)
    load_after = os.getloadavg()
    minutes = (time.monotonic() - t_start) / 60
    npts = res[P[-1][0]]["json"]["points"]
    rows = []
    for pid, prog, meth, kind, cmd in P:
        d = res[pid]
        pos, _ = ev(os.path.join(work, pid + ".ply"), truth, surface, name, pid)
        tc = statistics.median(d["compute"])
        rows.append({"id": pid, "program": prog, "method": meth, "kind": kind, "compute_s": tc,
                     "points_per_s": npts / tc, "process_s": statistics.median(d["wall"]),
                     "process_cpu_s": statistics.median(d["cpu"]), "peak_rss_kb": max(d["rss"]),
                     "compute_runs": d["compute"], "process_runs": d["wall"],
                     "mean_h": part(pos, None, "mean_h"), "rms_h": part(pos, None, "rms_h"),
                     "json": d["json"]})
    bs_ids = [p[0] for p in P if p[3] == "bs"]
    peer_ids = [p[0] for p in P if p[3] == "peer"]
    ratios = {}
    for b in bs_ids:
        for q in peer_ids:
            ratios[(b, q)] = (
                statistics.median(x / y for x, y in zip(res[b]["compute"], res[q]["compute"])),
                statistics.median(x / y for x, y in zip(res[b]["wall"], res[q]["wall"])))
    pos_before, _ = ev(noisy, truth, surface, name, "before")
    print()
    print("### Smoothing speed: %s, %d points, noise %s, K = %d, %d threads, median of %d rounds" %
          (name, npts, noise, a.k, a.threads, a.reps))
    print("load average (1/5/15 min) before %.2f %.2f %.2f, after %.2f %.2f %.2f; %.1f min" %
          (tuple(load_before) + tuple(load_after) + (minutes,)))
    print()
    print("| program | method | compute s | points/s | process s | process CPU s | peak RSS MB "
          "| mean h | RMS h |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    print("| noisy input | before | | | | | | %s | %s |" %
          (fmt(part(pos_before, None, "mean_h"), ".4f"), fmt(part(pos_before, None, "rms_h"), ".4f")))
    for r in rows:
        print("| %s | %s | %.3f | %s | %.3f | %.3f | %.0f | %s | %s |" % (
            r["program"], r["method"], r["compute_s"], format(r["points_per_s"], ",.0f"),
            r["process_s"], r["process_cpu_s"], r["peak_rss_kb"] / 1024,
            fmt(r["mean_h"], ".4f"), fmt(r["rms_h"], ".4f")))
    if bs_ids:
        print()
        print("bootsurf / peer, compute s (process s in brackets), same round, median; below 1: "
              "bootsurf is faster")
        print()
        names = {p[0]: p[2] for p in P}
        print("| bootsurf \\ peer | " + " | ".join(names[q] for q in peer_ids) + " |")
        print("|---|" + "---:|" * len(peer_ids))
        for b in bs_ids:
            print("| %s | %s |" % (names[b], " | ".join(
                "%.2f (%.2f)" % ratios[(b, q)] for q in peer_ids)))
    print()
    for r in rows:
        js = r["json"]
        if r["id"] == "cgal_bilateral":
            print("- CGAL bilateral compute split (last round): jet normals %.2f s, MST orientation "
                  "%.2f s, 3 bilateral passes %.2f s" %
                  (js["normals_seconds"], js["orient_seconds"], js["smooth_seconds"]))
        if r["id"] == "pcl_mls":
            print("- PCL MLS: radius %.4g (mean %.1f points inside), dropped %d points; the radius "
                  "choice took %.3f s (not in compute s)" %
                  (js["radius"], js["mean_inside_radius"], js["dropped"], js["radius_seconds"]))
        if r["kind"] == "bs":
            print("- bootsurf %s: JSON seconds (whole command) %.3f s; runs compute %s" %
                  (r["method"], js.get("seconds", float("nan")),
                   ", ".join("%.2f" % x for x in r["compute_runs"])))
        else:
            print("- %s %s: runs compute %s" % (r["program"], r["method"],
                                                ", ".join("%.2f" % x for x in r["compute_runs"])))
    return {"mode": "bench", "input": name, "points": npts, "reps": a.reps, "k": a.k,
            "threads": a.threads, "load_before": load_before, "load_after": load_after,
            "minutes": minutes, "rows": rows,
            "ratios": {"%s/%s" % k: v for k, v in ratios.items()}}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bootsurf", required=True)
    ap.add_argument("--peers", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--k", type=int, default=50)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--bench", action="store_true")
    ap.add_argument("--peers-only", action="store_true")
    ap.add_argument("--json-out")
    ap.add_argument("--methods", default="naive,bilateral,multipass",
                    help="bootsurf smooth methods, comma-separated")
    ap.add_argument("--peer-methods", default="jet,bilateral,mls",
                    help="peers, comma-separated: jet (CGAL), bilateral (CGAL), mls (PCL)")
    ap.add_argument("--input", nargs=5, action="append", required=True,
                    metavar=("NAME", "NOISE", "NOISY", "TRUTH", "SURFACE"))
    a = ap.parse_args()
    a.methods = [m for m in a.methods.split(",") if m]
    a.peer_methods = [m for m in a.peer_methods.split(",") if m]
    bad = [m for m in a.methods if m not in ("naive", "bilateral", "multipass")] + \
        [m for m in a.peer_methods if m not in ("jet", "bilateral", "mls")]
    if bad or not a.peer_methods:
        ap.error("unknown or no methods: %s" % ",".join(bad))
    a.launcher = os.path.join(a.peers, "rss_exec")
    env = dict(os.environ, OMP_NUM_THREADS=str(a.threads))
    ev = Evaluator(a, env)
    out = bench(a, env, ev) if a.bench else quality(a, env, ev)
    sys.stdout.flush()
    if a.json_out:
        with open(a.json_out, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
