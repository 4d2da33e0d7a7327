/* The MSE rule's noise passes (docs/normals.md, "Choosing K"; the
 * derivation at the top of kselect.c, "Noise s2"): the residual variance
 * of a local quadric per point at a scale chosen per point (the truncation
 * rule, then Lepski's method over the nested scales, below) and the
 * Richardson extrapolation of its misfit, pooled as the lower quartile
 * over the K_max neighbours, then (BSURF_NOISE_POOL_GLOBAL) as the median
 * over the cloud. */
#include "algo/kselect.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The noise's pooling: the lower quartile of the neighbours' estimates,
 * each divided by the lower quartile of chi^2_nu / nu (see the top of the
 * file); Z_Q is the standard normal's quartile. */
#define POOL_Q 0.25
#define Z_Q (-0.6744897501960817)

/* the POOL_Q quantile of chi^2_nu / nu (Wilson-Hilferty) */
static double chi2_quantile_ratio(int nu) {
  return bsurf_chi2_ratio_wh(nu, Z_Q);
}

/* Pass 1: the residual variance of a quadric on the point's K nearest
 * neighbours, in their own PCA frame, at a scale K chosen per point among
 * the nested scales noise_k < K_1 < K_2 < ... (the candidates above
 * noise_k). Stored divided by the lower quartile of chi^2_nu / nu, for the
 * quartile pooling of pass 2.
 *
 * The scale. The residual variance v_K reads sigma^2 only where the
 * quadric holds and the ball holds the noise: too small a ball truncates
 * the heights (v_K low), too large a one holds the surface's misfit (v_K
 * high, growing with K). So:
 *  - Truncation. A scale whose K-th neighbour lies less than TRUNC
 *    residual standard deviations away, R_K^2 < TRUNC^2 v_K, is truncated
 *    (see the top of the file): no estimate of sigma^2.
 *  - Lepski's method (Lepski, Mammen & Spokoiny 1997, Ann. Statist. 25;
 *    the intersection of confidence intervals of Goldenshluger & Nemirovski
 *    1997 and Katkovnik 1999): the scales are taken in increasing order,
 *    and the point keeps the largest scale K whose estimate agrees with
 *    every smaller untruncated scale j's; the first that does not holds
 *    structure the smaller ones did not (misfit), and so does every larger
 *    one (nested). Agreement is tested on the log scale, where chi^2_nu /
 *    nu has the variance 2 / nu whatever sigma (the variance-stabilising
 *    transform of a sample variance, Bartlett & Kendall 1946), and the
 *    nested samples make Var(ln v_j - ln v_K) = 2 / nu_j - 2 / nu_K (the
 *    larger sample's estimate is the efficient one: the Hausman identity
 *    of kselect.c's drift): K is rejected when
 *        ln(v_K / v_j) > z sqrt(2 / nu_j - 2 / nu_K),
 *    z the lack-of-fit tests' level (kselect_lof.c, 5% over the
 *    candidates, Bonferroni). A fall is not tested: misfit only adds
 *    to the residual variance as K grows.
 *  - Every accepted smaller scale j constrains K (each passed its own
 *    truncation test, R_j^2 >= TRUNC^2 v_j), except where its PCA plane is
 *    thinner than K's level allows a surface's (ksel_thin_plane,
 *    kselect_lof.c: the neighbours lie in a plane that holds the noise,
 *    ring-sampled CAD vertices, and read no noise). A further condition
 *    that j could have read K's level, R_j^2 >= TRUNC^2 v_K, was measured
 *    and dropped: it lets the statistic under test choose its own
 *    witnesses, so the larger K's rise (the more misfit), the fewer smaller
 *    scales test it (elephant's vertices at g0.6: 1.083 times the best
 *    fixed K's mean angle error with it, 1.036 without; docs/normals.md,
 *    "The noise fit's scale per point").
 * Where no scale is untruncated, the largest (the truncation rule's
 * stop at K_max). */
#define TRUNC 5.0
/* the residual variance of a quadric on the first K neighbours in their own
 * PCA frame, the mean sixth power of their tangential distances (the scale
 * of a cubic's misfit) and (l3 non-NULL) the frame's smallest eigenvalue;
 * -1 when rank-deficient */
static int quad_resid(const double *xyz, const uint32_t *idx, int K, ksel_scratch *s, double *var,
                      double *m6, double *l3) {
  bsurf_frame f;
  const double sc = local_coords(xyz, idx, K, K, &f, s->u, s->v, s->z);
  if (l3) *l3 = f.eigenvalues[0];
  quad_sums q;
  memset(&q, 0, sizeof q);
  double r6 = 0;
  for (int j = 0; j < K; j++) {
    quad_add(&q, s->u[j], s->v[j], s->z[j]);
    const double r2 = s->u[j] * s->u[j] + s->v[j] * s->v[j];
    r6 += r2 * r2 * r2;
  }
  double coef[QT], rss;
  if (quad_solve(&q, coef, &rss, NULL) != 0) return -1;
  *var = rss / (K - QT);
  *m6 = r6 / K * sc * sc * sc * sc * sc * sc;
  return 0;
}

/* Whether scale K's estimate v rose beyond what the m accepted smaller
 * scales allow (Lepski's test above); sc holds, per accepted scale, K, v,
 * l3 and R^2. */
static int rose(const double *sc, int m, int K, double v, double z) {
  for (int t = 0; t < m; t++) {
    const double *j = &sc[4 * t];
    const int Kj = (int)j[0];
    if (ksel_thin_plane(Kj, j[2], j[3], v, z)) continue;
    if (log(v / j[1]) > z * sqrt(2.0 * (1.0 / (Kj - QT) - 1.0 / (K - QT)))) return 1;
  }
  return 0;
}

void noise_point(void *vctx, int thread, size_t i) {
  ksel_ctx *c = vctx;
  ksel_scratch *s = &c->scr[thread];
  const bsurf_kselect_options *o = c->o;
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  const double *d = &c->xyz[3 * (size_t)idx[0]];
  c->s2[i] = NAN;
  int ka = 0, m = 0; /* the kept scale; the untruncated scales accepted */
  double va = 0, m6a = 0;
  for (int a = -1; a < o->nk; a++) {
    const int K = a < 0 ? o->noise_k : o->ks[a];
    if (a >= 0 && K <= o->noise_k) continue;
    double v, m6, l3;
    if (quad_resid(c->xyz, idx, K, s, &v, &m6, &l3) != 0) continue;
    const double *p = &c->xyz[3 * (size_t)idx[K - 1]];
    const double R2 = (p[0] - d[0]) * (p[0] - d[0]) + (p[1] - d[1]) * (p[1] - d[1]) +
                      (p[2] - d[2]) * (p[2] - d[2]);
    if (R2 < TRUNC * TRUNC * v) { /* truncated: kept only until a scale is not */
      if (!m) ka = K, va = v, m6a = m6;
      continue;
    }
    if (rose(s->scales, m, K, v, c->lof_z)) break; /* misfit from K on */
    double *e = &s->scales[4 * m++];
    e[0] = K, e[1] = v, e[2] = l3, e[3] = R2;
    ka = K, va = v, m6a = m6;
  }
  if (!ka) return;
  c->s2[i] = va / chi2_quantile_ratio(ka - QT);
  /* Richardson extrapolation of the quadric's misfit (see the top of the
   * file): a second fit on twice the points, the misfit's share removed */
  const int kb = 2 * ka < c->kmax ? 2 * ka : c->kmax;
  if (kb <= ka + QT) return;
  double vb, m6b;
  if (quad_resid(c->xyz, idx, kb, s, &vb, &m6b, NULL) != 0 || !(m6b > m6a)) return;
  const double e = (va * m6b - vb * m6a) / (m6b - m6a);
  /* degenerate: the residual variance grew from ka to kb points faster
   * than the misfit's sixth-power law allows with no noise at all (the
   * doubled neighbourhood crosses an edge or wraps round a thin part), so
   * the extrapolation says nothing about the noise: no estimate, as for a
   * rank-deficient fit (formerly clamped to 0, which the lower-quartile
   * pool then picked) */
  if (!(e > 0)) {
    c->s2[i] = NAN;
    return;
  }
  /* the extrapolated estimate e = w va - (w - 1) vb, w = m6b / (m6b - m6a),
   * scatters more than va: with Var(v) = 2 s2^2 / nu and, the samples
   * nested, Cov(va, vb) = Var(vb), Var(e) = 2 s2^2 (w^2 / nu_a + (1 - w^2)
   * / nu_b); its quartile is that of chi^2 / nu at Satterthwaite's
   * effective degrees of freedom nu = 2 s2^2 / Var(e) */
  const double w = m6b / (m6b - m6a), na = ka - QT, nb = kb - QT;
  const double nu = 1.0 / (w * w / na + (1.0 - w * w) / nb);
  c->s2[i] = (e < va ? e : va) / bsurf_chi2_ratio_wh(nu, Z_Q);
}

/* Pass 2: the lower quartile of the (quartile-corrected) residual
 * variances over the point's kmax neighbours (the largest candidate's
 * neighbourhood; see the top of the file). */
void pool_point(void *vctx, int thread, size_t i) {
  ksel_ctx *c = vctx;
  ksel_scratch *s = &c->scr[thread];
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  int m = 0;
  for (int j = 0; j < c->kmax; j++)
    if (!isnan(c->s2[idx[j]])) s->pool[m++] = c->s2[idx[j]];
  if (m == 0) {
    c->noise[i] = 0;
    return;
  }
  /* the order statistic nearest the quartile (interpolated): the lo-th
   * smallest by selection, the next the smallest above it (the values of a
   * full sort) */
  const double r = POOL_Q * (m - 1);
  const int lo = (int)r;
  const double vlo = bsurf_kth_smallest(s->pool, (size_t)m, (size_t)lo);
  double vhi = vlo;
  if (lo + 1 < m) {
    vhi = s->pool[lo + 1];
    for (int j = lo + 2; j < m; j++)
      vhi = s->pool[j] < vhi ? s->pool[j] : vhi;
  }
  c->noise[i] = lo + 1 < m ? vlo + (r - lo) * (vhi - vlo) : vlo;
}

/* Pass 2b (BSURF_NOISE_POOL_GLOBAL): one noise level for the cloud, the
 * median of the points' pooled estimates (see the top of the file), of a
 * sorted copy: the same whatever the threads. */
bsurf_status pool_global(double *noise, size_t n) {
  double *tmp = bsurf_alloc_array(n, sizeof(double));
  if (!tmp) return BSURF_ERR_NOMEM;
  memcpy(tmp, noise, n * sizeof(double));
  const double med = bsurf_median(tmp, n);
  for (size_t i = 0; i < n; i++)
    noise[i] = med;
  free(tmp);
  return BSURF_OK;
}
