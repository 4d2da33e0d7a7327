#!/usr/bin/env python3
"""Chapter-5 validation of bootsurf normals (docs/validation.md, issue "normals").

Usage: scripts/validate_normals.py BUILD_DIR DATA_DIR OUT_DIR [--quick]

DATA_DIR holds fandisk_large.off and bunny00.off (scripts/get-data.sh DATA_DIR).
Runs only the bootsurf command line; prints markdown tables on stdout. Noise is
`noise --model uniform` (the thesis text's model, whose magnitudes chapter 5's
tables match), seed 1, levels 0.25 0.5 1.0 1.5; angle errors are unoriented
mean angles in radians against the ground truth (mesh vertex normals, or the
generated sphere's exact normals), computed by `bootsurf eval`.
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tables import header, row, run  # noqa: E402

NOISES = [0.25, 0.5, 1.0, 1.5]


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    build, data, out = sys.argv[1:4]
    quick = "--quick" in sys.argv
    bs = os.path.join(build, "bootsurf")
    os.makedirs(out, exist_ok=True)

    def path(name):
        return os.path.join(out, name)

    def normals(src, dst, *opts):
        return json.loads(run([bs, "normals", src, "-o", dst, "--json", "-q"] + list(opts)))

    def evaluate(res, truth, *opts):
        return json.loads(run([bs, "eval", res, "--truth", truth, "--json"] + list(opts)))

    # ground truth clouds
    truths = {}
    run([bs, "generate", "sphere", "-n", "4000" if quick else "26010", "-o", path("sphere.ply"), "-q"])
    truths["sphere"] = path("sphere.ply")
    for name, mesh in (("fandisk", "fandisk_large.off"), ("bunny", "bunny00.off")):
        run([bs, "sample", os.path.join(data, mesh), "-o", path(name + ".ply"), "-q"])
        truths[name] = path(name + ".ply")
    run([bs, "generate", "cube", "-n", "6146", "-o", path("cube.ply"), "-q"])
    truths["cube"] = path("cube.ply")

    noisy = {}
    for name, t in truths.items():
        for xi in NOISES:
            dst = path("%s_%g.ply" % (name, xi))
            run([bs, "noise", t, "--model", "uniform", "--level", str(xi), "--seed", "1", "-o", dst, "-q"])
            noisy[(name, xi)] = dst

    def angle(name, xi, *opts, split=None):
        res = path("res.ply")
        normals(noisy[(name, xi)], res, *opts)
        e = evaluate(res, truths[name], *(["--split", split] if split else []))
        return e

    # Table 5.1: PCA single fit vs bootstrap (B = 50), k = 15 and 30
    print("\n### Table 5.1: PCA single fit vs bootstrap mean (B = 50), mean angle error (rad)\n")
    for name in ("sphere", "bunny", "fandisk"):
        header(name + " noise", "k=15 single", "k=15 bootstrap", "k=30 single", "k=30 bootstrap")
        for xi in NOISES:
            vals = []
            for k in (15, 30):
                for B in (0, 50):
                    vals.append(angle(name, xi, "-k", str(k), "-B", str(B))["normals"]["mean_rad"])
            row("%g" % xi, *("%.4f" % v for v in vals))
        print()

    # Table 5.2: K = 50, the 15% of points with the highest normal_var vs the rest
    print("\n### Table 5.2: mean angle error of the 15% highest-variance points vs the rest (K = 50, B = 50)\n")
    for name in ("bunny", "fandisk"):
        header(name + " noise", "low variance (85%)", "high variance (15%)", "ratio")
        for xi in NOISES:
            e = angle(name, xi, "-k", "50", "-B", "50", split="normal_var:0.85")
            lo, hi = e["split"]["low"]["normals"]["mean_rad"], e["split"]["high"]["normals"]["mean_rad"]
            row("%g" % xi, "%.4f" % lo, "%.4f" % hi, "%.2f" % (hi / lo))
        print()

    # Table 5.4: PCA vs quadratic (M2) bootstrap normals on the sphere, both PCA centres
    print("\n### Table 5.4: sphere, bootstrap (B = 50) PCA vs quadratic normals, mean angle error (rad)\n")
    for center in ("centroid", "point"):
        header("PCA about the %s: noise" % center, "k=15 PCA", "k=15 M2", "k=30 PCA", "k=30 M2")
        for xi in NOISES:
            vals = []
            for k in (15, 30):
                vals.append(angle("sphere", xi, "-k", str(k), "--pca-center", center)["normals"]["mean_rad"])
                vals.append(angle("sphere", xi, "-k", str(k), "--fit", "poly", "-d", "2",
                                 "--pca-center", center)["normals"]["mean_rad"])
            row("%g" % xi, *("%.4f" % v for v in vals))
        print()

    # Figure 5.2: bilateral (sigma_nu auto) vs single Gaussian (sigma_nu inf) smoothing,
    # feature / non-feature points by the ground-truth `feature` label, noise 0.5
    print("\n### Figure 5.2: normal smoothing at noise 0.5, mean angle error (rad) on feature / non-feature points\n")
    iters = [0, 1, 2, 5, 10, 20]
    for name in ("cube", "fandisk"):
        header(name + " iterations", "bilateral feature", "single Gaussian feature", "bilateral non-feature",
               "single Gaussian non-feature")
        for it in iters:
            vals = []
            for sig in ("auto", "inf"):
                e = angle(name, 0.5, "-k", "15", "-B", "50", "--smooth-iterations", str(it),
                          "--alpha", "0.1", "--sigma-nu", sig, split="feature:0.5")
                vals.append((e["split"]["high"]["normals"]["mean_rad"], e["split"]["low"]["normals"]["mean_rad"]))
            row(it, "%.4f" % vals[0][0], "%.4f" % vals[1][0], "%.4f" % vals[0][1], "%.4f" % vals[1][1])
        print()

    # Neighbourhood choice: per-point selected K vs the best single K, with PCA
    # and with quadratic fits (Eq. 5.10's g^b(p_j) then follows the curvature)
    ks = list(range(10, 51, 5))
    for fit in (["--fit", "pca"], ["--fit", "poly", "-d", "2"]):
        label = "PCA" if fit[1] == "pca" else "quadratic"
        print("\n### Neighbourhood choice (%s): per-point K (min normal_err) vs the best single K, "
              "mean angle error (rad)\n" % label)
        for name in ("fandisk", "bunny"):
            header(name + " noise", "best single K", "its error", "selected-K error", "mean selected K")
            for xi in NOISES:
                best = None
                for k in ks:
                    a = angle(name, xi, "-k", str(k), "-B", "0", *fit)["normals"]["mean_rad"]
                    if best is None or a < best[1]:
                        best = (k, a)
                res = path("sel.ply")
                j = normals(noisy[(name, xi)], res, "-B", "20", "--select-k", "10:50:5", "--select-rule", "test-error",
                            "--k-ref", "30", *fit)
                e = evaluate(res, truths[name])
                row("%g" % xi, best[0], "%.4f" % best[1], "%.4f" % e["normals"]["mean_rad"],
                    "%.1f" % j["mean"]["k_selected"])
            print()


if __name__ == "__main__":
    main()
