#!/usr/bin/env python3
"""Chapter-7 validation of bootsurf features beside two baselines (docs/validation.md).

Usage: scripts/validate_features.py BUILD_DIR DATA_DIR OUT_DIR [--peers DIR]
           [--noise 0,0.5,1] [--models cube,fandisk] [--no-baselines]

DATA_DIR holds fandisk_large.off (scripts/get-data.sh DATA_DIR). Prints markdown
tables of precision / recall / F1 against the ground-truth `feature` labels
(generated cube: analytic edges; Fandisk: `bootsurf sample`, sharp edges from
dihedral angles > 30 degrees; feature = within 2 nominal spacings), at uniform
noise 0, 0.5 and 1.0 (seed 1), for

  * bootsurf features --method variance --tail-rule otsu (K 30, B 50; the null-test rule,
    the default since issue 22, is measured by scripts/features_table.py) and --method distance
    (defaults), each with its automatic threshold and the best fixed one;
  * the distance method's rules: fixed T_{a/c} (--noise-factor 0) or the
    noise-adapted one (default), the thesis's T_h = 0 (--threshold 0) or the
    automatic T_h (default); and the bilateral filter's effect (Eq. 7.1, Fig.
    7.5): --iterations 0 against 5 passes, range sigma 0.05 (default), 0.5, 2;
  * surface variation lambda0 / (lambda0 + lambda1 + lambda2), K 30, from PCL's
    NormalEstimationOMP (bench/peers/features_pcl.cpp), thresholded by the best
    fixed value and by an automatic rule: Otsu's split of log(score), the rule
    bootsurf's variance method uses (256 bins between the 0.1% quantile and the
    maximum; values <= 1e-12 max left out);
  * CGAL's Voronoi covariance measure (bench/peers/features_cgal.cpp):
    compute_vcm with R and r from the mean spacing h as CGAL's edges_example
    (R = 0.2, r = 0.1 on its data/fandisk.off, h = 0.01687: R = 11.85 h,
    r = 5.93 h), and smaller radii R = 4 h, r = 2 h; thresholded at the
    example's 0.16 (vcm_is_on_feature_edge) and at the best fixed value.

"Best fixed": the best F1 over thresholds at the 0.5%, 1%, ..., 99.5% quantiles
of the score (distance: fractions 0.025 ... 0.975 of max(feature_dist), the
values `--threshold` takes) -- an oracle, chosen with the truth. The bootsurf
automatic results are scored by `bootsurf eval`; the script checks that its own
scoring agrees. The peers are built into --peers (default OUT_DIR/peers) by
bench/peers/build.sh (which rebuilds only what is missing or out of date).
Needs only python3 (no numpy). About a minute on an idle 2-core machine.
"""
import bisect
import json
import math
import os
import struct
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tables import row, run  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# CGAL's edges_example.cpp: R = 0.2, r = 0.1 on data/fandisk.off (h = 0.0168718)
CGAL_EXAMPLE = (0.2 / 0.0168718, 0.1 / 0.0168718)
CGAL_SMALL = (4.0, 2.0)
CGAL_THRESHOLD = 0.16


# ---- PLY (as bootsurf writes it: binary little-endian, or ascii) ----
PLY_TYPES = {"char": "b", "int8": "b", "uchar": "B", "uint8": "B", "short": "h", "int16": "h",
             "ushort": "H", "uint16": "H", "int": "i", "int32": "i", "uint": "I", "uint32": "I",
             "float": "f", "float32": "f", "double": "d", "float64": "d"}


def read_fields(path, names):
    """The named vertex properties of a PLY file: {name: list of floats}."""
    with open(path, "rb") as f:
        fmt, props, n, in_vertex = None, [], 0, False
        while True:
            line = f.readline().decode("ascii", "replace").strip()
            w = line.split()
            if not w:
                continue
            if w[0] == "format":
                fmt = w[1]
            elif w[0] == "element":
                in_vertex = w[1] == "vertex"
                if in_vertex:
                    n = int(w[2])
            elif w[0] == "property" and in_vertex:
                props.append((w[-1], PLY_TYPES[w[1]]))
            elif w[0] == "end_header":
                break
        idx = {p[0]: i for i, p in enumerate(props)}
        missing = [m for m in names if m not in idx]
        if missing:
            sys.exit("%s: no field %s" % (path, ", ".join(missing)))
        out = {m: [] for m in names}
        if fmt == "ascii":
            for _ in range(n):
                v = f.readline().split()
                for m in names:
                    out[m].append(float(v[idx[m]]))
            return out
        endian = "<" if fmt == "binary_little_endian" else ">"
        rec = struct.Struct(endian + "".join(p[1] for p in props))
        data = f.read(rec.size * n)
        for v in rec.iter_unpack(data):
            for m in names:
                out[m].append(v[idx[m]])
        return out


def read_scores(path):
    with open(path) as f:
        return [float(x) for x in f]


# ---- scoring ----
def prf(pred, truth):
    tp = sum(1 for p, t in zip(pred, truth) if p and t)
    fp = sum(1 for p, t in zip(pred, truth) if p and not t)
    fn = sum(1 for p, t in zip(pred, truth) if t and not p)
    p = tp / (tp + fp) if tp + fp else None
    r = tp / (tp + fn) if tp + fn else None
    f1 = 2 * p * r / (p + r) if p and r else (0.0 if p is not None and r is not None else None)
    return {"precision": p, "recall": r, "f1": f1}


def fmt(e):
    f = lambda v: "-" if v is None else "%.2f" % v
    return "%s / %s / %s" % (f(e["precision"]), f(e["recall"]), f(e["f1"]))


def best_threshold(score, truth, candidates, above):
    """The candidate threshold with the best F1 (score > t when above, else score <= t):
    (t, precision / recall / F1), from the sorted scores and prefix sums of the truth."""
    pairs = sorted(zip(score, truth))
    keys = [s for s, _ in pairs]
    pre = [0]
    for _, t in pairs:
        pre.append(pre[-1] + (1 if t else 0))
    n, pos = len(pairs), pre[-1]
    best = None
    for t in candidates:
        k = bisect.bisect_right(keys, t)  # keys[:k] <= t
        sel, tp = (n - k, pos - pre[k]) if above else (k, pre[k])
        e = {"precision": tp / sel if sel else None, "recall": tp / pos if pos else None}
        e["f1"] = 2 * tp / (sel + pos) if sel + pos else None
        if e["f1"] is not None and (best is None or e["f1"] > best[1]["f1"]):
            best = (t, e)
    return best


def quantiles(values, qs):
    v = sorted(x for x in values if math.isfinite(x))
    return sorted(set(v[min(len(v) - 1, int(q * (len(v) - 1)))] for q in qs))


def otsu_log(values):
    """bootsurf's BSURF_TAIL_OTSU (src/algo/features.c) in Python: Otsu on log(value)."""
    mx = max(values)
    floor_v = 1e-12 * mx
    l = sorted(math.log(v) for v in values if v > floor_v)
    if len(l) < 2:
        return floor_v
    bins = 256
    lo, hi = l[int(0.001 * (len(l) - 1))], l[-1]
    if not hi > lo:
        return math.exp(hi)
    w = (hi - lo) / bins
    hist = [0] * bins
    for x in l:
        b = 0 if x <= lo else int((x - lo) / w)
        hist[min(b, bins - 1)] += 1
    total = len(l)
    sum_all = sum(b * h for b, h in enumerate(hist))
    w0 = sum0 = 0
    best, best_b = -1, 0
    for b in range(bins - 1):
        w0 += hist[b]
        sum0 += b * hist[b]
        w1 = total - w0
        if w0 <= 0 or w1 <= 0:
            continue
        m0, m1 = sum0 / w0, (sum_all - sum0) / w1
        between = w0 * w1 * (m0 - m1) ** 2
        if between > best:
            best, best_b = between, b
    return math.exp(lo + (best_b + 1) * w)


def main():
    args = sys.argv[1:]
    opts = {"--peers": None, "--noise": "0,0.5,1", "--models": "cube,fandisk"}
    baselines = True
    pos = []
    i = 0
    while i < len(args):
        if args[i] in opts and i + 1 < len(args):
            opts[args[i]] = args[i + 1]
            i += 2
        elif args[i] == "--no-baselines":
            baselines = False
            i += 1
        elif args[i].startswith("-"):
            sys.exit(__doc__)
        else:
            pos.append(args[i])
            i += 1
    if len(pos) != 3:
        sys.exit(__doc__)
    build, data, out = pos
    noises = [float(x) for x in opts["--noise"].split(",")]
    models = opts["--models"].split(",")
    bs = os.path.join(build, "bootsurf")
    os.makedirs(out, exist_ok=True)
    p = lambda name: os.path.join(out, name)
    peers = opts["--peers"] or p("peers")
    if baselines:  # builds what is missing or older than its sources
        r = subprocess.run([os.path.join(ROOT, "bench", "peers", "build.sh"), peers], capture_output=True,
                           text=True)
        missing = [x for x in ("features_pcl", "features_cgal") if not os.access(os.path.join(peers, x), os.X_OK)]
        if missing:
            sys.exit("bench/peers/build.sh did not build %s:\n%s" % (", ".join(missing), r.stderr))
        if r.returncode != 0:  # another peer failed; ours are there (perhaps not rebuilt)
            sys.stderr.write("warning: bench/peers/build.sh failed:\n%s" % r.stderr[-2000:])

    truths = {"cube": p("cube.ply"), "fandisk": p("fandisk.ply")}
    if "cube" in models:
        run([bs, "generate", "cube", "-n", "20000", "-o", truths["cube"], "-q"])
    if "fandisk" in models:
        run([bs, "sample", os.path.join(data, "fandisk_large.off"), "-o", truths["fandisk"], "-q"])

    def features(src, truth_path, score_name, *o):
        """bootsurf features (2 threads) + eval: (its JSON, eval's scores, the output's fields)."""
        j = json.loads(run([bs, "features", src, "-o", p("f.ply"), "--json", "-q", "-j", "2"] + list(o)))
        e = json.loads(run([bs, "eval", p("f.ply"), "--truth", truth_path, "--json"]))["features"]
        return j, e, read_fields(p("f.ply"), ["feature", score_name])

    main_rows, rules_rows, filter_rows, base_rows, summary_rows, notes = [], [], [], [], [], []
    fractions = [0.025 * k for k in range(1, 40)]
    qs = [0.005 * k for k in range(1, 200)]
    for name in models:
        truth_path = truths[name]
        truth = [v != 0 for v in read_fields(truth_path, ["feature"])["feature"]]
        for xi in noises:
            src = truth_path
            if xi > 0:
                src = p("%s_%g.ply" % (name, xi))
                run([bs, "noise", truth_path, "--model", "uniform", "--level", str(xi), "--seed", "1", "-o", src,
                     "-q"])
            h = json.loads(run([bs, "features", src, "-o", p("f.ply"), "--json", "-q", "-j", "2",
                                "--method", "distance", "--iterations", "0"]))["h"]
            # variance (7.2)
            jv, ev, fv = features(src, truth_path, "normal_var", "--method", "variance", "--tail-rule", "otsu")
            own = prf([x != 0 for x in fv["feature"]], truth)
            if abs((own["f1"] or 0) - (ev["f1"] or 0)) > 1e-9:
                sys.exit("scoring disagrees with bootsurf eval: %r %r" % (own, ev))
            bv = best_threshold(fv["normal_var"], truth, quantiles(fv["normal_var"], qs), True)
            # distance (7.1): the default, the rules and the filter's effect
            dist = {}
            for nf in ("1.75", "0"):
                for it, sr in (("5", "0.05"), ("0", "0.05"), ("5", "0.5"), ("5", "2")):
                    j, e, f = features(src, truth_path, "feature_dist", "--method", "distance", "--noise-factor", nf,
                                       "--iterations", it, "--sigma-range", sr)
                    d = f["feature_dist"]
                    mx = max(d)
                    dist[(nf, it, sr)] = {
                        "json": j, "auto": e, "zero": prf([x <= 0 for x in d], truth),
                        "best": best_threshold(d, truth, [fr * mx for fr in fractions], False), "max": mx}
            dd = dist[("1.75", "5", "0.05")]
            main_rows.append((name, "%g" % xi, "%s (t = %.3g)" % (fmt(ev), jv["threshold"]),
                              "%s (t = %.3g)" % (fmt(bv[1]), bv[0]),
                              "%s (%.2f)" % (fmt(dd["auto"]), dd["json"]["threshold"] / dd["max"]),
                              "%s (%.3f)" % (fmt(dd["best"][1]), dd["best"][0] / dd["max"])))
            f1 = lambda e: "-" if e["f1"] is None else "%.2f" % e["f1"]
            rules_rows.append([name, "%g" % xi] + [fmt(dist[(nf, "5", "0.05")][rule]) for nf, rule in
                                                   (("0", "zero"), ("0", "auto"), ("1.75", "zero"), ("1.75", "auto"))]
                              + ["%.3g" % dd["json"]["parameters"]["ratio_threshold_kmin"]])
            fl = [name, "%g" % xi]
            for nf, rule in (("0", "zero"), ("1.75", "auto")):
                for sr in ("0.05", "0.5", "2"):
                    fl.append("%s → %s" % (f1(dist[(nf, "0", "0.05")][rule]), f1(dist[(nf, "5", sr)][rule])))
            filter_rows.append(fl)
            if not baselines:
                continue
            # surface variation (PCL)
            jp = json.loads(run([os.path.join(peers, "features_pcl"), src, "-o", p("pcl.txt"), "-k", "30", "-j", "2"]))
            sp = read_scores(p("pcl.txt"))
            sp = [0.0 if math.isnan(x) else x for x in sp]
            tp = otsu_log(sp)
            ep = prf([x > tp for x in sp], truth)
            bp = best_threshold(sp, truth, quantiles(sp, qs), True)
            cells = [name, "%g" % xi, "%s (t = %.3g)" % (fmt(ep), tp), "%s (t = %.3g)" % (fmt(bp[1]), bp[0])]
            # Voronoi covariance measure (CGAL)
            nan_counts, vcm = [], []
            for fR, fr in (CGAL_EXAMPLE, CGAL_SMALL):
                jc = json.loads(run([os.path.join(peers, "features_cgal"), src, "-o", p("cgal.txt"),
                                     "--R", "%.9g" % (fR * h), "--r", "%.9g" % (fr * h),
                                     "--threshold", str(CGAL_THRESHOLD)]))
                # nan (a VCM that is not finite, e.g. on the regular noise-free cube): never an
                # edge for vcm_is_on_feature_edge, so never one here
                sc = [-math.inf if math.isnan(x) else x for x in read_scores(p("cgal.txt"))]
                nan_counts.append(jc["nan"])
                pred = [x >= CGAL_THRESHOLD for x in sc]
                if sum(pred) != jc["on_edge"]:
                    sys.exit("features_cgal: score >= threshold is not vcm_is_on_feature_edge")
                ec = prf(pred, truth)
                # >= t: "> t" over the candidate set just below each quantile value
                bc = best_threshold(sc, truth, [q - 1e-12 for q in quantiles(sc, qs)], True)
                cells += [fmt(ec), "%s (t = %.3g)" % (fmt(bc[1]), bc[0])]
                vcm.append((ec, bc[1]))
            cells.append("%.2f / %.1f" % (jp["seconds"], jc["seconds"]))
            summary_rows.append([name, "%g" % xi] + [f1(e) for e in (
                ev, bv[1], dd["auto"], dd["best"][1], ep, bp[1], vcm[0][0], vcm[0][1], vcm[1][0], vcm[1][1])])
            if any(nan_counts):
                notes.append("%s noise %g: the VCM is nan at %s of %d points (R 11.85h, R 4h)"
                             % (name, xi, " and ".join(str(c) for c in nan_counts), len(sc)))
            base_rows.append(cells)

    if baselines:
        print("\n### F1 side by side (automatic threshold / best fixed threshold)\n")
        row("model", "noise", "variance auto", "variance best", "distance auto", "distance best",
            "surface variation auto", "surface variation best", "VCM 11.85h t 0.16", "VCM 11.85h best",
            "VCM 4h t 0.16", "VCM 4h best")
        row(*(["---"] * 12))
        for r in summary_rows:
            row(*r)
    print("\n### bootsurf: precision / recall / F1 against the truth labels\n")
    row("model", "noise", "variance, auto (Otsu)", "variance, best fixed t", "distance, auto (fraction of max)",
        "distance, best fixed fraction")
    row(*(["---"] * 6))
    for r in main_rows:
        row(*r)
    print("\n### distance method: thresholds, precision / recall / F1 (filter on: 5 passes, sigma_range 0.05)\n")
    row("model", "noise", "fixed T_{a/c} 0.1, T_h = 0 (thesis; the old auto)", "fixed T_{a/c}, Otsu T_h",
        "adapted T_{a/c}, T_h = 0", "adapted T_{a/c}, Otsu T_h (the new auto)", "T_{a/c} at k_min")
    row(*(["---"] * 7))
    for r in rules_rows:
        row(*r)
    print("\n### distance method: F1 without → with the bilateral filter (--iterations 0 → 5, --sigma-range S)\n")
    row("model", "noise", "thesis (fixed T_{a/c}, T_h = 0), S 0.05", "thesis, S 0.5", "thesis, S 2",
        "default (adapted, auto), S 0.05", "default, S 0.5", "default, S 2")
    row(*(["---"] * 8))
    for r in filter_rows:
        row(*r)
    if baselines:
        print("\n### baselines: precision / recall / F1 against the same truth labels\n")
        row("model", "noise", "surface variation (PCL), auto (Otsu log)", "surface variation, best fixed",
            "VCM (CGAL) R 11.85h r 5.93h, t 0.16", "VCM 11.85h/5.93h, best fixed", "VCM R 4h r 2h, t 0.16",
            "VCM 4h/2h, best fixed", "seconds PCL / CGAL (R 4h)")
        row(*(["---"] * 9))
        for r in base_rows:
            row(*r)
        for note in notes:
            print("\n" + note)


if __name__ == "__main__":
    main()
