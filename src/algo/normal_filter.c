/* Bilateral Gaussian filter for normal smoothing (thesis 5.3, Eqs. 5.6-5.8).
 *
 * One iteration updates every normal by
 *   n(d_i) <- (1 - alpha) n(d_i)
 *             + alpha / c(d_i) sum_{p in N_i} G(nu_p, sigma_nu) G(|d_i - p|, sigma_d) n(p)
 * with G(a, b) = exp(-a^2 / b^2) (Eq. 5.7) and c(d_i) the sum of the weights
 * (Eq. 5.8), so normals with a high bootstrap variance nu (unreliable ones)
 * have little influence. The thesis writes G(nu_j, ...) inside a sum over p:
 * we read nu_j as the variance of the neighbour p, which is what makes the
 * filter protect smooth regions from unreliable normals (5.3.2). Normals are
 * unoriented, so each n(p) is first flipped to agree with n(d_i). The result
 * is normalised. Every iteration reads the previous iteration's normals only
 * (Jacobi order), so the result does not depend on threads or point order.
 * sigma_nu = infinity (or no variances) gives the single Gaussian filter the
 * thesis compares against. */
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct filter_ctx {
  const double *xyz;
  const bsurf_neighbors *nb;
  int k;
  const double *src;
  double *dst;
  const double *nu;
  double alpha, sigma_d, sigma_nu;
} filter_ctx;

static void filter_point(void *vctx, int thread, size_t i) {
  (void)thread;
  const filter_ctx *c = vctx;
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  const double *ni = &c->src[3 * i], *di = &c->xyz[3 * i];
  double acc[3] = {0, 0, 0}, wsum = 0;
  for (int j = 0; j < c->k; j++) {
    const size_t p = idx[j];
    const double *np = &c->src[3 * p], *dp = &c->xyz[3 * p];
    double dx = di[0] - dp[0], dy = di[1] - dp[1], dz = di[2] - dp[2];
    double dist2 = dx * dx + dy * dy + dz * dz;
    double w = exp(-dist2 / (c->sigma_d * c->sigma_d));
    if (c->nu && isfinite(c->sigma_nu))
      w *= exp(-(c->nu[p] * c->nu[p]) / (c->sigma_nu * c->sigma_nu));
    double s = (np[0] * ni[0] + np[1] * ni[1] + np[2] * ni[2]) < 0 ? -w : w;
    for (int t = 0; t < 3; t++)
      acc[t] += s * np[t];
    wsum += w;
  }
  double out[3];
  for (int t = 0; t < 3; t++)
    out[t] = wsum > 0 ? (1 - c->alpha) * ni[t] + c->alpha * acc[t] / wsum : ni[t];
  double len = sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
  for (int t = 0; t < 3; t++)
    c->dst[3 * i + t] = len > 0 ? out[t] / len : ni[t];
}

bsurf_status bsurf_smooth_normals(const double *xyz, const bsurf_neighbors *nb, int k,
                                  double *normals, const double *normal_var, int iterations,
                                  double alpha, double sigma_d, double sigma_nu, int threads) {
  BSURF_REQUIRE(xyz && normals, "xyz or normals is NULL");
  BSURF_REQUIRE(nb && nb->idx, "nb is %s: build it with bsurf_neighbors_build",
                nb ? "empty" : "NULL");
  BSURF_REQUIRE(k >= 1 && k <= nb->k, "k = %d: must be in [1, nb->k = %d]", k, nb->k);
  BSURF_REQUIRE(iterations >= 0, "iterations = %d: must be >= 0", iterations);
  BSURF_REQUIRE(alpha >= 0 && alpha <= 1, "alpha = %g: must be in [0, 1]", alpha);
  BSURF_REQUIRE(sigma_d > 0 && isfinite(sigma_d), "sigma_d = %g: must be finite and > 0", sigma_d);
  BSURF_REQUIRE(sigma_nu > 0, "sigma_nu = %g: must be > 0 (INFINITY: no variance term)", sigma_nu);
  if (iterations == 0) return BSURF_OK;
  const size_t n = nb->point_count;
  double *tmp = bsurf_alloc_array(n, 3 * sizeof(double));
  if (!tmp) return BSURF_ERR_NOMEM;
  filter_ctx ctx = {xyz, nb, k, normals, tmp, normal_var, alpha, sigma_d, sigma_nu};
  bsurf_status st = BSURF_OK;
  for (int it = 0; it < iterations && st == BSURF_OK; it++) {
    st = bsurf_parallel_points(n, threads, filter_point, &ctx, NULL, NULL);
    const double *t = ctx.src;
    ctx.src = ctx.dst;
    ctx.dst = (double *)t;
  }
  if (ctx.src != normals) memcpy(normals, ctx.src, n * 3 * sizeof(double));
  free(tmp);
  return st;
}
