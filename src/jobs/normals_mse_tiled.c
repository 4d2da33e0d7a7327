/* The MSE rule of `normals --select-k` tile by tile (docs/scaling.md,
 * "The MSE rule in stages"): the passes of bsurf_select_k (kselect_run.c)
 * run on the tiles' rows, every value a pass reads at a neighbour computed
 * in the same tile from the neighbour's own exact row (the tile's ring,
 * bsurf_tile_ops.ring_k) or carried from the previous stage, so that every
 * output byte is the in-memory run's.
 *
 *   stage 1 (K = K_max, ring_k = K_max): pass 1 (each point's quadric
 *     residual variance s2 and cross-section estimate, two values from its
 *     own K_max neighbours) on the core's and the ring's rows, so that every
 *     s2 the core reads is at hand, then pass 2 (the two pooled noises:
 *     quantiles of the K_max neighbours' s2) on the core's rows; the pooled
 *     values are kept (two per point);
 *   the level: with the GLOBAL pool, the median of the points' pooled
 *     values (pool_global: of the cloud's majority population), read back
 *     in index order (16 + 8 bytes per point in memory, on every rank);
 *   stage 2 (normals_job.c's tiled run, K = K_max, ring_k = noise_k): pass 3
 *     on the ring's rows (the first choices that the tie-break reads at the
 *     core's noise_k nearest outside the tile), passes 3 and 4 on the core's
 *     (bsurf_ksel_choose writes the core's own first choices where pass 4
 *     reads them), the two-sheet test and the bootstrap at the chosen K.
 *     With the empirical bias (PCA candidates: bsurf_ksel_empirical,
 *     kselect_lof.c) pass 3 reads the first choices of a pass 3 without it
 *     at the point's noise_k nearest: the tile then has two rings (ring_k =
 *     noise_k, the ring of the first ring too), pass 3 without the bias runs
 *     on every row (core and both rings: bsurf_select_k's first pass), then
 *     with it on the first ring's rows, then passes 3 and 4 on the core's.
 *
 * Until issue 25 these were four stages (s2, pool, first choices, choice),
 * each a tiled run with its passes over the input, its k-d trees and K_max
 * searches, and pass 3 ran twice per point; the rings cost the rows of the
 * points around each tile instead (docs/scaling.md, measured there). */
#include "algo/algo.h"
#include "jobs/jobs.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct mse_stages {
  bsurf_ksel_run *run;
} mse_stages;

/* Values indexed by local point from values by row (a row's point is its
 * first entry); NAN at the points that are not rows. */
static void by_point(const bsurf_neighbors *nb, size_t rows, const double *row_vals, size_t width,
                     double *point_vals, size_t nl) {
  for (size_t l = 0; l < nl * width; l++)
    point_vals[l] = NAN;
  for (size_t r = 0; r < rows; r++)
    memcpy(&point_vals[width * nb->idx[r * (size_t)nb->k]], &row_vals[width * r],
           width * sizeof(double));
}

/* A tile's first pass on the core's and the ring's rows (pass1: 2 values a
 * row, bsurf_ksel_noise or bsurf_ksel_section_tests), the values by local
 * point in *s2 (the caller frees it) for a second pass on the core's rows,
 * *core (nb with the core's rows only). */
static bsurf_status rows_pass(const mse_stages *m, const bsurf_tile *t,
                              bsurf_status (*pass1)(bsurf_ksel_run *, const double *,
                                                    const bsurf_neighbors *, double *),
                              double **s2, bsurf_neighbors *core) {
  const size_t nc = t->core_count, rows = nc + t->ring_count, nl = t->local_count;
  double *s2row = bsurf_alloc_array(rows ? rows : 1, 2 * sizeof(double));
  *s2 = bsurf_alloc_array(nl ? nl : 1, 2 * sizeof(double));
  bsurf_status st = s2row && *s2 ? BSURF_OK : BSURF_ERR_NOMEM;
  if (st == BSURF_OK) st = pass1(m->run, t->xyz, t->nb, s2row);
  if (st == BSURF_OK) by_point(t->nb, rows, s2row, 2, *s2, nl);
  *core = *t->nb;
  core->point_count = nc;
  free(s2row);
  return st;
}

/* stage 1: s2 of the core and the ring, the core's pooled noise */
static bsurf_status noise_run(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  (void)core;
  (void)sums;
  const mse_stages *m = user;
  double *s2 = NULL;
  bsurf_neighbors cnb;
  bsurf_status st = rows_pass(m, t, bsurf_ksel_noise, &s2, &cnb);
  if (st == BSURF_OK) st = bsurf_ksel_pool(m->run, t->xyz, &cnb, s2, t->values_out);
  free(s2);
  return st;
}

/* the section test alone (bsurf_jobs_section_bound): on the core's and the
 * ring's rows, then the core's flags, counted in sums[0] */
static bsurf_status section_run(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  (void)core;
  const mse_stages *m = user;
  double *s2 = NULL;
  bsurf_neighbors cnb;
  size_t flagged = 0;
  bsurf_status st = rows_pass(m, t, bsurf_ksel_section_tests, &s2, &cnb);
  if (st == BSURF_OK) st = bsurf_ksel_section_flags(m->run, t->xyz, &cnb, s2, &flagged);
  sums[0] += (double)flagged;
  free(s2);
  return st;
}

bsurf_status bsurf_jobs_section_bound(const bsurf_job_io *io, int k, int threads,
                                      bsurf_progress_fn progress, void *progress_user,
                                      bsurf_ksel_run *run, size_t *bound, bsurf_tile_report *tr,
                                      bsurf_failure *err) {
  mse_stages m = {run};
  bsurf_tile_ops ops;
  bsurf_jobs_tile_ops(&ops, io, k, threads, progress, progress_user, &m);
  ops.run = section_run;
  ops.nsums = 1;
  ops.ring_k = k;
  double sum = 0;
  memset(tr, 0, sizeof *tr);
  tr->sums = &sum;
  bsurf_status st = bsurf_tiles_run(io->input, io->output, &ops, tr, err);
  *bound = st == BSURF_OK ? (size_t)sum : 0;
  return st;
}

bsurf_status bsurf_jobs_mse_stages(const bsurf_job_io *io, const bsurf_kselect_options *ko, int k,
                                   int threads, bsurf_progress_fn progress, void *progress_user,
                                   bsurf_ksel_run *run, bsurf_tile_values *pooled, double *level,
                                   size_t *sections, bsurf_tile_report *tr, bsurf_failure *err) {
  mse_stages m = {run};
  bsurf_tile_ops ops;
  bsurf_jobs_tile_ops(&ops, io, k, threads, progress, progress_user, &m);
  ops.run = noise_run;
  ops.nvalues = 2; /* the quadric's and the cross-section's pools (bsurf_ksel_pool) */
  ops.values_out = pooled;
  ops.ring_k = k;
  memset(tr, 0, sizeof *tr);
  bsurf_status st = bsurf_tiles_run(io->input, io->output, &ops, tr, err);
  /* the level every rank takes from the pooled values read back (GLOBAL:
   * their median, in-memory pass 2b on the same array); the ranks agree on
   * a failure before the next collective run */
  *level = 0;
  if (sections) *sections = 0;
  if (st == BSURF_OK && (ko->noise_pool == BSURF_NOISE_POOL_GLOBAL || sections)) {
    double *all = bsurf_alloc_array(pooled->count ? pooled->count : 1, 2 * sizeof(double));
    st = all ? bsurf_tile_values_read(pooled, 0, pooled->count, all) : BSURF_ERR_NOMEM;
    if (st == BSURF_OK && sections) *sections = bsurf_ksel_sections(all, pooled->count);
    if (st == BSURF_OK && ko->noise_pool == BSURF_NOISE_POOL_GLOBAL) {
      st = bsurf_ksel_level(run, all, pooled->count);
      if (st == BSURF_OK) *level = pooled->count ? all[0] : 0;
    }
    free(all);
    if (io->comm && io->comm->max(io->comm->user, st != BSURF_OK) && st == BSURF_OK)
      st = BSURF_ERR_IO;
  }
  return st;
}

int bsurf_jobs_mse_rings(const bsurf_ksel_run *run) {
  return bsurf_ksel_empirical(run) ? 2 : 1;
}

bsurf_status bsurf_jobs_mse_tile(bsurf_ksel_run *run, const bsurf_tile *t, int global, double level,
                                 double **noise, double **fref, double **fmref, double **bref,
                                 double **bmref) {
  const size_t nc = t->core_count, nr = t->ring_count, n1 = t->ring_first, nl = t->local_count,
               k = (size_t)t->nb->k, rows = nc + nr;
  const int emp = bsurf_ksel_empirical(run);
  *noise = bsurf_alloc_array(rows ? rows : 1, sizeof(double));
  *fref = bsurf_alloc_array(nl ? nl : 1, 3 * sizeof(double));
  *fmref = bsurf_alloc_array(nl ? nl : 1, sizeof(double));
  *bref = emp ? bsurf_alloc_array(nl ? nl : 1, 3 * sizeof(double)) : NULL;
  *bmref = emp ? bsurf_alloc_array(nl ? nl : 1, sizeof(double)) : NULL;
  double *rf = bsurf_alloc_array(rows ? rows : 1, 3 * sizeof(double));
  double *rm = bsurf_alloc_array(rows ? rows : 1, sizeof(double));
  bsurf_status st = *noise && *fref && *fmref && (!emp || (*bref && *bmref)) && rf && rm
                        ? BSURF_OK
                        : BSURF_ERR_NOMEM;
  for (size_t r = 0; r < rows && st == BSURF_OK; r++) /* by row */
    (*noise)[r] = global ? level : bsurf_ksel_point_level(&t->values[2 * t->nb->idx[r * k]]);
  if (st == BSURF_OK && emp) {
    /* the first choices without the bias at every row's point: the
     * references of the bias where the core and the first ring read them */
    st = bsurf_ksel_first(run, t->xyz, t->nb, *noise, NULL, NULL, rf, rm);
    if (st == BSURF_OK) {
      by_point(t->nb, rows, rf, 3, *bref, nl);
      by_point(t->nb, rows, rm, 1, *bmref, nl);
    }
  }
  /* the first ring's first choices (pass 3 on its rows, with the bias's
   * references), by local point; the core's own are written by
   * bsurf_ksel_choose */
  bsurf_neighbors ring = {emp ? n1 : nr, t->nb->k, t->nb->idx + nc * k, 0.0, NULL};
  if (st == BSURF_OK && ring.point_count)
    st = bsurf_ksel_first(run, t->xyz, &ring, *noise + nc, *bref, *bmref, rf, rm);
  if (st == BSURF_OK) {
    by_point(&ring, ring.point_count, rf, 3, *fref, nl);
    by_point(&ring, ring.point_count, rm, 1, *fmref, nl);
  }
  free(rf);
  free(rm);
  if (st != BSURF_OK) {
    free(*noise);
    free(*fref);
    free(*fmref);
    free(*bref);
    free(*bmref);
    *noise = *fref = *fmref = *bref = *bmref = NULL;
  }
  return st;
}
