/* The library's contract at its boundary (include/bootsurf.h, "Ownership and
 * lifetimes"): who owns what, repeated frees, field pointers after another
 * field is added, reading into a cloud that held data, and bad input to
 * every public computation -- NULL, zero counts, NaN, k > N, unknown option
 * values -- each a status and a printable message naming the parameter,
 * never a crash. Only the public header is used, as a program would. */
// clang-format off
/* cmocka.h needs these first */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
// clang-format on

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"
#include "test_util.h"

static bsurf_cloud sphere(size_t n) {
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, n, BSURF_SAMPLING_REGULAR, 1, 2),
                   BSURF_OK);
  return c;
}

static void test_version(void **state) {
  (void)state;
  assert_int_equal(bsurf_version(), BSURF_VERSION_NUMBER);
  char v[32];
  snprintf(v, sizeof v, "%d.%d.%d", BSURF_VERSION_MAJOR, BSURF_VERSION_MINOR, BSURF_VERSION_PATCH);
  assert_string_equal(bsurf_version_string(), v);
  assert_string_equal(bsurf_version_string(), BSURF_VERSION_STRING);
}

static void test_frees_are_idempotent(void **state) {
  (void)state;
  bsurf_cloud c = sphere(200);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 8, 1, NULL, NULL), BSURF_OK);
  bsurf_neighbors_free(&nb);
  bsurf_neighbors_free(&nb); /* twice: empty after the first */
  assert_null(nb.idx);
  bsurf_neighbors_free(NULL);
  bsurf_cloud_free(&c);
  bsurf_cloud_free(&c);
  assert_int_equal(c.point_count, 0);
  assert_null(c.xyz);
  bsurf_cloud_free(NULL);
  bsurf_knn_free(NULL);
  bsurf_mesh_index_free(NULL);
}

static void test_field_values_stay_put(void **state) {
  (void)state;
  bsurf_cloud c = sphere(100);
  size_t before = c.field_count;
  bsurf_field *f = bsurf_cloud_add_field(&c, "first", BSURF_FLOAT32);
  assert_non_null(f);
  double *values = f->values;
  values[7] = 3.5;
  /* many more fields: the table of fields is reallocated, the values are not */
  char name[32];
  for (int i = 0; i < 40; i++) {
    snprintf(name, sizeof name, "extra%d", i);
    assert_non_null(bsurf_cloud_add_field(&c, name, BSURF_FLOAT64));
  }
  bsurf_field *again = bsurf_cloud_field(&c, "first");
  assert_non_null(again);
  assert_ptr_equal(again->values, values);
  assert_true(values[7] == 3.5);
  /* removing another field leaves it too */
  bsurf_cloud_remove_field(&c, "extra0");
  assert_ptr_equal(bsurf_cloud_field(&c, "first")->values, values);
  assert_int_equal(c.field_count, before + 40);
  /* adding an existing name keeps its values, takes the type */
  assert_ptr_equal(bsurf_cloud_add_field(&c, "first", BSURF_UINT8)->values, values);
  /* a name too long for BSURF_FIELD_NAME_MAX */
  char longname[BSURF_FIELD_NAME_MAX + 8];
  memset(longname, 'a', sizeof longname - 1);
  longname[sizeof longname - 1] = '\0';
  assert_null(bsurf_cloud_add_field(&c, longname, BSURF_FLOAT32));
  /* an empty cloud: fields without values */
  bsurf_cloud e;
  bsurf_cloud_init(&e);
  bsurf_field *ef = bsurf_cloud_add_field(&e, "x", BSURF_FLOAT32);
  assert_non_null(ef);
  assert_null(ef->values);
  bsurf_cloud_remove_field(&e, "absent");
  bsurf_cloud_free(&e);
  bsurf_cloud_free(&c);
}

static void test_read_into_used_cloud(void **state) {
  (void)state;
  char path[512];
  const char *t = getenv("BSURF_TMP");
  snprintf(path, sizeof path, "%s/test_api_cloud.ply", t ? t : ".");
  bsurf_cloud c = sphere(300);
  bsurf_failure err;
  assert_int_equal(bsurf_write(path, &c, NULL, &err), BSURF_OK);
  /* the documented way: free, then read into the same struct */
  bsurf_cloud_free(&c);
  bsurf_cloud r = sphere(50);
  bsurf_cloud_free(&r);
  assert_int_equal(bsurf_read(path, &r, &err), BSURF_OK);
  assert_int_equal(r.point_count, 300);
  /* a failed read leaves the cloud empty (and freeing it is harmless) */
  bsurf_cloud_free(&r);
  assert_int_not_equal(bsurf_read("/nonexistent/x.ply", &r, &err), BSURF_OK);
  assert_int_equal(r.point_count, 0);
  assert_null(r.xyz);
  assert_true(strstr(bsurf_last_message(), "cannot open") != NULL);
  assert_string_equal(err.message, bsurf_last_message());
  bsurf_cloud_free(&r);
  /* NULL arguments */
  assert_int_equal(bsurf_read(NULL, &r, &err), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_read(path, NULL, &err), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_read(path, &r, NULL), BSURF_OK); /* err is optional */
  bsurf_cloud_free(&r);
  remove(path);
}

static void test_neighbors_bad_input(void **state) {
  (void)state;
  bsurf_cloud c = sphere(200);
  bsurf_neighbors nb;
  assert_invalid(bsurf_neighbors_build(NULL, c.xyz, c.point_count, 8, 1, NULL, NULL),
                 "bsurf_neighbors_build", "nb is NULL");
  assert_invalid(bsurf_neighbors_build(&nb, NULL, c.point_count, 8, 1, NULL, NULL),
                 "bsurf_neighbors_build", "xyz is NULL");
  assert_invalid(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 1, 1, NULL, NULL),
                 "bsurf_neighbors_build", "k = 1");
  /* k > N, zero points */
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, 5, 8, 1, NULL, NULL),
                   BSURF_ERR_TOO_FEW_POINTS);
  assert_non_null(strstr(bsurf_last_message(), "k = 8 exceeds the 5 points"));
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, 0, 8, 1, NULL, NULL),
                   BSURF_ERR_TOO_FEW_POINTS);
  assert_null(nb.idx);
  /* NaN coordinates */
  c.xyz[3 * 17 + 1] = NAN;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 8, 1, NULL, NULL),
                   BSURF_ERR_INVALID_VALUE);
  assert_non_null(strstr(bsurf_last_message(), "point 17"));
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, c.point_count, 1, &h), BSURF_ERR_INVALID_VALUE);
  c.xyz[3 * 17 + 1] = 0;
  assert_invalid(bsurf_mean_spacing(c.xyz, c.point_count, 1, NULL), "bsurf_mean_spacing_progress",
                 "h is NULL");
  assert_int_equal(bsurf_mean_spacing(c.xyz, 1, 1, &h), BSURF_ERR_TOO_FEW_POINTS);

  bsurf_knn_index *ix = NULL;
  assert_invalid(bsurf_knn_build(NULL, c.xyz, c.point_count), "bsurf_knn_build", "index is NULL");
  assert_int_equal(bsurf_knn_build(&ix, c.xyz, 0), BSURF_ERR_TOO_FEW_POINTS);
  assert_int_equal(bsurf_knn_build(&ix, c.xyz, c.point_count), BSURF_OK);
  uint32_t idx[8];
  double q[3] = {0, 0, 1};
  assert_invalid(bsurf_knn_query(ix, q, 201, idx, NULL), "bsurf_knn_query", "k = 201");
  assert_invalid(bsurf_knn_query(ix, q, 0, idx, NULL), "bsurf_knn_query", "k = 0");
  assert_invalid(bsurf_knn_query(ix, q, 4, NULL, NULL), "bsurf_knn_query", "is NULL");
  assert_invalid(bsurf_knn_all(ix, 4, 1, NULL, NULL, NULL, NULL), "bsurf_knn_all", "idx is NULL");
  assert_int_equal(bsurf_knn_query(ix, q, 4, idx, NULL), BSURF_OK);
  bsurf_knn_free(ix);
  assert_invalid(bsurf_knn_all_brute(c.xyz, 10, 11, idx, NULL), "bsurf_knn_all_brute", "k = 11");
  bsurf_cloud_free(&c);
}

typedef struct fixture {
  bsurf_cloud c;
  bsurf_neighbors nb;
  double *a, *b;
} fixture;

static int setup(void **state) {
  fixture *f = calloc(1, sizeof *f);
  f->c = sphere(300);
  if (bsurf_neighbors_build(&f->nb, f->c.xyz, f->c.point_count, 30, 1, NULL, NULL) != BSURF_OK)
    return 1;
  f->a = calloc(f->c.point_count * 3, sizeof(double));
  f->b = calloc(f->c.point_count * 3, sizeof(double));
  *state = f;
  return 0;
}

static int teardown(void **state) {
  fixture *f = *state;
  bsurf_neighbors_free(&f->nb);
  bsurf_cloud_free(&f->c);
  free(f->a);
  free(f->b);
  free(f);
  return 0;
}

static void test_error_bad_input(void **state) {
  fixture *f = *state;
  bsurf_error_options o = bsurf_error_options_default();
  o.k = 20;
  o.bootstrap = 4;
  bsurf_error_fields out = {0};
  out.err_632 = f->a;
  bsurf_neighbors empty = {0};
  assert_invalid(bsurf_estimate_error(NULL, &f->nb, NULL, &o, &out, NULL), "bsurf_estimate_error",
                 "xyz is NULL");
  assert_invalid(bsurf_estimate_error(f->c.xyz, &f->nb, NULL, &o, NULL, NULL),
                 "bsurf_estimate_error", "out is NULL");
  assert_invalid(bsurf_estimate_error(f->c.xyz, NULL, NULL, &o, &out, NULL), "error options",
                 "nb is NULL");
  assert_invalid(bsurf_estimate_error(f->c.xyz, &empty, NULL, &o, &out, NULL), "error options",
                 "nb is empty");
  bsurf_error_options bad = o;
  bad.k = 31; /* more than the neighbourhoods hold */
  assert_invalid(bsurf_estimate_error(f->c.xyz, &f->nb, NULL, &bad, &out, NULL), "error options",
                 "k = 31 exceeds the neighbourhoods' nb->k = 30");
  bad = o;
  bad.degree = 5;
  assert_invalid(bsurf_estimate_error(f->c.xyz, &f->nb, NULL, &bad, &out, NULL), "error options",
                 "degree = 5: must be in [1, 4]");
  bad = o;
  bad.bootstrap = -1;
  assert_invalid(bsurf_estimate_error(f->c.xyz, &f->nb, NULL, &bad, &out, NULL), "error options",
                 "bootstrap (B) = -1");
  bad = o;
  bad.gamma = (bsurf_gamma_mode)7;
  assert_invalid(bsurf_estimate_error(f->c.xyz, &f->nb, NULL, &bad, &out, NULL), "error options",
                 "gamma = 7");
  bad = o;
  bad.pca_center = (bsurf_pca_center)9;
  assert_invalid(bsurf_estimate_error(f->c.xyz, &f->nb, NULL, &bad, &out, NULL), "error options",
                 "pca_center = 9");
  bad = o;
  bad.k = 8; /* fewer than a cubic's 10 coefficients */
  assert_int_equal(bsurf_estimate_error(f->c.xyz, &f->nb, NULL, &bad, &out, NULL),
                   BSURF_ERR_TOO_FEW_POINTS);
  assert_non_null(strstr(bsurf_last_message(), "too small for degree 3"));
  /* all outputs NULL is fine: nothing is written */
  bsurf_error_fields none = {0};
  assert_int_equal(bsurf_estimate_error(f->c.xyz, &f->nb, NULL, &o, &none, NULL), BSURF_OK);
  /* B = 0: no replicates, no crash */
  bad = o;
  bad.bootstrap = 0;
  assert_int_equal(bsurf_estimate_error(f->c.xyz, &f->nb, NULL, &bad, &out, NULL), BSURF_OK);
  /* NULL options: the defaults (K = 50 > nb->k = 30: a message, no crash) */
  assert_invalid(bsurf_estimate_error(f->c.xyz, &f->nb, NULL, NULL, &out, NULL), "error options",
                 "k = 50");
}

/* the two K selections: every refusal names its argument */
static void test_select_bad_input(void **state) {
  fixture *f = *state;
  bsurf_normal_options o = bsurf_normal_options_default();
  o.bootstrap = 4;
  int ks[3] = {10, 20, 30}, down[3] = {10, 30, 20}, big[2] = {10, 40};
  bsurf_normal_select_fields sel;
  memset(&sel, 0, sizeof sel);
  sel.normals = f->b;
  assert_invalid(bsurf_select_normals_k(NULL, &f->nb, f->a, &o, ks, 3, &sel, NULL),
                 "bsurf_select_normals_k", "must not be NULL");
  assert_invalid(bsurf_select_normals_k(f->c.xyz, &f->nb, f->a, &o, ks, 0, &sel, NULL),
                 "bsurf_select_normals_k", "nk = 0");
  assert_invalid(bsurf_select_normals_k(f->c.xyz, &f->nb, f->a, &o, down, 3, &sel, NULL),
                 "bsurf_select_normals_k", "ks[2] = 20 must be above ks[1] = 30");
  assert_invalid(bsurf_select_normals_k(f->c.xyz, &f->nb, f->a, &o, big, 2, &sel, NULL),
                 "bsurf_select_normals_k", "ks[1] = 40 must be at most the neighbourhoods' k = 30");
  bsurf_normal_options poly = o;
  poly.fit = BSURF_NORMAL_POLY;
  assert_invalid(bsurf_select_normals_k(f->c.xyz, &f->nb, f->a, &poly, ks, 3, &sel, NULL),
                 "bsurf_select_normals_k", "takes PCA normals");
  bsurf_kselect_options ko = bsurf_kselect_options_default();
  ko.ks = ks;
  ko.nk = 3;
  bsurf_kselect_fields kf = {f->b, NULL, NULL, NULL, NULL, NULL};
  assert_invalid(bsurf_select_k(f->c.xyz, &f->nb, NULL, &kf, NULL), "bsurf_select_k",
                 "must not be NULL");
  bsurf_kselect_options bad = ko;
  bad.noise_k = 4;
  assert_invalid(bsurf_select_k(f->c.xyz, &f->nb, &bad, &kf, NULL), "bsurf_select_k",
                 "noise_k = 4");
  bad = ko;
  bad.ks = down;
  assert_invalid(bsurf_select_k(f->c.xyz, &f->nb, &bad, &kf, NULL), "bsurf_select_k", "ks[2] = 20");
  bad = ko;
  bad.nk = 0;
  assert_invalid(bsurf_select_k(f->c.xyz, &f->nb, &bad, &kf, NULL), "bsurf_select_k", "nk = 0");
}

static void test_normals_bad_input(void **state) {
  fixture *f = *state;
  bsurf_normal_options o = bsurf_normal_options_default();
  o.k = 20;
  o.bootstrap = 4;
  bsurf_normal_fields out = {f->a, NULL, NULL};
  assert_invalid(bsurf_estimate_normals(NULL, &f->nb, NULL, &o, &out, NULL),
                 "bsurf_estimate_normals", "xyz is NULL");
  assert_invalid(bsurf_estimate_normals(f->c.xyz, NULL, NULL, &o, &out, NULL),
                 "bsurf_estimate_normals", "nb is NULL");
  assert_invalid(bsurf_estimate_normals(f->c.xyz, &f->nb, NULL, &o, NULL, NULL),
                 "bsurf_estimate_normals", "out is NULL");
  bsurf_normal_options bad = o;
  bad.fit = (bsurf_normal_fit)3;
  assert_invalid(bsurf_estimate_normals(f->c.xyz, &f->nb, NULL, &bad, &out, NULL),
                 "bsurf_estimate_normals", "fit = 3");
  bad = o;
  bad.k = 40;
  assert_invalid(bsurf_estimate_normals(f->c.xyz, &f->nb, NULL, &bad, &out, NULL),
                 "bsurf_estimate_normals", "k = 40");
  bad = o;
  bad.fit = BSURF_NORMAL_POLY;
  bad.degree = 0;
  assert_invalid(bsurf_estimate_normals(f->c.xyz, &f->nb, NULL, &bad, &out, NULL),
                 "bsurf_estimate_normals", "degree = 0");
  assert_int_equal(bsurf_estimate_normals(f->c.xyz, &f->nb, NULL, &o, &out, NULL), BSURF_OK);
  /* the filter and the orientation */
  assert_invalid(bsurf_smooth_normals(f->c.xyz, &f->nb, 10, f->a, NULL, 2, 1.5, 0.1, INFINITY, 1),
                 "bsurf_smooth_normals", "alpha = 1.5");
  assert_invalid(bsurf_smooth_normals(f->c.xyz, &f->nb, 10, f->a, NULL, 2, 0.5, NAN, INFINITY, 1),
                 "bsurf_smooth_normals", "sigma_d = nan");
  assert_invalid(bsurf_smooth_normals(f->c.xyz, &f->nb, 31, f->a, NULL, 2, 0.5, 0.1, INFINITY, 1),
                 "bsurf_smooth_normals", "k = 31");
  assert_invalid(bsurf_orient_normals(f->c.xyz, &f->nb, 31, f->a), "bsurf_orient_normals",
                 "k = 31");
  assert_invalid(bsurf_orient_normals(f->c.xyz, &f->nb, 10, NULL), "bsurf_orient_normals",
                 "is NULL");
}

static void test_smooth_bad_input(void **state) {
  fixture *f = *state;
  bsurf_smooth_options o = bsurf_smooth_options_default();
  o.error.k = 20;
  o.error.bootstrap = 4;
  assert_invalid(bsurf_smooth(f->c.xyz, &f->nb, &o, f->c.xyz, NULL, NULL), "bsurf_smooth",
                 "out_xyz is xyz");
  assert_invalid(bsurf_smooth(NULL, &f->nb, &o, f->a, NULL, NULL), "bsurf_smooth", "xyz is NULL");
  bsurf_smooth_options bad = o;
  bad.method = (bsurf_smooth_method)5;
  assert_invalid(bsurf_smooth(f->c.xyz, &f->nb, &bad, f->a, NULL, NULL), "bsurf_smooth",
                 "method = 5");
  bad = o;
  bad.h1 = NAN;
  assert_invalid(bsurf_smooth(f->c.xyz, &f->nb, &bad, f->a, NULL, NULL), "bsurf_smooth",
                 "h1 = nan");
  bad = o;
  bad.estimator = (bsurf_smooth_estimator)4;
  assert_invalid(bsurf_smooth(f->c.xyz, &f->nb, &bad, f->a, NULL, NULL), "bsurf_smooth",
                 "estimator = 4");
  bad = o;
  bad.method = BSURF_SMOOTH_MULTIPASS;
  bad.k_min = 25;
  assert_invalid(bsurf_smooth(f->c.xyz, &f->nb, &bad, f->a, NULL, NULL), "bsurf_smooth",
                 "k_min = 25");
  bad = o;
  bad.error.k = 60;
  assert_invalid(bsurf_smooth(f->c.xyz, &f->nb, &bad, f->a, NULL, NULL), "error options", "k = 60");
  assert_int_equal(bsurf_smooth(f->c.xyz, &f->nb, &o, f->a, NULL, NULL), BSURF_OK);
}

static void test_features_bad_input(void **state) {
  fixture *f = *state;
  uint8_t *feat = calloc(f->c.point_count, 1);
  bsurf_feature_options o = bsurf_feature_options_default();
  o.method = BSURF_FEATURES_DISTANCE; /* its k_max is checked below */
  o.k_max = 30;
  assert_invalid(bsurf_detect_features(NULL, &f->nb, &o, feat, NULL, NULL), "bsurf_detect_features",
                 "xyz is NULL");
  assert_invalid(bsurf_detect_features(f->c.xyz, &f->nb, &o, NULL, NULL, NULL),
                 "bsurf_detect_features", "feature is NULL");
  bsurf_feature_options bad = o;
  bad.method = (bsurf_feature_method)2;
  assert_invalid(bsurf_detect_features(f->c.xyz, &f->nb, &bad, feat, NULL, NULL),
                 "bsurf_detect_features", "method = 2");
  bad = o;
  bad.k_max = 60; /* k > the neighbourhoods */
  assert_invalid(bsurf_detect_features(f->c.xyz, &f->nb, &bad, feat, NULL, NULL), "feature options",
                 "k_max = 60");
  bad = o;
  bad.alpha = NAN;
  assert_invalid(bsurf_detect_features(f->c.xyz, &f->nb, &bad, feat, NULL, NULL), "feature options",
                 "alpha = nan");
  bad = o;
  bad.method = BSURF_FEATURES_VARIANCE;
  bad.normals.bootstrap = 1;
  assert_invalid(bsurf_detect_features(f->c.xyz, &f->nb, &bad, feat, NULL, NULL),
                 "bsurf_detect_features", "normals.bootstrap = 1");
  bad = o;
  bad.tail_rule = (bsurf_tail_rule)3;
  assert_invalid(bsurf_detect_features(f->c.xyz, &f->nb, &bad, feat, NULL, NULL),
                 "bsurf_detect_features", "tail_rule = 3");
  double v[3] = {1, 2, 3}, t;
  assert_invalid(bsurf_tail_threshold(v, 3, (bsurf_tail_rule)5, &t), "bsurf_tail_threshold",
                 "rule = 5");
  assert_int_equal(bsurf_tail_threshold(v, 1, BSURF_TAIL_OTSU, &t), BSURF_ERR_TOO_FEW_POINTS);
  v[1] = NAN;
  assert_int_equal(bsurf_tail_threshold(v, 3, BSURF_TAIL_OTSU, &t), BSURF_ERR_INVALID_VALUE);
  free(feat);
}

static void test_synth_eval_bad_input(void **state) {
  fixture *f = *state;
  bsurf_cloud c;
  assert_invalid(bsurf_generate(&c, (bsurf_shape)9, 100, BSURF_SAMPLING_REGULAR, 1, 2),
                 "bsurf_generate", "shape = 9");
  assert_invalid(bsurf_generate(&c, BSURF_SHAPE_CUBE, 0, BSURF_SAMPLING_REGULAR, 1, 2),
                 "bsurf_generate", "n = 0");
  assert_invalid(bsurf_generate(&c, BSURF_SHAPE_CUBE, 10, (bsurf_sampling)4, 1, 2),
                 "bsurf_generate", "sampling = 4");
  assert_invalid(bsurf_generate(&c, BSURF_SHAPE_CUBE, 10, BSURF_SAMPLING_RANDOM, 1, NAN),
                 "bsurf_generate", "feature_width = nan");
  assert_invalid(bsurf_generate(NULL, BSURF_SHAPE_CUBE, 10, BSURF_SAMPLING_RANDOM, 1, 2),
                 "bsurf_generate", "cloud is NULL");
  assert_invalid(bsurf_add_noise(f->a, f->c.normals, 10, BSURF_NOISE_GAUSSIAN, NAN, 1, 1),
                 "bsurf_add_noise", "level = nan");
  assert_invalid(bsurf_add_noise(f->a, f->c.normals, 10, (bsurf_noise_model)3, 1, 1, 1),
                 "bsurf_add_noise", "model = 3");
  assert_int_equal(bsurf_add_noise(NULL, NULL, 0, BSURF_NOISE_GAUSSIAN, 1, 1, 1),
                   BSURF_OK); /* zero points */
  bsurf_angle_stats as;
  assert_int_equal(bsurf_angle_stats_compute(NULL, NULL, 0, 0, &as), BSURF_OK);
  assert_int_equal(as.count, 0);
  assert_true(isnan(as.mean_rad));
  assert_invalid(bsurf_angle_stats_compute(NULL, NULL, 0, 3, &as), "bsurf_angle_stats_compute",
                 "angles is NULL");
  assert_invalid(bsurf_quantile_split(f->a, 3, 1.5, NULL, NULL, NULL, NULL), "bsurf_quantile_split",
                 "q = 1.5");
  assert_invalid(bsurf_quantile_split(f->a, 3, NAN, NULL, NULL, NULL, NULL), "bsurf_quantile_split",
                 "q = nan");
  bsurf_feature_stats fs;
  assert_invalid(bsurf_eval_features(NULL, NULL, 3, &fs), "bsurf_eval_features", "is NULL");
  bsurf_distance_stats ds;
  assert_int_equal(bsurf_distance_stats_compute(NULL, NULL, 0, 0, &ds), BSURF_OK);
  bsurf_true_surface s = {0};
  s.kind = (bsurf_surface_kind)8;
  assert_invalid(bsurf_position_errors(f->c.xyz, 3, &s, 1, f->a, NULL, NULL),
                 "bsurf_position_errors", "kind = 8");
  s.kind = BSURF_SURFACE_MESH;
  assert_invalid(bsurf_position_errors(f->c.xyz, 3, &s, 1, f->a, NULL, NULL),
                 "bsurf_position_errors", "surface->mesh is NULL");
  uint32_t m[3];
  assert_invalid(bsurf_match_nearest(f->c.xyz, 0, f->c.xyz, 3, 1, m), "bsurf_match_nearest",
                 "truth_count = 0");
  bsurf_mesh_index *mi;
  assert_invalid(bsurf_mesh_index_build(&mi, &f->c), "bsurf_mesh_index_build", "no face");
  bsurf_sample_options so = bsurf_sample_options_default();
  so.sharp_angle_deg = 200;
  bsurf_cloud out;
  assert_invalid(bsurf_sample_mesh(&out, &f->c, &so, NULL), "bsurf_sample_mesh",
                 "sharp_angle_deg = 200");
  double nrm[3];
  assert_invalid(bsurf_mesh_vertex_normals(&f->c, nrm, NULL), "mesh", "no face");
}

static void test_render_bad_input(void **state) {
  fixture *f = *state;
  uint8_t *rgb = malloc(64 * 64 * 3);
  bsurf_render_options ro = bsurf_render_options_default();
  ro.width = ro.height = 64;
  ro.views = 3;
  assert_invalid(bsurf_render(rgb, f->c.xyz, NULL, f->c.point_count, NULL, &ro, NULL),
                 "bsurf_render", "views = 3");
  ro.views = 1;
  ro.point_size = NAN;
  assert_invalid(bsurf_render(rgb, f->c.xyz, NULL, f->c.point_count, NULL, &ro, NULL),
                 "bsurf_render", "point_size nan: must be from 0.05 to 50");
  ro.point_size = 2;
  ro.azimuth = INFINITY; /* the view's check (bsurf_render_options_check) */
  assert_invalid(bsurf_render(rgb, f->c.xyz, NULL, f->c.point_count, NULL, &ro, NULL),
                 "bsurf_render", "azimuth inf: must be from -360 to 360");
  ro.azimuth = bsurf_render_options_default().azimuth;
  ro.width = 8;
  assert_invalid(bsurf_render(rgb, f->c.xyz, NULL, f->c.point_count, NULL, &ro, NULL),
                 "bsurf_render", "width x height = 8 x 64");
  ro.width = 64;
  assert_int_equal(bsurf_render(rgb, NULL, NULL, 0, NULL, &ro, NULL),
                   BSURF_OK); /* no points: background */
  bsurf_histogram_options ho = bsurf_histogram_options_default();
  ho.bins = 0;
  assert_invalid(bsurf_render_histogram(rgb, f->a, 3, &ho, NULL), "bsurf_render_histogram",
                 "bins = 0");
  double lo, hi;
  assert_invalid(bsurf_render_range(NULL, 3, 1, 99, &lo, &hi), "bsurf_render_range", "is NULL");
  free(rgb);
}

/* bsurf_bounding_box: exact corners and diagonal; none: +-inf and 0 */
static void test_bounding_box(void **state) {
  (void)state;
  const double xyz[9] = {1, -2, 3, -4, 5, 0.5, 2, 0, -1};
  double lo[3], hi[3];
  const double d = bsurf_bounding_box(xyz, 3, lo, hi);
  const double want_lo[3] = {-4, -2, -1}, want_hi[3] = {2, 5, 3};
  for (int t = 0; t < 3; t++) {
    assert_true(lo[t] == want_lo[t]);
    assert_true(hi[t] == want_hi[t]);
  }
  assert_true(d == sqrt(36.0 + 49.0 + 16.0));
  assert_true(bsurf_bounding_box(xyz, 3, NULL, NULL) == d);
  assert_true(bsurf_bounding_box(NULL, 0, lo, hi) == 0.0);
  assert_true(isinf(lo[0]) && lo[0] > 0 && isinf(hi[2]) && hi[2] < 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_version),
      cmocka_unit_test(test_bounding_box),
      cmocka_unit_test(test_frees_are_idempotent),
      cmocka_unit_test(test_field_values_stay_put),
      cmocka_unit_test(test_read_into_used_cloud),
      cmocka_unit_test(test_neighbors_bad_input),
      cmocka_unit_test_setup_teardown(test_error_bad_input, setup, teardown),
      cmocka_unit_test_setup_teardown(test_normals_bad_input, setup, teardown),
      cmocka_unit_test_setup_teardown(test_select_bad_input, setup, teardown),
      cmocka_unit_test_setup_teardown(test_smooth_bad_input, setup, teardown),
      cmocka_unit_test_setup_teardown(test_features_bad_input, setup, teardown),
      cmocka_unit_test_setup_teardown(test_synth_eval_bad_input, setup, teardown),
      cmocka_unit_test_setup_teardown(test_render_bad_input, setup, teardown),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
