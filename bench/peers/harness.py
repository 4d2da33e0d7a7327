"""harness — what the side-by-side benchmark scripts share (compare.py,
smooth_compare.py, kernels.py): running one program under bench/peers/rss_exec
(wall time, peak RSS, CPU time), reading its one-line JSON result, the rounds
that alternate the programs, and same-round ratios.

Imported, never run. Python 3 standard library only.
"""
import json
import os
import statistics
import subprocess
import sys
import time


def run(cmd, out_path, env, launcher=None):
    """Runs cmd; returns (wall s, peak RSS kB, CPU s, stdout text). Raises on failure.

    stdout and stderr go to out_path + ".stdout" / ".stderr". With launcher
    (bench/peers/rss_exec) wall, RSS and CPU are the launcher's: Linux carries a
    parent's RSS peak across fork and exec, so the harness cannot take
    ru_maxrss of its own children (see rss_exec.c); without it RSS and CPU are None.
    """
    stats = out_path + ".stats"
    full = [launcher, stats] + cmd if launcher else cmd
    with open(out_path + ".stdout", "wb") as so, open(out_path + ".stderr", "wb") as se:
        t0 = time.monotonic()
        rc = subprocess.call(full, stdout=so, stderr=se, env=env)
        wall, rss, cpu = time.monotonic() - t0, None, None
    if rc != 0:
        err = open(out_path + ".stderr", errors="replace").read()
        raise RuntimeError("%s failed (%d):\n%s" % (" ".join(cmd), rc, err[-3000:]))
    if launcher:
        w, r, c = open(stats).read().split()
        wall, rss, cpu = float(w), int(r), float(c)
    return wall, rss, cpu, open(out_path + ".stdout").read()


def last_json(text):
    """The last line of text that is a JSON object (every program prints one)."""
    for line in reversed(text.strip().splitlines()):
        line = line.strip()
        if line.startswith("{"):
            return json.loads(line)
    raise ValueError("no JSON line in: " + text[:500])


def rounds(ids, reps, run_one, label=""):
    """Calls run_one(id, round) for every id, reps times; each round runs every
    program once, in an order rotated by one from the previous round, so that
    the slow phases of a shared machine fall on different programs."""
    for r in range(reps):
        s = r % len(ids)
        for pid in ids[s:] + ids[:s]:
            run_one(pid, r)


def median_ratio(xs, ys):
    """t(x) / t(y) of the same round, then the median over the rounds."""
    return statistics.median(x / y for x, y in zip(xs, ys))


def log(*args):
    print(*args, file=sys.stderr, flush=True)


def load_now():
    return list(os.getloadavg())
