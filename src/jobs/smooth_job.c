/* The `smooth` job (issue 18): denoising driven by the bootstrap error
 * (thesis chapter 6, bsurf_smooth), in memory or tile by tile, through one
 * call. The command line parses its options and prints the summary;
 * everything between is here. */
#include "algo/algo.h"
#include "algo/smooth_stages.h"
#include "jobs/jobs.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define SJ "bsurf_smooth_job"

static const char *const smooth_field_names[BSURF_SMOOTH_JOB_FIELDS] = {
    "err_632", "err_632plus", "moved", "k_hat", "d_local"};

bsurf_smooth_job_options bsurf_smooth_job_options_default(void) {
  bsurf_smooth_job_options o;
  memset(&o, 0, sizeof o);
  o.smooth = bsurf_smooth_options_default();
  return o;
}

size_t bsurf_smooth_job_point_values(const bsurf_smooth_job_options *opts) {
  return opts ? bsurf_smooth_stage_values(&opts->smooth) : 0;
}

/* The lengths given in units of h, converted once h is known (NAN and
 * INFINITY keep their meaning). */
static void smooth_lengths(bsurf_smooth_options *so, const bsurf_smooth_job_options *o, double h) {
  if (o->threshold_in_h && isfinite(so->threshold)) so->threshold *= h;
  if (o->h1_in_h) so->h1 *= h;
  if (o->h2_in_h) so->h2 *= h;
  if (o->k_error_in_h) so->k_error *= h;
}

/* The input's normals belong to the points before they moved: the output
 * has none (docs/robustness.md, "Honest truth"). */
static void drop_normals(bsurf_cloud *c) {
  free(c->normals);
  c->normals = NULL;
}

static bsurf_status add_fields(bsurf_cloud *c, int count) {
  const bsurf_type types[BSURF_SMOOTH_JOB_FIELDS] = {BSURF_FLOAT32, BSURF_FLOAT32, BSURF_FLOAT32,
                                                     BSURF_FLOAT32, BSURF_FLOAT32};
  return bsurf_jobs_add_fields(c, smooth_field_names, types, count);
}

/* ---- tiled runs (docs/scaling.md) ----
 * Stage 1 (tiles): W_i and the naive projection or the bilateral fit of
 * every point, kept by index. |W| is then summed in index order from them,
 * as bsurf_smooth sums it. Stage 2: naive streams the points with their
 * values (bsurf_tiles_map); bilateral runs tiles again with the halo of
 * reverse neighbours (every neighbourhood that contains a tile point). */

typedef struct smooth_tiles {
  bsurf_smooth_options so; /* resolved for stage 2 */
  size_t nv;               /* stage 1 values per point */
  double noise;            /* the guard's noise variance (bsurf_smooth_noise) */
  /* naive's map runs on rank 0 in index order: its counts and sums are
   * those of the in-memory loops */
  size_t projected, moved_points;
  double moved_sum, moved_max;
} smooth_tiles;

#define SMOOTH_SUMS 3 /* replicates skipped, degree reduced, centre unestimated */

static bsurf_status smooth_stage1_run(void *user, const bsurf_tile *tile, bsurf_cloud *core,
                                      double *sums) {
  (void)core;
  const smooth_tiles *t = user;
  bsurf_smooth_options so = t->so;
  so.error.point_index = tile->point_index;
  so.error.progress = NULL;
  bsurf_error_report rep;
  bsurf_status st = bsurf_smooth_stage1(tile->xyz, tile->nb, &so, tile->values_out, &rep);
  sums[0] += (double)rep.replicates_skipped;
  sums[1] += (double)rep.degree_reduced;
  sums[2] += (double)rep.center_unestimated;
  return st;
}

static bsurf_status smooth_prepare(void *user, bsurf_cloud *c) {
  (void)user;
  drop_normals(c);
  return add_fields(c, 3);
}

/* The smoothed positions and the fields of the cloud's points (local
 * indices point[], NULL: 0..) into c. */
static void smooth_store(const smooth_tiles *t, bsurf_cloud *c, const double *values,
                         const uint32_t *point, const double *out, const double *moved) {
  double *e632 = bsurf_cloud_field(c, "err_632")->values,
         *e632p = bsurf_cloud_field(c, "err_632plus")->values;
  double *mv = bsurf_cloud_field(c, "moved")->values;
  for (size_t r = 0; r < c->point_count; r++) {
    const double *v = &values[(point ? (size_t)point[r] : r) * t->nv];
    memcpy(&c->xyz[3 * r], &out[3 * r], 3 * sizeof(double));
    e632[r] = v[0];
    e632p[r] = v[1];
    mv[r] = moved[r];
  }
}

/* bilateral: one tile of stage 2 (its points and their reverse neighbours) */
static bsurf_status smooth_stage2_run(void *user, const bsurf_tile *tile, bsurf_cloud *core,
                                      double *sums) {
  (void)sums;
  const smooth_tiles *t = user;
  const size_t n = tile->core_count;
  uint32_t *point = calloc(n ? n : 1, sizeof *point);
  double *out = calloc(n ? n : 1, 3 * sizeof(double));
  bsurf_status st = point && out ? BSURF_OK : BSURF_ERR_NOMEM;
  for (size_t r = 0; r < n && point; r++)
    point[r] = tile->nb->idx[r * (size_t)tile->nb->k]; /* each row's point */
  if (st == BSURF_OK)
    st = bsurf_smooth_stage2(tile->xyz, tile->local_count, tile->values, n, point, tile->rev_off,
                             tile->rev, &t->so, t->noise, out, tile->values_out);
  if (st == BSURF_OK) smooth_store(t, core, tile->values, point, out, tile->values_out);
  free(point);
  free(out);
  return st;
}

/* naive: one range of points of stage 2, in index order */
static bsurf_status smooth_map(void *user, size_t first, bsurf_cloud *c, const double *values) {
  (void)first;
  smooth_tiles *t = user;
  const size_t n = c->point_count;
  double *out = calloc(n ? n : 1, 3 * sizeof(double)), *moved = calloc(n ? n : 1, sizeof(double));
  bsurf_status st = out && moved ? BSURF_OK : BSURF_ERR_NOMEM;
  if (st == BSURF_OK)
    st = bsurf_smooth_stage2(c->xyz, n, values, n, NULL, NULL, NULL, &t->so, t->noise, out, moved);
  if (st == BSURF_OK) {
    const int wc = bsurf_smooth_w_column(&t->so);
    for (size_t r = 0; r < n; r++) {
      t->projected += values[r * t->nv + (size_t)wc] < t->so.threshold;
      t->moved_sum += moved[r];
      t->moved_points += moved[r] > 0;
      if (moved[r] > t->moved_max) t->moved_max = moved[r];
    }
    smooth_store(t, c, values, NULL, out, moved);
  }
  free(out);
  free(moved);
  return st;
}

/* Sums over a values file in index order (the order of the in-memory loops):
 * sum[c] of column c, and of column 0 the count > 0 and the maximum. */
static bsurf_status values_sums(const bsurf_tile_values *v, double *sum, size_t *positive,
                                double *max, bsurf_failure *err) {
  const size_t per = 1 << 16, nv = v->nvalues;
  double *buf = malloc(per * nv * sizeof(double));
  if (!buf) return BSURF_ERR_NOMEM;
  for (size_t c = 0; c < nv; c++)
    sum[c] = 0;
  *positive = 0;
  *max = 0;
  for (size_t i = 0; i < v->count; i += per) {
    size_t m = v->count - i < per ? v->count - i : per;
    if (bsurf_tile_values_read(v, i, m, buf) != BSURF_OK) {
      free(buf);
      return bsurf_fail(err, BSURF_ERR_IO, 0, -1,
                        "cannot read the scratch file of the first stage");
    }
    for (size_t r = 0; r < m; r++)
      for (size_t c = 0; c < nv; c++) {
        double x = buf[r * nv + c];
        sum[c] += x;
        if (c == 0) *positive += x > 0, *max = x > *max ? x : *max;
      }
  }
  free(buf);
  return BSURF_OK;
}

/* The guard's second reading of the noise, tile by tile (bsurf_smooth's
 * select_noise: the K selection's noise passes on the 80-neighbourhoods,
 * bsurf_jobs_mse_stages, the same bits): sel[0] the level, sel[1] the share
 * of section-sampled points; NAN, 0 for a cloud of 80 points or fewer; NAN
 * and the section test's bound where that needs no level. */
static bsurf_status select_noise_tiled(const bsurf_job_io *io, const bsurf_smooth_options *so,
                                       size_t points, double sel[2], bsurf_failure *err) {
  sel[0] = NAN, sel[1] = 0;
  if (points <= BSURF_SMOOTH_SELECT_K) return BSURF_OK;
  bsurf_kselect_options ko;
  bsurf_smooth_select_options(so->error.threads, &ko);
  struct bsurf_ksel_run *run = NULL;
  bsurf_status st = bsurf_ksel_open(&ko, BSURF_SMOOTH_SELECT_K, 0, &run);
  if (st != BSURF_OK) return st;
  bsurf_tile_values pooled = {-1, 0, 0};
  bsurf_tile_report tr;
  size_t ns = 0;
  /* tiles of at least twice its K (the tile engine's least; the tiles'
   * size changes no value, their halos are proven) */
  bsurf_job_io sio = *io;
  if (sio.tile_points < 2 * BSURF_SMOOTH_SELECT_K) sio.tile_points = 2 * BSURF_SMOOTH_SELECT_K;
  /* the section test alone first, as in memory; the engine reports the
   * tiles of each (so Ctrl-C stops them between tiles) */
  st = bsurf_jobs_section_bound(&sio, BSURF_SMOOTH_SELECT_K, so->error.threads, so->error.progress,
                                so->error.progress_user, run, &ns, &tr, err);
  sel[1] = (double)ns / (double)points;
  if (st == BSURF_OK && sel[1] > BSURF_SMOOTH_SECTION_SHARE) {
    st = bsurf_jobs_mse_stages(&sio, &ko, BSURF_SMOOTH_SELECT_K, so->error.threads,
                               so->error.progress, so->error.progress_user, run, &pooled, &sel[0],
                               &ns, &tr, err);
    sel[1] = (double)ns / (double)points;
  }
  bsurf_tile_values_close(&pooled);
  bsurf_ksel_close(run);
  return st;
}

/* The guard's noise estimate from stage 1's misfit records (variance, degrees
 * of freedom, the interval's share, the ball's radius), the last BSURF_SMOOTH_SV columns of every
 * row, as bsurf_smooth makes it (the same values in index order), and the count of fits its misfit
 * test rejects. Holds BSURF_SMOOTH_SV + 1 doubles per point in memory. */
static bsurf_status values_noise(const bsurf_tile_values *v, const double sel[2], double *noise,
                                 bsurf_smooth_report *rep, bsurf_failure *err) {
  const size_t per = 1 << 16, nv = v->nvalues, n = v->count;
  double *buf = malloc(per * nv * sizeof(double));
  double *sv = bsurf_alloc_array(n ? n : 1, BSURF_SMOOTH_SV * sizeof(double));
  double *scratch = bsurf_alloc_array(n ? n : 1, sizeof(double));
  bsurf_status st = buf && sv && scratch ? BSURF_OK : BSURF_ERR_NOMEM;
  for (size_t i = 0; i < n && st == BSURF_OK; i += per) {
    size_t m = n - i < per ? n - i : per;
    if (bsurf_tile_values_read(v, i, m, buf) != BSURF_OK) {
      st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot read the scratch file of the first stage");
      break;
    }
    for (size_t r = 0; r < m; r++)
      memcpy(&sv[BSURF_SMOOTH_SV * (i + r)], &buf[r * nv + nv - BSURF_SMOOTH_SV],
             BSURF_SMOOTH_SV * sizeof(double));
  }
  if (st == BSURF_OK) {
    const double fits = bsurf_smooth_noise(sv, n, BSURF_SMOOTH_SV, scratch);
    *noise = bsurf_smooth_noise_level(fits, sel[0], sel[1]);
    rep->noise = sqrt(*noise);
    rep->noise_fits = sqrt(fits);
    rep->noise_select = sqrt(sel[0]);
    rep->section_share = sel[1];
    rep->misfit_fits = 0;
    for (size_t i = 0; i < n; i++)
      rep->misfit_fits += bsurf_smooth_misfit(&sv[BSURF_SMOOTH_SV * i], *noise);
  }
  free(buf);
  free(sv);
  free(scratch);
  return st;
}

/* Stage 2 (the output) and how far the points moved, in index order:
 * naive's map runs in it; bilateral's second stage keeps them by index. */
static bsurf_status smooth_stage2(const bsurf_job_io *io, smooth_tiles *t, bsurf_tile_ops *ops,
                                  const bsurf_tile_values *vals, bsurf_smooth_job_summary *s,
                                  bsurf_failure *err) {
  bsurf_smooth_report *rep = &s->report;
  ops->prepare = smooth_prepare;
  if (t->so.method == BSURF_SMOOTH_NAIVE) {
    bsurf_status st = bsurf_tiles_map(io->input, io->output, ops, vals, smooth_map, err);
    if (st != BSURF_OK) return st;
    rep->projected = t->projected;
    rep->moved_points = t->moved_points;
    rep->moved_max = t->moved_max;
    s->means[2] = t->moved_sum / (double)s->points;
  } else {
    bsurf_tile_values moved = {-1, 0, 0};
    ops->run = smooth_stage2_run;
    ops->nsums = 0;
    ops->nvalues = 1;
    ops->values_out = &moved;
    ops->values_in = vals;
    ops->reverse = 1;
    bsurf_tile_report tr2;
    memset(&tr2, 0, sizeof tr2);
    double ms = 0;
    bsurf_status st = bsurf_tiles_run(io->input, io->output, ops, &tr2, err);
    if (st == BSURF_OK) st = values_sums(&moved, &ms, &rep->moved_points, &rep->moved_max, err);
    bsurf_tile_values_close(&moved);
    if (st != BSURF_OK) return st;
    s->means[2] = ms / (double)s->points;
  }
  rep->moved_mean = s->means[2];
  return BSURF_OK;
}

static bsurf_status smooth_tiled(const bsurf_job_io *io, const bsurf_smooth_job_options *o,
                                 bsurf_smooth_job_summary *s, bsurf_failure *err) {
  const bsurf_smooth_options so = o->smooth;
  smooth_tiles t;
  memset(&t, 0, sizeof t);
  t.so = so;
  t.nv = bsurf_smooth_stage_values(&so);
  bsurf_tile_values vals = {-1, 0, 0};
  double sums[SMOOTH_SUMS] = {0}, vs[64];
  bsurf_tile_ops ops;
  bsurf_jobs_tile_ops(&ops, io, so.error.k, so.error.threads, so.error.progress,
                      so.error.progress_user, &t);
  ops.run = smooth_stage1_run;
  ops.nsums = SMOOTH_SUMS;
  ops.nvalues = t.nv;
  ops.values_out = &vals;
  bsurf_tile_report tr;
  memset(&tr, 0, sizeof tr);
  tr.sums = sums;
  size_t positive;
  double mx;
  /* stage 1, then |W| and the fields' means in index order */
  bsurf_status st = bsurf_tiles_run(io->input, io->output, &ops, &tr, err);
  s->tile_points = io->tile_points;
  bsurf_jobs_tiled_numbers(&tr, &s->points, &s->h, &s->duplicates, &s->tiles, &s->bad_point);
  if (st == BSURF_OK) st = values_sums(&vals, vs, &positive, &mx, err);
  if (st == BSURF_OK) {
    bsurf_smooth_report *rep = &s->report;
    rep->error.replicates_total = s->points * (size_t)so.error.bootstrap;
    rep->error.replicates_skipped = (size_t)sums[0];
    rep->error.degree_reduced = (size_t)sums[1];
    rep->error.center_unestimated = (size_t)sums[2];
    s->means[0] = vs[0] / (double)s->points;
    s->means[1] = vs[1] / (double)s->points;
    rep->mean_error = vs[bsurf_smooth_w_column(&so)] / (double)s->points;
    t.noise = NAN;
    rep->noise = rep->noise_fits = rep->noise_select = rep->section_share = NAN;
    if (so.guard) {
      double sel[2];
      st = select_noise_tiled(io, &so, s->points, sel, err);
      if (st == BSURF_OK) st = values_noise(&vals, sel, &t.noise, rep, err);
    }
    smooth_lengths(&t.so, o, s->h);
    bsurf_smooth_resolve(&t.so, s->h, rep->mean_error, t.noise);
    rep->h = s->h;
    rep->threshold = t.so.threshold;
    rep->h1 = t.so.h1;
    rep->h2 = t.so.h2;
    if (st == BSURF_OK) st = smooth_stage2(io, &t, &ops, &vals, s, err);
  }
  bsurf_tile_values_close(&vals);
  return st;
}

/* ---- in memory ---- */

static bsurf_status smooth_in_memory(const bsurf_job_io *io, const bsurf_smooth_job_options *o,
                                     bsurf_smooth_job_summary *s) {
  bsurf_cloud *c = io->cloud;
  bsurf_smooth_options so = o->smooth;
  bsurf_neighbors nb;
  bsurf_status st = bsurf_jobs_neighbors(c, so.error.k, so.error.threads, so.error.progress,
                                         so.error.progress_user, &nb, &s->duplicates);
  if (st != BSURF_OK) return st;
  const size_t n = c->point_count;
  s->points = n;
  s->h = nb.h;
  smooth_lengths(&so, o, s->h);
  double *smoothed = malloc((n ? n : 1) * 3 * sizeof(double));
  st = smoothed ? add_fields(c, s->field_count) : BSURF_ERR_NOMEM;
  if (st == BSURF_OK) {
    bsurf_smooth_fields sf;
    memset(&sf, 0, sizeof sf);
    double **slots[BSURF_SMOOTH_JOB_FIELDS] = {&sf.err_632, &sf.err_632plus, &sf.moved, &sf.k_hat,
                                               &sf.d_local};
    /* looked up after every add: the table of fields moves, the values do not */
    for (int f = 0; f < s->field_count; f++)
      *slots[f] = bsurf_cloud_field(c, smooth_field_names[f])->values;
    st = bsurf_smooth(c->xyz, &nb, &so, smoothed, &sf, &s->report);
  }
  bsurf_neighbors_free(&nb);
  if (st == BSURF_OK) {
    memcpy(c->xyz, smoothed, n * 3 * sizeof(double));
    drop_normals(c);
    for (int f = 0; f < s->field_count; f++)
      s->means[f] = bsurf_jobs_mean(bsurf_cloud_field(c, smooth_field_names[f])->values, n);
  }
  free(smoothed);
  return st;
}

static bsurf_status smooth_check(const bsurf_smooth_job_options *o, int tiled) {
  const bsurf_smooth_options *so = &o->smooth;
  const bsurf_error_options *eo = &so->error;
  BSURF_REQUIRE_IN(SJ, so->method >= BSURF_SMOOTH_NAIVE && so->method <= BSURF_SMOOTH_MULTIPASS,
                   "opts->smooth.method = %d must be BSURF_SMOOTH_NAIVE, _BILATERAL or _MULTIPASS",
                   (int)so->method);
  BSURF_REQUIRE_IN(SJ, so->order == BSURF_ORDER_PARALLEL || so->order == BSURF_ORDER_SEQUENTIAL,
                   "opts->smooth.order = %d must be BSURF_ORDER_PARALLEL or _SEQUENTIAL",
                   (int)so->order);
  BSURF_REQUIRE_IN(SJ, eo->k >= 2 && eo->k <= 65535,
                   "opts->smooth.error.k = %d must be in [2, 65535]", eo->k);
  BSURF_REQUIRE_IN(SJ, eo->degree >= 1 && eo->degree <= 4,
                   "opts->smooth.error.degree = %d must be in [1, 4]", eo->degree);
  BSURF_REQUIRE_IN(SJ, eo->k >= bsurf_poly_terms(eo->degree),
                   "opts->smooth.error.k = %d is too small for degree %d: a fit needs at least %d "
                   "points",
                   eo->k, eo->degree, bsurf_poly_terms(eo->degree));
  /* K_i = k_min points carry a plane fit at least (bsurf_smooth) */
  BSURF_REQUIRE_IN(SJ,
                   so->method != BSURF_SMOOTH_MULTIPASS ||
                       (so->k_min >= bsurf_poly_terms(1) && so->k_min <= eo->k),
                   "opts->smooth.k_min = %d must be in [%d (a plane's points), error.k = %d]",
                   so->k_min, bsurf_poly_terms(1), eo->k);
  BSURF_REQUIRE_IN(SJ,
                   so->method != BSURF_SMOOTH_MULTIPASS || so->k_max == 0 ||
                       (so->k_max >= eo->k && so->k_max <= 65535),
                   "opts->smooth.k_max = %d must be 0 (8 error.k) or in [error.k = %d, 65535]",
                   so->k_max, eo->k);
  BSURF_REQUIRE_IN(SJ, !isnan(so->threshold) || !o->threshold_in_h,
                   "opts->threshold_in_h with threshold NAN (auto): auto is no length");
  if (!tiled) return BSURF_OK;
  BSURF_REQUIRE_IN(SJ, so->method != BSURF_SMOOTH_MULTIPASS,
                   "opts->smooth.method MULTIPASS runs its passes each one neighbourhood ring "
                   "further: in memory only");
  BSURF_REQUIRE_IN(SJ, so->order == BSURF_ORDER_PARALLEL,
                   "opts->smooth.order SEQUENTIAL chains every neighbourhood of the whole cloud: "
                   "in memory only");
  return BSURF_OK;
}

bsurf_status bsurf_smooth_job_memory(const bsurf_smooth_job_options *opts,
                                     bsurf_smooth_job_plan *plan) {
  BSURF_REQUIRE_IN("bsurf_smooth_job_memory", plan, "plan must not be NULL");
  memset(plan, 0, sizeof *plan);
  bsurf_smooth_job_options o = opts ? *opts : bsurf_smooth_job_options_default();
  if (o.smooth.method == BSURF_SMOOTH_AUTO) o.smooth.method = BSURF_SMOOTH_MULTIPASS;
  bsurf_status st = smooth_check(&o, 0);
  if (st != BSURF_OK) return st;
  const bsurf_smooth_options *so = &o.smooth;
  const int k = so->error.k, T = bsurf_threads_resolve(so->error.threads);
  plan->method = so->method;
  plan->k = plan->k_max = k;
  plan->field_count = so->method == BSURF_SMOOTH_MULTIPASS ? 5 : 3;
  /* the job's smoothed positions (24); bsurf_smooth's stage 1 and passes */
  const double s1 = bsurf_smooth_stage1_bytes(so);
  double b = 24 + s1 + bsurf_smooth_passes_bytes(so, k, T, NULL);
  if (so->guard) {
    /* the guard's second reading of the noise (smooth.c, select_noise):
     * the 80-neighbourhoods (4 x 80, and their order 4) and the noise
     * passes' two values per point of two passes (32), while stage 1's
     * records are held */
    const double sel = 24 + s1 + 4.0 * BSURF_SMOOTH_SELECT_K + 4 + 32;
    if (sel > b) b = sel;
  }
  if (so->method == BSURF_SMOOTH_MULTIPASS && so->guard && so->k_max != k) {
    /* the scale rule (smooth.c) at its cap K: stage 1 at k held while the
     * neighbourhoods of K (4 K, and their order 4) and bsurf_smooth at K
     * (stage 1 and the passes) run */
    const long cap = so->k_max > 0 ? so->k_max : 8L * k;
    const int K = cap > 65535 ? 65535 : (int)cap;
    double per_k = 0;
    const double atk = 24 + s1 + 4.0 * K + 4 + s1 + bsurf_smooth_passes_bytes(so, K, T, &per_k);
    if (atk > b) b = atk;
    plan->k_max = K;
    plan->k_max_bytes = 4 + per_k;
  }
  plan->point_bytes = b;
  return BSURF_OK;
}

bsurf_status bsurf_smooth_job(const bsurf_job_io *io, const bsurf_smooth_job_options *opts,
                              bsurf_smooth_job_summary *summary, bsurf_failure *err) {
  bsurf_status st = bsurf_jobs_begin(SJ, io, summary, sizeof *summary);
  bsurf_smooth_job_options o = opts ? *opts : bsurf_smooth_job_options_default();
  if (o.smooth.method == BSURF_SMOOTH_AUTO) /* multipass is in memory only */
    o.smooth.method = io->cloud ? BSURF_SMOOTH_MULTIPASS : BSURF_SMOOTH_BILATERAL;
  if (st == BSURF_OK) st = smooth_check(&o, io->cloud == NULL);
  if (st != BSURF_OK) return st;
  const bsurf_smooth_options *so = &o.smooth;
  summary->estimator =
      so->estimator == BSURF_SMOOTH_EST_632PLUS ||
              (so->estimator == BSURF_SMOOTH_EST_DEFAULT && so->method == BSURF_SMOOTH_NAIVE)
          ? "err_632plus"
          : "err_632";
  summary->method = so->method;
  summary->field_count = so->method == BSURF_SMOOTH_MULTIPASS ? 5 : 3;
  for (int f = 0; f < BSURF_SMOOTH_JOB_FIELDS; f++)
    summary->field_names[f] = smooth_field_names[f];
  return io->cloud ? smooth_in_memory(io, &o, summary) : smooth_tiled(io, &o, summary, err);
}
