#!/usr/bin/python3
"""bench_ksel -- choosing K for PCA normals on the development set (issue 24).

usage:
  /usr/bin/python3 scripts/bench_ksel.py DEVSET_DIR --bootsurf BUILD/bootsurf [--peers DIR]
      [--out WORK_DIR] [--quick] [--only SUBSTR] [--noise LIST] [--sampling LIST]
      [--cases LIST] [--rules LIST] [--fresh] [--markdown FILE]

Needs Debian's python3-numpy and, for the mse rule's two_sheet check (a k-d tree),
python3-scipy (apt-get install python3-scipy).

DEVSET_DIR is built by scripts/devset.py. For every case it runs, on the noisy
points (x y z only):
  - `bootsurf normals -k K -B 0` (a single PCA fit) for every fixed K in KS;
  - each selection rule: `normals --select-k 15:80:5 -B 0 --select-rule mse` (`--rules
    mse`; `mse10`: the same over the issue's candidates 10:80:5), and
    the thesis's Eq. 5.10 rule `--select-rule test-error --select-k 10:80:5 -B 20
    --k-ref 30` (20 replicates, not 50, to keep the full run within reach);
  - Open3D's PCA at K = 30 (bench/peers/normals_open3d.py) and CGAL's jet fit at
    K = 30 (PEERS/normals_cgal --method jet), when available.
Metrics, against the truth normals (unoriented): mean and RMS angle error (rad),
PGP5 and PGP10 (fraction of points within 5 and 10 degrees), and the wall time of
the command (read, neighbours, estimate, write). "best K" is the fixed K with the
smallest mean error of that case, chosen in hindsight.

Prints markdown: the summary over cases (each row's metrics averaged over the
cases, its mean error relative to the case's best fixed K and to Open3D), the
rules against the issue's targets, the per-case mean errors and, for the mse rule,
its two_sheet field (flagged share; on the thin cases precision and recall against
the neighbourhoods that hold >= 10% points of the far face). Results of fixed
K and peers are cached in WORK_DIR/cache.json (rules are always rerun unless
--rules is empty); --fresh ignores the cache.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import devset  # noqa: E402

KS = [10, 15, 20, 25, 30, 40, 50, 60, 70, 80]
RULES = {
    "select mse": ["--select-k", "15:80:5", "-B", "0", "--select-rule", "mse"],
    # the same rule over the issue's own candidates (issue 24's command, 10:80:5)
    "select mse 10:80:5": ["--select-k", "10:80:5", "-B", "0", "--select-rule", "mse"],
    "select test-error (Eq. 5.10)": ["--select-k", "10:80:5", "-B", "20", "--k-ref", "30",
                                     "--select-rule", "test-error"],
}
RULE_KEYS = {"mse": "select mse", "mse10": "select mse 10:80:5", "test-error": "select test-error (Eq. 5.10)"}


def angles(result, truth_normals):
    f, _ = devset.read_ply(result)
    n = np.stack([f["nx"], f["ny"], f["nz"]], axis=1).astype(np.float64)
    t = truth_normals
    cross = np.linalg.norm(np.cross(n, t), axis=1)
    dot = np.abs(np.sum(n * t, axis=1))
    return np.arctan2(cross, dot)


def sheet_stats(result, truth_fields, mixed_share=0.1):
    """The two_sheet field against the truth: the flagged share and, with the
    truth's oriented normals, the share of points whose chosen neighbourhood
    (k_selected nearest noisy points) holds at least `mixed_share` points whose
    true normal faces the other way (dot < 0: the far face of a thin part),
    with the precision and recall of the flag for those points."""
    f, _ = devset.read_ply(result)
    if "two_sheet" not in f or "k_selected" not in f:
        return None
    from scipy.spatial import cKDTree
    flag = f["two_sheet"] > 0.5
    p = np.stack([f["x"], f["y"], f["z"]], axis=1).astype(np.float64)
    t = np.stack([truth_fields["nx"], truth_fields["ny"], truth_fields["nz"]], axis=1).astype(np.float64)
    ks = f["k_selected"].astype(int)
    _, idx = cKDTree(p).query(p, int(ks.max()))
    opposite = (np.einsum("ijk,ik->ij", t[idx], t) < 0)
    first = np.arange(idx.shape[1])[None, :] < ks[:, None]
    mixed = (opposite & first).sum(1) >= mixed_share * ks
    tp = int((flag & mixed).sum())
    return {"flagged": float(flag.mean()), "mixed": float(mixed.mean()),
            "precision": tp / flag.sum() if flag.sum() else float("nan"),
            "recall": tp / mixed.sum() if mixed.sum() else float("nan")}


def metrics(a, secs):
    return {"mean": float(a.mean()), "rms": float(math.sqrt((a * a).mean())),
            "pgp5": float((a < math.radians(5)).mean()), "pgp10": float((a < math.radians(10)).mean()),
            "seconds": secs}


def timed(cmd):
    t0 = time.monotonic()
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    secs = time.monotonic() - t0
    if r.returncode != 0:
        sys.exit("failed: %s\n%s" % (" ".join(cmd), r.stderr))
    return secs, r.stdout


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("devset")
    ap.add_argument("--bootsurf", required=True)
    ap.add_argument("--peers", default="/work/peers")
    ap.add_argument("--out", default="bench_ksel_work")
    ap.add_argument("--quick", action="store_true", help="devset's quick models and noises only")
    ap.add_argument("--only", default=None)
    ap.add_argument("--cases", default=None, help="comma-separated case names (default: all)")
    ap.add_argument("--noise", default=None, help="comma-separated noises (default: all)")
    ap.add_argument("--sampling", default=None, help="comma-separated samplings (default: all)")
    ap.add_argument("--rules", default="mse,test-error", help="comma-separated: mse, mse10 (the mse rule over 10:80:5), test-error")
    ap.add_argument("--fresh", action="store_true")
    ap.add_argument("--markdown", default=None, help="also write the tables to this file")
    ap.add_argument("-j", "--threads", type=int, default=2)
    a = ap.parse_args()
    if any(r.startswith("mse") for r in a.rules.split(",")):
        try:
            import scipy.spatial  # noqa: F401  (sheet_stats)
        except ImportError:
            sys.exit("bench_ksel: the mse rule's two_sheet check needs scipy: apt-get install python3-scipy")
    bs = a.bootsurf
    if os.path.isdir(bs):
        bs = os.path.join(bs, "bootsurf")
    os.makedirs(a.out, exist_ok=True)
    cache_path = os.path.join(a.out, "cache.json")
    cache = {}
    if os.path.exists(cache_path) and not a.fresh:
        with open(cache_path) as f:
            cache = json.load(f)

    cases = devset.load(a.devset, only=a.only)
    if a.quick:
        cases = [c for c in cases if (c.model in devset.QUICK_MODELS or c.sampling == "thin" or c.model == "cube")
                 and c.noise in devset.QUICK_NOISES and c.sampling != "regular"]
    if a.cases:
        cases = [c for c in cases if c.name in a.cases.split(",")]
    if a.noise:
        cases = [c for c in cases if c.noise in a.noise.split(",")]
    if a.sampling:
        cases = [c for c in cases if c.sampling in a.sampling.split(",")]
    cases = [c for c in cases if c.sampling != "regular"]  # issue 24's set: no regular shapes
    rules = [RULE_KEYS[r] for r in a.rules.split(",") if r]
    o3d = os.path.join(os.path.dirname(HERE), "bench", "peers", "normals_open3d.py")
    cgal = os.path.join(a.peers, "normals_cgal")
    have_cgal = os.access(cgal, os.X_OK)
    res = os.path.join(a.out, "result.ply")
    j = str(a.threads)

    table = {}  # case -> row -> metrics
    for c in cases:
        f, _ = devset.read_ply(c.truth)
        tn = np.stack([f["nx"], f["ny"], f["nz"]], axis=1).astype(np.float64)
        row = {}
        todo = [("K=%d" % k, [bs, "normals", c.noisy, "-o", res, "-k", str(k), "-B", "0", "-q", "-j", j])
                for k in KS]
        todo.append(("Open3D K=30", ["/usr/bin/python3", o3d, c.noisy, "-o", res, "-k", "30", "-j", j]))
        if have_cgal:
            todo.append(("CGAL jet K=30", [cgal, c.noisy, "-o", res, "--method", "jet", "-k", "30", "-j", j]))
        for name, cmd in todo:
            key = c.name + "|" + name
            if key not in cache:
                secs, _ = timed(cmd)
                cache[key] = metrics(angles(res, tn), secs)
            row[name] = cache[key]
        for r in rules:
            secs, _ = timed([bs, "normals", c.noisy, "-o", res, "-q", "-j", j] + RULES[r])
            row[r] = metrics(angles(res, tn), secs)
            sh = sheet_stats(res, f)
            if sh:
                row[r]["sheet"] = sh
        table[c.name] = row
        with open(cache_path, "w") as fh:
            json.dump(cache, fh)
        best = min(("K=%d" % k for k in KS), key=lambda n: row[n]["mean"])
        print("%-34s best %-5s %.4f  o3d %.4f  %s" % (
            c.name, best, row[best]["mean"], row["Open3D K=30"]["mean"],
            "  ".join("%s %.4f" % (" ".join(r.split()[1:2] + r.split()[2:3]), row[r]["mean"]) for r in rules)), file=sys.stderr, flush=True)

    out = []
    emit = out.append
    names = list(table)
    if not names:
        sys.exit("no cases")
    for n in names:
        row = table[n]
        best = min(("K=%d" % k for k in KS), key=lambda m: row[m]["mean"])
        row["best fixed K (hindsight)"] = dict(row[best], k=int(best[2:]))
    rows = ["K=%d" % k for k in KS] + ["best fixed K (hindsight)", "Open3D K=30"]
    if have_cgal:
        rows.append("CGAL jet K=30")
    rows += rules
    emit("%d cases (%s). Each metric is the mean over the cases; `/best` and `/Open3D` are the means of "
         "the per-case ratios of the mean angle error.\n" % (len(names), "quick subset" if a.quick else "listed cases" if a.cases else "the set in %s" % a.devset))
    emit("| row | mean (rad) | RMS (rad) | PGP5 | PGP10 | /best | /Open3D | time (s) |")
    emit("|---|---|---|---|---|---|---|---|")
    for r in rows:
        v = [table[n][r] for n in names]
        rb = [table[n][r]["mean"] / table[n]["best fixed K (hindsight)"]["mean"] for n in names]
        ro = [table[n][r]["mean"] / table[n]["Open3D K=30"]["mean"] for n in names]
        emit("| %s | %.4f | %.4f | %.3f | %.3f | %.3f | %.3f | %.1f |" % (
            r, np.mean([x["mean"] for x in v]), np.mean([x["rms"] for x in v]), np.mean([x["pgp5"] for x in v]),
            np.mean([x["pgp10"] for x in v]), np.mean(rb), np.mean(ro), np.sum([x["seconds"] for x in v])))
    emit("")
    emit("Against the issue's targets (mean angle error per case, thin cases apart):\n")
    emit("| rule | cases | <= best fixed K | max ratio to best | mean ratio to best | mean ratio to Open3D |")
    emit("|---|---|---|---|---|---|")
    ordinary = [n for n in names if "_thin_" not in n]
    thin = [n for n in names if "_thin_" in n]
    for r in rules:
        for label, group in (("ordinary", ordinary), ("thin", thin)):
            if not group:
                continue
            rb = np.array([table[n][r]["mean"] / table[n]["best fixed K (hindsight)"]["mean"] for n in group])
            ro = np.array([table[n][r]["mean"] / table[n]["Open3D K=30"]["mean"] for n in group])
            emit("| %s, %s | %d | %d (%.0f%%) | %.3f | %.3f | %.3f |" % (
                r, label, len(group), (rb <= 1.0).sum(), 100.0 * (rb <= 1.0).mean(), rb.max(), rb.mean(), ro.mean()))
    emit("")
    emit("Per case, mean angle error (rad):\n")
    head = ["case", "best K", "best", "K=30", "Open3D"] + (["CGAL jet"] if have_cgal else []) + \
        [r.replace("select ", "").replace(" (Eq. 5.10)", "") for r in rules]
    emit("| " + " | ".join(head) + " |")
    emit("|" + "---|" * len(head))
    for n in names:
        row = table[n]
        cells = [n, str(row["best fixed K (hindsight)"]["k"]), "%.4f" % row["best fixed K (hindsight)"]["mean"],
                 "%.4f" % row["K=30"]["mean"], "%.4f" % row["Open3D K=30"]["mean"]]
        if have_cgal:
            cells.append("%.4f" % row["CGAL jet K=30"]["mean"])
        cells += ["%.4f" % row[r]["mean"] for r in rules]
        emit("| " + " | ".join(cells) + " |")
    sheet_rules = [r for r in rules if all("sheet" in table[n][r] for n in names)]
    for r in sheet_rules:
        emit("")
        emit("The `two_sheet` field of %s on the thin cases: the share of points flagged, the share whose "
             "chosen neighbourhood holds >= 10%% points of the far face (true normals facing the other way), "
             "and the flag's precision and recall for those:\n" % r)
        emit("| case | flagged | mixed (truth) | precision | recall |")
        emit("|---|---|---|---|---|")
        for n in thin:
            sh = table[n][r]["sheet"]
            emit("| %s | %.4f | %.4f | %.3f | %.3f |" % (n, sh["flagged"], sh["mixed"], sh["precision"], sh["recall"]))
        if ordinary:
            fl = np.array([table[n][r]["sheet"]["flagged"] for n in ordinary])
            emit("\nOn the %d other cases (one sheet; at their largest K some neighbourhoods wrap around "
                 "a thin limb, which the far-face count above cannot tell from a thin part): flagged share "
                 "mean %.4f, max %.4f (%s).\n" % (len(ordinary), fl.mean(), fl.max(), ordinary[int(fl.argmax())]))
    text = "\n".join(out) + "\n"
    sys.stdout.write(text)
    if a.markdown:
        with open(a.markdown, "w") as fh:
            fh.write(text)


if __name__ == "__main__":
    main()
