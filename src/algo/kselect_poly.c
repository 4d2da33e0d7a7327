/* Per-point K and degree by the estimated mean squared error of the
 * polynomial fit's normal (docs/normals.md, "Choosing K and the degree";
 * issues 24 and 25): pass 3 of bsurf_select_k when opts->nd >= 1. The
 * noise passes, the curve test, the tie band and the neighbours'
 * tie-break are the PCA rule's (kselect.c, kselect_noise.c).
 *
 * The fit (thesis 3.3, Eqs. 3.5-3.9; the normal of Eq. 5.9): heights z_j
 * of the K nearest neighbours over a frame with the point at its origin,
 * least squares on the graded basis phi of degree d, z ~ phi^T c; the
 * normal at the point is (-g, 1) / |(-g, 1)|, g = (c_u, c_v) the fitted
 * gradient at the origin. Here every candidate (K, d) is fitted in one
 * frame, the PCA frame of the largest candidate's K_max neighbours, so
 * that all candidates are comparable and their normal equations are
 * running sums over the sorted neighbours: the per-neighbour monomials of
 * src/local (bsurf_localfit_setup, degree <= 2 d_max) summed once along
 * the list, the sums copied at each candidate K, each degree's system a
 * leading block of them. A point costs one K_max pass of monomials and a
 * small LDL^T solve per candidate; no bootstrap (the caller runs the B
 * replicates at the chosen (K, d) only).
 *
 *  - Variance. With heights z = X beta + e, Cov(e) = s2 I (s2 the rule's
 *    pooled noise), the least-squares coefficients have Cov(c^) = s2
 *    (X^T X)^-1 (Gauss-Markov), so the gradient has Sigma_g = s2 [(X^T
 *    X)^-1]_gg (the 2 x 2 block of the linear terms; scaled coordinates
 *    divided by the frame's scale). To first order the normal turns by
 *    dg^T M dg, M = (I - g g^T / L^2) / L^2, L^2 = 1 + |g|^2; the true
 *    slope at the point is small in the K_max frame, and M at a noisy g^
 *    understates the variance of near-interpolating fits (K = 10, degree
 *    3: a nearly vertical slope, M -> 0), so M = I:
 *        V(K, d) = tr(Sigma_g).
 *  - Bias of the degree (Q). Where the surface has terms beyond degree d
 *    (X_2 beta_2), the degree-d fit has E c^_d = beta_d + A beta_2 with
 *    the alias matrix A = (X_d^T X_d)^-1 X_d^T X_2 (Box & Draper 1987,
 *    ch. 3; Montgomery, Design and Analysis of Experiments, "alias
 *    matrix"). By the omitted-variable identity the degree-d fit and a
 *    degree-d' > d fit of the same points differ by exactly A beta^_2,
 *    so g_d - g_d' estimates the gradient's bias of degree d (that of d'
 *    taken as negligible); where both are unbiased, g_d is efficient
 *    under the smaller model, Cov(g_d, g_d' - g_d) = 0 (Hausman 1978), so
 *    Cov(g_d - g_d') = Sigma_g(d') - Sigma_g(d) and
 *        Q(K, d) = sin^2(n_d, n_d') - (V(K, d') - V(K, d))
 *    is unbiased for the squared angle bias, d' the next larger candidate
 *    degree at the same K (the largest degree: Q = 0).
 *  - Bias beyond the polynomials (D: an edge, the far side of a thin
 *    part): the drift over K at one degree, by the same identity between
 *    nested samples (the larger sample's fit is efficient), as the PCA
 *    rule's drift was before its two witnesses (kselect.c, drift_of; this
 *    rule keeps the maximum): D(K, d) = max_{K' < K} sin^2(n_K', n_K) - c
 *    (V(K') - V(K)), with c = drift_tol(1) = 3, the level e^-3 of one
 *    comparison: the drifts of one point's nested neighbourhoods are
 *    strongly correlated, so Bonferroni's ln(a) (the PCA rule's maximum's)
 *    charged too little here (docs/normals.md, "Choosing K and the degree",
 *    gives both).
 *  - The criterion is M(K, d) = V + max(Q, D, 0); the candidates within
 *    the tie band of the smallest are told apart by the neighbours' first
 *    choices (kselect.c, ksel_ties, tie_point). Candidates whose K reads
 *    as a curve (the curve test), and fits whose system is rank-deficient,
 *    are not assessed; where none is, the largest K at the smallest
 *    degree.
 *
 * Deterministic: no draws; a point's result depends on its neighbourhood
 * and the pooled noise only. */
#include "algo/kselect.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct kpoly_scratch {
  bsurf_localfit lf;
  double *rows; /* nk x ncols: each candidate K's moments and phi z sums */
  bsurf_blocks mem;
  int dmax, dlow; /* the largest degree, the index of the smallest */
} kpoly_scratch;

bsurf_status poly_alloc(ksel_scratch *s, const bsurf_kselect_options *o, int kmax) {
  kpoly_scratch *p = calloc(1, sizeof *p);
  if (!p) return BSURF_ERR_NOMEM;
  s->poly = p;
  for (int d = 0; d < o->nd; d++) {
    if (o->ds[d] > p->dmax) p->dmax = o->ds[d];
    if (o->ds[d] < o->ds[p->dlow]) p->dlow = d;
  }
  bsurf_status st = bsurf_localfit_alloc(&p->lf, kmax, p->dmax);
  if (st != BSURF_OK) return st;
  p->rows = bsurf_blocks_array(&p->mem, (size_t)o->nk, BSURF_NCOLS_MAX * sizeof(double));
  return bsurf_blocks_status(&p->mem);
}

void poly_free(ksel_scratch *s) {
  if (!s->poly) return;
  bsurf_localfit_free(&s->poly->lf);
  bsurf_blocks_free(&s->poly->mem);
  free(s->poly);
  s->poly = NULL;
}

/* The fit of degree d on the sums `row`: its normal (global, into n) and
 * V = tr(M Sigma_g) (the top of the file); INFINITY when the system is
 * rank-deficient. */
static double poly_candidate(const bsurf_localfit *lf, const bsurf_frame *f, int d,
                             const double *row, double s2, double n[3]) {
  double coef[BSURF_TERMS_MAX], gi[3];
  if (!row || bsurf_localfit_solve_row_grad(lf, d, row, coef, gi) != 0) {
    for (int t = 0; t < 3; t++) /* the frame's plane, as a degree-0 fit */
      n[t] = f->rot[2][t];
    return INFINITY;
  }
  const double inv = 1.0 / lf->scale;
  const double gu = coef[1] * inv, gv = coef[2] * inv;
  const double L2 = 1.0 + gu * gu + gv * gv, len = sqrt(L2);
  const double l[3] = {-gu / len, -gv / len, 1.0 / len};
  bsurf_frame_dir_to_global(f, l, n);
  /* Sigma_g = s2 G^-1_gg / scale^2, tr(Sigma_g) (the top of the file) */
  return s2 * (gi[0] + gi[2]) * inv * inv;
}

void poly_point(void *vctx, int thread, size_t i) {
  ksel_ctx *c = vctx;
  ksel_scratch *s = &c->scr[thread];
  kpoly_scratch *p = s->poly;
  const bsurf_kselect_options *o = c->o;
  const int nk = o->nk, nd = o->nd, ncand = nk * nd, kmax = o->ks[nk - 1];
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  const double s2 = c->noise[i];
  bsurf_frame f;
  bsurf_local_frame(c->xyz, idx, kmax, BSURF_PCA_CENTROID, &f);
  bsurf_localfit *lf = &p->lf;
  bsurf_localfit_setup(lf, c->xyz, idx, kmax, &f, p->dmax);
  /* every candidate K's normal equations: running sums along the list */
  const int w = lf->p + lf->m;
  double acc[BSURF_NCOLS_MAX] = {0};
  for (int a = 0, j = 0; a < nk; a++) {
    for (; j < o->ks[a]; j++) {
      const double *op = &lf->op[(size_t)j * lf->ncols];
      for (int t = 0; t < w; t++)
        acc[t] += op[t];
    }
    memcpy(&p->rows[(size_t)a * BSURF_NCOLS_MAX], acc, (size_t)w * sizeof(double));
  }
  double *nrm = s->nrm, *var = s->var, *mse = s->mse;
  for (int a = 0; a < nk; a++)
    for (int e = 0; e < nd; e++)
      var[a * nd + e] = poly_candidate(
          lf, &f, o->ds[e],
          o->ks[a] < bsurf_poly_terms(o->ds[e]) ? NULL : &p->rows[(size_t)a * BSURF_NCOLS_MAX], s2,
          &nrm[3 * (a * nd + e)]);
  /* where the K_max neighbours sample a curve, the K that read fewer than
   * two dimensions are not assessed (kselect.c) */
  if (curve_sampled(c->xyz, idx, idx[0], o->ks, nk, s->curve))
    for (int a = 0; a < nk; a++)
      if (s->curve[a])
        for (int e = 0; e < nd; e++)
          var[a * nd + e] = INFINITY;
  /* M = V + max(Q, D) (the top of the file) */
  int best = -1;
  double best_mse = INFINITY;
  for (int a = 0; a < ncand; a++) {
    mse[a] = INFINITY;
    if (!isfinite(var[a])) continue;
    const int ka = a / nd, da = o->ds[a % nd];
    const double *na = &nrm[3 * a];
    /* Q: the alias of the next larger degree's extra terms, unbiased */
    int up = -1;
    for (int e = 0; e < nd; e++)
      if (o->ds[e] > da && isfinite(var[ka * nd + e]) && (up < 0 || o->ds[e] < o->ds[up % nd]))
        up = ka * nd + e;
    double b2 = up >= 0 ? ksel_sin2(na, &nrm[3 * up]) - (var[up] - var[a]) : 0;
    /* D: the drifts from the smaller K at the same degree (Lepski), each
     * at the level of one comparison (the top of the file) */
    const double tol = drift_tol(1);
    for (int r = a % nd; r < a; r += nd) {
      if (!isfinite(var[r])) continue;
      const double d = ksel_sin2(na, &nrm[3 * r]) - tol * (var[r] - var[a]);
      if (d > b2) b2 = d;
    }
    mse[a] = var[a] + (b2 > 0 ? b2 : 0);
    if (mse[a] < best_mse) /* ties keep the smaller K, then the earlier degree */
      best_mse = mse[a], best = a;
  }
  ksel_ties(c, s, i, ncand, best, best_mse, (nk - 1) * nd + p->dlow);
}
