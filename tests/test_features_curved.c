/* The variance test's null on curved, unevenly sampled surfaces (issue 22;
 * features_variance.c, "the null's scale"): the expected lambda0 of a
 * smooth patch E(g) = sigma^2 + c g, g = (lambda1 + lambda2)^2, fitted to the
 * cloud, and a featureless surface whose density varies 10x flagged at about
 * the tests' level, at light and at heavy noise. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "algo/algo.h"
#include "bootsurf.h"

static uint64_t rng_next(uint64_t *s) {
  *s ^= *s << 13, *s ^= *s >> 7, *s ^= *s << 17;
  return *s;
}

static double rng_uniform(uint64_t *s) {
  return (double)(rng_next(s) >> 11) * (1.0 / 9007199254740992.0);
}

/* E(g) = sigma2 + c g fitted on its pieces as the callers use them */
static bsurf_fvar_fit fit_of(const double *l0, const double *g, size_t n, double *s2) {
  double *a = malloc(n * sizeof(double)), *b = malloc(n * sizeof(double));
  memcpy(a, g, n * sizeof(double));
  bsurf_fvar_fit f;
  bsurf_fvar_fit_prepare(&f, a, n);
  for (size_t i = 0; i < n; i++)
    bsurf_fvar_fit_put(&f, a, g[i], l0[i]);
  memcpy(b, l0, n * sizeof(double));
  *s2 = bsurf_median(b, n);
  bsurf_fvar_fit_solve(&f, a, *s2);
  free(a);
  free(b);
  return f;
}

/* Exact cases: lambda0 = sigma^2 + c g times a chi^2-like scatter (the
 * median of the scatter is 1), g spread over 100x, and a fifth of the points
 * "features" (lambda0 50 times larger, anywhere in g): the fit recovers
 * sigma^2 and c to 3% (after the medians' known bias). lambda0 that does not grow with g (a flat
 * cloud, a uniform density) gives c = 0 and sigma2 = the median lambda0
 * exactly, and scaling changes nothing. */
static void test_fit_exact(void **state) {
  (void)state;
  const size_t n = 20000;
  double *l0 = malloc(n * sizeof(double)), *g = malloc(n * sizeof(double));
  double *u = malloc(n * sizeof(double)), *w = malloc(n * sizeof(double));
  uint64_t r = 0x853c49e6748fea9bull;
  for (int model = 0; model < 2; model++) {
    const double sigma2 = 2.0, c = model ? 0.5 : 0;
    for (size_t i = 0; i < n; i++) {
      g[i] = pow(100.0, rng_uniform(&r));
      /* median 1: exp of a symmetric variate */
      const double scatter = exp(0.5 * (rng_uniform(&r) - 0.5));
      l0[i] = (sigma2 + c * g[i]) * scatter * (i % 5 == 0 ? 50 : 1);
      u[i] = w[i] = 1;
    }
    double s2;
    bsurf_fvar_fit f = fit_of(l0, g, n, &s2);
    printf("model c %.2f: fitted sigma2 %.4f c %.4f (median lambda0 %.4f, %d bins)\n", c, f.sigma2,
           f.c, s2, f.bins);
    assert_int_equal(f.bins, FVAR_FIT_BINS);
    if (model) {
      /* a fifth of features moves each bin's median to the scatter's
       * 0.5 / 0.8 quantile: exp((0.625 - 0.5) / 2) of the model */
      const double bias = exp(0.0625);
      assert_true(fabs(f.sigma2 / (bias * sigma2) - 1) < 0.03);
      assert_true(fabs(f.c / (bias * c) - 1) < 0.03);
      /* the scaled u is s2 / E(g): 1 at the g where E = s2, lower where sparser */
      bsurf_fvar_fit_scale(&f, s2, n, g, u, w);
      for (size_t i = 0; i < n; i++) {
        const double gg = g[i] < f.g[0] ? f.g[0] : g[i];
        assert_true(fabs(u[i] - s2 / (f.sigma2 + 1.5 * f.c * gg)) < 1e-12 * u[i]);
        assert_true(u[i] == w[i]);
      }
    } else {
      assert_true(f.c == 0);
      assert_true(f.sigma2 == s2);
      bsurf_fvar_fit_scale(&f, s2, n, g, u, w);
      for (size_t i = 0; i < n; i++)
        assert_true(u[i] == 1 && w[i] == 1);
    }
  }
  /* too few points for two bins of 64: one bin, the median */
  double s2;
  bsurf_fvar_fit f = fit_of(l0, g, 100, &s2);
  assert_int_equal(f.bins, 1);
  assert_true(f.c == 0 && f.sigma2 == s2);
  free(l0);
  free(g);
  free(u);
  free(w);
}

/* A featureless shape whose sampling density varies 10x (the development
 * set's `aniso` sampling in small: random points thinned with keep
 * probability 0.1^t, t the x coordinate scaled to [0, 1]), uniform noise
 * 0.25 mean spacings, the default options. Where the sampling is sparse the
 * neighbourhood is wider and the surface's curvature raises lambda0 and nu
 * (r^4); with the median lambda0 as the noise this was read as an edge.
 * Bound: the two tests at alpha each flag at most 2 alpha of a flat area
 * (test_null_featureless), with the same 2.5x allowance for the estimate.
 * Measured (100,000 points thinned to about 39,000): the torus 24.3%
 * flagged with s^2 = the median lambda0 as the noise (23.1% by the variance
 * test), 2.2% with V(g) (0.9%); the sphere 1.4% (0.1%); with the quadric
 * check (the default since) 1.3% (0.9%) and 1.3% (0.1%). */
static double aniso_rate(bsurf_shape shape, bsurf_noise_model model, double level, double *alpha) {
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, shape, 100000, BSURF_SAMPLING_RANDOM, 7, 0), BSURF_OK);
  double lo = INFINITY, hi = -INFINITY;
  for (size_t i = 0; i < c.point_count; i++) {
    lo = fmin(lo, c.xyz[3 * i]);
    hi = fmax(hi, c.xyz[3 * i]);
  }
  uint64_t r = 0x9e3779b97f4a7c15ull;
  size_t m = 0;
  for (size_t i = 0; i < c.point_count; i++) {
    const double t = (c.xyz[3 * i] - lo) / (hi - lo);
    if (rng_uniform(&r) < pow(0.1, t)) {
      memmove(&c.xyz[3 * m], &c.xyz[3 * i], 3 * sizeof(double));
      memmove(&c.normals[3 * m], &c.normals[3 * i], 3 * sizeof(double));
      m++;
    }
  }
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, m, 0, &h), BSURF_OK);
  assert_int_equal(bsurf_add_noise(c.xyz, c.normals, m, model, level, h, 3), BSURF_OK);
  bsurf_neighbors nb;
  bsurf_feature_options o = bsurf_feature_options_default();
  /* the lists as the CLI builds them: up to the K rule's cap, so that K can grow */
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, m, bsurf_fvar_k_cap(&o, m), 0, NULL, NULL),
                   BSURF_OK);
  uint8_t *feat = malloc(m);
  double *z = malloc(m * sizeof(double));
  bsurf_feature_report rep;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &o, feat, z, &rep), BSURF_OK);
  size_t byz = 0;
  for (size_t i = 0; i < m; i++)
    byz += z[i] > rep.threshold;
  free(z);
  *alpha = o.false_positive_rate;
  const double rate = (double)rep.feature_points / (double)m;
  printf("%s, density varying 10x (%zu points), %s noise %.2f h: K %d, %.4f flagged (%.4f "
         "by the variance test)\n",
         bsurf_shape_name(shape), m, model == BSURF_NOISE_UNIFORM ? "uniform" : "gaussian", level,
         rep.k, rate, (double)byz / (double)m);
  free(feat);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
  return rate;
}

static void test_aniso_featureless(void **state) {
  (void)state;
  double alpha;
  const double torus = aniso_rate(BSURF_SHAPE_TORUS, BSURF_NOISE_UNIFORM, 0.25, &alpha);
  assert_true(torus <= 2.5 * 2 * alpha);
  const double sphere = aniso_rate(BSURF_SHAPE_SPHERE, BSURF_NOISE_UNIFORM, 0.25, &alpha);
  assert_true(sphere <= 2.5 * 2 * alpha);
}

/* The same shapes at heavy noise, gaussian 2 h (K grows: the lists are
 * built to the K rule's cap), the same bound. Measured: K 60, the torus
 * 4.4% flagged (3.2% by the variance test), the sphere 3.2% (2.0%). The
 * simulated patches with their neighbourhoods on the noisy points (tried,
 * not kept: docs/features.md, "The null's patches on noisy points") read the
 * noise right but take one null at the cloud's median eta, too lenient
 * where the points are dense: 8.3% (6.6%) and 7.5% (5.9%), failing here. */
static void test_aniso_featureless_heavy(void **state) {
  (void)state;
  double alpha;
  const double torus = aniso_rate(BSURF_SHAPE_TORUS, BSURF_NOISE_GAUSSIAN, 2.0, &alpha);
  const double sphere = aniso_rate(BSURF_SHAPE_SPHERE, BSURF_NOISE_GAUSSIAN, 2.0, &alpha);
  assert_true(torus <= 2.5 * 2 * alpha);
  assert_true(sphere <= 2.5 * 2 * alpha);
}

/* The quadric check (features_variance.c, step 7). An L-shaped part, a
 * horizontal and a vertical plate 30 x 60 spacings (unit density, random
 * positions), joined either by a 90 degree crease or by a smooth quarter
 * cylinder of radius rho = 4 spacings (a fillet: C1, no feature), noise
 * along the normal (uniform, level x the mean spacing). Where is the
 * crease's or fillet's band: within 2 spacings of the crease line, or on
 * the fillet and within 2 spacings of its ends. Returns the flagged shares
 * of the band and of the rest, with the check (quadric_angle 45) or
 * without it (0), and the report. */
static void l_part(double rho, bsurf_noise_model model, double level, double quadric_angle,
                   double *band, double *rest, bsurf_feature_report *rep) {
  const double W = 30, L = 60, arc = rho * 3.14159265358979323846 / 2;
  const double area = (2 * W + arc) * L;
  const size_t n = (size_t)area;
  double *xyz = malloc(3 * n * sizeof(double)), *nrm = malloc(3 * n * sizeof(double));
  unsigned char *in_band = malloc(n);
  uint64_t r = 0x2545f4914f6cdd1dull;
  for (size_t i = 0; i < n; i++) {
    /* s: the arc length across the profile, from the horizontal plate's
     * far edge (0) to the vertical plate's top (2 W + arc) */
    const double s = rng_uniform(&r) * (2 * W + arc), y = rng_uniform(&r) * L;
    double *p = &xyz[3 * i], *q = &nrm[3 * i];
    if (s < W) { /* horizontal: z = 0, x from -W - rho to -rho */
      p[0] = s - W - rho, p[2] = 0, q[0] = 0, q[2] = 1;
    } else if (s < W + arc) { /* the fillet about (-rho, rho) */
      const double a = (s - W) / (rho > 0 ? rho : 1);
      p[0] = -rho + rho * sin(a), p[2] = rho - rho * cos(a), q[0] = -sin(a), q[2] = cos(a);
    } else { /* vertical: x = 0, z from rho up */
      p[0] = 0, p[2] = rho + (s - W - arc), q[0] = -1, q[2] = 0;
    }
    p[1] = y, q[1] = 0;
    in_band[i] = s > W - 2 && s < W + arc + 2;
  }
  double h;
  assert_int_equal(bsurf_mean_spacing(xyz, n, 0, &h), BSURF_OK);
  assert_int_equal(bsurf_add_noise(xyz, nrm, n, model, level, h, 5), BSURF_OK);
  bsurf_feature_options o = bsurf_feature_options_default();
  o.quadric_angle = quadric_angle;
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, n, bsurf_fvar_k_cap(&o, n), 0, NULL, NULL),
                   BSURF_OK);
  uint8_t *feat = malloc(n);
  assert_int_equal(bsurf_detect_features(xyz, &nb, &o, feat, NULL, rep), BSURF_OK);
  size_t nb_band = 0, fb = 0, fr = 0;
  for (size_t i = 0; i < n; i++) {
    nb_band += in_band[i];
    fb += in_band[i] && feat[i];
    fr += !in_band[i] && feat[i];
  }
  *band = (double)fb / (double)nb_band;
  *rest = (double)fr / (double)(n - nb_band);
  printf("%s, %s noise %.2f h, quadric angle %g: K %d, K_q %d (crease kept %.2f), "
         "band %.3f flagged, rest %.3f, %zu cleared\n",
         rho > 0 ? "fillet rho 4" : "crease", model == BSURF_NOISE_UNIFORM ? "uniform" : "gaussian",
         level, quadric_angle, rep->k, rep->quadric_k, rep->quadric_power, *band, *rest,
         rep->quadric_cleared);
  free(feat);
  bsurf_neighbors_free(&nb);
  free(xyz);
  free(nrm);
  free(in_band);
}

/* At light noise the check runs (K_q found) and clears the fillet, whose
 * normals turn by 90 degrees within 6 spacings, while it keeps the crease:
 * the crease's band flagged with the check at least 0.9 of its share
 * without it (the check's own guarantee on its simulated 45 degree crease
 * is 9 in 10 of the points within a spacing; this one is steeper); the
 * fillet's band flagged at most a third of its share without the check.
 * At heavy noise (gaussian 2 h) no K_q keeps 9 in 10 of a 45 degree crease:
 * no check, the same flags as without it. Measured: see the test's output
 * (docs/features.md, "The quadric check"). */
static void test_quadric_check(void **state) {
  (void)state;
  double b0, r0, b1, r1;
  bsurf_feature_report rep;
  l_part(0, BSURF_NOISE_UNIFORM, 0.25, 0, &b0, &r0, &rep);
  assert_int_equal(rep.quadric_k, 0);
  l_part(0, BSURF_NOISE_UNIFORM, 0.25, 45, &b1, &r1, &rep);
  assert_true(rep.quadric_k > 0);
  assert_true(rep.quadric_power >= 0.9);
  assert_true(b1 >= 0.9 * b0);
  assert_true(r1 <= r0);
  l_part(4, BSURF_NOISE_UNIFORM, 0.25, 0, &b0, &r0, &rep);
  l_part(4, BSURF_NOISE_UNIFORM, 0.25, 45, &b1, &r1, &rep);
  assert_true(rep.quadric_k > 0);
  assert_true(b0 > 0.3); /* the test alone reads the fillet as an edge */
  assert_true(b1 <= b0 / 3);
  /* heavy noise: no check */
  l_part(0, BSURF_NOISE_GAUSSIAN, 2.0, 0, &b0, &r0, &rep);
  l_part(0, BSURF_NOISE_GAUSSIAN, 2.0, 45, &b1, &r1, &rep);
  assert_int_equal(rep.quadric_k, 0);
  assert_true(rep.quadric_power < 0.9);
  assert_true(b1 == b0 && r1 == r0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_fit_exact),
      cmocka_unit_test(test_aniso_featureless),
      cmocka_unit_test(test_aniso_featureless_heavy),
      cmocka_unit_test(test_quadric_check),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
