/* The two-sheet guard of every smoothing method (docs/smoothing.md, "The
 * guard"). */
#include "algo/smooth_ctx.h"
#include "search/search.h"
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- the guard (docs/smoothing.md, "The guard") ------------------------
 * A least-squares fit to a neighbourhood that mixes two sheets (the
 * opposite face of a thin part, the other side of a sharp edge) runs
 * between them, and every point it moves goes off its own surface. The guard
 * makes each neighbourhood's fit a fit of its centre's sheet, and moves with
 * it only the points of that sheet:
 *  1. the centre's sheet: the n_s = max(K/4, 12) points nearest the centre,
 *     fitted first; their residuals give the sheet's offset m (median) and
 *     noise scale s (1.4826 x the median absolute deviation, robust to the
 *     few points of another sheet among them);
 *  2. a point belongs to the sheet when its residual lies in the prediction
 *     interval |r - m| <= t s sqrt(1 + 1/n_s) (t: Student's quantile at
 *     two-sided level 1%, n_s - 1 degrees of freedom); the fit is made again
 *     from these points only, and 1-2 repeat until the set stops changing
 *     (at most GUARD_ROUNDS times);
 *  3. the fit must be unbiased at the centre: Student's one-sample t test
 *     of "the mean residual of the centre's sheet's n_s nearest points is 0"
 *     (two-sided, same level). A fit that fails is made again from the
 *     nearest K/2 points (the degree drops so that there are two points per
 *     coefficient), down to k_min points; a neighbourhood whose smallest fit
 *     still fails moves no point.
 * The fit then moves only points within GUARD_MOVE prediction half-widths of
 * it (fit_delta's bound). The level is the tests' false-alarm rate on a single sheet: a false
 * alarm costs a fit from fewer points, or one point left to other fits. */
#define BSURF_GUARD_Z 2.5758293035489 /* the normal quantile of 1 - 0.01 / 2 */
#define GUARD_ROUNDS 6
/* A fit moves the points within GUARD_MOVE prediction half-widths of it:
 * with one, the noise's own tail (1% of a sheet at this level, more where
 * n_s points underestimate the scale) was never moved (cube, gaussian 0.5:
 * 0.156 h against 0.147 h with two); a second sheet lies farther out. */
#define GUARD_MOVE 2.0

/* Student's t quantile with nu degrees of freedom at the normal quantile z
 * (Cornish-Fisher expansion, Abramowitz & Stegun 26.7.5: within 1% of the
 * table for nu >= 5 at z = 2.58). */
static double student_t_quantile(double z, double nu) {
  const double z2 = z * z, z3 = z2 * z, z5 = z3 * z2, z7 = z5 * z2;
  return z + (z3 + z) / (4 * nu) + (5 * z5 + 16 * z3 + 3 * z) / (96 * nu * nu) +
         (3 * z7 + 19 * z5 + 17 * z3 - 15 * z) / (384 * nu * nu * nu);
}

/* The degree of a sheet's fit by Mallows' C_p: among the degrees deg, deg -
 * 1, ..., 1 (a plane) of the same points, the one whose estimated mean
 * squared prediction error RSS_d + 2 p_d s^2 is least (p_d coefficients;
 * s^2 = RSS_deg / (n - p_deg), the noise variance from the highest degree:
 * unbiased for it when that fit is). A cubic's extra terms follow the noise
 * where the surface is a quadric or flatter, at a cost in variance of about
 * 2 s^2 per term summed over the points, which C_p weighs against the bias
 * they remove (docs/smoothing.md, "The degree test"). lf: set up at degree
 * >= deg; coef: the fit at deg in, the chosen fit out (zero-padded to m);
 * pred: lf->k doubles. Returns the degree. */
static int degree_by_cp(const bsurf_localfit *lf, int deg, int m, double *coef, double *pred) {
  const int n = lf->k, top = deg;
  if (n - bsurf_poly_terms(top) < 1) return deg;
  double rss = 0;
  bsurf_localfit_predict(lf, top, 1, coef, NULL, pred);
  for (int j = 0; j < n; j++)
    rss += (lf->z[j] - pred[j]) * (lf->z[j] - pred[j]);
  const double s2 = rss / (n - bsurf_poly_terms(top));
  double best = rss + 2.0 * bsurf_poly_terms(top) * s2;
  for (int d = top - 1; d >= 1; d--) {
    double c[BSURF_TERMS_MAX];
    if (bsurf_localfit_solve(lf, d, NULL, c) != 0) break;
    bsurf_localfit_predict(lf, d, 1, c, NULL, pred);
    double r = 0;
    for (int j = 0; j < n; j++)
      r += (lf->z[j] - pred[j]) * (lf->z[j] - pred[j]);
    const double cp = r + 2.0 * bsurf_poly_terms(d) * s2;
    if (cp < best) {
      best = cp;
      deg = d;
      for (int a = 0; a < m; a++)
        coef[a] = a < bsurf_poly_terms(d) ? c[a] : 0.0;
    }
  }
  return deg;
}

/* n_s: a quarter of the neighbourhood, and at least 12 points (two per
 * coefficient of a quadric, the lowest degree that follows curvature: the
 * first fit of an exact surface is then exact) */
static int guard_near(int k) {
  return k / 4 > 12 ? k / 4 : (k < 12 ? k : 12);
}

/* Two sheets apart: the largest gap between the sorted residuals v[0..n-1]
 * of the first fit, as a scan test. On a single sheet the residuals near
 * any value c are locally uniform with density lambda (points per unit
 * residual), so the spacing after a point exceeds x / lambda with
 * probability e^-x, and the largest of n spacings exceeds ln(n / alpha) /
 * lambda with probability about alpha (the guard's level, 1%). lambda at a
 * gap: the q = max(3, n/4) points on each side over the width they span. A
 * gap with lambda g above that bound separates two sheets (the opposite face
 * of a thin part: on a 2 x 2 plate whose faces are 1.3 spacings apart, at
 * uniform noise 0.25 h, the faces' residuals leave a gap of 0.8 h); only
 * gaps with at least q points on each side count, and only gaps wider than
 * tiny (1e-9 of the neighbourhood's radius: on exact data the residuals are
 * rounding). Returns the gap's midpoint, NAN when there is none. */
static double guard_gap(const double *v, int n, double tiny) {
  const int q = n / 4 > 3 ? n / 4 : 3;
  double best = log((double)n / 0.01), cut = NAN;
  for (int i = q - 1; i + q < n; i++) {
    const double g = v[i + 1] - v[i];
    const double wl = v[i] - v[i - q + 1], wr = v[i + q] - v[i + 1];
    if (!(g > tiny)) continue; /* rounding, not a gap */
    const double lambda = (wl + wr > 0) ? 2.0 * (q - 1) / (wl + wr) : INFINITY;
    if (lambda * g > best) {
      best = lambda * g;
      cut = 0.5 * (v[i] + v[i + 1]);
    }
  }
  return cut;
}

/* Two sheets mixed (bsurf_split_bimodal, split.c, has the test's
 * derivation). It finds sheets whose residuals overlap too closely for
 * guard_gap: on the development set's thin plate at uniform noise 0.5 h,
 * where a gap of 0.27 h is left between the faces, it fires on about 40% of
 * the 50-point neighbourhoods that guard_gap missed (simulated). Residuals
 * whose spread is rounding (below tiny) are not tested. Returns the split's
 * midpoint, NAN when the share is above the test's quantile. */
static double guard_bimodal(const double *v, int n, double tiny) {
  double cut;
  return bsurf_split_bimodal(v, n, tiny, &cut) ? cut : NAN;
}

#define GUARD_Q_Z -1.2815515655446004     /* the normal lower decile */
#define GUARD_MISFIT_Z 1.6448536269514722 /* the normal quantile of 1 - 0.05 */

/* The share of a normal variance left inside the interval |x| <= c sigma:
 * Var(X | |X| <= c) / sigma^2 = 1 - 2 c phi(c) / (2 Phi(c) - 1) (the
 * truncated normal's variance; c^2 / 3 as c -> 0, where the density is flat
 * across the interval). */
static double trunc_share(double c) {
  if (!(c > 1e-4)) return c > 0 ? c * c / 3.0 : 0.0;
  if (c > 40) return 1.0;
  const double phi = exp(-0.5 * c * c) * 0.3989422804014327 /* 1 / sqrt(2 pi) */;
  const double mass = erf(c / sqrt(2.0));
  const double g = 1.0 - 2.0 * c * phi / mass;
  return g > c * c / 3.0 * 1e-3 ? g : c * c / 3.0 * 1e-3;
}

/* The share of the noise variance a sheet's interval keeps, from the share p
 * of the points it would move (within GUARD_MOVE half-widths) that fall
 * outside its interval: for normal noise the interval is |x| <= c sigma with
 * p = erfc(c / sqrt 2), and keeps trunc_share(c); light-tailed noise (a
 * uniform's interval is about 4 of its standard deviations wide) leaves no
 * point outside, p = 0 and a share of 1. */
static double kept_share(int n_out, int n_in) {
  if (n_out <= 0 || n_in <= 0) return 1.0;
  const double p = (double)n_out / (n_out + n_in);
  double lo = 0, hi = 40;
  for (int it = 0; it < 60; it++) {
    const double mid = 0.5 * (lo + hi);
    if (erfc(mid * 0.7071067811865476) > p)
      lo = mid;
    else
      hi = mid;
  }
  return trunc_share(0.5 * (lo + hi));
}

/* kappa, the share of the noise variance a ball of radius t sigma keeps
 * (guard_ball_share = bsurf_ball_share, ball_scale.c, which derives and
 * tabulates it). */

/* The cloud's noise variance for the misfit test (docs/smoothing.md, "The
 * misfit test", "The noise estimate"): sigma^2 such that it is the lower
 * decile over the sheet fits of s_i^2 / (q(nu_i) g_i kappa(R_i / sigma)),
 * s_i^2 = RSS / nu_i a fit's residual variance over the points of its
 * interval, g_i the share of the noise variance that interval keeps
 * (kept_share), kappa the share the fit's ball of radius R_i keeps
 * (guard_ball_share) and q(nu) the lower decile of chi^2_nu / nu. Where every
 * fit sees only noise of variance sigma^2, s_i^2 / (q(nu_i) g_i kappa_i)
 * falls below sigma^2 for a tenth of the fits, whatever their degrees of
 * freedom, intervals and balls; fits with misfit (a coarse mesh's creases,
 * two sheets the guard did not part) only raise the upper part, so up to
 * nine tenths of the fits may be biased (the lower quartile, used before,
 * was a mixture's on the thin plate at uniform 0.5 h, where about 60% of
 * the fits hold both faces). kappa depends on sigma: the fixed point is
 * reached from below, from kappa = 1 (each step's estimate is at least the
 * one before, and bounded, as kappa >= its value at t = 1), stopping when it
 * changes by less than 1e-12 of itself (at most 200 steps). sv: records
 * (s^2, nu, g, R) every `stride` doubles; scratch: n doubles. NAN when no fit
 * has a variance. */
double guard_noise(const double *sv, size_t n, size_t stride, double *scratch) {
  double s2 = NAN;
  for (int step = 0; step < 200; step++) {
    size_t m = 0;
    const double inv = step ? 1.0 / sqrt(s2) : 0.0;
    for (size_t i = 0; i < n; i++) {
      const double *v = &sv[i * stride];
      if (!(v[0] >= 0 && v[1] >= 1)) continue;
      const double kap = step ? guard_ball_share(v[3] * inv) : 1.0;
      scratch[m++] = v[0] / (bsurf_chi2_ratio_wh(v[1], GUARD_Q_Z) * v[2] * kap);
    }
    if (!m) return NAN;
    const double next = bsurf_kth_smallest(scratch, m, m / 10);
    if (step && !(fabs(next - s2) > 1e-12 * s2)) return next;
    s2 = next;
    if (!(s2 > 0)) return s2; /* exact data: no noise to scale the balls by */
  }
  return s2;
}

/* 1 when a sheet fit (sv: its record) has more misfit than noise: a point
 * moved onto it ends farther from the surface, on average, than it was. Its
 * residual variance over its interval and ball, s^2 / (g kappa), estimates
 * sigma^2 + b^2 (b^2 the mean squared misfit, which is also about the
 * squared bias of its predictions), and a full move helps when b^2 <
 * sigma^2: the test rejects "s^2 / (g kappa) <= 2 sigma^2" when it exceeds 2
 * sigma^2 times the upper 5% quantile of chi^2_nu / nu. noise NAN: no test.
 * noise 0 (a tenth of the fits or more leave no residual: noise-free input)
 * is a level like any other: no move helps where there is no noise to
 * remove, and every fit that leaves a residual, however small, is rejected
 * (a clean CAD part's fits across its edges moved points off them:
 * docs/smoothing.md, "Noise-free input"). */
int guard_misfit(const double *sv, double noise) {
  if (!(noise >= 0)) return 0;
  if (!(sv[1] >= 1)) return 0; /* no variance: no fit (moves nothing anyway) */
  /* noise-free: any residual is misfit (the test below in the limit; said
   * here rather than left to sv[3] / sqrt(0) = inf and guard_ball_share's
   * value there) */
  if (noise == 0) return !(sv[0] <= 0);
  const double kap = guard_ball_share(sv[3] / sqrt(noise));
  return !(sv[0] <= 2.0 * noise * sv[2] * kap * bsurf_chi2_ratio_wh(sv[1], GUARD_MISFIT_Z));
}

/* The guard on the neighbourhood idx[0..k-1] (idx[0] its centre) of the
 * positions xyz: F (fit_store's record) and *degree out. Returns the
 * neighbourhood size whose fit passes (negative when the fit is of only part
 * of it, a sheet); 0 when none down to k_min does, F's scale is then NAN,
 * which fit_delta and the pair lanes read as "moves nothing". s: the
 * thread's scratch (its localfit and est_scratch); act: k entries.
 * Where the first fit's residuals fall in two groups apart (guard_gap), the
 * centre's group is its sheet: the offset and scale come from that sheet's
 * nearest points, and no point beyond the gap belongs to it or is moved.
 * svar (NULL: not wanted): the passing fit's record for the misfit test
 * (guard_noise, guard_misfit): its residual variance over its sheet's
 * points, RSS / nu, nu = points - coefficients, and g, the share of the
 * noise variance its interval keeps (kept_share, from the points it would
 * move outside the interval), and R, the radius of the ball its kc points
 * fill (guard_ball_share) (NAN, 0, NAN, NAN when none passes). */
int guard_fit(const smooth_ctx *c, bsurf_error_scratch *s, uint32_t *act, const double *xyz,
              const uint32_t *idx, int k, double *F, int *degree, double *svar) {
  if (svar) svar[0] = NAN, svar[1] = 0, svar[2] = NAN, svar[3] = NAN;
  /* tiny: the rounding level of residuals, 1e-9 of the neighbourhood's
   * radius in its frame (lf->scale of the plane fit below). Of the
   * neighbourhood's own points only: a tile's neighbour graph has no global
   * spacing h (a tiled stage 1 runs before h is known; its nb->h is 0), and
   * 1e-9 h in memory against 0 in a tile made the tests (the gap, the
   * interval's floor, the t test) count rounding in one run and not in the
   * other: test_tiles' tiled naive/bilateral differed from bsurf_smooth. */
  double tiny = 0;
  const int kmin = c->o.k_min > 3 ? c->o.k_min : 3;
  bsurf_localfit *lf = &s->lf;
  /* the scratch is sized for the full neighbourhood size c->k (k <= c->k) */
  const int K = c->k;
  double *r = s->est_scratch + K, *tmp = s->est_scratch + 2 * (size_t)K;
  double *srt = s->est_scratch + 3 * (size_t)K, *in = s->est_scratch + 4 * (size_t)K;
  double *mine = s->est_scratch + 5 * (size_t)K;
  /* two sheets: the residuals about a plane through all K points of the
   * neighbourhood (both sheets; K even where the fit is of fewer points, as
   * multipass's K_i) fall in two groups with a gap between them
   * (guard_gap); the centre's group is its sheet (mine[j] = 1), and lim is
   * half the distance between the groups' medians: no point farther than
   * that from the sheet belongs to it or is moved by its fit. A plane: a fit
   * of higher degree bends between the sheets and fills the gap (a cubic of
   * 50 points hid it in most neighbourhoods of the development set's thin
   * plate). */
  int split = 0;
  double lim = INFINITY;
  {
    bsurf_frame fr;
    bsurf_local_frame(xyz, idx, K, c->o.error.pca_center, &fr);
    bsurf_localfit_setup(lf, xyz, idx, K, &fr, 1);
    tiny = 1e-9 * lf->scale;
    double coef[BSURF_TERMS_MAX];
    const int dd = solve_with_fallback(lf, 1, c->m, coef);
    fit_store(F, &fr, 1.0 / lf->scale, coef, c->m);
    int nv = 0;
    for (int j = 0; j < K; j++) {
      r[j] = -fit_delta_any(F, dd, c->m, &xyz[3 * (size_t)idx[j]], 0);
      if (!isnan(r[j])) srt[nv++] = r[j];
    }
    qsort(srt, (size_t)nv, sizeof *srt, bsurf_cmp_double);
    double cut = nv >= 8 && !isnan(r[0]) ? guard_gap(srt, nv, tiny) : NAN;
    if (nv >= 8 && !isnan(r[0]) && isnan(cut)) cut = guard_bimodal(srt, nv, tiny);
    if (!isnan(cut)) {
      split = 1;
      const int side = r[0] > cut ? 1 : -1;
      int lo = 0, hi = 0;
      for (int j = 0; j < nv; j++)
        if (srt[j] > cut)
          hi++;
        else
          lo++;
      /* the groups' medians: srt[0..lo) and srt[lo..nv) */
      const double m_lo = lo % 2 ? srt[lo / 2] : 0.5 * (srt[lo / 2 - 1] + srt[lo / 2]);
      const double m_hi =
          hi % 2 ? srt[lo + hi / 2] : 0.5 * (srt[lo + hi / 2 - 1] + srt[lo + hi / 2]);
      lim = 0.5 * (m_hi - m_lo);
      for (int j = 0; j < K; j++)
        mine[j] = !isnan(r[j]) && (r[j] > cut ? 1 : -1) == side;
    }
  }
  for (int kc = k; kc >= kmin; kc /= 2) {
    const int ns = guard_near(kc);
    /* the first fit: the centre's ns nearest points (most of them on its
     * sheet, however many of the K are not), grown from there; or, split,
     * the centre's sheet's points among the kc */
    int na = ns, deg = c->degree;
    for (int j = 0; j < ns; j++)
      act[j] = idx[j];
    double m = 0, bound = INFINITY;
    int side = 0;
    double lim_kc = INFINITY;
    if (split) {
      int nm = 0;
      for (int j = 0; j < kc; j++)
        if (mine[j] != 0) act[nm++] = idx[j];
      if (nm >= 3) {
        side = 1;
        na = nm;
        lim_kc = lim;
      } else {
        for (int j = 0; j < ns; j++)
          act[j] = idx[j];
      }
    }
    for (int round = 0;; round++) {
      /* the fit of the sheet's points: frame, degree with two points per
       * coefficient, least squares */
      bsurf_frame fr;
      bsurf_local_frame(xyz, act, na, c->o.error.pca_center, &fr);
      int d = c->degree;
      while (d > 1 && 2 * bsurf_poly_terms(d) > na)
        d--;
      bsurf_localfit_setup(lf, xyz, act, na, &fr, d);
      double coef[BSURF_TERMS_MAX];
      deg = solve_with_fallback(lf, d, c->m, coef);
      if (c->o.degree_test) deg = degree_by_cp(lf, deg, c->m, coef, s->pred_full);
      fit_store(F, &fr, 1.0 / lf->scale, coef, c->m);
      /* residuals of every point of the neighbourhood (beyond the fit's
       * disc too: the sheet grows from its nearest points) */
      int nn = 0;
      for (int j = 0; j < kc; j++)
        r[j] = -fit_delta_any(F, deg, c->m, &xyz[3 * (size_t)idx[j]], 0);
      if (side) { /* which of the neighbourhood's points are the sheet's now */
        for (int j = 0; j < kc; j++)
          in[j] = 0;
        for (int a = 0, j = 0; a < na && j < kc; j++)
          if (idx[j] == act[a]) in[j] = 1, a++;
      }
      /* 1: the centre's sheet: offset and noise scale from its nearest
       * points (of its side of a gap) */
      for (int j = 0; j < kc && nn < ns; j++)
        if (!isnan(r[j]) && (side ? in[j] != 0 : j < ns)) tmp[nn++] = r[j];
      if (nn < 3) break;
      m = bsurf_median(tmp, (size_t)nn);
      int t = 0;
      for (int j = 0; j < kc && t < nn; j++)
        if (!isnan(r[j]) && (side ? in[j] != 0 : j < ns)) tmp[t++] = fabs(r[j] - m);
      const double sc = 1.4826 * bsurf_median(tmp, (size_t)t);
      bound = fmax(student_t_quantile(BSURF_GUARD_Z, t - 1) * sc * sqrt(1.0 + 1.0 / t), tiny);
      const double bin = fmin(bound, lim_kc);
      /* 2: the points of that sheet (the centre always) */
      int n_in = 1, changed = 0;
      for (int j = 1; j < kc; j++) {
        if (!(fabs(r[j] - m) <= bin)) continue;
        if (n_in >= na || act[n_in] != idx[j]) changed = 1;
        act[n_in++] = idx[j];
      }
      changed |= n_in != na;
      if (!changed || round == GUARD_ROUNDS || n_in < 3) break;
      na = n_in;
    }
    /* 3: unbiased at the centre: the t test on the sheet's nearest points */
    const double bin = fmin(bound, lim_kc);
    double sum = 0, ss = 0;
    int n = 0;
    for (int j = 0; j < ns; j++)
      if (fabs(r[j] - m) <= bin) sum += r[j], n++;
    const double mean = n ? sum / n : 0;
    for (int j = 0; j < ns; j++)
      if (fabs(r[j] - m) <= bin) ss += (r[j] - mean) * (r[j] - mean);
    const double sd = n > 1 ? sqrt(ss / (n - 1)) : 0;
    if (svar) {
      /* the sheet's residual variance RSS / (n - p), over the points of its
       * interval (docs/smoothing.md, "The misfit test", for why not those
       * of the wider move bound) */
      double rss = 0;
      int nin = 0, nout = 0;
      const double mv = fmin(GUARD_MOVE * bound, lim_kc);
      for (int j = 0; j < kc; j++)
        if (fabs(r[j] - m) <= bin)
          rss += r[j] * r[j], nin++;
        else if (fabs(r[j] - m) <= mv)
          nout++;
      const int p = bsurf_poly_terms(deg);
      svar[0] = nin > p ? rss / (nin - p) : NAN;
      svar[1] = nin - p;
      svar[2] = kept_share(nout, nin);
      /* the ball's radius: the farthest of the kc points from the centre */
      double R2 = 0;
      const double *z0 = &xyz[3 * (size_t)idx[0]];
      for (int j = 1; j < kc; j++) {
        const double *z = &xyz[3 * (size_t)idx[j]];
        const double d2 = (z[0] - z0[0]) * (z[0] - z0[0]) + (z[1] - z0[1]) * (z[1] - z0[1]) +
                          (z[2] - z0[2]) * (z[2] - z0[2]);
        if (d2 > R2) R2 = d2;
      }
      svar[3] = sqrt(R2);
    }
    if (n >= 3 && !(fabs(mean) > tiny &&
                    fabs(mean) * sqrt((double)n) > student_t_quantile(BSURF_GUARD_Z, n - 1) * sd)) {
      /* moves: delta = f - z = -r, so |delta| <= |m| + bound holds the sheet
       * (and no point beyond a gap) */
      F[13] = fabs(m) + fmin(GUARD_MOVE * bound, lim_kc);
      *degree = deg;
      return na < kc ? -kc : kc;
    }
  }
  if (svar) svar[0] = NAN, svar[1] = 0, svar[2] = NAN, svar[3] = NAN;
  F[12] = NAN;
  return 0;
}
