/* Evaluation against ground truth: normal angle errors and their summaries.
 *
 * Thesis 5.2.2, 5.4 to 5.6 (Tables 5.1, 5.3-5.9) report the average
 * unoriented angle (in radians) between estimated normals and ground-truth
 * normals computed from the mesh connectivity; 5.2.3 (Table 5.2) splits the
 * vertices into the 15% with the highest bootstrap variance and the rest.
 * We add the median, the RMS and PCPNet's PGP5/PGP10 (the fractions of
 * points within 5 and 10 degrees).
 *
 * The angle is atan2(|a x b|, |a . b|) of the normalised vectors: acos of the
 * dot product loses half the digits near 0, where good normals are. All sums
 * run in point order, so results are reproducible bit for bit. */
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

double bsurf_normal_angle(const double a[3], const double b[3]) {
  double la = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
  double lb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
  if (!(la > 0) || !(lb > 0) || !isfinite(la) || !isfinite(lb)) return NAN;
  double u[3] = {a[0] / la, a[1] / la, a[2] / la}, v[3] = {b[0] / lb, b[1] / lb, b[2] / lb};
  double c[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
               fabs(u[0] * v[0] + u[1] * v[1] + u[2] * v[2]));
}

bsurf_status bsurf_angle_stats_compute(const double *angles, const uint8_t *mask, uint8_t keep,
                                       size_t count, bsurf_angle_stats *stats) {
  BSURF_REQUIRE(stats, "stats is NULL");
  BSURF_REQUIRE(!count || angles, "angles is NULL");
  size_t n = 0;
  for (size_t i = 0; i < count; i++)
    n += !mask || mask[i] == keep;
  stats->count = n;
  if (n == 0) {
    stats->mean_rad = stats->median_rad = stats->rms_rad = stats->mean_deg = NAN;
    stats->under5deg = stats->under10deg = NAN;
    return BSURF_OK;
  }
  double *sorted = bsurf_alloc_array(n, sizeof(double));
  if (!sorted) return BSURF_ERR_NOMEM;
  const double lim5 = 5.0 * PI / 180.0, lim10 = 10.0 * PI / 180.0;
  double sum = 0, sum2 = 0;
  size_t u5 = 0, u10 = 0, j = 0;
  for (size_t i = 0; i < count; i++) {
    if (mask && mask[i] != keep) continue;
    double a = angles[i];
    sum += a;
    sum2 += a * a;
    u5 += a < lim5;
    u10 += a < lim10;
    sorted[j++] = a;
  }
  qsort(sorted, n, sizeof(double), bsurf_cmp_double);
  const double dn = (double)n;
  stats->mean_rad = sum / dn;
  stats->median_rad = bsurf_median_sorted(sorted, n);
  stats->rms_rad = sqrt(sum2 / dn);
  stats->mean_deg = stats->mean_rad * 180.0 / PI;
  stats->under5deg = (double)u5 / dn;
  stats->under10deg = (double)u10 / dn;
  free(sorted);
  return BSURF_OK;
}

bsurf_status bsurf_eval_normals(const double *result, const double *truth, size_t count,
                                double *angles, bsurf_angle_stats *stats, size_t *bad_index) {
  BSURF_REQUIRE(!count || (result && truth), "result or truth is NULL");
  double *a = angles ? angles : (count ? bsurf_alloc_array(count, sizeof(double)) : NULL);
  if (count && !a) return BSURF_ERR_NOMEM;
  bsurf_status st = BSURF_OK;
  for (size_t i = 0; i < count; i++) {
    a[i] = bsurf_normal_angle(&result[3 * i], &truth[3 * i]);
    if (isnan(a[i])) {
      if (bad_index) *bad_index = i;
      st = BSURF_ERR_INVALID_VALUE;
      break;
    }
  }
  if (st == BSURF_OK && stats) st = bsurf_angle_stats_compute(a, NULL, 0, count, stats);
  if (a != angles) free(a);
  return st;
}

bsurf_status bsurf_quantile_split(const double *values, size_t count, double q, uint8_t *high,
                                  double *threshold, size_t *high_count, size_t *bad_index) {
  BSURF_REQUIRE(q >= 0 && q <= 1, "q = %g: must be in [0, 1]", q);
  BSURF_REQUIRE(!count || values, "values is NULL");
  for (size_t i = 0; i < count; i++)
    if (isnan(values[i])) {
      if (bad_index) *bad_index = i;
      return BSURF_ERR_INVALID_VALUE;
    }
  /* m = ceil(q N), with q N snapped to a whole number first when rounding
   * put it a hair above one (0.85 x 20 must give 17, not 18) */
  double x = q * (double)count, r = nearbyint(x);
  size_t m = fabs(x - r) <= 1e-9 * (x > 1 ? x : 1) ? (size_t)r : (size_t)ceil(x);
  if (m > count) m = count;
  double t = -INFINITY;
  if (m > 0) {
    double *sorted = bsurf_alloc_array(count, sizeof(double));
    if (!sorted) return BSURF_ERR_NOMEM;
    memcpy(sorted, values, sizeof(double) * count);
    qsort(sorted, count, sizeof(double), bsurf_cmp_double);
    t = sorted[m - 1];
    free(sorted);
  }
  size_t nh = 0;
  for (size_t i = 0; i < count; i++) {
    int h = values[i] > t;
    nh += (size_t)h;
    if (high) high[i] = (uint8_t)h;
  }
  if (threshold) *threshold = t;
  if (high_count) *high_count = nh;
  return BSURF_OK;
}

bsurf_status bsurf_eval_features(const uint8_t *result, const uint8_t *truth, size_t count,
                                 bsurf_feature_stats *stats) {
  BSURF_REQUIRE(stats, "stats is NULL");
  BSURF_REQUIRE(!count || (result && truth), "result or truth is NULL");
  memset(stats, 0, sizeof *stats);
  for (size_t i = 0; i < count; i++) {
    int r = result[i] != 0, t = truth[i] != 0;
    if (r && t)
      stats->true_pos++;
    else if (r)
      stats->false_pos++;
    else if (t)
      stats->false_neg++;
    else
      stats->true_neg++;
  }
  double tp = (double)stats->true_pos;
  size_t det = stats->true_pos + stats->false_pos, pos = stats->true_pos + stats->false_neg;
  stats->precision = det ? tp / (double)det : NAN;
  stats->recall = pos ? tp / (double)pos : NAN;
  stats->f1 = det + pos ? 2 * tp / (double)(det + pos) : NAN;
  return BSURF_OK;
}
