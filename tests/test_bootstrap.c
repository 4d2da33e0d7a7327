/* The bootstrap engine (thesis chapter 4): resampling and the estimators on
 * a tiny example computed by hand. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <string.h>

#include "bootsurf.h"
#include "bootstrap/bootstrap.h"

#define NEAR(a, b) assert_true(fabs((a) - (b)) < 1e-12)

/* k = 3 points, B = 2 replicates.
 *   y         = 0, 1, 2        f(x_j) = 0.5, 1, 1.5
 *   S_1 counts  2, 1, 0        f*1    = 0, 1, 3
 *   S_2 counts  0, 1, 2        f*2    = 1, 1, 2
 * err_train = (0.5 + 0 + 0.5)/3 = 1/3                          (4.6)
 * err_boot  = (0+0+1 + 1+0+0)/6 = 1/3                          (4.3)
 * C_1 = {2}, C_2 = {}, C_3 = {1}: err_loo = (|1-0| + |3-2|)/2 = 1 (4.4)
 * err_loo_center = |f*2(x_1) - y_1| = 1                        (4.11)
 * err_632 = .368/3 + .632                                       (4.5)
 * gamma(f)   = (2.5 + 2 + 2.5)/9 = 7/9                          (4.10)
 * gamma(f*1) = (3 + 2 + 6)/9 = 11/9,  gamma(f*2) = (2 + 2 + 3)/9 = 7/9
 * fit:  R = (2/3)/(4/9) = 1.5 -> 1, w = 1,   err_632plus = 1
 * mean: gamma = 1, R = (2/3)/(2/3) = 1,      err_632plus = 1
 * max:  gamma = 11/9, R = (2/3)/(8/9) = .75, w = .632/(1 - .276)  */
static const double y[3] = {0, 1, 2}, full[3] = {0.5, 1, 1.5};
static const double boot[6] = {0, 1, 3, 1, 1, 2};
/* 1 where the point is not in the replicate (its count is 0) */
static const double counts[6] = {0, 0, 1, 1, 0, 0};

static void test_estimators_by_hand(void **state) {
  (void)state;
  unsigned char valid[2] = {1, 1};
  double scratch[32];
  bsurf_boot_result r;
  bsurf_boot_estimate(3, 2, y, full, boot, counts, valid, BSURF_GAMMA_FIT, scratch, &r);
  NEAR(r.err_train, 1.0 / 3);
  NEAR(r.err_boot, 1.0 / 3);
  NEAR(r.err_loo, 1.0);
  NEAR(r.err_loo_center, 1.0);
  NEAR(r.err_632, 0.368 / 3 + 0.632);
  NEAR(r.gamma, 7.0 / 9);
  NEAR(r.overfit_rate, 1.0);
  NEAR(r.err_632plus, 1.0);
  assert_int_equal(r.valid_replicates, 2);
  assert_int_equal(r.center_unestimated, 0);

  bsurf_boot_estimate(3, 2, y, full, boot, counts, valid, BSURF_GAMMA_MEAN, scratch, &r);
  NEAR(r.gamma, 1.0);
  NEAR(r.overfit_rate, 1.0);
  NEAR(r.err_632plus, 1.0);

  bsurf_boot_estimate(3, 2, y, full, boot, counts, valid, BSURF_GAMMA_MAX, scratch, &r);
  NEAR(r.gamma, 11.0 / 9);
  NEAR(r.overfit_rate, 0.75);
  double w = 0.632 / (1 - 0.368 * 0.75);
  NEAR(r.err_632plus, (1 - w) / 3 + w);
}

/* A skipped (rank-deficient) replicate takes no part; the centre then is in
 * every valid replicate and falls back to err_loo, flagged. */
static void test_estimators_skip_replicate(void **state) {
  (void)state;
  unsigned char valid[2] = {1, 0};
  double scratch[32];
  bsurf_boot_result r;
  bsurf_boot_estimate(3, 2, y, full, boot, counts, valid, BSURF_GAMMA_FIT, scratch, &r);
  NEAR(r.err_boot, 1.0 / 3);
  NEAR(r.err_loo, 1.0); /* only C_3 = {1} remains */
  NEAR(r.err_loo_center, 1.0);
  assert_int_equal(r.center_unestimated, 1);
  assert_int_equal(r.valid_replicates, 1);
  /* no valid replicate: everything is the training error, R = 0 */
  unsigned char none[2] = {0, 0};
  bsurf_boot_estimate(3, 2, y, full, boot, counts, none, BSURF_GAMMA_FIT, scratch, &r);
  NEAR(r.err_loo, 1.0 / 3);
  NEAR(r.err_632plus, 1.0 / 3);
  NEAR(r.overfit_rate, 0.0);
}

/* R = 0 when gamma <= err (no information, 4.2.1), even though err_loo is
 * far above err_train: .632+ then equals .632.
 *   y = 0, 1, 2, f = 1, 1, 1: err = 2/3, gamma = (2 + 2 + 2)/9 = 2/3
 *   f*1 = f*2 = 3, 3, 3: err_loo = (|3 - 0| + |3 - 2|)/2 = 2 */
static void test_estimators_no_information(void **state) {
  (void)state;
  const double ff[3] = {1, 1, 1};
  const double bb[6] = {3, 3, 3, 3, 3, 3};
  unsigned char valid[2] = {1, 1};
  double scratch[32];
  bsurf_boot_result r;
  bsurf_boot_estimate(3, 2, y, ff, bb, counts, valid, BSURF_GAMMA_FIT, scratch, &r);
  NEAR(r.err_train, 2.0 / 3);
  NEAR(r.gamma, 2.0 / 3);
  NEAR(r.err_loo, 2.0);
  NEAR(r.overfit_rate, 0.0);
  NEAR(r.err_632, 0.368 * 2.0 / 3 + 0.632 * 2.0);
  NEAR(r.err_632plus, r.err_632);
}

static void test_gamma_fast_equals_naive(void **state) {
  (void)state;
  bsurf_rng rng;
  bsurf_rng_init(&rng, 11, 0, 0);
  for (int trial = 0; trial < 200; trial++) {
    int k = 1 + (int)bsurf_rng_below(&rng, 120);
    double pred[120], yy[120], ys[120], prefix[121], scratch[120];
    for (int j = 0; j < k; j++) {
      pred[j] = bsurf_rng_normal(&rng);
      /* some ties between predictions and observations */
      yy[j] = (j % 4 == 0) ? pred[j] : bsurf_rng_normal(&rng);
      ys[j] = yy[j];
    }
    bsurf_sort_doubles(ys, k);
    prefix[0] = 0;
    for (int j = 0; j < k; j++)
      prefix[j + 1] = prefix[j] + ys[j];
    double fast = bsurf_boot_gamma(k, pred, ys, prefix, scratch);
    double slow = bsurf_boot_gamma_naive(k, pred, yy);
    assert_true(fabs(fast - slow) <= 1e-12 * (1 + slow));
  }
}

/* Counts: K draws, reproducible from (seed, point, replicate), different
 * for different keys, and each point missed with probability about
 * (1 - 1/K)^K = .368 (Eq. 4.1). */
static void test_counts(void **state) {
  (void)state;
  enum { K = 50 };
  uint16_t a[K], b[K];
  long missed = 0, total = 0;
  for (uint32_t rep = 0; rep < 2000; rep++) {
    bsurf_boot_counts(9, 123, rep, K, a);
    bsurf_boot_counts(9, 123, rep, K, b);
    assert_memory_equal(a, b, sizeof a);
    int sum = 0;
    for (int j = 0; j < K; j++) {
      sum += a[j];
      missed += a[j] == 0;
      total++;
    }
    assert_int_equal(sum, K);
  }
  double frac = (double)missed / total;
  assert_true(fabs(frac - pow(1 - 1.0 / K, K)) < 0.01);
  bsurf_boot_counts(9, 124, 0, K, a);
  bsurf_boot_counts(9, 123, 0, K, b);
  assert_true(memcmp(a, b, sizeof a) != 0);
  bsurf_boot_counts(10, 123, 0, K, a);
  assert_true(memcmp(a, b, sizeof a) != 0);
}

/* Four replicates in vector lanes give exactly the scalar counts, also when
 * draws are rejected (k = 300: about half the replicates meet a rejection,
 * so groups mix redone and kept lanes; k = 60000: every replicate, redone by
 * the scalar code) and for a partial group. */
/* How many 16-bit chunks resample.c's scalar draw rejects for one replicate
 * (the first k chunks; replacements not counted). */
static int scalar_rejections(uint64_t seed, uint64_t point, uint32_t rep, int k) {
  bsurf_rng rng;
  bsurf_rng_init(&rng, seed, point, rep);
  const uint32_t threshold = 65536u % (uint32_t)k;
  int rejected = 0;
  for (int t = 0; t < k; t += 4) {
    const uint64_t x = bsurf_rng_next(&rng);
    for (int c = 0; c < 4 && t + c < k; c++)
      rejected += ((uint32_t)(x >> (16 * c) & 0xffffu) * (uint32_t)k & 0xffffu) < threshold;
  }
  return rejected;
}

static void test_counts4_equal_scalar(void **state) {
  (void)state;
  static uint16_t four[4 * 60000], one[60000], draws[4 * 60000], hist[60000];
  /* the lane fallback is exercised: every k = 60000 replicate below meets a
   * rejection, some but not all of the k = 300 ones do */
  int rejections = 0, kept = 0;
  for (uint32_t b0 = 0; b0 < 12; b0 += 4)
    for (uint32_t l = 0; l < 4; l++) {
      rejections += scalar_rejections(5, 77 + b0, b0 + l, 60000) > 0;
      kept += scalar_rejections(5, 77 + b0, b0 + l, 300) == 0;
    }
  assert_int_equal(rejections, 12);
  assert_true(kept > 0 && kept < 12);
  const int ks[] = {2, 3, 30, 50, 51, 300, 60000};
  for (size_t t = 0; t < sizeof ks / sizeof ks[0]; t++) {
    const int k = ks[t];
    for (uint32_t b0 = 0; b0 < 12; b0 += 4)
      for (int nrep = 1; nrep <= 4; nrep++) {
        bsurf_boot_counts4(5, 77 + b0, b0, nrep, k, four, NULL);
        for (int l = 0; l < nrep; l++) {
          bsurf_boot_counts(5, 77 + b0, b0 + (uint32_t)l, k, one);
          assert_memory_equal(one, four + (size_t)l * k, (size_t)k * sizeof *one);
        }
        /* with the draws: the same counts, and the draws' histogram is them */
        /* interleaved (the weights' lanes): the same counts */
        bsurf_boot_counts4_lanes(5, 77 + b0, b0, nrep, k, draws);
        for (int l = 0; l < 4; l++) {
          if (l < nrep) bsurf_boot_counts(5, 77 + b0, b0 + (uint32_t)l, k, one);
          for (int j = 0; j < k; j++)
            assert_int_equal(draws[4 * (size_t)j + l], l < nrep ? one[j] : 0);
        }
        bsurf_boot_counts4(5, 77 + b0, b0, nrep, k, four, draws);
        for (int l = 0; l < nrep; l++) {
          bsurf_boot_counts(5, 77 + b0, b0 + (uint32_t)l, k, one);
          assert_memory_equal(one, four + (size_t)l * k, (size_t)k * sizeof *one);
          memset(hist, 0, (size_t)k * sizeof *hist);
          for (int t = 0; t < k; t++) {
            assert_true(draws[(size_t)l * k + t] < k);
            hist[draws[(size_t)l * k + t]]++;
          }
          assert_memory_equal(one, hist, (size_t)k * sizeof *one);
        }
      }
  }
}

/* bsurf_sort_doubles (rank counting up to 128 values, qsort above) gives the
 * bits of a stable insertion sort: ties (many, from a small value set), and
 * -0 before or after +0 as in the input. */
static void test_sort_doubles_stable(void **state) {
  (void)state;
  uint64_t x = 12345;
  for (int n = 1; n <= 134; n++)
    for (int rep = 0; rep < 20; rep++) {
      double a[134], ref[134];
      for (int i = 0; i < n; i++) {
        x = x * 6364136223846793005ull + 1442695040888963407ull;
        const int v = (int)(x >> 59); /* 0..31: many ties */
        a[i] = v == 0 ? (x >> 20 & 1 ? -0.0 : 0.0) : (double)(v - 16) * 0.25;
      }
      memcpy(ref, a, sizeof ref);
      for (int i = 1; i < n; i++) { /* stable insertion sort */
        double t = ref[i];
        int j = i - 1;
        while (j >= 0 && ref[j] > t) {
          ref[j + 1] = ref[j];
          j--;
        }
        ref[j + 1] = t;
      }
      bsurf_sort_doubles(a, n);
      if (n <= 128) assert_memory_equal(a, ref, (size_t)n * sizeof *a);
      for (int i = 1; i < n; i++)
        assert_true(a[i - 1] <= a[i]); /* qsort: order only */
    }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_estimators_by_hand),
      cmocka_unit_test(test_estimators_skip_replicate),
      cmocka_unit_test(test_estimators_no_information),
      cmocka_unit_test(test_gamma_fast_equals_naive),
      cmocka_unit_test(test_counts),
      cmocka_unit_test(test_counts4_equal_scalar),
      cmocka_unit_test(test_sort_doubles_stable),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
