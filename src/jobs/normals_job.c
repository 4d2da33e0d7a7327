/* The `normals` job (issue 18): normals with bootstrap confidence (thesis
 * chapter 5), the per-point choice of K and degree (5.5), smoothing and
 * orientation, in memory or tile by tile, through one call. The command
 * line parses its options and prints the summary; everything between is
 * here. */
#include "jobs/jobs.h"
#include "algo/algo.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAX_CANDIDATES 1024

bsurf_normals_job_options bsurf_normals_job_options_default(void) {
  bsurf_normals_job_options o;
  memset(&o, 0, sizeof o);
  o.normals = bsurf_normal_options_default();
  o.select_rule = BSURF_KSELECT_AUTO;
  o.noise_k = bsurf_kselect_options_default().noise_k;
  o.alpha = 0.1;
  o.sigma_d = 0;
  o.sigma_nu = NAN;
  o.orient = BSURF_ORIENT_NONE;
  return o;
}

/* What one run computes (every candidate K and degree), shared by the
 * in-memory run and the tiles. */
typedef struct normals_job {
  bsurf_normal_options no;
  int test_error, selecting, select_k, select_degree, k_ref, kmax;
  bsurf_kselect_options ksel; /* rule MSE: bsurf_select_k chooses K */
  int ks[MAX_CANDIDATES], nk, ds[4], nd;
  bsurf_normals_curve_row *curve; /* in memory: the candidates' means */
  size_t curve_rows;
  const double *truth; /* the curve's true normals, or NULL */
  /* a tiled run of the MSE rule's last stage (normals_mse_tiled.c): the
   * run, and per tile the noise by core row and the neighbours' first
   * choices; NULL in memory */
  bsurf_ksel_run *mse_run;
  const double *mse_noise, *mse_bref, *mse_bmref;
  double *mse_fref, *mse_fmref; /* the ring's; bsurf_ksel_choose adds the core's */
  double mse_level;             /* the GLOBAL pool's noise level */
} normals_job;

/* Per-point results (n long, x 3 for vectors). */
typedef struct normals_bufs {
  double *normals, *var, *err, *ref, *cand_n, *cand_v, *cand_e, *best_e, *ksel, *dsel, *sheet;
} normals_bufs;

static void normals_bufs_free(normals_bufs *b) {
  free(b->normals);
  free(b->var);
  free(b->err);
  free(b->ref);
  free(b->cand_n);
  free(b->cand_v);
  free(b->cand_e);
  free(b->best_e);
  free(b->ksel);
  free(b->dsel);
  free(b->sheet);
  memset(b, 0, sizeof *b);
}

static bsurf_status normals_bufs_alloc(normals_bufs *b, const normals_job *job, size_t n) {
  memset(b, 0, sizeof *b);
  const size_t m = n ? n : 1;
  b->normals = bsurf_alloc_array(m * 3, sizeof(double)); /* large: huge pages (status.c) */
  /* without replicates no variance is written out: calloc's untouched pages */
  b->var =
      job->no.bootstrap >= 2 ? bsurf_calloc_array(m, sizeof(double)) : calloc(m, sizeof(double));
  /* calloc: pages that are never written (no test error) are never touched */
  b->err = calloc(m, sizeof(double));
  int ok = b->normals && b->var && b->err;
  if (job->test_error && job->ksel.rule != BSURF_KSELECT_MSE)
    ok = ok && (b->ref = malloc(m * 3 * sizeof(double)));
  if (job->selecting) {
    b->cand_n = malloc(m * 3 * sizeof(double));
    b->cand_v = calloc(m, sizeof(double));
    b->cand_e = calloc(m, sizeof(double));
    b->best_e = malloc(m * sizeof(double));
    b->ksel = calloc(m, sizeof(double));
    b->dsel = calloc(m, sizeof(double));
    ok = ok && b->cand_n && b->cand_v && b->cand_e && b->best_e && b->ksel && b->dsel;
    if (job->ksel.rule == BSURF_KSELECT_MSE) ok = ok && (b->sheet = calloc(m, sizeof(double)));
    for (size_t i = 0; ok && i < n; i++)
      b->best_e[i] = INFINITY;
  }
  if (!ok) normals_bufs_free(b);
  return ok ? BSURF_OK
            : bsurf_set_message(BSURF_ERR_NOMEM, "out of memory (normals of %zu points)", n);
}

/* One row of the curve: a candidate's means over the points (sums in point
 * order). */
static void curve_row(normals_job *job, int k, int degree, double se, double sv, double sa,
                      size_t n) {
  bsurf_normals_curve_row *r = &job->curve[job->curve_rows++];
  r->k = k;
  r->degree = degree;
  r->mean_normal_err = se / (double)n;
  r->mean_normal_var = sv / (double)n;
  r->mean_angle_err = job->truth ? sa / (double)n : NAN;
}

/* Selection by the test error: every candidate in one visit of each point
 * (bsurf_select_normals_k for PCA, bsurf_select_normals_kd for the
 * polynomial's K and degree); with a curve each candidate's means. */
static bsurf_status normals_select_nested(normals_job *job, const double *xyz,
                                          const bsurf_neighbors *nb, const bsurf_normal_options *no,
                                          const double *ref, normals_bufs *b,
                                          bsurf_normal_report *total) {
  const size_t n = nb->point_count;
  const int poly = no->fit == BSURF_NORMAL_POLY;
  const int nk = job->nk, nd = poly ? job->nd : 1, nc = nk * nd;
  const int curve = job->curve != NULL;
  int *ksel = malloc((n ? n : 1) * sizeof *ksel);
  int *dsel = poly ? malloc((n ? n : 1) * sizeof *dsel) : NULL;
  double *ce = NULL, *cv = NULL, *cn = NULL;
  if (curve) {
    ce = bsurf_alloc_array(n * (size_t)nc, sizeof *ce);
    cv = bsurf_alloc_array(n * (size_t)nc, sizeof *cv);
    cn = job->truth ? bsurf_alloc_array(n * (size_t)nc * 3, sizeof *cn) : NULL;
  }
  bsurf_status st = BSURF_ERR_NOMEM;
  if (ksel && (!poly || dsel) && (!curve || (ce && cv && (!job->truth || cn)))) {
    bsurf_normal_select_fields out = {b->normals, b->var, b->err, ksel, ce, cv, cn};
    st = poly ? bsurf_select_normals_kd(xyz, nb, ref, no, job->ks, nk, job->ds, nd, &out, dsel,
                                        total)
              : bsurf_select_normals_k(xyz, nb, ref, no, job->ks, nk, &out, total);
  }
  if (st == BSURF_OK) {
    for (size_t i = 0; i < n; i++) {
      b->ksel[i] = ksel[i];
      b->dsel[i] = poly ? dsel[i] : no->degree;
      b->best_e[i] = b->err[i];
    }
    for (int a = 0; curve && a < nc; a++) {
      double se = 0, sv = 0, sa = 0;
      for (size_t i = 0; i < n; i++) {
        se += ce[i * nc + a];
        sv += cv[i * nc + a];
        if (job->truth) sa += bsurf_normal_angle(&cn[(i * nc + a) * 3], &job->truth[3 * i]);
      }
      curve_row(job, job->ks[a / nd], poly ? job->ds[a % nd] : 1, se, sv, sa, n);
    }
  }
  free(ksel);
  free(dsel);
  free(ce);
  free(cv);
  free(cn);
  return st;
}

/* Keeps, per point, the candidate with the smallest normal_err (ties keep
 * the smaller K, then degree). */
static void normals_keep(const normals_job *job, normals_bufs *b, const bsurf_normal_options *o,
                         size_t n, double *se, double *sv, double *sa) {
  for (size_t i = 0; i < n; i++) {
    *se += b->cand_e[i];
    *sv += b->cand_v[i];
    if (job->truth) *sa += bsurf_normal_angle(&b->cand_n[3 * i], &job->truth[3 * i]);
    if (b->cand_e[i] < b->best_e[i]) {
      b->best_e[i] = b->cand_e[i];
      memcpy(&b->normals[3 * i], &b->cand_n[3 * i], 3 * sizeof(double));
      b->var[i] = b->cand_v[i];
      b->err[i] = b->cand_e[i];
      b->ksel[i] = o->k;
      b->dsel[i] = o->degree;
    }
  }
}

/* The reference normals (or ref_in, the first stage's of a tiled run: one
 * per point of xyz), then every candidate (K, degree), keeping per point
 * the one with the smallest normal_err. */
static bsurf_status normals_compute(normals_job *job, const double *xyz, const bsurf_neighbors *nb,
                                    const uint64_t *point_index, const double *ref_in,
                                    normals_bufs *b, bsurf_normal_report *total) {
  const size_t n = nb->point_count;
  bsurf_normal_options no = job->no;
  no.point_index = point_index;
  bsurf_normal_report rep;
  bsurf_status st;
  memset(total, 0, sizeof *total);
  const double *ref = ref_in ? ref_in : b->ref;
  if (b->ref && !ref_in) { /* NULL with the MSE rule: it needs no reference */
    /* reference normals n_j of Eq. 5.10: single PCA fits on a fixed K */
    bsurf_normal_options ro = no;
    ro.fit = BSURF_NORMAL_PCA;
    ro.k = job->k_ref;
    ro.bootstrap = 0;
    bsurf_normal_fields rf = {b->ref, NULL, NULL};
    st = bsurf_estimate_normals(xyz, nb, NULL, &ro, &rf, NULL);
    if (st != BSURF_OK) return st;
  }
  const int selecting = job->selecting;
  if (selecting && job->ksel.rule != BSURF_KSELECT_MSE) /* nested candidates, one pass */
    return normals_select_nested(job, xyz, nb, &no, ref, b, total);
  if (job->ksel.rule == BSURF_KSELECT_MSE) {
    int *kmse = NULL, *dmse = NULL; /* the chosen K (and degree) */
    bsurf_kselect_options ko = job->ksel;
    ko.progress = no.progress;
    ko.progress_user = no.progress_user;
    const int poly = ko.nd > 0;
    /* the polynomial's normal is always re-estimated in the thesis's frame
     * of the chosen K (the rule's fits share the K_max frame) */
    int bootstrap = no.bootstrap >= 2 || poly;
    int *sheet = NULL;
    if (!(kmse = malloc((n ? n : 1) * sizeof(int))) ||
        !(sheet = malloc((n ? n : 1) * sizeof(int))) ||
        (poly && !(dmse = malloc((n ? n : 1) * sizeof(int))))) {
      free(kmse);
      free(sheet);
      return BSURF_ERR_NOMEM;
    }
    bsurf_kselect_fields kf = {bootstrap ? NULL : b->normals, kmse, b->err, NULL, sheet, dmse};
    st = job->mse_run ? bsurf_ksel_choose(job->mse_run, xyz, nb, job->mse_noise, job->mse_bref,
                                          job->mse_bmref, job->mse_fref, job->mse_fmref, &kf, NULL)
                      : bsurf_select_k(xyz, nb, &ko, &kf, NULL);
    for (size_t i = 0; i < n; i++)
      b->ksel[i] = kmse[i], b->sheet[i] = sheet[i], b->dsel[i] = poly ? dmse[i] : no.degree;
    free(sheet);
    if (st == BSURF_OK && bootstrap) {
      /* the B replicates at each point's chosen K (and degree) only, in
       * one pass: the bits of one pass per candidate kept at the points
       * that chose it, a fifteenth of the work with 15 candidates (issue
       * 25) */
      bsurf_normal_options o = no;
      o.k = job->ks[job->nk - 1];
      for (int d = 0; poly && d < job->nd; d++)
        if (d == 0 || job->ds[d] > o.degree) o.degree = job->ds[d];
      bsurf_normal_fields out = {b->normals, no.bootstrap >= 2 ? b->var : NULL, NULL};
      st = bsurf_estimate_normals_at_kd(xyz, nb, &o, kmse, dmse, &out, total);
    }
    free(kmse);
    free(dmse);
    return st;
  }
  for (int a = 0; a < job->nk; a++) {
    for (int d = 0; d < job->nd; d++) {
      bsurf_normal_options o = no;
      o.k = job->ks[a];
      o.degree = job->ds[d];
      bsurf_normal_fields out = {selecting ? b->cand_n : b->normals, selecting ? b->cand_v : b->var,
                                 job->test_error ? (selecting ? b->cand_e : b->err) : NULL};
      st = bsurf_estimate_normals(xyz, nb, ref, &o, &out, &rep);
      if (st != BSURF_OK) return st;
      total->replicates_total += rep.replicates_total;
      total->replicates_skipped += rep.replicates_skipped;
      total->degree_reduced += rep.degree_reduced;
      total->degenerate += rep.degenerate;
      if (!selecting) continue;
      double se = 0, sv = 0, sa = 0;
      normals_keep(job, b, &o, n, &se, &sv, &sa);
      if (job->curve)
        curve_row(job, o.k, no.fit == BSURF_NORMAL_POLY ? o.degree : 1, se, sv, sa, n);
    }
  }
  return BSURF_OK;
}

/* The output fields of a run, in the order they are added to the cloud;
 * which[t]: the buffer of field t (0 var, 1 err, 2 ksel, 3 dsel, 4 sheet).
 * At most BSURF_NORMALS_JOB_FIELDS = 4: two_sheet comes with the MSE rule
 * where the degree is not selected (with B >= 2, normal_var, normal_err,
 * k_selected and degree_selected fill the four). */
static int normals_field_names(const normals_job *job, const char **names, bsurf_type *types,
                               int *which) {
  int nf = 0;
  if (job->no.bootstrap >= 2) names[nf] = "normal_var", which[nf] = 0, types[nf++] = BSURF_FLOAT32;
  if (job->test_error) names[nf] = "normal_err", which[nf] = 1, types[nf++] = BSURF_FLOAT32;
  if (job->select_k) names[nf] = "k_selected", which[nf] = 2, types[nf++] = BSURF_UINT16;
  if (job->select_degree) names[nf] = "degree_selected", which[nf] = 3, types[nf++] = BSURF_UINT8;
  if (job->select_k && job->ksel.rule == BSURF_KSELECT_MSE && nf < BSURF_NORMALS_JOB_FIELDS)
    names[nf] = "two_sheet", which[nf] = 4, types[nf++] = BSURF_UINT8;
  return nf;
}

/* Normals replaced (FLOAT32 when the input had none), fields added; with b,
 * the values copied in, or with move (a cloud that owns its arrays) and no
 * normals in c, b's array moved in (no copy; it then belongs to c). */
static bsurf_status normals_store(const normals_job *job, bsurf_cloud *c, normals_bufs *b,
                                  int move) {
  const size_t n = c->point_count;
  move = move && b && !c->normals;
  if (!c->normals) c->normal_type = BSURF_FLOAT32;
  if (move) {
    c->normals = b->normals;
    b->normals = NULL;
  } else if (!c->normals) {
    c->normals = bsurf_calloc_array(n ? n * 3 : 3, sizeof(double));
    if (!c->normals) return BSURF_ERR_NOMEM;
  }
  if (b && !move) memcpy(c->normals, b->normals, n * 3 * sizeof(double));
  const char *names[4];
  bsurf_type types[4];
  int which[4];
  const double *vals[5] = {b ? b->var : NULL, b ? b->err : NULL, b ? b->ksel : NULL,
                           b ? b->dsel : NULL, b ? b->sheet : NULL};
  int nf = normals_field_names(job, names, types, which);
  for (int t = 0; t < nf; t++) {
    bsurf_field *fl = bsurf_cloud_add_field(c, names[t], types[t]);
    if (!fl) return BSURF_ERR_NOMEM;
    if (b) memcpy(fl->values, vals[which[t]], n * sizeof(double));
  }
  return BSURF_OK;
}

/* ---- tiled (bsurf_tiles_run) ---- */

#define NORMALS_SUMS 8 /* replicates total, skipped, degree reduced, degenerate, 4 field sums */

static bsurf_status normals_prepare(void *user, bsurf_cloud *c) {
  return normals_store(user, c, NULL, 0);
}

static bsurf_status normals_run(void *user, const bsurf_tile *tile, bsurf_cloud *core,
                                double *sums) {
  normals_job *job = user;
  normals_bufs b;
  bsurf_status st = normals_bufs_alloc(&b, job, tile->core_count);
  if (st != BSURF_OK) return st;
  bsurf_normal_report total;
  double *noise = NULL, *fref = NULL, *fmref = NULL, *bref = NULL, *bmref = NULL;
  /* the MSE rule: the noise and the neighbours' first choices, from the
   * first stages (normals_mse_tiled.c) */
  if (job->mse_run && (st = bsurf_jobs_mse_tile(
                           job->mse_run, tile, job->ksel.noise_pool == BSURF_NOISE_POOL_GLOBAL,
                           job->mse_level, &noise, &fref, &fmref, &bref, &bmref)) != BSURF_OK) {
    normals_bufs_free(&b);
    return st;
  }
  job->mse_noise = noise;
  job->mse_fref = fref;
  job->mse_fmref = fmref;
  /* the empirical bias's references (PCA candidates; NULL otherwise) */
  job->mse_bref = bref;
  job->mse_bmref = bmref;
  /* with normal_err: the reference normals of every local point, from the
   * first stage (normals_ref_run); the core's rows (the MSE rule's ring
   * follows them) */
  bsurf_neighbors cnb = *tile->nb;
  cnb.point_count = tile->core_count;
  st = normals_compute(job, tile->xyz, &cnb, tile->point_index,
                       job->test_error && !job->mse_run ? tile->values : NULL, &b, &total);
  free(noise);
  free(fref);
  free(fmref);
  free(bref);
  free(bmref);
  if (st == BSURF_OK) st = normals_store(job, core, &b, 0);
  if (st == BSURF_OK) {
    bsurf_jobs_add_counts(sums, total.replicates_total, total.replicates_skipped,
                          total.degree_reduced, total.degenerate);
    const char *names[4];
    bsurf_type types[4];
    int which[4];
    int nf = normals_field_names(job, names, types, which);
    for (int t = 0; t < nf; t++)
      sums[4 + t] += bsurf_jobs_mean(bsurf_cloud_field(core, names[t])->values, core->point_count) *
                     (double)core->point_count;
  }
  normals_bufs_free(&b);
  return st;
}

/* The first stage of a tiled run with normal_err: the reference normals of
 * Eq. 5.10 (the in-memory run's: single PCA fits on the first k_ref
 * neighbours) of every point, kept by the engine for the second stage's
 * halos (docs/scaling.md). */
static bsurf_status normals_ref_run(void *user, const bsurf_tile *tile, bsurf_cloud *core,
                                    double *sums) {
  (void)core;
  (void)sums;
  const normals_job *job = user;
  bsurf_normal_options ro = job->no;
  ro.fit = BSURF_NORMAL_PCA;
  ro.k = job->k_ref;
  ro.bootstrap = 0;
  ro.point_index = tile->point_index;
  bsurf_normal_fields rf = {tile->values_out, NULL, NULL};
  return bsurf_estimate_normals(tile->xyz, tile->nb, NULL, &ro, &rf, NULL);
}

static bsurf_status normals_tiled(const bsurf_job_io *io, normals_job *job,
                                  bsurf_normals_job_summary *s, bsurf_failure *err) {
  const bsurf_progress_fn progress = job->no.progress;
  void *const progress_user = job->no.progress_user;
  job->no.progress = NULL; /* the engine reports the tiles */
  job->no.progress_user = NULL;
  double sums[NORMALS_SUMS] = {0};
  bsurf_status st = BSURF_OK;
  /* with normal_err, two stages: the reference normals of every point,
   * then the tiles with those of their halos */
  bsurf_tile_values refs = {-1, 0, 0};
  bsurf_tile_report tr;
  memset(&tr, 0, sizeof tr);
  bsurf_tile_ops ops;
  if (job->ksel.rule == BSURF_KSELECT_MSE) { /* two stages (normals_mse_tiled.c) */
    st = bsurf_ksel_open(&job->ksel, job->kmax, 1, &job->mse_run);
    if (st == BSURF_OK)
      st =
          bsurf_jobs_mse_stages(io, &job->ksel, job->kmax, job->no.threads, progress, progress_user,
                                job->mse_run, &refs, &job->mse_level, NULL, &tr, err);
  } else if (job->test_error) {
    bsurf_jobs_tile_ops(&ops, io, job->k_ref, job->no.threads, progress, progress_user, job);
    ops.run = normals_ref_run;
    ops.nvalues = 3;
    ops.values_out = &refs;
    st = bsurf_tiles_run(io->input, io->output, &ops, &tr, err);
  }
  if (st == BSURF_OK) {
    bsurf_jobs_tile_ops(&ops, io, job->kmax, job->no.threads, progress, progress_user, job);
    ops.prepare = normals_prepare;
    ops.run = normals_run;
    ops.nsums = NORMALS_SUMS;
    ops.values_in = job->test_error ? &refs : NULL;
    /* the MSE rule's tie-break reads the first choices of the noise_k
     * nearest: the tiles' rings */
    if (job->mse_run)
      ops.ring_k = job->ksel.noise_k, ops.rings = bsurf_jobs_mse_rings(job->mse_run);
    memset(&tr, 0, sizeof tr);
    tr.sums = sums;
    st = bsurf_tiles_run(io->input, io->output, &ops, &tr, err);
  }
  bsurf_tile_values_close(&refs);
  bsurf_ksel_close(job->mse_run);
  job->mse_run = NULL;
  s->tile_points = io->tile_points;
  bsurf_jobs_tiled_numbers(&tr, &s->points, &s->h, &s->duplicates, &s->tiles, &s->bad_point);
  if (st != BSURF_OK) return st;
  bsurf_normal_report *r = &s->report;
  bsurf_jobs_counts(sums, &r->replicates_total, &r->replicates_skipped, &r->degree_reduced,
                    &r->degenerate);
  bsurf_jobs_means(s->means, sums + 4, s->field_count, s->points);
  return BSURF_OK;
}

/* ---- in memory ---- */

/* A run that needs each point's neighbours only for its own estimate (no
 * reference normals of the neighbours, no smoothing, no orientation):
 * estimated as the search goes, without the lists (normals_streamed). */
static int normals_streamable(const normals_job *job, const bsurf_normals_job_options *o) {
  return !job->test_error && !job->selecting && !job->curve && o->smooth_iterations == 0 &&
         o->orient == BSURF_ORIENT_NONE;
}

/* bsurf_jobs_neighbors + normals_compute in one pass: the same rows, the
 * same per-point estimate (bsurf_estimate_normals_streamed). */
static bsurf_status normals_streamed(normals_job *job, const bsurf_cloud *c, normals_bufs *b,
                                     bsurf_normals_job_summary *s) {
  const size_t n = c->point_count;
  if (n < (size_t)job->kmax)
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS, "has %zu points, fewer than K = %d", n,
                             job->kmax);
  bsurf_normal_fields out = {b->normals, job->no.bootstrap >= 2 ? b->var : NULL, NULL};
  return bsurf_estimate_normals_streamed(c->xyz, n, job->kmax, &job->no, &out, &s->report, &s->h,
                                         &s->duplicates);
}

static bsurf_status normals_in_memory(const bsurf_job_io *io, const bsurf_normals_job_options *o,
                                      normals_job *job, bsurf_normals_job_summary *s) {
  bsurf_cloud *c = io->cloud;
  const size_t n = c->point_count;
  const int streamed = normals_streamable(job, o);
  bsurf_neighbors nb;
  memset(&nb, 0, sizeof nb);
  bsurf_status st = BSURF_OK;
  if (!streamed) {
    st = bsurf_jobs_neighbors(c, job->kmax, job->no.threads, job->no.progress,
                              job->no.progress_user, &nb, &s->duplicates);
    if (st != BSURF_OK) return st;
    s->points = n;
    s->h = nb.h;
  }
  normals_bufs b;
  st = normals_bufs_alloc(&b, job, n);
  if (st == BSURF_OK)
    st = streamed ? normals_streamed(job, c, &b, s)
                  : normals_compute(job, c->xyz, &nb, NULL, NULL, &b, &s->report);
  if (st == BSURF_OK && streamed) s->points = n;
  s->curve_rows = job->curve_rows;
  if (st == BSURF_OK && o->smooth_iterations > 0) {
    /* auto: the threshold of the top 15% of normal_var (Table 5.2's split) */
    double sigma_nu = o->sigma_nu;
    if (isnan(sigma_nu) &&
        (job->no.bootstrap < 2 ||
         bsurf_quantile_split(b.var, n, 0.85, NULL, &sigma_nu, NULL, NULL) != BSURF_OK))
      sigma_nu = INFINITY;
    if (!(sigma_nu > 0)) sigma_nu = INFINITY; /* all variances 0: nothing to weigh */
    s->sigma_d = o->sigma_d > 0 ? o->sigma_d : s->h;
    s->sigma_nu = sigma_nu;
    st = bsurf_smooth_normals(c->xyz, &nb, job->no.k, b.normals,
                              job->no.bootstrap >= 2 ? b.var : NULL, o->smooth_iterations, o->alpha,
                              s->sigma_d, sigma_nu, job->no.threads);
  }
  if (st == BSURF_OK && o->orient == BSURF_ORIENT_MST)
    st = bsurf_orient_normals(c->xyz, &nb, job->no.k, b.normals);
  /* outputs: normals replaced, confidence and error fields added */
  if (st == BSURF_OK) st = normals_store(job, c, &b, 1);
  for (int t = 0; st == BSURF_OK && t < s->field_count; t++)
    s->means[t] = bsurf_jobs_mean(bsurf_cloud_field(c, s->field_names[t])->values, n);
  normals_bufs_free(&b);
  bsurf_neighbors_free(&nb);
  return st;
}

/* ---- options ---- */

#define NJ who /* the function called, in the messages */

static bsurf_status normals_check_candidates(const char *who, const bsurf_normals_job_options *o) {
  const bsurf_normal_options *no = &o->normals;
  BSURF_REQUIRE_IN(NJ, !o->select_k == !o->select_k_count,
                   "opts->select_k_count = %d: give it with opts->select_k (count 0 and NULL: no "
                   "selection)",
                   o->select_k_count);
  BSURF_REQUIRE_IN(NJ, o->select_k_count >= 0 && o->select_k_count <= MAX_CANDIDATES,
                   "opts->select_k_count = %d must be in [0, %d]", o->select_k_count,
                   MAX_CANDIDATES);
  for (int a = 0; a < o->select_k_count; a++) {
    BSURF_REQUIRE_IN(NJ, o->select_k[a] >= 3 && o->select_k[a] <= 65535,
                     "opts->select_k[%d] = %d must be in [3, 65535]", a, o->select_k[a]);
    BSURF_REQUIRE_IN(NJ, a == 0 || o->select_k[a] > o->select_k[a - 1],
                     "opts->select_k[%d] = %d: the candidates must be strictly ascending", a,
                     o->select_k[a]);
  }
  BSURF_REQUIRE_IN(NJ, !o->select_degree == !o->select_degree_count,
                   "opts->select_degree_count = %d: give it with opts->select_degree",
                   o->select_degree_count);
  BSURF_REQUIRE_IN(NJ, o->select_degree_count >= 0 && o->select_degree_count <= 4,
                   "opts->select_degree_count = %d must be in [0, 4]", o->select_degree_count);
  BSURF_REQUIRE_IN(NJ, !o->select_degree || no->fit == BSURF_NORMAL_POLY,
                   "opts->select_degree needs opts->normals.fit = BSURF_NORMAL_POLY");
  for (int d = 0; d < o->select_degree_count; d++)
    BSURF_REQUIRE_IN(NJ, o->select_degree[d] >= 1 && o->select_degree[d] <= 4,
                     "opts->select_degree[%d] = %d must be in [1, 4]", d, o->select_degree[d]);
  if (no->fit != BSURF_NORMAL_POLY) return BSURF_OK;
  /* every candidate K must hold a fit of every candidate degree */
  const int nk = o->select_k ? o->select_k_count : 1,
            nd = o->select_degree ? o->select_degree_count : 1;
  for (int a = 0; a < nk; a++)
    for (int d = 0; d < nd; d++) {
      int k = o->select_k ? o->select_k[a] : no->k,
          deg = o->select_degree ? o->select_degree[d] : no->degree;
      BSURF_REQUIRE_IN(NJ, k >= bsurf_poly_terms(deg),
                       "K = %d is too small for degree %d: a fit needs at least %d points", k, deg,
                       bsurf_poly_terms(deg));
    }
  return BSURF_OK;
}

static bsurf_status normals_check(const char *who, const bsurf_normals_job_options *o, int tiled) {
  const bsurf_normal_options *no = &o->normals;
  BSURF_REQUIRE_IN(NJ, no->fit == BSURF_NORMAL_PCA || no->fit == BSURF_NORMAL_POLY,
                   "opts->normals.fit = %d must be BSURF_NORMAL_PCA or BSURF_NORMAL_POLY",
                   (int)no->fit);
  BSURF_REQUIRE_IN(NJ, no->pca_center == BSURF_PCA_CENTROID || no->pca_center == BSURF_PCA_POINT,
                   "opts->normals.pca_center = %d must be BSURF_PCA_CENTROID or BSURF_PCA_POINT",
                   (int)no->pca_center);
  BSURF_REQUIRE_IN(NJ, no->k >= 3 && no->k <= 65535, "opts->normals.k = %d must be in [3, 65535]",
                   no->k);
  BSURF_REQUIRE_IN(NJ, no->degree >= 1 && no->degree <= 4,
                   "opts->normals.degree = %d must be in [1, 4]", no->degree);
  BSURF_REQUIRE_IN(NJ, no->bootstrap >= 0, "opts->normals.bootstrap = %d must be at least 0",
                   no->bootstrap);
  BSURF_REQUIRE_IN(NJ, o->k_ref == 0 || (o->k_ref >= 3 && o->k_ref <= 65535),
                   "opts->k_ref = %d must be 0 (normals.k) or in [3, 65535]", o->k_ref);
  bsurf_status st = normals_check_candidates(who, o);
  if (st != BSURF_OK) return st;
  BSURF_REQUIRE_IN(
      NJ, o->select_rule == BSURF_KSELECT_TEST_ERROR || o->select_rule == BSURF_KSELECT_MSE,
      "opts->select_rule = %d must be BSURF_KSELECT_TEST_ERROR or BSURF_KSELECT_MSE",
      (int)o->select_rule);
  if (o->select_rule == BSURF_KSELECT_MSE) {
    BSURF_REQUIRE_IN(NJ, o->select_k || o->select_degree,
                     "opts->select_rule MSE needs opts->select_k or opts->select_degree");
    BSURF_REQUIRE_IN(NJ, !o->curve, "opts->curve needs opts->select_rule TEST_ERROR");
    const int k0 = o->select_k ? o->select_k[0] : no->k;
    BSURF_REQUIRE_IN(NJ, k0 >= 7, "%s = %d: the MSE rule needs candidates K >= 7 (a quadric per K)",
                     o->select_k ? "opts->select_k[0]" : "opts->normals.k", k0);
    BSURF_REQUIRE_IN(NJ, o->noise_k >= 12 && o->noise_k <= 65535,
                     "opts->noise_k = %d must be in [12, 65535]", o->noise_k);
    BSURF_REQUIRE_IN(
        NJ, o->noise_pool == BSURF_NOISE_POOL_GLOBAL || o->noise_pool == BSURF_NOISE_POOL_LOCAL,
        "opts->noise_pool = %d must be BSURF_NOISE_POOL_GLOBAL or LOCAL", (int)o->noise_pool);
  }
  BSURF_REQUIRE_IN(NJ, !o->curve || o->select_k, "opts->curve needs opts->select_k");
  BSURF_REQUIRE_IN(NJ, !o->curve_truth || o->curve, "opts->curve_truth is used by opts->curve");
  BSURF_REQUIRE_IN(NJ, o->smooth_iterations >= 0, "opts->smooth_iterations = %d must be at least 0",
                   o->smooth_iterations);
  BSURF_REQUIRE_IN(NJ, o->alpha >= 0 && o->alpha <= 1, "opts->alpha = %g must be in [0, 1]",
                   o->alpha);
  BSURF_REQUIRE_IN(NJ, !isnan(o->sigma_d), "opts->sigma_d is NaN: give a length, or <= 0 for h");
  BSURF_REQUIRE_IN(NJ, isnan(o->sigma_nu) || o->sigma_nu > 0,
                   "opts->sigma_nu = %g must be positive, INFINITY or NAN (auto)", o->sigma_nu);
  BSURF_REQUIRE_IN(NJ, o->orient == BSURF_ORIENT_NONE || o->orient == BSURF_ORIENT_MST,
                   "opts->orient = %d must be BSURF_ORIENT_NONE or BSURF_ORIENT_MST",
                   (int)o->orient);
  if (!tiled) return BSURF_OK;
  BSURF_REQUIRE_IN(NJ, !o->curve,
                   "opts->curve keeps every candidate's values of every point: in memory only");
  BSURF_REQUIRE_IN(NJ, o->smooth_iterations == 0 && o->orient == BSURF_ORIENT_NONE,
                   "opts->smooth_iterations = %d, opts->orient = %d: smoothing and orientation use "
                   "more than each point's K-neighbourhood: in memory only",
                   o->smooth_iterations, (int)o->orient);
  return BSURF_OK;
}

/* The resolved run: candidates, reference K, the largest K. */
static void normals_setup(normals_job *job, const bsurf_normals_job_options *o) {
  job->no = o->normals;
  job->no.point_index = NULL;
  job->select_k = o->select_k != NULL;
  job->select_degree = o->select_degree != NULL;
  job->selecting = job->select_k || job->select_degree;
  job->test_error = o->test_error || job->selecting;
  job->k_ref = o->k_ref ? o->k_ref : o->normals.k;
  job->nk = job->select_k ? o->select_k_count : 1;
  job->nd = job->select_degree ? o->select_degree_count : 1;
  for (int a = 0; a < job->nk; a++)
    job->ks[a] = job->select_k ? o->select_k[a] : o->normals.k;
  for (int d = 0; d < job->nd; d++)
    job->ds[d] = job->select_degree ? o->select_degree[d] : o->normals.degree;
  job->ksel = bsurf_kselect_options_default();
  job->ksel.rule = o->select_rule;
  job->ksel.noise_k = o->noise_k;
  job->ksel.noise_pool = o->noise_pool;
  job->ksel.ks = job->ks;
  job->ksel.nk = job->nk;
  job->ksel.threads = o->normals.threads;
  if (o->normals.fit == BSURF_NORMAL_POLY) /* the MSE rule's (K, degree) candidates */
    job->ksel.ds = job->ds, job->ksel.nd = job->nd;
  int kmax = job->k_ref > job->no.k ? job->k_ref : job->no.k;
  if (job->ksel.rule == BSURF_KSELECT_MSE && job->ksel.noise_k > kmax) kmax = job->ksel.noise_k;
  for (int a = 0; a < job->nk; a++)
    if (job->ks[a] > kmax) kmax = job->ks[a];
  job->kmax = kmax;
  job->curve = o->curve;
  job->truth = o->curve_truth;
}

/* AUTO resolved: MSE where it applies (bootsurf.h, BSURF_KSELECT_AUTO) */
static void normals_resolve_rule(bsurf_normals_job_options *o) {
  if (o->select_rule == BSURF_KSELECT_AUTO)
    o->select_rule = ((o->select_k && o->select_k_count > 0 && o->select_k[0] >= 7) ||
                      (!o->select_k && o->select_degree && o->normals.k >= 7)) &&
                             !o->curve
                         ? BSURF_KSELECT_MSE
                         : BSURF_KSELECT_TEST_ERROR;
}

/* The options resolved (AUTO) and checked, the run set up (the caller frees
 * it); NULL with the status in *st. */
static normals_job *normals_open(const char *who, bsurf_normals_job_options *o, int tiled,
                                 bsurf_status *st) {
  normals_resolve_rule(o);
  if ((*st = normals_check(who, o, tiled)) != BSURF_OK) return NULL;
  normals_job *job = calloc(1, sizeof *job);
  if (!job) {
    *st = BSURF_ERR_NOMEM;
    return NULL;
  }
  normals_setup(job, o);
  return job;
}

bsurf_status bsurf_normals_job_memory(const bsurf_normals_job_options *opts,
                                      bsurf_normals_job_plan *plan) {
  const char *who = "bsurf_normals_job_memory";
  BSURF_REQUIRE_IN(NJ, plan, "plan must not be NULL");
  memset(plan, 0, sizeof *plan);
  bsurf_normals_job_options o = opts ? *opts : bsurf_normals_job_options_default();
  bsurf_status st;
  normals_job *job = normals_open(who, &o, 0, &st);
  if (!job) return st;
  bsurf_type types[4];
  int which[4];
  const char *names[4];
  plan->select_rule = o.select_rule;
  plan->k_max = job->kmax;
  plan->field_count = normals_field_names(job, names, types, which);
  /* Upper bounds, counted from the allocations (bytes per point):
   * normals_bufs_alloc: the normals 24, normal_var 8, normal_err 8; the
   * reference normals 24 (normal_err without the MSE rule); selecting: the
   * candidate's normal 24, variance, error, best error, K, degree 8 each
   * (64), the two-sheet flags 8 (MSE). */
  const int mse = o.select_rule == BSURF_KSELECT_MSE;
  const int ncand = job->nk * (o.normals.fit == BSURF_NORMAL_POLY ? job->nd : 1);
  double b = 40;
  if (job->test_error && !mse) b += 24;
  if (job->selecting) b += 64 + (mse ? 8 : 0);
  if (mse) {
    /* the MSE rule (kselect_run.c, normals_compute): the chosen K, degree
     * and flag as ints 12; the noise passes' s2 (the quadric's and the
     * cross-section's estimates, kselect_noise.c) and their pools 32, or
     * the pooled noise and the median's copy 16; pass 3's first choice 4, its
     * normal 24 and M 8, the tied record's pointer 8, the visit order 4;
     * the tied record, 8 + 40 per tied candidate, counted for every
     * candidate (the worst case: a sphere at noise 0.5 has about 2.6 of 15
     * tied); a tile's noise by row 8, first choices by point 24 + 8 and
     * by row 24 + 8 (normals_mse_tiled.c); with PCA candidates the
     * empirical bias's references, the first choices without it, 24 + 8
     * (kselect_lof.c) */
    b += 12 + 32 + 4 + 24 + 8 + 8 + 4 + (8 + 40.0 * ncand) + 40 + 32;
    if (o.normals.fit == BSURF_NORMAL_PCA) b += 32;
    /* a tiled run with the GLOBAL pool: every point's two pooled values
     * and the median's copy, on every rank, between the stages (not with a
     * tile) */
    if (job->ksel.noise_pool == BSURF_NOISE_POOL_GLOBAL) plan->cloud_bytes = 24;
  } else if (job->selecting) {
    /* the test-error selection: the chosen K and degree as ints 8, and
     * with the curve every candidate's error and variance (16), and
     * normal with curve_truth (24) */
    b += 8;
    if (job->curve) b += 16.0 * ncand + (job->truth ? 24.0 * ncand : 0);
  }
  plan->point_bytes = b;
  free(job);
  return BSURF_OK;
}

bsurf_status bsurf_normals_job(const bsurf_job_io *io, const bsurf_normals_job_options *opts,
                               bsurf_normals_job_summary *summary, bsurf_failure *err) {
  const char *who = "bsurf_normals_job";
  bsurf_status st = bsurf_jobs_begin(NJ, io, summary, sizeof *summary);
  bsurf_normals_job_options o = opts ? *opts : bsurf_normals_job_options_default();
  if (st != BSURF_OK) return st;
  normals_job *job = normals_open(who, &o, io->cloud == NULL, &st);
  summary->select_rule = o.select_rule; /* AUTO resolved */
  if (!job) return st;
  bsurf_type types[4];
  int which[4];
  summary->field_count = normals_field_names(job, summary->field_names, types, which);
  st = io->cloud ? normals_in_memory(io, &o, job, summary) : normals_tiled(io, job, summary, err);
  free(job);
  return st;
}
