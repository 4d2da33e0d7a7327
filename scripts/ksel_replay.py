#!/usr/bin/python3
"""ksel_replay -- replay the mse rule's last pass on development cases (issue 24).

usage:
  /usr/bin/python3 scripts/ksel_replay.py DEVSET_DIR --bootsurf TRACE_BUILD/bootsurf
      --out WORK_DIR [--sampling vertices] [--cases LIST] [--variants LIST]
      [--select-k 15:80:5]

TRACE_BUILD is a build configured with -DCMAKE_C_FLAGS=-DBSURF_KSEL_TRACE: its
`normals --select-k A:B:STEP -B 0 --select-rule mse -j 1` (the candidates of
--select-k; one WORK_DIR per candidate set) writes, with
BSURF_KSEL_TRACE=FILE in the environment, each point's terms of the rule's last
selection pass (src/algo/kselect.c, trace_point). This script runs it once per
case (cached in WORK_DIR as CASE.npz, with K = 10's normals for the best fixed K),
replays the choice in numpy -- the criterion M(K) = V + max(quadric tilt, drift,
empirical bias where the lack-of-fit gate is on), the tie band and the
precision-weighted tie-break -- checks that the replay gives the C code's normals,
and prints, for each variant of the rule, each case's mean angle error over the
best fixed K's (K in 10, 15, ..., 30, 40, ..., 80, in hindsight) and the count at
most the best / more than 5% above / mean / worst. The variants are diagnostics
(docs/normals.md, "What the benchmark says", the vertex sets), not rules;
VARIANT@true runs VARIANT with the case's true noise variance in place of the
pooled estimate (V, the quadric's noise share, the thin-plane and lack-of-fit
tests and the drift all follow it); s2xF the pooled estimate times F. Each
variant's mean chosen K is printed beside its ratios.

  /usr/bin/python3 scripts/ksel_replay.py SET_DIR --noise-stages --cases LIST
      [--select-k 10:80:5] [--noise-k 12]

needs no build: a numpy replica of the quadric noise estimate's pass 1
(src/algo/kselect_noise.c, quad_estimate: truncation, Lepski's scales, the
Richardson extrapolation, each estimate over the lower quartile of chi^2_nu / nu)
and of its pools (the lower quartile over the K_max neighbours, the median over
the cloud; no cross-section estimate), printing each stage's reading over the true
sigma^2 (case.json), the misfit a fit leaves on the noise-free points (truth.ply,
the same neighbours), and the same pool for a cubic and a quartic fit
(docs/normals.md, "Light noise on fine detail").
"""
import argparse
import json
import math
import os
import subprocess
import sys
from statistics import NormalDist

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import devset  # noqa: E402

KS = list(range(15, 81, 5))  # --select-k (main() may replace it)
FIXED = [10, 15, 20, 25, 30, 40, 50, 60, 70, 80]
TIE_F = 0.5  # kselect.c
ALPHA = 0.05  # kselect_lof.c
S2 = None  # a variant's noise variance in place of the pooled one (VARIANT@true)


def ang(n, t):
    return np.arctan2(np.linalg.norm(np.cross(n, t), axis=1), np.abs(np.sum(n * t, 1)))


def normals_of(path):
    f, _ = devset.read_ply(path)
    return np.stack([f["nx"], f["ny"], f["nz"]], 1).astype(float), f


def run_case(bs, dev, out, case):
    npz = os.path.join(out, case + ".npz")
    if os.path.exists(npz):
        return dict(np.load(npz))
    src = os.path.join(dev, case, "noisy.ply")
    dump, res, r10 = (os.path.join(out, case + x) for x in (".trace", ".ply", ".k10.ply"))
    env = dict(os.environ, BSURF_KSEL_TRACE=dump)
    ks = "%d:%d:%d" % (KS[0], KS[-1], KS[1] - KS[0])
    subprocess.run([bs, "normals", src, "-o", res, "-q", "-j", "1", "--select-k", ks, "-B", "0",
                    "--select-rule", "mse"], env=env, check=True)
    subprocess.run([bs, "normals", src, "-o", r10, "-q", "-k", "10", "-B", "0"], check=True)
    P, C = [], []
    for line in open(dump):
        w = line.split()
        (P if w[0] == "P" else C).append([float(x) for x in w[1 if w[0] == "P" else 2:]])
    P, C = np.array(P), np.array(C)
    order = np.argsort(P[:, 0].astype(int))
    P, C = P[order], C.reshape(len(P), len(KS), -1)[order]
    cn, f = normals_of(res)
    d = dict(s2=P[:, 1], bref=P[:, 2:5], bmref=P[:, 5], nb=P[:, 6:].astype(int), nrm=C[:, :, 0:3],
             var=C[:, :, 3], qb=C[:, :, 4], D=C[:, :, 5], gate=C[:, :, 6].astype(int), rssv=C[:, :, 7],
             b2raw=C[:, :, 8], tr=C[:, :, 9], l1=C[:, :, 10], l2=C[:, :, 11], l3=C[:, :, 12], rk2=C[:, :, 13],
             cnorm=cn,
             k10=normals_of(r10)[0], truth=normals_of(os.path.join(dev, case, "truth.ply"))[0])
    np.savez(npz, **d)
    for p in (dump, res, r10):
        os.remove(p)
    return d


def wh(nu, z):  # the quantile of chi^2_nu / nu by Wilson-Hilferty
    a = 2.0 / (9 * nu)
    return (1 - a + z * math.sqrt(a)) ** 3


def rej0(d):  # the smallest candidate rejects the quadric (kselect_lof.c)
    z = NormalDist().inv_cdf(1 - ALPHA / len(KS))
    return d["rssv"][:, 0] > (d["s2"] if S2 is None else S2) * wh(KS[0] - 6, z)


def test_error(d):
    """T(K) against the neighbours' first choices without the empirical bias, R, and
    whether any reference is assessed (kselect_lof.c)."""
    n, nb = len(d["s2"]), d["nb"]
    with np.errstate(divide="ignore"):
        w = 1.0 / d["bmref"][nb]
    w[(nb == np.arange(n)[:, None]) | ~np.isfinite(w) | (w < 0)] = 0
    ws = w.sum(1)
    dots = np.einsum("nac,njc->naj", d["nrm"], d["bref"][nb])
    T = np.einsum("naj,nj->na", 1 - dots ** 2, w) / np.where(ws > 0, ws, 1)[:, None]
    R = (w > 0).sum(1) / np.where(ws > 0, ws, np.inf)
    return T, R, ws > 0


def rejects(d):
    """each candidate's own lack-of-fit test (kselect_lof.c, Bonferroni over the candidates)"""
    z = NormalDist().inv_cdf(1 - ALPHA / len(KS))
    q = np.array([wh(K - 6, z) for K in KS])
    s2 = d["s2"][:, None] if S2 is None else S2
    return np.isfinite(d["rssv"]) & (d["rssv"] > s2 * q)


def drift(d, var, tol=None, hit=None, tri=None, ref_ok=None):
    """the second largest over the smaller candidates of sin^2 - c (V(j) - V(K))
    (kselect.c, drift_of: two witnesses), c = (3 + ln(a (a - 1) / 2)) / 2 for a >= 2
    smaller candidates, 3 for a = 1; with one reference, its term at c = 3; tol
    replaces c where hit; tri: the smaller candidate's own bias^2 taken off first;
    ref_ok: which smaller candidates may serve as references."""
    n, nk = var.shape
    nrm = d["nrm"]
    out = np.full((n, nk), -np.inf)
    for a in range(1, nk):
        c = np.full(n, (3 + math.log(a * (a - 1) / 2)) / 2 if a >= 2 else 3.0)
        c1 = np.full(n, 3.0)  # a lone reference's: one comparison
        if tol is not None:
            c = np.where(hit[:, a], tol, c)
            c1 = np.where(hit[:, a], tol, c1)
        d1 = np.full(n, -np.inf)  # the largest two terms
        d2 = np.full(n, -np.inf)
        lone = np.full(n, -np.inf)
        m = np.zeros(n, int)
        for b in range(a):
            s2 = 1 - np.sum(nrm[:, a] * nrm[:, b], 1) ** 2
            with np.errstate(invalid="ignore"):
                x = s2 - c * (var[:, b] - var[:, a])
                x1 = s2 - c1 * (var[:, b] - var[:, a])
            if tri is not None:
                x = np.maximum(0, np.sqrt(np.maximum(x, 0)) - np.sqrt(tri[:, b])) ** 2
                x1 = np.maximum(0, np.sqrt(np.maximum(x1, 0)) - np.sqrt(tri[:, b])) ** 2
            use = np.isfinite(var[:, b]) if ref_ok is None else np.isfinite(var[:, b]) & ref_ok[:, b]
            x = np.where(use, x, -np.inf)
            d2 = np.where(x > d1, d1, np.maximum(d2, x))
            d1 = np.maximum(d1, x)
            lone = np.where(use, x1, lone)
            m += use
        out[:, a] = np.where(m >= 2, d2, np.where(m == 1, lone, -np.inf))
    return out


def thin_planes(d, s2):
    """the candidates whose plane is thinner than the noise s2 allows (kselect_lof.c,
    ksel_thin_plane): K l3 < (K - 3) s2 q, q the lower ALPHA / nk quantile of
    chi^2_{K-3} / (K - 3), where the K-th neighbour is >= 5 deviations away, and
    whose normal is nearer perpendicular to the K_max neighbours' (the last
    candidate's) than parallel, or whose K_max neighbours are no surface patch
    (kselect_lof.c, ksel_same_plane and ksel_disc: a plane that agrees with a
    patch's plane is the surface's, with less noise than the cloud's level)"""
    K = np.array(KS)
    z = NormalDist().inv_cdf(ALPHA / len(KS))
    q = np.array([wh(k - 3, z) for k in KS])
    same = np.einsum("nac,nc->na", d["nrm"], d["nrm"][:, -1]) ** 2 >= 0.5
    la, lb = d["l1"][:, -1], d["l2"][:, -1]
    disc = np.abs(lb - la) <= 2 * math.sqrt(-math.log(ALPHA) / (3 * (KS[-1] - 1))) * (la + lb)
    same &= disc[:, None]
    return (s2 > 0) & (d["rk2"] >= 25 * s2) & (K * d["l3"] < (K - 3) * s2 * q) & ~same


def criterion(d, s2=None, gate=None, emp="R", drift_kw=None, no_drift=None, thin=True):
    """V + max(Q, D, the empirical bias where gated), recomputed; s2 replaces the
    pooled noise (then V, Q, the thin-plane test (unless not thin), the gate and D
    follow it)."""
    var, Q = d["var"], d["qb"]
    n, nk = var.shape
    if s2 is None:
        s2 = S2
    if s2 is not None:
        s2 = np.broadcast_to(np.reshape(s2, (-1, 1)), var.shape)
        l1, l2 = d["l1"], d["l2"]
        thin0 = thin_planes(d, d["s2"][:, None])
        curve = ~np.isfinite(var) & (l1 > d["s2"][:, None]) & (l2 > 0) & ~thin0  # the curve test's
        ok = (l1 > s2) & (l2 > 0) & ~curve & (~thin_planes(d, s2) if thin else True)
        with np.errstate(all="ignore"):
            var = np.where(ok, s2 / np.array(KS) * (l1 / (l1 - s2) ** 2 + l2 / (l2 - s2) ** 2), np.inf)
            Q = d["b2raw"] - s2 * d["tr"]
        z = NormalDist().inv_cdf(1 - ALPHA / nk)
        rej = np.isfinite(d["rssv"]) & (d["rssv"] > s2 * np.array([wh(K - 6, z) for K in KS]))
        gate = np.maximum.accumulate(rej, 1) & ~rej[:, :1]
    if gate is None:
        gate = d["gate"] == 1
    Q = np.where(np.isfinite(Q) & (Q > 0), Q, 0)
    D = drift(d, var, **(drift_kw or {}))
    if no_drift is not None:
        D[no_drift] = -np.inf
    b2 = np.maximum(Q, D)
    T, R, ok = test_error(d)
    if emp == "R":
        eb = np.maximum(0, T - R[:, None] - var)
    else:  # differenced against the last candidate the gate passes: R cancels
        k0 = np.maximum(np.argmax(gate, 1) - 1, 0)
        ix = np.arange(n)
        M0 = np.where(np.isfinite(var[ix, k0]), var[ix, k0] + b2[ix, k0], R)
        eb = np.maximum(0, T - T[ix, k0][:, None] + M0[:, None] - var)
    b2 = np.maximum(b2, np.where(gate & ok[:, None], eb, 0))
    return var, np.where(np.isfinite(var), var + b2, np.inf)


def choose(d, var, mse, band_f=TIE_F, band_inf=None, pick=None, agg=None):
    """the minimum, the tie band and the precision-weighted tie-break (kselect.c)"""
    n, nk = var.shape
    ix = np.arange(n)
    if agg is not None:  # the criterion averaged over the noise_k neighbours
        nb = d["nb"]
        Mn = mse[nb]
        fin = np.isfinite(Mn)
        fm = np.min(mse, 1)
        w = (np.where(np.isfinite(fm), 1.0 / np.maximum(fm, 1e-300), 0)[nb] if agg[0] == "prec"
             else np.ones(nb.shape))[:, :, None] * fin
        X = np.log(np.where(fin, Mn, 1.0)) if agg[1] else np.where(fin, Mn, 0)
        s = (w * X).sum(1) / np.maximum(w.sum(1), 1e-300)
        mse = np.where(np.isfinite(mse) & (w.sum(1) > 0), np.exp(s) if agg[1] else s, np.inf)
    best = np.argmin(mse, 1)
    bm = mse[ix, best]
    none = ~np.isfinite(bm)
    best[none] = nk - 1
    fn, fm = d["nrm"][ix, best], bm
    band = np.where(none, np.inf, bm + band_f * np.where(none, 0, var[ix, best]))
    if band_inf is not None:
        band = np.where(band_inf & ~none, np.inf, band)
    tied = np.isfinite(var) & (mse <= band[:, None])
    tied[ix, best] = True
    if pick == "small":
        ch = np.argmax(tied, 1)
    elif pick == "large":
        ch = nk - 1 - np.argmax(tied[:, ::-1], 1)
    else:
        nb = d["nb"]
        with np.errstate(divide="ignore"):
            w = 1.0 / fm[nb]
        w[nb == ix[:, None]] = 0
        T = np.einsum("naj,nj->na", 1 - np.einsum("nac,njc->naj", d["nrm"], fn[nb]) ** 2, w)
        ch = np.where(w.sum(1) > 0, np.argmin(np.where(tied, T, np.inf), 1), best)
    ch = np.where(none, nk - 1, ch)
    return d["nrm"][ix, ch]


def true_s2(dev, case):
    cj = json.load(open(os.path.join(dev, case, "case.json")))
    if cj.get("noise_sigma"):
        return cj["noise_sigma"] ** 2
    return (float(cj["noise"][1:]) * cj["h"]) ** 2 / 3  # uniform in [-xi h, xi h]


def variant(name, d, dev, case):
    global S2
    if name.endswith("@true"):  # a diagnostic: VARIANT with the true noise variance
        S2 = true_s2(dev, case)
        try:
            return variant(name[:-5], d, dev, case)
        finally:
            S2 = None

    def r0_rows():
        return rej0(d)
    if name == "base":
        return choose(d, *criterion(d))
    if name.startswith("band"):
        return choose(d, *criterion(d), band_f=float(name[4:]))
    if name in ("tie_small", "tie_large"):
        return choose(d, *criterion(d), pick=name[4:])
    if name == "tie_all_r0":  # the neighbours' test error at every candidate where K_1 rejects
        return choose(d, *criterion(d), band_inf=r0_rows())
    if name.startswith("agg_"):  # agg_prec, agg_eq, agg_logeq, agg_logprec
        w = name[4:]
        return choose(d, *criterion(d), agg=(w.replace("log", ""), w.startswith("log")))
    if name == "emp_diff":
        return choose(d, *criterion(d, emp="diff"))
    if name in ("emp_r0", "emp_diff_r0"):  # the empirical bias also where K_1 rejects
        g = (d["gate"] == 1) | r0_rows()[:, None]
        if name == "emp_diff_r0":
            g[:, 0] &= ~r0_rows()
        return choose(d, *criterion(d, gate=g, emp="diff" if "diff" in name else "R"))
    if name == "drift_off_r0":
        r0 = r0_rows()
        return choose(d, *criterion(d, no_drift=np.repeat(r0[:, None], len(KS), 1)))
    if name == "drift_sound":  # drifts only from the candidates whose quadric holds
        return choose(d, *criterion(d, drift_kw=dict(ref_ok=~rejects(d))))
    if name == "no_drift":
        return choose(d, *criterion(d, no_drift=np.ones(d["var"].shape, bool)))
    if name == "drift_c1":  # the unbiased drift where the gate or K_1 rejects
        hit = (d["gate"] == 1) | r0_rows()[:, None]
        return choose(d, *criterion(d, drift_kw=dict(tol=1.0, hit=hit)))
    if name == "drift_tri":
        var = d["var"]
        Q = np.where(np.isfinite(d["qb"]) & (d["qb"] > 0), d["qb"], 0)
        B = Q.copy()  # each candidate's bias^2, built up from the smaller ones
        for a in range(1, len(KS)):
            B[:, a] = np.maximum(B[:, a], drift(d, var, tri=B)[:, a])
        return choose(d, *criterion(d, drift_kw=dict(tri=B)))
    if name == "fgate":  # the gate by the nested F test of the residual variance's growth
        rng = np.random.default_rng(1)
        RSS = d["rssv"] * (np.array(KS) - 6)
        F = ((RSS - RSS[:, :1]) / np.maximum(np.array(KS) - KS[0], 1)) / (RSS[:, :1] / (KS[0] - 6))
        q = [np.inf] + [np.quantile(rng.chisquare(K - KS[0], 200000) / (K - KS[0]) /
                                    (rng.chisquare(KS[0] - 6, 200000) / (KS[0] - 6)),
                                    1 - ALPHA / (len(KS) - 1)) for K in KS[1:]]
        g = np.maximum.accumulate(np.isfinite(F) & (F > np.array(q)), 1)
        return choose(d, *criterion(d, gate=g))
    if name == "k_largest":  # the largest assessed candidate
        var, mse = criterion(d)
        a = len(KS) - 1 - np.argmax(np.isfinite(mse)[:, ::-1], 1)
        return d["nrm"][np.arange(len(a)), a]
    if name == "no_thin":  # the rule without the thin-plane test
        return choose(d, *criterion(d, s2=d["s2"], thin=False))
    if name.startswith("s2x"):  # a diagnostic: the pooled noise variance times x
        return choose(d, *criterion(d, s2=float(name[3:]) * d["s2"]))
    if name.startswith("true_s2"):  # a diagnostic: the true noise variance times x
        x = float(name.split("x")[1]) if "x" in name else 1.0
        return choose(d, *criterion(d, s2=x * true_s2(dev, case)))
    sys.exit("unknown variant %s" % name)


def lower_quartile(x):  # kselect_noise.c's, interpolated
    x = np.sort(x[np.isfinite(x)])
    if not len(x):
        return 0.0
    r = 0.25 * (len(x) - 1)
    lo = int(r)
    return x[lo] + (r - lo) * (x[lo + 1] - x[lo]) if lo + 1 < len(x) else x[lo]


def height_fit(X, deg=2):
    """a degree-deg height fit to each row of K points in their own PCA frame: the
    residual variance RSS / (K - p), the mean sixth power of the (unscaled) tangential
    distances and the smallest covariance eigenvalue"""
    c = X.mean(1, keepdims=True)
    w, V = np.linalg.eigh(np.einsum("nki,nkj->nij", X - c, X - c) / X.shape[1])
    L = np.einsum("nkj,nji->nki", X - c, V)
    z, u, v = L[..., 0], L[..., 1], L[..., 2]
    s = np.sqrt(np.max(u ** 2 + v ** 2, 1))[:, None]
    A = np.stack([(u / s) ** (d - j) * (v / s) ** j for d in range(deg + 1) for j in range(d + 1)], -1)
    p = A.shape[-1]
    coef = np.linalg.solve(np.einsum("nki,nkj->nij", A, A) + 1e-14 * np.eye(p),
                           np.einsum("nki,nk->ni", A, z)[..., None])[..., 0]
    r = z - np.einsum("nki,ni->nk", A, coef)
    return (r ** 2).sum(1) / (X.shape[1] - p), ((u ** 2 + v ** 2) ** 3).mean(1), w[:, 0]


def noise_stages(dev, case, noise_k):
    """each stage of the quadric noise estimate over the true sigma^2 (see the top)"""
    from scipy.spatial import cKDTree
    f, _ = devset.read_ply(os.path.join(dev, case, "noisy.ply"))
    P = np.stack([f["x"], f["y"], f["z"]], 1).astype(float)
    t = normals_of(os.path.join(dev, case, "truth.ply"))[1]
    T = np.stack([t["x"], t["y"], t["z"]], 1).astype(float)
    s2, n, kmax = true_s2(dev, case), len(P), KS[-1]
    idx = cKDTree(P).query(P, kmax)[1]
    zl = NormalDist().inv_cdf(1 - ALPHA / len(KS))
    zq = NormalDist().inv_cdf(0.25)
    scales = [noise_k] + [K for K in KS if K > noise_k]
    V, M6, L3, R2 = {}, {}, {}, {}
    for K in sorted(set(scales) | {min(2 * K, kmax) for K in scales}):
        V[K], M6[K], L3[K] = height_fit(P[idx[:, :K]])
        R2[K] = ((P[idx[:, K - 1]] - P) ** 2).sum(1)
    ka, va = np.zeros(n, int), np.zeros(n)
    for i in range(n):  # the truncation rule and Lepski's method (quad_estimate, rose)
        acc = []
        for K in scales:
            v = V[K][i]
            if R2[K][i] < 25 * v:
                if not acc:
                    ka[i], va[i] = K, v
                continue
            if any(not (r2 >= 25 * v and kj * l3 < (kj - 3) * v * wh(kj - 3, -zl)) and
                   math.log(v / vj) > zl * math.sqrt(2 * (1 / (kj - 6) - 1 / (K - 6)))
                   for kj, vj, l3, r2 in acc):
                break
            acc.append((K, v, L3[K][i], R2[K][i]))
            ka[i], va[i] = K, v
    plain = va / np.array([wh(k - 6, zq) for k in ka])
    out, e = plain.copy(), np.full(n, np.nan)
    for k in set(ka.tolist()):  # the Richardson extrapolation of the misfit
        sel, kb = ka == k, min(2 * k, kmax)
        if kb <= k + 6:
            continue
        ma, mb = (height_fit(P[idx[sel][:, :K]])[1] for K in (k, kb))
        ek = (va[sel] * mb - V[kb][sel] * ma) / (mb - ma)
        w = mb / (mb - ma)
        with np.errstate(all="ignore"):
            nu = 1 / (w * w / (k - 6) + (1 - w * w) / (kb - 6))
            q = np.array([wh(x, zq) if x > 0 else np.nan for x in nu])
            o = np.where(ek > 0, np.minimum(ek, va[sel]) / q, np.nan)
        out[sel], e[sel] = np.where(mb > ma, o, plain[sel]), ek
    pool = lambda q: np.array([lower_quartile(q[idx[i]]) for i in range(n)])
    r = lambda x: np.nanmedian(x) / s2
    print("%s: sigma %.3f h" % (case, math.sqrt(s2) / json.load(open(os.path.join(dev, case, "case.json")))["h"]))
    for deg, K in ((2, noise_k), (3, noise_k), (4, 20)):
        p = (deg + 1) * (deg + 2) // 2
        v = height_fit(P[idx[:, :K]], deg)[0]
        print("  degree %d, K = %d: residual variance %.3f, misfit on the noise-free points %.3f, "
              "pooled %.3f" % (deg, K, r(v), r(height_fit(T[idx[:, :K]], deg)[0]), r(pool(v / wh(K - p, zq)))))
    print("  Lepski's scale: mean K %.1f, residual variance %.3f, pooled %.3f" % (ka.mean(), r(va), r(pool(plain))))
    print("  Richardson: extrapolated %.3f (not positive at %.1f%%), pooled %.3f = the cloud's level" %
          (r(e), 100 * np.mean(~(e > 0) & np.isfinite(e)), r(pool(out))))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("devset")
    ap.add_argument("--bootsurf", help="a build with -DBSURF_KSEL_TRACE (required but with --noise-stages)")
    ap.add_argument("--out", help="the work directory (required but with --noise-stages)")
    ap.add_argument("--sampling", default="vertices")
    ap.add_argument("--cases", default="")
    ap.add_argument("--variants", default="base")
    ap.add_argument("--select-k", default="15:80:5", help="the candidates A:B:STEP")
    ap.add_argument("--noise-stages", action="store_true", help="the noise estimate's stages (no build)")
    ap.add_argument("--noise-k", type=int, default=12)
    a = ap.parse_args()
    lo, hi, st = (int(x) for x in a.select_k.split(":"))
    KS[:] = list(range(lo, hi + 1, st))
    if a.noise_stages:
        for c in a.cases.split(","):
            noise_stages(a.devset, c, a.noise_k)
        return
    if not a.bootsurf or not a.out:
        ap.error("--bootsurf and --out are required (but with --noise-stages)")
    os.makedirs(a.out, exist_ok=True)
    cases = a.cases.split(",") if a.cases else sorted(
        c for c in os.listdir(a.devset) if os.path.isdir(os.path.join(a.devset, c)) and
        any("_%s_" % s in c + "_" for s in a.sampling.split(",")))
    names = a.variants.split(",")
    ratios = {v: [] for v in names}
    kmean = {v: [] for v in names}
    print("| case | best K | " + " | ".join(names) + " |")
    print("|---|---|" + "---|" * len(names))
    for c in cases:
        d = run_case(a.bootsurf, a.devset, a.out, c)
        t = d["truth"]
        fe = {10: ang(d["k10"], t).mean()}  # overwritten where 10 is a candidate
        fe.update({K: ang(d["nrm"][:, i], t).mean() for i, K in enumerate(KS)})
        bk = min(FIXED, key=lambda k: fe[k])
        if not np.allclose(choose(d, *criterion(d)), d["cnorm"], atol=1e-6):
            print("warning: %s: the replay differs from the C code's normals" % c, file=sys.stderr)
        row = []
        for v in names:
            nv = variant(v, d, a.devset, c)
            ratios[v].append(ang(nv, t).mean() / fe[bk])
            # the chosen candidate: the one whose normal the variant returned
            ch = np.argmax(np.abs(np.einsum("nkc,nc->nk", d["nrm"], nv)) > 1 - 1e-12, 1)
            kmean[v].append(np.mean(np.array(KS)[ch]))
            row.append("%.3f (K %.1f)" % (ratios[v][-1], kmean[v][-1]))
        print("| %s | %d | %s |" % (c, bk, " | ".join(row)), flush=True)
    print("\n| variant | cases | <= best fixed K | > 5% above | mean ratio | worst | mean K |")
    print("|---|---|---|---|---|---|---|")
    for v in names:
        r = np.array(ratios[v])
        print("| %s | %d | %d | %d | %.4f | %.3f (%s) | %.1f |" % (
            v, len(r), np.sum(r <= 1), np.sum(r > 1.05), r.mean(), r.max(), cases[int(np.argmax(r))],
            np.mean(kmean[v])))


if __name__ == "__main__":
    main()
