/* Local analysis (thesis 3.3): PCA, frames, polynomial height functions and
 * the small least-squares solver they need. Internal to the library. */
#ifndef BSURF_LOCAL_H
#define BSURF_LOCAL_H

#include "bootsurf.h"

#define BSURF_DEGREE_MAX 4
#define BSURF_TERMS_MAX 15 /* bsurf_poly_terms(BSURF_DEGREE_MAX) */
#define BSURF_PACKED_MAX (BSURF_TERMS_MAX * (BSURF_TERMS_MAX + 1) / 2)
#define BSURF_MOMENTS_MAX 45 /* bsurf_poly_terms(2 * BSURF_DEGREE_MAX) */
#define BSURF_NCOLS_MAX 64   /* BSURF_MOMENTS_MAX + BSURF_TERMS_MAX, padded to 8 */

/* Eigen-decomposition of a symmetric n x n matrix (n <= BSURF_EIGEN_MAX, a
 * row-major, not modified) by cyclic Jacobi rotations: evals ascending,
 * evecs[i n .. i n + n - 1] the unit eigenvector of evals[i]. */
#define BSURF_EIGEN_MAX 8
void bsurf_eigen_sym(int n, const double *a, double *evals, double *evecs);
/* The same for n = 3 (the same bits). */
void bsurf_eigen_sym3(double a[3][3], double evals[3], double evecs[3][3]);
/* The PCA normal of the packed symmetric matrix c = (xx, xy, xz, yy, yz, zz)
 * by the Jacobi sweeps: the unit eigenvector of the smallest eigenvalue;
 * returns 0, or -1 when lambda2 <= 0 or lambda1 <= 1e-12 lambda2. */
int bsurf_eigen_sym3_normal(const double c[6], double n[3]);
/* The unit eigenvector of the smallest eigenvalue (the PCA normal) of the
 * symmetric matrix c = (xx, xy, xz, yy, yz, zz): Newton on the characteristic
 * polynomial and a cross product (eigen.c), several times faster than the
 * sweeps, which it falls back on when the two smallest eigenvalues nearly
 * coincide. Returns 0, or -1 when the matrix is degenerate for PCA
 * (lambda2 <= 0 or lambda1 <= 1e-12 lambda2). The sign of n is arbitrary. */
int bsurf_eigen_sym3_smallest(const double c[6], double n[3]);
/* The same for R matrices in vector lanes, column-major: c[t R + r] is entry
 * t of matrix r, n[t R + r] component t of its normal, status[r] its return
 * value; every lane gets exactly the scalar function's result. */
void bsurf_eigen_sym3_smallest_lanes(int R, const double *c, double *n, int *status);

/* p' = rot (p - origin) (Eq. 3.4 rows X', Y', n; see frame.c on Eq. 3.5). */
void bsurf_frame_to_local(const bsurf_frame *f, const double p[3], double out[3]);
/* p = rot^T p' + origin: the inverse rotation (Eq. 3.6). */
void bsurf_frame_to_global(const bsurf_frame *f, const double local[3], double out[3]);
/* A direction (no translation) from local to global coordinates. */
void bsurf_frame_dir_to_global(const bsurf_frame *f, const double local[3], double out[3]);

/* Monomials of total degree <= degree (at most 2 * BSURF_DEGREE_MAX) in
 * graded order 1, u, v, u^2, uv, v^2, u^3, u^2 v, u v^2, v^3, ...
 * so the basis of a lower degree is a prefix of the basis of a higher one. */
static inline void bsurf_poly_basis(int degree, double u, double v, double *phi) {
  /* degree d: u^d, u^(d-1) v, ..., v^d from the previous degree's block
   * (at phi + p), in place; inline, so that a constant degree unrolls (a
   * copy through arrays and a call per point were a third of the MSE
   * rule's quadric sums; the same products, the same bits) */
  phi[0] = 1.0;
  for (int d = 1, p = 0; d <= degree; p += d, d++) {
    double *cur = phi + p + d;
    for (int j = 0; j < d; j++)
      cur[j] = phi[p + j] * u;
    cur[d] = phi[p + d - 1] * v;
  }
}

/* Partial derivatives of the basis: du[a] = d phi_a / du, dv[a] = d phi_a / dv
 * (appendix A lists them for M = 2, 3, 4). */
void bsurf_poly_basis_grad(int degree, double u, double v, double *du, double *dv);

/* Index in column-packed upper-triangular storage: (i, j), i <= j. */
static inline int bsurf_packed_index(int i, int j) {
  return j * (j + 1) / 2 + i;
}

/* Solves G c = r for a symmetric positive definite m x m system by LDL^T
 * (G in column-packed upper storage; its leading m(m+1)/2 entries are used).
 * A pivot that falls below rel_tol times its original diagonal entry means
 * the columns of the design are (numerically) dependent: returns -1 and
 * leaves c undefined; 0 on success. */
int bsurf_ldl_solve_packed(int m, const double *G, const double *r, double rel_tol, double *c);

/* The same in two steps, for several right-hand sides of one G: the
 * factors (0, or -1 as above), then a solve (the bits of
 * bsurf_ldl_solve_packed's). */
typedef struct bsurf_ldl {
  int m;
  double L[BSURF_TERMS_MAX * BSURF_TERMS_MAX], inv[BSURF_TERMS_MAX];
} bsurf_ldl;
int bsurf_ldl_factor_packed(int m, const double *G, double rel_tol, bsurf_ldl *f);
void bsurf_ldl_solve_factored(const bsurf_ldl *f, const double *r, double *c);

/* Default relative pivot tolerance for rank detection. */
#define BSURF_RANK_TOL 1e-10

/* A neighbourhood prepared for (weighted) polynomial height fits: local
 * coordinates scaled to the unit disc, the basis at every point and the
 * per-point monomials u^i v^j of degree <= 2M (every entry phi_a phi_b of
 * phi phi^T is one of them: 28 numbers for a cubic instead of 55) and phi z,
 * so that the normal equations of any integer-weighted (bootstrap) fit are
 * sums of precomputed terms (thesis 4.1.2: a fit on each resample S_b). */
typedef struct bsurf_localfit {
  int kmax, degree_max;
  int k, degree, m, p; /* current neighbourhood size, degree, terms, moments
                          of degree <= 2 * degree */
  int ncols;           /* p + m padded to a multiple of 8: the width of a row
                          of `op` (the padding is zero) */
  double scale;        /* local coordinates are divided by this */
  double *u, *v, *z;   /* k: scaled x', y' and unscaled height z' */
  int kp;              /* k rounded up to a multiple of 8: the row stride of phit */
  double *phit;        /* m x kp: basis, transposed (term-major), zero beyond k */
  double *op;          /* k x ncols: the moments' monomials, then phi z */
} bsurf_localfit;

bsurf_status bsurf_localfit_alloc(bsurf_localfit *lf, int kmax, int degree_max);
void bsurf_localfit_free(bsurf_localfit *lf);

/* Localises the k points xyz[idx[j]] in `frame` and prepares fits of degree
 * <= `degree`. */
void bsurf_localfit_setup(bsurf_localfit *lf, const double *xyz, const uint32_t *idx, int k,
                          const bsurf_frame *frame, int degree);

/* out = W (R x k) * A (k x nc) with R a multiple of 4 and nc of 8, stored
 * in groups of four rows interleaved by column: entry (r, c) at
 * out[(r / 4) * 4 nc + 4 c + r % 4], the layout of four LDL^T solves
 * in vector lanes. Each entry is summed in the order j = 0..k-1, a multiply
 * then an add (the bits of the plain row-major product on every code path). */
void bsurf_gemm_lanes(int R, int k, int nc, const double *W, const double *A, double *out);
/* The same product for integer weights given as draws: row b < B of out
 * (bsurf_boot_rows(B) rows, the lanes layout above) is the sum of the rows
 * A[draws[b k + t]], t = 0..k-1 in that order (so the count of j times
 * A[j], up to rounding); row B the sum of all k rows in order j = 0..k-1
 * (the bits of bsurf_gemm_lanes with weights 1); the rest zero. Needs
 * nc <= BSURF_NCOLS_MAX, a multiple of 8. */
void bsurf_draw_sums_lanes(int B, int k, int nc, const uint16_t *draws, const double *A,
                           double *out);
/* Row r of a bsurf_gemm_lanes result, contiguous (nc entries). */
void bsurf_lanes_row(int nc, const double *lanes, int r, double *row);

/* Normal equations of R weighted fits at once (an R x k by k x ncols matrix
 * product, R a multiple of 4): row b (in the layout of bsurf_gemm_lanes,
 * R x lf->ncols) receives the moments of G followed by r for the weights W[b]
 * (W: R x k, row-major). The sum over the points runs in index order, so a
 * row equals what a point-by-point sum gives. */
void bsurf_localfit_normal_eq_lanes(const bsurf_localfit *lf, int R, const double *W,
                                    double *lanes);

/* The normal equations of B resamples given by their draws
 * (bsurf_boot_draw_rows) and of the whole neighbourhood (row B), as
 * bsurf_localfit_normal_eq_lanes gives them for the weight rows up to the
 * order of the sums (bsurf_draw_sums_lanes): bsurf_boot_rows(B) rows. */
void bsurf_localfit_normal_eq_draws(const bsurf_localfit *lf, int B, const uint16_t *draws,
                                    double *lanes);

/* Solves one row (bsurf_lanes_row) of bsurf_localfit_normal_eq_lanes for a fit of degree `degree`
 * (<= the setup degree; the lower degree's system is a leading block).
 * Returns 0, or -1 when the system is rank-deficient. */
int bsurf_localfit_solve_row(const bsurf_localfit *lf, int degree, const double *row, double *coef);

/* bsurf_localfit_solve_row for a fit of degree >= 1, and the gradient
 * block of G^-1 (the rows and columns of the coefficients of u and v:
 * (0, 0), (0, 1), (1, 1) in ginv_g), so that s2 times it is the covariance
 * of the fitted gradient at the origin (in scaled units) under noise of
 * variance s2 (the MSE rule of the polynomial fit, kselect_poly.c). */
int bsurf_localfit_solve_row_grad(const bsurf_localfit *lf, int degree, const double *row,
                                  double *coef, double ginv_g[3]);

/* Solves every row b < B of bsurf_localfit_normal_eq_lanes with valid[b]
 * != 0 (coefs out: B x terms(degree)); a rank-deficient row gets valid[b]
 * = 0. Same results as bsurf_localfit_solve_row row by row, four at once in
 * vector lanes. */
void bsurf_localfit_solve_lanes(const bsurf_localfit *lf, int degree, int B, const double *lanes,
                                unsigned char *valid, double *coefs);

/* Least-squares fit of degree `degree` (<= the setup degree) with integer
 * weights `counts` (k; NULL = every point once). coef out: terms(degree).
 * Returns 0, or -1 when the system is rank-deficient. */
int bsurf_localfit_solve(const bsurf_localfit *lf, int degree, const uint16_t *counts,
                         double *coef);

/* Predicted heights at the k neighbourhood points of B fits (coef: B x
 * terms(degree)), skipping rows whose valid[b] is 0 (valid may be NULL).
 * pred out: B x k. */
void bsurf_localfit_predict(const bsurf_localfit *lf, int degree, int B, const double *coef,
                            const unsigned char *valid, double *pred);

/* For B fits (coef: B x terms(degree); rows with valid[b] = 0 skipped, valid
 * may be NULL), the absolute residuals e_bj = |f_b(x_j) - z_j| at the k
 * neighbourhood points, summed over b in increasing order: all[j] = sum_b
 * e_bj, out[j] = sum_b w_bj e_bj and cnt[j] = sum_b w_bj, with w_bj = 1 where
 * counts[b k + j] = 0 and 0 elsewhere (counts: B x k, the replicates'
 * multiplicities: w is the bootstrap's b in C_j, the `missing` rows of
 * bsurf_boot_weight_rows, formed in registers instead of read). The
 * predictions are those of bsurf_localfit_predict and the sums those of
 * bsurf_boot_estimate (same bits), without storing the B x k predictions. */
void bsurf_localfit_residual_sums(const bsurf_localfit *lf, int degree, int B, const double *coef,
                                  const unsigned char *valid, const uint16_t *counts, double *all,
                                  double *out, double *cnt);

/* The unit normal (global coordinates, Eq. 5.9 rotated back by Eq. 3.6) of
 * the fitted height function at the neighbourhood point with scaled local
 * coordinates (u, v): (-f_x, -f_y, 1) / |.|, f_x = (df/du) / scale. */
void bsurf_localfit_normal(const bsurf_localfit *lf, const bsurf_frame *frame, int degree,
                           const double *coef, double u, double v, double n[3]);
/* The same unit normal in the frame's coordinates (before the rotation). */
void bsurf_localfit_normal_local(const bsurf_localfit *lf, int degree, const double *coef, double u,
                                 double v, double l[3]);
/* bsurf_localfit_normal_local of n fits at one point (coefs: n rows of
 * bsurf_poly_terms(degree)), out[3 b ..]: the same bits, in vector lanes. */
void bsurf_localfit_normals_local(const bsurf_localfit *lf, int degree, int n, const double *coefs,
                                  double u, double v, double *out);

/* The fit's height at a point given in unscaled local coordinates. */
double bsurf_localfit_eval(const bsurf_localfit *lf, int degree, const double *coef, double x,
                           double y);

#endif
