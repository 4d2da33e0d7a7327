/* Per-point K and degree selection of polynomial normals (thesis 5.5,
 * Algorithm 3; docs/normals.md "How --select-k and --select-degree
 * compute"): every candidate (K, M) of a point in one visit, instead of one
 * whole normals pass per candidate.
 *
 * For a point with its sorted kmax = ks[nk - 1] neighbours:
 *  - B replicates of Poisson(1) counts per neighbour, drawn once and shared
 *    by every K (each K's replicate b is the Poisson bootstrap of its first
 *    K points, as in bsurf_select_normals_k) and every degree: all
 *    candidates are compared on the same resamples;
 *  - per K, the PCA frame of its K points (Eq. 3.4; the single fit's frame,
 *    as bsurf_estimate_normals) and the per-neighbour monomials u^i v^j of
 *    degree <= 2 M_max and phi z (src/local), then one product of the
 *    B + 1 weight rows with them (bsurf_localfit_normal_eq_lanes): the
 *    normal equations (Eq. 3.9) of every replicate and of the whole
 *    neighbourhood at the largest degree, whose leading blocks are those of
 *    every lower degree (the graded basis is a prefix);
 *  - per degree, the whole neighbourhood's fit (with the degree reduced
 *    while its system is rank-deficient, as bsurf_estimate_normals), the
 *    replicates' LDL^T solves in vector lanes, their normals at d_i
 *    (Eq. 5.9), the estimate (Eq. 5.4), the variance (Eq. 5.5) and the test
 *    error (Eq. 5.10): the angles between each replicate's normal at every
 *    neighbour p_j and n_j, evaluated in the frame (the reference normals
 *    rotated into it once) in vector lanes.
 * The candidate with the smallest test error wins (ties: the smaller K,
 * then the earlier degree). The frames are per K because the height
 * function of Eq. 3.5 lives in the neighbourhood's own PCA frame; only the
 * draws and the sums' kernels are shared across K. */
#include "algo/algo.h"
#include "bootstrap/bootstrap.h"
#include "common/common.h"
#include "local/local.h"
#include "search/search.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct kd_scratch {
  bsurf_localfit lf;
  uint32_t *u;             /* kmax */
  double *Wt;              /* kmax x B: the Poisson counts */
  double *Wr;              /* B x kmax: the same, replicate-major */
  double *W;               /* rows x K: one candidate's weight rows */
  double *lanes;           /* rows x ncols: its normal equations */
  int *nz;                 /* B: distinct points among the first K */
  float *ref;              /* 3 x kq: the reference normals in the frame (float) */
  float *phif;             /* terms(dmax - 1) x kq: the gradient's basis (float) */
  float *accf;             /* kq */
  double *accd;            /* kq */
  double *coefs;           /* (B + 1) x terms: the whole fit, then the replicates */
  unsigned char *valid;    /* B */
  double *bn, *ang2;       /* B x 3, B */
  double *err, *var, *nrm; /* candidates, candidates, candidates x 3 */
  bsurf_blocks mem;        /* the arrays above */
  size_t skipped, reduced, degenerate;
} kd_scratch;

static void kd_free(void *vs) {
  kd_scratch *s = vs;
  bsurf_localfit_free(&s->lf);
  bsurf_blocks_free(&s->mem);
  memset(s, 0, sizeof *s);
}

typedef struct kd_sizes {
  int kmax, dmax, B, ncand; /* the largest K and degree, B, candidates (K, degree) */
} kd_sizes;

static bsurf_status kd_alloc(void *vs, const void *vz) {
  kd_scratch *s = vs;
  const kd_sizes *z = vz;
  const int kmax = z->kmax, B = z->B, ncand = z->ncand;
  bsurf_status st = bsurf_localfit_alloc(&s->lf, kmax, z->dmax);
  if (st != BSURF_OK) return st;
  const size_t kk = (size_t)kmax, b1 = (size_t)(B > 0 ? B : 1), rows = (size_t)bsurf_boot_rows(B);
  const size_t kq = (kk + 15) / 16 * 16;
  const size_t mg = (size_t)bsurf_poly_terms(z->dmax - 1);
  bsurf_blocks *m = &s->mem;
  s->u = bsurf_blocks_array(m, kk, sizeof(uint32_t));
  s->Wt = bsurf_blocks_aligned(m, kk * b1, sizeof(double));
  s->Wr = bsurf_blocks_aligned(m, b1 * kk, sizeof(double));
  s->W = bsurf_blocks_aligned(m, rows * kk, sizeof(double));
  s->lanes = bsurf_blocks_aligned(m, rows, BSURF_NCOLS_MAX * sizeof(double));
  s->nz = bsurf_blocks_array(m, b1, sizeof(int));
  s->ref = bsurf_blocks_aligned(m, 3 * kq, sizeof(float));
  s->phif = bsurf_blocks_aligned(m, mg * kq, sizeof(float));
  s->accf = bsurf_blocks_aligned(m, kq, sizeof(float));
  s->accd = bsurf_blocks_aligned(m, kq, sizeof(double));
  s->coefs = bsurf_blocks_aligned(m, b1 + 1, BSURF_TERMS_MAX * sizeof(double));
  s->valid = bsurf_blocks_array(m, b1, 1);
  s->bn = bsurf_blocks_array(m, b1, 3 * sizeof(double));
  s->ang2 = bsurf_blocks_array(m, b1, sizeof(double));
  s->err = bsurf_blocks_array(m, (size_t)ncand, sizeof(double));
  s->var = bsurf_blocks_array(m, (size_t)ncand, sizeof(double));
  s->nrm = bsurf_blocks_array(m, (size_t)ncand, 3 * sizeof(double));
  /* the invalid replicates' rows are read (their normals computed in lanes,
   * not used): never uninitialised */
  if (s->coefs) memset(s->coefs, 0, (b1 + 1) * BSURF_TERMS_MAX * sizeof(double));
  return bsurf_blocks_status(m); /* the loop frees what was made */
}

typedef struct kd_ctx {
  const double *xyz;
  const bsurf_neighbors *nb;
  const double *ref;
  const bsurf_normal_options *o;
  const int *ks, *ds;
  int nk, nd, dmax;
  bsurf_normal_select_fields *out;
  int *dsel;
  bsurf_normal_report *report;
} kd_ctx;

/* Candidate (K, degree) of one point, the K's frame, fits and weights set
 * up: writes s->nrm, s->var and s->err of candidate c. */
static void kd_candidate(const kd_ctx *c, kd_scratch *s, const bsurf_frame *frame, int K, size_t kq,
                         int degree0, int cand) {
  const int B = c->o->bootstrap;
  const bsurf_localfit *lf = &s->lf;
  double *const fit = s->coefs, *const reps = s->coefs + BSURF_TERMS_MAX;
  /* the whole neighbourhood (row B), the degree reduced while rank-deficient */
  double row[BSURF_NCOLS_MAX];
  bsurf_lanes_row(lf->ncols, s->lanes, B, row);
  int degree = degree0;
  while (degree > 0 && bsurf_localfit_solve_row(lf, degree, row, fit) != 0)
    degree--;
  if (degree != degree0) s->reduced++;
  /* the normals in the frame's coordinates: Eqs. 5.4 and 5.5 (orientation,
   * mean, angles) do not depend on the rotation, the mean is rotated back
   * once */
  double nP[3] = {0.0, 0.0, 1.0}; /* degree 0, a constant height: the tangent plane */
  if (degree > 0) bsurf_localfit_normal_local(lf, degree, fit, lf->u[0], lf->v[0], nP);
  /* the replicates (Eq. 4.2 as Poisson counts): enough distinct points for
   * the candidate's degree, or, reduced, let the solve decide */
  for (int b = 0; b < B; b++)
    s->valid[b] = (s->nz[b] >= bsurf_poly_terms(degree0) || degree < degree0) && degree > 0;
  if (degree > 0) bsurf_localfit_solve_lanes(lf, degree, B, s->lanes, s->valid, reps);
  if (degree > 0) /* every row (the invalid ones' are not used) */
    bsurf_localfit_normals_local(lf, degree, B, reps, lf->u[0], lf->v[0], s->bn);
  double nl[3];
  const int nvalid = bsurf_nested_summary(B, nP, s->bn, s->valid, nl, &s->var[cand], s->ang2);
  bsurf_frame_dir_to_global(frame, nl, &s->nrm[3 * cand]);
  s->skipped += (size_t)(B - nvalid);
  /* Eq. 5.10: (1 / (B K)) sum_b sum_j theta(g^b(p_j), n_j); with no valid
   * replicate the single fit's training error */
  const double inv = 1.0 / lf->scale;
  if (nvalid > 0)
    s->err[cand] = bsurf_nested_field_angle_total(degree, B, reps, s->valid, inv, s->phif, kq,
                                                  s->ref, K, s->accf, s->accd) /
                   ((double)nvalid * K);
  else
    s->err[cand] = bsurf_nested_field_angle_total(degree, 1, fit, NULL, inv, s->phif, kq, s->ref, K,
                                                  s->accf, s->accd) /
                   K;
}

static void kd_point(void *vctx, void *scratch, size_t i) {
  const kd_ctx *c = vctx;
  const bsurf_normal_options *o = c->o;
  kd_scratch *s = scratch;
  const int nk = c->nk, nd = c->nd, kmax = c->ks[nk - 1], B = o->bootstrap;
  const int R = bsurf_boot_rows(B);
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];

  /* the replicates: one draw per point, shared by every candidate */
  const uint64_t key = o->point_index ? o->point_index[i] : i;
  if (B > 0) bsurf_boot_poisson_rows(o->seed, key, B, kmax, s->u, s->Wt);
  for (int j = 0; j < kmax; j++) /* replicate-major once: each K copies row prefixes */
    for (int b = 0; b < B; b++)
      s->Wr[(size_t)b * kmax + j] = s->Wt[(size_t)j * B + b];
  memset(s->nz, 0, (size_t)(B > 0 ? B : 1) * sizeof *s->nz);

  int best = 0, k0 = 0;
  for (int a = 0; a < nk; a++) {
    const int K = c->ks[a];
    /* the distinct points of each replicate among the first K */
    for (int j = k0; j < K; j++)
      for (int b = 0; b < B; b++)
        s->nz[b] += s->Wt[(size_t)j * B + b] != 0;
    k0 = K;
    bsurf_frame frame;
    bsurf_local_frame(c->xyz, idx, K, o->pca_center, &frame);
    const int flat =
        frame.eigenvalues[2] > 0 && frame.eigenvalues[1] > 1e-12 * frame.eigenvalues[2];
    if (!flat) s->degenerate += (size_t)nd;
    bsurf_localfit *lf = &s->lf;
    bsurf_localfit_setup(lf, c->xyz, idx, K, &frame, c->dmax);
    /* the weight rows (replicates, then the whole P), row-major R x K */
    double *W = s->W;
    for (int b = 0; b < B; b++)
      memcpy(&W[(size_t)b * K], &s->Wr[(size_t)b * kmax], (size_t)K * sizeof *W);
    for (int j = 0; j < K; j++)
      W[(size_t)B * K + j] = 1.0;
    memset(&W[(size_t)(B + 1) * K], 0, (size_t)(R - B - 1) * K * sizeof *W);
    bsurf_localfit_normal_eq_lanes(lf, R, W, s->lanes);
    /* the reference normals in the frame and the gradient's basis rows, in
     * float (Eq. 5.10's angles are single precision), padded to kq (a
     * multiple of 16) with r = (0, 0, 1) and phi = 0: the angle loops run
     * over whole vectors */
    const size_t kq = (size_t)(K + 15) / 16 * 16;
    float *rx = s->ref, *ry = rx + kq, *rz = ry + kq;
    for (int j = 0; j < K; j++) {
      const double *r = &c->ref[3 * (size_t)idx[j]];
      rx[j] = (float)(frame.rot[0][0] * r[0] + frame.rot[0][1] * r[1] + frame.rot[0][2] * r[2]);
      ry[j] = (float)(frame.rot[1][0] * r[0] + frame.rot[1][1] * r[1] + frame.rot[1][2] * r[2]);
      rz[j] = (float)(frame.rot[2][0] * r[0] + frame.rot[2][1] * r[1] + frame.rot[2][2] * r[2]);
    }
    for (size_t j = (size_t)K; j < kq; j++)
      rx[j] = ry[j] = 0.0f, rz[j] = 1.0f;
    const int mg = bsurf_poly_terms(c->dmax - 1);
    for (int t = 0; t < mg; t++) {
      float *row = &s->phif[(size_t)t * kq];
      const double *src = &lf->phit[(size_t)t * lf->kp];
      for (int j = 0; j < K; j++)
        row[j] = (float)src[j];
      for (size_t j = (size_t)K; j < kq; j++)
        row[j] = 0.0f;
    }
    for (int d = 0; d < nd; d++) {
      const int cand = a * nd + d;
      kd_candidate(c, s, &frame, K, kq, c->ds[d], cand);
      if (s->err[cand] < s->err[best]) best = cand; /* ties: the smaller K, then degree */
    }
  }

  bsurf_normal_select_fields *out = c->out;
  const int ncand = nk * nd;
  if (out->normals)
    for (int t = 0; t < 3; t++)
      out->normals[3 * i + t] = s->nrm[3 * best + t];
  if (out->normal_var) out->normal_var[i] = s->var[best];
  if (out->normal_err) out->normal_err[i] = s->err[best];
  if (out->k_selected) out->k_selected[i] = c->ks[best / nd];
  if (c->dsel) c->dsel[i] = c->ds[best % nd];
  if (out->cand_err)
    memcpy(&out->cand_err[i * (size_t)ncand], s->err, (size_t)ncand * sizeof(double));
  if (out->cand_var)
    memcpy(&out->cand_var[i * (size_t)ncand], s->var, (size_t)ncand * sizeof(double));
  if (out->cand_normals)
    memcpy(&out->cand_normals[i * (size_t)ncand * 3], s->nrm, (size_t)ncand * 3 * sizeof(double));
}

static void kd_tally(void *vctx, const void *scratch) {
  const kd_ctx *c = vctx;
  const kd_scratch *s = scratch;
  if (!c->report) return;
  c->report->replicates_skipped += s->skipped;
  c->report->degree_reduced += s->reduced;
  c->report->degenerate += s->degenerate;
}

bsurf_status bsurf_select_normals_kd(const double *xyz, const bsurf_neighbors *nb,
                                     const double *ref_normals, const bsurf_normal_options *opts,
                                     const int *ks, int nk, const int *ds, int nd,
                                     bsurf_normal_select_fields *out, int *degree_selected,
                                     bsurf_normal_report *report) {
  bsurf_normal_options o = opts ? *opts : bsurf_normal_options_default();
  if (report) memset(report, 0, sizeof *report);
  BSURF_REQUIRE(xyz && nb && nb->idx && ref_normals && ks && ds && out,
                "xyz, nb, nb->idx, ref_normals, ks, ds and out must not be NULL");
  BSURF_REQUIRE(nk >= 1 && nd >= 1, "nk = %d, nd = %d: at least one candidate K and degree", nk,
                nd);
  BSURF_REQUIRE(o.fit == BSURF_NORMAL_POLY, "opts->fit = %d: selection of the degree takes POLY",
                (int)o.fit);
  BSURF_REQUIRE(o.bootstrap >= 0 && o.bootstrap <= 100000,
                "opts->bootstrap = %d must be in [0, 100000]", o.bootstrap);
  BSURF_REQUIRE((unsigned)o.pca_center <= BSURF_PCA_POINT,
                "pca_center = %d: must be BSURF_PCA_CENTROID or BSURF_PCA_POINT",
                (int)o.pca_center);
  int dmax = 0;
  for (int d = 0; d < nd; d++) {
    BSURF_REQUIRE(ds[d] >= 1 && ds[d] <= BSURF_DEGREE_MAX, "ds[%d] = %d must be in [1, %d]", d,
                  ds[d], BSURF_DEGREE_MAX);
    if (ds[d] > dmax) dmax = ds[d];
  }
  /* every candidate K holds a fit of every degree */
  const int kmin = bsurf_poly_terms(dmax) > 3 ? bsurf_poly_terms(dmax) : 3;
  bsurf_status st = bsurf_nested_check_ks("bsurf_select_normals_kd", ks, nk, kmin, nb);
  if (st != BSURF_OK) return st;

  static const bsurf_point_loop loop = {sizeof(kd_scratch), kd_alloc, kd_free, kd_point, kd_tally};
  const kd_sizes sizes = {ks[nk - 1], dmax, o.bootstrap, nk * nd};
  kd_ctx ctx = {xyz, nb, ref_normals, &o, ks, ds, nk, nd, dmax, out, degree_selected, report};
  const double work = (double)ks[nk - 1] * nk * nd * (o.bootstrap + 1) * bsurf_poly_terms(dmax);
  st = bsurf_point_loop_run(&loop, &sizes, &ctx, nb, xyz, work, o.threads, o.progress,
                            o.progress_user);
  if (report && st == BSURF_OK)
    report->replicates_total = nb->point_count * (size_t)o.bootstrap * (size_t)nk * (size_t)nd;
  return st;
}
