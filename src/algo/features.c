/* Feature detection (thesis chapter 7): the entry point, bsurf_detect_features,
 * and the tail thresholds. The distance map (7.1) is in features_distance.c,
 * the variance method's null test in features_variance.c.
 *
 * Variance (7.2, Eq. 7.2): F = {i | nu_i > t_h}, nu = normal_var from
 * bsurf_estimate_normals; t_h given or from bsurf_tail_threshold.
 *
 * Why Otsu on log(nu) is the default auto rule: normal_var is a bulk of
 * flat-area values spread by the noise plus a heavy upper tail of feature
 * points; on a log scale these are two modes, which is what Otsu's
 * between-class criterion separates. median + 3 MAD of log(nu) assumes the
 * bulk is most of the points AND that the tail starts a fixed number of
 * spreads above it. Measured (F1 against feature_width 2 labels, k 30, B 50,
 * uniform noise in units of h; best fixed threshold in brackets):
 *               Otsu   MAD   (best)
 *   cube 0      0.89   0.00  (0.97)   (nonzero nu is all near-edge: the MAD
 *   cube 0.5    0.90   0.89  (0.91)    of the logs is then far too wide)
 *   cube 1.0    0.65   0.46  (0.73)
 *   fandisk 0   0.67   0.00  (0.91)
 *   fandisk 0.5 0.89   0.27  (0.89)
 *   fandisk 1.0 0.76   0.16  (0.76)
 * Otsu is within 0.01 of the best fixed threshold on the noisy Fandisk.
 * The knee of the sorted values (largest gap below the chord from the
 * smallest to the largest) was also tried and not kept: F1 0.33 / 0.90 /
 * 0.57 on the cube and 0.20 / 0.19 / 0.21 on Fandisk at noise 0 / 0.5 / 1.0
 * (0.17 / 0.84 / 0.73 and 0.05 / 0.45 / 0.47 on log values). */
#include "algo/algo.h"
#include "common/common.h"
#include "local/local.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

bsurf_feature_options bsurf_feature_options_default(void) {
  /* every member not named is zero */
  bsurf_feature_options o = {
      .method = BSURF_FEATURES_VARIANCE,
      .k_min = 15,
      .k_max = 60,
      .k_step = 2,
      .ratio_threshold = 0.1,
      .noise_factor = 1.75,
      .alpha = 0.5,
      .iterations = 5,
      .sigma_range = 0.05,
      .threshold = NAN,
      .tail_rule = BSURF_TAIL_NULL,
      .false_positive_rate = 0.01,
      .feature_angle = 90,
      .quadric_angle = 45,
      .normals = bsurf_normal_options_default(),
  };
  return o;
}

/* ---- automatic tail threshold ---- */

/* Otsu's two-class split of sorted values (count >= 1) on a 256-bin
 * histogram between the 0.1% and 100% quantiles (a few outliers at the
 * bottom would stretch the range): the upper edge of the last bin of the
 * lower class. */
double bsurf_otsu_sorted(const double *l, size_t count) {
  enum { BINS = 256 };
  double lo = l[(size_t)(0.001 * (double)(count - 1))], hi = l[count - 1];
  if (!(hi > lo)) return hi;
  double hist[BINS] = {0};
  double w = (hi - lo) / BINS;
  for (size_t i = 0; i < count; i++) {
    int b = l[i] <= lo ? 0 : (int)((l[i] - lo) / w);
    if (b >= BINS) b = BINS - 1;
    hist[b] += 1;
  }
  double total = (double)count, sum_all = 0;
  for (int b = 0; b < BINS; b++)
    sum_all += b * hist[b];
  double w0 = 0, sum0 = 0, best = -1;
  int best_b = 0;
  for (int b = 0; b < BINS - 1; b++) {
    w0 += hist[b];
    sum0 += b * hist[b];
    double w1 = total - w0;
    if (w0 <= 0 || w1 <= 0) continue;
    double m0 = sum0 / w0, m1 = (sum_all - sum0) / w1;
    double between = w0 * w1 * (m0 - m1) * (m0 - m1);
    if (between > best) {
      best = between;
      best_b = b;
    }
  }
  return lo + (best_b + 1) * w;
}

bsurf_status bsurf_tail_threshold(const double *values, size_t count, bsurf_tail_rule rule,
                                  double *threshold) {
  BSURF_REQUIRE(values, "values is NULL");
  BSURF_REQUIRE(threshold, "threshold is NULL");
  BSURF_REQUIRE(rule == BSURF_TAIL_OTSU || rule == BSURF_TAIL_MAD,
                "rule = %d: must be BSURF_TAIL_OTSU or BSURF_TAIL_MAD (BSURF_TAIL_NULL needs "
                "the points: bsurf_detect_features)",
                (int)rule);
  if (count < 2)
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS,
                             "bsurf_tail_threshold: %zu values, at least 2 needed", count);
  for (size_t i = 0; i < count; i++)
    if (isnan(values[i])) return BSURF_ERR_INVALID_VALUE;
  /* values at or below 1e-12 x max are rounding-level zeros (a noise-free
   * flat area: every bootstrap normal is the same): they are bulk, left out
   * of the logs, which they would otherwise dominate */
  double mx = 0;
  for (size_t i = 0; i < count; i++)
    if (values[i] > mx) mx = values[i];
  const double floor_v = 1e-12 * mx;
  double *l = bsurf_alloc_array(count, sizeof(double));
  if (!l) return BSURF_ERR_NOMEM;
  size_t m = 0;
  for (size_t i = 0; i < count; i++)
    if (values[i] > floor_v) l[m++] = log(values[i]);
  if (m < 2) {
    free(l);
    *threshold = floor_v;
    return BSURF_OK;
  }
  count = m;
  qsort(l, count, sizeof(double), bsurf_cmp_double);
  double t;
  if (rule == BSURF_TAIL_MAD) {
    double med = bsurf_median_sorted(l, count);
    for (size_t i = 0; i < count; i++)
      l[i] = fabs(l[i] - med);
    qsort(l, count, sizeof(double), bsurf_cmp_double);
    double mad = bsurf_median_sorted(l, count);
    t = med + 3.0 * 1.4826 * mad;
  } else {
    t = bsurf_otsu_sorted(l, count);
  }
  free(l);
  *threshold = exp(t);
  return BSURF_OK;
}

/* ---- the entry point ---- */

void bsurf_feature_report_clear(bsurf_feature_report *rep) {
  memset(rep, 0, sizeof *rep);
  rep->ratio_threshold_kmin = NAN;
  rep->noise_level = NAN;
  rep->edge_power = NAN;
  rep->border_threshold = NAN;
  rep->quadric_threshold = NAN;
  rep->quadric_power = NAN;
  rep->quadric_noise = NAN;
}

bsurf_status bsurf_detect_features(const double *xyz, const bsurf_neighbors *nb,
                                   const bsurf_feature_options *opts, uint8_t *feature,
                                   double *score, bsurf_feature_report *report) {
  bsurf_feature_options o = opts ? *opts : bsurf_feature_options_default();
  if (report) bsurf_feature_report_clear(report);
  BSURF_REQUIRE(xyz, "xyz is NULL");
  BSURF_REQUIRE(feature, "feature is NULL");
  BSURF_REQUIRE(nb && nb->idx, "nb is %s: build it with bsurf_neighbors_build",
                nb ? "empty" : "NULL");
  BSURF_REQUIRE(o.method == BSURF_FEATURES_DISTANCE || o.method == BSURF_FEATURES_VARIANCE,
                "method = %d: must be BSURF_FEATURES_DISTANCE or BSURF_FEATURES_VARIANCE",
                (int)o.method);
  BSURF_REQUIRE((unsigned)o.tail_rule <= BSURF_TAIL_NULL,
                "tail_rule = %d: must be BSURF_TAIL_OTSU, _MAD or _NULL", (int)o.tail_rule);
  BSURF_REQUIRE(o.method != BSURF_FEATURES_VARIANCE || o.normals.bootstrap >= 2,
                "normals.bootstrap = %d: the variance method needs B >= 2", o.normals.bootstrap);
  BSURF_REQUIRE(o.feature_angle >= 0 && o.feature_angle < 180,
                "feature_angle = %g: must be in [0, 180)", o.feature_angle);
  BSURF_REQUIRE(o.variance_k_max >= 0, "variance_k_max = %d: must be >= 0", o.variance_k_max);
  BSURF_REQUIRE(o.quadric_angle >= 0 && o.quadric_angle < 180,
                "quadric_angle = %g: must be in [0, 180)", o.quadric_angle);
  const size_t n = nb->point_count;
  double *sc = score ? score : bsurf_alloc_array(n, sizeof(double));
  double *tmp = NULL;
  uint8_t *state = NULL;
  if (!sc) return BSURF_ERR_NOMEM;
  bsurf_status st = BSURF_OK;
  double thr = 0, R = 0, t_kmin = NAN;
  size_t imm = 0;
  const int null_rule = isnan(o.threshold) && o.tail_rule == BSURF_TAIL_NULL;
  if (o.method == BSURF_FEATURES_VARIANCE && null_rule && o.feature_angle > 0) {
    /* the neighbourhood from the test's power (features_variance.c), at
     * most nb->k */
    double eta = 0, pw = NAN;
    int k = o.normals.k, cap = bsurf_fvar_k_cap(&o, n);
    if (cap > nb->k) cap = nb->k;
    st = bsurf_fvar_eta(xyz, nb, o.normals.k, o.threads, &eta);
    if (st == BSURF_OK) st = bsurf_fvar_choose_k(&o, eta, cap, &k, &pw);
    o.normals.k = k;
    o.variance_k_max = cap; /* the choice's cap stays the quadric check's (as the job) */
    if (report) report->edge_power = pw;
  }
  if (report) report->k = o.normals.k;
  if (st == BSURF_OK && o.method == BSURF_FEATURES_VARIANCE) {
    bsurf_normal_options no = o.normals;
    no.threads = o.threads;
    no.progress = o.progress;
    no.progress_user = o.progress_user;
    if (no.bootstrap < 2) st = BSURF_ERR_INVALID_ARG;
    bsurf_normal_fields nf = {NULL, sc, NULL};
    if (st == BSURF_OK) st = bsurf_estimate_normals(xyz, nb, NULL, &no, &nf, NULL);
    if (st == BSURF_OK && null_rule) {
      /* the null test (features_variance.c): sc becomes the filtered z */
      bsurf_fvar_result vr;
      st = bsurf_fvar_detect(xyz, nb, &o, sc, feature, &vr);
      /* vr is set only where the detection ran (a refused option or no
       * memory leave it unset: the report stays cleared) */
      if (st == BSURF_OK) thr = vr.threshold;
      if (st == BSURF_OK && report) bsurf_fvar_report(&vr, report);
    } else if (st == BSURF_OK) {
      if (isnan(o.threshold))
        st = bsurf_tail_threshold(sc, n, o.tail_rule, &thr);
      else
        thr = o.threshold;
      if (st == BSURF_OK)
        for (size_t i = 0; i < n; i++)
          feature[i] = sc[i] > thr;
    }
  } else if (st == BSURF_OK) {
    /* the stages of the tiled run (src/tile/features_tiled.c), on the whole cloud */
    state = bsurf_alloc_array(n, 1);
    st = state ? bsurf_fdist_distance_raw(xyz, nb, &o, sc, NULL, &R, &imm, &t_kmin, state)
               : BSURF_ERR_NOMEM;
    const int passes = bsurf_fdist_filter_passes(&o, R);
    if (st == BSURF_OK && passes > 0) {
      tmp = bsurf_alloc_array(n, sizeof(double));
      if (!tmp) st = BSURF_ERR_NOMEM;
      for (int it = 0; it < passes && st == BSURF_OK; it++)
        st = bsurf_fdist_filter(xyz, nb, &o, nb->h, R, it % 2 ? tmp : sc, it % 2 ? sc : tmp);
      if (st == BSURF_OK && passes % 2) memcpy(sc, tmp, n * sizeof(double));
    }
    if (st == BSURF_OK) {
      double mx = -INFINITY;
      bsurf_fdist_max_radius(sc, n, &mx);
      if (isnan(o.threshold))
        st = bsurf_fdist_auto_threshold(sc, n, &thr);
      else
        thr = o.threshold * mx;
    }
    if (st == BSURF_OK)
      for (size_t i = 0; i < n; i++)
        feature[i] = (uint8_t)bsurf_fdist_feature(sc[i], state[i], thr, o.threshold);
  }
  if (st == BSURF_OK && report) {
    report->threshold = thr;
    report->max_radius = R;
    report->immediate = imm;
    report->ratio_threshold_kmin = t_kmin;
    for (size_t i = 0; i < n; i++)
      report->feature_points += feature[i];
  }
  free(tmp);
  free(state);
  if (!score) free(sc);
  return st;
}
