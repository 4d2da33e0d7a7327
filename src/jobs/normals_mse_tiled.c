/* The MSE rule of `normals --select-k` tile by tile (docs/scaling.md,
 * "The MSE rule in stages"): the passes of bsurf_select_k (kselect_run.c)
 * each run on the tiles' core rows, every value a pass reads at a
 * neighbour carried from the previous stage in the halo rows, so that
 * every output byte is the in-memory run's.
 *
 *   stage 1 (K = K_max): each point's quadric residual variance s2 (pass 1;
 *     its fits use the point's own K_max neighbours, no more);
 *   stage 2 (K = K_max, s2 of every local point): each point's pooled noise
 *     (pass 2: a quantile of its K_max neighbours' s2, a 2-ring);
 *   the level: with the GLOBAL pool, the median of every point's pooled
 *     value, read back in index order (8 + 8 bytes per point in memory, on
 *     every rank);
 *   stage 3 (K = K_max): each point's first choice's normal (pass 3), kept
 *     with its noise;
 *   stage 3b (K = K_max, PCA candidates: bsurf_ksel_empirical): pass 3
 *     again with the empirical bias where the quadric does not fit, its
 *     references the neighbours' first choices of stage 3 (a 2-ring;
 *     kselect_lof.c), kept beside them;
 *   stage 4 (normals_job.c's tiled run, K = K_max): pass 3 again for the
 *     tied candidates (the references of stage 3), the tie-break (pass 4)
 *     with the neighbours' first choices from stage 3b (stage 3 without
 *     it), the two-sheet test and the bootstrap at the chosen K. */
#include "algo/algo.h"
#include "jobs/jobs.h"

#include <stdlib.h>
#include <string.h>

/* stage 3's values: the first choice's normal, its M, the noise; then
 * stage 3's normal and M again (stage 3b: its own first choice's in the
 * first four, stage 3's kept in the last four) */
#define SEL_COLS 9

typedef struct mse_stages {
  bsurf_ksel_run *run;
  int global;   /* one noise level for the cloud */
  double level; /* its variance */
} mse_stages;

static bsurf_status s2_run(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  (void)core;
  (void)sums;
  const mse_stages *m = user;
  return bsurf_ksel_noise(m->run, t->xyz, t->nb, t->values_out);
}

static bsurf_status pool_run(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  (void)core;
  (void)sums;
  const mse_stages *m = user;
  return bsurf_ksel_pool(m->run, t->xyz, t->nb, t->values, t->values_out);
}

/* stage 3: per core point its first choice's normal, its criterion M (the
 * tie-break's weight) and its noise */
static bsurf_status first_run(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  (void)core;
  (void)sums;
  const mse_stages *m = user;
  const size_t nc = t->core_count, k = (size_t)t->nb->k;
  double *noise = bsurf_alloc_array(nc ? nc : 1, sizeof(double));
  double *f = bsurf_alloc_array(nc ? nc : 1, 3 * sizeof(double));
  double *fm = bsurf_alloc_array(nc ? nc : 1, sizeof(double));
  bsurf_status st = noise && f && fm ? BSURF_OK : BSURF_ERR_NOMEM;
  for (size_t r = 0; r < nc && st == BSURF_OK; r++)
    noise[r] = m->global ? m->level : t->values[t->nb->idx[r * k]];
  if (st == BSURF_OK) st = bsurf_ksel_first(m->run, t->xyz, t->nb, noise, NULL, NULL, f, fm);
  for (size_t r = 0; r < nc && st == BSURF_OK; r++) {
    double *v = &t->values_out[SEL_COLS * r];
    memcpy(v, &f[3 * r], 3 * sizeof(double));
    v[3] = fm[r];
    v[4] = noise[r];
    memcpy(&v[5], &f[3 * r], 3 * sizeof(double));
    v[8] = fm[r];
  }
  free(noise);
  free(f);
  free(fm);
  return st;
}

/* stage 3b: pass 3 with the empirical bias, its references the
 * neighbours' stage 3 first choices; stage 3's own kept (kselect_lof.c) */
static bsurf_status emp_run(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  (void)core;
  (void)sums;
  const mse_stages *m = user;
  const size_t nc = t->core_count, nl = t->local_count, k = (size_t)t->nb->k;
  double *noise = bsurf_alloc_array(nc ? nc : 1, sizeof(double));
  double *f = bsurf_alloc_array(nc ? nc : 1, 3 * sizeof(double));
  double *fm = bsurf_alloc_array(nc ? nc : 1, sizeof(double));
  double *bref = bsurf_alloc_array(nl ? nl : 1, 3 * sizeof(double));
  double *bmref = bsurf_alloc_array(nl ? nl : 1, sizeof(double));
  bsurf_status st = noise && f && fm && bref && bmref ? BSURF_OK : BSURF_ERR_NOMEM;
  for (size_t l = 0; l < nl && st == BSURF_OK; l++) {
    memcpy(&bref[3 * l], &t->values[SEL_COLS * l + 5], 3 * sizeof(double));
    bmref[l] = t->values[SEL_COLS * l + 8];
  }
  for (size_t r = 0; r < nc && st == BSURF_OK; r++)
    noise[r] = t->values[SEL_COLS * (size_t)t->nb->idx[r * k] + 4];
  if (st == BSURF_OK) st = bsurf_ksel_first(m->run, t->xyz, t->nb, noise, bref, bmref, f, fm);
  for (size_t r = 0; r < nc && st == BSURF_OK; r++) {
    double *v = &t->values_out[SEL_COLS * r];
    const double *own = &t->values[SEL_COLS * (size_t)t->nb->idx[r * k]];
    memcpy(v, &f[3 * r], 3 * sizeof(double));
    v[3] = fm[r];
    v[4] = noise[r];
    memcpy(&v[5], &own[5], 4 * sizeof(double));
  }
  free(noise);
  free(f);
  free(fm);
  free(bref);
  free(bmref);
  return st;
}

/* One values-only stage. */
static bsurf_status mse_stage(const bsurf_job_io *io, bsurf_tile_ops *ops, mse_stages *m,
                              bsurf_status (*run)(void *, const bsurf_tile *, bsurf_cloud *,
                                                  double *),
                              const bsurf_tile_values *in, size_t nvalues, bsurf_tile_values *out,
                              bsurf_tile_report *tr, bsurf_failure *err) {
  ops->user = m;
  ops->run = run;
  ops->values_in = in;
  ops->nvalues = nvalues;
  ops->values_out = out;
  memset(tr, 0, sizeof *tr);
  return bsurf_tiles_run(io->input, io->output, ops, tr, err);
}

/* The level every rank takes from the pooled values read back (GLOBAL:
 * their median, in-memory pass 2b on the same array); the ranks agree on a
 * failure before the next collective run. */
static bsurf_status mse_level(const bsurf_job_io *io, mse_stages *m, const bsurf_tile_values *v) {
  bsurf_status st = BSURF_OK;
  if (m->global) {
    double *all = bsurf_alloc_array(v->count ? v->count : 1, sizeof(double));
    st = all ? bsurf_tile_values_read(v, 0, v->count, all) : BSURF_ERR_NOMEM;
    if (st == BSURF_OK) st = bsurf_ksel_level(m->run, all, v->count);
    if (st == BSURF_OK) m->level = v->count ? all[0] : 0;
    free(all);
  }
  if (io->comm && io->comm->max(io->comm->user, st != BSURF_OK) && st == BSURF_OK)
    st = BSURF_ERR_IO;
  return st;
}

bsurf_status bsurf_jobs_mse_stages(const bsurf_job_io *io, const bsurf_kselect_options *ko, int k,
                                   int threads, bsurf_progress_fn progress, void *progress_user,
                                   bsurf_ksel_run *run, bsurf_tile_values *sel,
                                   bsurf_tile_report *tr, bsurf_failure *err) {
  mse_stages m = {run, ko->noise_pool == BSURF_NOISE_POOL_GLOBAL, 0};
  bsurf_tile_values s2 = {-1, 0, 0}, pooled = {-1, 0, 0};
  bsurf_tile_ops ops;
  bsurf_jobs_tile_ops(&ops, io, k, threads, progress, progress_user, &m);
  bsurf_status st = mse_stage(io, &ops, &m, s2_run, NULL, 1, &s2, tr, err);
  if (st == BSURF_OK) st = mse_stage(io, &ops, &m, pool_run, &s2, 1, &pooled, tr, err);
  bsurf_tile_values_close(&s2);
  if (st == BSURF_OK) st = mse_level(io, &m, &pooled);
  if (!bsurf_ksel_empirical(run)) {
    if (st == BSURF_OK) st = mse_stage(io, &ops, &m, first_run, &pooled, SEL_COLS, sel, tr, err);
    bsurf_tile_values_close(&pooled);
    return st;
  }
  bsurf_tile_values first = {-1, 0, 0};
  if (st == BSURF_OK) st = mse_stage(io, &ops, &m, first_run, &pooled, SEL_COLS, &first, tr, err);
  bsurf_tile_values_close(&pooled);
  if (st == BSURF_OK) st = mse_stage(io, &ops, &m, emp_run, &first, SEL_COLS, sel, tr, err);
  bsurf_tile_values_close(&first);
  return st;
}

bsurf_status bsurf_jobs_mse_tile(const bsurf_tile *t, double **noise, double **fref, double **fmref,
                                 double **bref, double **bmref) {
  const size_t nc = t->core_count, nl = t->local_count, k = (size_t)t->nb->k;
  *noise = bsurf_alloc_array(nc ? nc : 1, sizeof(double));
  *fref = bsurf_alloc_array(nl ? nl : 1, 3 * sizeof(double));
  *fmref = bsurf_alloc_array(nl ? nl : 1, sizeof(double));
  *bref = bsurf_alloc_array(nl ? nl : 1, 3 * sizeof(double));
  *bmref = bsurf_alloc_array(nl ? nl : 1, sizeof(double));
  if (!*noise || !*fref || !*fmref || !*bref || !*bmref) {
    free(*noise);
    free(*fref);
    free(*fmref);
    free(*bref);
    free(*bmref);
    *noise = *fref = *fmref = *bref = *bmref = NULL;
    return BSURF_ERR_NOMEM;
  }
  for (size_t l = 0; l < nl; l++) {
    memcpy(&(*fref)[3 * l], &t->values[SEL_COLS * l], 3 * sizeof(double));
    (*fmref)[l] = t->values[SEL_COLS * l + 3];
    memcpy(&(*bref)[3 * l], &t->values[SEL_COLS * l + 5], 3 * sizeof(double));
    (*bmref)[l] = t->values[SEL_COLS * l + 8];
  }
  for (size_t r = 0; r < nc; r++)
    (*noise)[r] = t->values[SEL_COLS * (size_t)t->nb->idx[r * k] + 4];
  return BSURF_OK;
}
