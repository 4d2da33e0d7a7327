#!/usr/bin/python3
"""features_table -- feature detection F1 over the development set (issue 22, docs/features.md).

usage:
  nice -n 10 /usr/bin/python3 scripts/features_table.py --bootsurf BUILD --devset DIR \\
      --peers DIR [--models LIST] [--noise LIST] [--write docs/features.md] [--work DIR]

For every case MODEL_SAMPLING_NOISE of the development set (scripts/devset.py; default
models: the CAD ones, whose labels are sharp edges: fandisk_large, couplingdown and joint
as `vertices` and `area50k`, the generated cube as `regular` and `aniso`; noise u0.25,
u0.5, g0.6) it runs, on noisy.ply, at their documented defaults:

  distance   bootsurf features --method distance (7.1; automatic T_h)
  variance   bootsurf features --method variance (7.2; the automatic null-test threshold)
  PCL sv     surface variation lambda0 / (lambda0 + lambda1 + lambda2), K 30
             (bench/peers/features_pcl.cpp, PCL's NormalEstimationOMP); PCL has no
             threshold of its own: Otsu on log(score), the rule of scripts/validate_features.py
  CGAL VCM   compute_vcm + vcm_is_on_feature_edge (bench/peers/features_cgal.cpp) with
             CGAL's edges_example settings scaled by the mean spacing h: R = 11.85 h,
             r = 5.93 h, threshold 0.16
  all        the trivial "everything is a feature" baseline (recall 1)

and scores precision / recall / F1 against truth.ply's `feature` labels (within 2 point
spacings of a sharp edge). --write replaces the part of the file between the markers
<!-- features-table:begin --> and <!-- features-table:end --> with the table.
"""
import argparse
import json
import math
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import devset  # noqa: E402
from validate_features import CGAL_EXAMPLE, CGAL_THRESHOLD, otsu_log  # noqa: E402

MODELS = ["fandisk_large_area50k", "fandisk_large_vertices", "couplingdown_area50k",
          "couplingdown_vertices", "joint_area50k", "joint_vertices", "cube_regular", "cube_aniso"]
NOISES = ["u0.25", "u0.5", "g0.6"]
METHODS = ["distance", "variance", "PCL sv", "CGAL VCM", "all"]
BEGIN, END = "<!-- features-table:begin -->", "<!-- features-table:end -->"


def run(args):
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError("failed: %s\n%s" % (" ".join(map(str, args)), r.stderr))
    return r.stdout


def prf(pred, truth):
    tp = int(np.sum(pred & truth))
    fp = int(np.sum(pred & ~truth))
    fn = int(np.sum(~pred & truth))
    p = tp / (tp + fp) if tp + fp else float("nan")
    r = tp / (tp + fn) if tp + fn else float("nan")
    return {"p": p, "r": r, "f1": 2 * tp / (2 * tp + fp + fn) if tp + fp + fn else float("nan")}


def case_rows(bs, peers, case, work):
    truth = devset.read_ply(case.truth)[0]["feature"] != 0
    out = os.path.join(work, "f.ply")
    res, h = {}, None
    for m in ("distance", "variance"):
        j = json.loads(run([bs, "features", case.noisy, "--method", m, "-o", out, "--force", "-q",
                            "--json"]))
        h = j["h"]
        res[m] = prf(devset.read_ply(out)[0]["feature"] != 0, truth)
    txt = os.path.join(work, "s.txt")
    run([os.path.join(peers, "features_pcl"), case.noisy, "-o", txt, "-k", "30"])
    s = np.nan_to_num(np.loadtxt(txt), nan=0.0)
    res["PCL sv"] = prf(s > otsu_log(list(s)), truth)
    run([os.path.join(peers, "features_cgal"), case.noisy, "-o", txt, "--R",
         "%.9g" % (CGAL_EXAMPLE[0] * h), "--r", "%.9g" % (CGAL_EXAMPLE[1] * h), "--threshold",
         str(CGAL_THRESHOLD)])
    s = np.loadtxt(txt)
    res["CGAL VCM"] = prf(np.nan_to_num(s, nan=-np.inf) >= CGAL_THRESHOLD, truth)
    res["all"] = prf(np.ones_like(truth), truth)
    return res, float(truth.mean())


def fmt(e):
    f = lambda v: "-" if math.isnan(v) else "%.2f" % v
    return "**%s** (%s / %s)" % (f(e["f1"]), f(e["p"]), f(e["r"]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bootsurf", required=True)
    ap.add_argument("--devset", required=True)
    ap.add_argument("--peers", required=True)
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--noise", default=",".join(NOISES))
    ap.add_argument("--write")
    ap.add_argument("--work", default="/tmp/bootsurf_features_table")
    a = ap.parse_args()
    bs = os.path.abspath(a.bootsurf)
    if os.path.isdir(bs):
        bs = os.path.join(bs, "bootsurf")
    os.makedirs(a.work, exist_ok=True)
    lines = ["| case | features | " + " | ".join(METHODS) + " |",
             "|---|---|" + "---|" * len(METHODS)]
    wins = {m: 0 for m in METHODS}
    for model in a.models.split(","):
        for noise in a.noise.split(","):
            cases = devset.load(a.devset, only="%s_%s" % (model, noise))
            cases = [c for c in cases if c.name == "%s_%s" % (model, noise)]
            if not cases:
                sys.exit("features_table: no case %s_%s in %s" % (model, noise, a.devset))
            res, frac = case_rows(bs, a.peers, cases[0], a.work)
            best = max(res[m]["f1"] for m in METHODS)
            for m in METHODS:
                wins[m] += res[m]["f1"] == best
            lines.append("| %s | %.1f%% | %s |" % (cases[0].name, 100 * frac,
                                                   " | ".join(fmt(res[m]) for m in METHODS)))
            print(lines[-1], flush=True)
    lines.append("")
    lines.append("Best F1 (ties counted for each): " +
                 ", ".join("%s %d" % (m, wins[m]) for m in METHODS) + ".")
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
