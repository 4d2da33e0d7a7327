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

void bsurf_poly_basis(int degree, double u, double v, double *phi) {
  int t = 0;
  phi[t++] = 1.0;
  /* degree up to 2 * BSURF_DEGREE_MAX: the moments of localfit */
  double prev[2 * BSURF_DEGREE_MAX + 1] = {1.0}; /* monomials of degree d-1 */
  for (int d = 1; d <= degree; d++) {
    /* degree d: u^d, u^(d-1) v, ..., v^d from the previous degree */
    double cur[2 * BSURF_DEGREE_MAX + 1];
    for (int j = 0; j < d; j++) cur[j] = prev[j] * u;
    cur[d] = prev[d - 1] * v;
    for (int j = 0; j <= d; j++) {
      phi[t++] = cur[j];
      prev[j] = cur[j];
    }
  }
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

int bsurf_chol_solve_packed(int m, const double *G, const double *r, double rel_tol,
                            double *c) {
  /* G = L L^T, L lower triangular stored row-major in a full m x m array;
   * inv[j] = 1 / L[j][j], so each column costs one division. */
  double L[BSURF_TERMS_MAX * BSURF_TERMS_MAX], inv[BSURF_TERMS_MAX];
  for (int j = 0; j < m; j++) {
    const double gjj = G[bsurf_packed_index(j, j)];
    double s = gjj;
    for (int t = 0; t < j; t++) s -= L[j * m + t] * L[j * m + t];
    if (!(s > rel_tol * gjj) || !(gjj > 0)) return -1; /* also catches NaN */
    inv[j] = 1.0 / sqrt(s);
    for (int i = j + 1; i < m; i++) {
      double a = G[bsurf_packed_index(j, i)];
      for (int t = 0; t < j; t++) a -= L[i * m + t] * L[j * m + t];
      L[i * m + j] = a * inv[j];
    }
  }
  double y[BSURF_TERMS_MAX];
  for (int i = 0; i < m; i++) { /* L y = r */
    double a = r[i];
    for (int t = 0; t < i; t++) a -= L[i * m + t] * y[t];
    y[i] = a * inv[i];
  }
  for (int i = m - 1; i >= 0; i--) { /* L^T c = y */
    double a = y[i];
    for (int t = i + 1; t < m; t++) a -= L[t * m + i] * c[t];
    c[i] = a * inv[i];
  }
  return 0;
}

bsurf_status bsurf_localfit_alloc(bsurf_localfit *lf, int kmax, int degree_max) {
  memset(lf, 0, sizeof *lf);
  if (kmax < 1 || degree_max < 0 || degree_max > BSURF_DEGREE_MAX)
    return BSURF_ERR_INVALID_ARG;
  int m = bsurf_poly_terms(degree_max), ncols = (bsurf_poly_terms(2 * degree_max) + m + 7) / 8 * 8;
  lf->kmax = kmax;
  lf->degree_max = degree_max;
  lf->u = bsurf_alloc_array((size_t)kmax, 3 * sizeof(double));
  lf->phit = bsurf_alloc_array((size_t)kmax * m, sizeof(double));
  lf->op = bsurf_alloc_array((size_t)kmax * ncols, sizeof(double));
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

void bsurf_localfit_setup(bsurf_localfit *lf, const double *xyz, const uint32_t *idx,
                          int k, const bsurf_frame *frame, int degree) {
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
  const int m = lf->m, p = lf->p, nc = lf->ncols;
  for (int j = 0; j < k; j++) {
    lf->u[j] *= inv;
    lf->v[j] *= inv;
    /* the monomials of degree <= 2M in graded order: every product
     * phi_a phi_b is one of them (moment_index), and the basis of degree M
     * is their prefix */
    double *o = &lf->op[(size_t)j * nc];
    bsurf_poly_basis(2 * degree, lf->u[j], lf->v[j], o);
    for (int a = 0; a < m; a++) lf->phit[(size_t)a * k + j] = o[a];
    for (int a = 0; a < m; a++) o[p + a] = o[a] * lf->z[j];
    for (int c = p + m; c < nc; c++) o[c] = 0.0;
  }
}

/* Position of the monomial phi_a phi_b among the graded monomials, for
 * every packed (a, b), a <= b < BSURF_TERMS_MAX: phi_a of total degree d_a
 * has v-power j_a = a - d_a(d_a+1)/2, and u^i v^j of degree d = i + j sits at
 * d(d+1)/2 + j, so phi_a phi_b is at d(d+1)/2 + j_a + j_b with d = d_a + d_b.
 * (Generated from that formula; a wrong entry breaks test_local's exact
 * recovery of polynomials.) */
static const unsigned char packed_moment[BSURF_PACKED_MAX] = {
    0, 1, 3, 2, 4, 5, 3, 6, 7, 10, 4, 7, 8, 11, 12, 5, 8, 9, 12, 13,
    14, 6, 10, 11, 15, 16, 17, 21, 7, 11, 12, 16, 17, 18, 22, 23, 8, 12, 13, 17,
    18, 19, 23, 24, 25, 9, 13, 14, 18, 19, 20, 24, 25, 26, 27, 10, 15, 16, 21, 22,
    23, 28, 29, 30, 31, 36, 11, 16, 17, 22, 23, 24, 29, 30, 31, 32, 37, 38, 12, 17,
    18, 23, 24, 25, 30, 31, 32, 33, 38, 39, 40, 13, 18, 19, 24, 25, 26, 31, 32, 33,
    34, 39, 40, 41, 42, 14, 19, 20, 25, 26, 27, 32, 33, 34, 35, 40, 41, 42, 43, 44,
};

static const unsigned char *moment_map(void) { return packed_moment; }

/* The packed G (m x m) of one row of moments. */
static void gram_from_moments(int m, const double *row, double *G) {
  const unsigned char *map = moment_map();
  const int pm = m * (m + 1) / 2;
  for (int q = 0; q < pm; q++) G[q] = row[map[q]];
}

/* rows (B x nc) = W (B x k) * A (k x nc). Blocks of 4 rows by 8 columns are
 * accumulated in registers (GCC/Clang vector types: AVX2 in the x86-64-v3
 * clone, SSE2 pairs otherwise, scalar elsewhere); for each output entry the
 * terms are added in the order j = 0, 1, ..., k-1 with a separate multiply
 * and add, exactly as the plain loop below, so every path gives the same
 * bits. */
#if defined(__GNUC__)
typedef double v4d __attribute__((vector_size(32)));
#define HAVE_V4D 1
#endif

static void gemm_plain(int b0, int b1, int c0, int c1, int k, int nc, const double *W,
                       const double *A, double *out) {
  for (int b = b0; b < b1; b++) {
    double *o = &out[(size_t)b * nc];
    for (int c = c0; c < c1; c++) o[c] = 0;
    for (int j = 0; j < k; j++) {
      const double x = W[(size_t)b * k + j];
      const double *a = &A[(size_t)j * nc];
      for (int c = c0; c < c1; c++) o[c] += x * a[c];
    }
  }
}

BSURF_CLONES
void bsurf_gemm_rows(int B, int k, int nc, const double *restrict W, const double *restrict A,
                     double *restrict out) {
#ifdef HAVE_V4D
  const int nc8 = nc - nc % 8, B4 = B - B % 4;
  for (int b = 0; b < B4; b += 4) {
    const double *w0 = &W[(size_t)b * k], *w1 = w0 + k, *w2 = w1 + k, *w3 = w2 + k;
    for (int c = 0; c < nc8; c += 8) {
      v4d a00 = {0, 0, 0, 0}, a01 = a00, a10 = a00, a11 = a00, a20 = a00, a21 = a00, a30 = a00,
          a31 = a00;
      for (int j = 0; j < k; j++) {
        v4d x0, x1;
        memcpy(&x0, &A[(size_t)j * nc + c], sizeof x0);
        memcpy(&x1, &A[(size_t)j * nc + c + 4], sizeof x1);
        const v4d s0 = {w0[j], w0[j], w0[j], w0[j]}, s1 = {w1[j], w1[j], w1[j], w1[j]};
        const v4d s2 = {w2[j], w2[j], w2[j], w2[j]}, s3 = {w3[j], w3[j], w3[j], w3[j]};
        a00 += s0 * x0;
        a01 += s0 * x1;
        a10 += s1 * x0;
        a11 += s1 * x1;
        a20 += s2 * x0;
        a21 += s2 * x1;
        a30 += s3 * x0;
        a31 += s3 * x1;
      }
      double *o = &out[(size_t)b * nc + c];
      memcpy(o, &a00, 32);
      memcpy(o + 4, &a01, 32);
      memcpy(o + nc, &a10, 32);
      memcpy(o + nc + 4, &a11, 32);
      memcpy(o + 2 * nc, &a20, 32);
      memcpy(o + 2 * nc + 4, &a21, 32);
      memcpy(o + 3 * nc, &a30, 32);
      memcpy(o + 3 * nc + 4, &a31, 32);
    }
    if (nc8 < nc) gemm_plain(b, b + 4, nc8, nc, k, nc, W, A, out);
  }
  if (B4 < B) gemm_plain(B4, B, 0, nc, k, nc, W, A, out);
#else
  gemm_plain(0, B, 0, nc, k, nc, W, A, out);
#endif
}

#ifdef HAVE_V4D
typedef long long v4l __attribute__((vector_size(32)));

/* Four Cholesky solves at once, one per vector lane, with exactly the
 * operations of bsurf_chol_solve_packed in each lane (so the same bits).
 * A lane whose pivot fails is given pivot 1 to keep the others going and is
 * reported in the returned bit mask of failures. */
BSURF_CLONES
static int chol_solve4(int m, int p, const double *const rows[4], double rel_tol,
                       double *const coef[4]) {
  v4d G[BSURF_PACKED_MAX], r[BSURF_TERMS_MAX], L[BSURF_TERMS_MAX * BSURF_TERMS_MAX];
  v4d inv[BSURF_TERMS_MAX], y[BSURF_TERMS_MAX], c[BSURF_TERMS_MAX];
  const int pm = m * (m + 1) / 2;
  const unsigned char *map = moment_map();
  for (int q = 0; q < pm; q++)
    G[q] = (v4d){rows[0][map[q]], rows[1][map[q]], rows[2][map[q]], rows[3][map[q]]};
  for (int i = 0; i < m; i++)
    r[i] = (v4d){rows[0][p + i], rows[1][p + i], rows[2][p + i], rows[3][p + i]};
  const v4d one = {1, 1, 1, 1}, zero = {0, 0, 0, 0};
  const v4d tol = {rel_tol, rel_tol, rel_tol, rel_tol};
  v4l failed = {0, 0, 0, 0};
  for (int j = 0; j < m; j++) {
    const v4d gjj = G[bsurf_packed_index(j, j)];
    v4d s = gjj;
    for (int t = 0; t < j; t++) s -= L[j * m + t] * L[j * m + t];
    v4l ok = (s > tol * gjj) & (gjj > zero);
    failed |= ~ok;
    s = (v4d)(((v4l)s & ok) | ((v4l)one & ~ok));
    v4d root;
    for (int l = 0; l < 4; l++) root[l] = sqrt(s[l]);
    inv[j] = one / root;
    for (int i = j + 1; i < m; i++) {
      v4d a = G[bsurf_packed_index(j, i)];
      for (int t = 0; t < j; t++) a -= L[i * m + t] * L[j * m + t];
      L[i * m + j] = a * inv[j];
    }
  }
  for (int i = 0; i < m; i++) {
    v4d a = r[i];
    for (int t = 0; t < i; t++) a -= L[i * m + t] * y[t];
    y[i] = a * inv[i];
  }
  for (int i = m - 1; i >= 0; i--) {
    v4d a = y[i];
    for (int t = i + 1; t < m; t++) a -= L[t * m + i] * c[t];
    c[i] = a * inv[i];
  }
  int mask = 0;
  for (int l = 0; l < 4; l++) {
    if (failed[l]) mask |= 1 << l;
    else
      for (int i = 0; i < m; i++) coef[l][i] = c[i][l];
  }
  return mask;
}
#endif

void bsurf_localfit_solve_rows(const bsurf_localfit *lf, int degree, int B, const double *rows,
                               unsigned char *valid, double *coefs) {
  const int m = bsurf_poly_terms(degree), nc = lf->ncols;
  int b = 0;
#ifdef HAVE_V4D
  int lane_b[4], nl = 0;
  for (; b < B; b++) {
    if (!valid[b]) continue;
    lane_b[nl++] = b;
    if (nl < 4) continue;
    const double *rp[4];
    double *cp[4];
    for (int l = 0; l < 4; l++) {
      rp[l] = &rows[(size_t)lane_b[l] * nc];
      cp[l] = &coefs[(size_t)lane_b[l] * m];
    }
    int failed = chol_solve4(m, lf->p, rp, BSURF_RANK_TOL, cp);
    for (int l = 0; l < 4; l++)
      if (failed & (1 << l)) valid[lane_b[l]] = 0;
    nl = 0;
  }
  for (int l = 0; l < nl; l++) { /* the last 1-3 in the scalar solver */
    int bb = lane_b[l];
    if (bsurf_localfit_solve_row(lf, degree, &rows[(size_t)bb * nc], &coefs[(size_t)bb * m]) != 0)
      valid[bb] = 0;
  }
#else
  for (; b < B; b++)
    if (valid[b] && bsurf_localfit_solve_row(lf, degree, &rows[(size_t)b * nc], &coefs[(size_t)b * m]) != 0)
      valid[b] = 0;
#endif
}

void bsurf_localfit_normal_eq(const bsurf_localfit *lf, int B, const double *W, double *rows) {
  bsurf_gemm_rows(B, lf->k, lf->ncols, W, lf->op, rows);
}

int bsurf_localfit_solve_row(const bsurf_localfit *lf, int degree, const double *row,
                             double *coef) {
  /* G from the moments (a lower degree uses a subset of them); the
   * right-hand side of a lower degree is a prefix of r, which starts at
   * column p */
  const int m = bsurf_poly_terms(degree);
  double G[BSURF_PACKED_MAX];
  gram_from_moments(m, row, G);
  return bsurf_chol_solve_packed(m, G, row + lf->p, BSURF_RANK_TOL, coef);
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
    for (int a = 0; a < nc; a++) row[a] += w * o[a];
  }
  if (distinct < m) return -1; /* fewer distinct points than coefficients */
  return bsurf_localfit_solve_row(lf, degree, row, coef);
}

BSURF_CLONES
void bsurf_localfit_predict(const bsurf_localfit *lf, int degree, int B, const double *coef,
                            const unsigned char *valid, double *pred) {
  /* pred[b][j] = sum_a coef[b][a] phi_a(x_j), summed over a in order;
   * vectorised across j. */
  const int m = bsurf_poly_terms(degree), k = lf->k;
  for (int b = 0; b < B; b++) {
    if (valid && !valid[b]) continue;
    double *restrict pb = &pred[(size_t)b * k];
    const double *cb = &coef[(size_t)b * m];
    for (int j = 0; j < k; j++) pb[j] = 0;
    for (int a = 0; a < m; a++) {
      const double ca = cb[a];
      const double *restrict ph = &lf->phit[(size_t)a * k];
      for (int j = 0; j < k; j++) pb[j] += ca * ph[j];
    }
  }
}

void bsurf_localfit_normal(const bsurf_localfit *lf, const bsurf_frame *frame, int degree,
                           const double *coef, double u, double v, double n[3]) {
  double du[BSURF_TERMS_MAX], dv[BSURF_TERMS_MAX];
  bsurf_poly_basis_grad(degree, u, v, du, dv);
  double fu = 0, fv = 0;
  for (int a = 0; a < bsurf_poly_terms(degree); a++) {
    fu += coef[a] * du[a];
    fv += coef[a] * dv[a];
  }
  /* r = (x, y, f(x, y)): r_x x r_y = (-f_x, -f_y, 1) (Eq. 5.9) */
  double l[3] = {-fu / lf->scale, -fv / lf->scale, 1.0};
  double len = sqrt(l[0] * l[0] + l[1] * l[1] + 1.0);
  for (int t = 0; t < 3; t++) l[t] /= len;
  bsurf_frame_dir_to_global(frame, l, n);
}

double bsurf_localfit_eval(const bsurf_localfit *lf, int degree, const double *coef,
                           double x, double y) {
  double phi[BSURF_TERMS_MAX];
  bsurf_poly_basis(degree, x / lf->scale, y / lf->scale, phi);
  double s = 0;
  for (int a = 0; a < bsurf_poly_terms(degree); a++) s += phi[a] * coef[a];
  return s;
}
