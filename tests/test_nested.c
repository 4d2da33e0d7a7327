/* Nested neighbourhoods (src/algo/nested.c), the closed-form smallest
 * eigenvector (src/local/eigen.c), the Poisson(1) resampling
 * (src/bootstrap/resample.c) and the per-point selections built on them
 * (bsurf_select_normals_k; K and degree: bsurf_select_normals_kd,
 * src/algo/select_degree.c, with its angle kernel
 * bsurf_nested_field_angle_total). */
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

/* The vectorised unoriented angles against atan2 of the same cross and dot
 * products: within 2 ulp relative, from 1e-9 rad to pi/2. */
static void test_angle_sum_accuracy(void **state) {
  (void)state;
  bsurf_rng r;
  bsurf_rng_init(&r, 7, 1, 2);
  double rx[64], ry[64], rz[64];
  double worst = 0;
  for (int it = 0; it < 400; it++) {
    double g[3] = {bsurf_rng_normal(&r), bsurf_rng_normal(&r), bsurf_rng_normal(&r)};
    unit(g);
    const double spread = pow(10, -9 * bsurf_rng_uniform(&r));
    for (int j = 0; j < 64; j++) {
      double v[3];
      for (int t = 0; t < 3; t++)
        v[t] = (j % 2 ? -g[t] : g[t]) + (j % 3 ? spread : 10.0) * bsurf_rng_normal(&r);
      unit(v);
      rx[j] = v[0], ry[j] = v[1], rz[j] = v[2];
    }
    for (int j = 0; j < 64; j++) {
      const double got = bsurf_nested_angle_sum(g, rx + j, ry + j, rz + j, 1);
      const double c[3] = {g[1] * rz[j] - g[2] * ry[j], g[2] * rx[j] - g[0] * rz[j],
                           g[0] * ry[j] - g[1] * rx[j]};
      const double want = atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
                                fabs(g[0] * rx[j] + g[1] * ry[j] + g[2] * rz[j]));
      assert_true(want >= 0 && want <= 1.5707963267948966 + 1e-15);
      const double rel = fabs(got - want) / want;
      if (rel > worst) worst = rel;
    }
    /* the sum equals the sum of its terms (up to the order of additions) */
    double sum = 0;
    for (int j = 0; j < 64; j++)
      sum += bsurf_nested_angle_sum(g, rx + j, ry + j, rz + j, 1);
    assert_true(fabs(bsurf_nested_angle_sum(g, rx, ry, rz, 64) - sum) <= 1e-14 * sum);
  }
  assert_true(worst <= 2 * 2.3e-16);
}

/* Eq. 5.5 in bsurf_nested_summary: the angles between the first valid
 * replicate and each (after the orientation to n_P, in place), oriented
 * (up to pi), against libm's atan2 of the same cross and dot products
 * within 2 ulp relative; the variance from them; invalid replicates (any
 * values) left out. */
static void test_summary_angles(void **state) {
  (void)state;
  enum { B = 45 };
  bsurf_rng r;
  bsurf_rng_init(&r, 8, 3, 4);
  double bn[3 * B], ang[B], worst = 0;
  unsigned char valid[B];
  for (int it = 0; it < 200; it++) {
    double nP[3] = {bsurf_rng_normal(&r), bsurf_rng_normal(&r), bsurf_rng_normal(&r)};
    unit(nP);
    const double spread = it % 4 == 0 ? 3.0 : pow(10, -8 * bsurf_rng_uniform(&r));
    for (int b = 0; b < B; b++) {
      double *v = &bn[3 * b];
      for (int t = 0; t < 3; t++)
        v[t] = (b % 2 ? -nP[t] : nP[t]) + spread * bsurf_rng_normal(&r);
      unit(v);
      valid[b] = (b + it) % 7 != 1;
      if (!valid[b]) v[0] = NAN; /* never read */
    }
    double nrm[3], var;
    const int nv = bsurf_nested_summary(B, nP, bn, valid, nrm, &var, ang);
    int first = -1, count = 0;
    double mean = 0;
    double want[B];
    for (int b = 0; b < B; b++) {
      if (!valid[b]) continue;
      if (first < 0) first = b;
      const double *g = &bn[3 * first], *v = &bn[3 * b];
      const double c[3] = {g[1] * v[2] - g[2] * v[1], g[2] * v[0] - g[0] * v[2],
                           g[0] * v[1] - g[1] * v[0]};
      want[b] = atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
                      g[0] * v[0] + g[1] * v[1] + g[2] * v[2]);
      if (b == first)
        assert_true(ang[b] == 0.0);
      else {
        const double rel = fabs(ang[b] - want[b]) / want[b];
        if (rel > worst) worst = rel;
      }
      mean += want[b];
      count++;
    }
    assert_int_equal(nv, count);
    mean /= count;
    double v2 = 0;
    for (int b = 0; b < B; b++)
      if (valid[b]) v2 += (want[b] - mean) * (want[b] - mean);
    v2 /= count - 1;
    assert_true(fabs(var - v2) <= 1e-12 * v2 + 1e-300);
  }
  assert_true(worst <= 2 * 2.3e-16);
}

/* The angle sums of many (candidate, replicate) pairs in lanes: each pair's
 * sum has the bits of its own bsurf_nested_angle_sum, in the fixed order
 * (four running sums by j mod 4), whatever the other pairs: counts from 1
 * to 64 (non-decreasing, several pairs a count, as the candidates' B
 * replicates), more pairs than one chunk of lanes, pairs marked invalid. */
static void test_angle_sums_pairs(void **state) {
  (void)state;
  bsurf_rng r;
  bsurf_rng_init(&r, 9, 4, 5);
  enum { K = 64, P = 700 };
  double rx[K], ry[K], rz[K], g[3 * P], sums[P];
  int kl[P];
  unsigned char valid[P];
  for (int j = 0; j < K; j++) {
    double v[3] = {bsurf_rng_normal(&r), bsurf_rng_normal(&r), bsurf_rng_normal(&r)};
    unit(v);
    rx[j] = v[0], ry[j] = v[1], rz[j] = v[2];
  }
  for (int p = 0; p < P; p++) {
    double *v = &g[3 * p];
    v[0] = bsurf_rng_normal(&r), v[1] = bsurf_rng_normal(&r), v[2] = bsurf_rng_normal(&r);
    unit(v);
    kl[p] = 1 + p * K / P; /* 1 .. 64, about 11 pairs each */
    valid[p] = p % 13 != 5;
  }
  bsurf_nested_angle_sums(P, g, valid, kl, rx, ry, rz, sums);
  for (int p = 0; p < P; p++) {
    if (!valid[p]) continue;
    const double *v = &g[3 * p];
    assert_true(sums[p] == bsurf_nested_angle_sum(v, rx, ry, rz, kl[p]));
    /* the fixed order, from the angles one at a time */
    double s4[4] = {0, 0, 0, 0};
    for (int j = 0; j < kl[p]; j++)
      s4[j % 4] += bsurf_nested_angle_sum(v, rx + j, ry + j, rz + j, 1);
    assert_true(sums[p] == (s4[0] + s4[1]) + (s4[2] + s4[3]));
  }
  /* a subset of the pairs gives the same bits */
  double part[P];
  bsurf_nested_angle_sums(P - 301, g + 3 * 301, valid + 301, kl + 301, rx, ry, rz, part);
  for (int p = 301; p < P; p++)
    if (valid[p]) assert_true(part[p - 301] == sums[p]);
}

/* Reference: libm's atan2 of the cross and dot products of the double
 * field (-f_u s^-1, -f_v s^-1, 1) at (u, v), from the basis's gradient. */
static double field_angle_ref(int degree, const double *coef, double inv, double u, double v,
                              const double r[3]) {
  double du[BSURF_TERMS_MAX], dv[BSURF_TERMS_MAX], fu = 0, fv = 0;
  bsurf_poly_basis_grad(degree, u, v, du, dv);
  for (int t = 0; t < bsurf_poly_terms(degree); t++)
    fu += coef[t] * du[t], fv += coef[t] * dv[t];
  const double g[3] = {-fu * inv, -fv * inv, 1.0};
  const double c[3] = {g[1] * r[2] - g[2] * r[1], g[2] * r[0] - g[0] * r[2],
                       g[0] * r[1] - g[1] * r[0]};
  return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
               fabs(g[0] * r[0] + g[1] * r[1] + g[2] * r[2]));
}

/* Eq. 5.10's single-precision field angles (bsurf_nested_field_angle_total)
 * against libm's atan2 of the double field: each angle within 2e-6 rad
 * (about 3e-7 measured: the float basis, slopes and angle), degrees 0..4,
 * coefficients up to 1e30 (the slopes' pre-scaling); the totals over
 * replicates (valid ones only, more than one float chunk of 64) within
 * 1e-6 relative of the double sum; the padding past k adds nothing. */
static void test_field_angle_accuracy(void **state) {
  (void)state;
  bsurf_rng r;
  bsurf_rng_init(&r, 11, 2, 3);
  enum { K = 37, KQ = 48, NREP = 150, MG = 10 /* terms(BSURF_DEGREE_MAX - 1) */ };
  static float phif[MG * KQ], rf[3 * KQ], one_phi[MG * 16], one_r[3 * 16], accf[KQ];
  static double accd[KQ], coef[NREP * BSURF_TERMS_MAX], u[K], v[K], rr[K][3];
  static unsigned char valid[NREP];
  /* the padding of the callers: phi past K zero, r = (0, 0, 1) */
  for (int j = K; j < KQ; j++) {
    for (int t = 0; t < MG; t++)
      phif[t * KQ + j] = 0.0f;
    rf[j] = rf[KQ + j] = 0.0f, rf[2 * KQ + j] = 1.0f;
  }
  for (int j = 1; j < 16; j++) {
    for (int t = 0; t < MG; t++)
      one_phi[t * 16 + j] = 0.0f;
    one_r[j] = one_r[16 + j] = 0.0f, one_r[32 + j] = 1.0f;
  }
  double worst = 0;
  for (int it = 0; it < 200; it++) {
    const int degree = it % 5, m = bsurf_poly_terms(degree);
    const int nrep = it % 20 == 19 ? NREP : 1 + it % 4;
    const double inv = 1.0 / (0.1 + bsurf_rng_uniform(&r));
    const double mag = it % 50 == 49 ? 1e30 : pow(10, 3 * bsurf_rng_uniform(&r) - 2);
    for (int t = 0; t < nrep * m; t++)
      coef[t] = mag * bsurf_rng_normal(&r);
    for (int b = 0; b < nrep; b++)
      valid[b] = b % 7 != 3;
    for (int j = 0; j < K; j++) {
      const double a = 6.283185307179586 * bsurf_rng_uniform(&r), rad = sqrt(bsurf_rng_uniform(&r));
      u[j] = rad * cos(a), v[j] = rad * sin(a);
      double phi[BSURF_TERMS_MAX];
      bsurf_poly_basis(BSURF_DEGREE_MAX, u[j], v[j], phi);
      for (int t = 0; t < MG; t++)
        phif[t * KQ + j] = (float)phi[t];
      double w[3] = {bsurf_rng_normal(&r), bsurf_rng_normal(&r), bsurf_rng_normal(&r)};
      unit(w);
      for (int t = 0; t < 3; t++)
        rr[j][t] = w[t], rf[t * KQ + j] = (float)w[t];
    }
    double want = 0;
    for (int b = 0; b < nrep; b++) {
      if (!valid[b]) continue;
      for (int j = 0; j < K; j++) {
        const double ref = field_angle_ref(degree, &coef[b * m], inv, u[j], v[j], rr[j]);
        want += ref;
        if (b > 0) continue;
        /* one angle: neighbour j alone at lane 0 */
        for (int t = 0; t < MG; t++)
          one_phi[t * 16] = phif[t * KQ + j];
        for (int t = 0; t < 3; t++)
          one_r[t * 16] = rf[t * KQ + j];
        const double got = bsurf_nested_field_angle_total(degree, 1, &coef[b * m], NULL, inv,
                                                          one_phi, 16, one_r, 1, accf, accd);
        assert_true(isfinite(got));
        if (fabs(got - ref) > worst) worst = fabs(got - ref);
      }
    }
    const double all =
        bsurf_nested_field_angle_total(degree, nrep, coef, valid, inv, phif, KQ, rf, K, accf, accd);
    assert_true(fabs(all - want) <= 1e-6 * want);
    /* the padded lanes (phi = 0, r = (0, 0, 1)) are not summed: k = K - 5 */
    double part = 0;
    for (int b = 0; b < nrep; b++)
      for (int j = 0; j < K - 5 && valid[b]; j++)
        part += field_angle_ref(degree, &coef[b * m], inv, u[j], v[j], rr[j]);
    assert_true(fabs(bsurf_nested_field_angle_total(degree, nrep, coef, valid, inv, phif, KQ, rf,
                                                    K - 5, accf, accd) -
                     part) <= 1e-6 * part);
  }
  print_message("field angles: worst %.3g rad\n", worst);
  assert_true(worst <= 2e-6);
}

/* The smallest eigenvector against the Jacobi sweeps, on covariances of
 * flat-ish, curved and nearly degenerate point sets; the lanes give the
 * scalar function's bits. */
static void test_smallest_eigenvector(void **state) {
  (void)state;
  bsurf_rng r;
  bsurf_rng_init(&r, 3, 4, 5);
  enum { R = 37 };
  double lanes_c[6 * R], lanes_n[3 * R];
  int lanes_st[R];
  for (int it = 0; it < 2000; it++) {
    /* eigenvalues 1, s1, s0 (s0 <= s1 <= 1) in a random frame */
    const double s1 = it % 7 == 0 ? 1 - 1e-9 * bsurf_rng_uniform(&r) : bsurf_rng_uniform(&r);
    const double s0 = it % 5 == 0 ? 0 : s1 * (it % 11 == 0 ? 1 - 1e-7 : bsurf_rng_uniform(&r));
    const double lam[3] = {s0, s1, 1};
    double q[3][3];
    for (int a = 0; a < 3; a++) {
      for (int t = 0; t < 3; t++)
        q[a][t] = bsurf_rng_normal(&r);
      for (int b = 0; b < a; b++) { /* Gram-Schmidt */
        const double d = q[a][0] * q[b][0] + q[a][1] * q[b][1] + q[a][2] * q[b][2];
        for (int t = 0; t < 3; t++)
          q[a][t] -= d * q[b][t];
      }
      unit(q[a]);
    }
    double c[6];
    const int ij[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
    for (int e = 0; e < 6; e++) {
      c[e] = 0;
      for (int a = 0; a < 3; a++)
        c[e] += lam[a] * q[a][ij[e][0]] * q[a][ij[e][1]];
    }
    double n[3];
    const int st = bsurf_eigen_sym3_smallest(c, n);
    double C[3][3] = {{c[0], c[1], c[2]}, {c[1], c[3], c[4]}, {c[2], c[4], c[5]}}, ev[3], V[3][3];
    bsurf_eigen_sym3(C, ev, V);
    assert_int_equal(st, (ev[2] > 0 && ev[1] > 1e-12 * ev[2]) ? 0 : -1);
    const double dot = fabs(n[0] * V[0][0] + n[1] * V[0][1] + n[2] * V[0][2]);
    assert_true(fabs(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1) < 1e-14);
    if (s1 - s0 > 1e-3) assert_true(dot > 1 - 1e-20 / ((s1 - s0) * (s1 - s0)) - 1e-15);
    if (s1 - s0 > 1e-3)
      assert_true(fabs(n[0] * q[0][0] + n[1] * q[0][1] + n[2] * q[0][2]) > 1 - 1e-12);
    /* lanes: the same bits */
    const int l = it % R;
    for (int e = 0; e < 6; e++)
      lanes_c[e * R + l] = c[e];
    if (l == R - 1) {
      bsurf_eigen_sym3_smallest_lanes(R, lanes_c, lanes_n, lanes_st);
      for (int k = 0; k < R; k++) {
        const double m[6] = {lanes_c[k],         lanes_c[R + k],     lanes_c[2 * R + k],
                             lanes_c[3 * R + k], lanes_c[4 * R + k], lanes_c[5 * R + k]};
        double v[3];
        assert_int_equal(lanes_st[k], bsurf_eigen_sym3_smallest(m, v));
        for (int t = 0; t < 3; t++)
          assert_memory_equal(&lanes_n[t * R + k], &v[t], sizeof(double));
      }
    }
  }
  /* zero and rank-one matrices: degenerate */
  const double zero[6] = {0, 0, 0, 0, 0, 0}, line[6] = {1, 1, 0, 1, 0, 0};
  double n[3];
  assert_int_equal(bsurf_eigen_sym3_smallest(zero, n), -1);
  assert_int_equal(bsurf_eigen_sym3_smallest(line, n), -1);
}

/* Every candidate's sums equal a separate weighted sum over its own first K
 * neighbours (same order: same bits); distinct counts the nonzero weights.
 * Lane counts R of every remainder: the vector groups of 8 and 4, the last
 * group overlapping the one before, and single lanes. */
static void test_nested_sums(void **state) {
  (void)state;
  enum { KMAX = 40, RMAX = 50, NK = 4 };
  const int ks[NK] = {5, 12, 13, 40};
  double xyz[3 * KMAX];
  uint32_t idx[KMAX];
  bsurf_rng r;
  bsurf_rng_init(&r, 1, 2, 3);
  for (int j = 0; j < KMAX; j++) {
    idx[j] = (uint32_t)((j * 7) % KMAX);
    for (int t = 0; t < 3; t++)
      xyz[3 * j + t] = 1000 + bsurf_rng_normal(&r);
  }
  static double terms[KMAX * BSURF_NESTED_COLS], Wt[KMAX * RMAX],
      sums[NK * BSURF_NESTED_COLS * RMAX], cov[6 * RMAX];
  static int distinct[NK * RMAX], ok[RMAX];
  uint32_t u[KMAX];
  bsurf_nested_terms(xyz, idx, KMAX, terms);
  const int Rs[] = {1, 2, 3, 4, 5, 7, 8, 9, 12, 13, 17, 50};
  for (size_t ri = 0; ri < sizeof Rs / sizeof Rs[0]; ri++) {
    const int R = Rs[ri];
    bsurf_boot_poisson_rows(5, 17, R, KMAX, u, Wt);
    bsurf_nested_sums(terms, KMAX, R, Wt, ks, NK, sums, distinct);
    for (int c = 0; c < NK; c++)
      for (int b = 0; b < R; b++) {
        double want[BSURF_NESTED_COLS] = {0};
        int nz = 0;
        for (int j = 0; j < ks[c]; j++) {
          for (int col = 0; col < BSURF_NESTED_COLS; col++)
            want[col] += Wt[j * R + b] * terms[j * BSURF_NESTED_COLS + col];
          nz += Wt[j * R + b] != 0;
        }
        for (int col = 0; col < BSURF_NESTED_COLS; col++)
          assert_memory_equal(&sums[(c * BSURF_NESTED_COLS + col) * R + b], &want[col],
                              sizeof(double));
        assert_int_equal(distinct[c * R + b], nz);
        /* the lanes' covariances are the row-by-row ones */
        double mu[3], one[6];
        bsurf_nested_cov_lanes(&sums[c * BSURF_NESTED_COLS * R], R, BSURF_PCA_CENTROID, cov, ok);
        assert_int_equal(
            bsurf_nested_cov(&sums[c * BSURF_NESTED_COLS * R + b], R, BSURF_PCA_CENTROID, mu, one),
            ok[b] ? 0 : -1);
        for (int t = 0; ok[b] && t < 6; t++)
          assert_memory_equal(&cov[t * R + b], &one[t], sizeof(double));
      }
  }
}

/* Poisson(1) weights: mean 1, variance 1, P(0) = 1/e, at a fixed seed over
 * 200k draws (5 standard errors); the streams depend on (seed, point, b)
 * only, not on B. */
static void test_poisson_weights(void **state) {
  (void)state;
  enum { K = 100, B = 40 };
  static double Wt[K * B], Wt2[K * 7];
  uint32_t u[K];
  double s = 0, s2 = 0, zeros = 0;
  const int points = 50;
  for (int p = 0; p < points; p++) {
    bsurf_boot_poisson_rows(9, (uint64_t)p, B, K, u, Wt);
    for (int t = 0; t < K * B; t++)
      s += Wt[t], s2 += Wt[t] * Wt[t], zeros += Wt[t] == 0;
    bsurf_boot_poisson_rows(9, (uint64_t)p, 7, K, u, Wt2);
    for (int j = 0; j < K; j++)
      for (int b = 0; b < 7; b++)
        assert_true(Wt2[j * 7 + b] == Wt[j * B + b]);
  }
  const double m = (double)points * K * B, mean = s / m, var = s2 / m - mean * mean;
  assert_true(fabs(mean - 1) < 5 * sqrt(1 / m));
  assert_true(fabs(var - 1) < 5 * sqrt(3 / m)); /* Var of X^2 about 3 at large counts: generous */
  assert_true(fabs(zeros / m - exp(-1)) < 5 * sqrt(exp(-1) * (1 - exp(-1)) / m));
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

/* The reference normals of Eq. 5.10: single PCA fits on 20 neighbours. */
static double *reference_normals(const bsurf_cloud *c, const bsurf_neighbors *nb) {
  bsurf_normal_options ro = bsurf_normal_options_default();
  ro.bootstrap = 0;
  ro.k = 20;
  double *ref = malloc(sizeof(double) * 3 * c->point_count);
  bsurf_normal_fields rf = {ref, NULL, NULL};
  assert_int_equal(bsurf_estimate_normals(c->xyz, nb, NULL, &ro, &rf, NULL), BSURF_OK);
  return ref;
}

/* K selection: bit-identical for 1 and 2 threads; with B = 0 and one
 * candidate the single fit of bsurf_estimate_normals (same normal, its
 * training error up to the order of the sum); the chosen K is the candidate
 * of smallest error; selection beats the worst candidate on the truth. */
static void test_select_k(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_neighbors nb;
  double *truth = noisy_torus(&c, 6000, &nb, 40);
  const size_t n = c.point_count;
  double *ref = reference_normals(&c, &nb);

  const int ks[4] = {10, 20, 30, 40};
  const int nk = 4;
  double *a = malloc(sizeof(double) * 5 * n), *b = malloc(sizeof(double) * 5 * n);
  double *ce = malloc(sizeof(double) * n * nk), *cv = malloc(sizeof(double) * n * nk);
  double *cn = malloc(sizeof(double) * 3 * n * nk);
  int *ka = malloc(sizeof(int) * n), *kb = malloc(sizeof(int) * n);
  bsurf_normal_options o = bsurf_normal_options_default();
  o.bootstrap = 20;
  o.threads = 1;
  bsurf_normal_select_fields fa = {a, a + 3 * n, a + 4 * n, ka, ce, cv, cn};
  bsurf_normal_select_fields fb = {b, b + 3 * n, b + 4 * n, kb, NULL, NULL, NULL};
  bsurf_normal_report rep;
  assert_int_equal(bsurf_select_normals_k(c.xyz, &nb, ref, &o, ks, nk, &fa, &rep), BSURF_OK);
  assert_int_equal(rep.replicates_total, n * 20 * nk);
  o.threads = 2;
  assert_int_equal(bsurf_select_normals_k(c.xyz, &nb, ref, &o, ks, nk, &fb, NULL), BSURF_OK);
  assert_memory_equal(a, b, sizeof(double) * 5 * n);
  assert_memory_equal(ka, kb, sizeof(int) * n);
  double worst = 0, sel = 0;
  for (int k = 0; k < nk; k++) {
    double e = 0;
    for (size_t i = 0; i < n; i++) {
      double t =
          fabs(cn[(i * nk + k) * 3] * truth[3 * i] + cn[(i * nk + k) * 3 + 1] * truth[3 * i + 1] +
               cn[(i * nk + k) * 3 + 2] * truth[3 * i + 2]);
      e += acos(t > 1 ? 1 : t);
    }
    if (e > worst) worst = e;
  }
  for (size_t i = 0; i < n; i++) {
    int best = 0;
    for (int k = 1; k < nk; k++)
      if (ce[i * nk + k] < ce[i * nk + best]) best = k;
    assert_int_equal(ka[i], ks[best]);
    assert_true(a[4 * n + i] == ce[i * nk + best]);
    assert_true(a[3 * n + i] == cv[i * nk + best]);
    double t = fabs(a[3 * i] * truth[3 * i] + a[3 * i + 1] * truth[3 * i + 1] +
                    a[3 * i + 2] * truth[3 * i + 2]);
    sel += acos(t > 1 ? 1 : t);
  }
  assert_true(sel < worst);

  /* one candidate, B = 0: the single fit */
  o.bootstrap = 0;
  const int k30 = 30;
  bsurf_normal_select_fields f1 = {a, NULL, a + 4 * n, ka, NULL, NULL, NULL};
  assert_int_equal(bsurf_select_normals_k(c.xyz, &nb, ref, &o, &k30, 1, &f1, NULL), BSURF_OK);
  o.k = 30;
  bsurf_normal_fields f2 = {b, NULL, b + 4 * n};
  assert_int_equal(bsurf_estimate_normals(c.xyz, &nb, ref, &o, &f2, NULL), BSURF_OK);
  assert_memory_equal(a, b, sizeof(double) * 3 * n);
  for (size_t i = 0; i < n; i++)
    assert_true(fabs(a[4 * n + i] - b[4 * n + i]) <= 1e-14 + 1e-13 * b[4 * n + i]);

  /* bad arguments */
  const int bad[2] = {20, 20};
  assert_int_equal(bsurf_select_normals_k(c.xyz, &nb, ref, &o, bad, 2, &f1, NULL),
                   BSURF_ERR_INVALID_ARG);
  const int big = 41;
  assert_int_equal(bsurf_select_normals_k(c.xyz, &nb, ref, &o, &big, 1, &f1, NULL),
                   BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_select_normals_k(c.xyz, &nb, NULL, &o, ks, nk, &f1, NULL),
                   BSURF_ERR_INVALID_ARG);
  free(a);
  free(b);
  free(ce);
  free(cv);
  free(cn);
  free(ka);
  free(kb);
  free(ref);
  free(truth);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

static double angle_to_truth(const double *n, const double *truth) {
  double t = fabs(n[0] * truth[0] + n[1] * truth[1] + n[2] * truth[2]);
  return acos(t > 1 ? 1 : t);
}

/* K and degree selection: bit-identical for 1 and 2 threads; the chosen
 * (K, degree) is the candidate of smallest error (ties: smaller K, then
 * degree) and its values are written; with B = 0 and one candidate the
 * single fit of bsurf_estimate_normals (same normal bits, its training error
 * up to the single-precision angles' rounding); selection beats the worst candidate on the
 * truth; bad arguments. */
static void test_select_kd(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_neighbors nb;
  double *truth = noisy_torus(&c, 5000, &nb, 40);
  const size_t n = c.point_count;
  double *ref = reference_normals(&c, &nb);

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
  /* Eq. 5.10's angles in single precision: each within 2e-6 rad */
  for (size_t i = 0; i < n; i++)
    assert_true(fabs(a[4 * n + i] - b[4 * n + i]) <= 2e-6);

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
      cmocka_unit_test(test_angle_sum_accuracy), cmocka_unit_test(test_summary_angles),
      cmocka_unit_test(test_angle_sums_pairs),   cmocka_unit_test(test_smallest_eigenvector),
      cmocka_unit_test(test_nested_sums),        cmocka_unit_test(test_poisson_weights),
      cmocka_unit_test(test_select_k),           cmocka_unit_test(test_field_angle_accuracy),
      cmocka_unit_test(test_select_kd),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
