/* The MSE rule where the quadric does not fit (src/algo/kselect_lof.c;
 * docs/normals.md, "Choosing K", *where the quadric does not fit*): the
 * lack-of-fit gate's exact cases, the gate silent on a noisy plane at a
 * fixed seed, smaller K and smaller errors near a cube's edges than
 * without the empirical bias, -j1 == -j2; the test for planes thinner
 * than the noise (ksel_thin_plane): its exact cases, its level on noisy
 * planes at a fixed seed, and a ring whose noise lies in its plane. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include <stdint.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"
#include "algo/algo.h"
#include "algo/kselect.h"

static const int KS[] = {15, 20, 25, 30, 40, 50, 60, 70, 80};
#define NKS ((int)(sizeof KS / sizeof KS[0]))

/* the upper 0.05 / 9 quantile of the standard normal (the Bonferroni
 * level of 9 candidates) */
#define Z9 2.5391848136513118

static double angle_u(const double *a, const double *b) {
  double d = fabs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
  double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]), d);
}

/* The gate: silent where every residual variance is the noise's; from the
 * first candidate that rejects on (just above its critical ratio: the
 * chi^2 quantile at the Bonferroni level; just below: not); none where the
 * smallest candidate already rejects; NaN (no fit) never rejects. */
static void test_gate_exact(void **state) {
  (void)state;
  const double s2 = 2.0;
  double rssv[NKS];
  int gate[NKS];
  for (int a = 0; a < NKS; a++)
    rssv[a] = s2;
  assert_int_equal(ksel_lof_gate(rssv, KS, NKS, s2, ksel_level_z(NKS), gate), 0);
  for (int a = 0; a < NKS; a++)
    assert_int_equal(gate[a], 0);
  /* candidate 3 (K = 30) just above its critical value, 4 just below */
  const double c3 = bsurf_chi2_ratio_wh(KS[3] - 6, Z9), c4 = bsurf_chi2_ratio_wh(KS[4] - 6, Z9);
  rssv[3] = s2 * c3 * (1 + 1e-5);
  rssv[4] = s2 * c4 * (1 - 1e-5);
  assert_int_equal(ksel_lof_gate(rssv, KS, NKS, s2, ksel_level_z(NKS), gate), 1);
  for (int a = 0; a < NKS; a++)
    assert_int_equal(gate[a], a >= 3);
  rssv[3] = s2 * c3 * (1 - 1e-5); /* below: nothing rejects */
  assert_int_equal(ksel_lof_gate(rssv, KS, NKS, s2, ksel_level_z(NKS), gate), 0);
  rssv[3] = NAN;
  assert_int_equal(ksel_lof_gate(rssv, KS, NKS, s2, ksel_level_z(NKS), gate), 0);
  /* the smallest rejects: the sampling does not resolve the surface, no gate */
  rssv[0] = 100 * s2;
  rssv[5] = 100 * s2;
  assert_int_equal(ksel_lof_gate(rssv, KS, NKS, s2, ksel_level_z(NKS), gate), 0);
  for (int a = 0; a < NKS; a++)
    assert_int_equal(gate[a], 0);
}

/* The thin-plane test (ksel_thin_plane): K l3 just below (K - 3) s2 q, q the
 * lower Bonferroni quantile of chi^2_{K-3} / (K - 3), rejects; just above
 * does not; nor does a neighbourhood that does not resolve the noise (its
 * K-th neighbour within 5 deviations), nor s2 <= 0. The level's z is the
 * lack-of-fit gate's. */
static void test_thin_exact(void **state) {
  (void)state;
  assert_true(fabs(ksel_level_z(NKS) - Z9) < 1e-9);
  const double s2 = 0.25, rk2 = 100 * s2;
  for (int a = 0; a < NKS; a++) {
    const int K = KS[a];
    const double l3 = (K - 3) * s2 * bsurf_chi2_ratio_wh(K - 3, -Z9) / K;
    assert_int_equal(ksel_thin_plane(K, l3 * (1 - 1e-6), rk2, s2, Z9), 1);
    assert_int_equal(ksel_thin_plane(K, l3 * (1 + 1e-6), rk2, s2, Z9), 0);
    assert_int_equal(ksel_thin_plane(K, 0, 24.9 * s2, s2, Z9), 0); /* not resolved */
    assert_int_equal(ksel_thin_plane(K, 0, 25.1 * s2, s2, Z9), 1);
    assert_int_equal(ksel_thin_plane(K, 0, rk2, 0, Z9), 0);
  }
}

/* Which of a thin plane's explanations holds (ksel_same_plane): a plane
 * whose normal is nearer parallel to the K_max neighbours' is the surface's
 * own (1), nearer perpendicular a cross-section's (0); the boundary is 45
 * degrees, and the sign of either normal does not matter. */
static void test_same_plane(void **state) {
  (void)state;
  const double N[3] = {0, 0, 1}, up[3] = {0, 0, -1}, side[3] = {1, 0, 0};
  assert_int_equal(ksel_same_plane(N, N), 1);
  assert_int_equal(ksel_same_plane(up, N), 1);
  assert_int_equal(ksel_same_plane(side, N), 0);
  const double t = 3.14159265358979323846 / 4;
  const double in[3] = {sin(t - 1e-6), 0, cos(t - 1e-6)},
               out[3] = {sin(t + 1e-6), 0, cos(t + 1e-6)};
  assert_int_equal(ksel_same_plane(in, N), 1);
  assert_int_equal(ksel_same_plane(out, N), 0);
}

/* The drift's two witnesses (drift_of, kselect.c), exact: candidate a's
 * normal is z and candidate j's tilted from it with sin^2 = s_j, so each
 * term is s_j - c (V(j) - V(a)). With a = 3 smaller candidates the second
 * largest at c2 = (3 + ln 3) / 2; one wrong small candidate (s = 0.75) no
 * longer decides, as the maximum did. With one assessed smaller candidate
 * its term at c = 3; with none, -inf; two equal largest terms give that
 * value. */
#define NEAR(x, y) (fabs((x) - (y)) < 1e-12)
static void set_tilt(double *n, double s) {
  n[0] = sqrt(s), n[1] = 0, n[2] = sqrt(1 - s);
}
static void test_drift_of(void **state) {
  (void)state;
  double nrm[12], var[4] = {0.02, 0.006, 0.004, 0.002};
  const double s[3] = {0.75, 0.01, 0.004};
  for (int j = 0; j < 3; j++)
    set_tilt(&nrm[3 * j], s[j]);
  set_tilt(&nrm[9], 0);
  const double c2 = (3 + log(3.0)) / 2;
  assert_true(NEAR(drift_of(nrm, var, 3), 0.01 - c2 * 0.004)); /* 0.0018027754226638 */
  /* the wrong candidate unassessed: the second largest of the other two,
   * still at c2 of a = 3 */
  var[0] = INFINITY;
  assert_true(NEAR(drift_of(nrm, var, 3), 0.004 - c2 * 0.002));
  /* one assessed smaller candidate (the others unassessed): its term at 3 */
  var[1] = INFINITY;
  assert_true(NEAR(drift_of(nrm, var, 3), 0.004 - 3 * 0.002));
  /* none */
  var[2] = INFINITY;
  assert_true(isinf(drift_of(nrm, var, 3)) && drift_of(nrm, var, 3) < 0);
  /* a = 1: the single comparison, c = 3 */
  const double v1[2] = {0.02, 0.006};
  double n1[6];
  set_tilt(&n1[0], 0.75);
  set_tilt(&n1[3], 0);
  assert_true(NEAR(drift_of(n1, v1, 1), 0.75 - 3 * 0.014));
  /* a = 0: nothing to compare with */
  assert_true(isinf(drift_of(n1, v1, 0)));
  /* two equal largest terms: that value */
  double n2[9], v2[3] = {0.01, 0.01, 0.002};
  set_tilt(&n2[0], 0.3);
  set_tilt(&n2[3], 0.3);
  set_tilt(&n2[6], 0);
  assert_true(NEAR(drift_of(n2, v2, 2), 0.3 - (3 + log(1.0)) / 2 * 0.008));
}

static uint64_t rng_state = 88172645463325252ull;
static double unif(void) { /* xorshift64*, (0, 1) */
  rng_state ^= rng_state >> 12, rng_state ^= rng_state << 25, rng_state ^= rng_state >> 27;
  return ((rng_state * 2685821657736338717ull) >> 11) * (1.0 / 9007199254740992.0) + 1e-17;
}
static double gauss(void) {
  return sqrt(-2 * log(unif())) * cos(2 * 3.14159265358979323846 * unif());
}

/* K points' covariance (about the centroid): its smallest eigenvalue */
/* the K points' PCA eigenvalues, ascending */
static void pca_eigen(const double (*p)[3], int K, double ev[3]) {
  double mu[3] = {0, 0, 0}, C[3][3] = {{0}}, V[3][3];
  for (int j = 0; j < K; j++)
    for (int t = 0; t < 3; t++)
      mu[t] += p[j][t] / K;
  for (int j = 0; j < K; j++)
    for (int t = 0; t < 3; t++)
      for (int u = 0; u < 3; u++)
        C[t][u] += (p[j][t] - mu[t]) * (p[j][u] - mu[u]) / K;
  bsurf_eigen_sym3(C, ev, V);
}

static double smallest_ev(const double (*p)[3], int K) {
  double ev[3];
  pca_eigen(p, K, ev);
  return ev[0];
}

/* K points uniform on a disc of radius r in z = 0, heights N(0, sz^2) */
static void disc_points(double (*p)[3], int K, double r, double sz) {
  for (int j = 0; j < K; j++) {
    const double rho = r * sqrt(unif()), phi = 2 * 3.14159265358979323846 * unif();
    p[j][0] = rho * cos(phi), p[j][1] = rho * sin(phi), p[j][2] = sz * gauss();
  }
}

/* K consecutive points from i0 of a ring of 300 points of radius 1 in
 * z = 0, radial noise N(0, sr^2) and heights N(0, sz^2) */
static void ring_arc(double (*p)[3], int K, int i0, double sr, double sz) {
  for (int j = 0; j < K; j++) {
    const double phi = 2 * 3.14159265358979323846 * (i0 + j) / 300, r = 1 + sr * gauss();
    p[j][0] = r * cos(phi), p[j][1] = r * sin(phi), p[j][2] = sz * gauss();
  }
}

/* The disc test (ksel_disc), at a fixed seed: K points uniform on a disc
 * (a surface patch: the test's null) are taken for a curve's run at about
 * its level, 5% (measured: 4.4%, 4.9%, 5.1% at K = 10, 30, 80 with the
 * K - 1 degrees of freedom of ksel_disc_level; 6.6%, 5.4%, 5.3% with K),
 * and every run of K points along a ring's arc (at most 96 degrees here)
 * with noise of a tenth of its spacing across it is. */
static void test_disc_level(void **state) {
  (void)state;
  const int Ks[] = {10, 30, 80}, trials = 20000;
  double(*p)[3] = malloc(80 * sizeof *p);
  for (int c = 0; c < 3; c++) {
    const int K = Ks[c];
    const double q = ksel_disc_level(K);
    int rej = 0;
    for (int t = 0; t < trials; t++) {
      disc_points(p, K, 1.0, 0.01);
      double ev[3];
      pca_eigen((const double(*)[3])p, K, ev);
      rej += !ksel_disc(ev, q);
    }
    print_message("disc, K = %d: taken for a curve %.4f (level 0.05)\n", K, (double)rej / trials);
    assert_true(rej > 0.03 * trials && rej < 0.08 * trials);
    for (int i0 = 0; i0 < 300; i0 += 7) {
      ring_arc(p, K, i0, 0.1 * (2 * 3.14159265358979323846 / 300), 0.001);
      double ev[3];
      pca_eigen((const double(*)[3])p, K, ev);
      assert_int_equal(ksel_disc(ev, q), 0);
    }
  }
  free(p);
}

/* Its level, at a fixed seed: K points uniform on a disc of radius 10 with
 * unit Gaussian noise along its normal (a plane: the test's null) reject at
 * about the Bonferroni share 0.05 / 9 per candidate (Wilson-Hilferty's
 * quantile at K = 10 is a little conservative); and every neighbourhood of
 * a ring whose noise lies in its own plane (the CAD rings of joint's
 * vertices: radial noise on a circle in z = 0) rejects. */
static void test_thin_level(void **state) {
  (void)state;
  const int Ks[] = {10, 30, 80}, trials = 20000;
  double(*p)[3] = malloc(80 * sizeof *p);
  for (int c = 0; c < 3; c++) {
    const int K = Ks[c];
    int rej = 0;
    for (int t = 0; t < trials; t++) {
      disc_points(p, K, 10.0, 1.0);
      rej += ksel_thin_plane(K, smallest_ev((const double(*)[3])p, K), 100, 1.0, Z9);
    }
    print_message("plane, K = %d: rejected %.4f (level %.4f)\n", K, (double)rej / trials,
                  0.05 / NKS);
    assert_true(rej > 0.25 * 0.05 / NKS * trials && rej < 1.5 * 0.05 / NKS * trials);
  }
  /* a ring of 300 points, radius 1, radial noise 0.01 (and 0.0005 off its plane) */
  const double sd = 0.01;
  for (int i0 = 0; i0 < 300; i0 += 7) {
    const int K = 10 + i0 % 71;
    ring_arc(p, K, i0, sd, 0.05 * sd);
    const double rk = 2 * sin(3.14159265358979323846 * (K - 1) / 300);
    assert_int_equal(
        ksel_thin_plane(K, smallest_ev((const double(*)[3])p, K), rk * rk, sd * sd, Z9), 1);
  }
  free(p);
}

typedef struct shape {
  bsurf_cloud c;
  double *clean;
  bsurf_neighbors nb;
} shape;

static void shape_make(shape *s, bsurf_shape which, size_t n, double level) {
  assert_int_equal(bsurf_generate(&s->c, which, n, BSURF_SAMPLING_RANDOM, 3, 2), BSURF_OK);
  bsurf_neighbors nb0;
  assert_int_equal(bsurf_neighbors_build(&nb0, s->c.xyz, s->c.point_count, 2, 2, NULL, NULL),
                   BSURF_OK);
  const double h = nb0.h;
  bsurf_neighbors_free(&nb0);
  s->clean = malloc(3 * s->c.point_count * sizeof(double));
  memcpy(s->clean, s->c.normals, 3 * s->c.point_count * sizeof(double));
  assert_int_equal(
      bsurf_add_noise(s->c.xyz, s->c.normals, s->c.point_count, BSURF_NOISE_GAUSSIAN, level, h, 7),
      BSURF_OK);
  assert_int_equal(bsurf_neighbors_build(&s->nb, s->c.xyz, s->c.point_count, 80, 2, NULL, NULL),
                   BSURF_OK);
}

static void shape_free(shape *s) {
  bsurf_neighbors_free(&s->nb);
  bsurf_cloud_free(&s->c);
  free(s->clean);
}

/* The rule by its passes, with (emp) or without the empirical bias:
 * normals and K per point. */
static void run_passes(const shape *s, int emp, int threads, double *normals, int *k) {
  const size_t n = s->c.point_count;
  bsurf_kselect_options o = bsurf_kselect_options_default();
  o.ks = KS;
  o.nk = NKS;
  o.threads = threads;
  bsurf_ksel_run *r;
  assert_int_equal(bsurf_ksel_open(&o, s->nb.k, 0, &r), BSURF_OK);
  assert_true(bsurf_ksel_empirical(r));
  double *s2 = malloc(2 * n * sizeof(double)), *noise = malloc(2 * n * sizeof(double));
  double *bref = malloc(3 * n * sizeof(double)), *bm = malloc(n * sizeof(double));
  assert_int_equal(bsurf_ksel_noise(r, s->c.xyz, &s->nb, s2), BSURF_OK);
  assert_int_equal(bsurf_ksel_pool(r, s->c.xyz, &s->nb, s2, noise), BSURF_OK);
  assert_int_equal(bsurf_ksel_level(r, noise, n), BSURF_OK);
  assert_int_equal(bsurf_ksel_first(r, s->c.xyz, &s->nb, noise, NULL, NULL, bref, bm), BSURF_OK);
  bsurf_kselect_fields f = {normals, k, NULL, NULL, NULL, NULL};
  assert_int_equal(bsurf_ksel_choose(r, s->c.xyz, &s->nb, noise, emp ? bref : NULL, emp ? bm : NULL,
                                     NULL, NULL, &f, NULL),
                   BSURF_OK);
  free(s2);
  free(noise);
  free(bref);
  free(bm);
  bsurf_ksel_close(r);
}

/* On a noisy plane (Gaussian, 0.5 h; seed fixed) the quadric holds at
 * every scale: the gate fires at a few points only (the tests' level, 5%
 * for all candidates), and there the neighbours' normals agree with every
 * candidate, so the empirical bias moves (nearly) no choice: the rule with
 * it chooses the K of the rule without it at 99% of the points or more
 * (measured: 0.9995; 0.9982 before the thin-plane test), and bsurf_select_k is the run with it. */
static void test_plane_silent(void **state) {
  (void)state;
  shape s;
  shape_make(&s, BSURF_SHAPE_PLANE, 8000, 0.5);
  const size_t n = s.c.point_count;
  double *n0 = malloc(3 * n * sizeof(double)), *n1 = malloc(3 * n * sizeof(double));
  double *n2 = malloc(3 * n * sizeof(double));
  int *k0 = malloc(n * sizeof(int)), *k1 = malloc(n * sizeof(int)), *k2 = malloc(n * sizeof(int));
  run_passes(&s, 0, 2, n0, k0);
  run_passes(&s, 1, 2, n1, k1);
  size_t same = 0;
  for (size_t i = 0; i < n; i++)
    same += k0[i] == k1[i];
  print_message("plane: same K at %.4f of the points\n", (double)same / n);
  assert_true(same >= 0.99 * n);
  bsurf_kselect_options o = bsurf_kselect_options_default();
  o.ks = KS;
  o.nk = NKS;
  o.threads = 1;
  bsurf_kselect_fields f = {n2, k2, NULL, NULL, NULL, NULL};
  assert_int_equal(bsurf_select_k(s.c.xyz, &s.nb, &o, &f, NULL), BSURF_OK);
  assert_memory_equal(k1, k2, n * sizeof(int));
  assert_memory_equal(n1, n2, 3 * n * sizeof(double));
  free(n0), free(n1), free(n2), free(k0), free(k1), free(k2);
  shape_free(&s);
}

/* Near a cube's edges (the generator's feature flag; light Gaussian noise,
 * 0.25 h, seed fixed) a crease is no quadric and the quadric's bias term
 * under-reads: with the empirical bias the points there take smaller K,
 * and neither their mean angle error nor the whole cloud's rises
 * (measured: edges K 26.6 -> 22.9, error 0.3777 -> 0.3767; all 0.0592 ->
 * 0.0588; the points on an edge itself have no one true normal, so their
 * error stays large). -j1 and -j2 give the same bits. */
static void test_cube_crease(void **state) {
  (void)state;
  shape s;
  shape_make(&s, BSURF_SHAPE_CUBE, 20000, 0.25);
  const size_t n = s.c.point_count;
  const bsurf_field *fe = bsurf_cloud_field(&s.c, "feature");
  assert_non_null(fe);
  double *n0 = malloc(3 * n * sizeof(double)), *n1 = malloc(3 * n * sizeof(double));
  double *n2 = malloc(3 * n * sizeof(double));
  int *k0 = malloc(n * sizeof(int)), *k1 = malloc(n * sizeof(int)), *k2 = malloc(n * sizeof(int));
  run_passes(&s, 0, 2, n0, k0);
  run_passes(&s, 1, 2, n1, k1);
  run_passes(&s, 1, 1, n2, k2);
  assert_memory_equal(k1, k2, n * sizeof(int));
  assert_memory_equal(n1, n2, 3 * n * sizeof(double));
  double kf0 = 0, kf1 = 0, ef0 = 0, ef1 = 0, e0 = 0, e1 = 0, nf = 0;
  for (size_t i = 0; i < n; i++) {
    const double a0 = angle_u(&n0[3 * i], &s.clean[3 * i]),
                 a1 = angle_u(&n1[3 * i], &s.clean[3 * i]);
    e0 += a0, e1 += a1;
    if (fe->values[i] > 0.5) kf0 += k0[i], kf1 += k1[i], ef0 += a0, ef1 += a1, nf++;
  }
  assert_true(nf > 100);
  print_message("cube edges: K %.1f -> %.1f, error %.4f -> %.4f; all %.4f -> %.4f\n", kf0 / nf,
                kf1 / nf, ef0 / nf, ef1 / nf, e0 / n, e1 / n);
  assert_true(kf1 < 0.95 * kf0);
  assert_true(ef1 <= ef0);
  assert_true(e1 <= e0);
  free(n0), free(n1), free(n2), free(k0), free(k1), free(k2);
  shape_free(&s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_gate_exact),   cmocka_unit_test(test_thin_exact),
      cmocka_unit_test(test_same_plane),   cmocka_unit_test(test_drift_of),
      cmocka_unit_test(test_disc_level),   cmocka_unit_test(test_thin_level),
      cmocka_unit_test(test_plane_silent), cmocka_unit_test(test_cube_crease),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
