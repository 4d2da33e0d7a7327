/* Joint K and degree selection by the estimated mean squared error of the
 * polynomial fit's normal (src/algo/kselect_poly.c): the closed-form
 * gradient covariance against Monte Carlo, the alias identity of the bias
 * estimate, exact cases (a plane: degree 1; a curved patch's border:
 * degree >= 2), determinism across thread counts, bad options. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include <stdint.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"
#include "algo/algo.h"
#include "local/local.h"

static const int KS[] = {15, 20, 30, 40, 50, 60, 70, 80};
#define NKS ((int)(sizeof KS / sizeof KS[0]))
static const int DS[] = {1, 2, 3};

/* A grid of g x g points on [-L, L]^2 with heights a x^2 + b y^2 + noise
 * (a fixed-seed Gaussian of deviation sd), neighbourhoods of 80. */
typedef struct patch {
  double *xyz;
  size_t n;
  int g;
  bsurf_neighbors nb;
} patch;

static void patch_make(patch *p, int g, double L, double a, double b, double sd) {
  p->g = g;
  p->n = (size_t)g * g;
  p->xyz = malloc(3 * p->n * sizeof(double));
  bsurf_rng rng;
  bsurf_rng_init(&rng, 11, 0, 0);
  for (int r = 0; r < g; r++)
    for (int c = 0; c < g; c++) {
      double *q = &p->xyz[3 * ((size_t)r * g + c)];
      q[0] = L * (-1 + 2.0 * c / (g - 1)), q[1] = L * (-1 + 2.0 * r / (g - 1));
      q[2] = a * q[0] * q[0] + b * q[1] * q[1] + sd * bsurf_rng_normal(&rng);
    }
  assert_int_equal(bsurf_neighbors_build(&p->nb, p->xyz, p->n, 80, 2, NULL, NULL), BSURF_OK);
}

static void patch_free(patch *p) {
  bsurf_neighbors_free(&p->nb);
  free(p->xyz);
}

typedef struct kd_out {
  double *normals, *rmse;
  int *k, *d;
} kd_out;

static void kd_run(const double *xyz, const bsurf_neighbors *nb, int threads, kd_out *r) {
  const size_t n = nb->point_count;
  r->normals = malloc(3 * n * sizeof(double));
  r->rmse = malloc(n * sizeof(double));
  r->k = malloc(n * sizeof(int));
  r->d = malloc(n * sizeof(int));
  bsurf_kselect_options o = bsurf_kselect_options_default();
  o.ks = KS;
  o.nk = NKS;
  o.ds = DS;
  o.nd = 3;
  o.threads = threads;
  bsurf_kselect_fields f = {r->normals, r->k, r->rmse, NULL, NULL, r->d};
  assert_int_equal(bsurf_select_k(xyz, nb, &o, &f, NULL), BSURF_OK);
}

static void kd_free(kd_out *r) {
  free(r->normals);
  free(r->rmse);
  free(r->k);
  free(r->d);
}

/* The closed-form covariance of the fitted gradient, s2 [G^-1]_gg
 * (bsurf_localfit_solve_row_grad), against the sample covariance of the
 * gradients of 20000 fits of one neighbourhood with fresh Gaussian noise
 * (fixed seed): within 5% for every degree. */
static void test_gradient_variance(void **state) {
  (void)state;
  enum { K = 30, DRAWS = 20000 };
  double xyz[3 * K];
  uint32_t idx[K];
  bsurf_rng rng;
  bsurf_rng_init(&rng, 5, 0, 0);
  for (int j = 0; j < K; j++) { /* a disc, the point at its centre */
    double x = 0, y = 0;
    if (j) do {
        x = 2 * bsurf_rng_uniform(&rng) - 1, y = 2 * bsurf_rng_uniform(&rng) - 1;
      } while (x * x + y * y > 1);
    xyz[3 * j] = 0.1 * x, xyz[3 * j + 1] = 0.1 * y, xyz[3 * j + 2] = 0;
    idx[j] = (uint32_t)j;
  }
  bsurf_frame f;
  memset(&f, 0, sizeof f);
  f.rot[0][0] = f.rot[1][1] = f.rot[2][2] = 1; /* the plane's own frame */
  bsurf_localfit lf;
  assert_int_equal(bsurf_localfit_alloc(&lf, K, 3), BSURF_OK);
  const double sd = 0.01;
  for (int d = 1; d <= 3; d++) {
    double s[3] = {0}, m[2] = {0}, gi[3], coef[BSURF_TERMS_MAX];
    for (int t = 0; t < DRAWS; t++) {
      for (int j = 0; j < K; j++)
        xyz[3 * j + 2] = sd * bsurf_rng_normal(&rng);
      bsurf_localfit_setup(&lf, xyz, idx, K, &f, d);
      assert_int_equal(bsurf_localfit_solve(&lf, d, NULL, coef), 0);
      const double gu = coef[1] / lf.scale, gv = coef[2] / lf.scale;
      m[0] += gu, m[1] += gv;
      s[0] += gu * gu, s[1] += gu * gv, s[2] += gv * gv;
    }
    double row[BSURF_NCOLS_MAX] = {0};
    for (int j = 0; j < K; j++)
      for (int c = 0; c < lf.ncols; c++)
        row[c] += lf.op[(size_t)j * lf.ncols + c];
    assert_int_equal(bsurf_localfit_solve_row_grad(&lf, d, row, coef, gi), 0);
    const double inv2 = sd * sd / (lf.scale * lf.scale);
    const double cuu = s[0] / DRAWS - (m[0] / DRAWS) * (m[0] / DRAWS);
    const double cvv = s[2] / DRAWS - (m[1] / DRAWS) * (m[1] / DRAWS);
    const double cuv = s[1] / DRAWS - (m[0] / DRAWS) * (m[1] / DRAWS);
    assert_true(fabs(cuu / (gi[0] * inv2) - 1) < 0.05);
    assert_true(fabs(cvv / (gi[2] * inv2) - 1) < 0.05);
    assert_true(fabs(cuv - gi[1] * inv2) < 0.05 * sqrt(gi[0] * gi[2]) * inv2);
  }
  bsurf_localfit_free(&lf);
}

/* The bias estimate's identity (kselect_poly.c): the degree-1 fit's
 * gradient minus the degree-2 fit's is the alias matrix (X_1^T X_1)^-1
 * X_1^T X_2 applied to the degree-2 fit's quadratic coefficients, exactly
 * (to rounding), on an off-centre neighbourhood of a noisy quadric; and on
 * a noise-free quadric the degree-2 gradient is the true one. */
static void test_alias_identity(void **state) {
  (void)state;
  patch p;
  patch_make(&p, 40, 1, 0.7, -0.4, 0.01);
  bsurf_localfit lf;
  assert_int_equal(bsurf_localfit_alloc(&lf, 40, 2), BSURF_OK);
  const uint32_t *idx = &p.nb.idx[0]; /* a corner: a one-sided neighbourhood */
  bsurf_frame f;
  bsurf_local_frame(p.xyz, idx, 40, BSURF_PCA_CENTROID, &f);
  bsurf_localfit_setup(&lf, p.xyz, idx, 40, &f, 2);
  double row[BSURF_NCOLS_MAX] = {0}, c1[3], c2[6], gi[3];
  for (int j = 0; j < 40; j++)
    for (int c = 0; c < lf.ncols; c++)
      row[c] += lf.op[(size_t)j * lf.ncols + c];
  assert_int_equal(bsurf_localfit_solve_row_grad(&lf, 1, row, c1, gi), 0);
  assert_int_equal(bsurf_localfit_solve_row_grad(&lf, 2, row, c2, gi), 0);
  /* A's columns: the degree-1 fits of the quadratic monomials' values */
  double alias[2] = {0, 0};
  for (int t = 3; t < 6; t++) {
    double r1[BSURF_NCOLS_MAX] = {0}, a[3];
    for (int j = 0; j < 40; j++) {
      double phi[6];
      bsurf_poly_basis(2, lf.u[j], lf.v[j], phi);
      for (int c = 0; c < lf.p; c++)
        r1[c] += lf.op[(size_t)j * lf.ncols + c];
      for (int c = 0; c < 3; c++)
        r1[lf.p + c] += phi[c] * phi[t];
    }
    assert_int_equal(bsurf_localfit_solve_row(&lf, 1, r1, a), 0);
    alias[0] += a[1] * c2[t], alias[1] += a[2] * c2[t];
  }
  assert_true(fabs((c1[1] - c2[1]) - alias[0]) < 1e-9 * (1 + fabs(alias[0])));
  assert_true(fabs((c1[2] - c2[2]) - alias[1]) < 1e-9 * (1 + fabs(alias[1])));
  assert_true(fabs(alias[0]) + fabs(alias[1]) > 1e-3); /* a real bias at the corner */
  patch_free(&p);
  /* noise-free, the frame the surface's own (the apex): degree 2 exact */
  patch_make(&p, 41, 1, 0.7, -0.4, 0);
  const size_t mid = (size_t)20 * 41 + 20;
  idx = &p.nb.idx[mid * (size_t)p.nb.k];
  memset(&f, 0, sizeof f);
  memcpy(f.origin, &p.xyz[3 * mid], sizeof f.origin);
  f.rot[0][0] = f.rot[1][1] = f.rot[2][2] = 1;
  bsurf_localfit_setup(&lf, p.xyz, idx, 40, &f, 2);
  memset(row, 0, sizeof row);
  for (int j = 0; j < 40; j++)
    for (int c = 0; c < lf.ncols; c++)
      row[c] += lf.op[(size_t)j * lf.ncols + c];
  assert_int_equal(bsurf_localfit_solve_row_grad(&lf, 2, row, c2, gi), 0);
  assert_true(fabs(c2[1]) < 1e-12 && fabs(c2[2]) < 1e-12);
  assert_true(fabs(c2[3] / (lf.scale * lf.scale) - 0.7) < 1e-9);
  assert_true(fabs(c2[5] / (lf.scale * lf.scale) + 0.4) < 1e-9);
  bsurf_localfit_free(&lf);
  patch_free(&p);
}

/* A noisy plane: every fit is unbiased, the plane (degree 1) has the
 * smallest variance, so the rule takes large K and mostly degree 1 (degree
 * 2 at K_max is within the tie band: its variance is barely larger, the
 * quadratic terms nearly orthogonal to the slope), rarely degree 3. */
static void test_plane_degree_one(void **state) {
  (void)state;
  patch p;
  patch_make(&p, 60, 1, 0, 0, 0.01);
  kd_out r;
  kd_run(p.xyz, &p.nb, 2, &r);
  size_t d1 = 0, d3 = 0;
  double ks = 0;
  for (size_t i = 0; i < p.n; i++)
    d1 += r.d[i] == 1, d3 += r.d[i] == 3, ks += r.k[i];
  fprintf(stderr, "plane d1 %zu d3 %zu of %zu, mean K %g\n", d1, d3, p.n, ks / p.n);
  assert_true(d1 >= 0.5 * p.n && d3 <= 0.05 * p.n);
  assert_true(ks / p.n >= 60);
  kd_free(&r);
  patch_free(&p);
}

/* A curved patch with little noise: at its border the neighbourhood is one
 * sided, the plane fit's slope at the point is biased by the curvature
 * (the alias of the quadratic terms), and the rule takes degree >= 2 at
 * most border points, at a large K, with less than half the error of the
 * largest K's plane fit there; inside, where the quadratic terms do not
 * alias into the slope of a symmetric neighbourhood, degree 1 remains
 * possible. */
static void test_border_higher_degree(void **state) {
  (void)state;
  patch p;
  patch_make(&p, 60, 0.5, 1.0, 1.0, 0.0005);
  kd_out r;
  kd_run(p.xyz, &p.nb, 2, &r);
  /* the plane fit of the largest K, for comparison */
  double *plane = malloc(3 * p.n * sizeof(double));
  bsurf_normal_options no = bsurf_normal_options_default();
  no.fit = BSURF_NORMAL_POLY, no.degree = 1, no.k = 80, no.bootstrap = 0;
  bsurf_normal_fields pf = {plane, NULL, NULL};
  assert_int_equal(bsurf_estimate_normals(p.xyz, &p.nb, NULL, &no, &pf, NULL), BSURF_OK);
  size_t nb = 0, hi = 0;
  double ks = 0, err = 0, err80 = 0;
  for (int row = 0; row < p.g; row++)
    for (int c = 0; c < p.g; c++) {
      if (row > 0 && row < p.g - 1 && c > 0 && c < p.g - 1) continue;
      const size_t i = (size_t)row * p.g + c;
      nb++, hi += r.d[i] >= 2, ks += r.k[i];
      const double *q = &p.xyz[3 * i];
      const double t[3] = {-2 * q[0], -2 * q[1], 1}; /* the true normal, unnormalised */
      err += bsurf_normal_angle(&r.normals[3 * i], t);
      err80 += bsurf_normal_angle(&plane[3 * i], t);
    }
  fprintf(stderr, "border: degree >= 2 at %zu of %zu, mean K %g, error %g (plane K 80: %g)\n", hi,
          nb, ks / nb, err / nb, err80 / nb);
  assert_true(hi >= 0.75 * nb);
  assert_true(ks / nb >= 40);
  assert_true(err < 0.5 * err80);
  free(plane);
  kd_free(&r);
  patch_free(&p);
}

/* Same bits with one thread and with two, on a noisy torus. */
static void test_determinism(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_TORUS, 4000, BSURF_SAMPLING_RANDOM, 3, 2),
                   BSURF_OK);
  assert_int_equal(
      bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_UNIFORM, 0.5, 0.03, 7),
      BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 80, 2, NULL, NULL), BSURF_OK);
  kd_out a, b;
  kd_run(c.xyz, &nb, 1, &a);
  kd_run(c.xyz, &nb, 2, &b);
  const size_t n = c.point_count;
  assert_memory_equal(a.normals, b.normals, 3 * n * sizeof(double));
  assert_memory_equal(a.k, b.k, n * sizeof(int));
  assert_memory_equal(a.d, b.d, n * sizeof(int));
  assert_memory_equal(a.rmse, b.rmse, n * sizeof(double));
  int seen[4] = {0};
  for (size_t i = 0; i < n; i++)
    seen[a.d[i]] = 1;
  assert_true(seen[1] + seen[2] + seen[3] >= 2); /* the degrees are exercised */
  kd_free(&a);
  kd_free(&b);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

static void test_bad_options(void **state) {
  (void)state;
  patch p;
  patch_make(&p, 30, 1, 0, 0, 0.01);
  kd_out r;
  r.normals = malloc(3 * p.n * sizeof(double));
  r.k = malloc(p.n * sizeof(int));
  r.d = malloc(p.n * sizeof(int));
  r.rmse = NULL;
  bsurf_kselect_fields f = {r.normals, r.k, NULL, NULL, NULL, r.d};
  bsurf_kselect_options o = bsurf_kselect_options_default();
  o.ks = KS;
  o.nk = NKS;
  o.nd = 1; /* ds NULL */
  assert_int_equal(bsurf_select_k(p.xyz, &p.nb, &o, &f, NULL), BSURF_ERR_INVALID_ARG);
  const int bad[] = {1, 5}, many[] = {1, 2, 3, 4, 1};
  o.ds = bad;
  o.nd = 2;
  assert_int_equal(bsurf_select_k(p.xyz, &p.nb, &o, &f, NULL), BSURF_ERR_INVALID_ARG);
  o.ds = many;
  o.nd = 5;
  assert_int_equal(bsurf_select_k(p.xyz, &p.nb, &o, &f, NULL), BSURF_ERR_INVALID_ARG);
  o.nd = -1;
  assert_int_equal(bsurf_select_k(p.xyz, &p.nb, &o, &f, NULL), BSURF_ERR_INVALID_ARG);
  kd_free(&r);
  patch_free(&p);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_gradient_variance), cmocka_unit_test(test_alias_identity),
      cmocka_unit_test(test_plane_degree_one),  cmocka_unit_test(test_border_higher_degree),
      cmocka_unit_test(test_determinism),       cmocka_unit_test(test_bad_options),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
