#!/usr/bin/env python3
"""Chapter-6 validation of bootsurf smooth (docs/smoothing.md, issue "smoothing").

Usage: scripts/validate_smoothing.py BUILD_DIR DATA_DIR OUT_DIR [--quick]

DATA_DIR holds fandisk_large.off and bunny00.off (scripts/get-data.sh DATA_DIR).
Runs only the bootsurf command line and prints markdown tables on stdout:
  1. the naive projection (Eq. 6.1) with the automatic threshold against no
     threshold, noise 0, 0.25, 0.5 (Figures 6.2-6.3);
  2. single-pass bilateral smoothing (Algorithm 4) against multipass
     (Algorithm 5) over a sweep of their weights, to compare feature error at
     equal overall smoothing;
  3. the defaults of every method.
Models: the generated cube (analytic surface and edges) and fandisk (40,000
points sampled by area, sharp edges at 30 degrees, distance to the mesh).
Position errors are mean distances to the true surface in units of the truth's
spacing h, overall and on feature / non-feature points (`bootsurf eval`).
Noise: gaussian along the normals, seed 1.
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tables import header, row, run  # noqa: E402


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    build, data, out = sys.argv[1:4]
    quick = "--quick" in sys.argv
    bs = os.path.join(build, "bootsurf")
    os.makedirs(out, exist_ok=True)
    n = "8000" if quick else "40000"

    def path(name):
        return os.path.join(out, name)

    models = {}
    run([bs, "generate", "cube", "-n", n, "-o", path("cube.ply"), "-q"])
    models["cube"] = (path("cube.ply"), [])
    mesh = os.path.join(data, "fandisk_large.off")
    run([bs, "sample", mesh, "-n", n, "-o", path("fandisk.ply"), "-q"])
    models["fandisk"] = (path("fandisk.ply"), ["--surface", mesh])

    def noisy(name, level):
        truth = models[name][0]
        if level == 0:
            return truth
        dst = path("%s_n%s.ply" % (name, level))
        if not os.path.exists(dst):
            run([bs, "noise", truth, "--level", str(level), "--seed", "1", "-o", dst, "-q"])
        return dst

    def position(res, name):
        truth, extra = models[name]
        d = json.loads(run([bs, "eval", res, "--truth", truth, "--json", "-q"] + extra))["position"]
        return d["mean_h"], d["feature"]["mean_h"], d["non_feature"]["mean_h"]

    def smooth(src, *opts):
        dst = path("out.ply")
        j = json.loads(run([bs, "smooth", src, "-o", dst, "--json", "-q"] + list(opts)))
        return dst, j

    def fmt(v):
        return "%.4f" % v

    print("### Naive projection (Eq. 6.1): threshold auto (mean .632+) against none\n")
    header("model", "noise", "input all / feature", "none: all / feature", "auto: all / feature",
           "auto: projected")
    for name in models:
        for level in (0, 0.25, 0.5):
            src = noisy(name, level)
            a0, f0, _ = position(src, name)
            res, _ = smooth(src, "--method", "naive", "--threshold", "none")
            a1, f1, _ = position(res, name)
            res, j = smooth(src, "--method", "naive")
            a2, f2, _ = position(res, name)
            row(name, level, fmt(a0) + " / " + fmt(f0), fmt(a1) + " / " + fmt(f1),
                fmt(a2) + " / " + fmt(f2), "%d of %d" % (j["projected"], j["points"]))
    print()

    print("### One bilateral pass (Algorithm 4) against multipass (Algorithm 5), noise 0.5\n")
    print("Each row is one setting; compare feature error between rows of similar overall error.\n")
    header("model", "method", "setting", "all", "feature", "non-feature")
    sweeps = [("bilateral", ["--h2", h2], "h2 = " + h2) for h2 in ("0.75W", "1W", "1.2W", "1.5W", "2W")]
    sweeps += [("multipass", ["--h2", h2, "--k-error", ke], "h2 = %s, k_error = %s" % (h2, ke))
               for h2, ke in (("0.3W", "1W"), ("1W", "1W"), ("1W", "1.5W"), ("1W", "2W"), ("1W", "3W"))]
    for name in models:
        src = noisy(name, 0.5)
        for method, opts, label in sweeps:
            res, _ = smooth(src, "--method", method, *opts)
            a, f, nf = position(res, name)
            row(name, method, label, fmt(a), fmt(f), fmt(nf))
    print()

    print("### Defaults\n")
    header("model", "noise", "method", "all", "feature", "non-feature", "moved mean (h)")
    for name in models:
        for level in (0.25, 0.5):
            src = noisy(name, level)
            a, f, nf = position(src, name)
            row(name, level, "input", fmt(a), fmt(f), fmt(nf), "")
            for method in ("naive", "bilateral", "multipass"):
                res, j = smooth(src, "--method", method)
                a, f, nf = position(res, name)
                row(name, level, method, fmt(a), fmt(f), fmt(nf), "%.3f" % j["moved_mean_h"])


if __name__ == "__main__":
    main()
