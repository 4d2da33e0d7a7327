/* The smoothing guard's noise estimate (docs/smoothing.md, "The noise
 * estimate"): the share of the noise variance a K-ball keeps (its table
 * against the quadrature it was made by), and the estimate on generated
 * shapes at noise levels from a quarter spacing to three spacings, where a
 * 50-neighbourhood is about as thick as it is wide. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"
#include "algo/smooth_ctx.h" /* guard_ball_share, bsurf_ball_count */

#define PI 3.14159265358979323846

/* kappa(t) and count(t) by quadrature (ball_scale.c has the derivation):
 * over z0 ~ N(0, 1) (midpoints on [-8, 8]) and over the ball's points at
 * distance rho = t sin(th) from the centre's normal line (midpoints in th,
 * which takes out the square root at rho = t), the variance of N(0, 1)
 * truncated to [z0 - a, z0 + a], a = t cos(th), weighted by rho and the
 * window's mass; count: 2 pi times that weight. */
static double ball_quad(double t, double *count) {
  const int nz = 801, nth = 200;
  const double dz = 16.0 / nz;
  double tot = 0, cnt = 0;
  for (int iz = 0; iz < nz; iz++) {
    const double z0 = -8 + (iz + 0.5) * dz;
    const double wz = exp(-0.5 * z0 * z0) / sqrt(2 * PI) * dz;
    double num = 0, den = 0;
    for (int it = 0; it < nth; it++) {
      const double th = (it + 0.5) / nth * (PI / 2);
      const double rho = t * sin(th), a = t * cos(th), w = rho * t * cos(th);
      const double al = z0 - a, be = z0 + a;
      const double M = 0.5 * (erf(be / sqrt(2.0)) - erf(al / sqrt(2.0)));
      den += w * M;
      if (!(M > 1e-12)) continue;
      const double pa = exp(-0.5 * al * al) / sqrt(2 * PI);
      const double pb = exp(-0.5 * be * be) / sqrt(2 * PI);
      const double m1 = (pa - pb) / M;
      num += w * M * (1 + (al * pa - be * pb) / M - m1 * m1);
    }
    tot += wz * num / den;
    cnt += wz * 2 * PI * den * (PI / 2) / nth;
  }
  if (count) *count = cnt;
  return tot;
}

static double ball_share_quad(double t) {
  return ball_quad(t, NULL);
}

/* The ball's count (ball_scale.c, the scale rule's K -> t) at and between
 * its nodes within 1e-3 (relative) of the quadrature, its wide-ball limit
 * pi (t^2 - 2) (the heights' spread comes off the squared radius), a volume
 * (t^3) below t = 1, and increasing. */
static void test_ball_count(void **state) {
  (void)state;
  double prev = 0;
  for (int j = 64; j >= 2; j--) {
    const double t = 64.0 / j, c = bsurf_ball_count(t);
    double q;
    ball_quad(t, &q);
    if (j % 16 == 0) print_message("count(%.3f) = %.4f (quadrature %.4f)\n", t, c, q);
    assert_true(fabs(c / q - 1) < 1e-3);
    assert_true(c > prev);
    prev = c;
  }
  assert_true(fabs(bsurf_ball_count(32) / (PI * (32.0 * 32 - 2)) - 1) < 1e-5);
  assert_true(fabs(bsurf_ball_count(0.5) / bsurf_ball_count(1) - 0.125) < 1e-12);
}

/* The table at its nodes t = 32 / j and between them, within 1e-3 of the
 * quadrature; 1 for a ball much wider than the noise, t^2 / 5 (a uniform
 * ball's heights) as t -> 0 (read at t = 1 below that), decreasing. */
static void test_ball_share(void **state) {
  (void)state;
  double prev = 1.0;
  for (int j = 1; j <= 64; j++) {
    const double t = 64.0 / j;
    const double q = ball_share_quad(t), g = guard_ball_share(t);
    if (j % 8 == 0) print_message("kappa(%.3f) = %.5f (quadrature %.5f)\n", t, g, q);
    assert_true(fabs(g - q) < 1e-3);
    assert_true(g <= prev + 1e-12);
    prev = g;
  }
  assert_true(fabs(guard_ball_share(1e6) - 1.0) < 1e-6);
  assert_true(fabs(ball_share_quad(0.05) / (0.05 * 0.05 / 5) - 1) < 0.01);
  assert_true(guard_ball_share(0.5) == guard_ball_share(1.0));
}

/* The estimate (bsurf_smooth_report.noise) on a torus and a sphere (20,000
 * random points, K = 50, seed 5, naive smoothing with the degree test on, as
 * bilateral and multipass fit: the same records; B = 5, which the estimate
 * does not use) at gaussian sigma = 0.25, 0.5, 1.5 and 3 h and uniform
 * U[-a, a], a = 0.25, 0.5 and 1.5 h (sigma = a / sqrt 3). Without the
 * ball's share the estimate read 0.62-0.67 sigma at gaussian 3 h (a ball of
 * 50 points is then about 1.8 sigma wide); with it, measured: see
 * docs/smoothing.md, "The noise estimate". Bounds: within 0.15 of sigma
 * for every case up to 1.5 h (the uniform and the gaussian alike), and
 * within 0.25 at gaussian 3 h. */
static void test_noise_estimate_levels(void **state) {
  (void)state;
  const bsurf_shape shapes[2] = {BSURF_SHAPE_TORUS, BSURF_SHAPE_SPHERE};
  const struct {
    bsurf_noise_model model;
    double level, tol;
  } noises[7] = {{BSURF_NOISE_GAUSSIAN, 0.25, 0.15}, {BSURF_NOISE_GAUSSIAN, 0.5, 0.15},
                 {BSURF_NOISE_GAUSSIAN, 1.5, 0.15},  {BSURF_NOISE_GAUSSIAN, 3.0, 0.25},
                 {BSURF_NOISE_UNIFORM, 0.25, 0.15},  {BSURF_NOISE_UNIFORM, 0.5, 0.15},
                 {BSURF_NOISE_UNIFORM, 1.5, 0.15}};
  for (int s = 0; s < 2; s++)
    for (int v = 0; v < 7; v++) {
      bsurf_cloud c;
      assert_int_equal(bsurf_generate(&c, shapes[s], 20000, BSURF_SAMPLING_RANDOM, 5, 0), BSURF_OK);
      double h;
      assert_int_equal(bsurf_mean_spacing(c.xyz, c.point_count, 2, &h), BSURF_OK);
      const size_t n = c.point_count;
      assert_int_equal(
          bsurf_add_noise(c.xyz, c.normals, n, noises[v].model, noises[v].level, h, 41 + v),
          BSURF_OK);
      const double sigma =
          noises[v].level * h / (noises[v].model == BSURF_NOISE_UNIFORM ? sqrt(3.0) : 1.0);
      bsurf_neighbors nb;
      assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, 50, 2, NULL, NULL), BSURF_OK);
      bsurf_smooth_options o = bsurf_smooth_options_default();
      o.method = BSURF_SMOOTH_NAIVE;
      o.degree_test = 1;
      o.error.bootstrap = 5;
      o.error.threads = 2;
      bsurf_smooth_report rep;
      double *out = malloc(n * 3 * sizeof(double));
      assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, &rep), BSURF_OK);
      print_message("noise estimate, shape %d, %s %.2f h: %.3f h (true %.3f h, ratio %.3f)\n",
                    (int)shapes[s], noises[v].model == BSURF_NOISE_UNIFORM ? "uniform" : "gaussian",
                    noises[v].level, rep.noise / h, sigma / h, rep.noise / sigma);
      assert_true(fabs(rep.noise - sigma) < noises[v].tol * sigma);
      free(out);
      bsurf_neighbors_free(&nb);
      bsurf_cloud_free(&c);
    }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_ball_share),
      cmocka_unit_test(test_ball_count),
      cmocka_unit_test(test_noise_estimate_levels),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
