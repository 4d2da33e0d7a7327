/* The MSE rule's passes on the rows of a neighbourhood table (docs/normals.md,
 * "Choosing K"; docs/scaling.md for the tiles): bsurf_select_k on the whole
 * cloud; the same passes per tile for the tiled job
 * (src/jobs/normals_mse_tiled.c). */
#include "algo/kselect.h"

#include <stdlib.h>
#include <string.h>

/* A pass over nb's rows in their visit order (no result depends on it). */
static bsurf_status ksel_pass(const bsurf_ksel_run *r, ksel_ctx *c, void (*fn)(void *, int, size_t),
                              int progress) {
  uint32_t *owned = NULL;
  const uint32_t *order = bsurf_visit_order(c->nb, c->xyz, &owned);
  if (!order) return BSURF_ERR_NOMEM;
  bsurf_status st = bsurf_parallel_points_ordered(c->nb->point_count, order, r->T, fn, c,
                                                  progress ? r->o.progress : NULL,
                                                  progress ? r->o.progress_user : NULL);
  free(owned);
  return st;
}

static ksel_ctx ksel_ctx_of(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb) {
  ksel_ctx c = {
      .xyz = xyz, .nb = nb, .o = &r->o, .kmax = r->kmax, .scr = r->scr, .sheet_crit = r->crit};
  return c;
}

bsurf_status bsurf_ksel_noise(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                              double *s2) {
  ksel_ctx c = ksel_ctx_of(r, xyz, nb);
  c.s2 = s2; /* by row */
  return ksel_pass(r, &c, noise_point, 0);
}

bsurf_status bsurf_ksel_pool(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                             const double *s2, double *noise) {
  ksel_ctx c = ksel_ctx_of(r, xyz, nb);
  c.s2 = (double *)s2; /* read only, by neighbour */
  c.noise = noise;
  return ksel_pass(r, &c, pool_point, 0);
}

bsurf_status bsurf_ksel_level(const bsurf_ksel_run *r, double *noise, size_t n) {
  return r->o.noise_pool == BSURF_NOISE_POOL_GLOBAL ? pool_global(noise, n) : BSURF_OK;
}

/* Pass 3 (fnrm != NULL: only the first choices' normals, by row, no tied
 * record), or passes 3 and 4 into out. */
static bsurf_status ksel_select(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                                const double *noise, const double *bref, const double *bmref,
                                const double *fref, const double *fmref, double *fnrm, double *fmse,
                                bsurf_kselect_fields *out, bsurf_kselect_report *report) {
  const size_t n = nb->point_count, m = n ? n : 1;
  ksel_ctx c = ksel_ctx_of(r, xyz, nb);
  c.noise = (double *)noise; /* read only, by row */
  c.out = out;
  int *first = bsurf_alloc_array(m, sizeof(int));
  double *own = fnrm ? NULL : bsurf_alloc_array(m, 3 * sizeof(double));
  double *own_m = fmse ? NULL : bsurf_alloc_array(m, sizeof(double));
  double **tied = fnrm ? NULL : bsurf_alloc_array(m, sizeof(double *));
  bsurf_status st =
      first && (fmse || own_m) && (fnrm || (own && tied)) ? BSURF_OK : BSURF_ERR_NOMEM;
  c.first = first;
  c.fnrm = fnrm ? fnrm : own;
  c.tied = tied;
  c.fmse = fmse ? fmse : own_m;
  c.fref = fref ? fref : c.fnrm;
  c.fmref = fmref ? fmref : c.fmse;
  c.bref = bref; /* the empirical bias's references (kselect_lof.c), or none */
  c.bmref = bmref;
  bsurf_i_ksel_reset(r);
  /* progress is reported for pass 3 (the bulk of the work) */
  if (st == BSURF_OK) st = ksel_pass(r, &c, r->o.nd > 0 ? poly_point : select_point, 1);
  for (int t = 0; t < r->T && st == BSURF_OK; t++)
    if (r->scr[t].tie_nomem) st = BSURF_ERR_NOMEM;
  if (st == BSURF_OK && !fnrm) st = ksel_pass(r, &c, tie_point, 0);
  if (report && st == BSURF_OK && !fnrm)
    for (int t = 0; t < r->T; t++)
      report->unassessed += r->scr[t].none;
  bsurf_i_ksel_reset(r);
  free(first);
  free(own);
  free(own_m);
  free(tied);
  return st;
}

bsurf_status bsurf_ksel_first(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                              const double *noise, const double *bref, const double *bmref,
                              double *fnrm, double *fmse) {
  return ksel_select(r, xyz, nb, noise, bref, bmref, NULL, NULL, fnrm, fmse, NULL, NULL);
}

bsurf_status bsurf_ksel_choose(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                               const double *noise, const double *bref, const double *bmref,
                               const double *fref, const double *fmref, bsurf_kselect_fields *out,
                               bsurf_kselect_report *report) {
  BSURF_REQUIRE(!out->two_sheet || r->crit, "the run was opened without the two-sheet test");
  return ksel_select(r, xyz, nb, noise, bref, bmref, fref, fmref, NULL, NULL, out, report);
}

int bsurf_ksel_empirical(const bsurf_ksel_run *r) {
  return r->o.nd == 0; /* the PCA candidates' (kselect_lof.c) */
}

bsurf_status bsurf_select_k(const double *xyz, const bsurf_neighbors *nb,
                            const bsurf_kselect_options *opts, bsurf_kselect_fields *out,
                            bsurf_kselect_report *report) {
  if (report) memset(report, 0, sizeof *report);
  BSURF_REQUIRE(xyz && nb && nb->idx && opts && out && opts->ks,
                "xyz, nb, nb->idx, opts, opts->ks and out must not be NULL");
  bsurf_status st = bsurf_i_ksel_check(__func__, opts, nb->k);
  bsurf_ksel_run *r = NULL;
  if (st == BSURF_OK) st = bsurf_ksel_open(opts, nb->k, out->two_sheet != NULL, &r);
  if (st != BSURF_OK) return st;
  const size_t n = nb->point_count;
  if ((size_t)r->kmax > n) {
    bsurf_ksel_close(r);
    return BSURF_ERR_TOO_FEW_POINTS;
  }
  /* the noise passes, then the selection and the tie-break */
  double *s2 = bsurf_alloc_array(n, sizeof(double)), *noise = bsurf_alloc_array(n, sizeof(double));
  st = s2 && noise ? BSURF_OK : BSURF_ERR_NOMEM;
  if (st == BSURF_OK) st = bsurf_ksel_noise(r, xyz, nb, s2);
  if (st == BSURF_OK) st = bsurf_ksel_pool(r, xyz, nb, s2, noise);
  free(s2);
  if (st == BSURF_OK) st = bsurf_ksel_level(r, noise, n);
  /* the first choices without the empirical bias, its references where
   * the quadric does not fit (kselect_lof.c) */
  double *bref = NULL, *bmref = NULL;
  if (st == BSURF_OK && bsurf_ksel_empirical(r)) {
    bref = bsurf_alloc_array(n, 3 * sizeof(double));
    bmref = bsurf_alloc_array(n, sizeof(double));
    st = bref && bmref ? BSURF_OK : BSURF_ERR_NOMEM;
    if (st == BSURF_OK) st = bsurf_ksel_first(r, xyz, nb, noise, NULL, NULL, bref, bmref);
  }
  if (st == BSURF_OK)
    st = bsurf_ksel_choose(r, xyz, nb, noise, bref, bmref, NULL, NULL, out, report);
  free(bref);
  free(bmref);
  free(noise);
  bsurf_ksel_close(r);
  return st;
}
