#!/usr/bin/python3
"""features_table -- feature detection F1 over the development set (issue 22, docs/features.md).

usage:
  nice -n 10 /usr/bin/python3 scripts/features_table.py --bootsurf BUILD --devset DIR \\
      --peers DIR [--models LIST] [--noise LIST] [--extra LIST] [--write docs/features.md]
      [--work DIR] [--jobs N] [--no-peers] [--oracle]

For every case MODEL_NOISE of the development set (scripts/devset.py; default models:
the CAD meshes fandisk_large, couplingdown and joint, then the organic meshes bunny00,
elephant, dino, femur and camel, each sampled as `area50k` and `vertices`, and the
generated cube, torus (`regular`, `aniso`), thin plate and thin shell; noise u0.25, u0.5,
g0.6; plus --extra cases, by default cube_regular_gh0.5, the README's cube) it runs, on
noisy.ply:

  default    bootsurf features (no method option: the variance test with its
             neighbourhood chosen from the noise, docs/features.md)
  distance   bootsurf features --method distance (7.1; automatic T_h)
  var K30    bootsurf features --method variance --feature-angle 0 (the test at the
             fixed K = 30, the previous default rule; the quadric check on, its default)
  PCL sv     surface variation lambda0 / (lambda0 + lambda1 + lambda2), K 30
             (bench/peers/features_pcl.cpp, PCL's NormalEstimationOMP); PCL has no
             threshold of its own: Otsu on log(score), the rule of scripts/validate_features.py
  CGAL VCM   compute_vcm + vcm_is_on_feature_edge (bench/peers/features_cgal.cpp) with
             CGAL's edges_example settings scaled by the mean spacing h: R = 11.85 h,
             r = 5.93 h, threshold 0.16
  all        the trivial "everything is a feature" baseline (recall 1)

and scores F1 (precision / recall) against truth.ply's `feature` labels (within 2 point
spacings of a sharp edge: faces whose normals differ by more than 30 degrees; the
generated shapes' edges). Cases without labels (the torus: no edge) show the share of
points flagged instead, in brackets. The peers' scores are kept in --work per case and
reused (they do not depend on bootsurf); bootsurf's are recomputed when its binary
changes. --no-peers leaves the peers' columns empty (held-out noise levels, for which no
peer scores are cached: `--noise g0.25,g1.2 --extra "" --no-peers --oracle`). --oracle adds
the column "oracle z": the default's F1 at the best threshold on its score z (over z's
0.5-99.5% quantiles, the border test's flags kept), the ceiling of any threshold rule on
that score. --write replaces the part of the file between the markers
<!-- features-table:begin --> and <!-- features-table:end --> with the table.
"""
import argparse
import hashlib
import json
import math
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import devset  # noqa: E402
from validate_features import CGAL_EXAMPLE, CGAL_THRESHOLD, otsu_log  # noqa: E402

CAD = ["fandisk_large", "couplingdown", "joint"]
ORGANIC = ["bunny00", "elephant", "dino", "femur", "camel"]
MODELS = ([m + s for m in CAD for s in ("_area50k", "_vertices")] +
          ["cube_regular", "cube_aniso", "plate_thin", "shell_thin", "torus_regular",
           "torus_aniso"] +
          [m + s for m in ORGANIC for s in ("_area50k", "_vertices")])
NOISES = ["u0.25", "u0.5", "g0.6"]
EXTRA = ["cube_regular_gh0.5"]
BOOTSURF = {"default": [], "distance": ["--method", "distance"],
            "var K30": ["--method", "variance", "--feature-angle", "0"]}
METHODS = ["default", "distance", "var K30", "PCL sv", "CGAL VCM", "all"]
BEGIN, END = "<!-- features-table:begin -->", "<!-- features-table:end -->"


def run(args):
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError("failed: %s\n%s" % (" ".join(map(str, args)), r.stderr))
    return r.stdout


def prf(pred, truth):
    if truth is None:
        return {"flagged": float(np.mean(pred))}
    tp = int(np.sum(pred & truth))
    fp = int(np.sum(pred & ~truth))
    fn = int(np.sum(~pred & truth))
    p = tp / (tp + fp) if tp + fp else float("nan")
    r = tp / (tp + fn) if tp + fn else float("nan")
    return {"p": p, "r": r, "f1": 2 * tp / (2 * tp + fp + fn) if tp + fp + fn else float("nan")}


def oracle(z, feat, t, truth):
    """the best F1 of (z > q) | border over z's quantiles q (border: flagged with z <= t)"""
    border = feat & ~(z > t)
    return max(prf((z > q) | border, truth)["f1"] for q in np.quantile(z, np.linspace(0.005, 0.995, 199)))


def cached(path, compute):
    if os.path.exists(path):
        with open(path) as f:
            return json.load(f)
    v = compute()
    with open(path + ".part", "w") as f:
        json.dump(v, f)
    os.replace(path + ".part", path)
    return v


def case_rows(bs, stamp, peers, case, work, want_oracle):
    d = os.path.join(work, case.name)
    os.makedirs(d, exist_ok=True)
    fields = devset.read_ply(case.truth)[0]
    truth = fields["feature"] != 0 if "feature" in fields else None
    res = {}

    def bootsurf(m):
        def go():
            out = os.path.join(d, "f.ply")
            j = json.loads(run([bs, "features", case.noisy] + BOOTSURF[m] +
                               ["-o", out, "--force", "-q", "--json"]))
            f = devset.read_ply(out)[0]
            r = prf(f["feature"] != 0, truth)
            if m == "default" and truth is not None and "variance_z" in f:
                r["oracle"] = oracle(f["variance_z"], f["feature"] != 0, j["threshold"], truth)
            r["h"] = j["h"]
            r["k"] = j["parameters"].get("k")
            os.remove(out)
            return r
        return cached(os.path.join(d, "%s.%s.json" % (m.replace(" ", "_"), stamp)), go)

    for m in BOOTSURF:
        res[m] = bootsurf(m)
    h = res["distance"]["h"]

    def pcl():
        txt = os.path.join(d, "s.txt")
        run([os.path.join(peers, "features_pcl"), case.noisy, "-o", txt, "-k", "30"])
        s = np.nan_to_num(np.loadtxt(txt), nan=0.0)
        return prf(s > otsu_log(list(s)), truth)

    def vcm():
        txt = os.path.join(d, "v.txt")
        run([os.path.join(peers, "features_cgal"), case.noisy, "-o", txt, "--R",
             "%.9g" % (CGAL_EXAMPLE[0] * h), "--r", "%.9g" % (CGAL_EXAMPLE[1] * h),
             "--threshold", str(CGAL_THRESHOLD)])
        s = np.loadtxt(txt)
        return prf(np.nan_to_num(s, nan=-np.inf) >= CGAL_THRESHOLD, truth)

    nan = {"p": float("nan"), "r": float("nan"), "f1": float("nan")}
    if truth is None:
        nan = {"flagged": float("nan")}
    res["PCL sv"] = cached(os.path.join(d, "pcl.json"), pcl) if peers else nan
    res["CGAL VCM"] = cached(os.path.join(d, "vcm.json"), vcm) if peers else nan
    if want_oracle:
        if "oracle" not in res["default"] and truth is not None:
            os.remove(os.path.join(d, "default.%s.json" % stamp))
            res["default"] = bootsurf("default")
        res["oracle z"] = ({"f1": res["default"]["oracle"], "p": float("nan"), "r": float("nan")}
                           if truth is not None else {"flagged": float("nan")})
    n = len(fields["x"])
    res["all"] = prf(np.ones(n, dtype=bool), truth)
    return res, (float(truth.mean()) if truth is not None else None)


def fmt(e):
    f = lambda v: "-" if math.isnan(v) else "%.2f" % v
    if "flagged" in e:
        return "-" if math.isnan(e["flagged"]) else "(%.1f%%)" % (100 * e["flagged"])
    if math.isnan(e["p"]) and math.isnan(e["r"]):
        return f(e["f1"])
    return "**%s** (%s / %s)" % (f(e["f1"]), f(e["p"]), f(e["r"]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bootsurf", required=True)
    ap.add_argument("--devset", required=True)
    ap.add_argument("--peers", help="the peers' programs (bench/peers/build.sh)")
    ap.add_argument("--no-peers", action="store_true", help="leave PCL sv and CGAL VCM empty")
    ap.add_argument("--oracle", action="store_true", help="add the column oracle z")
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--noise", default=",".join(NOISES))
    ap.add_argument("--extra", default=",".join(EXTRA), help="more cases by full name")
    ap.add_argument("--write")
    ap.add_argument("--work", default="/tmp/bootsurf_features_table")
    ap.add_argument("--jobs", type=int, default=1)
    a = ap.parse_args()
    if not a.peers and not a.no_peers:
        ap.error("--peers DIR is needed (or --no-peers)")
    peers = None if a.no_peers else a.peers
    methods = METHODS + (["oracle z"] if a.oracle else [])
    scored_methods = [m for m in METHODS if peers or m not in ("PCL sv", "CGAL VCM")]
    bs = os.path.abspath(a.bootsurf)
    if os.path.isdir(bs):
        bs = os.path.join(bs, "bootsurf")
    with open(bs, "rb") as f:
        stamp = hashlib.sha256(f.read()).hexdigest()[:12]
    os.makedirs(a.work, exist_ok=True)
    names = ["%s_%s" % (m, z) for m in a.models.split(",") if m for z in a.noise.split(",") if z]
    names += [e for e in a.extra.split(",") if e]
    all_cases = {c.name: c for c in devset.load(a.devset)}
    for nm in names:
        if nm not in all_cases:
            sys.exit("features_table: no case %s in %s" % (nm, a.devset))

    def one(nm):
        return case_rows(bs, stamp, peers, all_cases[nm], a.work, a.oracle)

    with ThreadPoolExecutor(max_workers=max(1, a.jobs)) as ex:
        results = list(ex.map(one, names))
    lines = ["| case | features | " + " | ".join(methods) + " |",
             "|---|---|" + "---|" * len(methods)]
    wins = {m: 0 for m in METHODS}
    margin = {m: [] for m in methods}  # CAD rows: F1 - all
    scored = 0
    for nm, (res, frac) in zip(names, results):
        if frac is not None:
            scored += 1
            # (the oracle is a ceiling, not a method: not counted)
            best = max(res[m]["f1"] for m in scored_methods if not math.isnan(res[m]["f1"]))
            for m in scored_methods:
                wins[m] += res[m]["f1"] == best
            if any(nm.startswith(c) for c in CAD + ["cube", "plate", "shell"]):
                for m in methods:
                    margin[m].append((res[m]["f1"] - res["all"]["f1"], nm))
        lines.append("| %s | %s | %s |" % (nm, "-" if frac is None else "%.1f%%" % (100 * frac),
                                          " | ".join(fmt(res[m]) for m in methods)))
        print(lines[-1], flush=True)
    lines.append("")
    lines.append("Best F1 over the %d labelled rows (ties counted for each): " % scored +
                 ", ".join("%s %d" % (m, wins[m]) for m in scored_methods) + ".")
    cad = [m for m in scored_methods + methods[len(METHODS):] if m != "all" and margin[m]]
    if cad:
        lines.append("")
        lines.append("F1 minus the trivial baseline on the %d rows of CAD and generated "
                     "shapes with edges (CAD meshes, cube, plate, shell): " %
                     len(margin["default"]) + "; ".join(
                         "%s: min %+.2f (%s), %d of %d rows >= +0.2" % (
                             m, min(margin[m])[0], min(margin[m])[1],
                             sum(v >= 0.2 for v, _ in margin[m]), len(margin[m]))
                         for m in cad) + ".")
    table = "\n".join(lines)
    if a.write:
        text = open(a.write).read()
        i, j = text.find(BEGIN), text.find(END)
        if i < 0 or j < i:
            sys.exit("features_table: %s has no %s ... %s markers" % (a.write, BEGIN, END))
        text = text[:i + len(BEGIN)] + "\n" + table + "\n" + text[j:]
        with open(a.write + ".part", "w") as f:
            f.write(text)
        os.replace(a.write + ".part", a.write)
    else:
        print(table)


if __name__ == "__main__":
    main()
