/* Per-point K and degree selection of polynomial normals
 * (bsurf_select_normals_kd, src/algo/select_degree.c) and its angle kernel
 * (bsurf_nested_field_angle_sum, src/algo/nested.c). */
// clang-format off
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
// clang-format on

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "algo/algo.h"
#include "bootsurf.h"
#include "common/common.h"
#include "local/local.h"

static void unit(double v[3]) {
  const double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  for (int t = 0; t < 3; t++)
    v[t] /= l;
}

/* The polynomial's normals at every point against libm's atan2 of the cross
 * and dot products of (-f_u s^-1, -f_v s^-1, 1) from the basis's gradient:
 * within 1e-13 relative (about 1e-14 measured: the slopes' rounding, formed
 * from the gradient's own coefficients, dominates), degrees 0..4, slopes up
 * to 1e30. */
static void test_field_angle_accuracy(void **state) {
  (void)state;
  bsurf_rng r;
  bsurf_rng_init(&r, 11, 2, 3);
  enum { K = 37, KP = 40 };
  double phit[BSURF_TERMS_MAX * KP], rx[K], ry[K], rz[K], sc[K], u[K], v[K];
  double worst = 0;
  for (int it = 0; it < 300; it++) {
    const int degree = it % 5;
    const double inv = 1.0 / (0.1 + bsurf_rng_uniform(&r));
    const double mag = it % 50 == 49 ? 1e30 : pow(10, 3 * bsurf_rng_uniform(&r) - 2);
    double coef[BSURF_TERMS_MAX];
    for (int t = 0; t < BSURF_TERMS_MAX; t++)
      coef[t] = mag * bsurf_rng_normal(&r);
    for (int j = 0; j < K; j++) {
      const double a = 6.283185307179586 * bsurf_rng_uniform(&r), rad = sqrt(bsurf_rng_uniform(&r));
      u[j] = rad * cos(a), v[j] = rad * sin(a);
      double phi[BSURF_TERMS_MAX];
      bsurf_poly_basis(BSURF_DEGREE_MAX, u[j], v[j], phi);
      for (int t = 0; t < BSURF_TERMS_MAX; t++)
        phit[t * KP + j] = phi[t];
      double w[3] = {bsurf_rng_normal(&r), bsurf_rng_normal(&r), bsurf_rng_normal(&r)};
      unit(w);
      rx[j] = w[0], ry[j] = w[1], rz[j] = w[2];
    }
    double sum = 0;
    for (int j = 0; j < K; j++) {
      double du[BSURF_TERMS_MAX], dv[BSURF_TERMS_MAX], fu = 0, fv = 0;
      bsurf_poly_basis_grad(degree, u[j], v[j], du, dv);
      for (int t = 0; t < bsurf_poly_terms(degree); t++)
        fu += coef[t] * du[t], fv += coef[t] * dv[t];
      const double g[3] = {-fu * inv, -fv * inv, 1.0};
      const double c[3] = {g[1] * rz[j] - g[2] * ry[j], g[2] * rx[j] - g[0] * rz[j],
                           g[0] * ry[j] - g[1] * rx[j]};
      const double want = atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
                                fabs(g[0] * rx[j] + g[1] * ry[j] + g[2] * rz[j]));
      /* one point: the stride is still KP, so shift the basis by j */
      const double got = bsurf_nested_field_angle_sum(degree, coef, inv, phit + j, KP, rx + j,
                                                      ry + j, rz + j, 1, sc);
      assert_true(isfinite(got));
      const double rel = fabs(got - want) / (want > 1e-300 ? want : 1e-300);
      if (rel > worst) worst = rel;
      sum += got;
    }
    const double all = bsurf_nested_field_angle_sum(degree, coef, inv, phit, KP, rx, ry, rz, K, sc);
    assert_true(fabs(all - sum) <= 1e-14 * sum);
  }
  assert_true(worst <= 1e-13);
}

static double *noisy_torus(bsurf_cloud *c, size_t n, bsurf_neighbors *nb, int kmax) {
  assert_int_equal(bsurf_generate(c, BSURF_SHAPE_TORUS, n, BSURF_SAMPLING_RANDOM, 3, 0), BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c->xyz, c->point_count, 2, &h), BSURF_OK);
  double *truth = malloc(sizeof(double) * 3 * c->point_count);
  memcpy(truth, c->normals, sizeof(double) * 3 * c->point_count);
  assert_int_equal(
      bsurf_add_noise(c->xyz, c->normals, c->point_count, BSURF_NOISE_GAUSSIAN, 0.5, h, 1),
      BSURF_OK);
  assert_int_equal(bsurf_neighbors_build(nb, c->xyz, c->point_count, kmax, 2, NULL, NULL),
                   BSURF_OK);
  return truth;
}

static double angle_to_truth(const double *n, const double *truth) {
  double t = fabs(n[0] * truth[0] + n[1] * truth[1] + n[2] * truth[2]);
  return acos(t > 1 ? 1 : t);
}

/* K and degree selection: bit-identical for 1 and 2 threads; the chosen
 * (K, degree) is the candidate of smallest error (ties: smaller K, then
 * degree) and its values are written; with B = 0 and one candidate the
 * single fit of bsurf_estimate_normals (same normal bits, its training error
 * up to the angle's rounding); selection beats the worst candidate on the
 * truth; bad arguments. */
static void test_select_kd(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_neighbors nb;
  double *truth = noisy_torus(&c, 5000, &nb, 40);
  const size_t n = c.point_count;
  bsurf_normal_options ro = bsurf_normal_options_default();
  ro.bootstrap = 0;
  ro.k = 20;
  double *ref = malloc(sizeof(double) * 3 * n);
  bsurf_normal_fields rf = {ref, NULL, NULL};
  assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, NULL, &ro, &rf, NULL), BSURF_OK);

  const int ks[3] = {10, 25, 40}, ds[3] = {1, 2, 3};
  const int nk = 3, nd = 3, nc = nk * nd;
  double *a = malloc(sizeof(double) * 5 * n), *b = malloc(sizeof(double) * 5 * n);
  double *ce = malloc(sizeof(double) * n * nc), *cv = malloc(sizeof(double) * n * nc);
  double *cn = malloc(sizeof(double) * 3 * n * nc);
  int *ka = malloc(sizeof(int) * n), *kb = malloc(sizeof(int) * n);
  int *da = malloc(sizeof(int) * n), *db = malloc(sizeof(int) * n);
  bsurf_normal_options o = bsurf_normal_options_default();
  o.fit = BSURF_NORMAL_POLY;
  o.bootstrap = 12;
  o.threads = 1;
  bsurf_normal_select_fields fa = {a, a + 3 * n, a + 4 * n, ka, ce, cv, cn};
  bsurf_normal_select_fields fb = {b, b + 3 * n, b + 4 * n, kb, NULL, NULL, NULL};
  bsurf_normal_report rep;
  assert_int_equal(bsurf_select_normals_kd(c.xyz, &nb, ref, &o, ks, nk, ds, nd, &fa, da, &rep),
                   BSURF_OK);
  assert_int_equal(rep.replicates_total, n * 12 * nc);
  /* K = 10 with a cubic (10 terms) needs all 10 points drawn: few are */
  assert_true(rep.replicates_skipped < rep.replicates_total / 5);
  o.threads = 2;
  assert_int_equal(bsurf_select_normals_kd(c.xyz, &nb, ref, &o, ks, nk, ds, nd, &fb, db, NULL),
                   BSURF_OK);
  assert_memory_equal(a, b, sizeof(double) * 5 * n);
  assert_memory_equal(ka, kb, sizeof(int) * n);
  assert_memory_equal(da, db, sizeof(int) * n);
  double worst = 0, sel = 0;
  int used[3] = {0, 0, 0};
  for (int q = 0; q < nc; q++) {
    double e = 0;
    for (size_t i = 0; i < n; i++)
      e += angle_to_truth(&cn[(i * nc + q) * 3], &truth[3 * i]);
    if (e > worst) worst = e;
  }
  for (size_t i = 0; i < n; i++) {
    int best = 0;
    for (int q = 1; q < nc; q++)
      if (ce[i * nc + q] < ce[i * nc + best]) best = q;
    assert_int_equal(ka[i], ks[best / nd]);
    assert_int_equal(da[i], ds[best % nd]);
    used[best % nd]++;
    assert_true(a[4 * n + i] == ce[i * nc + best]);
    assert_true(a[3 * n + i] == cv[i * nc + best]);
    assert_memory_equal(&a[3 * i], &cn[(i * nc + best) * 3], 3 * sizeof(double));
    sel += angle_to_truth(&a[3 * i], &truth[3 * i]);
  }
  assert_true(sel < worst);
  assert_true(used[0] + used[1] + used[2] == (int)n);

  /* one candidate, B = 0: the single fit of bsurf_estimate_normals */
  o.bootstrap = 0;
  const int k30 = 30, d2 = 2;
  bsurf_normal_select_fields f1 = {a, NULL, a + 4 * n, ka, NULL, NULL, NULL};
  assert_int_equal(bsurf_select_normals_kd(c.xyz, &nb, ref, &o, &k30, 1, &d2, 1, &f1, NULL, NULL),
                   BSURF_OK);
  o.k = 30;
  o.degree = 2;
  bsurf_normal_fields f2 = {b, NULL, b + 4 * n};
  assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, ref, &o, &f2, NULL), BSURF_OK);
  assert_memory_equal(a, b, sizeof(double) * 3 * n);
  for (size_t i = 0; i < n; i++)
    assert_true(fabs(a[4 * n + i] - b[4 * n + i]) <= 1e-14 + 1e-12 * b[4 * n + i]);

  /* bad arguments */
  const int bad[2] = {20, 20}, d5 = 5, k5 = 5, d3 = 3;
  assert_int_equal(bsurf_select_normals_kd(c.xyz, &nb, ref, &o, bad, 2, ds, 1, &f1, NULL, NULL),
                   BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_select_normals_kd(c.xyz, &nb, ref, &o, ks, 1, &d5, 1, &f1, NULL, NULL),
                   BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_select_normals_kd(c.xyz, &nb, ref, &o, &k5, 1, &d3, 1, &f1, NULL, NULL),
                   BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_select_normals_kd(c.xyz, &nb, NULL, &o, ks, nk, ds, nd, &f1, NULL, NULL),
                   BSURF_ERR_INVALID_ARG);
  o.fit = BSURF_NORMAL_PCA;
  assert_int_equal(bsurf_select_normals_kd(c.xyz, &nb, ref, &o, ks, nk, ds, nd, &f1, NULL, NULL),
                   BSURF_ERR_INVALID_ARG);
  free(a);
  free(b);
  free(ce);
  free(cv);
  free(cn);
  free(ka);
  free(kb);
  free(da);
  free(db);
  free(ref);
  free(truth);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_field_angle_accuracy),
      cmocka_unit_test(test_select_kd),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
