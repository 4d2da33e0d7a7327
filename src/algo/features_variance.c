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
 *    the normal, the tilt of the normal has variance about sigma^2 /
 *    (sum_j |t_j|^2), t_j the tangential offsets (the slope of a least-
 *    squares line), and sum_j |t_j|^2 = K tr_i with tr_i the trace of the
 *    neighbourhood's covariance. So nu_i tr_i K / sigma^2 does not depend
 *    on the density (anisotropic sampling) or the units. The noise is
 *    measured on the cloud itself: s^2 = median_i lambda0_i, the median of
 *    the smallest covariance eigenvalue (features are a minority; on a
 *    flat area lambda0 is the variance of the noise along the normal). The
 *    score is
 *        Z_i = nu_i tr_i / s^2.
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
 * Without noise (s^2 = 0: most neighbourhoods exactly flat) the null is
 * the point mass nu = 0: Z = nu tr, and t = 1e-12 max z (rounding).
 *
 * What it does not do: near an edge every point whose neighbourhood
 * reaches across it is "not flat", so the detected band is about the
 * neighbourhood's radius wide whatever the threshold; and when the noise is
 * comparable to the neighbourhood's radius (eta above ~0.1) the features'
 * nu is inside the null's spread and few points pass (docs/features.md). */
#include "algo/algo.h"
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

enum {
  NULL_INTERIOR = 20000,   /* points of the patch whose statistics count */
  NULL_STREAM = 0x6e756c6c /* "null": the patch's random streams */
};

int bsurf_fvar_filter_k(const bsurf_feature_options *o) {
  if (o->variance_filter_k > 0) return o->variance_filter_k;
  return o->normals.k / 2 > 1 ? o->normals.k / 2 : 1;
}

/* ---- per row: u = nu tr, lambda0, lambda0 / tr ---- */

typedef struct local_ctx {
  const double *xyz;
  const bsurf_neighbors *nb;
  int k;
  const double *nu; /* by row */
  double *u, *l0, *ratio;
} local_ctx;

static void local_row(void *vctx, int thread, size_t r) {
  (void)thread;
  const local_ctx *c = vctx;
  double l0, tr;
  bsurf_pca_l0_trace(c->xyz, &c->nb->idx[r * (size_t)c->nb->k], c->k, &l0, &tr);
  c->u[r] = c->nu[r] * tr;
  c->l0[r] = l0;
  c->ratio[r] = tr > 0 ? l0 / tr : 0;
}

bsurf_status bsurf_fvar_local(const double *xyz, const bsurf_neighbors *nb, int k, int threads,
                              const double *nu, double *u, double *l0, double *ratio) {
  local_ctx c = {xyz, nb, k, nu, u, l0, ratio};
  return bsurf_parallel_points(nb->point_count, bsurf_threads_resolve(threads), local_row, &c, NULL,
                               NULL);
}

/* ---- the median filter ---- */

static int cmp_double(const void *pa, const void *pb) {
  double a = *(const double *)pa, b = *(const double *)pb;
  return (a > b) - (a < b);
}

static double median_sorted(const double *v, size_t n) {
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

typedef struct filter_ctx {
  const bsurf_neighbors *nb;
  int kf;
  double inv_s2;
  const double *u; /* by point */
  double *z;       /* by row */
  double *scratch; /* threads x kf */
} filter_ctx;

static void filter_row(void *vctx, int thread, size_t r) {
  const filter_ctx *c = vctx;
  const uint32_t *idx = &c->nb->idx[r * (size_t)c->nb->k];
  double *w = &c->scratch[(size_t)thread * (size_t)c->kf];
  for (int j = 0; j < c->kf; j++)
    w[j] = c->u[idx[j]];
  qsort(w, (size_t)c->kf, sizeof(double), cmp_double);
  c->z[r] = median_sorted(w, (size_t)c->kf) * c->inv_s2;
}

bsurf_status bsurf_fvar_filter(const bsurf_neighbors *nb, int kf, int threads, double s2,
                               const double *u, double *z) {
  const int t = bsurf_threads_resolve(threads);
  filter_ctx c = {nb, kf, s2 > 0 ? 1 / s2 : 1, u, z, NULL};
  c.scratch = bsurf_alloc_array((size_t)t * (size_t)kf, sizeof(double));
  if (!c.scratch) return BSURF_ERR_NOMEM;
  bsurf_status st = bsurf_parallel_points(nb->point_count, t, filter_row, &c, NULL, NULL);
  free(c.scratch);
  return st;
}

double bsurf_fvar_median(double *v, size_t n) {
  if (!n) return 0;
  qsort(v, n, sizeof(double), cmp_double);
  return median_sorted(v, n);
}

/* ---- the null patch ---- */

typedef struct null_patch {
  size_t n;
  double side, margin;
  double *xyz, *g; /* g: the unit gaussian draw of each point */
  bsurf_neighbors nb;
  double *nu, *u, *l0, *ratio, *z;
} null_patch;

static void patch_free(null_patch *p) {
  bsurf_neighbors_free(&p->nb);
  free(p->xyz);
  free(p->g);
  free(p->nu);
  free(p->u);
  free(p->l0);
  free(p->ratio);
  free(p->z);
}

/* the median of lambda0 / tr over the patch's interior at noise sigma */
static bsurf_status patch_eta(null_patch *p, int k, int threads, double sigma, double *eta) {
  for (size_t i = 0; i < p->n; i++)
    p->xyz[3 * i + 2] = sigma * p->g[i];
  bsurf_status st = bsurf_fvar_local(p->xyz, &p->nb, k, threads, p->nu, p->u, p->l0, p->ratio);
  if (st != BSURF_OK) return st;
  size_t m = 0;
  for (size_t i = 0; i < p->n; i++) {
    const double *q = &p->xyz[3 * i];
    if (q[0] > p->margin && q[0] < p->side - p->margin && q[1] > p->margin &&
        q[1] < p->side - p->margin)
      p->u[m++] = p->ratio[i];
  }
  *eta = bsurf_fvar_median(p->u, m);
  return BSURF_OK;
}

bsurf_status bsurf_fvar_null_threshold(const bsurf_feature_options *o, double eta, double *t,
                                       double *sigma0) {
  const int k = o->normals.k, kf = bsurf_fvar_filter_k(o);
  const int kk = k > kf ? k : kf;
  null_patch p;
  memset(&p, 0, sizeof p);
  /* unit density: a K-neighbourhood has radius sqrt(K / pi); a point counts
   * when its neighbourhood and its filter's neighbours' are inside */
  p.margin = sqrt(k / PI) + sqrt(kf / PI) + 1;
  p.side = ceil(sqrt((double)NULL_INTERIOR) + 2 * p.margin);
  p.n = (size_t)(p.side * p.side);
  p.xyz = bsurf_alloc_array(3 * p.n, sizeof(double));
  p.g = bsurf_alloc_array(p.n, sizeof(double));
  p.nu = bsurf_calloc_array(p.n, sizeof(double));
  p.u = bsurf_alloc_array(p.n, sizeof(double));
  p.l0 = bsurf_alloc_array(p.n, sizeof(double));
  p.ratio = bsurf_alloc_array(p.n, sizeof(double));
  p.z = bsurf_alloc_array(p.n, sizeof(double));
  bsurf_status st = BSURF_OK;
  if (!p.xyz || !p.g || !p.nu || !p.u || !p.l0 || !p.ratio || !p.z) st = BSURF_ERR_NOMEM;
  for (size_t i = 0; st == BSURF_OK && i < p.n; i++) {
    bsurf_rng rng;
    bsurf_rng_init(&rng, o->normals.seed, i, NULL_STREAM);
    p.xyz[3 * i] = p.side * bsurf_rng_uniform(&rng);
    p.xyz[3 * i + 1] = p.side * bsurf_rng_uniform(&rng);
    p.xyz[3 * i + 2] = 0;
    p.g[i] = bsurf_rng_normal(&rng);
  }
  /* the neighbourhoods do not depend on the (small) noise: built on the
   * plane z = 0 so that they stay the same while sigma_0 is tuned */
  if (st == BSURF_OK) st = bsurf_neighbors_build(&p.nb, p.xyz, p.n, kk, o->threads, NULL, NULL);
  /* sigma_0: lambda0 ~ sigma^2 and tr ~ K / (2 pi) on a unit-density disc,
   * then three secant steps on eta(sigma) ~ sigma^2 */
  double sigma = sqrt(eta * k / (2 * PI));
  for (int it = 0; st == BSURF_OK && it < 4 && sigma > 0; it++) {
    double e;
    st = patch_eta(&p, k, o->threads, sigma, &e);
    if (st == BSURF_OK && e > 0) sigma *= sqrt(eta / e);
  }
  if (st == BSURF_OK) {
    for (size_t i = 0; i < p.n; i++)
      p.xyz[3 * i + 2] = sigma * p.g[i];
    bsurf_normal_options no = o->normals;
    no.threads = o->threads;
    no.progress = NULL;
    no.progress_user = NULL;
    no.point_index = NULL;
    bsurf_normal_fields nf = {NULL, p.nu, NULL};
    st = bsurf_estimate_normals(p.xyz, &p.nb, NULL, &no, &nf, NULL);
  }
  if (st == BSURF_OK) st = bsurf_fvar_local(p.xyz, &p.nb, k, o->threads, p.nu, p.u, p.l0, p.ratio);
  double s2 = 0;
  if (st == BSURF_OK) {
    memcpy(p.z, p.l0, p.n * sizeof(double));
    s2 = bsurf_fvar_median(p.z, p.n);
    st = bsurf_fvar_filter(&p.nb, kf, o->threads, s2, p.u, p.z);
  }
  if (st == BSURF_OK) {
    size_t m = 0;
    for (size_t i = 0; i < p.n; i++) {
      const double *q = &p.xyz[3 * i];
      if (q[0] > p.margin && q[0] < p.side - p.margin && q[1] > p.margin &&
          q[1] < p.side - p.margin)
        p.l0[m++] = p.z[i];
    }
    qsort(p.l0, m, sizeof(double), cmp_double);
    /* the smallest value that at most alpha m of the m values exceed */
    size_t r = (size_t)ceil((1 - o->false_positive_rate) * (double)m);
    *t = m ? p.l0[r > 0 ? (r <= m ? r - 1 : m - 1) : 0] : 0;
    if (sigma0) *sigma0 = sigma;
  }
  patch_free(&p);
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
         *ratio = bsurf_alloc_array(n, sizeof(double));
  bsurf_status st = u && l0 && ratio ? BSURF_OK : BSURF_ERR_NOMEM;
  if (st == BSURF_OK) st = bsurf_fvar_local(xyz, nb, o->normals.k, o->threads, score, u, l0, ratio);
  double s2 = 0, eta = 0;
  if (st == BSURF_OK) {
    s2 = bsurf_fvar_median(l0, n);
    eta = bsurf_fvar_median(ratio, n);
    st = bsurf_fvar_filter(nb, kf, o->threads, s2, u, score);
  }
  if (st == BSURF_OK) st = bsurf_fvar_threshold(o, score, n, s2, eta, res);
  if (st == BSURF_OK)
    for (size_t i = 0; i < n; i++)
      feature[i] = score[i] > res->threshold;
  free(u);
  free(l0);
  free(ratio);
  return st;
}

bsurf_status bsurf_fvar_threshold(const bsurf_feature_options *o, const double *z, size_t n,
                                  double s2, double eta, bsurf_fvar_result *res) {
  res->noise_level = sqrt(s2);
  res->sigma0 = 0;
  res->null_threshold = res->split = NAN;
  if (s2 > 0) {
    /* t = max(t_null, Otsu's split of log z): the test bounds the flat
     * area's false positives; among what it lets through, the split keeps
     * the upper mode (the band nearest the edge) when z is bimodal */
    bsurf_status st = bsurf_fvar_null_threshold(o, eta, &res->null_threshold, &res->sigma0);
    if (st == BSURF_OK && n >= 2) st = bsurf_tail_threshold(z, n, BSURF_TAIL_OTSU, &res->split);
    if (st != BSURF_OK) return st;
    res->threshold = res->split > res->null_threshold ? res->split : res->null_threshold;
    return BSURF_OK;
  }
  /* noise-free: the null is nu = 0; rounding-level values are flat */
  double mx = 0;
  for (size_t i = 0; i < n; i++)
    if (z[i] > mx) mx = z[i];
  res->threshold = 1e-12 * mx;
  return BSURF_OK;
}
