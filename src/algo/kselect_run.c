/* The MSE rule's passes on the rows of a neighbourhood table (docs/normals.md,
 * "Choosing K"; docs/scaling.md for the tiles): bsurf_select_k on the whole
 * cloud; the same passes per tile for the tiled job
 * (src/jobs/normals_mse_tiled.c). */
#include "algo/kselect.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Where a pass stands in the caller's progress: the selection's pass
 * reports its rows done to r->o.progress; the passes before it (the noise
 * passes and the section test's: about 1.6 s per 50,000 points at two
 * threads, docs/python.md) report none done, (0, rows), and the passes
 * after it (the deferred points', the tie-break's) all done, after
 * every chunk as well, so that a caller can cancel them too without its
 * progress going back. With r->slots > 0 (bsurf_select_k) the range is
 * slots times the rows: each pass before the selection's reports its rows
 * in a range of its own while there is one before the last (the noise
 * fits' pass), the others hold where the last such pass ended, the
 * selection's pass reports in the last range and the passes after it hold
 * at the total. */
enum { KSEL_BEFORE, KSEL_REPORT, KSEL_AFTER };

/* A pass over nb's rows in their visit order (no result depends on it). */
static bsurf_status ksel_pass(bsurf_ksel_run *r, ksel_ctx *c, void (*fn)(void *, int, size_t),
                              int where) {
  uint32_t *owned = NULL;
  const uint32_t *order = bsurf_visit_order(c->nb, c->xyz, &owned);
  if (!order) return BSURF_ERR_NOMEM;
  const size_t rows = c->nb->point_count;
  /* the pass's range [base, base + rows) of total, or held at base */
  size_t base = where == KSEL_AFTER ? rows : 0, total = rows;
  int reports = where == KSEL_REPORT;
  if (r->slots > 0) {
    total = rows * (size_t)r->slots;
    if (where == KSEL_REPORT)
      base = rows * (size_t)(r->slots - 1);
    else if (where == KSEL_AFTER)
      base = total;
    else if (r->slot < r->slots - 1)
      base = rows * (size_t)r->slot++, reports = 1;
    else
      base = rows * (size_t)r->slot;
  }
  bsurf_progress_hold range = {r->o.progress, r->o.progress_user, base, total, reports ? rows : 0};
  bsurf_status st = bsurf_parallel_points_ordered(
      rows, order, r->T, fn, c, r->o.progress ? bsurf_progress_hold_cb : NULL, &range);
  free(owned);
  return st;
}

static ksel_ctx ksel_ctx_of(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb) {
  ksel_ctx c = {.xyz = xyz,
                .nb = nb,
                .o = &r->o,
                .kmax = r->kmax,
                .lof_z = ksel_level_z(r->o.nk), /* once a run, not per point */
                .disc_q = ksel_disc_level(r->kmax),
                .scr = r->scr,
                .sheet_crit = r->crit};
  ksel_section_levels(&c); /* once a run, not per point */
  return c;
}

bsurf_status bsurf_ksel_noise(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                              double *s2) {
  ksel_ctx c = ksel_ctx_of(r, xyz, nb);
  c.s2 = s2; /* by row */
  return ksel_pass(r, &c, noise_point, KSEL_BEFORE);
}

bsurf_status bsurf_ksel_pool(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                             const double *s2, double *noise) {
  ksel_ctx c = ksel_ctx_of(r, xyz, nb);
  c.s2 = (double *)s2; /* read only, by neighbour */
  c.noise = noise;
  return ksel_pass(r, &c, pool_point, KSEL_BEFORE);
}

bsurf_status bsurf_ksel_section_tests(bsurf_ksel_run *r, const double *xyz,
                                      const bsurf_neighbors *nb, double *s2) {
  ksel_ctx c = ksel_ctx_of(r, xyz, nb);
  c.s2 = s2; /* by row */
  return ksel_pass(r, &c, section_point, KSEL_BEFORE);
}

bsurf_status bsurf_ksel_section_flags(bsurf_ksel_run *r, const double *xyz,
                                      const bsurf_neighbors *nb, const double *s2,
                                      size_t *flagged) {
  const size_t n = nb->point_count;
  double *flag = bsurf_alloc_array(n ? n : 1, sizeof(double));
  if (!flag) return BSURF_ERR_NOMEM;
  ksel_ctx c = ksel_ctx_of(r, xyz, nb);
  c.s2 = (double *)s2; /* read only, by neighbour */
  c.noise = flag;
  bsurf_status st = ksel_pass(r, &c, section_flag_point, KSEL_BEFORE);
  *flagged = 0;
  for (size_t i = 0; i < n && st == BSURF_OK; i++)
    *flagged += flag[i] > 0;
  free(flag);
  return st;
}

bsurf_status bsurf_ksel_section_bound(const double *xyz, const bsurf_neighbors *nb,
                                      const bsurf_kselect_options *opts, size_t *bound) {
  *bound = 0;
  bsurf_ksel_run *r = NULL;
  bsurf_status st = bsurf_ksel_open(opts, nb->k, 0, &r);
  if (st != BSURF_OK) return st;
  const size_t n = nb->point_count;
  double *s2 = (size_t)r->kmax <= n ? bsurf_alloc_array(n, 2 * sizeof(double)) : NULL;
  st = (size_t)r->kmax > n ? BSURF_ERR_TOO_FEW_POINTS : s2 ? BSURF_OK : BSURF_ERR_NOMEM;
  if (st == BSURF_OK) st = bsurf_ksel_section_tests(r, xyz, nb, s2);
  if (st == BSURF_OK) st = bsurf_ksel_section_flags(r, xyz, nb, s2, bound);
  free(s2);
  bsurf_ksel_close(r);
  return st;
}

bsurf_status bsurf_ksel_level(const bsurf_ksel_run *r, double *noise, size_t n) {
  if (r->o.noise_pool == BSURF_NOISE_POOL_GLOBAL) return pool_global(noise, n);
  for (size_t i = 0; i < n; i++) /* in place: i <= 2 i */
    noise[i] = bsurf_ksel_point_level(&noise[2 * i]);
  return BSURF_OK;
}

/* The second pass 3 of a deferred selection (ksel_select, defer): the
 * points the first deferred, the others' choices standing. */
typedef struct ksel_redo {
  ksel_ctx c; /* first: select_point takes a ksel_ctx */
  const unsigned char *deferred;
} ksel_redo;

static void select_deferred(void *vctx, int thread, size_t i) {
  if (((const ksel_redo *)vctx)->deferred[i]) select_point(vctx, thread, i);
}

/* Pass 3 (fnrm != NULL: only the first choices' normals, by row, no tied
 * record), or passes 3 and 4 into out (fref, fmref given: the rows' own
 * first choices are written into them, at the rows' points, before pass 4).
 *
 * defer (in memory, bsurf_select_k, with the empirical bias; bref NULL):
 * the choices of bsurf_ksel_first followed by bsurf_ksel_choose with its
 * first choices as bref, at the cost of about one pass 3. The bias enters a
 * point's criterion only where the lack-of-fit gate fires (select_point:
 * emp), and the gate reads the point's own quadrics and noise, not the
 * references; so the first pass, without the bias, already makes every
 * other point's final choice and stores its tied record, and defers the
 * gated ones (c->deferred: their first choices kept as the references, no
 * tied record); a second pass chooses the deferred points again, with the
 * bias, against the references of the first. Each point's computation is
 * the one bsurf_ksel_choose makes: the results are the same bits. */
static bsurf_status ksel_select(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                                const double *noise, const double *bref, const double *bmref,
                                double *fref, double *fmref, double *fnrm, double *fmse, int defer,
                                bsurf_kselect_fields *out, bsurf_kselect_report *report) {
  const size_t n = nb->point_count, m = n ? n : 1;
  ksel_redo rd = {.c = ksel_ctx_of(r, xyz, nb)};
  ksel_ctx *c = &rd.c;
  c->noise = (double *)noise; /* read only, by row */
  c->out = out;
  int *first = bsurf_alloc_array(m, sizeof(int));
  double *own = fnrm ? NULL : bsurf_alloc_array(m, 3 * sizeof(double));
  double *own_m = fmse ? NULL : bsurf_alloc_array(m, sizeof(double));
  double **tied = fnrm ? NULL : bsurf_alloc_array(m, sizeof(double *));
  /* deferring: the gate's flags and the references of the bias, by point */
  unsigned char *deferred = defer ? bsurf_alloc_array(m, 1) : NULL;
  double *dref = defer ? bsurf_alloc_array(m, 3 * sizeof(double)) : NULL;
  double *dmref = defer ? bsurf_alloc_array(m, sizeof(double)) : NULL;
  bsurf_status st =
      first && (fmse || own_m) && (fnrm || (own && tied)) && (!defer || (deferred && dref && dmref))
          ? BSURF_OK
          : BSURF_ERR_NOMEM;
  c->first = first;
  c->fnrm = fnrm ? fnrm : own;
  c->tied = tied;
  c->fmse = fmse ? fmse : own_m;
  c->fref = fref ? fref : c->fnrm;
  c->fmref = fmref ? fmref : c->fmse;
  c->bref = bref; /* the empirical bias's references (kselect_lof.c), or none */
  c->bmref = bmref;
  c->deferred = deferred;
  bsurf_i_ksel_reset(r);
  /* pass 3 (the bulk of the work) advances the progress; the others hold
   * it (ksel_pass) */
  if (st == BSURF_OK) st = ksel_pass(r, c, r->o.nd > 0 ? poly_point : select_point, KSEL_REPORT);
  for (int t = 0; t < r->T && st == BSURF_OK; t++)
    if (r->scr[t].tie_nomem) st = BSURF_ERR_NOMEM;
  for (size_t i = 0; fref && st == BSURF_OK && i < n; i++) { /* row i's point: idx[i k] */
    const size_t p = nb->idx[i * (size_t)nb->k];
    memcpy(&fref[3 * p], &c->fnrm[3 * i], 3 * sizeof(double));
    fmref[p] = c->fmse[i];
  }
  size_t recount = 0; /* deferred points counted unassessed by the first pass */
  if (defer && st == BSURF_OK) {
    for (size_t i = 0; i < n; i++) {
      const size_t p = nb->idx[i * (size_t)nb->k];
      memcpy(&dref[3 * p], &c->fnrm[3 * i], 3 * sizeof(double));
      dmref[p] = c->fmse[i];
      recount += deferred[i] && !isfinite(c->fmse[i]); /* ksel_ties: M infinite */
    }
    c->bref = dref, c->bmref = dmref;
    c->deferred = NULL;
    rd.deferred = deferred;
    st = ksel_pass(r, c, select_deferred, KSEL_AFTER);
    for (int t = 0; t < r->T && st == BSURF_OK; t++)
      if (r->scr[t].tie_nomem) st = BSURF_ERR_NOMEM;
  }
  if (st == BSURF_OK && !fnrm) st = ksel_pass(r, c, tie_point, KSEL_AFTER);
  if (report && st == BSURF_OK && !fnrm) {
    for (int t = 0; t < r->T; t++)
      report->unassessed += r->scr[t].none;
    report->unassessed -= recount;
  }
  bsurf_i_ksel_reset(r);
  free(first);
  free(own);
  free(own_m);
  free(tied);
  free(deferred);
  free(dref);
  free(dmref);
  return st;
}

bsurf_status bsurf_ksel_first(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                              const double *noise, const double *bref, const double *bmref,
                              double *fnrm, double *fmse) {
  return ksel_select(r, xyz, nb, noise, bref, bmref, NULL, NULL, fnrm, fmse, 0, NULL, NULL);
}

bsurf_status bsurf_ksel_choose(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                               const double *noise, const double *bref, const double *bmref,
                               double *fref, double *fmref, bsurf_kselect_fields *out,
                               bsurf_kselect_report *report) {
  BSURF_REQUIRE(!out->two_sheet || r->crit, "the run was opened without the two-sheet test");
  return ksel_select(r, xyz, nb, noise, bref, bmref, fref, fmref, NULL, NULL, 0, out, report);
}

int bsurf_ksel_empirical(const bsurf_ksel_run *r) {
  return r->o.nd == 0; /* the PCA candidates' (kselect_lof.c) */
}

/* Passes 1, 2 and 2b on every point of the cloud (nb's rows): noise (2 n)
 * holds the level of each point, noise[0 .. n) (bsurf_ksel_level). */
static bsurf_status noise_passes(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                                 double *noise, size_t *sections) {
  const size_t n = nb->point_count;
  double *s2 = bsurf_alloc_array(n ? n : 1, 2 * sizeof(double));
  bsurf_status st = s2 ? BSURF_OK : BSURF_ERR_NOMEM;
  if (st == BSURF_OK) st = bsurf_ksel_noise(r, xyz, nb, s2);
  if (st == BSURF_OK) st = bsurf_ksel_pool(r, xyz, nb, s2, noise);
  free(s2);
  if (st == BSURF_OK && sections) *sections = bsurf_ksel_sections(noise, n);
  if (st == BSURF_OK) st = bsurf_ksel_level(r, noise, n);
  return st;
}

size_t bsurf_ksel_sections(const double *pooled, size_t n) {
  size_t ns = 0;
  for (size_t i = 0; i < n; i++)
    ns += !isnan(pooled[2 * i + 1]);
  return ns;
}

bsurf_status bsurf_ksel_cloud_noise(const double *xyz, const bsurf_neighbors *nb,
                                    const bsurf_kselect_options *opts, double *level,
                                    size_t *sections) {
  *level = NAN;
  *sections = 0;
  bsurf_ksel_run *r = NULL;
  bsurf_status st = bsurf_ksel_open(opts, nb->k, 0, &r);
  if (st != BSURF_OK) return st;
  const size_t n = nb->point_count;
  double *noise = (size_t)r->kmax <= n ? bsurf_alloc_array(n, 2 * sizeof(double)) : NULL;
  st = (size_t)r->kmax > n ? BSURF_ERR_TOO_FEW_POINTS
       : noise             ? noise_passes(r, xyz, nb, noise, sections)
                           : BSURF_ERR_NOMEM;
  if (st == BSURF_OK) *level = noise[0];
  free(noise);
  bsurf_ksel_close(r);
  return st;
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
  /* the progress in two ranges of n: the noise fits' pass, then the
   * selection's (the pooling between them, and the passes after the
   * selection, hold; ksel_pass). The trace build below runs the
   * selection's pass twice, each in the last range: its progress steps
   * back once (a developer's build only). */
  r->slots = 2;
  /* the noise passes, then the selection and the tie-break */
  double *noise = bsurf_alloc_array(n, 2 * sizeof(double));
  st = noise ? noise_passes(r, xyz, nb, noise, NULL) : BSURF_ERR_NOMEM;
  /* the selection and the tie-break: with the empirical bias where the
   * quadric does not fit (kselect_lof.c), its references the first
   * choices without it */
#ifdef BSURF_KSEL_TRACE
  /* the developer's trace (kselect.c, scripts/ksel_replay.py) records every
   * point's last pass with its references: the two full passes, the same
   * bits as the deferred selection */
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
#else
  /* (the run was opened with the two-sheet test when out asks for it) */
  if (st == BSURF_OK)
    st = ksel_select(r, xyz, nb, noise, NULL, NULL, NULL, NULL, NULL, NULL, bsurf_ksel_empirical(r),
                     out, report);
#endif
  free(noise);
  bsurf_ksel_close(r);
  return st;
}
