/* bsurf_estimate_error end to end on generated shapes: exact cases,
 * determinism for any thread count, degenerate neighbourhoods, argument
 * checks. (The thesis's Table 4.1 relations are in test_table41.c.) */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"
#include "common/common.h"

typedef struct {
  double *v[10];
  bsurf_error_fields f;
} fields;

static void fields_alloc(fields *F, size_t n) {
  memset(F, 0, sizeof *F);
  for (int t = 0; t < 10; t++)
    F->v[t] = calloc(n, sizeof(double));
  F->f.err_train = F->v[0];
  F->f.err_boot = F->v[1];
  F->f.err_loo = F->v[2];
  F->f.err_loo_center = F->v[3];
  F->f.err_632 = F->v[4];
  F->f.err_632plus = F->v[5];
  F->f.gamma = F->v[6];
  F->f.overfit_rate = F->v[7];
  F->f.err_test = F->v[8];
  F->f.err_test_center = F->v[9];
}

static void fields_free(fields *F) {
  for (int t = 0; t < 10; t++)
    free(F->v[t]);
}

/* Points on a plane (any orientation) are fitted exactly at every degree:
 * every estimate is 0. */
static void test_plane_zero_error(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_PLANE, 2500, BSURF_SAMPLING_RANDOM, 3, 0),
                   BSURF_OK);
  /* tilt it: rotate about x by 0.7 rad and shift */
  for (size_t i = 0; i < c.point_count; i++) {
    double *p = &c.xyz[3 * i];
    double y = p[1], z = p[2];
    p[1] = cos(0.7) * y - sin(0.7) * z + 5;
    p[2] = sin(0.7) * y + cos(0.7) * z - 2;
  }
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 30, 2, NULL, NULL), BSURF_OK);
  for (int degree = 1; degree <= 4; degree++) {
    bsurf_error_options o = bsurf_error_options_default();
    o.k = 30;
    o.degree = degree;
    o.bootstrap = 20;
    fields F;
    fields_alloc(&F, c.point_count);
    bsurf_error_report rep;
    assert_int_equal(bsurf_estimate_error(c.xyz, &nb, c.xyz, &o, &F.f, &rep), BSURF_OK);
    for (size_t i = 0; i < c.point_count; i++)
      for (int t = 0; t < 6; t++)
        assert_true(F.v[t][i] < 1e-9);
    for (size_t i = 0; i < c.point_count; i++)
      assert_true(F.f.err_test[i] < 1e-9);
    assert_int_equal(rep.degree_reduced, 0);
    fields_free(&F);
  }
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* A random torus of about n points with gaussian noise 0.5 h along the
 * normals. */
static void noisy_torus(bsurf_cloud *c, size_t n, uint64_t seed, uint64_t noise_seed) {
  assert_int_equal(bsurf_generate(c, BSURF_SHAPE_TORUS, n, BSURF_SAMPLING_RANDOM, seed, 0),
                   BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c->xyz, c->point_count, 2, &h), BSURF_OK);
  assert_int_equal(
      bsurf_add_noise(c->xyz, c->normals, c->point_count, BSURF_NOISE_GAUSSIAN, 0.5, h, noise_seed),
      BSURF_OK);
}

/* Bit-identical results for 1 and 2 threads, and for two runs. */
static void test_thread_determinism(void **state) {
  (void)state;
  bsurf_cloud c;
  noisy_torus(&c, 6000, 5, 9);
  fields A, B2, C;
  fields_alloc(&A, c.point_count);
  fields_alloc(&B2, c.point_count);
  fields_alloc(&C, c.point_count);
  bsurf_neighbors nb1, nb2;
  assert_int_equal(bsurf_neighbors_build(&nb1, c.xyz, c.point_count, 40, 1, NULL, NULL), BSURF_OK);
  assert_int_equal(bsurf_neighbors_build(&nb2, c.xyz, c.point_count, 40, 2, NULL, NULL), BSURF_OK);
  assert_memory_equal(nb1.idx, nb2.idx, c.point_count * 40 * sizeof(uint32_t));
  assert_true(nb1.h == nb2.h);
  for (int g = 0; g < 3; g++) {
    bsurf_error_options o = bsurf_error_options_default();
    o.k = 40;
    o.gamma = (bsurf_gamma_mode)g;
    o.threads = 1;
    assert_int_equal(bsurf_estimate_error(c.xyz, &nb1, NULL, &o, &A.f, NULL), BSURF_OK);
    o.threads = 2;
    assert_int_equal(bsurf_estimate_error(c.xyz, &nb2, NULL, &o, &B2.f, NULL), BSURF_OK);
    assert_int_equal(bsurf_estimate_error(c.xyz, &nb2, NULL, &o, &C.f, NULL), BSURF_OK);
    for (int t = 0; t < 8; t++) {
      assert_memory_equal(A.v[t], B2.v[t], c.point_count * sizeof(double));
      assert_memory_equal(A.v[t], C.v[t], c.point_count * sizeof(double));
    }
  }
  /* a different seed changes the bootstrap estimates but not err_train */
  bsurf_error_options o = bsurf_error_options_default();
  o.k = 40;
  o.seed = 2;
  assert_int_equal(bsurf_estimate_error(c.xyz, &nb2, NULL, &o, &C.f, NULL), BSURF_OK);
  assert_memory_equal(A.v[0], C.v[0], c.point_count * sizeof(double));
  assert_true(memcmp(A.v[2], C.v[2], c.point_count * sizeof(double)) != 0);
  fields_free(&A);
  fields_free(&B2);
  fields_free(&C);
  bsurf_neighbors_free(&nb1);
  bsurf_neighbors_free(&nb2);
  bsurf_cloud_free(&c);
}

/* Duplicate and collinear points: finite output, counted degree reductions
 * and skipped replicates, no NaN. */
static void test_degenerate_neighbourhoods(void **state) {
  (void)state;
  enum { N = 400 };
  double *xyz = malloc(sizeof(double) * 3 * N);
  for (int i = 0; i < N; i++) {
    /* 200 points on a line, 200 copies of 20 points */
    if (i < 200) {
      xyz[3 * i] = i * 0.01;
      xyz[3 * i + 1] = 2 * i * 0.01;
      xyz[3 * i + 2] = 5;
    } else {
      int q = (i - 200) % 20;
      xyz[3 * i] = 10 + q % 5;
      xyz[3 * i + 1] = 10 + q / 5;
      xyz[3 * i + 2] = 0.1 * q;
    }
  }
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, N, 20, 2, NULL, NULL), BSURF_OK);
  bsurf_error_options o = bsurf_error_options_default();
  o.k = 20;
  o.degree = 2;
  fields F;
  fields_alloc(&F, N);
  bsurf_error_report rep;
  assert_int_equal(bsurf_estimate_error(xyz, &nb, NULL, &o, &F.f, &rep), BSURF_OK);
  for (int i = 0; i < N; i++)
    for (int t = 0; t < 8; t++)
      assert_true(isfinite(F.v[t][i]));
  assert_true(rep.degree_reduced >= 200);
  assert_true(rep.replicates_skipped > 0);
  assert_int_equal(rep.replicates_total, (size_t)N * 50);
  fields_free(&F);
  bsurf_neighbors_free(&nb);
  free(xyz);
}

/* The two ways of summing the replicates give the same bits: gamma = fit
 * sums the residuals as they are predicted (left-out points formed from the
 * weights in registers), gamma = mean stores every prediction and the
 * left-out rows; err_train, err_boot, err_loo, err_loo_center and err_632
 * do not depend on gamma. On a noisy torus and on duplicate / collinear
 * points (reduced degrees, skipped replicates). */
static void test_sum_paths_agree(void **state) {
  (void)state;
  bsurf_cloud c;
  noisy_torus(&c, 3000, 3, 4);
  enum { N = 400 };
  double dup[3 * N];
  for (int i = 0; i < N; i++) {
    const int q = i % 20;
    dup[3 * i] = i < 200 ? i * 0.01 : 10 + q % 5;
    dup[3 * i + 1] = i < 200 ? 2 * i * 0.01 : 10 + q / 5;
    dup[3 * i + 2] = i < 200 ? 5 : 0.1 * q;
  }
  const double *clouds[2] = {c.xyz, dup};
  const size_t counts[2] = {c.point_count, N};
  for (int w = 0; w < 2; w++)
    for (int degree = 1; degree <= 3; degree++) {
      const size_t n = counts[w];
      bsurf_neighbors nb;
      assert_int_equal(bsurf_neighbors_build(&nb, clouds[w], n, 30, 2, NULL, NULL), BSURF_OK);
      fields A, M;
      fields_alloc(&A, n);
      fields_alloc(&M, n);
      bsurf_error_options o = bsurf_error_options_default();
      o.k = 30;
      o.degree = degree;
      o.gamma = BSURF_GAMMA_FIT;
      assert_int_equal(bsurf_estimate_error(clouds[w], &nb, NULL, &o, &A.f, NULL), BSURF_OK);
      o.gamma = BSURF_GAMMA_MEAN;
      assert_int_equal(bsurf_estimate_error(clouds[w], &nb, NULL, &o, &M.f, NULL), BSURF_OK);
      for (int t = 0; t < 5; t++)
        assert_memory_equal(A.v[t], M.v[t], n * sizeof(double));
      fields_free(&A);
      fields_free(&M);
      bsurf_neighbors_free(&nb);
    }
  bsurf_cloud_free(&c);
}

static int cancel_cb(void *user, size_t done, size_t total) {
  (void)user;
  (void)done;
  (void)total;
  return 1;
}

/* A regular sphere of n points, its k-neighbourhoods and zeroed fields. */
static void sphere_setup(size_t n, int k, bsurf_cloud *c, bsurf_neighbors *nb, fields *F) {
  assert_int_equal(bsurf_generate(c, BSURF_SHAPE_SPHERE, n, BSURF_SAMPLING_REGULAR, 1, 0),
                   BSURF_OK);
  assert_int_equal(bsurf_neighbors_build(nb, c->xyz, c->point_count, k, 1, NULL, NULL), BSURF_OK);
  fields_alloc(F, c->point_count);
}

typedef struct {
  int calls;
  size_t last, step; /* the previous `done`; the largest step between calls */
} progress_log;

static int log_cb(void *user, size_t done, size_t total) {
  progress_log *l = user;
  assert_true(done > l->last && done <= total);
  if (done - l->last > l->step) l->step = done - l->last;
  l->last = done;
  l->calls++;
  return 0;
}

/* The progress calls come every BSURF_PROGRESS_CHUNK points at the default
 * work, proportionally more often for heavy points (bsurf_progress_chunk:
 * Ctrl-C answered as soon for `error -B 1000`), never at less than 16 points;
 * the results do not depend on it. */
static void test_progress_chunk(void **state) {
  (void)state;
  const double ref = BSURF_PROGRESS_REF_WORK;
  assert_int_equal(bsurf_progress_chunk(0), BSURF_PROGRESS_CHUNK);
  assert_int_equal(bsurf_progress_chunk(ref), BSURF_PROGRESS_CHUNK);
  assert_int_equal(bsurf_progress_chunk(NAN), BSURF_PROGRESS_CHUNK);
  assert_int_equal(bsurf_progress_chunk(2 * ref), BSURF_PROGRESS_CHUNK / 2);
  assert_int_equal(bsurf_progress_chunk(8 * ref), BSURF_PROGRESS_CHUNK / 8);
  assert_int_equal(bsurf_progress_chunk(1e30), 16);

  bsurf_cloud c;
  bsurf_neighbors nb;
  fields M;
  sphere_setup(3000, 12, &c, &nb, &M);
  bsurf_error_options o = bsurf_error_options_default();
  o.k = 12;
  o.degree = 2;
  o.threads = 2;
  o.bootstrap = 1200; /* 12 x 1201 x 6 units a point: chunks of 1207 points */
  const size_t chunk = bsurf_progress_chunk(12.0 * 1201 * 6);
  assert_true(chunk < c.point_count / 2);
  progress_log l = {0, 0, 0};
  o.progress = log_cb;
  o.progress_user = &l;
  assert_int_equal(bsurf_estimate_error(c.xyz, &nb, NULL, &o, &M.f, NULL), BSURF_OK);
  assert_int_equal(l.calls, (int)((c.point_count + chunk - 1) / chunk));
  assert_int_equal(l.step, chunk);
  assert_int_equal(l.last, c.point_count);
  /* the same replicates at 1 thread without progress: the same bits */
  fields S;
  fields_alloc(&S, c.point_count);
  o.progress = NULL;
  o.threads = 1;
  assert_int_equal(bsurf_estimate_error(c.xyz, &nb, NULL, &o, &S.f, NULL), BSURF_OK);
  for (int t = 0; t < 10; t++)
    if (M.v[t]) assert_memory_equal(M.v[t], S.v[t], c.point_count * sizeof(double));
  fields_free(&S);
  fields_free(&M);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

static void test_arguments(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_neighbors nb;
  fields F;
  sphere_setup(500, 20, &c, &nb, &F);
  bsurf_error_options o = bsurf_error_options_default();
  o.k = 30; /* more than the neighbourhoods hold */
  assert_int_equal(bsurf_estimate_error(c.xyz, &nb, NULL, &o, &F.f, NULL), BSURF_ERR_INVALID_ARG);
  o.k = 12;
  o.degree = 4; /* 15 terms > 12 points */
  assert_int_equal(bsurf_estimate_error(c.xyz, &nb, NULL, &o, &F.f, NULL),
                   BSURF_ERR_TOO_FEW_POINTS);
  o.degree = 5;
  assert_int_equal(bsurf_estimate_error(c.xyz, &nb, NULL, &o, &F.f, NULL), BSURF_ERR_INVALID_ARG);
  o.degree = 2;
  o.progress = cancel_cb;
  assert_int_equal(bsurf_estimate_error(c.xyz, &nb, NULL, &o, &F.f, NULL), BSURF_ERR_CANCELLED);
  /* B = 0: every bootstrap estimate is the training error */
  o.progress = NULL;
  o.bootstrap = 0;
  assert_int_equal(bsurf_estimate_error(c.xyz, &nb, NULL, &o, &F.f, NULL), BSURF_OK);
  for (size_t i = 0; i < c.point_count; i++)
    assert_true(F.f.err_632plus[i] == F.f.err_train[i]);
  fields_free(&F);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_plane_zero_error), cmocka_unit_test(test_thread_determinism),
      cmocka_unit_test(test_progress_chunk),   cmocka_unit_test(test_degenerate_neighbourhoods),
      cmocka_unit_test(test_sum_paths_agree),  cmocka_unit_test(test_arguments),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
