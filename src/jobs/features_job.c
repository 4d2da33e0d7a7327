/* The `features` job (issue 18): feature detection by the distance map
 * (7.1) or the normal variance (7.2), in memory or tile by tile, through one
 * call. The command line parses its options and prints the summary;
 * everything between is here.
 *
 * Input fields named like the outputs (`feature`, and `feature_dist` or
 * `normal_var`) are most often ground truth (`generate` and `sample` write
 * feature and feature_dist; `noise` keeps them) or an earlier run's results.
 * Overwriting would silently lose the truth -- and `feature_dist` of the
 * truth (exact distance to an edge) is not the distance map of 7.1 -- so
 * an input field NAME is kept as NAME_in. When NAME_in exists already (the
 * input is itself a features output, NAME_in the original), NAME is an
 * earlier result and is replaced; NAME_in stays. Refusing would break the
 * common generate | noise | features pipeline. Both cases are reported in
 * the summary (kept, replaced). */
#include "jobs/jobs.h"
#include "algo/algo.h"
#include "algo/smooth_stages.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define FJ "bsurf_features_job"

/* The output fields: an input field NAME is kept as NAME_in, unless NAME_in
 * exists (then NAME is an earlier result and is replaced); then the score
 * and `feature` are added (their values zero). kept / replaced: per name. */
static bsurf_status features_fields(bsurf_cloud *c, const char *const names[2], int kept[2],
                                    int replaced[2]) {
  for (int t = 0; t < 2; t++) {
    kept[t] = replaced[t] = 0;
    bsurf_field *old = bsurf_cloud_field(c, names[t]);
    if (!old) continue;
    char in_name[BSURF_FIELD_NAME_MAX];
    snprintf(in_name, sizeof in_name, "%s_in", names[t]);
    if (bsurf_cloud_field(c, in_name)) {
      replaced[t] = 1;
    } else {
      strcpy(old->name, in_name);
      kept[t] = 1;
    }
  }
  /* adding a field may move the field array: look both up once both exist */
  const char *const order[2] = {names[1], names[0]};
  const bsurf_type types[2] = {BSURF_FLOAT32, BSURF_UINT8};
  return bsurf_jobs_add_fields(c, order, types, 2);
}

/* ---- tiled runs (docs/scaling.md) ----
 * variance: stage 1 (tiles): normal_var of every point from its
 * K-neighbourhood, kept by index. The automatic threshold of Eq. 7.2 needs
 * every value: they are read back in index order into memory (8 bytes per
 * point) for bsurf_tail_threshold. Stage 2 streams the points with their
 * values and writes normal_var and feature = normal_var > t_h.
 * distance: the library's chain of tiled stages
 * (bsurf_features_distance_tiled, src/tile/features_tiled.c). */

typedef struct features_tiles {
  bsurf_normal_options no;
  double threshold;
  bsurf_features_job_summary *s; /* field names; kept and replaced out */
} features_tiles;

static bsurf_status features_stage1_run(void *user, const bsurf_tile *tile, bsurf_cloud *core,
                                        double *sums) {
  (void)core;
  (void)sums;
  const features_tiles *ft = user;
  bsurf_normal_options no = ft->no;
  no.point_index = tile->point_index;
  bsurf_normal_fields nf = {NULL, tile->values_out, NULL};
  return bsurf_estimate_normals(tile->xyz, tile->nb, NULL, &no, &nf, NULL);
}

static bsurf_status features_prepare(void *user, bsurf_cloud *c) {
  features_tiles *ft = user;
  return features_fields(c, ft->s->field_names, ft->s->kept, ft->s->replaced);
}

static bsurf_status features_map(void *user, size_t first, bsurf_cloud *c, const double *values) {
  (void)first;
  const features_tiles *ft = user;
  double *score = bsurf_cloud_field(c, ft->s->field_names[1])->values,
         *feat = bsurf_cloud_field(c, ft->s->field_names[0])->values;
  for (size_t i = 0; i < c->point_count; i++) {
    score[i] = values[i];
    feat[i] = values[i] > ft->threshold; /* Eq. 7.2 */
  }
  return BSURF_OK;
}

/* A first tiled stage of one value per point (run, neighbourhoods of k):
 * the values read back in index order into *v (the caller frees it and
 * closes vals, which a later stage may read). */
static bsurf_status
stage_values(const bsurf_job_io *io, const bsurf_feature_options *fo, features_tiles *ft, int k,
             int progress, bsurf_status (*run)(void *, const bsurf_tile *, bsurf_cloud *, double *),
             bsurf_tile_ops *ops, bsurf_tile_values *vals, double **v, bsurf_failure *err) {
  bsurf_features_job_summary *s = ft->s;
  ft->no = fo->normals;
  ft->no.threads = fo->threads;
  ft->no.progress = NULL;
  bsurf_jobs_tile_ops(ops, io, k, fo->threads, progress ? fo->progress : NULL,
                      progress ? fo->progress_user : NULL, ft);
  ops->run = run;
  ops->nvalues = 1;
  ops->values_out = vals;
  bsurf_tile_report tr;
  memset(&tr, 0, sizeof tr);
  bsurf_status st = bsurf_tiles_run(io->input, io->output, ops, &tr, err);
  bsurf_jobs_tiled_numbers(&tr, &s->points, &s->h, &s->duplicates, &s->tiles, &s->bad_point);
  *v = NULL;
  if (st == BSURF_OK) {
    *v = bsurf_alloc_array(s->points ? s->points : 1, sizeof(double));
    if (!*v)
      st = BSURF_ERR_NOMEM;
    else if (bsurf_tile_values_read(vals, 0, s->points, *v) != BSURF_OK)
      st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot read the scratch file of the first stage");
  }
  return st;
}

/* variance: normal_var tile by tile, the threshold (given or automatic) over
 * every value in index order, then the output by a pointwise stage. */
static bsurf_status variance_tiled(const bsurf_job_io *io, const bsurf_feature_options *fo,
                                   features_tiles *ft, bsurf_failure *err) {
  bsurf_features_job_summary *s = ft->s;
  bsurf_tile_values vals = {-1, 0, 0};
  bsurf_tile_ops ops;
  double *v = NULL;
  bsurf_status st =
      stage_values(io, fo, ft, fo->normals.k, 1, features_stage1_run, &ops, &vals, &v, err);
  if (st == BSURF_OK && isnan(fo->threshold))
    st = bsurf_tail_threshold(v, s->points, fo->tail_rule, &ft->threshold);
  else
    ft->threshold = fo->threshold;
  s->report.threshold = ft->threshold;
  s->report.ratio_threshold_kmin = NAN;
  for (size_t i = 0; st == BSURF_OK && i < s->points; i++)
    s->report.feature_points += v[i] > ft->threshold;
  free(v);
  if (st == BSURF_OK) {
    ops.prepare = features_prepare;
    st = bsurf_tiles_map(io->input, io->output, &ops, &vals, features_map, err);
  }
  bsurf_tile_values_close(&vals);
  return st;
}

/* variance, null rule, feature_angle > 0: a first tiled stage gives
 * lambda0 / tr of every point at normals.k, whose median eta (over every
 * value, as in memory) chooses the neighbourhood (bsurf_fvar_choose_k) */
static bsurf_status eta_stage_run(void *user, const bsurf_tile *tile, bsurf_cloud *core,
                                  double *sums) {
  (void)core;
  (void)sums;
  const features_tiles *ft = user;
  const size_t nc = tile->core_count ? tile->core_count : 1;
  double *nu = bsurf_calloc_array(nc, sizeof(double)), *u = bsurf_alloc_array(nc, sizeof(double)),
         *l0 = bsurf_alloc_array(nc, sizeof(double));
  bsurf_status st = nu && u && l0 ? BSURF_OK : BSURF_ERR_NOMEM;
  if (st == BSURF_OK)
    st = bsurf_fvar_local(tile->xyz, tile->nb, ft->no.k, ft->no.threads, nu, u, l0,
                          tile->values_out, NULL, NULL, NULL);
  free(nu);
  free(u);
  free(l0);
  return st;
}

static bsurf_status eta_tiled(const bsurf_job_io *io, const bsurf_feature_options *fo,
                              features_tiles *ft, double *eta, bsurf_failure *err) {
  bsurf_tile_values vals = {-1, 0, 0};
  bsurf_tile_ops ops;
  double *v = NULL;
  bsurf_status st = stage_values(io, fo, ft, fo->normals.k, 0, eta_stage_run, &ops, &vals, &v, err);
  if (st == BSURF_OK) *eta = bsurf_median(v, ft->s->points);
  free(v);
  bsurf_tile_values_close(&vals);
  return st;
}

/* The quadric check's noise level, tile by tile: the K selection's noise
 * passes on the 80-neighbourhoods (bsurf_jobs_mse_stages; in memory
 * features_variance.c reads bsurf_ksel_cloud_noise, the same bits). NAN
 * where the check cannot run (off, another rule, 80 points or fewer). Read
 * before the stages, so also where the check then finds no K_q (heavy
 * noise): its cost there is the noise passes'. */
static bsurf_status quadric_noise_tiled(const bsurf_job_io *io, const bsurf_feature_options *fo,
                                        double *level, bsurf_failure *err) {
  *level = NAN;
  if (!(fo->quadric_angle > 0) || fo->method != BSURF_FEATURES_VARIANCE ||
      fo->tail_rule != BSURF_TAIL_NULL || !isnan(fo->threshold))
    return BSURF_OK;
  uint64_t points = 0;
  bsurf_status st = bsurf_read_header(io->input, &points, err);
  if (st != BSURF_OK || points <= BSURF_SMOOTH_SELECT_K) return st;
  bsurf_kselect_options ko;
  bsurf_smooth_select_options(fo->threads, &ko);
  struct bsurf_ksel_run *run = NULL;
  st = bsurf_ksel_open(&ko, BSURF_SMOOTH_SELECT_K, 0, &run);
  if (st != BSURF_OK) return st;
  bsurf_tile_values pooled = {-1, 0, 0};
  bsurf_tile_report tr;
  memset(&tr, 0, sizeof tr);
  size_t ns = 0;
  /* tiles of at least twice its K (the tile engine's least; the tiles'
   * size changes no value, their halos are proven) */
  bsurf_job_io sio = *io;
  if (sio.tile_points < 2 * BSURF_SMOOTH_SELECT_K) sio.tile_points = 2 * BSURF_SMOOTH_SELECT_K;
  st = bsurf_jobs_mse_stages(&sio, &ko, BSURF_SMOOTH_SELECT_K, fo->threads, NULL, NULL, run,
                             &pooled, level, &ns, &tr, err);
  bsurf_tile_values_close(&pooled);
  bsurf_ksel_close(run);
  return st;
}

/* distance, and variance under the null rule: the library's chains of tiled
 * stages (bsurf_features_distance_tiled, bsurf_features_variance_tiled) */
static bsurf_status chain_tiled(const bsurf_job_io *io, const bsurf_feature_options *fo,
                                features_tiles *ft, bsurf_failure *err) {
  bsurf_features_job_summary *s = ft->s;
  const int distance = fo->method == BSURF_FEATURES_DISTANCE;
  bsurf_tile_ops ops;
  bsurf_jobs_tile_ops(&ops, io, distance ? fo->k_max : fo->normals.k, fo->threads, fo->progress,
                      fo->progress_user, ft);
  ops.prepare = features_prepare;
  bsurf_tile_report tr;
  memset(&tr, 0, sizeof tr);
  double level = NAN;
  bsurf_status st = distance ? BSURF_OK : quadric_noise_tiled(io, fo, &level, err);
  if (st == BSURF_OK)
    st = distance
             ? bsurf_features_distance_tiled(io->input, io->output, &ops, fo, &s->report, &tr, err)
             : bsurf_features_variance_tiled(io->input, io->output, &ops, fo, level, &s->report,
                                             &tr, err);
  bsurf_jobs_tiled_numbers(&tr, &s->points, &s->h, &s->duplicates, &s->tiles, &s->bad_point);
  return st;
}

/* ---- in memory ---- */

/* the variance test chooses its neighbourhood */
static int choose_k(const bsurf_feature_options *fo) {
  return fo->method == BSURF_FEATURES_VARIANCE && isnan(fo->threshold) &&
         fo->tail_rule == BSURF_TAIL_NULL && fo->feature_angle > 0;
}

static bsurf_status features_in_memory(const bsurf_job_io *io, const bsurf_feature_options *fo,
                                       bsurf_features_job_summary *s) {
  bsurf_cloud *c = io->cloud;
  const int kmax = fo->method == BSURF_FEATURES_DISTANCE ? fo->k_max : fo->normals.k;
  bsurf_neighbors nb;
  bsurf_status st = bsurf_jobs_neighbors(c, kmax, fo->threads, fo->progress, fo->progress_user, &nb,
                                         &s->duplicates);
  if (st != BSURF_OK) return st;
  const size_t n = c->point_count;
  s->points = n;
  s->h = nb.h;
  /* the variance test's neighbourhood (bsurf_fvar_choose_k): from eta at
   * normals.k; the neighbourhoods are built again when it grows */
  bsurf_feature_options fk = *fo;
  double power = NAN;
  if (choose_k(fo)) {
    double eta = 0;
    int k = fo->normals.k;
    st = bsurf_fvar_eta(c->xyz, &nb, fo->normals.k, fo->threads, &eta);
    if (st == BSURF_OK) st = bsurf_fvar_choose_k(fo, eta, bsurf_fvar_k_cap(fo, n), &k, &power);
    fk.normals.k = k;
    fk.feature_angle = 0;
    /* the cap the choice used stays the quadric check's (not 8 times the chosen K) */
    fk.variance_k_max = bsurf_fvar_k_cap(fo, n);
    if (st != BSURF_OK) {
      bsurf_neighbors_free(&nb);
      return st;
    }
  }
  /* the table once more where the chosen K or the quadric check (K_q and the
   * noise passes' 80) needs more; a small cloud: every point (as tiled) */
  int need = fk.method == BSURF_FEATURES_VARIANCE
                 ? bsurf_fvar_neighbors_k(&fk, bsurf_fvar_k_cap(&fk, n))
                 : nb.k;
  if ((size_t)need > n) need = (int)n;
  if (need < fk.normals.k) need = fk.normals.k;
  if (need > nb.k) {
    bsurf_neighbors_free(&nb);
    size_t dup = 0;
    st = bsurf_jobs_neighbors(c, need, fo->threads, NULL, NULL, &nb, &dup);
    if (st != BSURF_OK) return st;
  }
  uint8_t *feat = malloc(n ? n : 1);
  double *score = malloc((n ? n : 1) * sizeof(double));
  st = feat && score ? bsurf_detect_features(c->xyz, &nb, &fk, feat, score, &s->report)
                     : BSURF_ERR_NOMEM;
  s->report.edge_power = power;
  bsurf_neighbors_free(&nb);
  if (st == BSURF_OK) st = features_fields(c, s->field_names, s->kept, s->replaced);
  if (st == BSURF_OK) {
    memcpy(bsurf_cloud_field(c, s->field_names[1])->values, score, n * sizeof(double));
    double *fv = bsurf_cloud_field(c, s->field_names[0])->values;
    for (size_t i = 0; i < n; i++)
      fv[i] = feat[i];
  }
  free(feat);
  free(score);
  return st;
}

static bsurf_status features_check(const bsurf_feature_options *fo) {
  BSURF_REQUIRE_IN(FJ,
                   fo->method == BSURF_FEATURES_DISTANCE || fo->method == BSURF_FEATURES_VARIANCE,
                   "opts->method = %d must be BSURF_FEATURES_DISTANCE or BSURF_FEATURES_VARIANCE",
                   (int)fo->method);
  if (fo->method == BSURF_FEATURES_DISTANCE) {
    BSURF_REQUIRE_IN(FJ, fo->k_min >= 3 && fo->k_min <= 65535,
                     "opts->k_min = %d must be in [3, 65535]", fo->k_min);
    BSURF_REQUIRE_IN(FJ, fo->k_max >= fo->k_min && fo->k_max <= 65535,
                     "opts->k_max = %d must be in [k_min = %d, 65535]", fo->k_max, fo->k_min);
    BSURF_REQUIRE_IN(FJ, fo->k_step >= 1, "opts->k_step = %d must be at least 1", fo->k_step);
    BSURF_REQUIRE_IN(FJ, fo->filter_k >= 0 && fo->filter_k <= fo->k_max,
                     "opts->filter_k = %d must be in [0, k_max = %d]", fo->filter_k, fo->k_max);
  } else {
    BSURF_REQUIRE_IN(FJ, fo->normals.k >= 3 && fo->normals.k <= 65535,
                     "opts->normals.k = %d must be in [3, 65535]", fo->normals.k);
    BSURF_REQUIRE_IN(
        FJ, fo->normals.bootstrap >= 2,
        "opts->normals.bootstrap = %d: the variance method needs at least 2 replicates",
        fo->normals.bootstrap);
    BSURF_REQUIRE_IN(FJ,
                     fo->tail_rule == BSURF_TAIL_OTSU || fo->tail_rule == BSURF_TAIL_MAD ||
                         fo->tail_rule == BSURF_TAIL_NULL,
                     "opts->tail_rule = %d must be BSURF_TAIL_NULL, BSURF_TAIL_OTSU or "
                     "BSURF_TAIL_MAD",
                     (int)fo->tail_rule);
    if (fo->tail_rule == BSURF_TAIL_NULL) {
      BSURF_REQUIRE_IN(FJ, fo->false_positive_rate > 0 && fo->false_positive_rate < 1,
                       "opts->false_positive_rate = %g must be in (0, 1)", fo->false_positive_rate);
      BSURF_REQUIRE_IN(FJ, fo->variance_filter_k >= 0 && fo->variance_filter_k <= 65535,
                       "opts->variance_filter_k = %d must be in [0, 65535]", fo->variance_filter_k);
      BSURF_REQUIRE_IN(FJ, fo->feature_angle >= 0 && fo->feature_angle < 180,
                       "opts->feature_angle = %g must be in [0, 180)", fo->feature_angle);
      BSURF_REQUIRE_IN(FJ, fo->variance_k_max >= 0 && fo->variance_k_max <= 65535,
                       "opts->variance_k_max = %d must be in [0, 65535]", fo->variance_k_max);
      BSURF_REQUIRE_IN(FJ, fo->quadric_angle >= 0 && fo->quadric_angle < 180,
                       "opts->quadric_angle = %g must be in [0, 180)", fo->quadric_angle);
    }
  }
  /* in the words every front end prints (bsurf_feature_threshold_check) */
  return bsurf_feature_threshold_check(fo->method, fo->threshold);
}

bsurf_status bsurf_feature_threshold_check(bsurf_feature_method method, double threshold) {
  if (isnan(threshold)) return BSURF_OK; /* auto */
  if (!isfinite(threshold))
    return bsurf_set_message(BSURF_ERR_INVALID_ARG, "threshold %g: must be a number or auto",
                             threshold);
  /* distance: a fraction of max(feature_dist); variance: a normal_var (a
   * negative threshold would flag every point) */
  if (method == BSURF_FEATURES_DISTANCE && !(threshold >= 0 && threshold <= 1))
    return bsurf_set_message(
        BSURF_ERR_INVALID_ARG,
        "threshold %g: method distance takes a fraction of max(feature_dist), 0 to 1, or auto",
        threshold);
  if (method != BSURF_FEATURES_DISTANCE && !(threshold >= 0))
    return bsurf_set_message(
        BSURF_ERR_INVALID_ARG,
        "threshold %g: method variance takes a normal_var value, at least 0, or auto", threshold);
  return BSURF_OK;
}

int bsurf_features_job_neighbors(const bsurf_feature_options *opts) {
  const bsurf_feature_options o = opts ? *opts : bsurf_feature_options_default();
  if (o.method == BSURF_FEATURES_DISTANCE) return o.k_max;
  /* the K choice's cap before the cloud's size bounds it */
  const int cap = bsurf_fvar_k_cap(&o, SIZE_MAX);
  int k = choose_k(&o) ? cap : o.normals.k;
  /* the quadric check's table at the largest K the choice may take */
  bsurf_feature_options q = o;
  q.normals.k = k;
  const int need = bsurf_fvar_neighbors_k(&q, cap);
  return need > k ? need : k;
}

bsurf_status bsurf_features_job(const bsurf_job_io *io, const bsurf_feature_options *opts,
                                bsurf_features_job_summary *summary, bsurf_failure *err) {
  bsurf_status st = bsurf_jobs_begin(FJ, io, summary, sizeof *summary);
  if (st == BSURF_OK) bsurf_feature_report_clear(&summary->report);
  bsurf_feature_options fo = opts ? *opts : bsurf_feature_options_default();
  if (st == BSURF_OK) st = features_check(&fo);
  if (st != BSURF_OK) return st;
  summary->field_names[0] = "feature";
  /* the null rule's score is the normalised, filtered variance z of
   * docs/features.md, not normal_var itself */
  const int null_rule = fo.method == BSURF_FEATURES_VARIANCE && isnan(fo.threshold) &&
                        fo.tail_rule == BSURF_TAIL_NULL;
  summary->field_names[1] = fo.method == BSURF_FEATURES_DISTANCE ? "feature_dist"
                            : null_rule                          ? "variance_z"
                                                                 : "normal_var";
  if (io->cloud) return features_in_memory(io, &fo, summary);
  summary->tile_points = io->tile_points;
  features_tiles ft;
  memset(&ft, 0, sizeof ft);
  ft.s = summary;
  double power = NAN;
  if (choose_k(&fo)) {
    double eta = 0;
    int k = fo.normals.k;
    st = eta_tiled(io, &fo, &ft, &eta, err);
    if (st == BSURF_OK)
      st = bsurf_fvar_choose_k(&fo, eta, bsurf_fvar_k_cap(&fo, summary->points), &k, &power);
    if (st != BSURF_OK) return st;
    fo.variance_k_max = bsurf_fvar_k_cap(&fo, summary->points); /* as in memory */
    fo.normals.k = k;
    fo.feature_angle = 0;
  }
  st = fo.method == BSURF_FEATURES_DISTANCE || null_rule ? chain_tiled(io, &fo, &ft, err)
                                                         : variance_tiled(io, &fo, &ft, err);
  summary->report.edge_power = power;
  summary->report.k = fo.normals.k;
  return st;
}
