#!/usr/bin/env python3
"""scaling — how `bootsurf error`'s time and memory grow with N, B, K and the
thread count; called by bench/scaling.sh (which explains the options), prints
markdown tables for docs/performance.md.

Every measurement is one run of BUILD/bench_error N THREADS K B DEGREE (the
library calls of `bootsurf error` on an in-memory noisy sphere, no file I/O;
its JSON line gives wall and CPU time of the neighbourhood step — k-d tree,
all-kNN, h — and of the estimation step), started under bench/peers/rss_exec
for the process's peak RSS. A configuration shared by several tables (e.g.
N = 1M, K = 50, B = 50, 2 threads) is run once. With --reps R every
configuration runs R times, in rounds, and the tables show medians.

CPU s (user + system of all threads) is given beside wall time: the machine is
shared, and CPU time moves much less with other jobs than wall time does.
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
from harness import last_json, load_now, log, run  # noqa: E402


def ints(s):
    return [int(float(x)) for x in s.split()]


class Runner:
    def __init__(self, a):
        self.a = a
        self.done = {}  # (n, threads, k, b) -> list of results

    def key(self, n, t=None, k=None, b=None):
        a = self.a
        return (n, a.threads if t is None else t, a.k if k is None else k, a.b if b is None else b)

    def want(self, *keys):
        for key in keys:
            self.done.setdefault(key, [])

    def measure(self):
        """Runs every wanted configuration reps times, in rounds (smallest first)."""
        a = self.a
        keys = sorted(self.done, key=lambda k: (k[0] * k[3], k))
        for r in range(a.reps):
            for key in keys:
                n, t, k, b = key
                out = os.path.join(a.work, "n%d_t%d_k%d_b%d_r%d" % (n, t, k, b, r))
                wall, rss, cpu, text = run([a.bench_error, str(n), str(t), str(k), str(b), str(a.degree)],
                                           out, None, a.launcher)
                js = last_json(text)
                js.update({"process_s": wall, "process_cpu_s": cpu, "process_rss_kb": rss})
                self.done[key].append(js)
                log("  [round %d] N=%d threads=%d K=%d B=%d: neighbourhoods %.2f s, estimation %.2f s "
                    "(CPU %.2f s), peak RSS %.0f MB" % (r + 1, n, t, k, b, js["seconds_neighbors"],
                                                       js["seconds_estimate"], js["cpu_estimate"],
                                                       rss / 1024))

    def get(self, key, field):
        xs = [js[field] for js in self.done[key]]
        return statistics.median(xs) if field != "process_rss_kb" else max(xs)


def row_common(R, key):
    n = key[0]
    g = lambda f: R.get(key, f)  # noqa: E731
    return {"n": n, "threads": key[1], "k": key[2], "b": key[3],
            "nb_s": g("seconds_neighbors"), "est_s": g("seconds_estimate"), "total_s": g("seconds"),
            "nb_cpu": g("cpu_neighbors"), "est_cpu": g("cpu_estimate"), "total_cpu": g("cpu_seconds"),
            "rss_kb": g("process_rss_kb"), "pps": n / g("seconds"), "cpu_us_per_point": 1e6 * g("cpu_seconds") / n}


def table(title, header, rows, note=""):
    """A markdown table under a ### title: header cells, rows of cell strings, numbers right-aligned."""
    print()
    print("### " + title)
    print()
    print("| " + " | ".join(header) + " |")
    print("|" + "---:|" * len(header))
    for r in rows:
        print("| " + " | ".join(r) + " |")
    if note:
        print()
        print(note)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bench-error", required=True)
    ap.add_argument("--launcher", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--parts", default="n b k threads")
    ap.add_argument("--ns", default="100000 1000000 4000000")
    ap.add_argument("--sweep-n", type=int, default=1000000)
    ap.add_argument("--bs", default="10 50 200")
    ap.add_argument("--ks", default="20 50 100")
    ap.add_argument("--threads-list", default="1 2")
    ap.add_argument("--k", type=int, default=50)
    ap.add_argument("--b", type=int, default=50)
    ap.add_argument("--degree", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--reps", type=int, default=1)
    ap.add_argument("--big-n", type=int, default=0, help="also this N (e.g. 10000000); 0: none")
    ap.add_argument("--json-out")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    parts = a.parts.split()
    R = Runner(a)
    sn = a.sweep_n
    plan = {
        "n": [R.key(n) for n in ints(a.ns)] + ([R.key(a.big_n)] if a.big_n else []),
        "b": [R.key(sn, b=b) for b in ints(a.bs)],
        "k": [R.key(sn, k=k) for k in ints(a.ks)],
        "threads": [R.key(sn, t=t) for t in ints(a.threads_list)],
    }
    for p in parts:
        if p not in plan:
            sys.exit("scaling: unknown part %r (n, b, k, threads)" % p)
        R.want(*plan[p])
    load_before, t0 = load_now(), time.monotonic()
    R.measure()
    load_after = load_now()
    out = {"load_before": load_before, "load_after": load_after, "minutes": (time.monotonic() - t0) / 60,
           "degree": a.degree, "reps": a.reps, "tables": {}}

    print("load average (1/5/15 min) before %.2f %.2f %.2f, after %.2f %.2f %.2f; %.1f min; "
          "degree %d, median of %d run(s); `bench_error N THREADS K B %d` (no file I/O), peak RSS of "
          "the process" % (tuple(load_before) + tuple(load_after) + (out["minutes"], a.degree, a.reps,
                                                                      a.degree)))
    if "n" in parts:
        rows = [row_common(R, key) for key in plan["n"]]
        base = rows[0]
        for r in rows:
            r["cpu_per_point_rel"] = r["cpu_us_per_point"] / base["cpu_us_per_point"]
            r["rss_bytes_per_point"] = r["rss_kb"] * 1024.0 / r["n"]
        table("Time and memory against N (K = %d, B = %d, %d threads)" % (a.k, a.b, a.threads),
              ["N", "neighbourhoods s", "estimation s", "total s", "total CPU s", "points/s", "CPU µs / point",
               "CPU / point vs N = %s" % format(base["n"], ","), "peak RSS MB", "RSS bytes / point"],
              [[format(r["n"], ","), "%.2f" % r["nb_s"], "%.2f" % r["est_s"], "%.2f" % r["total_s"],
                "%.2f" % r["total_cpu"], format(r["pps"], ",.0f"), "%.2f" % r["cpu_us_per_point"],
                "%.2f" % r["cpu_per_point_rel"], "%.0f" % (r["rss_kb"] / 1024), "%.0f" % r["rss_bytes_per_point"]]
               for r in rows],
              "Near-linear: CPU per point stays near 1.00 x the smallest N's (the k-d tree's log N "
              "and cache misses on larger clouds push it up slowly).")
        out["tables"]["n"] = rows
    if "b" in parts:
        rows = [row_common(R, key) for key in plan["b"]]
        base = rows[0]
        note = ""
        if len(rows) >= 2:
            x = [r["b"] for r in rows]
            y = [r["est_cpu"] for r in rows]
            mx, my = statistics.mean(x), statistics.mean(y)
            slope = sum((u - mx) * (v - my) for u, v in zip(x, y)) / sum((u - mx) ** 2 for u in x)
            icpt = my - slope * mx
            note = ("Least-squares line: estimation CPU s = %.2f + %.4f x B (per point: %.2f µs + %.3f µs x B); "
                    "the constant is the full fit, the estimators and the frame." % (
                        icpt, slope, 1e6 * icpt / sn, 1e6 * slope / sn))
            out["b_fit"] = {"intercept_cpu_s": icpt, "slope_cpu_s_per_b": slope}
        table("Time against B (N = %s, K = %d, %d threads)" % (format(sn, ","), a.k, a.threads),
              ["B", "estimation s", "estimation CPU s", "CPU s / B", "est. CPU vs B = %d" % base["b"],
               "B / %d" % base["b"], "total s"],
              [["%d" % r["b"], "%.2f" % r["est_s"], "%.2f" % r["est_cpu"], "%.3f" % (r["est_cpu"] / r["b"]),
                "%.2f" % (r["est_cpu"] / base["est_cpu"]), "%.1f" % (r["b"] / base["b"]), "%.2f" % r["total_s"]]
               for r in rows], note)
        out["tables"]["b"] = rows
    if "k" in parts:
        rows = [row_common(R, key) for key in plan["k"]]
        table("Time and memory against K (N = %s, B = %d, %d threads)" % (format(sn, ","), a.b, a.threads),
              ["K", "neighbourhoods s", "neighbourhoods CPU s", "estimation s", "estimation CPU s", "total s",
               "CPU µs / point", "peak RSS MB", "RSS bytes / point"],
              [["%d" % r["k"], "%.2f" % r["nb_s"], "%.2f" % r["nb_cpu"], "%.2f" % r["est_s"], "%.2f" % r["est_cpu"],
                "%.2f" % r["total_s"], "%.2f" % r["cpu_us_per_point"], "%.0f" % (r["rss_kb"] / 1024),
                "%.0f" % (r["rss_kb"] * 1024.0 / r["n"])] for r in rows])
        out["tables"]["k"] = rows
    if "threads" in parts:
        rows = [row_common(R, key) for key in plan["threads"]]
        base = rows[0]
        for r in rows:
            r["speedup_est"] = base["est_s"] / r["est_s"]
            r["speedup_total"] = base["total_s"] / r["total_s"]
            # with idle cores: threads x (1-thread CPU s / this CPU s), the work's own parallel overhead
            r["speedup_cpu_bound"] = r["threads"] * base["total_cpu"] / r["total_cpu"] / base["threads"]
        table("Threads (N = %s, K = %d, B = %d)" % (format(sn, ","), a.k, a.b),
              ["threads", "neighbourhoods s", "estimation s", "total s", "total CPU s", "CPU s / total s",
               "speed-up, estimation", "speed-up, total", "bound from CPU s"],
              [["%d" % r["threads"], "%.2f" % r["nb_s"], "%.2f" % r["est_s"], "%.2f" % r["total_s"],
                "%.2f" % r["total_cpu"], "%.2f" % (r["total_cpu"] / r["total_s"]), "%.2f" % r["speedup_est"],
                "%.2f" % r["speedup_total"], "%.2f" % r["speedup_cpu_bound"]] for r in rows],
              "Target: speed-up >= 1.8 from 1 to 2 threads (wall time, total). Wall-time speed-up needs "
              "idle cores: with other jobs running it understates the code's scaling (CPU s / total s "
              "shows the cores the run got). \"Bound from CPU s\" = threads x CPU s(1 thread) / CPU s: the "
              "speed-up on idle cores if nothing but the extra work of threading limited it.")
        out["tables"]["threads"] = rows
    if a.json_out:
        with open(a.json_out, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
