/* The streamed normals pass (issue 25): the all-kNN handing each row to
 * the estimate instead of storing the lists (bsurf_knn_stream,
 * bsurf_neighbors_stream, bsurf_estimate_normals_streamed) against the plain
 * path (bsurf_knn_all, bsurf_neighbors_build + bsurf_estimate_normals): the
 * same rows, the same bits of every normal and variance, h and the
 * duplicates, for any thread count; cancellation and bad input. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "algo/algo.h"
#include "bootsurf.h"
#include "search/search.h"

/* A noisy torus with some points repeated (exact duplicates: ties in the
 * search, collinear-free but repeated neighbourhoods). */
static size_t make_cloud(bsurf_cloud *c, size_t n, size_t *dups) {
  assert_int_equal(bsurf_generate(c, BSURF_SHAPE_TORUS, n, BSURF_SAMPLING_RANDOM, 5, 0), BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c->xyz, c->point_count, 2, &h), BSURF_OK);
  assert_int_equal(
      bsurf_add_noise(c->xyz, c->normals, c->point_count, BSURF_NOISE_UNIFORM, 0.5, h, 1),
      BSURF_OK);
  /* every 97th point moved onto the one before: both are duplicates */
  *dups = 0;
  for (size_t i = 97; i < c->point_count; i += 97) {
    memcpy(&c->xyz[3 * i], &c->xyz[3 * (i - 1)], 3 * sizeof(double));
    *dups += 2;
  }
  return c->point_count;
}

typedef struct row_check {
  const uint32_t *idx; /* the stored lists */
  const double *xyz;
  int k;
  unsigned char *seen;
  int bad;
} row_check;

static void check_row(void *user, int thread, uint32_t point, const uint32_t *ids,
                      const double *xyz) {
  row_check *r = user;
  if (thread < 0 || thread > 1 || r->seen[point]) r->bad = 1;
  r->seen[point] = 1; /* each point once, each write its own byte */
  if (memcmp(ids, &r->idx[(size_t)point * r->k], (size_t)r->k * sizeof *ids) != 0) r->bad = 1;
  for (int j = 0; j < r->k; j++)
    if (memcmp(&xyz[3 * j], &r->xyz[3 * (size_t)ids[j]], 3 * sizeof(double)) != 0) r->bad = 1;
}

/* The streamed rows are bsurf_knn_all's, with the cloud's coordinates;
 * nn_dist2 is the same; every point comes once. */
static void test_stream_rows(void **state) {
  (void)state;
  bsurf_cloud c;
  size_t dups;
  const size_t n = make_cloud(&c, 6000, &dups);
  const int k = 17;
  bsurf_knn_index *ix = NULL;
  assert_int_equal(bsurf_knn_build_threads(&ix, c.xyz, n, 2), BSURF_OK);
  uint32_t *idx = malloc(n * k * sizeof *idx);
  double *nn = malloc(n * sizeof *nn), *nn2 = malloc(n * sizeof *nn2);
  unsigned char *seen = malloc(n);
  assert_int_equal(bsurf_knn_all_ex(ix, k, 1, idx, NULL, nn, NULL, NULL), BSURF_OK);
  for (int threads = 1; threads <= 2; threads++) {
    memset(seen, 0, n);
    row_check r = {idx, c.xyz, k, seen, 0};
    assert_int_equal(bsurf_knn_stream(ix, k, threads, check_row, &r, nn2, NULL, NULL), BSURF_OK);
    assert_int_equal(r.bad, 0);
    for (size_t i = 0; i < n; i++)
      assert_int_equal(seen[i], 1);
    assert_memory_equal(nn, nn2, n * sizeof *nn);
  }
  free(idx);
  free(nn);
  free(nn2);
  free(seen);
  bsurf_knn_free(ix);
  bsurf_cloud_free(&c);
}

/* Every fit the streamed pass takes, bit for bit against the plain path,
 * with 1 and 2 threads; h and the duplicates as the lists give them. */
static void test_stream_normals_match(void **state) {
  (void)state;
  bsurf_cloud c;
  size_t dups;
  const size_t n = make_cloud(&c, 8000, &dups);
  const int nb_k = 24; /* lists longer than K: the first K of each are used */
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, nb_k, 2, NULL, NULL), BSURF_OK);
  size_t dup_lists = 0;
  for (size_t i = 0; i < n; i++) {
    const double *a = &c.xyz[3 * i], *b = &c.xyz[3 * (size_t)nb.idx[i * nb_k + 1]];
    dup_lists += a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
  }
  assert_int_equal(dup_lists, dups);
  double *a = malloc(4 * n * sizeof *a), *b = malloc(4 * n * sizeof *b);
  const struct {
    bsurf_normal_fit fit;
    bsurf_pca_center center;
    int k, degree, B;
  } cases[] = {{BSURF_NORMAL_PCA, BSURF_PCA_CENTROID, 20, 1, 0},
               {BSURF_NORMAL_PCA, BSURF_PCA_POINT, 24, 1, 7},
               {BSURF_NORMAL_PCA, BSURF_PCA_CENTROID, 10, 1, 12},
               {BSURF_NORMAL_POLY, BSURF_PCA_CENTROID, 20, 2, 5},
               {BSURF_NORMAL_POLY, BSURF_PCA_CENTROID, 24, 3, 0}};
  for (size_t t = 0; t < sizeof cases / sizeof cases[0]; t++) {
    bsurf_normal_options o = bsurf_normal_options_default();
    o.fit = cases[t].fit;
    o.pca_center = cases[t].center;
    o.k = cases[t].k;
    o.degree = cases[t].degree;
    o.bootstrap = cases[t].B;
    o.threads = 2;
    bsurf_normal_fields fa = {a, a + 3 * n, NULL};
    bsurf_normal_report ra, rb;
    assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, NULL, &o, &fa, &ra), BSURF_OK);
    for (int threads = 1; threads <= 2; threads++) {
      memset(b, 0xff, 4 * n * sizeof *b);
      o.threads = threads;
      bsurf_normal_fields fb = {b, b + 3 * n, NULL};
      double h = 0;
      size_t d = 0;
      assert_int_equal(bsurf_estimate_normals_streamed(c.xyz, n, nb_k, &o, &fb, &rb, &h, &d),
                       BSURF_OK);
      assert_memory_equal(a, b, 4 * n * sizeof *a);
      assert_memory_equal(&ra, &rb, sizeof ra);
      assert_true(h == nb.h);
      assert_int_equal(d, dups);
    }
  }
  free(a);
  free(b);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* The job's in-memory run without test error, smoothing or orientation
 * streams: its normals, variances, h and duplicates are the plain path's. */
static void test_stream_job(void **state) {
  (void)state;
  bsurf_cloud c, plain;
  size_t dups;
  const size_t n = make_cloud(&c, 5000, &dups);
  assert_int_equal(bsurf_cloud_copy(&plain, &c), BSURF_OK);
  bsurf_normals_job_options jo = bsurf_normals_job_options_default();
  jo.normals.k = 16;
  jo.normals.bootstrap = 9;
  jo.normals.threads = 2;
  bsurf_job_io io = {0};
  io.cloud = &c;
  bsurf_normals_job_summary s;
  bsurf_failure err = {0, -1, ""};
  assert_int_equal(bsurf_normals_job(&io, &jo, &s, &err), BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, plain.xyz, n, 16, 1, NULL, NULL), BSURF_OK);
  double *a = malloc(4 * n * sizeof *a);
  bsurf_normal_fields fa = {a, a + 3 * n, NULL};
  assert_int_equal(bsurf_estimate_normals(plain.xyz, &nb, NULL, &jo.normals, &fa, NULL), BSURF_OK);
  assert_memory_equal(c.normals, a, 3 * n * sizeof *a);
  const bsurf_field *var = bsurf_cloud_field(&c, "normal_var");
  assert_non_null(var);
  assert_memory_equal(var->values, a + 3 * n, n * sizeof *a);
  assert_true(s.h == nb.h);
  assert_int_equal(s.duplicates, dups);
  assert_int_equal(s.points, n);
  assert_int_equal(s.report.replicates_total, n * 9);
  /* a cloud without normals receives the estimate's array (moved, not copied) */
  free(plain.normals);
  plain.normals = NULL;
  io.cloud = &plain;
  jo.normals.bootstrap = 0;
  assert_int_equal(bsurf_normals_job(&io, &jo, &s, &err), BSURF_OK);
  jo.normals.threads = 1;
  assert_int_equal(bsurf_estimate_normals(plain.xyz, &nb, NULL, &jo.normals, &fa, NULL), BSURF_OK);
  assert_non_null(plain.normals);
  assert_int_equal(plain.normal_type, BSURF_FLOAT32);
  assert_memory_equal(plain.normals, a, 3 * n * sizeof *a);
  assert_null(bsurf_cloud_field(&plain, "normal_var"));
  free(a);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&plain);
  bsurf_cloud_free(&c);
}

static int stop_at_once(void *user, size_t done, size_t total) {
  (void)user, (void)done, (void)total;
  return 1;
}

/* Cancellation, a NaN coordinate, too few points, reference normals. */
static void test_stream_bad_input(void **state) {
  (void)state;
  bsurf_cloud c;
  size_t dups;
  const size_t n = make_cloud(&c, 3000, &dups);
  double *a = malloc(4 * n * sizeof *a);
  bsurf_normal_options o = bsurf_normal_options_default();
  o.k = 12;
  o.bootstrap = 0;
  bsurf_normal_fields fa = {a, a + 3 * n, NULL};
  double h;
  size_t d;
  o.progress = stop_at_once;
  assert_int_equal(bsurf_estimate_normals_streamed(c.xyz, n, 12, &o, &fa, NULL, &h, &d),
                   BSURF_ERR_CANCELLED);
  o.progress = NULL;
  assert_int_equal(bsurf_estimate_normals_streamed(c.xyz, 10, 12, &o, &fa, NULL, &h, &d),
                   BSURF_ERR_TOO_FEW_POINTS);
  bsurf_normal_fields fe = {a, NULL, a + 3 * n};
  assert_int_equal(bsurf_estimate_normals_streamed(c.xyz, n, 12, &o, &fe, NULL, &h, &d),
                   BSURF_ERR_INVALID_ARG);
  c.xyz[3 * 100 + 1] = NAN;
  assert_int_equal(bsurf_estimate_normals_streamed(c.xyz, n, 12, &o, &fa, NULL, &h, &d),
                   BSURF_ERR_INVALID_VALUE);
  free(a);
  bsurf_cloud_free(&c);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_stream_rows),
      cmocka_unit_test(test_stream_normals_match),
      cmocka_unit_test(test_stream_job),
      cmocka_unit_test(test_stream_bad_input),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
