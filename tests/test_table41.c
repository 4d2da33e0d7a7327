/* Reproduction of the relations of the thesis's Table 4.1 (section 4.2): a
 * sphere of 26,010 points, gaussian noise 0, 0.5, 1, 2 (in units of h),
 * K = 50 and 100, cubic and quartic fits, B = 50, gamma from the fit.
 *
 * Checked:
 *  - with noise > 0: mean err_train < mean err_632 < mean err_loo;
 *  - at K = 50 the quartic's err_loo is at least 10% above the cubic's
 *    (overfitting detected) while at K = 100 the gap is smaller;
 *  - every estimate grows with the noise;
 *  - at noise 0 every estimate is near 0 (< 0.01 h); gamma, the
 *    no-information rate, is not an estimate of the error and is not 0 on a
 *    curved patch (the heights of different points differ).
 * It also prints the table, with the true test error of the same fits
 * measured on an independent noisy copy of the sphere (docs/validation.md). */
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

enum { NF = 10, NNOISE = 4, NCOMBO = 4 };
static const char *names[NF] = {"err_train", "err_boot",       "err_loo", "err_loo_center",
                                "err_632",   "err_632plus",    "gamma",   "overfit_rate",
                                "err_test",  "err_test_center"};
static const double noise[NNOISE] = {0, 0.5, 1, 2};
static const int combo_k[NCOMBO] = {50, 50, 100, 100}, combo_d[NCOMBO] = {3, 4, 3, 4};
static double table[NNOISE][NCOMBO][NF]; /* means in units of h */
/* .632+ with gamma = mean and max over the replicates (columns 7-8) */
static double plus_mean[NNOISE][NCOMBO], plus_max[NNOISE][NCOMBO];

static double field_mean(const double *v, size_t n) {
  double s = 0;
  for (size_t i = 0; i < n; i++)
    s += v[i];
  return s / n;
}

/* The thesis's 26,010 points, unless BSURF_TABLE41_POINTS asks for fewer (the
 * sanitizer build in .ci/run uses 3000: same relations, a ninth of the time). */
static size_t requested_points(void) {
  const char *s = getenv("BSURF_TABLE41_POINTS");
  char *end = NULL;
  long v = s && *s ? strtol(s, &end, 10) : 0;
  return v >= 1000 && v <= 26010 && end && *end == 0 ? (size_t)v : 26010;
}

static void run_all(void) {
  bsurf_cloud clean;
  const size_t want = requested_points();
  assert_int_equal(bsurf_generate(&clean, BSURF_SHAPE_SPHERE, want, BSURF_SAMPLING_REGULAR, 1, 0),
                   BSURF_OK);
  const size_t n = clean.point_count;
  if (want == 26010) assert_int_equal(n, 26010);
  assert_true(n >= 900);
  double h;
  assert_int_equal(bsurf_mean_spacing(clean.xyz, n, 0, &h), BSURF_OK);
  double *noisy = malloc(sizeof(double) * 3 * n), *test = malloc(sizeof(double) * 3 * n);
  double *v[NF];
  for (int f = 0; f < NF; f++)
    v[f] = malloc(sizeof(double) * n);
  bsurf_error_fields out = {v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], v[9]};
  for (int a = 0; a < NNOISE; a++) {
    memcpy(noisy, clean.xyz, sizeof(double) * 3 * n);
    memcpy(test, clean.xyz, sizeof(double) * 3 * n);
    /* training and test samples: same surface points, independent noise */
    assert_int_equal(bsurf_add_noise(noisy, clean.normals, n, BSURF_NOISE_GAUSSIAN, noise[a], h, 1),
                     BSURF_OK);
    assert_int_equal(
        bsurf_add_noise(test, clean.normals, n, BSURF_NOISE_GAUSSIAN, noise[a], h, 1001), BSURF_OK);
    bsurf_neighbors nb;
    assert_int_equal(bsurf_neighbors_build(&nb, noisy, n, 100, 0, NULL, NULL), BSURF_OK);
    for (int c = 0; c < NCOMBO; c++) {
      bsurf_error_options o = bsurf_error_options_default();
      o.k = combo_k[c];
      o.degree = combo_d[c];
      o.bootstrap = 50;
      bsurf_error_report rep;
      assert_int_equal(bsurf_estimate_error(noisy, &nb, test, &o, &out, &rep), BSURF_OK);
      for (int f = 0; f < NF; f++)
        table[a][c][f] = field_mean(v[f], n) / (f == 7 ? 1 : h); /* R is a rate */
      bsurf_error_fields only = {0};
      only.err_632plus = v[5];
      o.gamma = BSURF_GAMMA_MEAN;
      assert_int_equal(bsurf_estimate_error(noisy, &nb, NULL, &o, &only, NULL), BSURF_OK);
      plus_mean[a][c] = field_mean(v[5], n) / h;
      o.gamma = BSURF_GAMMA_MAX;
      assert_int_equal(bsurf_estimate_error(noisy, &nb, NULL, &o, &only, NULL), BSURF_OK);
      plus_max[a][c] = field_mean(v[5], n) / h;
    }
    bsurf_neighbors_free(&nb);
  }
  printf("\nTable 4.1 reproduction: sphere %zu points, h = %.6g, gaussian noise, B = 50, gamma = "
         "fit\n",
         n, h);
  printf("%-8s %-4s %-6s", "fit", "K", "noise");
  for (int f = 0; f < NF; f++)
    printf(" %14s", names[f]);
  printf(" %14s %14s\n", "632plus_meanG", "632plus_maxG");
  for (int c = 0; c < NCOMBO; c++)
    for (int a = 0; a < NNOISE; a++) {
      printf("%-8s %-4d %-6.1f", combo_d[c] == 3 ? "cubic" : "quartic", combo_k[c], noise[a]);
      for (int f = 0; f < NF; f++)
        printf(" %14.4f", table[a][c][f]);
      printf(" %14.4f %14.4f\n", plus_mean[a][c], plus_max[a][c]);
    }
  for (int f = 0; f < NF; f++)
    free(v[f]);
  free(noisy);
  free(test);
  bsurf_cloud_free(&clean);
}

static int setup(void **state) {
  (void)state;
  run_all();
  return 0;
}

static void test_ordering_train_632_loo(void **state) {
  (void)state;
  for (int a = 1; a < NNOISE; a++)
    for (int c = 0; c < NCOMBO; c++) {
      double err = table[a][c][0], e632 = table[a][c][4], loo = table[a][c][2], p = table[a][c][5];
      assert_true(err < e632);
      assert_true(e632 < loo);
      assert_true(e632 <= p && p <= loo); /* .632+ lies between .632 and loo */
      /* section 4.2.1: the maximum gamma moves .632+ away from err_loo, the
       * mean gamma lies in between; all stay within [.632, loo] */
      assert_true(plus_max[a][c] <= plus_mean[a][c] + 1e-12);
      assert_true(e632 <= plus_max[a][c] && plus_mean[a][c] <= loo);
    }
}

static void test_quartic_overfits_at_k50(void **state) {
  (void)state;
  for (int a = 1; a < NNOISE; a++) {
    double gap50 = table[a][1][2] / table[a][0][2];  /* quartic / cubic err_loo, K = 50 */
    double gap100 = table[a][3][2] / table[a][2][2]; /* K = 100 */
    printf("noise %.1f: quartic/cubic err_loo K=50 %.3f, K=100 %.3f\n", noise[a], gap50, gap100);
    assert_true(gap50 >= 1.10);
    assert_true(gap100 < gap50);
  }
}

static void test_grows_with_noise(void **state) {
  (void)state;
  for (int c = 0; c < NCOMBO; c++)
    for (int f = 0; f < NF; f++) {
      if (f == 7) continue; /* R is a rate */
      for (int a = 1; a < NNOISE; a++)
        assert_true(table[a][c][f] > table[a - 1][c][f]);
    }
}

static void test_noise_zero_near_zero(void **state) {
  (void)state;
  for (int c = 0; c < NCOMBO; c++)
    for (int f = 0; f < NF; f++)
      if (f != 6 && f != 7) assert_true(table[0][c][f] < 0.01);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_ordering_train_632_loo),
      cmocka_unit_test(test_quartic_overfits_at_k50),
      cmocka_unit_test(test_grows_with_noise),
      cmocka_unit_test(test_noise_zero_near_zero),
  };
  return cmocka_run_group_tests(tests, setup, NULL);
}
