/* Variance features (thesis 7.2, Eq. 7.2) with an automatic threshold from
 * a null distribution (issue 22; docs/features.md has the equations and
 * the measurements).
 *
 * The thesis thresholds nu_i (the bootstrap variance of the normal, Eq.
 * 5.5) at a t_h chosen by eye from the histogram "at the start of the
 * tail", and notes that noise raises nu everywhere. Here the threshold is
 * the answer to a test: is nu_i larger than a flat patch with the cloud's
 * noise would give?
 *
 * 1. Scale. For a plane fitted by PCA to K points with noise sigma along
 *    the normal, the tilt about each tangential axis a has variance about
 *    sigma^2 / (K lambda_a) (the slope of a least-squares line; lambda1,
 *    lambda2 the tangential eigenvalues of the neighbourhood's covariance),
 *    so nu_i = sigma^2 (1 / lambda1 + 1 / lambda2) / K = 4 sigma^2 /
 *    (K d_i) with the design d_i = 4 / (1 / lambda1 + 1 / lambda2) (the
 *    trace less lambda0 when the neighbourhood is a disc; much smaller when
 *    its points lie nearly on a line, e.g. a coarse mesh's vertices on a
 *    ring, whose normal turns freely about that line without a feature).
 *    So nu_i d_i K / sigma^2 does not depend on the density (anisotropic
 *    sampling), on the shape of the sampled patch or on the units. The noise is
 *    measured on the cloud itself: s^2 = median_i lambda0_i, the median of
 *    the smallest covariance eigenvalue (features are a minority; on a
 *    flat area lambda0 is the variance of the noise along the normal). The
 *    score is
 *        Z_i = nu_i d_i / s^2.
 *    Two parallel sheets (a thin part: the heights about a pair of
 *    parallel planes split in two groups apart, bsurf_pca_l0_trace, with
 *    the pair's residual variance within the noise's 99% quantile) are
 *    flat, however far apart: Z_i = 0. Their gap, not a feature, raised
 *    nu_i (an edge's two planes are at an angle, and its heights do not
 *    split so: simulated, <= 2% of 90 degree edge neighbourhoods).
 * 2. Filter. nu_i comes from B resamples and one noise draw, so it scatters
 *    even on a plane; features are spatially coherent bands. The score is
 *    the median of Z over the first k_f neighbours (k_f = K / 2: a median
 *    keeps the band's edge where a mean would blur it),
 *        z_i = median_{j in N_kf(i)} Z_j.
 * 3. Null. A flat square patch of unit density (uniform random points,
 *    side L) with gaussian noise sigma_0 along its normal, where sigma_0 is
 *    set so that the patch's median lambda0 / tr equals the cloud's eta =
 *    median_i lambda0_i / tr_i (the noise relative to the neighbourhood
 *    size, the one number the distribution of z depends on besides K, B and
 *    k_f). The patch goes through the same bootstrap normals (same K, B,
 *    fit, seed), the same Z and the same filter; t = the (1 - alpha)
 *    quantile of z over the points whose neighbourhoods lie inside the
 *    patch (alpha = false_positive_rate).
 * 4. Split. The test says which points are not flat; near an edge that is
 *    every point whose neighbourhood reaches across it, a band about the
 *    neighbourhood's radius wide, while z keeps rising towards the edge. When
 *    z is bimodal (a flat bulk and a feature mode) Otsu's split of log z
 *    (bsurf_tail_threshold, BSURF_TAIL_OTSU) separates the modes; it always
 *    finds "a tail", even on a featureless shape, which the test prevents:
 *        t = max(t_alpha, t_Otsu).
 * 5. Features: F = {i | z_i > t} (Eq. 7.2 with z for nu): a flat area of
 *    the cloud's noise is flagged at rate alpha at most.
 * 6. Neighbourhood (feature_angle > 0, bsurf_fvar_choose_k): when the noise
 *    is comparable to the K-neighbourhood's radius the flat patch's own nu
 *    covers what an edge's reaches and the test has no power. sigma_0 (the
 *    noise in spacings) is found once from eta at normals.k; K doubles from
 *    normals.k until a folded patch (faces' normals feature_angle apart,
 *    noise sigma_0) is detected at >= half its points within a spacing of
 *    the fold, at t_alpha of its own flat parts.
 * 7. The quadric check (quadric_angle > 0, bsurf_fvar_quadric_k): a smooth
 *    bend tighter than the cloud's curvature model (one slope, step 1)
 *    raises nu as an edge does; a quadric explains the bend but not a
 *    crease. q_i = the median over the first k_f neighbours of the residual
 *    variance of the quadric of each one's K_q nearest (kselect_noise.c's
 *    fit), over the cloud's noise variance as the K selection reads it
 *    (bsurf_ksel_cloud_noise: a reading of the noise that is not the flat
 *    majority's lambda0, so it holds where most points are near a crease).
 *    A point z flags stays a feature only where q_i > t_q, the (1 - alpha)
 *    quantile of q on the flat patch (over its noise variance) whose noise is
 *    sigma_0 times sigma^ / s (the noise the check reads, not the median
 *    lambda0's, which a curved cloud's curvature lifts). K_q is
 *    the first of K, 2 K, 4 K (<= k_cap) at which a patch folded by
 *    quadric_angle keeps >= 9 in 10 of its points within a spacing of the
 *    fold: the check may cost a crease that steep a tenth of its band at
 *    most. Where no K_q reaches that (heavy noise), no check.
 * Without noise (s^2 = 0: most neighbourhoods exactly flat) the null is
 * the point mass nu = 0: Z = nu d, and t = 1e-12 max z (rounding).
 *
 * What it does not do: near an edge every point whose neighbourhood
 * reaches across it is "not flat", so the detected band is about the
 * neighbourhood's radius wide whatever the threshold; and when the noise is
 * comparable to the neighbourhood's radius (eta above ~0.1) at a fixed K
 * the features' nu is inside the null's spread and few points pass: step 6
 * grows K then (docs/features.md). */
#include "algo/algo.h"
#include "algo/smooth_stages.h"
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846
#define QT_TERMS 6 /* the quadric's terms (its residual variance needs more points) */

enum {
  NULL_INTERIOR = 20000,   /* points of the patch whose statistics count */
  FOLD_INTERIOR = 8000,    /* the same for the folded patches of the K choice and the quadric check:
                              about 200 points within a spacing of its edge,
                              the power to +-0.035 */
  NULL_STREAM = 0x6e756c6c /* "null": the patch's random streams */
};

int bsurf_fvar_filter_k(const bsurf_feature_options *o) {
  if (o->variance_filter_k > 0) return o->variance_filter_k;
  return o->normals.k / 2 > 1 ? o->normals.k / 2 : 1;
}

int bsurf_fvar_k_cap(const bsurf_feature_options *o, size_t n) {
  long cap = o->variance_k_max > 0 ? o->variance_k_max : 8L * o->normals.k;
  if (cap > 65535) cap = 65535;
  if ((size_t)cap > n) cap = (long)n;
  return cap < o->normals.k ? o->normals.k : (int)cap;
}

/* ---- per row: u = nu d (the design), lambda0, lambda0 / tr, w ---- */

typedef struct local_ctx {
  const double *xyz;
  const bsurf_neighbors *nb;
  int k;
  const double *nu; /* by row */
  double *u, *l0, *ratio, *w, *b, *g;
  double *scratch; /* threads x 2 k, with w */
} local_ctx;

static void local_row(void *vctx, int thread, size_t r) {
  const local_ctx *c = vctx;
  double l0, tr, design, mu0 = 0, border = 0;
  const int two = bsurf_pca_l0_trace(
      c->xyz, &c->nb->idx[r * (size_t)c->nb->k], c->k, &l0, &tr, &design,
      c->w ? &c->scratch[2 * (size_t)thread * (size_t)c->k] : NULL, &mu0, c->b ? &border : NULL);
  c->u[r] = c->nu[r] * design;
  if (c->b) c->b[r] = border;
  c->l0[r] = l0;
  c->ratio[r] = tr > 0 ? l0 / tr : 0;
  if (c->g) c->g[r] = (tr - l0) * (tr - l0);
  if (c->w) c->w[r] = two ? mu0 : -1;
}

bsurf_status bsurf_fvar_local(const double *xyz, const bsurf_neighbors *nb, int k, int threads,
                              const double *nu, double *u, double *l0, double *ratio, double *w,
                              double *b, double *g) {
  const int t = bsurf_threads_resolve(threads);
  local_ctx c = {xyz, nb, k, nu, u, l0, ratio, w, b, g, NULL};
  if (w && !(c.scratch = bsurf_alloc_array(2 * (size_t)t * (size_t)k, sizeof(double))))
    return BSURF_ERR_NOMEM;
  bsurf_status st = bsurf_parallel_points(nb->point_count, t, local_row, &c, NULL, NULL);
  free(c.scratch);
  return st;
}

/* ---- the null's scale: the expected lambda0 of a smooth patch ----
 * The thesis (7.2.1): "a high variance is caused either by noise or the
 * presence of a feature. Assuming that the noise level is uniform, a high
 * value of variance will signify the feature area". s^2 = median lambda0 is
 * that uniform level, the noise where the cloud is flat. On a curved
 * smooth patch the plane fit's residual also holds the patch's departure
 * from its tangent plane: for h = (k1 x^2 + k2 y^2) / 2 sampled uniformly
 * on a disc of radius r (E x^2 = r^2 / 4, E x^4 = r^4 / 8, E x^2 y^2 =
 * r^4 / 24) Var h = r^4 (k1^2 + k2^2 - 2 k1 k2 / 3) / 64, and with the
 * tangential eigenvalues lambda1 = lambda2 = r^2 / 4
 *     E[lambda0] = sigma^2 + c g,   g = (lambda1 + lambda2)^2,
 *     c = (k1^2 + k2^2 - 2 k1 k2 / 3) / 16
 * (a sphere: k^2 / 12, a cylinder: k^2 / 16; the curvature and noise terms
 * of the normal's error, Mitra, Nguyen and Guibas 2004). The bootstrap
 * resamples these residuals as it does the noise, so nu grows with them:
 * where the sampling is sparse (large r, g ~ r^4) a curved smooth area
 * has a larger nu d than the median s^2 explains, and was read as an
 * edge (the anisotropic torus: 24.7% flagged at u0.25). The model is fitted
 * to the cloud, robustly: the medians m_b of lambda0 in equal-count bins of
 * g (features, a minority, do not move a median), Theil-Sen's slope (the
 * median of the pairwise slopes of the bins, Sen 1968) where its one-sided
 * 99% confidence bound (Sen's, from Kendall's S) is above 0, else 0; the
 * intercept the median of m_b - c g_b clipped at 0. c = 0 (lambda0 does
 * not grow with the neighbourhood's spread: flat parts, or a uniform
 * density) leaves s^2 as it was. E(g) is not extrapolated below the
 * lowest bin's median g_0 (a smaller E would raise Z); above the highest
 * it is (a larger E only makes the test more conservative there). The
 * bootstrap resamples the curvature's residuals as it does the noise, but
 * they are not independent of the position: for the tilt of a least-squares
 * plane the sandwich variance E[x^2 e^2] / (K E[x^2]^2) replaces sigma^2 /
 * (K E[x^2]); with e the residual of h above, on a disc it is the noise's
 * for a sphere (k1 = k2), 4/3 of it for a cylinder (k2 = 0; averaged over
 * the two tilts: 2 across the axis, 2/3 along it) and 3/2 for a saddle (k2 =
 * -k1), rising monotonically from the sphere to the saddle (numerically,
 * k2 / k1 in [-1, 1]: 1.500 1.474 1.333 1.091 1.000 at -1, -1/2, 0, 1/2, 1).
 * nu d is compared with
 *     V(g) = sigma2 + gamma c g,   gamma = 3/2
 * (the saddle's, the largest: a curved area is never under-normalised),
 * Z_i = nu_i d_i / V(g_i): bsurf_fvar_fit_scale multiplies u by s^2 / V(g)
 * for the filter's division by s^2. */
enum { FIT_BIN_MIN = 64 }; /* points per bin at least (its median's scatter) */
#define FIT_GAMMA 1.5      /* the sandwich factor's largest (a saddle) */

static int fit_bin(const bsurf_fvar_fit *f, double g) {
  int b = 0;
  while (b < f->bins - 1 && g > f->edge[b])
    b++;
  return b;
}

void bsurf_fvar_fit_prepare(bsurf_fvar_fit *f, double *g, size_t n) {
  memset(f, 0, sizeof *f);
  size_t bins = n / FIT_BIN_MIN;
  f->bins = bins >= FVAR_FIT_BINS ? FVAR_FIT_BINS : bins >= 2 ? (int)bins : 1;
  qsort(g, n, sizeof(double), bsurf_cmp_double);
  for (int b = 0; b < f->bins - 1; b++)
    f->edge[b] = g[(size_t)(b + 1) * n / (size_t)f->bins - 1];
  /* the members of bin b are a run of the sorted g (ties go to the lower) */
  size_t i = 0;
  for (int b = 0; b < f->bins; b++) {
    f->first[b] = f->fill[b] = i;
    while (i < n && fit_bin(f, g[i]) == b)
      i++;
    f->g[b] = bsurf_median_sorted(g + f->first[b], i - f->first[b]);
  }
  f->first[f->bins] = n;
}

void bsurf_fvar_fit_put(bsurf_fvar_fit *f, double *dst, double g, double l0) {
  dst[f->fill[fit_bin(f, g)]++] = l0;
}

void bsurf_fvar_fit_solve(bsurf_fvar_fit *f, double *dst, double s2) {
  double m[FVAR_FIT_BINS], sl[FVAR_FIT_BINS * FVAR_FIT_BINS], r[FVAR_FIT_BINS];
  int nb = 0, ns = 0;
  f->sigma2 = s2;
  f->c = 0;
  for (int b = 0; b < f->bins; b++) {
    const size_t cnt = f->first[b + 1] - f->first[b];
    if (!cnt) continue;
    m[nb] = bsurf_median(dst + f->first[b], cnt);
    f->g[nb++] = f->g[b];
  }
  for (int a = 0; a < nb; a++)
    for (int b = a + 1; b < nb; b++)
      if (f->g[b] > f->g[a]) sl[ns++] = (m[b] - m[a]) / (f->g[b] - f->g[a]);
  if (!ns) return;
  const double c = bsurf_median(sl, (size_t)ns); /* sorts sl */
  /* growth with g at all? Sen's one-sided 99% confidence bound on the
   * slope (Kendall's S: variance nb (nb - 1) (2 nb + 5) / 18) must be
   * above 0; else no growth: the median, as before */
  const double cs = 2.3263478740408408 * sqrt(nb * (nb - 1.0) * (2 * nb + 5.0) / 18);
  const double lo = floor((ns - cs) / 2);
  if (!(c > 0) || !(sl[lo > 0 ? (size_t)lo : 0] > 0)) return;
  for (int b = 0; b < nb; b++)
    r[b] = m[b] - c * f->g[b];
  const double s = bsurf_median(r, (size_t)nb);
  f->c = c;
  f->sigma2 = s > 0 ? s : 0;
  f->bins = nb;
}

static double fit_expected(const bsurf_fvar_fit *f, double g) {
  if (!(f->c > 0)) return f->sigma2;
  const double lo = f->g[0];
  return f->sigma2 + FIT_GAMMA * f->c * (g < lo ? lo : g);
}

void bsurf_fvar_fit_scale(const bsurf_fvar_fit *f, double s2, size_t n, const double *g, double *u,
                          double *w) {
  if (!(f->c > 0) || !(s2 > 0)) return;
  for (size_t i = 0; i < n; i++) {
    const double e = fit_expected(f, g[i]);
    if (!(e > 0)) continue;
    u[i] *= s2 / e;
    if (w && w[i] >= 0) w[i] *= s2 / e;
  }
}

/* ---- the median filter ---- */

typedef struct filter_ctx {
  const bsurf_neighbors *nb;
  int kf;
  double flat, inv_s2;
  const double *u; /* by point */
  const double *w; /* by point, may be NULL */
  double *z;       /* by row */
  double *scratch; /* threads x kf */
} filter_ctx;

/* u of point j as the filter takes it: 0 where its neighbourhood is two
 * parallel flat sheets (bsurf_fvar_filter) */
static double filter_value(const filter_ctx *c, uint32_t j) {
  return c->w && c->w[j] >= 0 && c->w[j] <= c->flat ? 0 : c->u[j];
}

/* the standard normal's 99% quantile: the flat test's chi^2 level */
#define FLAT_Z 2.3263478740408408

static void filter_row(void *vctx, int thread, size_t r) {
  const filter_ctx *c = vctx;
  const uint32_t *idx = &c->nb->idx[r * (size_t)c->nb->k];
  double *w = &c->scratch[(size_t)thread * (size_t)c->kf];
  for (int j = 0; j < c->kf; j++)
    w[j] = filter_value(c, idx[j]);
  c->z[r] = bsurf_median(w, (size_t)c->kf) * c->inv_s2;
}

bsurf_status bsurf_fvar_filter(const bsurf_neighbors *nb, int kf, int threads, double s2, int k,
                               const double *u, const double *w, double *z) {
  const int t = bsurf_threads_resolve(threads);
  /* two parallel flat sheets: the pair's residual variance mu0 (k points,
   * 4 parameters: two offsets and the normal's two angles) within the 99%
   * quantile of the noise's, s^2 (lambda0 of one sheet: 3 parameters) */
  const double flat =
      k > 4 && s2 > 0 ? s2 * bsurf_chi2_ratio_wh(k - 4, FLAT_Z) * (k - 4) / (k - 3) : -1;
  filter_ctx c = {nb, kf, flat, s2 > 0 ? 1 / s2 : 1, u, w, z, NULL};
  c.scratch = bsurf_alloc_array((size_t)t * (size_t)kf, sizeof(double));
  if (!c.scratch) return BSURF_ERR_NOMEM;
  bsurf_status st = bsurf_parallel_points(nb->point_count, t, filter_row, &c, NULL, NULL);
  free(c.scratch);
  return st;
}

/* ---- the simulated patches ----
 * A square of side L in plane coordinates (u, v), unit density, uniform
 * random positions; folded (fold > 0) along u = L / 2 so that the normals of
 * its two halves differ by the angle fold: the half u > L / 2 is turned
 * about that line. Every point gets sigma g along its half's normal, g a
 * unit gaussian draw. */

typedef struct null_patch {
  size_t n;
  double side, margin, fold;
  double *uv, *xyz, *g;
  bsurf_neighbors nb;
  double *nu, *u, *l0, *ratio, *w, *z, *b, *zb;
} null_patch;

static void patch_free(null_patch *p) {
  bsurf_neighbors_free(&p->nb);
  free(p->uv);
  free(p->xyz);
  free(p->g);
  free(p->nu);
  free(p->u);
  free(p->l0);
  free(p->ratio);
  free(p->w);
  free(p->z);
  free(p->b);
  free(p->zb);
}

static void patch_place(null_patch *p, double sigma) {
  const double c = cos(p->fold), s = sin(p->fold), h = p->side / 2;
  for (size_t i = 0; i < p->n; i++) {
    const double u = p->uv[2 * i], e = sigma * p->g[i];
    double *q = &p->xyz[3 * i];
    q[1] = p->uv[2 * i + 1];
    if (p->fold > 0 && u > h) {
      q[0] = h + (u - h) * c - e * s; /* (u - h) (c, s) + e (-s, c) */
      q[2] = (u - h) * s + e * c;
    } else {
      q[0] = u;
      q[2] = e;
    }
  }
}

/* 1: point i's neighbourhood and its filter's neighbours' lie inside the
 * patch; with a fold, where = 1 asks for the flat parts (farther than the
 * margin from the fold line), where = 2 for the edge (within one spacing) */
static int patch_in(const null_patch *p, size_t i, int where) {
  const double u = p->uv[2 * i], v = p->uv[2 * i + 1], m = p->margin, d = fabs(u - p->side / 2);
  if (!(u > m && u < p->side - m && v > m && v < p->side - m)) return 0;
  if (p->fold > 0 && where == 1) return d > m;
  if (where == 2) return d <= 1;
  return 1;
}

/* the patch for neighbourhoods of k and a filter of kf: every array, the
 * positions without noise and the neighbourhoods, built once on the clean
 * surface so that they stay the same while sigma changes */
static bsurf_status patch_init(null_patch *p, const bsurf_feature_options *o, int k, int kf,
                               double fold) {
  memset(p, 0, sizeof *p);
  /* unit density: a K-neighbourhood has radius sqrt(K / pi) */
  p->margin = sqrt(k / PI) + sqrt(kf / PI) + 1;
  p->side = fold > 0 ? ceil(sqrt((double)FOLD_INTERIOR) + 4 * p->margin)
                     : ceil(sqrt((double)NULL_INTERIOR) + 2 * p->margin);
  p->fold = fold;
  p->n = (size_t)(p->side * p->side);
  p->uv = bsurf_alloc_array(2 * p->n, sizeof(double));
  p->xyz = bsurf_alloc_array(3 * p->n, sizeof(double));
  p->g = bsurf_alloc_array(p->n, sizeof(double));
  p->nu = bsurf_calloc_array(p->n, sizeof(double));
  p->u = bsurf_alloc_array(p->n, sizeof(double));
  p->l0 = bsurf_alloc_array(p->n, sizeof(double));
  p->ratio = bsurf_alloc_array(p->n, sizeof(double));
  p->w = bsurf_alloc_array(p->n, sizeof(double));
  p->z = bsurf_alloc_array(p->n, sizeof(double));
  p->b = bsurf_alloc_array(p->n, sizeof(double));
  p->zb = bsurf_alloc_array(p->n, sizeof(double));
  if (!p->uv || !p->xyz || !p->g || !p->nu || !p->u || !p->l0 || !p->ratio || !p->w || !p->z ||
      !p->b || !p->zb)
    return BSURF_ERR_NOMEM;
  for (size_t i = 0; i < p->n; i++) {
    bsurf_rng rng;
    bsurf_rng_init(&rng, o->normals.seed, i, NULL_STREAM);
    p->uv[2 * i] = p->side * bsurf_rng_uniform(&rng);
    p->uv[2 * i + 1] = p->side * bsurf_rng_uniform(&rng);
    p->g[i] = bsurf_rng_normal(&rng);
  }
  patch_place(p, 0);
  return bsurf_neighbors_build(&p->nb, p->xyz, p->n, k > kf ? k : kf, o->threads, NULL, NULL);
}

/* the median of lambda0 / tr over the patch's interior at noise sigma */
static bsurf_status patch_eta(null_patch *p, int k, int threads, double sigma, double *eta) {
  patch_place(p, sigma);
  bsurf_status st =
      bsurf_fvar_local(p->xyz, &p->nb, k, threads, p->nu, p->u, p->l0, p->ratio, NULL, NULL, NULL);
  if (st != BSURF_OK) return st;
  size_t m = 0;
  for (size_t i = 0; i < p->n; i++)
    if (patch_in(p, i, 1)) p->u[m++] = p->ratio[i];
  *eta = bsurf_median(p->u, m);
  return BSURF_OK;
}

/* z of every point at noise sigma: the bootstrap normals with the options'
 * B, fit and seed at k, Z = nu d / s^2 with s^2 the median lambda0 of the
 * flat part, filtered over kf; the border score zb (b filtered over kf)
 * when border is set */
static bsurf_status patch_scores(null_patch *p, const bsurf_feature_options *o, int k, int kf,
                                 double sigma, int border) {
  patch_place(p, sigma);
  bsurf_normal_options no = o->normals;
  no.k = k;
  no.threads = o->threads;
  no.progress = NULL;
  no.progress_user = NULL;
  no.point_index = NULL;
  bsurf_normal_fields nf = {NULL, p->nu, NULL};
  bsurf_status st = bsurf_estimate_normals(p->xyz, &p->nb, NULL, &no, &nf, NULL);
  if (st == BSURF_OK)
    st = bsurf_fvar_local(p->xyz, &p->nb, k, o->threads, p->nu, p->u, p->l0, p->ratio, p->w,
                          border ? p->b : NULL, NULL);
  if (st == BSURF_OK && border)
    st = bsurf_fvar_filter(&p->nb, kf, o->threads, 0, k, p->b, NULL, p->zb);
  if (st != BSURF_OK) return st;
  size_t m = 0;
  for (size_t i = 0; i < p->n; i++)
    if (!p->fold || patch_in(p, i, 1)) p->z[m++] = p->l0[i];
  const double s2 = bsurf_median(p->z, m);
  return bsurf_fvar_filter(&p->nb, kf, o->threads, s2, k, p->u, p->w, p->z);
}

/* the (1 - alpha) quantile of z (of v) over the points where
 * patch_in(where): the smallest value that at most alpha m of the m values
 * exceed */
static double patch_quantile(null_patch *p, const double *v, int where, double alpha) {
  size_t m = 0;
  for (size_t i = 0; i < p->n; i++)
    if (patch_in(p, i, where)) p->l0[m++] = v[i];
  if (!m) return 0;
  qsort(p->l0, m, sizeof(double), bsurf_cmp_double);
  size_t r = (size_t)ceil((1 - alpha) * (double)m);
  return p->l0[r > 0 ? (r <= m ? r - 1 : m - 1) : 0];
}

/* A folded patch's power: the share of its points within a spacing of the
 * fold whose score p->z exceeds t, the (1 - alpha) quantile of p->z over its
 * flat parts (t out may be NULL) */
static double patch_power(null_patch *p, double alpha, double *t_out) {
  const double t = patch_quantile(p, p->z, 1, alpha);
  size_t m = 0, hit = 0;
  for (size_t i = 0; i < p->n; i++)
    if (patch_in(p, i, 2)) {
      m++;
      hit += p->z[i] > t;
    }
  if (t_out) *t_out = t;
  return m ? (double)hit / (double)m : 0;
}

/* sigma_0 of the flat patch p (built for k) whose median lambda0 / tr is
 * eta: lambda0 ~ sigma^2 and tr ~ K / (2 pi) on a unit-density disc, then
 * secant steps on eta(sigma) ~ sigma^2 */
static bsurf_status patch_sigma(null_patch *p, int k, int threads, double eta, double *sigma) {
  double s = sqrt(eta * k / (2 * PI));
  bsurf_status st = BSURF_OK;
  for (int it = 0; st == BSURF_OK && it < 4 && s > 0; it++) {
    double e;
    st = patch_eta(p, k, threads, s, &e);
    if (st == BSURF_OK && e > 0) s *= sqrt(eta / e);
  }
  *sigma = s;
  return st;
}

bsurf_status bsurf_fvar_null_threshold(const bsurf_feature_options *o, double eta, double *t,
                                       double *tb, double *sigma0) {
  const int k = o->normals.k, kf = bsurf_fvar_filter_k(o);
  null_patch p;
  double sigma = 0;
  bsurf_status st = patch_init(&p, o, k, kf, 0);
  if (st == BSURF_OK && eta > 0) st = patch_sigma(&p, k, o->threads, eta, &sigma);
  if (st == BSURF_OK) st = patch_scores(&p, o, k, kf, sigma, tb != NULL);
  if (st == BSURF_OK) {
    const double a = o->false_positive_rate;
    *t = patch_quantile(&p, p.z, 0, a);
    if (tb) *tb = patch_quantile(&p, p.zb, 0, a);
    if (sigma0) *sigma0 = sigma;
  }
  patch_free(&p);
  return st;
}

/* ---- the neighbourhood: the test's power on a simulated edge ----
 * The test needs the flat area's normal to be steadier than an edge's: when
 * the noise is comparable to the neighbourhood's radius (eta large) the
 * flat patch's own nu fills the range an edge's reaches, and nothing passes.
 * The noise relative to the spacing, sigma_0 (unit density), is a property
 * of the cloud: it is found once, from eta at normals.k; then K = normals.k,
 * 2 normals.k, 4 normals.k ... <= k_cap, the first at which a simulated edge
 * whose faces' normals differ by feature_angle, at noise sigma_0, is
 * detected at more than half of its points within one spacing of the edge
 * (the test's power >= 1/2 at level alpha, t_alpha from the same patch's
 * flat parts). If none reaches it, the K of the largest power. */
bsurf_status bsurf_fvar_choose_k(const bsurf_feature_options *o, double eta, int k_cap, int *k,
                                 double *power) {
  const int k0 = o->normals.k;
  *k = k0;
  if (power) *power = NAN;
  if (!(o->feature_angle > 0) || !(eta > 0) || k_cap <= k0) return BSURF_OK;
  null_patch p;
  double sigma = 0, best = -1;
  bsurf_status st = BSURF_OK;
  int done = 0;
  for (int kk = k0; st == BSURF_OK && !done && kk <= k_cap; kk *= 2) {
    bsurf_feature_options ok = *o;
    ok.normals.k = kk;
    const int kf = bsurf_fvar_filter_k(&ok);
    st = patch_init(&p, o, kk, kf, o->feature_angle * PI / 180);
    /* sigma_0 from the first patch's flat parts at normals.k */
    if (st == BSURF_OK && kk == k0) st = patch_sigma(&p, k0, o->threads, eta, &sigma);
    if (st == BSURF_OK) st = patch_scores(&p, o, kk, kf, sigma, 0);
    if (st == BSURF_OK) {
      const double pw = patch_power(&p, o->false_positive_rate, NULL);
      if (pw > best) {
        best = pw;
        *k = kk;
        if (power) *power = pw;
      }
      done = pw >= 0.5;
    }
    patch_free(&p);
  }
  return st;
}

/* ---- the quadric check (step 7) ---- */

/* the share of a quadric_angle crease's points within a spacing of it that
 * the check must keep */
#define QUAD_KEEP 0.9

typedef struct qrss_ctx {
  const double *xyz;
  const bsurf_neighbors *nb;
  int kq;
  double *v;
  double *work; /* threads x 3 kq */
} qrss_ctx;

static void qrss_row(void *vctx, int thread, size_t r) {
  const qrss_ctx *c = vctx;
  double var;
  c->v[r] = bsurf_ksel_quad_variance(c->xyz, &c->nb->idx[r * (size_t)c->nb->k], c->kq,
                                     &c->work[3 * (size_t)thread * (size_t)c->kq], &var) == 0
                ? var
                : HUGE_VAL;
}

bsurf_status bsurf_fvar_quadric_rss(const double *xyz, const bsurf_neighbors *nb, int kq,
                                    int threads, double *v, bsurf_progress_fn progress,
                                    void *progress_user) {
  const int t = bsurf_threads_resolve(threads);
  qrss_ctx c = {xyz, nb, kq, v, bsurf_alloc_array(3 * (size_t)t * (size_t)kq, sizeof(double))};
  if (!c.work) return BSURF_ERR_NOMEM;
  bsurf_status st =
      bsurf_parallel_points(nb->point_count, t, qrss_row, &c, progress, progress_user);
  free(c.work);
  return st;
}

int bsurf_fvar_neighbors_k(const bsurf_feature_options *o, int k_cap) {
  const int k = o->normals.k;
  if (!(o->quadric_angle > 0) || o->method != BSURF_FEATURES_VARIANCE ||
      o->tail_rule != BSURF_TAIL_NULL || !isnan(o->threshold))
    return k;
  int m = 4 * k < k_cap ? 4 * k : k_cap;
  if (m < BSURF_SMOOTH_SELECT_K) m = BSURF_SMOOTH_SELECT_K;
  return m > k ? m : k;
}

bsurf_status bsurf_fvar_quadric_k(const bsurf_feature_options *o, double sigma, int k_cap, int *kq,
                                  double *tq, double *power) {
  const int k0 = o->normals.k, kf = bsurf_fvar_filter_k(o);
  *kq = 0;
  *tq = NAN;
  *power = NAN;
  if (!(o->quadric_angle > 0) || !(sigma > 0)) return BSURF_OK;
  null_patch p;
  bsurf_status st = BSURF_OK;
  const int top = 4 * k0 < k_cap ? 4 * k0 : k_cap;
  for (int kk = k0; st == BSURF_OK && kk <= top; kk *= 2) {
    if (kk <= QT_TERMS) continue; /* too few points for a quadric's residual */
    st = patch_init(&p, o, kk, kf, o->quadric_angle * PI / 180);
    if (st == BSURF_OK) {
      patch_place(&p, sigma);
      st = bsurf_fvar_quadric_rss(p.xyz, &p.nb, kk, o->threads, p.u, NULL, NULL);
    }
    if (st == BSURF_OK)
      st = bsurf_fvar_filter(&p.nb, kf, o->threads, sigma * sigma, kk, p.u, NULL, p.z);
    if (st == BSURF_OK) {
      double t;
      *power = patch_power(&p, o->false_positive_rate, &t);
      if (*power >= QUAD_KEEP) {
        *kq = kk;
        *tq = t;
        patch_free(&p);
        break;
      }
    }
    patch_free(&p);
  }
  return st;
}

/* The check on the cloud (in memory): res's quadric fields; q by point
 * (filtered, over the noise variance) when it runs. rss: n doubles of
 * scratch. res: bsurf_fvar_null's (sigma0). */
static bsurf_status quadric_check(const double *xyz, const bsurf_neighbors *nb,
                                  const bsurf_feature_options *o, double s2, double *rss, double *q,
                                  bsurf_fvar_result *res) {
  const size_t n = nb->point_count;
  if (!(o->quadric_angle > 0) || !(s2 > 0) || nb->k < BSURF_SMOOTH_SELECT_K ||
      n <= BSURF_SMOOTH_SELECT_K)
    return BSURF_OK;
  int cap = bsurf_fvar_k_cap(o, n);
  if (cap > nb->k) cap = nb->k;
  /* the cloud's noise as the K selection reads it; the progress held at
   * the normals' end (Ctrl-C still stops it) */
  bsurf_progress_hold hold = {o->progress, o->progress_user, n, n, 0};
  bsurf_kselect_options ko;
  bsurf_smooth_select_options(o->threads, &ko);
  ko.progress = o->progress ? bsurf_progress_hold_cb : NULL;
  ko.progress_user = &hold;
  double level = NAN;
  size_t sections = 0;
  bsurf_status st = bsurf_ksel_cloud_noise(xyz, nb, &ko, &level, &sections);
  if (st != BSURF_OK || !(level > 0)) return st;
  res->quadric_noise = sqrt(level);
  int kq = 0;
  double tq = NAN, pw = NAN;
  st = bsurf_fvar_quadric_k(o, bsurf_fvar_quadric_sigma(res, level, s2), cap, &kq, &tq, &pw);
  res->quadric_power = pw;
  if (st != BSURF_OK || !kq) return st;
  st = bsurf_fvar_quadric_rss(xyz, nb, kq, o->threads, rss, ko.progress, ko.progress_user);
  if (st == BSURF_OK)
    st = bsurf_fvar_filter(nb, bsurf_fvar_filter_k(o), o->threads, level, kq, rss, NULL, q);
  if (st == BSURF_OK) {
    res->quadric_k = kq;
    res->quadric_threshold = tq;
  }
  return st;
}

bsurf_status bsurf_fvar_eta(const double *xyz, const bsurf_neighbors *nb, int k, int threads,
                            double *eta) {
  const size_t n = nb->point_count;
  double *nu = bsurf_calloc_array(n ? n : 1, sizeof(double)),
         *u = bsurf_alloc_array(n ? n : 1, sizeof(double)),
         *l0 = bsurf_alloc_array(n ? n : 1, sizeof(double)),
         *ratio = bsurf_alloc_array(n ? n : 1, sizeof(double));
  bsurf_status st = nu && u && l0 && ratio ? BSURF_OK : BSURF_ERR_NOMEM;
  if (st == BSURF_OK)
    st = bsurf_fvar_local(xyz, nb, k, threads, nu, u, l0, ratio, NULL, NULL, NULL);
  if (st == BSURF_OK) *eta = bsurf_median(ratio, n);
  free(nu);
  free(u);
  free(l0);
  free(ratio);
  return st;
}

/* ---- in memory ---- */

bsurf_status bsurf_fvar_detect(const double *xyz, const bsurf_neighbors *nb,
                               const bsurf_feature_options *o, double *score, uint8_t *feature,
                               bsurf_fvar_result *res) {
  BSURF_REQUIRE_IN("feature options", o->false_positive_rate > 0 && o->false_positive_rate < 1,
                   "false_positive_rate = %g: must be in (0, 1)", o->false_positive_rate);
  const int kf = bsurf_fvar_filter_k(o);
  BSURF_REQUIRE_IN("feature options", o->variance_filter_k >= 0 && kf <= nb->k,
                   "variance_filter_k = %d: must be in [0, nb->k = %d]", o->variance_filter_k,
                   nb->k);
  const size_t n = nb->point_count;
  double *u = bsurf_alloc_array(n, sizeof(double)), *l0 = bsurf_alloc_array(n, sizeof(double)),
         *ratio = bsurf_alloc_array(n, sizeof(double)), *w = bsurf_alloc_array(n, sizeof(double)),
         *b = bsurf_alloc_array(n, sizeof(double)), *g = bsurf_alloc_array(n, sizeof(double));
  bsurf_status st = u && l0 && ratio && w && b && g ? BSURF_OK : BSURF_ERR_NOMEM;
  if (st == BSURF_OK)
    st = bsurf_fvar_local(xyz, nb, o->normals.k, o->threads, score, u, l0, ratio, w, b, g);
  double s2 = 0, eta = 0;
  if (st == BSURF_OK) {
    eta = bsurf_median(ratio, n);
    /* E(g) (ratio, no longer needed, holds the sorted g, then lambda0 by bin) */
    bsurf_fvar_fit fit;
    memcpy(ratio, g, n * sizeof(double));
    bsurf_fvar_fit_prepare(&fit, ratio, n);
    for (size_t i = 0; i < n; i++)
      bsurf_fvar_fit_put(&fit, ratio, g[i], l0[i]);
    s2 = bsurf_median(l0, n);
    bsurf_fvar_fit_solve(&fit, ratio, s2);
    bsurf_fvar_fit_scale(&fit, s2, n, g, u, w);
    st = bsurf_fvar_filter(nb, kf, o->threads, s2, o->normals.k, u, w, score);
  }
  /* the border score zb into l0 (no longer needed) */
  if (st == BSURF_OK) st = bsurf_fvar_filter(nb, kf, o->threads, 0, o->normals.k, b, NULL, l0);
  if (st == BSURF_OK) st = bsurf_fvar_null(o, s2, eta, res);
  if (st == BSURF_OK) st = bsurf_fvar_split(score, n, res);
  /* the quadric check: q into ratio, w its scratch (neither needed now) */
  if (st == BSURF_OK) st = quadric_check(xyz, nb, o, s2, w, ratio, res);
  if (st == BSURF_OK)
    for (size_t i = 0; i < n; i++)
      feature[i] =
          (uint8_t)bsurf_fvar_count(res, score[i], l0[i], res->quadric_k ? ratio[i] : NAN, NULL);
  free(u);
  free(l0);
  free(ratio);
  free(w);
  free(b);
  free(g);
  return st;
}

bsurf_status bsurf_fvar_null(const bsurf_feature_options *o, double s2, double eta,
                             bsurf_fvar_result *res) {
  res->quadric_k = 0;
  res->quadric_threshold = res->quadric_power = res->quadric_noise = NAN;
  res->quadric_cleared = 0;
  res->border_points = 0;
  res->noise_level = sqrt(s2);
  res->sigma0 = 0;
  res->threshold = res->null_threshold = res->split = NAN;
  /* the border score's null quantile: b does not depend on the noise's
   * size (a flat patch's centroid scatter), so also without noise */
  bsurf_status st = bsurf_fvar_null_threshold(o, s2 > 0 ? eta : 0, &res->null_threshold,
                                              &res->border_threshold, &res->sigma0);
  if (st == BSURF_OK && !(s2 > 0)) { /* noise-free: the null is nu = 0 (bsurf_fvar_split) */
    res->null_threshold = NAN;
    res->sigma0 = 0;
  }
  return st;
}

bsurf_status bsurf_fvar_split(const double *z, size_t n, bsurf_fvar_result *res) {
  if (res->noise_level > 0) {
    /* t = max(t_null, Otsu's split of log z): the test bounds the flat
     * area's false positives; among what it lets through, the split keeps
     * the upper mode (the band nearest the edge) when z is bimodal */
    bsurf_status st = BSURF_OK;
    if (n >= 2) st = bsurf_tail_threshold(z, n, BSURF_TAIL_OTSU, &res->split);
    if (st != BSURF_OK) return st;
    res->threshold = res->split > res->null_threshold ? res->split : res->null_threshold;
    return BSURF_OK;
  }
  /* noise-free: rounding-level values are flat */
  double mx = 0;
  for (size_t i = 0; i < n; i++)
    if (z[i] > mx) mx = z[i];
  res->threshold = 1e-12 * mx;
  return BSURF_OK;
}

/* cleared by the quadric check: a quadric explains the neighbourhood (a
 * NAN q, none computed, clears nothing) */
static int quadric_explains(const bsurf_fvar_result *res, double q) {
  return res->quadric_k > 0 && q <= res->quadric_threshold;
}

int bsurf_fvar_feature(const bsurf_fvar_result *res, double z, double zb, double q) {
  return (z > res->threshold && !quadric_explains(res, q)) || zb > res->border_threshold;
}

int bsurf_fvar_count(bsurf_fvar_result *res, double z, double zb, double q, size_t *features) {
  const int tested = z > res->threshold, cleared = tested && quadric_explains(res, q);
  const int border = zb > res->border_threshold, f = (tested && !cleared) || border;
  if (features) *features += (size_t)f;
  res->quadric_cleared += (size_t)(cleared && !border);
  res->border_points += (size_t)(border && !(tested && !cleared));
  return f;
}

double bsurf_fvar_quadric_sigma(const bsurf_fvar_result *res, double level, double s2) {
  return res->sigma0 * sqrt(level / s2);
}

void bsurf_fvar_report(const bsurf_fvar_result *res, bsurf_feature_report *rep) {
  rep->threshold = res->threshold;
  rep->noise_level = res->noise_level;
  rep->border_threshold = res->border_threshold;
  rep->quadric_k = res->quadric_k;
  rep->quadric_threshold = res->quadric_threshold;
  rep->quadric_power = res->quadric_power;
  rep->quadric_noise = res->quadric_noise;
  rep->quadric_cleared = res->quadric_cleared;
  rep->border_points = res->border_points;
}
