/* Feature detection by the distance map (thesis 7.1; bsurf_detect_features,
 * features.c, runs it), and the incremental PCA of a neighbourhood that it
 * and the variance method (bsurf_pca_l0_trace) read.
 *
 * Distance map (7.1): for every point p, PCA of its growing K-neighbourhoods
 * K = k_min, k_min + k_step, ... <= k_max along its sorted neighbour list.
 * The covariance is grown incrementally: running sums of q and q q^T with
 * q = x - p (about p for conditioning; the covariance is about the
 * centroid), so each size costs O(k_step) plus the eigenvalues of a 3x3
 * matrix (closed form, eigvals_sym3).
 * f(i) = lambda0 / lambda2 (a/c of the thesis). The first size where f (or
 * f + d f', f' the difference to the previous size) exceeds T_{a/c} stops
 * the growth; its radius (distance to its farthest point, the last of the
 * sorted list) is the distance h_p to the nearest feature. If T_{a/c} is
 * never exceeded the radius of k_max is used ("the process will terminate").
 *
 * Noise-adapted T_{a/c} (noise_factor c, default 1.75; 0 = the thesis's
 * fixed T_{a/c}): noise of amplitude sigma adds about sigma^2 to lambda0
 * while lambda2 grows with the radius squared, so on a flat area f(K) is
 * about 3 sigma^2 / r_K^2: uniform noise 1.0 h gives f(15) ~ 0.15 on the
 * faces of the cube, above 0.1, and 86% of the points "stopped at once"
 * (Fig. 7.3's problem; F1 0.26 on the cube, 0.50 on Fandisk, whatever T_h).
 * Each size K gets T(K) = max(T_{a/c}, c x median_i f_i(K)): the median
 * point is a flat one (features are a minority), so c x median sits above
 * the noise level of f(K) and below the features' f. At noise <= 0.5 h
 * c x median < 0.1 at every K and the map is the thesis's unchanged.
 * Measured on the cube and Fandisk of docs/validation.md (F1 with the
 * automatic T_h below, noise 0 / 0.5 / 1.0, without the filter): c = 1.25: cube 1.00 / 0.94 /
 * 0.44, Fandisk 0.86 / 0.90 / 0.72; 1.5: 0.64 and 0.82 at noise 1.0; 1.75:
 * 0.76 and 0.83; 2: 0.76 and 0.78; 2.5: 0.62 and 0.60 (and lower at 0.5:
 * T(k_min) passes 0.1). Subtracting an estimate of sigma^2 from lambda0
 * instead ((lambda0 - s^2) / (lambda2 - s^2), s^2 the median lambda0 at k_max
 * or at each K) was tried and not kept: 0.65-0.74 at noise 1.0 but Fandisk
 * at 0.5 fell from 0.90 to 0.78-0.84 (its curvature lifts the median). The
 * medians come from every stride-th point (at most ~4M values), so the
 * cost is a fraction of the map's.
 *
 * The points that stop at once (the k_min neighbourhood already exceeds
 * T_{a/c}) are the thesis's "points with zero distance values": they are on
 * a feature (or noisy) and get -max(radius), the negative of the largest
 * radius of all points, so that the edge-preserving bilateral filter keeps
 * them apart from the smooth positive part of the map.
 *
 * Bilateral filter (Eq. 7.1), Jacobi passes over the first filter_k
 * neighbours (the point included):
 *   h'_j = (1 - alpha) h_j + alpha sum g_a(|p_j - q_i|) g_b(|h_j - h_i|) h_i
 *                               / sum g_a(...) g_b(...)
 * g(x) = exp(-x^2 / (2 sigma^2)), sigma_a = h (mean nearest-neighbour
 * distance, as the thesis), sigma_b = sigma_range x max(radius).
 *
 * Features: feature_dist <= threshold x max(feature_dist) (Fig. 7.4: 10-30%
 * of the maximum; threshold 0 is Fig. 7.5's T_h = 0). Auto (NAN): the
 * points <= 0 and, among those that exceeded T_{a/c} at some size, the ones
 * below Otsu's split of the positive values. Why: T_h = 0 keeps only the
 * points that stop at k_min, i.e. within about one spacing of an edge
 * (recall 0.35-0.71 against the 2-spacing labels: F1 0.51-0.83); the
 * positive map is a plateau near max(radius) (neighbourhoods that never
 * met a feature) and a band below it (those that met one before k_max),
 * two modes that Otsu separates. Tried on the same data (F1, cube / Fandisk
 * at noise 0 / 0.5, fixed T_{a/c}, without the filter): T_h = 0: 0.67 0.83 / 0.51 0.68; Otsu on
 * all values (it splits at 0): the same; Otsu on the positive values: 1.00
 * 0.94 / 0.86 0.90; a fixed 0.75 x max: 1.00 0.96 / 0.88 0.91 (as good,
 * but tied to the k_max / k_min radius ratio); median - 3 MAD of the
 * positive values: 0.24 0.68 / 0.88 0.91 (the cube's plateau is too narrow).
 * Points that never exceeded T_{a/c} are kept out even below the split: on
 * a featureless surface the split would cut the density variations of the
 * k_max radii (a plane would get features). */
#include "algo/algo.h"
#include "common/common.h"
#include "local/local.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- incremental PCA ---- */

typedef struct pca_sums {
  double s1[3], s2[6]; /* sum q, sum q q^T (xx xy xz yy yz zz) */
  int m;
} pca_sums;

static void sums_add(pca_sums *s, const double *p, const double *o) {
  double q[3] = {p[0] - o[0], p[1] - o[1], p[2] - o[2]};
  s->s1[0] += q[0];
  s->s1[1] += q[1];
  s->s1[2] += q[2];
  s->s2[0] += q[0] * q[0];
  s->s2[1] += q[0] * q[1];
  s->s2[2] += q[0] * q[2];
  s->s2[3] += q[1] * q[1];
  s->s2[4] += q[1] * q[2];
  s->s2[5] += q[2] * q[2];
  s->m++;
}

/* The eigenvalues of a symmetric 3x3 matrix, ascending, in closed form
 * (trigonometric solution of the characteristic polynomial; Smith 1961).
 * Only the ratio lambda0 / lambda2 is needed, to be compared with T_{a/c}
 * ~ 0.1: the absolute error of about 1e-15 lambda2 is ample, and it is
 * several times faster than the Jacobi sweeps of bsurf_eigen_sym3 (which
 * also build the eigenvectors; it took 45% of the distance method). */
static void eigvals_sym3(const double C[3][3], double ev[3]) {
  const double p1 = C[0][1] * C[0][1] + C[0][2] * C[0][2] + C[1][2] * C[1][2];
  const double q = (C[0][0] + C[1][1] + C[2][2]) / 3;
  const double d0 = C[0][0] - q, d1 = C[1][1] - q, d2 = C[2][2] - q;
  const double p2 = d0 * d0 + d1 * d1 + d2 * d2 + 2 * p1;
  if (!(p2 > 0)) { /* a multiple of the identity (or 0) */
    ev[0] = ev[1] = ev[2] = q;
    return;
  }
  const double p = sqrt(p2 / 6), ip = 1 / p;
  const double b00 = d0 * ip, b11 = d1 * ip, b22 = d2 * ip;
  const double b01 = C[0][1] * ip, b02 = C[0][2] * ip, b12 = C[1][2] * ip;
  double r = 0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) +
                    b02 * (b01 * b12 - b11 * b02));
  r = r < -1 ? -1 : r > 1 ? 1 : r;
  const double phi = acos(r) / 3;
  ev[2] = q + 2 * p * cos(phi);
  ev[0] = q + 2 * p * cos(phi + 2.0943951023931954923); /* + 2 pi / 3 */
  ev[1] = 3 * q - ev[0] - ev[2];
}

/* lambda0 / lambda2 of the covariance about the centroid; 0 if lambda2 <= 0 */
static double sums_ratio(const pca_sums *s) {
  const double w = s->m;
  double mu[3] = {s->s1[0] / w, s->s1[1] / w, s->s1[2] / w};
  double C[3][3];
  C[0][0] = s->s2[0] / w - mu[0] * mu[0];
  C[0][1] = C[1][0] = s->s2[1] / w - mu[0] * mu[1];
  C[0][2] = C[2][0] = s->s2[2] / w - mu[0] * mu[2];
  C[1][1] = s->s2[3] / w - mu[1] * mu[1];
  C[1][2] = C[2][1] = s->s2[4] / w - mu[1] * mu[2];
  C[2][2] = s->s2[5] / w - mu[2] * mu[2];
  double ev[3];
  eigvals_sym3((const double(*)[3])C, ev);
  if (!(ev[2] > 0)) return 0;
  double r = ev[0] / ev[2];
  return r > 0 ? r : 0; /* rounding can make lambda0 a hair negative */
}

/* The heights of xyz[idx[0..k-1]] about the plane through mu (relative to
 * o) of normal n into h, and sorted into srt. */
static void heights(const double *xyz, const uint32_t *idx, int k, const double *o,
                    const double *mu, const double *n, double *h, double *srt) {
  for (int m = 0; m < k; m++) {
    const double *p = &xyz[3 * (size_t)idx[m]];
    h[m] =
        n[0] * (p[0] - o[0] - mu[0]) + n[1] * (p[1] - o[1] - mu[1]) + n[2] * (p[2] - o[2] - mu[2]);
    srt[m] = h[m];
  }
  qsort(srt, (size_t)k, sizeof(double), bsurf_cmp_double);
}

int bsurf_pca_l0_trace(const double *xyz, const uint32_t *idx, int k, double *l0, double *tr,
                       double *design, double *resid, double *mu0, double *border) {
  pca_sums s;
  memset(&s, 0, sizeof s);
  const double *o = &xyz[3 * (size_t)idx[0]];
  for (int m = 0; m < k; m++)
    sums_add(&s, &xyz[3 * (size_t)idx[m]], o);
  const double w = s.m;
  double mu[3] = {s.s1[0] / w, s.s1[1] / w, s.s1[2] / w};
  double C[3][3];
  C[0][0] = s.s2[0] / w - mu[0] * mu[0];
  C[0][1] = C[1][0] = s.s2[1] / w - mu[0] * mu[1];
  C[0][2] = C[2][0] = s.s2[2] / w - mu[0] * mu[2];
  C[1][1] = s.s2[3] / w - mu[1] * mu[1];
  C[1][2] = C[2][1] = s.s2[4] / w - mu[1] * mu[2];
  C[2][2] = s.s2[5] / w - mu[2] * mu[2];
  double ev[3];
  eigvals_sym3((const double(*)[3])C, ev);
  *l0 = ev[0] > 0 ? ev[0] : 0;
  *tr = C[0][0] + C[1][1] + C[2][2];
  if (design) {
    const double l1 = ev[1] > 0 ? ev[1] : 0, l2 = ev[2] > 0 ? ev[2] : 0;
    *design = l1 + l2 > 0 ? 4 * l1 * l2 / (l1 + l2) : 0;
  }
  double n[3];
  const double c6[6] = {C[0][0], C[0][1], C[0][2], C[1][1], C[1][2], C[2][2]};
  if (border) {
    /* A border (Gumhold et al. 2001's boundary criterion, cited in the
     * thesis's 7.0): the centroid's offset from the point in the tangent
     * plane. mu is relative to the point (o = idx[0]); within a surface the
     * point is in the middle of its neighbours and the offset is the
     * scatter of a mean of k positions, variance (lambda1 + lambda2) / k
     * over the two tangential axes; at a border the neighbours lie on one
     * side and the offset is a fixed share of the radius (4 / (3 pi) of a
     * half-disc's). b = k |offset_t|^2 / (lambda1 + lambda2), calibrated
     * on the null patch like z (features_variance.c). */
    *border = 0;
    const double sp = *tr - *l0;
    if (sp > 0 && bsurf_eigen_sym3_smallest(c6, n) == 0) {
      const double a = mu[0] * n[0] + mu[1] * n[1] + mu[2] * n[2];
      const double t0 = mu[0] - a * n[0], t1 = mu[1] - a * n[1], t2 = mu[2] - a * n[2];
      *border = w * (t0 * t0 + t1 * t1 + t2 * t2) / sp;
    }
  }
  if (!resid) return 0;
  /* Two parallel sheets: a plane through both tilts towards the imbalance
   * of the two sheets' points, which mixes their heights. So: the best split
   * of the heights about the PCA plane (groups of at least k / 4) gives two
   * groups; the pair of parallel planes fitted to them (the smallest
   * eigenvalue mu0 of the covariance pooled within the groups, each about
   * its own centroid) gives the common normal; the heights about it are
   * tested for two groups apart (bsurf_split_bimodal, rounding level 1e-9
   * of the radius sqrt(tr)). */
  double *h = resid, *srt = resid + k, cut;
  if (bsurf_eigen_sym3_smallest(c6, n) != 0) return 0;
  heights(xyz, idx, k, o, mu, n, h, srt);
  if (!(bsurf_split_share(srt, k, k / 4 > 3 ? k / 4 : 3, 0, &cut) < 1)) return 0;
  pca_sums g[2];
  memset(g, 0, sizeof g);
  for (int m = 0; m < k; m++)
    sums_add(&g[h[m] > cut], &xyz[3 * (size_t)idx[m]], o);
  double p6[6] = {0, 0, 0, 0, 0, 0};
  for (int a = 0; a < 2; a++) {
    const double gm = g[a].m, *s1 = g[a].s1;
    p6[0] += g[a].s2[0] - s1[0] * s1[0] / gm;
    p6[1] += g[a].s2[1] - s1[0] * s1[1] / gm;
    p6[2] += g[a].s2[2] - s1[0] * s1[2] / gm;
    p6[3] += g[a].s2[3] - s1[1] * s1[1] / gm;
    p6[4] += g[a].s2[4] - s1[1] * s1[2] / gm;
    p6[5] += g[a].s2[5] - s1[2] * s1[2] / gm;
  }
  if (bsurf_eigen_sym3_smallest(p6, n) != 0) return 0;
  const double q = n[0] * (n[0] * p6[0] + n[1] * p6[1] + n[2] * p6[2]) +
                   n[1] * (n[0] * p6[1] + n[1] * p6[3] + n[2] * p6[4]) +
                   n[2] * (n[0] * p6[2] + n[1] * p6[4] + n[2] * p6[5]);
  heights(xyz, idx, k, o, mu, n, h, srt);
  if (!bsurf_split_bimodal(srt, k, 1e-9 * sqrt(*tr > 0 ? *tr : 0), NULL)) return 0;
  if (mu0) *mu0 = q > 0 ? q / w : 0;
  return 1;
}

void bsurf_incremental_pca_ratios(const double *xyz, const uint32_t *idx, int k, double *ratio) {
  pca_sums s;
  memset(&s, 0, sizeof s);
  const double *o = &xyz[3 * (size_t)idx[0]];
  for (int m = 0; m < k; m++) {
    sums_add(&s, &xyz[3 * (size_t)idx[m]], o);
    ratio[m] = sums_ratio(&s);
  }
}

/* ---- distance map ---- */

typedef struct dist_ctx {
  const double *xyz;
  const bsurf_neighbors *nb;
  const bsurf_feature_options *o;
  const double *T; /* T_{a/c} of each size k_min + j k_step */
  double *dist;
  int *ksel;
  uint8_t *state; /* 0 reached k_max, 1 exceeded T_{a/c} later, 2 at k_min */
} dist_ctx;

/* Row i of nb (its point is idx[0]: i in memory, a local index in a tile). */
static void dist_point(void *vctx, int thread, size_t i) {
  (void)thread;
  dist_ctx *c = vctx;
  const bsurf_feature_options *o = c->o;
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  const double *p = &c->xyz[3 * (size_t)idx[0]];
  pca_sums s;
  memset(&s, 0, sizeof s);
  double f_prev = NAN;
  int stop = -1, m = 0, exceeded = 0, j = 0;
  for (int K = o->k_min; K <= o->k_max; K += o->k_step, j++) {
    while (m < K)
      sums_add(&s, &c->xyz[3 * (size_t)idx[m++]], p);
    double f = sums_ratio(&s);
    double g = f;
    if (o->derivative != 0 && !isnan(f_prev)) g = f + o->derivative * (f - f_prev);
    f_prev = f;
    stop = K;
    if (g > c->T[j]) {
      exceeded = 1;
      break;
    }
  }
  const double *far = &c->xyz[3 * (size_t)idx[stop - 1]];
  double d[3] = {far[0] - p[0], far[1] - p[1], far[2] - p[2]};
  c->dist[i] = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  if (c->ksel) c->ksel[i] = stop;
  /* stopped at once: the k_min neighbourhood already exceeds T_{a/c} */
  c->state[i] = (uint8_t)(exceeded ? (stop == o->k_min ? 2 : 1) : 0);
}

bsurf_status bsurf_fdist_raw(const double *xyz, const bsurf_neighbors *nb,
                             const bsurf_feature_options *o, const double *T, double *dist,
                             int *ksel, uint8_t *state) {
  dist_ctx ctx = {xyz, nb, o, T, dist, ksel, state};
  return bsurf_parallel_points(nb->point_count, bsurf_threads_resolve(o->threads), dist_point, &ctx,
                               o->progress, o->progress_user);
}

/* ---- noise-adapted T_{a/c} ----
 * f(K) of every sampled point at every size: the per-size medians give the
 * flat-area level of f, which noise raises (uniform noise t h, t in
 * [-1, 1]: f(15) ~ 0.15 on a plane, above the thesis's 0.1, so that every
 * point "stops at once"). The sample is every stride-th point, at most
 * ~4M values in all; deterministic. */

typedef struct ratio_ctx {
  const double *xyz;
  const bsurf_neighbors *nb;
  const bsurf_feature_options *o;
  const uint64_t *point_index; /* NULL: row i is point i */
  size_t stride, m;
  double *vals; /* [size j][sample s] */
} ratio_ctx;

/* f(K) at every size of one row of nb, into the sample's column s. */
static void ratio_row(const ratio_ctx *c, size_t row, size_t s) {
  const bsurf_feature_options *o = c->o;
  const uint32_t *idx = &c->nb->idx[row * (size_t)c->nb->k];
  const double *p = &c->xyz[3 * (size_t)idx[0]];
  pca_sums sm;
  memset(&sm, 0, sizeof sm);
  int m = 0, j = 0;
  for (int K = o->k_min; K <= o->k_max; K += o->k_step, j++) {
    while (m < K)
      sums_add(&sm, &c->xyz[3 * (size_t)idx[m++]], p);
    c->vals[(size_t)j * c->m + s] = sums_ratio(&sm);
  }
}

/* the whole cloud: over the samples s (row s x stride) */
static void ratio_sample(void *vctx, int thread, size_t s) {
  (void)thread;
  const ratio_ctx *c = vctx;
  ratio_row(c, s * c->stride, s);
}

/* a tile: over its rows, those whose global index is a multiple of stride */
static void ratio_tile_row(void *vctx, int thread, size_t r) {
  (void)thread;
  const ratio_ctx *c = vctx;
  const uint64_t g = c->point_index[r];
  if (g % c->stride == 0) ratio_row(c, r, (size_t)(g / c->stride));
}

int bsurf_fdist_sizes(const bsurf_feature_options *o) {
  return (o->k_max - o->k_min) / o->k_step + 1;
}

void bsurf_fdist_sample(const bsurf_feature_options *o, size_t n, size_t *stride, size_t *m) {
  const size_t sizes = (size_t)bsurf_fdist_sizes(o);
  size_t cap = (size_t)4000000 / sizes;
  if (cap < 1024) cap = 1024;
  *stride = n > cap ? (n + cap - 1) / cap : 1;
  *m = (n + *stride - 1) / *stride;
}

bsurf_status bsurf_fdist_sample_ratios(const double *xyz, const bsurf_neighbors *nb,
                                       const bsurf_feature_options *o, const uint64_t *point_index,
                                       size_t stride, size_t m, double *vals) {
  ratio_ctx rc = {xyz, nb, o, point_index, stride, m, vals};
  const int threads = bsurf_threads_resolve(o->threads);
  if (!point_index) return bsurf_parallel_points(m, threads, ratio_sample, &rc, NULL, NULL);
  return bsurf_parallel_points(nb->point_count, threads, ratio_tile_row, &rc, NULL, NULL);
}

void bsurf_fdist_thresholds(const bsurf_feature_options *o, size_t m, double *vals, double *T) {
  const int sizes = bsurf_fdist_sizes(o);
  for (int j = 0; j < sizes; j++)
    T[j] = o->ratio_threshold;
  if (!(o->noise_factor > 0) || !vals || !m) return;
  for (int j = 0; j < sizes; j++) {
    double *v = &vals[(size_t)j * m];
    qsort(v, m, sizeof(double), bsurf_cmp_double);
    double med = bsurf_median_sorted(v, m);
    if (o->noise_factor * med > T[j]) T[j] = o->noise_factor * med;
  }
}

static bsurf_status ratio_thresholds(const double *xyz, const bsurf_neighbors *nb,
                                     const bsurf_feature_options *o, double *T) {
  if (!(o->noise_factor > 0)) {
    bsurf_fdist_thresholds(o, 0, NULL, T);
    return BSURF_OK;
  }
  size_t stride, m;
  bsurf_fdist_sample(o, nb->point_count, &stride, &m);
  double *vals = bsurf_alloc_array(m * (size_t)bsurf_fdist_sizes(o), sizeof(double));
  if (!vals) return BSURF_ERR_NOMEM;
  bsurf_status st = bsurf_fdist_sample_ratios(xyz, nb, o, NULL, stride, m, vals);
  if (st == BSURF_OK) bsurf_fdist_thresholds(o, m, vals, T);
  free(vals);
  return st;
}

bsurf_status bsurf_fdist_check(const bsurf_feature_options *o, int k, size_t n) {
  BSURF_REQUIRE_IN("feature options", o->k_min >= 3, "k_min = %d: must be at least 3", o->k_min);
  BSURF_REQUIRE_IN("feature options", o->k_max >= o->k_min && o->k_max <= k,
                   "k_max = %d: must be in [k_min = %d, nb->k = %d]", o->k_max, o->k_min, k);
  BSURF_REQUIRE_IN("feature options", o->k_step >= 1, "k_step = %d: must be at least 1", o->k_step);
  BSURF_REQUIRE_IN("feature options", o->ratio_threshold >= 0, "ratio_threshold = %g: must be >= 0",
                   o->ratio_threshold);
  BSURF_REQUIRE_IN("feature options", isfinite(o->derivative), "derivative = %g: must be finite",
                   o->derivative);
  BSURF_REQUIRE_IN("feature options", o->noise_factor >= 0 && isfinite(o->noise_factor),
                   "noise_factor = %g: must be finite and >= 0", o->noise_factor);
  BSURF_REQUIRE_IN("feature options", o->alpha >= 0 && o->alpha <= 1,
                   "alpha = %g: must be in [0, 1]", o->alpha);
  BSURF_REQUIRE_IN("feature options", o->iterations >= 0, "iterations = %d: must be >= 0",
                   o->iterations);
  BSURF_REQUIRE_IN("feature options", o->filter_k >= 0 && o->filter_k <= k,
                   "filter_k = %d: must be in [0, nb->k = %d]", o->filter_k, k);
  BSURF_REQUIRE_IN("feature options", o->sigma_range > 0, "sigma_range = %g: must be > 0",
                   o->sigma_range);
  if ((size_t)o->k_max > n)
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS, "k_max = %d exceeds the %zu points",
                             o->k_max, n);
  return BSURF_OK;
}

void bsurf_fdist_max_radius(const double *dist, size_t n, double *R) {
  for (size_t i = 0; i < n; i++)
    if (dist[i] > *R) *R = dist[i];
}

/* state out (may be NULL): per point 0 = reached k_max without exceeding
 * T_{a/c}, 1 = exceeded it at a larger size, 2 = at k_min */
bsurf_status bsurf_fdist_distance_raw(const double *xyz, const bsurf_neighbors *nb,
                                      const bsurf_feature_options *opts, double *dist, int *ksel,
                                      double *max_radius, size_t *immediate, double *t_kmin,
                                      uint8_t *state) {
  bsurf_feature_options o = opts ? *opts : bsurf_feature_options_default();
  BSURF_REQUIRE(xyz && dist, "xyz or dist is NULL");
  BSURF_REQUIRE(nb && nb->idx, "nb is %s: build it with bsurf_neighbors_build",
                nb ? "empty" : "NULL");
  bsurf_status st = bsurf_fdist_check(&o, nb->k, nb->point_count);
  if (st != BSURF_OK) return st;
  const size_t n = nb->point_count;
  uint8_t *imm = state ? state : bsurf_alloc_array(n, 1);
  double *T = bsurf_alloc_array((size_t)bsurf_fdist_sizes(&o), sizeof(double));
  if (!imm || !T) {
    if (!state) free(imm);
    free(T);
    return BSURF_ERR_NOMEM;
  }
  st = ratio_thresholds(xyz, nb, &o, T);
  if (t_kmin) *t_kmin = T[0];
  if (st == BSURF_OK) st = bsurf_fdist_raw(xyz, nb, &o, T, dist, ksel, imm);
  if (st == BSURF_OK) {
    double R = 0;
    size_t ni = 0;
    bsurf_fdist_max_radius(dist, n, &R);
    for (size_t i = 0; i < n; i++) {
      ni += imm[i] == 2;
      dist[i] = bsurf_fdist_fixed(dist[i], imm[i], R);
    }
    if (max_radius) *max_radius = R;
    if (immediate) *immediate = ni;
  }
  if (!state) free(imm);
  free(T);
  return st;
}

bsurf_status bsurf_feature_distance_raw(const double *xyz, const bsurf_neighbors *nb,
                                        const bsurf_feature_options *opts, double *dist, int *ksel,
                                        double *max_radius, size_t *immediate) {
  return bsurf_fdist_distance_raw(xyz, nb, opts, dist, ksel, max_radius, immediate, NULL, NULL);
}

/* ---- the bilateral filter of Eq. 7.1 ---- */

typedef struct filter_ctx {
  const double *xyz;
  const bsurf_neighbors *nb;
  int k;
  double alpha, inv2a, inv2b;
  const double *in;
  double *out;
} filter_ctx;

/* Row j of nb (its point idx[0]; in memory j itself): out[j] from the
 * values `in` of the points of xyz. */
static void filter_point(void *vctx, int thread, size_t j) {
  (void)thread;
  filter_ctx *c = vctx;
  const uint32_t *idx = &c->nb->idx[j * (size_t)c->nb->k];
  const double *pj = &c->xyz[3 * (size_t)idx[0]];
  const double hj = c->in[idx[0]];
  double num = 0, den = 0;
  for (int t = 0; t < c->k; t++) {
    size_t i = idx[t];
    const double *q = &c->xyz[3 * i];
    double dx = pj[0] - q[0], dy = pj[1] - q[1], dz = pj[2] - q[2];
    double dh = hj - c->in[i];
    double w = exp(-(dx * dx + dy * dy + dz * dz) * c->inv2a - dh * dh * c->inv2b);
    num += w * c->in[i];
    den += w;
  }
  c->out[j] = den > 0 ? (1 - c->alpha) * hj + c->alpha * num / den : hj;
}

int bsurf_fdist_filter_k(const bsurf_feature_options *o) {
  return o->filter_k ? o->filter_k : o->k_min;
}

int bsurf_fdist_filter_passes(const bsurf_feature_options *o, double R) {
  return o->iterations > 0 && o->alpha > 0 && R > 0 ? o->iterations : 0;
}

bsurf_status bsurf_fdist_filter(const double *xyz, const bsurf_neighbors *nb,
                                const bsurf_feature_options *o, double h, double R,
                                const double *in, double *out) {
  const double sa = h > 0 ? h : R, sb = o->sigma_range * R;
  filter_ctx fc = {xyz, nb, bsurf_fdist_filter_k(o), o->alpha, 1 / (2 * sa * sa), 1 / (2 * sb * sb),
                   in,  out};
  return bsurf_parallel_points(nb->point_count, bsurf_threads_resolve(o->threads), filter_point,
                               &fc, NULL, NULL);
}

/* The distance method's automatic T_h: Otsu's split of the map's positive
 * values (the points <= 0 are features whatever it is); 0 when fewer than
 * two are positive. Only points that exceeded T_{a/c} somewhere (state > 0)
 * are features below it (see bsurf_detect_features). */
double bsurf_fdist_otsu_positive(double *pos, size_t m) {
  if (m < 2) return 0;
  qsort(pos, m, sizeof(double), bsurf_cmp_double);
  return bsurf_otsu_sorted(pos, m);
}

bsurf_status bsurf_fdist_auto_threshold(const double *map, size_t n, double *t) {
  double *v = bsurf_alloc_array(n ? n : 1, sizeof(double));
  if (!v) return BSURF_ERR_NOMEM;
  size_t m = 0;
  for (size_t i = 0; i < n; i++)
    if (map[i] > 0) v[m++] = map[i];
  *t = bsurf_fdist_otsu_positive(v, m);
  free(v);
  return BSURF_OK;
}

/* feature = feature_dist <= T_h; auto (threshold NAN): a point whose
 * neighbourhoods never exceeded T_{a/c} (state 0) has seen no feature up to
 * k_max, whatever its radius (on a featureless surface the split would
 * otherwise cut the density variations of the k_max radii) */
int bsurf_fdist_feature(double v, int state, double thr, double threshold) {
  return v <= thr && (v <= 0 || !isnan(threshold) || state != 0);
}
