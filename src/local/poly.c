/* Bivariate polynomial height functions z' = f(x', y') of total degree
 * M = 1..4 (thesis 3.3 and appendix A), and their least-squares fits.
 *
 * Appendix A lists the monomials in another order; any order spans the same
 * space, and the graded order used here makes the basis of degree M-1 a
 * prefix of the basis of degree M, so one set of precomputed products serves
 * every degree. Local coordinates are divided by the neighbourhood radius
 * before the monomials are formed, which keeps the normal equations well
 * conditioned (all basis values in [-1, 1]). */
#include "common/common.h"
#include "local/local.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int bsurf_poly_terms(int degree) {
  if (degree < 0) return 0;
  return (degree + 1) * (degree + 2) / 2;
}

void bsurf_poly_basis_grad(int degree, double u, double v, double *du, double *dv) {
  /* monomial u^(d-j) v^j: d/du = (d-j) u^(d-j-1) v^j, d/dv = j u^(d-j) v^(j-1) */
  double up[BSURF_DEGREE_MAX + 1], vp[BSURF_DEGREE_MAX + 1];
  up[0] = vp[0] = 1.0;
  for (int e = 1; e <= degree; e++) {
    up[e] = up[e - 1] * u;
    vp[e] = vp[e - 1] * v;
  }
  int t = 0;
  for (int d = 0; d <= degree; d++)
    for (int j = 0; j <= d; j++, t++) {
      int eu = d - j, ev = j;
      du[t] = eu > 0 ? eu * up[eu - 1] * vp[ev] : 0.0;
      dv[t] = ev > 0 ? ev * up[eu] * vp[ev - 1] : 0.0;
    }
}

int bsurf_ldl_factor_packed(int m, const double *G, double rel_tol, bsurf_ldl *f) {
  /* G = L D L^T with L unit lower triangular (LDL^T: no square roots), by
   * columns: A[i][j] = G[i][j] - sum_t L[i][t] A[j][t] (t < j) is L[i][j]
   * D[j], D[j] = A[j][j], L[i][j] = A[i][j] inv[j] with inv[j] = 1 / D[j],
   * so each column costs one division. L and A row-major in full m x m
   * arrays. */
  double A[BSURF_TERMS_MAX * BSURF_TERMS_MAX];
  double *L = f->L, *inv = f->inv;
  f->m = m;
  for (int j = 0; j < m; j++) {
    const double gjj = G[bsurf_packed_index(j, j)];
    double s = gjj;
    for (int t = 0; t < j; t++)
      s -= L[j * m + t] * A[j * m + t];
    if (!(s > rel_tol * gjj) || !(gjj > 0)) return -1; /* also catches NaN */
    inv[j] = 1.0 / s;
    for (int i = j + 1; i < m; i++) {
      double a = G[bsurf_packed_index(j, i)];
      for (int t = 0; t < j; t++)
        a -= L[i * m + t] * A[j * m + t];
      A[i * m + j] = a;
      L[i * m + j] = a * inv[j];
    }
  }
  return 0;
}

void bsurf_ldl_solve_factored(const bsurf_ldl *f, const double *r, double *c) {
  const int m = f->m;
  const double *L = f->L, *inv = f->inv;
  double y[BSURF_TERMS_MAX];
  for (int i = 0; i < m; i++) { /* L y = r */
    double a = r[i];
    for (int t = 0; t < i; t++)
      a -= L[i * m + t] * y[t];
    y[i] = a;
  }
  for (int i = m - 1; i >= 0; i--) { /* L^T c = D^-1 y */
    double a = y[i] * inv[i];
    for (int t = i + 1; t < m; t++)
      a -= L[t * m + i] * c[t];
    c[i] = a;
  }
}

int bsurf_ldl_solve_packed(int m, const double *G, const double *r, double rel_tol, double *c) {
  bsurf_ldl f;
  if (bsurf_ldl_factor_packed(m, G, rel_tol, &f) != 0) return -1;
  bsurf_ldl_solve_factored(&f, r, c);
  return 0;
}

bsurf_status bsurf_localfit_alloc(bsurf_localfit *lf, int kmax, int degree_max) {
  memset(lf, 0, sizeof *lf);
  if (kmax < 1 || degree_max < 0 || degree_max > BSURF_DEGREE_MAX) return BSURF_ERR_INVALID_ARG;
  int m = bsurf_poly_terms(degree_max), ncols = (bsurf_poly_terms(2 * degree_max) + m + 7) / 8 * 8;
  lf->kmax = kmax;
  lf->degree_max = degree_max;
  lf->u = bsurf_alloc_array((size_t)kmax, 3 * sizeof(double));
  /* phit rows are padded to a multiple of 8 points (zeros) for the
   * register blocks of bsurf_localfit_predict */
  lf->phit = bsurf_alloc_aligned((size_t)(kmax + 7) / 8 * 8 * m, sizeof(double));
  lf->op = bsurf_alloc_aligned((size_t)kmax * ncols, sizeof(double));
  if (!lf->u || !lf->phit || !lf->op) {
    bsurf_localfit_free(lf);
    return BSURF_ERR_NOMEM;
  }
  lf->v = lf->u + kmax;
  lf->z = lf->u + 2 * (size_t)kmax;
  return BSURF_OK;
}

void bsurf_localfit_free(bsurf_localfit *lf) {
  free(lf->u);
  free(lf->phit);
  free(lf->op);
  memset(lf, 0, sizeof *lf);
}

/* The monomials u^i v^e of degree <= d in graded order (u^i v^e at
 * (i+e)(i+e+1)/2 + e), each v^e times u, i times, left to right: the same
 * products as bsurf_poly_basis. */
static inline __attribute__((always_inline)) void monomials(int d, double u, double v, double *o) {
  double ve = 1.0;
  for (int e = 0; e <= d; e++) {
    double x = ve;
    for (int i = 0; i + e <= d; i++) {
      o[(i + e) * (i + e + 1) / 2 + e] = x;
      x *= u;
    }
    ve *= v;
  }
}

void bsurf_localfit_setup(bsurf_localfit *lf, const double *xyz, const uint32_t *idx, int k,
                          const bsurf_frame *frame, int degree) {
  lf->k = k;
  lf->degree = degree;
  lf->m = bsurf_poly_terms(degree);
  lf->p = bsurf_poly_terms(2 * degree);
  /* padded with zero columns to a multiple of 8, the width of the matrix
   * product's register blocks */
  lf->ncols = (lf->p + lf->m + 7) / 8 * 8;
  double r2max = 0;
  for (int j = 0; j < k; j++) {
    double q[3];
    bsurf_frame_to_local(frame, &xyz[3 * (size_t)idx[j]], q);
    lf->u[j] = q[0];
    lf->v[j] = q[1];
    lf->z[j] = q[2];
    double r2 = q[0] * q[0] + q[1] * q[1];
    if (r2 > r2max) r2max = r2;
  }
  lf->scale = r2max > 0 ? sqrt(r2max) : 1.0;
  const double inv = 1.0 / lf->scale;
  const int m = lf->m, p = lf->p, nc = lf->ncols, kp = (k + 7) / 8 * 8, d2 = 2 * degree;
  lf->kp = kp;
  for (int j = 0; j < k; j++) {
    const double u = lf->u[j] * inv, v = lf->v[j] * inv;
    lf->u[j] = u;
    lf->v[j] = v;
    /* the monomials of degree <= 2M in graded order: every product
     * phi_a phi_b is one of them (moment_index), and the basis of degree M
     * is their prefix */
    double *o = &lf->op[(size_t)j * nc];
    switch (d2) { /* constant degrees unroll */
    case 2: monomials(2, u, v, o); break;
    case 4: monomials(4, u, v, o); break;
    case 6: monomials(6, u, v, o); break;
    default: monomials(d2, u, v, o); break;
    }
    for (int a = 0; a < m; a++)
      lf->phit[(size_t)a * kp + j] = o[a];
    for (int a = 0; a < m; a++)
      o[p + a] = o[a] * lf->z[j];
    for (int c = p + m; c < nc; c++)
      o[c] = 0.0;
  }
  for (int a = 0; a < m; a++)
    for (int j = k; j < kp; j++)
      lf->phit[(size_t)a * kp + j] = 0.0;
}

/* Position of the monomial phi_a phi_b among the graded monomials, for
 * every packed (a, b), a <= b < BSURF_TERMS_MAX: phi_a of total degree d_a
 * has v-power j_a = a - d_a(d_a+1)/2, and u^i v^j of degree d = i + j sits at
 * d(d+1)/2 + j, so phi_a phi_b is at d(d+1)/2 + j_a + j_b with d = d_a + d_b.
 * (Generated from that formula; a wrong entry breaks test_local's exact
 * recovery of polynomials.) */
static const unsigned char packed_moment[BSURF_PACKED_MAX] = {
    0,  1,  3,  2,  4,  5,  3,  6,  7,  10, 4,  7,  8,  11, 12, 5,  8,  9,  12, 13, 14, 6,  10, 11,
    15, 16, 17, 21, 7,  11, 12, 16, 17, 18, 22, 23, 8,  12, 13, 17, 18, 19, 23, 24, 25, 9,  13, 14,
    18, 19, 20, 24, 25, 26, 27, 10, 15, 16, 21, 22, 23, 28, 29, 30, 31, 36, 11, 16, 17, 22, 23, 24,
    29, 30, 31, 32, 37, 38, 12, 17, 18, 23, 24, 25, 30, 31, 32, 33, 38, 39, 40, 13, 18, 19, 24, 25,
    26, 31, 32, 33, 34, 39, 40, 41, 42, 14, 19, 20, 25, 26, 27, 32, 33, 34, 35, 40, 41, 42, 43, 44,
};

static const unsigned char *moment_map(void) {
  return packed_moment;
}

/* The packed G (m x m) of one row of moments. */
static void gram_from_moments(int m, const double *row, double *G) {
  const unsigned char *map = moment_map();
  const int pm = m * (m + 1) / 2;
  for (int q = 0; q < pm; q++)
    G[q] = row[map[q]];
}

#if defined(__GNUC__)
typedef double v4d __attribute__((vector_size(32)));
#define HAVE_V4D 1
#endif

#ifdef HAVE_V4D
typedef long long v4l __attribute__((vector_size(32)));

/* LDL^T solves in vector lanes, two groups of four at once (g4[0],
 * g4[1]: groups of bsurf_gemm_lanes, column c of a group's four rows at
 * [4c .. 4c+3]), with exactly the operations of bsurf_ldl_solve_packed in
 * each lane (so the same bits). The two independent groups are interleaved
 * statement by statement to hide the latency of the divisions. A lane
 * whose pivot fails is given pivot 1 to keep the others going and is
 * reported in the returned bit mask of failures (lane 4h + l for group h);
 * lanes not in `want` are not stored. Inlined with a constant m
 * (ldl_solve8_m) so that the compiler unrolls the small loops. */
static inline __attribute__((always_inline)) int ldl_solve8(int m, int p, const double *const g4[2],
                                                            double rel_tol, int want,
                                                            double *const coef[8]) {
  v4d G[2][BSURF_PACKED_MAX], r[2][BSURF_TERMS_MAX], L[2][BSURF_TERMS_MAX * BSURF_TERMS_MAX];
  v4d A[2][BSURF_TERMS_MAX * BSURF_TERMS_MAX];
  v4d inv[2][BSURF_TERMS_MAX], y[2][BSURF_TERMS_MAX], c[2][BSURF_TERMS_MAX];
  const int pm = m * (m + 1) / 2;
  const unsigned char *map = moment_map();
  for (int h = 0; h < 2; h++) {
    for (int q = 0; q < pm; q++)
      memcpy(&G[h][q], &g4[h][4 * map[q]], sizeof(v4d));
    for (int i = 0; i < m; i++)
      memcpy(&r[h][i], &g4[h][4 * (p + i)], sizeof(v4d));
  }
  const v4d one = {1, 1, 1, 1}, zero = {0, 0, 0, 0};
  const v4d tol = {rel_tol, rel_tol, rel_tol, rel_tol};
  v4l failed[2] = {{0, 0, 0, 0}, {0, 0, 0, 0}};
  for (int j = 0; j < m; j++) {
    for (int h = 0; h < 2; h++) {
      const v4d gjj = G[h][bsurf_packed_index(j, j)];
      v4d s = gjj;
      for (int t = 0; t < j; t++)
        s -= L[h][j * m + t] * A[h][j * m + t];
      v4l ok = (s > tol * gjj) & (gjj > zero);
      failed[h] |= ~ok;
      s = (v4d)(((v4l)s & ok) | ((v4l)one & ~ok));
      inv[h][j] = one / s;
    }
    for (int i = j + 1; i < m; i++)
      for (int h = 0; h < 2; h++) {
        v4d a = G[h][bsurf_packed_index(j, i)];
        for (int t = 0; t < j; t++)
          a -= L[h][i * m + t] * A[h][j * m + t];
        A[h][i * m + j] = a;
        L[h][i * m + j] = a * inv[h][j];
      }
  }
  for (int i = 0; i < m; i++)
    for (int h = 0; h < 2; h++) {
      v4d a = r[h][i];
      for (int t = 0; t < i; t++)
        a -= L[h][i * m + t] * y[h][t];
      y[h][i] = a;
    }
  for (int i = m - 1; i >= 0; i--)
    for (int h = 0; h < 2; h++) {
      v4d a = y[h][i] * inv[h][i];
      for (int t = i + 1; t < m; t++)
        a -= L[h][t * m + i] * c[h][t];
      c[h][i] = a;
    }
  int mask = 0;
  for (int l = 0; l < 8; l++) {
    if (failed[l / 4][l % 4])
      mask |= 1 << l;
    else if (want & (1 << l))
      for (int i = 0; i < m; i++)
        coef[l][i] = c[l / 4][i][l % 4];
  }
  return mask;
}

/* dst = column `col` of a group of four rows (bsurf_gemm_lanes layout) */
#define LD4(dst, g, col) memcpy(&(dst), &(g)[4 * (col)], sizeof(v4d))
/* ldl_solve8 for m = 3, 6, 10 as straight-line code (generated). */
#include "ldl_unrolled.h" /* generated/ (scripts/gen_ldl_unrolled.py) */

BSURF_CLONES
static int ldl_solve8_m(int m, int p, const double *const g4[2], double rel_tol, int want,
                        double *const coef[8]) {
  switch (m) {
  case 3: return ldl_solve8_3(p, g4, rel_tol, want, coef);
  case 6: return ldl_solve8_6(p, g4, rel_tol, want, coef);
  case 10: return ldl_solve8_10(p, g4, rel_tol, want, coef);
  default: return ldl_solve8(m, p, g4, rel_tol, want, coef);
  }
}
#endif

void bsurf_localfit_solve_lanes(const bsurf_localfit *lf, int degree, int B, const double *lanes,
                                unsigned char *valid, double *coefs) {
  const int m = bsurf_poly_terms(degree), nc = lf->ncols;
  for (int b0 = 0; b0 < B; b0 += 8) {
    int want = 0;
    for (int l = 0; l < 8 && b0 + l < B; l++)
      if (valid[b0 + l]) want |= 1 << l;
    if (!want) continue;
#ifdef HAVE_V4D
    /* a missing second group repeats the first (its lanes are not wanted) */
    const double *g4[2] = {&lanes[(size_t)b0 * nc],
                           &lanes[(size_t)(b0 + 4 < B ? b0 + 4 : b0) * nc]};
    double *cp[8];
    for (int l = 0; l < 8; l++)
      cp[l] = &coefs[(size_t)(want & (1 << l) ? b0 + l : b0) * m];
    int failed = ldl_solve8_m(m, lf->p, g4, BSURF_RANK_TOL, want, cp) & want;
    for (int l = 0; l < 8; l++)
      if (failed & (1 << l)) valid[b0 + l] = 0;
#else
    for (int l = 0; l < 8; l++) {
      if (!(want & (1 << l))) continue;
      double row[BSURF_NCOLS_MAX];
      bsurf_lanes_row(nc, lanes, b0 + l, row);
      if (bsurf_localfit_solve_row(lf, degree, row, &coefs[(size_t)(b0 + l) * m]) != 0)
        valid[b0 + l] = 0;
    }
#endif
  }
}

void bsurf_localfit_normal_eq_lanes(const bsurf_localfit *lf, int R, const double *W,
                                    double *lanes) {
  bsurf_gemm_lanes(R, lf->k, lf->ncols, W, lf->op, lanes);
}

void bsurf_localfit_normal_eq_draws(const bsurf_localfit *lf, int B, const uint16_t *draws,
                                    double *lanes) {
  bsurf_draw_sums_lanes(B, lf->k, lf->ncols, draws, lf->op, lanes);
}

int bsurf_localfit_solve_row(const bsurf_localfit *lf, int degree, const double *row,
                             double *coef) {
  /* G from the moments (a lower degree uses a subset of them); the
   * right-hand side of a lower degree is a prefix of r, which starts at
   * column p */
  const int m = bsurf_poly_terms(degree);
  double G[BSURF_PACKED_MAX];
  gram_from_moments(m, row, G);
  return bsurf_ldl_solve_packed(m, G, row + lf->p, BSURF_RANK_TOL, coef);
}

int bsurf_localfit_solve_row_grad(const bsurf_localfit *lf, int degree, const double *row,
                                  double *coef, double ginv_g[3]) {
  const int m = bsurf_poly_terms(degree);
  double G[BSURF_PACKED_MAX];
  gram_from_moments(m, row, G);
  bsurf_ldl f;
  if (bsurf_ldl_factor_packed(m, G, BSURF_RANK_TOL, &f) != 0) return -1;
  bsurf_ldl_solve_factored(&f, row + lf->p, coef);
  /* columns 1 and 2 of G^-1 (the gradient's coefficients u, v) */
  double e[BSURF_TERMS_MAX] = {0}, x1[BSURF_TERMS_MAX], x2[BSURF_TERMS_MAX];
  e[1] = 1.0;
  bsurf_ldl_solve_factored(&f, e, x1);
  e[1] = 0.0, e[2] = 1.0;
  bsurf_ldl_solve_factored(&f, e, x2);
  ginv_g[0] = x1[1], ginv_g[1] = 0.5 * (x1[2] + x2[1]), ginv_g[2] = x2[2];
  return 0;
}

int bsurf_localfit_solve(const bsurf_localfit *lf, int degree, const uint16_t *counts,
                         double *coef) {
  const int k = lf->k, m = bsurf_poly_terms(degree), nc = lf->ncols;
  double row[BSURF_NCOLS_MAX] = {0};
  int distinct = 0;
  for (int j = 0; j < k; j++) {
    double w = counts ? (double)counts[j] : 1.0;
    if (w == 0) continue;
    distinct++;
    const double *o = &lf->op[(size_t)j * nc];
    for (int a = 0; a < nc; a++)
      row[a] += w * o[a];
  }
  if (distinct < m) return -1; /* fewer distinct points than coefficients */
  return bsurf_localfit_solve_row(lf, degree, row, coef);
}

#ifdef HAVE_V4D
/* The predictions of R <= 4 fits (coefficients c[r]) at 8 points whose basis
 * values are ph[a * stride + 0..7]: p[2 r], p[2 r + 1] for fit r, the terms
 * added in order a = 0..m-1 from 0, as the plain loop. The fits share each
 * load of the basis, and their 2 R chains of additions are independent. */
static inline __attribute__((always_inline)) void
predict8(int m, int R, const double *ph, size_t stride, const double *const *c, v4d p[8]) {
  v4d acc[8];
  for (int i = 0; i < 2 * R; i++)
    acc[i] = (v4d){0, 0, 0, 0};
    /* kept a loop: unrolled (m = 10), GCC hoisted all 4 m broadcasts and
     * spilled the accumulators */
#pragma GCC unroll 1
  for (int a = 0; a < m; a++) {
    v4d x0, x1;
    memcpy(&x0, &ph[(size_t)a * stride], sizeof x0);
    memcpy(&x1, &ph[(size_t)a * stride + 4], sizeof x1);
    for (int r = 0; r < R; r++) {
      const v4d ca = {c[r][a], c[r][a], c[r][a], c[r][a]};
      acc[2 * r] += ca * x0;
      acc[2 * r + 1] += ca * x1;
    }
  }
  for (int i = 0; i < 2 * R; i++)
    p[i] = acc[i];
}
#endif

BSURF_CLONES
void bsurf_localfit_predict(const bsurf_localfit *lf, int degree, int B, const double *coef,
                            const unsigned char *valid, double *pred) {
  /* pred[b][j] = sum_a coef[b][a] phi_a(x_j), summed over a in order;
   * vectorised across j, eight points at a time. */
  const int m = bsurf_poly_terms(degree), k = lf->k, kp = lf->kp;
#ifdef HAVE_V4D
  for (int b = 0; b < B; b++) {
    if (valid && !valid[b]) continue;
    for (int j0 = 0; j0 < k; j0 += 8) {
      v4d p[8];
      double t[8];
      const double *cb = &coef[(size_t)b * m];
      predict8(m, 1, &lf->phit[j0], (size_t)kp, &cb, p);
      memcpy(t, &p[0], 32);
      memcpy(t + 4, &p[1], 32);
      memcpy(&pred[(size_t)b * k + j0], t, (size_t)(k - j0 < 8 ? k - j0 : 8) * sizeof *t);
    }
  }
#else
  for (int b = 0; b < B; b++) {
    if (valid && !valid[b]) continue;
    double *restrict pb = &pred[(size_t)b * k];
    const double *cb = &coef[(size_t)b * m];
    for (int j = 0; j < k; j++)
      pb[j] = 0;
    for (int a = 0; a < m; a++) {
      const double ca = cb[a];
      const double *restrict ph = &lf->phit[(size_t)a * kp];
      for (int j = 0; j < k; j++)
        pb[j] += ca * ph[j];
    }
  }
#endif
}

#ifdef HAVE_V4D
/* The residuals' sums at the points of one block, in registers: all (s),
 * out (o, left-out points only) and cnt (c), 4 points per vector. */
typedef struct res_acc {
  v4d s, o, c;
} res_acc;

/* Adds the residual of one prediction p at heights y, multiplicities at
 * cr (0: left out): the operations of one replicate, in order. */
static inline __attribute__((always_inline)) void res_add(const v4d *p, const v4d *y,
                                                          const uint16_t *cr, res_acc *acc) {
  const v4d one = {1, 1, 1, 1};
  const v4l mc = {cr[0], cr[1], cr[2], cr[3]}, zero = {0, 0, 0, 0};
  /* 1.0 where the count is 0 (the point is not in replicate b), else 0 */
  const v4d w = (v4d)((mc == zero) & (v4l)one);
  v4d e = *p - *y;
  for (int l = 0; l < 4; l++)
    e[l] = fabs(e[l]); /* lane by lane (vectorised) */
  acc->s += e;
  acc->o += w * e;
  acc->c += w;
}

/* The residuals of R fits (coefficients c[r], multiplicity rows w[r]) at
 * the 8 points of a block (basis values ph, packed m x 8; heights y) added
 * to the sums, fit after fit. */
static inline __attribute__((always_inline)) void res_fits(int m, int R, const double *ph,
                                                           const double *const *c,
                                                           const uint16_t *const *w, const v4d y[2],
                                                           res_acc *acc0, res_acc *acc1) {
  v4d p[8];
  predict8(m, R, ph, 8, c, p);
  for (int r = 0; r < R; r++) {
    res_add(&p[2 * r], &y[0], w[r], acc0);
    res_add(&p[2 * r + 1], &y[1], w[r] + 4, acc1);
  }
}

/* The residual sums of bsurf_localfit_residual_sums for points j0..j0+7,
 * four (else two) valid replicates at a time where they follow each other;
 * for every point the replicates are added in order b = 0..B-1 as one at a
 * time. With pad (only when k < 8) the n = k - j0 points are padded to 8. */
static inline __attribute__((always_inline)) void
residual_block(int m, int pad, int k, int kp, const double *phit, const double *z, int j0, int B,
               const double *coef, const unsigned char *valid, const uint16_t *counts, double *all,
               double *out, double *cnt) {
  const int n = pad ? k - j0 : 8;
  /* the block's basis values packed (constant offsets, not m row pointers);
   * phit is zero-padded to kp, a multiple of 8 */
  double ph[BSURF_TERMS_MAX][8];
  for (int a = 0; a < m; a++) { /* by vectors: a memcpy loop became rep movsq */
    v4d x0, x1;
    memcpy(&x0, &phit[(size_t)a * kp + j0], sizeof x0);
    memcpy(&x1, &phit[(size_t)a * kp + j0 + 4], sizeof x1);
    memcpy(&ph[a][0], &x0, sizeof x0);
    memcpy(&ph[a][4], &x1, sizeof x1);
  }
  double yb[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  uint16_t wb[4][8];
  for (int l = 0; l < n; l++)
    yb[l] = z[j0 + l];
  for (int r = 0; r < 4; r++)
    for (int l = 0; l < 8; l++)
      wb[r][l] = 1; /* padding: drawn once, not missing */
  v4d y[2];
  memcpy(&y[0], yb, 32);
  memcpy(&y[1], yb + 4, 32);
  const v4d zero = {0, 0, 0, 0};
  res_acc acc0 = {zero, zero, zero}, acc1 = acc0;
  for (int b = 0; b < B;) {
    /* four valid replicates in a row, else two, else one */
    int R = 1;
    if (b + 3 < B && (!valid || (valid[b] && valid[b + 1] && valid[b + 2] && valid[b + 3])))
      R = 4;
    else if (b + 1 < B && (!valid || (valid[b] && valid[b + 1])))
      R = 2;
    else if (valid && !valid[b]) {
      b++;
      continue;
    }
    const double *c[4];
    const uint16_t *w[4];
    for (int r = 0; r < R; r++) {
      c[r] = &coef[(size_t)(b + r) * m];
      w[r] = &counts[(size_t)(b + r) * k + j0];
      if (pad) {
        for (int l = 0; l < n; l++)
          wb[r][l] = w[r][l];
        w[r] = wb[r];
      }
    }
    if (R == 4)
      res_fits(m, 4, ph[0], c, w, y, &acc0, &acc1);
    else if (R == 2)
      res_fits(m, 2, ph[0], c, w, y, &acc0, &acc1);
    else
      res_fits(m, 1, ph[0], c, w, y, &acc0, &acc1);
    b += R;
  }
  const res_acc *acc[2] = {&acc0, &acc1};
  for (int l = 0; l < n; l++) {
    all[j0 + l] = acc[l / 4]->s[l % 4];
    out[j0 + l] = acc[l / 4]->o[l % 4];
    cnt[j0 + l] = acc[l / 4]->c[l % 4];
  }
}
#endif

BSURF_CLONES
void bsurf_localfit_residual_sums(const bsurf_localfit *lf, int degree, int B, const double *coef,
                                  const unsigned char *valid, const uint16_t *counts, double *all,
                                  double *out, double *cnt) {
  const int m = bsurf_poly_terms(degree), k = lf->k, kp = lf->kp;
#ifdef HAVE_V4D
  /* a constant term count specialises the blocks; the last block ends at k,
   * overlapping the one before (its points come out the same again), so
   * no counts need padding */
#define RESIDUAL_BLOCKS(M)                                                                         \
  if (k < 8)                                                                                       \
    residual_block(M, 1, k, kp, lf->phit, lf->z, 0, B, coef, valid, counts, all, out, cnt);        \
  else                                                                                             \
    for (int j0 = 0; j0 < k; j0 += 8)                                                              \
    residual_block(M, 0, k, kp, lf->phit, lf->z, j0 + 8 > k ? k - 8 : j0, B, coef, valid, counts,  \
                   all, out, cnt)
  switch (m) {
  case 3: RESIDUAL_BLOCKS(3); break;
  case 6: RESIDUAL_BLOCKS(6); break;
  case 10: RESIDUAL_BLOCKS(10); break;
  default: RESIDUAL_BLOCKS(m); break;
  }
#undef RESIDUAL_BLOCKS
#else
  for (int j = 0; j < k; j++)
    all[j] = out[j] = cnt[j] = 0;
  for (int b = 0; b < B; b++) {
    if (valid && !valid[b]) continue;
    const double *cb = &coef[(size_t)b * m];
    for (int j = 0; j < k; j++) {
      double p = 0;
      for (int a = 0; a < m; a++)
        p += cb[a] * lf->phit[(size_t)a * kp + j];
      const double e = fabs(p - lf->z[j]), w = counts[(size_t)b * k + j] == 0 ? 1.0 : 0.0;
      all[j] += e;
      out[j] += w * e;
      cnt[j] += w;
    }
  }
#endif
}

/* The gradient (f_u, f_v) of the fit `coef` at the point whose basis
 * gradient is (du, dv), or at the frame's origin (the point d_i itself,
 * du NULL): there the linear terms (the general sum adds only zeros to
 * them); then (-f_u / s, -f_v / s, 1) normalised (Eq. 5.9). */
static inline __attribute__((always_inline)) void normal_local(double scale, int m,
                                                               const double *coef, const double *du,
                                                               const double *dv, double l[3]) {
  double fu = 0, fv = 0;
  if (!du) {
    fu = 0 + coef[1];
    fv = 0 + coef[2];
  } else {
    for (int a = 0; a < m; a++) {
      fu += coef[a] * du[a];
      fv += coef[a] * dv[a];
    }
  }
  /* r = (x, y, f(x, y)): r_x x r_y = (-f_x, -f_y, 1) (Eq. 5.9) */
  l[0] = -fu / scale, l[1] = -fv / scale, l[2] = 1.0;
  double len = sqrt(l[0] * l[0] + l[1] * l[1] + 1.0);
  for (int t = 0; t < 3; t++)
    l[t] /= len;
}

void bsurf_localfit_normal_local(const bsurf_localfit *lf, int degree, const double *coef, double u,
                                 double v, double l[3]) {
  double du[BSURF_TERMS_MAX], dv[BSURF_TERMS_MAX];
  const int origin = u == 0 && v == 0 && degree >= 1;
  if (!origin) bsurf_poly_basis_grad(degree, u, v, du, dv);
  normal_local(lf->scale, bsurf_poly_terms(degree), coef, origin ? NULL : du, origin ? NULL : dv,
               l);
}

#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-trapping-math")))
#endif
BSURF_CLONES void
bsurf_localfit_normals_local(const bsurf_localfit *lf, int degree, int n, const double *coefs,
                             double u, double v, double *out) {
  double du[BSURF_TERMS_MAX], dv[BSURF_TERMS_MAX];
  const int m = bsurf_poly_terms(degree);
  const double scale = lf->scale;
  if (u == 0 && v == 0 && degree >= 1) {
    for (int b = 0; b < n; b++) /* the loop in vector lanes */
      normal_local(scale, m, &coefs[(size_t)b * m], NULL, NULL, &out[3 * (size_t)b]);
  } else {
    bsurf_poly_basis_grad(degree, u, v, du, dv);
    for (int b = 0; b < n; b++)
      normal_local(scale, m, &coefs[(size_t)b * m], du, dv, &out[3 * (size_t)b]);
  }
}

void bsurf_localfit_normal(const bsurf_localfit *lf, const bsurf_frame *frame, int degree,
                           const double *coef, double u, double v, double n[3]) {
  double l[3];
  bsurf_localfit_normal_local(lf, degree, coef, u, v, l);
  bsurf_frame_dir_to_global(frame, l, n);
}

double bsurf_localfit_eval(const bsurf_localfit *lf, int degree, const double *coef, double x,
                           double y) {
  double phi[BSURF_TERMS_MAX];
  bsurf_poly_basis(degree, x / lf->scale, y / lf->scale, phi);
  double s = 0;
  for (int a = 0; a < bsurf_poly_terms(degree); a++)
    s += phi[a] * coef[a];
  return s;
}
