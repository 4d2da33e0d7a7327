#!/usr/bin/env python3
"""Chapter-7 validation of bootsurf features (docs/validation.md, issue "features").

Usage: scripts/validate_features.py BUILD_DIR DATA_DIR OUT_DIR

DATA_DIR holds fandisk_large.off (scripts/get-data.sh DATA_DIR). Runs only the
bootsurf command line and prints markdown tables: precision / recall / F1 of
both methods against the ground-truth `feature` labels (generated cube: analytic
edges; Fandisk: `bootsurf sample`, sharp edges from dihedral angles > 30 degrees,
feature = within 2 nominal spacings), with the automatic threshold and with the
best fixed threshold of a sweep, at uniform noise 0, 0.5 and 1.0 (seed 1).
"""
import json
import os
import subprocess
import sys

NOISES = [0.0, 0.5, 1.0]


def run(args):
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write("failed: %s\n%s" % (" ".join(args), r.stderr))
        sys.exit(1)
    return r.stdout


def row(*cells):
    print("| " + " | ".join(str(c) for c in cells) + " |")


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    build, data, out = sys.argv[1:4]
    bs = os.path.join(build, "bootsurf")
    os.makedirs(out, exist_ok=True)
    p = lambda name: os.path.join(out, name)

    truths = {"cube": p("cube.ply"), "fandisk": p("fandisk.ply")}
    run([bs, "generate", "cube", "-n", "20000", "-o", truths["cube"], "-q"])
    run([bs, "sample", os.path.join(data, "fandisk_large.off"), "-o", truths["fandisk"], "-q"])

    def score(src, truth, *opts):
        j = json.loads(run([bs, "features", src, "-o", p("f.ply"), "--json", "-q"] + list(opts)))
        e = json.loads(run([bs, "eval", p("f.ply"), "--truth", truth, "--json"]))["features"]
        return j, e

    def fmt(e):
        f = lambda v: "-" if v is None else "%.2f" % v
        return "%s / %s / %s" % (f(e["precision"]), f(e["recall"]), f(e["f1"]))

    print("\n### Feature detection: precision / recall / F1 against the truth labels\n")
    row("model", "noise", "variance, auto (Otsu)", "variance, best fixed t", "distance, auto (<= 0)",
        "distance, best fixed fraction")
    row(*(["---"] * 6))
    for name in ("cube", "fandisk"):
        for xi in NOISES:
            src = truths[name]
            if xi > 0:
                src = p("%s_%g.ply" % (name, xi))
                run([bs, "noise", truths[name], "--model", "uniform", "--level", str(xi), "--seed", "1",
                     "-o", src, "-q"])
            jv, ev = score(src, truths[name], "--method", "variance")
            best_v = None
            t_auto = jv["threshold"]
            for step in range(25):  # 1e-5 .. 0.075 rad^2, log-spaced
                t = 1e-5 * 1.45 ** step
                _, e = score(src, truths[name], "--method", "variance", "--threshold", "%.6g" % t)
                if e["f1"] is not None and (best_v is None or e["f1"] > best_v[1]["f1"]):
                    best_v = (t, e)
            _, ed = score(src, truths[name], "--method", "distance")
            best_d = None
            for frac in (0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9):
                _, e = score(src, truths[name], "--method", "distance", "--threshold", str(frac))
                if e["f1"] is not None and (best_d is None or e["f1"] > best_d[1]["f1"]):
                    best_d = (frac, e)
            row(name, "%g" % xi, "%s (t = %.3g)" % (fmt(ev), t_auto),
                "%s (t = %.3g)" % (fmt(best_v[1]), best_v[0]) if best_v else "-", fmt(ed),
                "%s (%.2f)" % (fmt(best_d[1]), best_d[0]) if best_d else "-")


if __name__ == "__main__":
    main()
