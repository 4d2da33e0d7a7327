/* Normals with bootstrap confidence (thesis chapter 5).
 *
 * For every point d_i with neighbourhood P_i (K points, d_i first):
 *  - the normal of the whole neighbourhood n_P: PCA (5.2; second moments
 *    about the centroid, or about d_i as Eq. 2.1 writes) or the normal of a
 *    degree-M height polynomial at d_i (5.4, Eq. 5.9: (-f_x, -f_y, 1)
 *    normalised and rotated back, Eq. 3.6);
 *  - B bootstrap samples S_b (Eq. 4.2) keyed by (seed, i, b), the same
 *    normal on each, oriented to minimise the angle with n_P (5.2.1);
 *  - the estimate n(d_i) = sum n_b / |sum n_b| (Eq. 5.4, Algorithms 2);
 *  - the confidence nu_i: the variance (1/(B-1), Eq. 5.2) of the angles
 *    between n_1 and n_b (Eq. 5.5);
 *  - with reference normals n_j (from a fixed neighbourhood size), the
 *    bootstrap test error of the normal (5.5, Eq. 5.10, Algorithm 3):
 *    (1/(B K)) sum_b sum_j theta(g^b(p_j), n_j), where g^b(p_j) is the
 *    normal of the b-th fit at the neighbour p_j (for PCA the plane's
 *    normal, the same for every j) and theta the unoriented angle.
 * With B = 0 the single fit gives the normal, nu = 0, and the test error is
 * the same average with the single fit (a training error).
 *
 * The weighted second moments of all B resamples are the nested sums of
 * nested.c for one candidate K (the multiplicities as weights in vector
 * lanes, the per-neighbour terms computed once); the normal equations of
 * the polynomial fits are sums over each replicate's draws (src/local). */
#include "algo/algo.h"
#include "bootstrap/bootstrap.h"
#include "common/common.h"
#include "local/local.h"
#include "search/search.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PCA_COLS BSURF_NESTED_COLS /* q q^T (6 entries), q (3), 1, with q = p - d_i */

bsurf_normal_options bsurf_normal_options_default(void) {
  bsurf_normal_options o = {.fit = BSURF_NORMAL_PCA,
                            .pca_center = BSURF_PCA_CENTROID,
                            .k = 30,
                            .degree = 2,
                            .bootstrap = 50,
                            .seed = 1};
  return o;
}

typedef struct normal_scratch {
  bsurf_localfit lf;
  double *terms;        /* k x PCA_COLS */
  double *weights;      /* PCA: k x B, the replicates' weights in lanes */
  double *rows;         /* the same count x ncols: the polynomial fits' lanes */
  double *coefs;        /* (B + 1) x terms */
  uint16_t *counts;     /* max(4, B) x k */
  uint16_t *draws;      /* B x k: each replicate's indices in the order drawn */
  unsigned char *valid; /* B */
  double *bn;           /* B x 3 bootstrap normals */
  double *lanes;        /* (COLS + 6 + 3) x B: PCA sums, covariances, normals in lanes */
  double *ang;          /* B: angles (Eq. 5.5) */
  int *ok, *st, *nz;    /* B, B, B */
  bsurf_blocks mem;     /* the arrays above */
  size_t skipped, reduced, degenerate;
} normal_scratch;

static void scratch_free(void *vs) {
  normal_scratch *s = vs;
  bsurf_localfit_free(&s->lf);
  bsurf_blocks_free(&s->mem);
  memset(s, 0, sizeof *s);
}

typedef struct scratch_sizes {
  int k, B, degree, nk; /* K (the select scratch: the largest), B, M, candidates */
} scratch_sizes;

static bsurf_status scratch_alloc(void *vs, const void *vsz) {
  normal_scratch *s = vs;
  const scratch_sizes *z = vsz;
  const int k = z->k, B = z->B;
  memset(s, 0, sizeof *s);
  bsurf_status st = bsurf_localfit_alloc(&s->lf, k, z->degree);
  if (st != BSURF_OK) return st;
  size_t nb = (size_t)bsurf_boot_rows(B);
  bsurf_blocks *m = &s->mem;
  s->terms = bsurf_blocks_array(m, (size_t)k, PCA_COLS * sizeof(double));
  s->weights = bsurf_blocks_array(m, nb * k, sizeof(double));
  s->rows = bsurf_blocks_aligned(m, nb, BSURF_NCOLS_MAX * sizeof(double));
  s->coefs = bsurf_blocks_aligned(m, nb, BSURF_TERMS_MAX * sizeof(double));
  /* four replicates' multiplicities (PCA), or all B (a polynomial's draws) */
  s->counts = bsurf_blocks_array(m, (size_t)(B > 4 ? B : 4) * k, sizeof(uint16_t));
  s->draws = bsurf_blocks_array(m, nb * k, sizeof(uint16_t));
  s->valid = bsurf_blocks_array(m, nb, 1);
  s->bn = bsurf_blocks_array(m, nb, 3 * sizeof(double));
  s->lanes = bsurf_blocks_aligned(m, nb, (PCA_COLS + 9) * sizeof(double));
  s->ok = bsurf_blocks_array(m, nb, sizeof(int));
  s->st = bsurf_blocks_array(m, nb, sizeof(int));
  s->ang = bsurf_blocks_array(m, nb, sizeof(double));
  s->nz = bsurf_blocks_array(m, nb, sizeof(int));
  return bsurf_blocks_status(m); /* the loop frees what was made */
}

/* PCA normal from the weighted sums of one row (q q^T, q, weight). Returns 0,
 * or -1 when the points are collinear or repeated (normal undetermined).
 * The smallest eigenvector in closed form (eigen.c; the Jacobi sweeps only
 * where the gap to the middle eigenvalue is too small for it), as the
 * replicates' normals: the single fit's Jacobi sweeps were a tenth of a
 * `-B 0` run. */
static int pca_normal_from_row(const double *row, bsurf_pca_center center, double n[3]) {
  double mu[3], c[6];
  if (bsurf_nested_cov(row, 1, center, mu, c) != 0) {
    n[0] = n[1] = 0, n[2] = 1;
    return -1;
  }
  return bsurf_eigen_sym3_smallest(c, n);
}

/* the context of both loops, bsurf_estimate_normals's and
 * bsurf_select_normals_k's (ks, nk and sel) */
typedef struct normals_ctx {
  const double *xyz;
  const bsurf_neighbors *nb;
  const double *ref;
  const bsurf_normal_options *o;
  bsurf_normal_fields *out;
  bsurf_normal_report *report;
  const int *ks;
  int nk;
  bsurf_normal_select_fields *sel;
  const int *k_at; /* NULL, or each point's own K (bsurf_estimate_normals_at) */
  const int *d_at; /* NULL, or each point's own degree (bsurf_estimate_normals_at_kd) */
} normals_ctx;

/* Point i with its neighbourhood: ids, the points' indices (i first, then
 * the others by distance), their coordinates at xyz[3 idx[j]]. The estimate
 * of both passes: the stored lists' (normals_point: the cloud's xyz, idx =
 * ids) and the streamed search's (stream_row: the row's coordinates, idx =
 * 0, 1, ...). */
static void normals_point_row(const normals_ctx *c, normal_scratch *s, size_t i, const double *xyz,
                              const uint32_t *idx, const uint32_t *ids) {
  const bsurf_normal_options *o = c->o;
  const int k = c->k_at ? c->k_at[i] : o->k, B = o->bootstrap;
  const int degree0 = c->d_at ? c->d_at[i] : o->degree;

  /* the B resamples: for PCA their multiplicities as weights in lanes, for
   * a polynomial their draws */
  const int pca = o->fit == BSURF_NORMAL_PCA;
  const uint64_t key = o->point_index ? o->point_index[i] : i;
  if (pca)
    bsurf_boot_weight_lanes(o->seed, key, B, k, s->counts, s->weights);
  else
    bsurf_boot_draw_rows(o->seed, key, B, k, bsurf_poly_terms(degree0), s->counts, s->draws,
                         s->valid);

  double nP[3];
  bsurf_frame frame;
  int degree = degree0;
  if (pca) {
    /* the moment sums of P and of the replicates (nested.c, one candidate
     * K: the weighted sums in vector lanes, the replicates' distinct points
     * counted alongside), the covariances (the single fit's formula) and
     * the closed-form smallest eigenvectors in lanes (eigen.c) */
    const int ks1[1] = {k};
    double row[PCA_COLS];
    bsurf_nested_terms(xyz, idx, k, s->terms);
    bsurf_nested_sums(s->terms, k, 1, NULL, ks1, 1, row, NULL);
    if (pca_normal_from_row(row, o->pca_center, nP) != 0) s->degenerate++;
    double *blk = s->lanes, *cov = blk + (size_t)PCA_COLS * B, *nl = cov + 6 * (size_t)B;
    if (B > 0) {
      bsurf_nested_sums(s->terms, k, B, s->weights, ks1, 1, blk, s->nz);
      bsurf_nested_cov_lanes(blk, B, o->pca_center, cov, s->ok);
      bsurf_eigen_sym3_smallest_lanes(B, cov, nl, s->st);
    }
    for (int b = 0; b < B; b++) {
      s->valid[b] = s->nz[b] >= 3 && s->ok[b] && s->st[b] == 0;
      for (int t = 0; t < 3; t++)
        s->bn[3 * b + t] = nl[(size_t)t * B + b];
    }
  } else {
    bsurf_local_frame(xyz, idx, k, o->pca_center, &frame);
    if (!(frame.eigenvalues[2] > 0 && frame.eigenvalues[1] > 1e-12 * frame.eigenvalues[2]))
      s->degenerate++;
    bsurf_localfit *lf = &s->lf;
    bsurf_localfit_setup(lf, xyz, idx, k, &frame, degree0);
    /* as lanes: four solves at a time (same bits as row by row) */
    bsurf_localfit_normal_eq_draws(lf, B, s->draws, s->rows);
    double row[BSURF_NCOLS_MAX];
    bsurf_lanes_row(lf->ncols, s->rows, B, row);
    while (degree > 0 && bsurf_localfit_solve_row(lf, degree, row, s->coefs) != 0)
      degree--;
    if (degree != degree0) s->reduced++;
    if (degree == 0) {
      /* a constant height: the tangent plane itself */
      for (int t = 0; t < 3; t++)
        nP[t] = frame.rot[2][t];
    } else {
      bsurf_localfit_normal(lf, &frame, degree, s->coefs, lf->u[0], lf->v[0], nP);
    }
    const int m = bsurf_poly_terms(degree);
    /* with a reduced degree fewer distinct points suffice: let the solve
     * decide for the replicates the first check rejected */
    for (int b = 0; b < B; b++)
      s->valid[b] = (s->valid[b] || degree < degree0) && degree > 0;
    bsurf_localfit_solve_lanes(lf, degree, B, s->rows, s->valid, s->coefs + m);
    for (int b = 0; b < B; b++)
      if (s->valid[b])
        bsurf_localfit_normal(lf, &frame, degree, &s->coefs[(size_t)(b + 1) * m], lf->u[0],
                              lf->v[0], &s->bn[3 * b]);
  }

  /* orient the bootstrap normals to n_P (5.2.1), Eq. 5.4 and Eq. 5.5 */
  double nrm[3], var;
  const int nvalid = bsurf_nested_summary(B, nP, s->bn, s->valid, nrm, &var, s->ang);
  s->skipped += (size_t)(B - nvalid);
  if (c->out->normals)
    for (int t = 0; t < 3; t++)
      c->out->normals[3 * i + t] = nrm[t];
  if (c->out->normal_var) c->out->normal_var[i] = var;

  if (c->out->normal_err && c->ref) {
    double total = 0;
    long terms = 0;
    for (int b = -1; b < B; b++) {
      /* the replicates; or, with none, the single fit (b = -1) */
      if (b >= 0 ? !s->valid[b] : nvalid > 0) continue;
      for (int j = 0; j < k; j++) {
        double g[3];
        if (o->fit == BSURF_NORMAL_PCA || degree == 0) {
          const double *src = b >= 0 ? &s->bn[3 * b] : nP;
          for (int t = 0; t < 3; t++)
            g[t] = src[t];
        } else {
          const int m = bsurf_poly_terms(degree);
          const double *cb = b >= 0 ? &s->coefs[(size_t)(b + 1) * m] : s->coefs;
          bsurf_localfit_normal(&s->lf, &frame, degree, cb, s->lf.u[j], s->lf.v[j], g);
        }
        total += bsurf_angle_between(g, &c->ref[3 * (size_t)ids[j]], 1);
        terms++;
      }
    }
    c->out->normal_err[i] = terms ? total / terms : 0.0;
  }
}

static void normals_point(void *vctx, void *scratch, size_t i) {
  const normals_ctx *c = vctx;
  const uint32_t *row = &c->nb->idx[i * (size_t)c->nb->k];
  normals_point_row(c, scratch, i, c->xyz, row, row);
}

static void normals_tally(void *vctx, const void *scratch) {
  const normals_ctx *c = vctx;
  const normal_scratch *s = scratch;
  if (!c->report) return;
  c->report->replicates_skipped += s->skipped;
  c->report->degree_reduced += s->reduced;
  c->report->degenerate += s->degenerate;
}

/* The options' checks of bsurf_estimate_normals, against lists of nb_k
 * neighbours of n points. */
static bsurf_status normals_check(const char *who, const bsurf_normal_options o, int nb_k,
                                  size_t n) {
  BSURF_REQUIRE_IN(who, o.fit == BSURF_NORMAL_PCA || o.fit == BSURF_NORMAL_POLY,
                   "fit = %d: must be BSURF_NORMAL_PCA or BSURF_NORMAL_POLY", (int)o.fit);
  BSURF_REQUIRE_IN(who,
                   o.fit != BSURF_NORMAL_POLY || (o.degree >= 1 && o.degree <= BSURF_DEGREE_MAX),
                   "degree = %d: must be in [1, %d]", o.degree, BSURF_DEGREE_MAX);
  BSURF_REQUIRE_IN(who, (unsigned)o.pca_center <= BSURF_PCA_POINT,
                   "pca_center = %d: must be BSURF_PCA_CENTROID or BSURF_PCA_POINT",
                   (int)o.pca_center);
  BSURF_REQUIRE_IN(who, o.bootstrap >= 0 && o.bootstrap <= 100000,
                   "bootstrap (B) = %d: must be in [0, 100000]", o.bootstrap);
  BSURF_REQUIRE_IN(who, o.k >= 3 && o.k <= 65535 && o.k <= nb_k,
                   "k = %d: must be in [3, %d] (nb->k = %d)", o.k, nb_k < 65535 ? nb_k : 65535,
                   nb_k);
  if ((size_t)o.k > n)
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS, "k = %d exceeds the %zu points", o.k, n);
  if (o.fit == BSURF_NORMAL_POLY && o.k < bsurf_poly_terms(o.degree))
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS,
                             "k = %d is too small for degree %d: a fit needs %d points", o.k,
                             o.degree, bsurf_poly_terms(o.degree));
  return BSURF_OK;
}

/* The point loop of bsurf_estimate_normals and bsurf_estimate_normals_at
 * (k_at: NULL, or each point's own K <= o->k), after their checks. */
static bsurf_status normals_run(const double *xyz, const bsurf_neighbors *nb,
                                const double *ref_normals, const bsurf_normal_options *o,
                                const int *k_at, const int *d_at, bsurf_normal_fields *out,
                                bsurf_normal_report *report) {
  static const bsurf_point_loop loop = {sizeof(normal_scratch), scratch_alloc, scratch_free,
                                        normals_point, normals_tally};
  const scratch_sizes sizes = {o->k, o->bootstrap, o->fit == BSURF_NORMAL_POLY ? o->degree : 1, 1};
  normals_ctx ctx = {xyz, nb, ref_normals, o, out, report, NULL, 0, NULL, k_at, d_at};
  const double work = (double)o->k * (o->bootstrap + 1) *
                      (o->fit == BSURF_NORMAL_POLY ? bsurf_poly_terms(o->degree) : 3);
  bsurf_status st = bsurf_point_loop_run(&loop, &sizes, &ctx, nb, xyz, work, o->threads,
                                         o->progress, o->progress_user);
  if (report && st == BSURF_OK) report->replicates_total = nb->point_count * (size_t)o->bootstrap;
  return st;
}

bsurf_status bsurf_estimate_normals(const double *xyz, const bsurf_neighbors *nb,
                                    const double *ref_normals, const bsurf_normal_options *opts,
                                    bsurf_normal_fields *out, bsurf_normal_report *report) {
  bsurf_normal_options o = opts ? *opts : bsurf_normal_options_default();
  if (report) memset(report, 0, sizeof *report);
  BSURF_REQUIRE(xyz, "xyz is NULL");
  BSURF_REQUIRE(nb && nb->idx, "nb is %s: build it with bsurf_neighbors_build",
                nb ? "empty" : "NULL");
  BSURF_REQUIRE(out, "out is NULL (give a bsurf_normal_fields, its unwanted outputs NULL)");
  bsurf_status st = normals_check("bsurf_estimate_normals", o, nb->k, nb->point_count);
  if (st != BSURF_OK) return st;
  return normals_run(xyz, nb, ref_normals, &o, NULL, NULL, out, report);
}

bsurf_status bsurf_estimate_normals_at(const double *xyz, const bsurf_neighbors *nb,
                                       const bsurf_normal_options *opts, const int *k_at,
                                       bsurf_normal_fields *out, bsurf_normal_report *report) {
  return bsurf_estimate_normals_at_kd(xyz, nb, opts, k_at, NULL, out, report);
}

bsurf_status bsurf_estimate_normals_at_kd(const double *xyz, const bsurf_neighbors *nb,
                                          const bsurf_normal_options *opts, const int *k_at,
                                          const int *d_at, bsurf_normal_fields *out,
                                          bsurf_normal_report *report) {
  bsurf_normal_options o = *opts;
  if (report) memset(report, 0, sizeof *report);
  BSURF_REQUIRE(xyz && nb && nb->idx && k_at && out && !out->normal_err,
                "xyz, nb, nb->idx, k_at and out must not be NULL, out->normal_err must be");
  bsurf_status st = normals_check("bsurf_estimate_normals_at", o, nb->k, nb->point_count);
  if (st != BSURF_OK) return st;
  BSURF_REQUIRE(!d_at || o.fit == BSURF_NORMAL_POLY, "d_at needs the POLY fit");
  for (size_t i = 0; i < nb->point_count; i++) {
    const int d = d_at ? d_at[i] : o.degree;
    BSURF_REQUIRE(d >= 1 && d <= o.degree, "d_at[%zu] = %d must be in [1, opts->degree = %d]", i, d,
                  o.degree);
    const int kmin = o.fit == BSURF_NORMAL_POLY ? bsurf_poly_terms(d) : 3;
    BSURF_REQUIRE(k_at[i] >= kmin && k_at[i] <= o.k, "k_at[%zu] = %d must be in [%d, opts->k = %d]",
                  i, k_at[i], kmin, o.k);
  }
  /* the scratch of the largest K; point i's estimate is bsurf_estimate_normals's with
   * opts->k = k_at[i] (the same draws, keyed by the point and K: the same bits) */
  return normals_run(xyz, nb, NULL, &o, k_at, d_at, out, report);
}

/* ---- the same estimate on the search's rows as they come ---- */

typedef struct stream_ctx {
  normals_ctx c;
  normal_scratch *scratch; /* one per thread */
  uint32_t *iota;          /* 0, 1, ..., nb_k - 1 */
} stream_ctx;

static void stream_row(void *vctx, int thread, uint32_t point, const uint32_t *ids,
                       const double *xyz) {
  stream_ctx *sc = vctx;
  normals_point_row(&sc->c, &sc->scratch[thread], point, xyz, sc->iota, ids);
}

bsurf_status bsurf_estimate_normals_streamed(const double *xyz, size_t point_count, int nb_k,
                                             const bsurf_normal_options *opts,
                                             bsurf_normal_fields *out, bsurf_normal_report *report,
                                             double *h, size_t *duplicates) {
  bsurf_normal_options o = *opts;
  if (report) memset(report, 0, sizeof *report);
  BSURF_REQUIRE(xyz && out && h && duplicates, "xyz, out, h and duplicates must not be NULL");
  BSURF_REQUIRE(!o.point_index, "opts->point_index: the streamed pass numbers the points itself");
  BSURF_REQUIRE(!out->normal_err, "out->normal_err: the test error needs reference normals");
  bsurf_status st = normals_check("bsurf_estimate_normals_streamed", o, nb_k, point_count);
  if (st != BSURF_OK) return st;
  const int T = bsurf_threads_resolve(o.threads);
  normal_scratch *scr = bsurf_calloc_array((size_t)T, sizeof *scr);
  uint32_t *iota = bsurf_alloc_array((size_t)nb_k, sizeof *iota);
  if (!scr || !iota) {
    free(scr);
    free(iota);
    return BSURF_ERR_NOMEM;
  }
  for (int j = 0; j < nb_k; j++)
    iota[j] = (uint32_t)j;
  const scratch_sizes sizes = {o.k, o.bootstrap, o.fit == BSURF_NORMAL_POLY ? o.degree : 1, 1};
  for (int t = 0; t < T && st == BSURF_OK; t++)
    st = scratch_alloc(&scr[t], &sizes);
  /* no reference normals: a streamed point cannot wait for its neighbours' */
  stream_ctx sc = {{xyz, NULL, NULL, &o, out, report, NULL, 0, NULL, NULL, NULL}, scr, iota};
  if (st == BSURF_OK)
    st = bsurf_neighbors_stream(xyz, point_count, nb_k, o.threads, stream_row, &sc, h, duplicates,
                                o.progress, o.progress_user);
  for (int t = 0; t < T; t++) {
    if (st == BSURF_OK) normals_tally(&sc.c, &scr[t]);
    scratch_free(&scr[t]);
  }
  free(scr);
  free(iota);
  if (report && st == BSURF_OK) report->replicates_total = point_count * (size_t)o.bootstrap;
  return st;
}

/* ---- per-point K selection over nested neighbourhoods ----
 *
 * For every point, all candidates K in one pass (src/algo/nested.c): the
 * terms of the kmax = ks[nk - 1] sorted neighbours once; the whole
 * neighbourhood's sums of every candidate (its normal n_P, the orientation
 * reference of 5.2.1); B replicates of Poisson(1) counts per neighbour,
 * drawn once and shared by every candidate (each candidate's replicate b is
 * the Poisson bootstrap of its first K points), with every candidate's
 * moments of every replicate from one running sum in vector lanes; each
 * replicate's normal by bsurf_eigen_sym3_smallest; then per candidate the
 * estimate of Eq. 5.4, the variance of Eq. 5.5 and the test error of
 * Eq. 5.10 against the reference normals of the neighbours (gathered once),
 * and the candidate with the smallest test error. */

typedef struct select_scratch {
  double *terms;           /* kmax x COLS */
  uint32_t *u;             /* kmax */
  double *Wt;              /* kmax x B */
  double *sums;            /* nk x COLS x max(B, 1) */
  double *fsums;           /* nk x COLS */
  int *nz;                 /* nk x B */
  double *ref;             /* 3 x kmax: rx, ry, rz */
  int *kl;                 /* nk x B: each (candidate, replicate)'s K */
  double *asum;            /* nk x B: its angle sum (Eq. 5.10) */
  double *bn;              /* nk x B x 3 */
  unsigned char *valid;    /* nk x B */
  double *nP;              /* nk x 3 */
  double *err, *var, *nrm; /* nk, nk, nk x 3 */
  double *cov, *nl, *ang2; /* 6 x B, 3 x B, B: one candidate's replicates in lanes */
  int *wok, *st;           /* B, B */
  bsurf_blocks mem;        /* the arrays above */
  size_t skipped, degenerate;
} select_scratch;

static void select_scratch_free(void *vs) {
  select_scratch *s = vs;
  bsurf_blocks_free(&s->mem);
  memset(s, 0, sizeof *s);
}

static bsurf_status select_scratch_alloc(void *vs, const void *vsz) {
  select_scratch *s = vs;
  const scratch_sizes *z = vsz;
  memset(s, 0, sizeof *s);
  const size_t b1 = (size_t)(z->B > 0 ? z->B : 1), kk = (size_t)z->k, cands = (size_t)z->nk;
  bsurf_blocks *m = &s->mem;
  s->terms = bsurf_blocks_array(m, kk, BSURF_NESTED_COLS * sizeof(double));
  s->u = bsurf_blocks_array(m, kk, sizeof(uint32_t));
  s->Wt = bsurf_blocks_aligned(m, kk * b1, sizeof(double));
  s->sums = bsurf_blocks_aligned(m, cands * b1, BSURF_NESTED_COLS * sizeof(double));
  s->fsums = bsurf_blocks_array(m, cands, BSURF_NESTED_COLS * sizeof(double));
  s->nz = bsurf_blocks_array(m, cands * b1, sizeof(int));
  s->ref = bsurf_blocks_aligned(m, kk, 3 * sizeof(double));
  s->kl = bsurf_blocks_array(m, cands * b1, sizeof(int));
  s->asum = bsurf_blocks_array(m, cands * b1, sizeof(double));
  s->bn = bsurf_blocks_array(m, cands * b1, 3 * sizeof(double));
  s->valid = bsurf_blocks_array(m, cands * b1, 1);
  s->nP = bsurf_blocks_array(m, cands, 3 * sizeof(double));
  s->err = bsurf_blocks_array(m, cands, sizeof(double));
  s->var = bsurf_blocks_array(m, cands, sizeof(double));
  s->nrm = bsurf_blocks_array(m, cands, 3 * sizeof(double));
  s->cov = bsurf_blocks_aligned(m, b1, 6 * sizeof(double));
  s->nl = bsurf_blocks_aligned(m, b1, 3 * sizeof(double));
  s->ang2 = bsurf_blocks_array(m, b1, sizeof(double));
  s->wok = bsurf_blocks_array(m, b1, sizeof(int));
  s->st = bsurf_blocks_array(m, b1, sizeof(int));
  return bsurf_blocks_status(m); /* the loop frees what was made */
}

static void select_point(void *vctx, void *scratch, size_t i) {
  const normals_ctx *c = vctx;
  select_scratch *s = scratch;
  const int nk = c->nk, *ks = c->ks, kmax = ks[nk - 1], B = c->o->bootstrap;
  const bsurf_normal_options *o = c->o;
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  const size_t COLS = BSURF_NESTED_COLS;

  bsurf_nested_terms(c->xyz, idx, kmax, s->terms);
  /* the reference normals */
  double *rx = s->ref, *ry = rx + kmax, *rz = ry + kmax;
  for (int j = 0; j < kmax; j++) {
    const double *r = &c->ref[3 * (size_t)idx[j]];
    rx[j] = r[0], ry[j] = r[1], rz[j] = r[2];
  }

  /* the whole neighbourhoods: the single fits (as bsurf_estimate_normals) */
  bsurf_nested_sums(s->terms, kmax, 1, NULL, ks, nk, s->fsums, NULL);
  for (int a = 0; a < nk; a++)
    if (pca_normal_from_row(&s->fsums[a * COLS], o->pca_center, &s->nP[3 * a]) != 0)
      s->degenerate++;

  /* the replicates: one draw per point, shared by the candidates */
  if (B > 0) {
    const uint64_t key = o->point_index ? o->point_index[i] : i;
    bsurf_boot_poisson_rows(o->seed, key, B, kmax, s->u, s->Wt);
    bsurf_nested_sums(s->terms, kmax, B, s->Wt, ks, nk, s->sums, s->nz);
    for (int a = 0; a < nk; a++) {
      const double *blk = &s->sums[(size_t)a * COLS * B];
      bsurf_nested_cov_lanes(blk, B, o->pca_center, s->cov, s->wok);
      bsurf_eigen_sym3_smallest_lanes(B, s->cov, s->nl, s->st);
      for (int b = 0; b < B; b++) {
        const size_t ab = (size_t)a * B + b;
        s->valid[ab] = s->nz[ab] >= 3 && s->wok[b] && s->st[b] == 0;
        for (int t = 0; t < 3; t++)
          s->bn[3 * ab + t] = s->nl[(size_t)t * B + b];
      }
    }
  }

  /* orient to n_P (5.2.1), Eq. 5.4 and Eq. 5.5 */
  for (int a = 0; a < nk; a++) {
    const int nvalid =
        bsurf_nested_summary(B, &s->nP[3 * a], &s->bn[(size_t)a * B * 3], &s->valid[(size_t)a * B],
                             &s->nrm[3 * a], &s->var[a], s->ang2);
    s->skipped += (size_t)(B - nvalid);
    for (int b = 0; b < B; b++)
      s->kl[(size_t)a * B + b] = ks[a];
  }
  /* Eq. 5.10's inner sums, every candidate's replicates at once */
  if (B > 0) bsurf_nested_angle_sums((size_t)nk * B, s->bn, s->valid, s->kl, rx, ry, rz, s->asum);
  int best = 0;
  for (int a = 0; a < nk; a++) {
    const int K = ks[a];
    const unsigned char *valid = &s->valid[(size_t)a * B];
    /* Eq. 5.10: (1 / (B K)) sum_b sum_j theta(g^b, n_j); with no valid
     * replicate the single fit's training error */
    double total = 0;
    int nvalid = 0;
    for (int b = 0; b < B; b++)
      if (valid[b]) total += s->asum[(size_t)a * B + b], nvalid++;
    if (nvalid > 0)
      s->err[a] = total / ((double)nvalid * K);
    else
      s->err[a] = bsurf_nested_angle_sum(&s->nP[3 * a], rx, ry, rz, K) / K;
    if (s->err[a] < s->err[best]) best = a; /* ties keep the smaller K */
  }

  bsurf_normal_select_fields *out = c->sel;
  if (out->normals)
    for (int t = 0; t < 3; t++)
      out->normals[3 * i + t] = s->nrm[3 * best + t];
  if (out->normal_var) out->normal_var[i] = s->var[best];
  if (out->normal_err) out->normal_err[i] = s->err[best];
  if (out->k_selected) out->k_selected[i] = ks[best];
  if (out->cand_err) memcpy(&out->cand_err[i * (size_t)nk], s->err, (size_t)nk * sizeof(double));
  if (out->cand_var) memcpy(&out->cand_var[i * (size_t)nk], s->var, (size_t)nk * sizeof(double));
  if (out->cand_normals)
    memcpy(&out->cand_normals[i * (size_t)nk * 3], s->nrm, (size_t)nk * 3 * sizeof(double));
}

static void select_tally(void *vctx, const void *scratch) {
  const normals_ctx *c = vctx;
  const select_scratch *s = scratch;
  if (!c->report) return;
  c->report->replicates_skipped += s->skipped;
  c->report->degenerate += s->degenerate;
}

bsurf_status bsurf_select_normals_k(const double *xyz, const bsurf_neighbors *nb,
                                    const double *ref_normals, const bsurf_normal_options *opts,
                                    const int *ks, int nk, bsurf_normal_select_fields *out,
                                    bsurf_normal_report *report) {
  bsurf_normal_options o = opts ? *opts : bsurf_normal_options_default();
  if (report) memset(report, 0, sizeof *report);
  BSURF_REQUIRE(xyz && nb && nb->idx && ref_normals && ks && out,
                "xyz, nb, nb->idx, ref_normals, ks and out must not be NULL");
  BSURF_REQUIRE(nk >= 1, "nk = %d: at least one candidate K", nk);
  BSURF_REQUIRE(o.fit == BSURF_NORMAL_PCA, "opts->fit = %d: selection of K takes PCA normals",
                (int)o.fit);
  BSURF_REQUIRE(o.bootstrap >= 0 && o.bootstrap <= 100000,
                "opts->bootstrap = %d must be in [0, 100000]", o.bootstrap);
  bsurf_status st = bsurf_nested_check_ks("bsurf_select_normals_k", ks, nk, 3, nb);
  if (st != BSURF_OK) return st;

  static const bsurf_point_loop loop = {sizeof(select_scratch), select_scratch_alloc,
                                        select_scratch_free, select_point, select_tally};
  const scratch_sizes sizes = {ks[nk - 1], o.bootstrap, 1, nk};
  normals_ctx ctx = {xyz, nb, ref_normals, &o, NULL, report, ks, nk, out, NULL, NULL};
  const double work = (double)ks[nk - 1] * nk * (o.bootstrap + 1) * 3;
  st = bsurf_point_loop_run(&loop, &sizes, &ctx, nb, xyz, work, o.threads, o.progress,
                            o.progress_user);
  if (report && st == BSURF_OK)
    report->replicates_total = nb->point_count * (size_t)o.bootstrap * (size_t)nk;
  return st;
}
