/* Local analysis (thesis 3.3): eigen-decomposition, frames, exact polynomial
 * recovery, rank-deficiency detection, PCA normal of a noisy plane. */
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
#include "local/local.h"

static void test_eigen_known(void **state) {
  (void)state;
  /* A = R diag(1, 2, 5) R^T with R a rotation about z by 30 degrees */
  double c = cos((3.14159265358979323846 / 6)), s = sin((3.14159265358979323846 / 6));
  double R[3][3] = {{c, -s, 0}, {s, c, 0}, {0, 0, 1}};
  double d[3] = {2, 5, 1};
  double A[3][3] = {{0}};
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++)
      for (int k = 0; k < 3; k++)
        A[i][j] += R[i][k] * d[k] * R[j][k];
  double ev[3], V[3][3];
  bsurf_eigen_sym3(A, ev, V);
  assert_true(fabs(ev[0] - 1) < 1e-12 && fabs(ev[1] - 2) < 1e-12 && fabs(ev[2] - 5) < 1e-12);
  /* eigenvector of 1 is z, of 5 is R's second column */
  assert_true(fabs(fabs(V[0][2]) - 1) < 1e-12);
  assert_true(fabs(fabs(V[2][0] * R[0][1] + V[2][1] * R[1][1]) - 1) < 1e-12);
  /* A v = lambda v for all */
  for (int e = 0; e < 3; e++)
    for (int i = 0; i < 3; i++) {
      double av = A[i][0] * V[e][0] + A[i][1] * V[e][1] + A[i][2] * V[e][2];
      assert_true(fabs(av - ev[e] * V[e][i]) < 1e-12);
    }
}

static void test_eigen_degenerate(void **state) {
  (void)state;
  double Z[3][3] = {{0}}, ev[3], V[3][3];
  bsurf_eigen_sym3(Z, ev, V);
  for (int i = 0; i < 3; i++)
    assert_true(ev[i] == 0);
  double I[3][3] = {{2, 0, 0}, {0, 2, 0}, {0, 0, 2}};
  bsurf_eigen_sym3(I, ev, V);
  for (int i = 0; i < 3; i++)
    assert_true(ev[i] == 2);
}

/* Points of a tilted plane through d: the frame's normal is the plane's
 * normal and every point has local height 0 (this fails if M^T of Eq. 3.5
 * is applied instead of M). */
static void test_frame_tangent_plane_height_zero(void **state) {
  (void)state;
  double n[3] = {1, 2, 2}; /* |n| = 3 */
  double u[3] = {2, -1, 0}, w[3];
  w[0] = n[1] * u[2] - n[2] * u[1];
  w[1] = n[2] * u[0] - n[0] * u[2];
  w[2] = n[0] * u[1] - n[1] * u[0];
  double d[3] = {10, -5, 3};
  enum { K = 40 };
  double xyz[3 * K];
  uint32_t idx[K];
  bsurf_rng rng;
  bsurf_rng_init(&rng, 7, 0, 0);
  for (int j = 0; j < K; j++) {
    double a = j == 0 ? 0 : bsurf_rng_uniform(&rng) * 2 - 1,
           b = j == 0 ? 0 : bsurf_rng_uniform(&rng) * 2 - 1;
    for (int t = 0; t < 3; t++)
      xyz[3 * j + t] = d[t] + a * u[t] / sqrt(5) + b * w[t] / sqrt(45);
    idx[j] = (uint32_t)j;
  }
  for (int center = 0; center < 2; center++) {
    bsurf_frame f;
    bsurf_local_frame(xyz, idx, K, (bsurf_pca_center)center, &f);
    double dot = (f.rot[2][0] * n[0] + f.rot[2][1] * n[1] + f.rot[2][2] * n[2]) / 3.0;
    assert_true(fabs(fabs(dot) - 1) < 1e-12);
    for (int j = 0; j < K; j++) {
      double q[3], back[3];
      bsurf_frame_to_local(&f, &xyz[3 * j], q);
      assert_true(fabs(q[2]) < 1e-12);
      bsurf_frame_to_global(&f, q, back); /* Eq. 3.6 inverts Eq. 3.5 */
      for (int t = 0; t < 3; t++)
        assert_true(fabs(back[t] - xyz[3 * j + t]) < 1e-12);
    }
    /* rows orthonormal and right-handed */
    for (int a = 0; a < 3; a++)
      for (int b = 0; b < 3; b++) {
        double s = 0;
        for (int t = 0; t < 3; t++)
          s += f.rot[a][t] * f.rot[b][t];
        assert_true(fabs(s - (a == b)) < 1e-12);
      }
    double cx = f.rot[0][1] * f.rot[1][2] - f.rot[0][2] * f.rot[1][1];
    assert_true(fabs(cx - f.rot[2][0]) < 1e-12);
    /* the origin is the point itself: local coordinates of d are 0 */
    double q0[3];
    bsurf_frame_to_local(&f, d, q0);
    assert_true(fabs(q0[0]) < 1e-12 && fabs(q0[1]) < 1e-12 && fabs(q0[2]) < 1e-12);
  }
}

static void test_poly_basis_order(void **state) {
  (void)state;
  double phi[15];
  bsurf_poly_basis(4, 2.0, 3.0, phi);
  double expect[15] = {1, 2, 3, 4, 6, 9, 8, 12, 18, 27, 16, 24, 36, 54, 81};
  for (int i = 0; i < 15; i++)
    assert_true(phi[i] == expect[i]);
  assert_int_equal(bsurf_poly_terms(1), 3);
  assert_int_equal(bsurf_poly_terms(2), 6);
  assert_int_equal(bsurf_poly_terms(3), 10);
  assert_int_equal(bsurf_poly_terms(4), 15);
}

/* The basis as the recurrence through copies it replaced (poly.c): the
 * same products, so the same bits for every degree up to 2 M_max. */
static void poly_basis_copies(int degree, double u, double v, double *phi) {
  int t = 0;
  phi[t++] = 1.0;
  double prev[2 * BSURF_DEGREE_MAX + 1] = {1.0};
  for (int d = 1; d <= degree; d++) {
    double cur[2 * BSURF_DEGREE_MAX + 1];
    for (int j = 0; j < d; j++)
      cur[j] = prev[j] * u;
    cur[d] = prev[d - 1] * v;
    for (int j = 0; j <= d; j++) {
      phi[t++] = cur[j];
      prev[j] = cur[j];
    }
  }
}

static void test_poly_basis_bits(void **state) {
  (void)state;
  srand(5);
  for (int trial = 0; trial < 2000; trial++) {
    const double u = (rand() / (double)RAND_MAX - 0.5) * (trial % 3 ? 2.0 : 1e-3);
    const double v = (rand() / (double)RAND_MAX - 0.5) * (trial % 5 ? 2.0 : 7.0);
    const int degree = trial % (2 * BSURF_DEGREE_MAX + 1);
    double a[64], b[64];
    memset(a, 0, sizeof a);
    memset(b, 0, sizeof b);
    bsurf_poly_basis(degree, u, v, a);
    poly_basis_copies(degree, u, v, b);
    assert_memory_equal(a, b, sizeof a);
  }
}

/* One factorisation, several right-hand sides: the bits of a solve each
 * (bsurf_ldl_solve_packed), and the solutions solve the system. */
static void test_ldl_factored(void **state) {
  (void)state;
  srand(9);
  for (int trial = 0; trial < 200; trial++) {
    const int m = 1 + trial % BSURF_TERMS_MAX;
    double X[3 * BSURF_TERMS_MAX][BSURF_TERMS_MAX], G[BSURF_PACKED_MAX];
    for (int r = 0; r < 3 * m; r++)
      for (int a = 0; a < m; a++)
        X[r][a] = rand() / (double)RAND_MAX - 0.5;
    for (int b = 0; b < m; b++)
      for (int a = 0; a <= b; a++) {
        double g = 0;
        for (int r = 0; r < 3 * m; r++)
          g += X[r][a] * X[r][b];
        G[bsurf_packed_index(a, b)] = g;
      }
    bsurf_ldl f;
    assert_int_equal(bsurf_ldl_factor_packed(m, G, BSURF_RANK_TOL, &f), 0);
    for (int rhs = 0; rhs < 4; rhs++) {
      double r[BSURF_TERMS_MAX], c1[BSURF_TERMS_MAX], c2[BSURF_TERMS_MAX];
      for (int a = 0; a < m; a++)
        r[a] = rhs == 0 ? rand() / (double)RAND_MAX : (a == rhs % m);
      bsurf_ldl_solve_factored(&f, r, c1);
      assert_int_equal(bsurf_ldl_solve_packed(m, G, r, BSURF_RANK_TOL, c2), 0);
      assert_memory_equal(c1, c2, (size_t)m * sizeof(double));
      for (int a = 0; a < m; a++) { /* G c = r */
        double s = 0;
        for (int b = 0; b < m; b++)
          s += G[a <= b ? bsurf_packed_index(a, b) : bsurf_packed_index(b, a)] * c1[b];
        assert_true(fabs(s - r[a]) < 1e-8 * (1 + fabs(r[a])));
      }
    }
  }
  /* a dependent column: refused by both */
  double G[3] = {1, 1, 1}, r[2] = {1, 1}, c[2];
  bsurf_ldl f;
  assert_int_equal(bsurf_ldl_factor_packed(2, G, BSURF_RANK_TOL, &f), -1);
  assert_int_equal(bsurf_ldl_solve_packed(2, G, r, BSURF_RANK_TOL, c), -1);
}

/* Selection's k-th smallest is the sorted array's k-th value, for every k,
 * with and without repeated values. */
/* The n x n Jacobi sweeps (the conic fit's 5 x 5 problem, kselect_noise.c):
 * the second-difference matrix tridiag(-1, 2, -1) of order 5 has the
 * eigenvalues 2 - 2 cos(j pi / 6), j = 1..5, and eigenvectors
 * sin(i j pi / 6); and n = 3 gives bsurf_eigen_sym3's bits. */
static void test_eigen_sym_n(void **state) {
  (void)state;
  const double pi = 3.14159265358979323846;
  double T[25] = {0}, ev[5], V[25];
  for (int i = 0; i < 5; i++) {
    T[i * 5 + i] = 2;
    if (i + 1 < 5) T[i * 5 + i + 1] = T[(i + 1) * 5 + i] = -1;
  }
  bsurf_eigen_sym(5, T, ev, V);
  for (int j = 1; j <= 5; j++) {
    assert_true(fabs(ev[j - 1] - (2 - 2 * cos(j * pi / 6))) < 1e-12);
    double dot = 0, nn = 0;
    for (int i = 1; i <= 5; i++)
      dot += V[(j - 1) * 5 + i - 1] * sin(i * j * pi / 6),
          nn += sin(i * j * pi / 6) * sin(i * j * pi / 6);
    assert_true(fabs(fabs(dot) / sqrt(nn) - 1) < 1e-12);
  }
  double A[3][3] = {{4, 1, 0.5}, {1, 3, 0.25}, {0.5, 0.25, 1}}, e3[3], v3[3][3], en[3], vn[9];
  bsurf_eigen_sym3(A, e3, v3);
  bsurf_eigen_sym(3, &A[0][0], en, vn);
  assert_memory_equal(e3, en, sizeof e3);
  assert_memory_equal(&v3[0][0], vn, sizeof vn);
}

/* Paulson's F quantiles (bsurf_f_quantile_paulson) against the exact ones
 * (scipy.stats.f.ppf): F(3, 7) at 95% 4.34683, F(9, 7) at 5% 0.303698,
 * F(3, 15) at 95% 3.28738; within 1%. */
static void test_f_quantile(void **state) {
  (void)state;
  const double z = 1.6448536269514722;
  assert_true(fabs(bsurf_f_quantile_paulson(3, 7, z) / 4.346831399907815 - 1) < 0.01);
  assert_true(fabs(bsurf_f_quantile_paulson(9, 7, -z) / 0.3036979010590348 - 1) < 0.01);
  assert_true(fabs(bsurf_f_quantile_paulson(3, 15, z) / 3.2873821046365115 - 1) < 0.01);
  assert_true(bsurf_f_quantile_paulson(3, 7, 0) > 0.8 && bsurf_f_quantile_paulson(3, 7, 0) < 1);
}

static void test_kth_smallest(void **state) {
  (void)state;
  srand(3);
  double v[101], w[101], sorted[101];
  for (int trial = 0; trial < 300; trial++) {
    const int n = 1 + trial % 101, levels = trial % 4 ? 1000000 : 1 + trial % 7;
    for (int j = 0; j < n; j++)
      v[j] = (double)(rand() % levels) - levels / 3;
    if (trial % 9 == 0) /* sorted or reversed input */
      for (int j = 0; j < n; j++)
        v[j] = trial % 2 ? j : n - j;
    memcpy(sorted, v, (size_t)n * sizeof(double));
    qsort(sorted, (size_t)n, sizeof(double), bsurf_cmp_double);
    for (int k = 0; k < n; k++) {
      memcpy(w, v, (size_t)n * sizeof(double));
      assert_true(bsurf_kth_smallest(w, (size_t)n, (size_t)k) == sorted[k]);
      assert_true(w[k] == sorted[k]);
      for (int j = 0; j < n; j++)
        assert_true(j < k ? w[j] <= w[k] : w[j] >= w[k]);
    }
  }
}

/* Identity frame at the origin: local coordinates are the coordinates. */
static void identity_frame(bsurf_frame *f) {
  memset(f, 0, sizeof *f);
  for (int t = 0; t < 3; t++)
    f->rot[t][t] = 1;
}

/* A polynomial of degree M is recovered exactly by a degree-M fit (and
 * predicted exactly everywhere), for M = 1..4, with or without weights. */
static void test_poly_exact_recovery(void **state) {
  (void)state;
  enum { K = 60 };
  double xyz[3 * K];
  uint32_t idx[K];
  bsurf_rng rng;
  bsurf_rng_init(&rng, 3, 1, 2);
  /* true coefficients in unscaled coordinates, graded order */
  double c_true[15];
  for (int i = 0; i < 15; i++)
    c_true[i] = bsurf_rng_uniform(&rng) * 2 - 1;
  for (int M = 1; M <= 4; M++) {
    int m = bsurf_poly_terms(M);
    for (int j = 0; j < K; j++) {
      double x = j == 0 ? 0 : 3 * (bsurf_rng_uniform(&rng) * 2 - 1);
      double y = j == 0 ? 0 : 3 * (bsurf_rng_uniform(&rng) * 2 - 1);
      double phi[15];
      bsurf_poly_basis(M, x, y, phi);
      double z = 0;
      for (int a = 0; a < m; a++)
        z += c_true[a] * phi[a];
      xyz[3 * j] = x;
      xyz[3 * j + 1] = y;
      xyz[3 * j + 2] = z;
      idx[j] = (uint32_t)j;
    }
    bsurf_frame f;
    identity_frame(&f);
    bsurf_localfit lf;
    assert_int_equal(bsurf_localfit_alloc(&lf, K, 4), BSURF_OK);
    bsurf_localfit_setup(&lf, xyz, idx, K, &f, 4);
    double coef[15], pred[K];
    assert_int_equal(bsurf_localfit_solve(&lf, M, NULL, coef), 0);
    bsurf_localfit_predict(&lf, M, 1, coef, NULL, pred);
    for (int j = 0; j < K; j++)
      assert_true(fabs(pred[j] - xyz[3 * j + 2]) < 1e-9);
    /* a higher-degree fit of a lower-degree polynomial is exact too */
    if (M < 4) {
      assert_int_equal(bsurf_localfit_solve(&lf, 4, NULL, coef), 0);
      bsurf_localfit_predict(&lf, 4, 1, coef, NULL, pred);
      for (int j = 0; j < K; j++)
        assert_true(fabs(pred[j] - xyz[3 * j + 2]) < 1e-9);
    }
    /* weighted (bootstrap-like) fit, and evaluation off the sample points */
    uint16_t counts[K];
    for (int j = 0; j < K; j++)
      counts[j] = (uint16_t)(j % 3);
    assert_int_equal(bsurf_localfit_solve(&lf, M, counts, coef), 0);
    double phi[15], z = 0;
    bsurf_poly_basis(M, 0.7, -1.3, phi);
    for (int a = 0; a < m; a++)
      z += c_true[a] * phi[a];
    assert_true(fabs(bsurf_localfit_eval(&lf, M, coef, 0.7, -1.3) - z) < 1e-9);
    bsurf_localfit_free(&lf);
  }
}

/* The replicates' residual sums (vector blocks of 8 points, the last one
 * overlapping, one, two or four replicates at a time) give the bits of the
 * plain loop: for every point the replicates in order b = 0..B-1, the terms
 * of each prediction in order from 0. For K below, at and above multiples
 * of 8, B with every remainder modulo 4, and replicates marked invalid. */
static void test_residual_sums_equal_plain(void **state) {
  (void)state;
  enum { KMAX = 29, BMAX = 11 };
  const int ks[] = {4, 7, 8, 13, 16, 21, 29}, Bs[] = {1, 2, 3, 4, 5, 7, 11};
  bsurf_rng rng;
  bsurf_rng_init(&rng, 5, 1, 2);
  double xyz[3 * KMAX];
  uint32_t idx[KMAX];
  for (int j = 0; j < KMAX; j++) {
    for (int t = 0; t < 3; t++)
      xyz[3 * j + t] = bsurf_rng_uniform(&rng) * 2 - 1;
    idx[j] = (uint32_t)j;
  }
  bsurf_frame f;
  identity_frame(&f);
  bsurf_localfit lf;
  assert_int_equal(bsurf_localfit_alloc(&lf, KMAX, 4), BSURF_OK);
  double coef[BMAX * 15], got[3][KMAX], want[3][KMAX];
  uint16_t counts[BMAX * KMAX];
  unsigned char valid[BMAX];
  int cases = 0;
  for (size_t ik = 0; ik < sizeof ks / sizeof *ks; ik++)
    for (int M = 1; M <= 4; M++) {
      const int k = ks[ik], m = bsurf_poly_terms(M);
      if (k < m) continue;
      bsurf_localfit_setup(&lf, xyz, idx, k, &f, M);
      for (size_t ib = 0; ib < sizeof Bs / sizeof *Bs; ib++)
        for (int mask = 0; mask < 3; mask++) {
          const int B = Bs[ib];
          for (int i = 0; i < B * m; i++)
            coef[i] = bsurf_rng_uniform(&rng) * 2 - 1;
          for (int i = 0; i < B * k; i++)
            counts[i] = (uint16_t)(bsurf_rng_next(&rng) % 3);
          /* none, every third, or one in the middle invalid */
          for (int b = 0; b < B; b++)
            valid[b] = mask == 1 ? b % 3 != 1 : mask == 2 ? b != B / 2 : 1;
          const unsigned char *v = mask ? valid : NULL;
          bsurf_localfit_residual_sums(&lf, M, B, coef, v, counts, got[0], got[1], got[2]);
          for (int j = 0; j < k; j++) {
            double s = 0, o = 0, c = 0;
            for (int b = 0; b < B; b++) {
              if (v && !v[b]) continue;
              double p = 0;
              for (int a = 0; a < m; a++)
                p += coef[b * m + a] * lf.phit[(size_t)a * lf.kp + j];
              const double e = fabs(p - lf.z[j]), w = counts[b * k + j] == 0 ? 1.0 : 0.0;
              s += e;
              o += w * e;
              c += w;
            }
            want[0][j] = s;
            want[1][j] = o;
            want[2][j] = c;
          }
          for (int t = 0; t < 3; t++)
            assert_memory_equal(got[t], want[t], (size_t)k * sizeof(double));
          cases++;
        }
    }
  assert_true(cases > 300);
  bsurf_localfit_free(&lf);
}

/* A flat patch of at most PATCH_MAX points, its frame and a fit for it. */
enum { PATCH_MAX = 64 };
typedef struct flat_patch_t {
  double xyz[3 * PATCH_MAX];
  uint32_t idx[PATCH_MAX];
  bsurf_rng rng; /* continues the stream the points came from */
  bsurf_frame f;
  bsurf_localfit lf;
} flat_patch_t;

/* K random points of a flat patch (|z| <= 0.1, x and y in [-1, 1]) from
 * the stream (seed, 2, 3), the identity frame, and a fit allocated for K
 * points up to degree 4. */
static void flat_patch(uint64_t seed, int K, flat_patch_t *p) {
  assert_true(K <= PATCH_MAX);
  bsurf_rng_init(&p->rng, seed, 2, 3);
  for (int j = 0; j < K; j++) {
    for (int t = 0; t < 3; t++)
      p->xyz[3 * j + t] = bsurf_rng_uniform(&p->rng) * 2 - 1;
    p->xyz[3 * j + 2] *= 0.1;
    p->idx[j] = (uint32_t)j;
  }
  identity_frame(&p->f);
  assert_int_equal(bsurf_localfit_alloc(&p->lf, K, 4), BSURF_OK);
}

/* The plain row-major product out (B x nc) = W (B x k) * A (k x nc), each
 * entry summed over j = 0..k-1 in order, a multiply then an add (C11
 * without contraction, as the library is built): the reference the lanes
 * must reproduce bit for bit. */
static void plain_rows(int B, int k, int nc, const double *W, const double *A, double *out) {
  for (int b = 0; b < B; b++)
    for (int col = 0; col < nc; col++) {
      double want = 0;
      for (int j = 0; j < k; j++) {
        const double term = W[b * k + j] * A[j * nc + col];
        want = want + term;
      }
      out[b * nc + col] = want;
    }
}

/* bsurf_gemm_lanes for row counts that are multiples of 4 and column
 * counts that are multiples of 8 (one group, several, a long last one)
 * gives the bits of the plain product, in the interleaved layout. */
static void test_gemm_lanes_any_shape(void **state) {
  (void)state;
  enum { K = 23 };
  const int rows[] = {4, 8, 52}, cols[] = {8, 16, 24};
  static double W[52 * K], A[K * 24], out[52 * 24], want[52 * 24];
  bsurf_rng r;
  bsurf_rng_init(&r, 5, 6, 7);
  for (int t = 0; t < 52 * K; t++)
    W[t] = (double)(bsurf_rng_next(&r) % 4);
  for (int t = 0; t < K * 24; t++)
    A[t] = bsurf_rng_normal(&r) * 1e3;
  for (size_t a = 0; a < sizeof rows / sizeof rows[0]; a++)
    for (size_t c = 0; c < sizeof cols / sizeof cols[0]; c++) {
      const int R = rows[a], nc = cols[c];
      bsurf_gemm_lanes(R, K, nc, W, A, out);
      plain_rows(R, K, nc, W, A, want);
      for (int b = 0; b < R; b++)
        for (int col = 0; col < nc; col++)
          assert_memory_equal(&out[(size_t)(b / 4) * 4 * nc + 4 * col + b % 4], &want[b * nc + col],
                              sizeof(double));
    }
}

/* The normal equations of many weighted fits as one matrix product in
 * vector lanes (the dense reference that the bootstrap's sums from draws
 * are checked against, test_draw_sums) give the same bits as the row
 * product and as one fit at a time, and the lane solver the same
 * coefficients (or the same rank-deficiency) as the row solver. */
static void test_lanes_equal_rows(void **state) {
  (void)state;
  enum { K = 37, R = 12 };
  flat_patch_t pt;
  flat_patch(11, K, &pt);
  for (int D = 1; D <= 4; D++) {
    bsurf_localfit_setup(&pt.lf, pt.xyz, pt.idx, K, &pt.f, D);
    const int nc = pt.lf.ncols, m = bsurf_poly_terms(D);
    double W[R * K], rows[R * 64], lanes[R * 64], row[64];
    uint16_t counts[R][K];
    for (int b = 0; b < R; b++)
      for (int j = 0; j < K; j++) {
        /* replicate 5 has only 2 distinct points: rank-deficient */
        counts[b][j] = b == 5 ? (uint16_t)(j < 2 ? 5 : 0) : (uint16_t)((j * 7 + b * 3) % 4);
        W[b * K + j] = counts[b][j];
      }
    plain_rows(R, K, nc, W, pt.lf.op, rows);
    bsurf_localfit_normal_eq_lanes(&pt.lf, R, W, lanes);
    unsigned char valid[R];
    double coefs[R * 15];
    for (int b = 0; b < R; b++) {
      bsurf_lanes_row(nc, lanes, b, row);
      assert_memory_equal(row, &rows[b * nc], (size_t)nc * sizeof *row);
      valid[b] = b != 7; /* a replicate the caller skips */
    }
    bsurf_localfit_solve_lanes(&pt.lf, D, R, lanes, valid, coefs);
    for (int b = 0; b < R; b++) {
      double c[15];
      int st = bsurf_localfit_solve(&pt.lf, D, counts[b], c);
      if (b == 7) continue;
      assert_int_equal(valid[b], st == 0);
      if (st == 0) assert_memory_equal(c, &coefs[b * m], (size_t)m * sizeof *c);
    }
    assert_int_equal(valid[5], 0);
  }
  bsurf_localfit_free(&pt.lf);
}

/* The normal equations from draws (the bootstrap's path): each row is the
 * sum of the drawn rows of A in the order drawn, bit for bit what a plain
 * loop gives; row B is the dense product's with weights 1, bit for bit;
 * the rows past B are zero; and every row equals the dense product of the
 * draws' counts up to rounding. For every degree (column counts 16, 24, 40,
 * 64), odd and even B and k, and k below 8. */
static void test_draw_sums(void **state) {
  (void)state;
  enum { KMAX = 53, BMAX = 9 };
  flat_patch_t pt;
  flat_patch(12, KMAX, &pt);
  const int ks[] = {5, 37, 53}, Bs[] = {1, 6, 7, 8, 9};
  for (int D = 1; D <= 4; D++)
    for (size_t ik = 0; ik < sizeof ks / sizeof ks[0]; ik++)
      for (size_t ib = 0; ib < sizeof Bs / sizeof Bs[0]; ib++) {
        const int K = ks[ik], B = Bs[ib], R = (B + 4) / 4 * 4;
        bsurf_localfit_setup(&pt.lf, pt.xyz, pt.idx, K, &pt.f, D);
        const int nc = pt.lf.ncols;
        uint16_t draws[BMAX * KMAX];
        double W[(BMAX + 4) * KMAX], lanes[(BMAX + 4) * 64], dense[(BMAX + 4) * 64], row[64];
        for (int b = 0; b < R; b++)
          for (int j = 0; j < K; j++)
            W[b * K + j] = b == B ? 1.0 : 0.0;
        for (int b = 0; b < B; b++)
          for (int t = 0; t < K; t++) {
            const uint16_t j = (uint16_t)(bsurf_rng_next(&pt.rng) % (uint64_t)K);
            draws[b * K + t] = j;
            W[b * K + j] += 1.0;
          }
        bsurf_draw_sums_lanes(B, K, nc, draws, pt.lf.op, lanes);
        bsurf_gemm_lanes(R, K, nc, W, pt.lf.op, dense);
        for (int b = 0; b < R; b++) {
          bsurf_lanes_row(nc, lanes, b, row);
          double ref[64], dref[64];
          bsurf_lanes_row(nc, dense, b, dref);
          for (int c = 0; c < nc; c++) {
            double x = 0;
            if (b < B)
              for (int t = 0; t < K; t++)
                x += pt.lf.op[(size_t)draws[b * K + t] * nc + c];
            ref[c] = x;
            if (b < B) {
              double mag = 0;
              for (int j = 0; j < K; j++)
                mag += W[b * K + j] * fabs(pt.lf.op[(size_t)j * nc + c]);
              assert_true(fabs(row[c] - dref[c]) <= 1e-14 * mag);
            }
          }
          if (b < B)
            assert_memory_equal(row, ref, (size_t)nc * sizeof *row);
          else /* the whole neighbourhood, and zero rows */
            assert_memory_equal(row, dref, (size_t)nc * sizeof *row);
        }
      }
  bsurf_localfit_free(&pt.lf);
}

/* Collinear points (all on the x axis) cannot determine a surface: every
 * degree >= 1 is reported rank-deficient, never silently solved. */
static void test_rank_deficient_detected(void **state) {
  (void)state;
  enum { K = 30 };
  double xyz[3 * K];
  uint32_t idx[K];
  for (int j = 0; j < K; j++) {
    xyz[3 * j] = j * 0.1;
    xyz[3 * j + 1] = 0;
    xyz[3 * j + 2] = 0.5 * j;
    idx[j] = (uint32_t)j;
  }
  bsurf_frame f;
  identity_frame(&f);
  bsurf_localfit lf;
  assert_int_equal(bsurf_localfit_alloc(&lf, K, 4), BSURF_OK);
  bsurf_localfit_setup(&lf, xyz, idx, K, &f, 4);
  double coef[15];
  for (int M = 1; M <= 4; M++)
    assert_int_equal(bsurf_localfit_solve(&lf, M, NULL, coef), -1);
  assert_int_equal(bsurf_localfit_solve(&lf, 0, NULL, coef), 0);
  /* a weighted sample with fewer distinct points than terms */
  uint16_t counts[K] = {0};
  counts[0] = 10;
  counts[5] = 10;
  counts[9] = 10;
  bsurf_localfit_setup(&lf, xyz, idx, K, &f, 4);
  assert_int_equal(bsurf_localfit_solve(&lf, 1, counts, coef), -1);
  /* 9 points on a 3x3 grid determine a quadratic's 6 terms but not a
   * cubic's 10 */
  for (int j = 0; j < 9; j++) {
    xyz[3 * j] = j % 3;
    xyz[3 * j + 1] = j / 3;
    xyz[3 * j + 2] = 0;
  }
  bsurf_localfit_setup(&lf, xyz, idx, 9, &f, 4);
  assert_int_equal(bsurf_localfit_solve(&lf, 2, NULL, coef), 0);
  assert_int_equal(bsurf_localfit_solve(&lf, 3, NULL, coef), -1);
  bsurf_localfit_free(&lf);
}

/* PCA normal of a noisy plane: the angle to the true normal is small and
 * shrinks with K. Theory: each tilt component has standard deviation about
 * sigma / sqrt(K var(x)), var(x) = r^2/4 over a disc holding K points
 * (r^2 = K h^2 / pi), and the mean angle is 1.25 times that: with
 * sigma = 0.3 h, 0.088 rad at K = 15 and 0.022 rad at K = 60. */
static void test_pca_noisy_plane(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_PLANE, 10000, BSURF_SAMPLING_REGULAR, 1, 0),
                   BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, c.point_count, 1, &h), BSURF_OK);
  assert_true(fabs(h - 0.02) < 1e-9);
  assert_int_equal(
      bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_GAUSSIAN, 0.3, h, 5), BSURF_OK);
  double prev = 1e9;
  int ks[2] = {15, 60};
  for (int t = 0; t < 2; t++) {
    bsurf_neighbors nb;
    assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, ks[t], 2, NULL, NULL),
                     BSURF_OK);
    double sum = 0;
    size_t count = 0;
    for (size_t i = 0; i < c.point_count; i++) {
      const double *p = &c.xyz[3 * i];
      if (fabs(p[0]) > 0.8 || fabs(p[1]) > 0.8) continue; /* away from the border */
      bsurf_frame f;
      bsurf_local_frame(c.xyz, &nb.idx[i * nb.k], nb.k, BSURF_PCA_CENTROID, &f);
      double cosang = fabs(f.rot[2][2]);
      sum += acos(cosang > 1 ? 1 : cosang);
      count++;
    }
    double mean = sum / count;
    assert_true(mean < (ks[t] == 15 ? 0.11 : 0.03));
    assert_true(mean < prev);
    prev = mean;
    bsurf_neighbors_free(&nb);
  }
  bsurf_cloud_free(&c);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_eigen_known),
      cmocka_unit_test(test_eigen_degenerate),
      cmocka_unit_test(test_eigen_sym_n),
      cmocka_unit_test(test_f_quantile),
      cmocka_unit_test(test_frame_tangent_plane_height_zero),
      cmocka_unit_test(test_poly_basis_order),
      cmocka_unit_test(test_poly_basis_bits),
      cmocka_unit_test(test_ldl_factored),
      cmocka_unit_test(test_kth_smallest),
      cmocka_unit_test(test_poly_exact_recovery),
      cmocka_unit_test(test_rank_deficient_detected),
      cmocka_unit_test(test_gemm_lanes_any_shape),
      cmocka_unit_test(test_lanes_equal_rows),
      cmocka_unit_test(test_draw_sums),
      cmocka_unit_test(test_residual_sums_equal_plain),
      cmocka_unit_test(test_pca_noisy_plane),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
