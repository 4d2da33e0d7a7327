/* Feature detection (thesis chapter 7): planes have none, the cube's edges
 * are found, incremental PCA equals PCA from scratch, thread independence,
 * the automatic tail threshold, precision/recall/F1. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"

/* test_cube_null_gaussian measured F1 0.788 (precision 0.941, recall 0.678;
 * 0.773 before the score's tangential spread became the design term
 * 4 / (1 / lambda1 + 1 / lambda2) instead of the trace) at these seeds: the bound leaves 0.07 for
 * legitimate drift (another neighbour tie order) */
#define F1_CUBE_BOUND 0.70

/* the last detect()'s report.border_points and threshold t */
static size_t last_border_points;
static double last_threshold;

static bsurf_feature_stats detect(const bsurf_cloud *c, const bsurf_feature_options *o, int k,
                                  uint8_t *feat, double *score) {
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c->xyz, c->point_count, k, 0, NULL, NULL), BSURF_OK);
  bsurf_feature_report rep;
  assert_int_equal(bsurf_detect_features(c->xyz, &nb, o, feat, score, &rep), BSURF_OK);
  size_t count = 0, alone = 0;
  for (size_t i = 0; i < c->point_count; i++) {
    count += feat[i];
    alone += feat[i] && !(score[i] > rep.threshold);
  }
  assert_int_equal(count, rep.feature_points);
  /* the border test's own share: without the quadric check, the flagged
   * points whose z is not above t (the variance method's null rule only) */
  const int null_rule = o->method == BSURF_FEATURES_VARIANCE && isnan(o->threshold) &&
                        o->tail_rule == BSURF_TAIL_NULL;
  if (!null_rule) assert_int_equal(rep.border_points, 0);
  if (null_rule && rep.quadric_k == 0) assert_int_equal(rep.border_points, alone);
  assert_true(rep.border_points <= rep.feature_points);
  last_border_points = rep.border_points;
  last_threshold = rep.threshold;
  bsurf_feature_stats s;
  memset(&s, 0, sizeof s);
  bsurf_field *truth = bsurf_cloud_field(c, "feature");
  if (truth) {
    uint8_t *t = malloc(c->point_count);
    for (size_t i = 0; i < c->point_count; i++)
      t[i] = truth->values[i] != 0;
    assert_int_equal(bsurf_eval_features(feat, t, c->point_count, &s), BSURF_OK);
    free(t);
  }
  bsurf_neighbors_free(&nb);
  return s;
}

/* A plane (with a little noise so the variance is not 0 everywhere) has no
 * feature with either method. */
static void test_plane_no_features(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_PLANE, 4000, BSURF_SAMPLING_RANDOM, 3, 0),
                   BSURF_OK);
  uint8_t *feat = malloc(c.point_count);
  double *score = malloc(c.point_count * sizeof(double));
  bsurf_feature_options o = bsurf_feature_options_default();
  o.method = BSURF_FEATURES_DISTANCE;
  detect(&c, &o, o.k_max, feat, score);
  size_t count = 0;
  for (size_t i = 0; i < c.point_count; i++)
    count += feat[i];
  assert_int_equal(count, 0);
  /* variance with a fixed threshold well above the flat-area level (the
   * auto rule always finds "a tail", so it is not asked on a featureless
   * shape); noise-free plane: every bootstrap normal is exact */
  o.method = BSURF_FEATURES_VARIANCE;
  o.normals.k = 20;
  o.normals.bootstrap = 10;
  o.threshold = 1e-6;
  detect(&c, &o, 20, feat, score);
  count = 0;
  for (size_t i = 0; i < c.point_count; i++)
    count += feat[i];
  assert_int_equal(count, 0);
  free(feat);
  free(score);
  bsurf_cloud_free(&c);
}

/* The regular cube at noise 0: the distance method with the thesis's T_h = 0
 * finds the points within one spacing of an edge; the automatic T_h those
 * within two (the labels of feature width 2). */
static void test_cube_edges_distance(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 12000, BSURF_SAMPLING_REGULAR, 1, 1.0),
                   BSURF_OK);
  uint8_t *feat = malloc(c.point_count);
  double *score = malloc(c.point_count * sizeof(double));
  bsurf_feature_options o = bsurf_feature_options_default();
  o.method = BSURF_FEATURES_DISTANCE;
  o.threshold = 0;
  bsurf_feature_stats s = detect(&c, &o, o.k_max, feat, score);
  assert_true(s.recall > 0.9);
  assert_true(s.precision > 0.8);
  /* the score of the detected points is <= 0, the rest positive */
  for (size_t i = 0; i < c.point_count; i++)
    assert_int_equal(feat[i], score[i] <= 0);
  bsurf_cloud_free(&c);
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 12000, BSURF_SAMPLING_REGULAR, 1, 2.0),
                   BSURF_OK);
  o.threshold = NAN;
  s = detect(&c, &o, o.k_max, feat, score);
  assert_true(s.recall > 0.95);
  assert_true(s.precision > 0.95);
  free(feat);
  free(score);
  bsurf_cloud_free(&c);
}

/* The distance method's automatic rule (noise-adapted T_{a/c}, Otsu's split
 * of the positive map values) on a cube with uniform noise 1.0 h, where the
 * thesis's fixed T_{a/c} = 0.1 stops nearly every point at k_min (noise alone
 * lifts lambda0/lambda2 above it): the thesis's setting marks most of the
 * cube, the automatic rule the edges. Without noise the adapted T_{a/c} is
 * the given one. */
static void test_distance_auto_rule(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 12000, BSURF_SAMPLING_REGULAR, 1, 2.0),
                   BSURF_OK);
  const size_t n = c.point_count;
  bsurf_neighbors nb;
  bsurf_feature_options o = bsurf_feature_options_default();
  o.method = BSURF_FEATURES_DISTANCE;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, o.k_max, 0, NULL, NULL), BSURF_OK);
  uint8_t *feat = malloc(n), *feat2 = malloc(n);
  double *score = malloc(n * sizeof(double)), *score2 = malloc(n * sizeof(double));
  bsurf_feature_report rep;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, feat, score, &rep), BSURF_OK);
  assert_true(rep.ratio_threshold_kmin == o.ratio_threshold);
  bsurf_neighbors_free(&nb);

  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, n, 0, &h), BSURF_OK);
  assert_int_equal(bsurf_add_noise(c.xyz, c.normals, n, BSURF_NOISE_UNIFORM, 1.0, h, 3), BSURF_OK);
  bsurf_feature_stats thesis, adapted;
  o.noise_factor = 0;
  o.threshold = 0;
  thesis = detect(&c, &o, o.k_max, feat, score);
  o = bsurf_feature_options_default();
  o.method = BSURF_FEATURES_DISTANCE;
  o.threads = 1;
  adapted = detect(&c, &o, o.k_max, feat, score);
  assert_true(thesis.f1 < 0.4);
  assert_true(adapted.f1 > 0.65);
  assert_true(adapted.precision > 0.5 && adapted.recall > 0.75);

  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, o.k_max, 0, NULL, NULL), BSURF_OK);
  o.threads = 2;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, feat2, score2, &rep), BSURF_OK);
  assert_true(rep.ratio_threshold_kmin > 2 * o.ratio_threshold); /* noise 1.0: f(k_min) ~ 0.15 */
  assert_true(rep.threshold > 0 && rep.threshold < rep.max_radius);
  for (size_t i = 0; i < n; i++)
    assert_int_equal(feat2[i], score2[i] <= rep.threshold);
  /* the sampled medians and the split are thread-independent */
  assert_memory_equal(feat, feat2, n);
  assert_memory_equal(score, score2, n * sizeof(double));
  o.noise_factor = -1;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, feat2, NULL, NULL), BSURF_ERR_INVALID_ARG);
  bsurf_neighbors_free(&nb);
  free(feat);
  free(feat2);
  free(score);
  free(score2);
  bsurf_cloud_free(&c);
}

/* The noisy cube (uniform noise 0.5 h): the variance method with the auto
 * threshold finds the edges of the feature width 2 labels. */
static void test_cube_edges_variance(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 12000, BSURF_SAMPLING_REGULAR, 1, 2.0),
                   BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, c.point_count, 0, &h), BSURF_OK);
  assert_int_equal(bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_UNIFORM, 0.5, h, 7),
                   BSURF_OK);
  uint8_t *feat = malloc(c.point_count);
  double *score = malloc(c.point_count * sizeof(double));
  bsurf_feature_options o = bsurf_feature_options_default();
  o.method = BSURF_FEATURES_VARIANCE;
  o.normals.bootstrap = 30;
  bsurf_feature_stats s = detect(&c, &o, o.normals.k, feat, score);
  assert_true(s.recall > 0.85);
  assert_true(s.precision > 0.75);
  free(feat);
  free(score);
  bsurf_cloud_free(&c);
}

/* The null-test threshold of the variance method (the default rule): on the
 * regular cube at gaussian noise 0.5 h (the README's cube, fixed seeds) F1
 * against the width-2 labels above a bound under the measured value. */
static void test_cube_null_gaussian(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 20000, BSURF_SAMPLING_REGULAR, 1, 2.0),
                   BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, c.point_count, 0, &h), BSURF_OK);
  assert_int_equal(
      bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_GAUSSIAN, 0.5, h, 1), BSURF_OK);
  uint8_t *feat = malloc(c.point_count);
  double *score = malloc(c.point_count * sizeof(double));
  bsurf_feature_options o = bsurf_feature_options_default();
  o.method = BSURF_FEATURES_VARIANCE;
  assert_int_equal(o.tail_rule, BSURF_TAIL_NULL);
  bsurf_feature_stats s = detect(&c, &o, o.normals.k, feat, score);
  printf("cube gaussian 0.5 h, null rule: precision %.3f recall %.3f F1 %.3f\n", s.precision,
         s.recall, s.f1);
  assert_true(s.f1 > F1_CUBE_BOUND);
  free(feat);
  free(score);
  bsurf_cloud_free(&c);
}

/* The defaults of `bootsurf features` (the job: method variance, null rule,
 * the neighbourhood chosen by the test's power on a simulated 90 degree edge)
 * on the regular cube at gaussian noise sigma = level x h (fixed seeds); F1
 * against the width-2 labels. k out: the neighbourhood chosen. */
static bsurf_feature_stats cube_defaults(double level, int *k) {
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 50000, BSURF_SAMPLING_REGULAR, 1, 2.0),
                   BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, c.point_count, 0, &h), BSURF_OK);
  assert_int_equal(
      bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_GAUSSIAN, level, h, 1),
      BSURF_OK);
  const size_t n = c.point_count;
  bsurf_field *tf = bsurf_cloud_field(&c, "feature");
  uint8_t *truth = malloc(n), *feat = malloc(n);
  for (size_t i = 0; i < n; i++)
    truth[i] = tf->values[i] != 0;
  /* the truth's fields would be kept as *_in: drop them from the input */
  bsurf_cloud in;
  bsurf_cloud_init(&in);
  in.point_count = n;
  in.xyz = c.xyz;
  bsurf_job_io io;
  memset(&io, 0, sizeof io);
  io.cloud = &in;
  bsurf_features_job_summary s;
  assert_int_equal(bsurf_features_job(&io, NULL, &s, NULL), BSURF_OK);
  assert_string_equal(s.field_names[1], "variance_z");
  bsurf_field *ff = bsurf_cloud_field(&in, "feature");
  assert_non_null(ff);
  for (size_t i = 0; i < n; i++)
    feat[i] = ff->values[i] != 0;
  bsurf_feature_stats st;
  assert_int_equal(bsurf_eval_features(feat, truth, n, &st), BSURF_OK);
  *k = s.report.k;
  printf("cube gaussian %.2f h, defaults: K %d (edge power %.2f) precision %.3f recall %.3f F1 "
         "%.3f\n",
         level, s.report.k, s.report.edge_power, st.precision, st.recall, st.f1);
  in.xyz = NULL; /* c's */
  bsurf_cloud_free(&in);
  free(truth);
  free(feat);
  bsurf_cloud_free(&c);
  return st;
}

/* The cube of 50,000 points (the development set's) at gaussian 0.5 h (the
 * README's cube; issue 22: F1 >= 0.8): measured F1 0.847 at K 30 (0.842
 * with the trace instead of the design term; then noise seeds 2 and 3: 0.831, 0.848; on 20,000
 * points seeds 1-3 give 0.773, 0.855, 0.857: 0.8 is a bound for this draw, not for every draw).
 * At 1.0 h the test at K 30 lets almost nothing through (F1 0.01 on the development set's cube at
 * g0.6) and the chosen K 60 restores it: measured F1 0.631 (0.651 with the trace; seed 2 then
 * 0.622; the distance method 0.290). */
static void test_cube_defaults(void **state) {
  (void)state;
  int k;
  bsurf_feature_stats s = cube_defaults(0.5, &k);
  assert_true(s.f1 >= 0.8);
  assert_int_equal(k, 30);
  s = cube_defaults(1.0, &k);
  assert_int_equal(k, 60);
  assert_true(s.f1 >= 0.55);
}

/* Two parallel sheets are not an edge. A flat sheet of 100 x 100 spacings
 * (10,000 random points) with a second sheet one spacing below it under a
 * quarter of it (2,500 points: a thin part of a thicker model, whose noise
 * the single sheet sets), uniform noise 0.25 spacings along the normal. The
 * doubled part's K-neighbourhoods hold both sheets: their normal's bootstrap
 * variance is raised by the gap, and the test flagged 100% of its interior
 * before the parallel-sheet test (features.c, bsurf_pca_l0_trace);
 * measured 4.6% with it. The single sheet stays unflagged. */
static uint64_t sheet_rng(uint64_t *s) {
  *s ^= *s << 13, *s ^= *s >> 7, *s ^= *s << 17;
  return *s;
}

static double sheet_uniform(uint64_t *s) {
  return (double)(sheet_rng(s) >> 11) * (1.0 / 9007199254740992.0);
}

/* The default options' features of n points xyz (malloc'ed flags). */
/* the defaults' flags; *z (if z) the score, z, to free */
static uint8_t *detect_defaults_z(double *xyz, size_t n, double **z) {
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  c.point_count = n;
  c.xyz = xyz;
  uint8_t *feat = malloc(n);
  double *score = malloc(n * sizeof(double));
  bsurf_feature_options o = bsurf_feature_options_default();
  detect(&c, &o, o.normals.k, feat, score);
  if (z)
    *z = score;
  else
    free(score);
  return feat;
}

static uint8_t *detect_defaults(double *xyz, size_t n) {
  return detect_defaults_z(xyz, n, NULL);
}

static void test_parallel_sheets(void **state) {
  (void)state;
  const size_t na = 10000, nb = 2500, n = na + nb;
  double *xyz = malloc(3 * n * sizeof(double));
  uint64_t r = 0x9e3779b97f4a7c15ull;
  for (size_t i = 0; i < n; i++) {
    const double side = i < na ? 100 : 50;
    xyz[3 * i] = side * sheet_uniform(&r);
    xyz[3 * i + 1] = side * sheet_uniform(&r);
    xyz[3 * i + 2] = (i < na ? 0 : -1.0) + 0.25 * (2 * sheet_uniform(&r) - 1);
  }
  uint8_t *feat = detect_defaults(xyz, n);
  size_t dbl = 0, dbl_flag = 0, sgl = 0, sgl_flag = 0;
  for (size_t i = 0; i < n; i++) {
    const double x = xyz[3 * i], y = xyz[3 * i + 1];
    if (x > 10 && x < 40 && y > 10 && y < 40) dbl++, dbl_flag += feat[i];
    if (x > 60 && x < 90 && y > 10 && y < 90) sgl++, sgl_flag += feat[i];
  }
  const double fd = (double)dbl_flag / (double)dbl, fs = (double)sgl_flag / (double)sgl;
  printf("parallel sheets 1 spacing apart: %.3f of the doubled part flagged, %.3f of the single\n",
         fd, fs);
  assert_true(fd < 0.15);
  assert_true(fs < 0.02);
  free(xyz);
  free(feat);
}

/* Featureless shapes: the null test flags about twice the stated
 * false-positive rate alpha of a noisy plane's interior (the null patch's own
 * situation, another noise draw; the variance test and the border test at
 * alpha each: measured 2.7% for alpha 1%, the variance test alone 1.2%)
 * and at most a few alpha of a noisy sphere (its curvature is counted in the
 * measured noise level). The plane's border is a border (test_border_thin_plate):
 * its points within the reach of the neighbourhood and the filter, (sqrt(K /
 * pi) + sqrt(k_f / pi) + 1) spacings, are left out. */
static double null_rate(bsurf_shape shape, bsurf_noise_model model, double level, double alpha) {
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, shape, 12000, BSURF_SAMPLING_RANDOM, 3, 0), BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, c.point_count, 0, &h), BSURF_OK);
  assert_int_equal(bsurf_add_noise(c.xyz, c.normals, c.point_count, model, level, h, 4), BSURF_OK);
  uint8_t *feat = malloc(c.point_count);
  double *score = malloc(c.point_count * sizeof(double));
  bsurf_feature_options o = bsurf_feature_options_default();
  o.method = BSURF_FEATURES_VARIANCE;
  o.false_positive_rate = alpha;
  detect(&c, &o, o.normals.k, feat, score);
  const double a = sqrt(4.0 / (double)c.point_count); /* the plane [-1, 1]^2's spacing */
  const double pi = 3.14159265358979323846, kf = o.normals.k / 2;
  const double edge = 1 - (sqrt(o.normals.k / pi) + sqrt(kf / pi) + 1) * a;
  size_t count = 0, m = 0;
  for (size_t i = 0; i < c.point_count; i++) {
    if (shape == BSURF_SHAPE_PLANE && (fabs(c.xyz[3 * i]) > edge || fabs(c.xyz[3 * i + 1]) > edge))
      continue;
    m++;
    count += feat[i];
  }
  double rate = (double)count / (double)m;
  free(feat);
  free(score);
  bsurf_cloud_free(&c);
  return rate;
}

static void test_null_featureless(void **state) {
  (void)state;
  for (int a = 0; a < 2; a++) {
    const double alpha = a ? 0.05 : 0.01;
    double plane = null_rate(BSURF_SHAPE_PLANE, BSURF_NOISE_GAUSSIAN, 0.3, alpha);
    double sphere = null_rate(BSURF_SHAPE_SPHERE, BSURF_NOISE_UNIFORM, 0.5, alpha);
    printf("alpha %.2f: plane %.4f sphere %.4f flagged\n", alpha, plane, sphere);
    /* two tests at alpha each: their union flags up to 2 alpha of a flat area */
    assert_true(plane >= alpha / 4 && plane <= 2.5 * 2 * alpha);
    assert_true(sphere <= 2.5 * alpha);
  }
}

/* A thin plate without its side walls: two sheets of 60 x 60 spacings
 * (3,600 random points each), 0.6 spacings apart, uniform noise 0.25
 * spacings (the development set's plate_thin_u0.25 in small). Every
 * neighbourhood holds both sheets; the variance test sees nothing at the
 * rim (the PCA normal of the pair is the mid-plane's on both sides: F1 0.00
 * on the development set), the border test (the centroid's tangential
 * offset, features.c) does. Measured: 58.2% of the points within
 * 2 spacings of the rim flagged, 1.3% of those farther than the
 * neighbourhood's and the filter's reach (7 spacings). */
static void test_border_thin_plate(void **state) {
  (void)state;
  const size_t per = 3600, n = 2 * per;
  double *xyz = malloc(3 * n * sizeof(double));
  uint64_t r = 0x2545f4914f6cdd1dull;
  for (size_t i = 0; i < n; i++) {
    xyz[3 * i] = 60 * sheet_uniform(&r);
    xyz[3 * i + 1] = 60 * sheet_uniform(&r);
    xyz[3 * i + 2] = (i < per ? 0 : 0.6) + 0.25 * (2 * sheet_uniform(&r) - 1);
  }
  double *z;
  uint8_t *feat = detect_defaults_z(xyz, n, &z);
  size_t rim = 0, rim_flag = 0, rim_border = 0, in = 0, in_flag = 0;
  for (size_t i = 0; i < n; i++) {
    const double x = xyz[3 * i], y = xyz[3 * i + 1];
    const double d = fmin(fmin(x, 60 - x), fmin(y, 60 - y));
    if (d < 2) rim++, rim_flag += feat[i], rim_border += feat[i] && !(z[i] > last_threshold);
    if (d > 7) in++, in_flag += feat[i];
  }
  const double fr = (double)rim_flag / (double)rim, fi = (double)in_flag / (double)in;
  printf("thin plate: %.3f of the rim band flagged, %.4f of the interior; %zu by the border "
         "test alone\n",
         fr, fi, last_border_points);
  assert_true(fr > 0.5);
  /* the rim is the border test's: the variance test sees nothing there */
  assert_int_equal(rim_border, rim_flag);
  assert_true(last_border_points >= rim_flag);
  assert_true(fi < 0.025);
  free(z);
  free(xyz);
  free(feat);
}

/* Differential: the running sums give the same a/c as a PCA from scratch of
 * every prefix of the neighbour list. */
static void test_incremental_pca(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 3000, BSURF_SAMPLING_RANDOM, 5, 2.0),
                   BSURF_OK);
  const int k = 60;
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, k, 1, NULL, NULL), BSURF_OK);
  double ratio[60];
  for (size_t i = 0; i < c.point_count; i += 37) {
    const uint32_t *idx = &nb.idx[i * (size_t)k];
    bsurf_incremental_pca_ratios(c.xyz, idx, k, ratio);
    for (int m = 3; m <= k; m++) {
      bsurf_frame f;
      bsurf_local_frame(c.xyz, idx, m, BSURF_PCA_CENTROID, &f);
      double ref = f.eigenvalues[2] > 0 ? f.eigenvalues[0] / f.eigenvalues[2] : 0;
      if (ref < 0) ref = 0;
      assert_true(fabs(ratio[m - 1] - ref) <= 1e-9 + 1e-7 * ref);
    }
  }
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* 1 and 2 threads give identical outputs (both methods). */
static void test_threads(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 5000, BSURF_SAMPLING_RANDOM, 9, 2.0),
                   BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, c.point_count, 0, &h), BSURF_OK);
  assert_int_equal(
      bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_GAUSSIAN, 0.3, h, 2), BSURF_OK);
  size_t n = c.point_count;
  uint8_t *f1 = malloc(n), *f2 = malloc(n);
  double *s1 = malloc(n * sizeof(double)), *s2 = malloc(n * sizeof(double));
  for (int m = 0; m < 2; m++) {
    bsurf_feature_options o = bsurf_feature_options_default();
    o.method = (bsurf_feature_method)m;
    o.normals.bootstrap = 10;
    int k = m == 0 ? o.k_max : o.normals.k;
    o.threads = 1;
    detect(&c, &o, k, f1, s1);
    o.threads = 2;
    detect(&c, &o, k, f2, s2);
    assert_memory_equal(f1, f2, n);
    assert_memory_equal(s1, s2, n * sizeof(double));
  }
  free(f1);
  free(f2);
  free(s1);
  free(s2);
  bsurf_cloud_free(&c);
}

/* A log-normal bulk (median 0.001) with a 5% tail at 0.05: both rules put
 * the threshold between the bulk's 99th percentile and the tail. */
static void test_tail_threshold(void **state) {
  (void)state;
  const size_t n = 10000, tail = 500;
  double *v = malloc(n * sizeof(double));
  bsurf_rng r;
  bsurf_rng_init(&r, 11, 0, 0);
  for (size_t i = 0; i < n; i++)
    v[i] =
        i < tail ? 0.05 * exp(0.2 * bsurf_rng_normal(&r)) : 0.001 * exp(0.3 * bsurf_rng_normal(&r));
  for (int rule = 0; rule < 2; rule++) {
    double t;
    assert_int_equal(bsurf_tail_threshold(v, n, (bsurf_tail_rule)rule, &t), BSURF_OK);
    size_t above_bulk = 0, above_tail = 0;
    for (size_t i = 0; i < n; i++) {
      if (i < tail)
        above_tail += v[i] > t;
      else
        above_bulk += v[i] > t;
    }
    assert_true(above_tail >= tail * 99 / 100);
    assert_true(above_bulk <= (n - tail) / 100);
  }
  assert_int_equal(bsurf_tail_threshold(v, 1, BSURF_TAIL_OTSU, &(double){0}),
                   BSURF_ERR_TOO_FEW_POINTS);
  v[3] = NAN;
  assert_int_equal(bsurf_tail_threshold(v, n, BSURF_TAIL_MAD, &(double){0}),
                   BSURF_ERR_INVALID_VALUE);
  free(v);
}

static void test_eval_features(void **state) {
  (void)state;
  const uint8_t r[6] = {1, 1, 0, 0, 1, 0}, t[6] = {1, 0, 1, 0, 1, 0};
  bsurf_feature_stats s;
  assert_int_equal(bsurf_eval_features(r, t, 6, &s), BSURF_OK);
  assert_int_equal(s.true_pos, 2);
  assert_int_equal(s.false_pos, 1);
  assert_int_equal(s.false_neg, 1);
  assert_int_equal(s.true_neg, 2);
  assert_true(fabs(s.precision - 2.0 / 3) < 1e-15);
  assert_true(fabs(s.recall - 2.0 / 3) < 1e-15);
  assert_true(fabs(s.f1 - 2.0 / 3) < 1e-15);
  const uint8_t z[2] = {0, 0};
  assert_int_equal(bsurf_eval_features(z, z, 2, &s), BSURF_OK);
  assert_true(isnan(s.precision) && isnan(s.recall) && isnan(s.f1));
}

static void test_bad_args(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_PLANE, 500, BSURF_SAMPLING_RANDOM, 3, 0),
                   BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 20, 1, NULL, NULL), BSURF_OK);
  uint8_t f[500];
  bsurf_feature_options o = bsurf_feature_options_default();
  o.method = BSURF_FEATURES_DISTANCE;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, f, NULL, NULL),
                   BSURF_ERR_INVALID_ARG); /* k_max > nb.k */
  o.k_max = 20;
  o.k_min = 25;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, f, NULL, NULL), BSURF_ERR_INVALID_ARG);
  o.k_min = 10;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, f, NULL, NULL), BSURF_OK);
  o.method = BSURF_FEATURES_VARIANCE;
  o.normals.k = 20;
  o.normals.bootstrap = 1;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, f, NULL, NULL), BSURF_ERR_INVALID_ARG);
  o.normals.bootstrap = 10;
  o.feature_angle = 180;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, f, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_non_null(strstr(bsurf_last_message(), "feature_angle = 180"));
  o.feature_angle = -1;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, f, NULL, NULL), BSURF_ERR_INVALID_ARG);
  o.feature_angle = 90;
  o.variance_k_max = -3;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, f, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_non_null(strstr(bsurf_last_message(), "variance_k_max = -3"));
  o.variance_k_max = 0;
  o.quadric_angle = 180;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, f, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_non_null(strstr(bsurf_last_message(), "quadric_angle = 180"));
  o.quadric_angle = NAN;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, f, NULL, NULL), BSURF_ERR_INVALID_ARG);
  /* refused inside the null test (after the report was started): the
   * report stays cleared, its NAN fields NAN (it once held the unset
   * result's bytes) */
  o.quadric_angle = 45;
  o.feature_angle = 0;
  o.false_positive_rate = 0;
  bsurf_feature_report rep;
  memset(&rep, 0x5a, sizeof rep);
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, f, NULL, &rep), BSURF_ERR_INVALID_ARG);
  assert_non_null(strstr(bsurf_last_message(), "false_positive_rate = 0"));
  assert_true(isnan(rep.noise_level) && isnan(rep.border_threshold) &&
              isnan(rep.quadric_threshold) && isnan(rep.quadric_power) &&
              isnan(rep.quadric_noise) && isnan(rep.ratio_threshold_kmin));
  assert_int_equal(rep.feature_points, 0);
  assert_int_equal(rep.border_points, 0);
  assert_int_equal(rep.quadric_cleared, 0);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_plane_no_features),
      cmocka_unit_test(test_cube_edges_distance),
      cmocka_unit_test(test_cube_edges_variance),
      cmocka_unit_test(test_incremental_pca),
      cmocka_unit_test(test_threads),
      cmocka_unit_test(test_tail_threshold),
      cmocka_unit_test(test_eval_features),
      cmocka_unit_test(test_bad_args),
      cmocka_unit_test(test_distance_auto_rule),
      cmocka_unit_test(test_cube_null_gaussian),
      cmocka_unit_test(test_null_featureless),
      cmocka_unit_test(test_cube_defaults),
      cmocka_unit_test(test_parallel_sheets),
      cmocka_unit_test(test_border_thin_plate),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
