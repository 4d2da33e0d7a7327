/* Normals with bootstrap confidence (thesis chapter 5): exact cases,
 * orientation, smoothing, determinism. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"
#include "algo/algo.h"

static double angle_u(const double *a, const double *b) {
  double d = fabs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
  double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]), d);
}

static double mean_angle(const double *n, const double *truth, size_t count) {
  double s = 0;
  for (size_t i = 0; i < count; i++)
    s += angle_u(&n[3 * i], &truth[3 * i]);
  return s / count;
}

/* A tilted plane: every method gives the plane's normal, zero variance and
 * zero test error against exact reference normals. */
static void test_plane_exact(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_PLANE, 3000, BSURF_SAMPLING_RANDOM, 2, 0),
                   BSURF_OK);
  const double a = 0.6;
  for (size_t i = 0; i < c.point_count; i++) {
    double *p = &c.xyz[3 * i], *n = &c.normals[3 * i];
    double x = p[0], z = p[2];
    p[0] = cos(a) * x - sin(a) * z;
    p[2] = sin(a) * x + cos(a) * z;
    n[0] = -sin(a);
    n[2] = cos(a);
  }
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 20, 2, NULL, NULL), BSURF_OK);
  double *n = malloc(sizeof(double) * 3 * c.point_count),
         *v = malloc(sizeof(double) * c.point_count), *e = malloc(sizeof(double) * c.point_count);
  for (int fit = 0; fit < 2; fit++)
    for (int center = 0; center < 2; center++)
      for (int degree = 1; degree <= (fit ? 4 : 1); degree++) {
        bsurf_normal_options o = bsurf_normal_options_default();
        o.k = 20;
        o.fit = (bsurf_normal_fit)fit;
        o.pca_center = (bsurf_pca_center)center;
        o.degree = degree;
        o.bootstrap = 10;
        bsurf_normal_fields out = {n, v, e};
        bsurf_normal_report rep;
        assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, c.normals, &o, &out, &rep), BSURF_OK);
        for (size_t i = 0; i < c.point_count; i++) {
          assert_true(angle_u(&n[3 * i], &c.normals[3 * i]) < 1e-7);
          assert_true(v[i] < 1e-12);
          assert_true(e[i] < 1e-7);
        }
        assert_int_equal(rep.degenerate, 0);
      }
  free(n);
  free(v);
  free(e);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* Noise-free sphere: quadratic fits give nearly exact normals (a sphere is
 * locally a paraboloid to second order), better than PCA; quartic better
 * still. */
static void test_sphere_poly_normals(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, 20000, BSURF_SAMPLING_REGULAR, 1, 0),
                   BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 30, 2, NULL, NULL), BSURF_OK);
  double *n = malloc(sizeof(double) * 3 * c.point_count);
  double err[3];
  for (int t = 0; t < 3; t++) {
    bsurf_normal_options o = bsurf_normal_options_default();
    o.bootstrap = 0;
    o.fit = t == 0 ? BSURF_NORMAL_PCA : BSURF_NORMAL_POLY;
    o.pca_center = BSURF_PCA_POINT;
    o.degree = t == 1 ? 2 : 4;
    bsurf_normal_fields out = {n, NULL, NULL};
    assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, NULL, &o, &out, NULL), BSURF_OK);
    err[t] = mean_angle(n, c.normals, c.point_count);
  }
  assert_true(err[1] < 1e-3);
  assert_true(err[1] < err[0]);
  assert_true(err[2] < err[1]);
  free(n);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* Bit-identical for 1 and 2 threads; B = 0 equals the single fit; the
 * bootstrap mean is close to the single fit (Table 5.1: comparable). */
static void test_determinism_and_single_fit(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_TORUS, 8000, BSURF_SAMPLING_RANDOM, 3, 0),
                   BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, c.point_count, 2, &h), BSURF_OK);
  double *truth = malloc(sizeof(double) * 3 * c.point_count);
  memcpy(truth, c.normals, sizeof(double) * 3 * c.point_count);
  assert_int_equal(
      bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_GAUSSIAN, 0.5, h, 1), BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 30, 2, NULL, NULL), BSURF_OK);
  size_t n = c.point_count;
  double *a = malloc(sizeof(double) * 5 * n), *b = malloc(sizeof(double) * 5 * n);
  for (int fit = 0; fit < 2; fit++) {
    bsurf_normal_options o = bsurf_normal_options_default();
    o.fit = (bsurf_normal_fit)fit;
    o.threads = 1;
    bsurf_normal_fields fa = {a, a + 3 * n, a + 4 * n}, fb = {b, b + 3 * n, b + 4 * n};
    assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, truth, &o, &fa, NULL), BSURF_OK);
    o.threads = 2;
    assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, truth, &o, &fb, NULL), BSURF_OK);
    assert_memory_equal(a, b, sizeof(double) * 5 * n);
    double boot = mean_angle(a, truth, n);
    o.bootstrap = 0;
    assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, truth, &o, &fb, NULL), BSURF_OK);
    double single = mean_angle(b, truth, n);
    assert_true(fabs(boot - single) < 0.1 * single);
    for (size_t i = 0; i < n; i++)
      assert_true(b[3 * n + i] == 0); /* no variance without replicates */
  }
  free(a);
  free(b);
  free(truth);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* Each point's own K in one pass (bsurf_estimate_normals_at, the MSE
 * rule's replicates): the bits of a pass at that K, for -j1 and -j2. */
static void test_estimate_at(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_TORUS, 6000, BSURF_SAMPLING_RANDOM, 3, 0),
                   BSURF_OK);
  const size_t n = c.point_count;
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, 40, 2, NULL, NULL), BSURF_OK);
  static const int KS3[3] = {10, 25, 40};
  int *k_at = malloc(n * sizeof(int));
  for (size_t i = 0; i < n; i++)
    k_at[i] = KS3[(i * 2654435761u >> 7) % 3];
  double *want = malloc(4 * n * sizeof(double)), *got = malloc(4 * n * sizeof(double));
  double *tmp = malloc(4 * n * sizeof(double));
  bsurf_normal_options o = bsurf_normal_options_default();
  o.bootstrap = 20;
  o.threads = 2;
  for (int a = 0; a < 3; a++) {
    o.k = KS3[a];
    bsurf_normal_fields f = {tmp, tmp + 3 * n, NULL};
    assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, NULL, &o, &f, NULL), BSURF_OK);
    for (size_t i = 0; i < n; i++)
      if (k_at[i] == KS3[a]) {
        memcpy(&want[3 * i], &tmp[3 * i], 3 * sizeof(double));
        want[3 * n + i] = tmp[3 * n + i];
      }
  }
  o.k = 40;
  for (int threads = 1; threads <= 2; threads++) {
    o.threads = threads;
    memset(got, 0, 4 * n * sizeof(double));
    bsurf_normal_fields f = {got, got + 3 * n, NULL};
    bsurf_normal_report rep;
    assert_int_equal(bsurf_estimate_normals_at(c.xyz, &nb, &o, k_at, &f, &rep), BSURF_OK);
    assert_memory_equal(got, want, 4 * n * sizeof(double));
    assert_true(rep.replicates_total == 20 * n);
  }
  /* a K above opts->k is refused */
  k_at[0] = 41;
  bsurf_normal_fields f = {got, NULL, NULL};
  assert_int_equal(bsurf_estimate_normals_at(c.xyz, &nb, &o, k_at, &f, NULL),
                   BSURF_ERR_INVALID_ARG);
  free(k_at);
  free(want);
  free(got);
  free(tmp);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* Table 5.2's claim on the cube: points with high normal_var (the top 15%)
 * have a much higher angle error than the rest. */
static void test_variance_flags_bad_normals(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 24000, BSURF_SAMPLING_REGULAR, 1, 2),
                   BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, c.point_count, 2, &h), BSURF_OK);
  double *truth = malloc(sizeof(double) * 3 * c.point_count);
  memcpy(truth, c.normals, sizeof(double) * 3 * c.point_count);
  assert_int_equal(bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_UNIFORM, 0.5, h, 1),
                   BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 50, 2, NULL, NULL), BSURF_OK);
  size_t n = c.point_count;
  double *nrm = malloc(sizeof(double) * 3 * n), *var = malloc(sizeof(double) * n);
  bsurf_normal_options o = bsurf_normal_options_default();
  o.k = 50;
  bsurf_normal_fields out = {nrm, var, NULL};
  assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, NULL, &o, &out, NULL), BSURF_OK);
  /* threshold: the 85th percentile, by bisection on the count above it */
  double lo = 0, hi = 1;
  for (int it = 0; it < 60; it++) {
    double mid = 0.5 * (lo + hi);
    size_t above = 0;
    for (size_t i = 0; i < n; i++)
      above += var[i] > mid;
    if (above > 0.15 * n)
      lo = mid;
    else
      hi = mid;
  }
  double eh = 0, el = 0;
  size_t ch = 0, cl = 0;
  for (size_t i = 0; i < n; i++) {
    double a = angle_u(&nrm[3 * i], &truth[3 * i]);
    if (var[i] > hi) {
      eh += a;
      ch++;
    } else {
      el += a;
      cl++;
    }
  }
  eh /= ch;
  el /= cl;
  assert_true(ch > 0.1 * n && ch < 0.2 * n);
  assert_true(eh > 3 * el);
  free(nrm);
  free(var);
  free(truth);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* MST orientation: unoriented normals of a closed surface, flipped at
 * random, all come out outward (agreeing with the exact normals). */
static void test_orientation_agreement(void **state) {
  (void)state;
  for (int s = 0; s < 2; s++) {
    bsurf_cloud c;
    assert_int_equal(bsurf_generate(&c, s ? BSURF_SHAPE_TORUS : BSURF_SHAPE_SPHERE, 10000,
                                    BSURF_SAMPLING_REGULAR, 1, 0),
                     BSURF_OK);
    size_t n = c.point_count;
    bsurf_neighbors nb;
    assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, 12, 2, NULL, NULL), BSURF_OK);
    double *nrm = malloc(sizeof(double) * 3 * n);
    bsurf_normal_options o = bsurf_normal_options_default();
    o.k = 12;
    o.bootstrap = 0;
    bsurf_normal_fields out = {nrm, NULL, NULL};
    assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, NULL, &o, &out, NULL), BSURF_OK);
    bsurf_rng rng;
    bsurf_rng_init(&rng, 5, 0, 0);
    for (size_t i = 0; i < n; i++)
      if (bsurf_rng_uniform(&rng) < 0.5)
        for (int t = 0; t < 3; t++)
          nrm[3 * i + t] = -nrm[3 * i + t];
    assert_int_equal(bsurf_orient_normals(c.xyz, &nb, 12, nrm), BSURF_OK);
    for (size_t i = 0; i < n; i++) {
      const double *a = &nrm[3 * i], *b = &c.normals[3 * i];
      assert_true(a[0] * b[0] + a[1] * b[1] + a[2] * b[2] > 0.9);
    }
    free(nrm);
    bsurf_neighbors_free(&nb);
    bsurf_cloud_free(&c);
  }
}

/* Bilateral smoothing: on a noisy sphere it lowers the angle error; with
 * sigma_nu = infinity it is the single Gaussian filter; alpha = 0 or no
 * iterations change nothing. */
static void test_smoothing(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, 10000, BSURF_SAMPLING_REGULAR, 1, 0),
                   BSURF_OK);
  size_t n = c.point_count;
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, n, 2, &h), BSURF_OK);
  double *truth = malloc(sizeof(double) * 3 * n);
  memcpy(truth, c.normals, sizeof(double) * 3 * n);
  assert_int_equal(bsurf_add_noise(c.xyz, c.normals, n, BSURF_NOISE_GAUSSIAN, 1.0, h, 2), BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, 15, 2, NULL, NULL), BSURF_OK);
  double *nrm = malloc(sizeof(double) * 3 * n), *var = malloc(sizeof(double) * n),
         *copy = malloc(sizeof(double) * 3 * n);
  bsurf_normal_options o = bsurf_normal_options_default();
  o.k = 15;
  bsurf_normal_fields out = {nrm, var, NULL};
  assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, NULL, &o, &out, NULL), BSURF_OK);
  double before = mean_angle(nrm, truth, n);
  memcpy(copy, nrm, sizeof(double) * 3 * n);
  assert_int_equal(bsurf_smooth_normals(c.xyz, &nb, 15, copy, var, 5, 0.0, h, INFINITY, 2),
                   BSURF_OK);
  for (size_t i = 0; i < 3 * n; i++)
    assert_true(fabs(copy[i] - nrm[i]) < 1e-15); /* only renormalised */
  memcpy(copy, nrm, sizeof(double) * 3 * n);
  assert_int_equal(bsurf_smooth_normals(c.xyz, &nb, 15, copy, var, 10, 0.5, 2 * h, 0.01, 1),
                   BSURF_OK);
  double after = mean_angle(copy, truth, n);
  assert_true(after < 0.8 * before);
  double *copy2 = malloc(sizeof(double) * 3 * n);
  memcpy(copy2, nrm, sizeof(double) * 3 * n);
  assert_int_equal(bsurf_smooth_normals(c.xyz, &nb, 15, copy2, var, 10, 0.5, 2 * h, 0.01, 2),
                   BSURF_OK);
  assert_memory_equal(copy, copy2, sizeof(double) * 3 * n); /* 1 thread == 2 threads */
  for (size_t i = 0; i < n; i++)
    assert_true(fabs(copy[3 * i] * copy[3 * i] + copy[3 * i + 1] * copy[3 * i + 1] +
                     copy[3 * i + 2] * copy[3 * i + 2] - 1) < 1e-12);
  free(copy2);
  free(nrm);
  free(var);
  free(copy);
  free(truth);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_plane_exact),
      cmocka_unit_test(test_sphere_poly_normals),
      cmocka_unit_test(test_determinism_and_single_fit),
      cmocka_unit_test(test_estimate_at),
      cmocka_unit_test(test_variance_flags_bad_normals),
      cmocka_unit_test(test_orientation_agreement),
      cmocka_unit_test(test_smoothing),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
