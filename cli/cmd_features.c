/* bootsurf features: feature detection (thesis chapter 7).
 *
 * Input fields named like the outputs (`feature`, and `feature_dist` or
 * `normal_var`) are most often ground truth (`generate` and `sample` write
 * feature and feature_dist; `noise` keeps them) or an earlier run's results.
 * Overwriting would silently lose the truth -- and `feature_dist` of the
 * truth (exact distance to an edge) is not the distance map of 7.1 -- so
 * an input field NAME is kept as NAME_in. When NAME_in exists already (the
 * input is itself a features output, NAME_in the original), NAME is an
 * earlier result and is replaced; NAME_in stays. Refusing would break the
 * common generate | noise | features pipeline. Both cases are reported
 * (stderr, and "kept_input_fields" / "replaced_input_fields" in --json). */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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
  return bsurf_cloud_add_field(c, names[1], BSURF_FLOAT32) &&
                 bsurf_cloud_add_field(c, names[0], BSURF_UINT8)
             ? BSURF_OK
             : BSURF_ERR_NOMEM;
}

static void features_warn(const char *input, const char *const names[2], const int kept[2],
                          const int replaced[2]) {
  for (int t = 0; t < 2; t++) {
    if (replaced[t])
      cli_warn("%s: replacing the input's %s (%s_in is kept)", input, names[t], names[t]);
    if (kept[t]) cli_warn("%s: the input's %s is kept as %s_in", input, names[t], names[t]);
  }
}

/* ---- tiled runs of the variance method (cli/tiles.c, docs/scaling.md) ----
 * Stage 1 (tiles): normal_var of every point from its K-neighbourhood, kept
 * by index. The automatic threshold of Eq. 7.2 needs every value: they are
 * read back in index order into memory (8 bytes per point) for
 * bsurf_tail_threshold. Stage 2 streams the points with their values and
 * writes normal_var and feature = normal_var > t_h. */

typedef struct features_tiles {
  bsurf_normal_options no;
  double threshold;
  const char *names[2];
  int kept[2], replaced[2];
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
  return features_fields(c, ft->names, ft->kept, ft->replaced);
}

static bsurf_status features_map(void *user, size_t first, bsurf_cloud *c, const double *values) {
  (void)first;
  const features_tiles *ft = user;
  double *score = bsurf_cloud_field(c, ft->names[1])->values,
         *feat = bsurf_cloud_field(c, ft->names[0])->values;
  for (size_t i = 0; i < c->point_count; i++) {
    score[i] = values[i];
    feat[i] = values[i] > ft->threshold; /* Eq. 7.2 */
  }
  return BSURF_OK;
}

/* The tiled variance method: threshold (given or automatic), the feature
 * count and h out. 0 or 1 (printed). */
static int features_tiled(const char *input, const char *output, const bsurf_feature_options *fo,
                          size_t *plan, int quiet, features_tiles *ft, size_t *tiles, size_t *n,
                          double *h, bsurf_feature_report *rep) {
  bsurf_tile_values vals = {-1, 0, 0};
  ft->no = fo->normals;
  ft->no.threads = fo->threads;
  bsurf_tile_ops ops = {.tile_points = *plan,
                        .k = fo->normals.k,
                        .threads = fo->threads,
                        .user = ft,
                        .run = features_stage1_run,
                        .nvalues = 1,
                        .values_out = &vals};
  bsurf_tile_report tr;
  tr.sums = NULL;
  int rc = cli_tiles_run(input, output, &ops, &tr, quiet);
  *plan = ops.tile_points;
  *tiles = tr.tiles;
  double *v = NULL;
  if (!rc) {
    *n = tr.points;
    *h = tr.h;
    v = malloc((*n ? *n : 1) * sizeof(double));
    if (!v)
      rc = cli_error("out of memory");
    else if (bsurf_tile_values_read(&vals, 0, *n, v) != BSURF_OK)
      rc = cli_error("%s: cannot read the scratch file of the first stage", input);
  }
  bsurf_status st = BSURF_OK;
  if (!rc && isnan(fo->threshold))
    st = bsurf_tail_threshold(v, *n, fo->tail_rule, &ft->threshold);
  else
    ft->threshold = fo->threshold;
  if (st != BSURF_OK) rc = cli_error("%s: %s", input, bsurf_strerror(st));
  memset(rep, 0, sizeof *rep);
  rep->threshold = ft->threshold;
  for (size_t i = 0; !rc && i < *n; i++)
    rep->feature_points += v[i] > ft->threshold;
  free(v);
  if (!rc) {
    ops.prepare = features_prepare;
    rc = cli_tiles_map(input, output, &ops, &vals, features_map, "features", quiet);
  }
  bsurf_tile_values_close(&vals);
  return rc;
}

/* The tiled distance method and the variance method's null rule: the
 * library's chains of tiled stages (bsurf_features_distance_tiled and
 * bsurf_features_variance_tiled, src/tile/features_tiled.c). 0 or 1. */
typedef struct features_distance_arg {
  const bsurf_feature_options *fo;
  bsurf_feature_report *rep;
} features_distance_arg;

static bsurf_status features_distance_fn(void *arg, const char *input, const char *output,
                                         bsurf_tile_ops *ops, bsurf_tile_report *rep,
                                         bsurf_failure *err) {
  const features_distance_arg *a = arg;
  return a->fo->method == BSURF_FEATURES_DISTANCE
             ? bsurf_features_distance_tiled(input, output, ops, a->fo, a->rep, rep, err)
             : bsurf_features_variance_tiled(input, output, ops, a->fo, a->rep, rep, err);
}

static int features_distance_tiled(const char *input, const char *output,
                                   const bsurf_feature_options *fo, size_t *plan, int quiet,
                                   features_tiles *ft, size_t *tiles, size_t *n, double *h,
                                   bsurf_feature_report *rep) {
  bsurf_tile_ops ops;
  memset(&ops, 0, sizeof ops);
  ops.tile_points = *plan;
  ops.k = fo->method == BSURF_FEATURES_DISTANCE ? fo->k_max : fo->normals.k;
  ops.threads = fo->threads;
  ops.user = ft;
  ops.prepare = features_prepare;
  bsurf_tile_report tr;
  memset(&tr, 0, sizeof tr);
  features_distance_arg arg = {fo, rep};
  int rc = cli_tiles_call(input, output, &ops, &tr, quiet, features_distance_fn, &arg);
  *plan = ops.tile_points;
  *tiles = tr.tiles;
  *n = tr.points;
  *h = tr.h;
  return rc;
}

int cmd_features(const cli_command *cmd, int argc, char **argv) {
  bsurf_feature_options fo = bsurf_feature_options_default();
  const char *method = "distance", *output = NULL, *threshold_s = "auto", *tail = "null";
  const char *memory_limit = "auto";
  size_t tile_points = 0;
  int ascii = 0, json = 0, quiet = 0, force = 0;
  cli_option opts[] = {
      {0, "method", ARG_STRING, &method, "M",
       "distance (PCA distance map, 7.1) or variance (7.2); both tiled in stages", 1, 0},
      {'k', "neighbors", ARG_INT, &fo.normals.k, "K", "variance: neighbourhood of the normals", 3,
       65535},
      {'B', "bootstrap", ARG_INT, &fo.normals.bootstrap, "B",
       "variance: bootstrap replicates (>= 2)", 2, 100000},
      {0, "k-min", ARG_INT, &fo.k_min, "K", "distance: smallest neighbourhood", 3, 65535},
      {0, "k-max", ARG_INT, &fo.k_max, "K", "distance: largest neighbourhood", 3, 65535},
      {0, "k-step", ARG_INT, &fo.k_step, "S", "distance: growth step of the neighbourhood", 1,
       65535},
      {0, "ratio-threshold", ARG_DOUBLE, &fo.ratio_threshold, "T",
       "distance: T_{a/c} on lambda0/lambda2", 0, 1},
      {0, "noise-factor", ARG_DOUBLE, &fo.noise_factor, "C",
       "distance: T_{a/c} of size K = max(T, C x median f(K)) (0 = T alone)", 0, 1e6},
      {0, "derivative", ARG_DOUBLE, &fo.derivative, "D",
       "distance: threshold f + D f' instead of f (0 = off)", 0, 1e6},
      {0, "alpha", ARG_DOUBLE, &fo.alpha, "A", "distance: bilateral filter strength (Eq. 7.1)", 0,
       1},
      {0, "iterations", ARG_INT, &fo.iterations, "N", "distance: bilateral filter passes", 0,
       100000},
      {0, "filter-k", ARG_INT, &fo.filter_k, "K",
       "distance: neighbours of the filter (0 = --k-min)", 0, 65535},
      {0, "sigma-range", ARG_DOUBLE, &fo.sigma_range, "S",
       "distance: range sigma of the filter, fraction of max radius", 1e-12, 1e6},
      {0, "threshold", ARG_STRING, &threshold_s, "T",
       "distance: fraction of max(feature_dist) or auto; variance: normal_var value or auto", 1, 0},
      {0, "tail-rule", ARG_STRING, &tail, "R",
       "variance auto threshold: null (test against a flat patch at the measured noise), otsu "
       "or mad (on log normal_var)",
       1, 0},
      {0, "false-positive-rate", ARG_DOUBLE, &fo.false_positive_rate, "A",
       "variance, rule null: share of a flat area flagged", 1e-9, 0.999999},
      {0, "variance-filter-k", ARG_INT, &fo.variance_filter_k, "K",
       "variance, rule null: neighbours of the median filter (0 = K/2, 1 = none)", 0, 65535},
      CLI_OPT_SEED(fo.normals.seed),
      CLI_OPT_THREADS(fo.threads),
      CLI_OPTS_OUTPUT(output, ascii, force),
      CLI_OPTS_TILES(tile_points, memory_limit),
      CLI_OPT_DROP_INVALID,
      CLI_OPTS_REPORT(json, quiet),
  };
  char *pos[1];
  int npos;
  int rc = cli_parse(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos, 1, &npos);
  if (rc != CLI_PARSED) return rc;
  if (npos != 1) return cli_usage_error(cmd, "expected one INPUT file");
  static const char *const methods[] = {"distance", "variance"}, *const tails[] = {"otsu", "mad",
                                                                                   "null"};
  int m = cli_choice(method, methods, 2), tr = cli_choice(tail, tails, 3);
  if (m < 0) return cli_usage_error(cmd, "--method must be distance or variance, not '%s'", method);
  if (tr < 0) return cli_usage_error(cmd, "--tail-rule must be null, otsu or mad, not '%s'", tail);
  fo.method = (bsurf_feature_method)m;
  fo.tail_rule = (bsurf_tail_rule)tr;
  if (strcmp(threshold_s, "auto") != 0) {
    char *end;
    fo.threshold = strtod(threshold_s, &end);
    if (end == threshold_s || *end || !isfinite(fo.threshold))
      return cli_usage_error(cmd, "--threshold must be a number or auto, not '%s'", threshold_s);
  }
  if (fo.k_max < fo.k_min) return cli_usage_error(cmd, "--k-max must be at least --k-min");
  if (fo.filter_k > fo.k_max) return cli_usage_error(cmd, "--filter-k must not exceed --k-max");
  if (!output) return cli_usage_error(cmd, "missing -o OUTPUT");
  if (cli_check_output(output, pos[0], force)) return 1;
  const int kmax = fo.method == BSURF_FEATURES_DISTANCE ? fo.k_max : fo.normals.k;
  size_t plan = 0, tiles = 0;
  rc = cli_tiles_plan(cmd, pos[0], output, ascii, tile_points, memory_limit, kmax, 2, &plan);
  if (rc) return rc;
  double t0 = cli_now();
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  bsurf_neighbors nb;
  memset(&nb, 0, sizeof nb);
  uint8_t *feat = NULL;
  double *score = NULL;
  const int null_rule = fo.method == BSURF_FEATURES_VARIANCE && isnan(fo.threshold) &&
                        fo.tail_rule == BSURF_TAIL_NULL;
  const char *score_name = fo.method == BSURF_FEATURES_DISTANCE ? "feature_dist"
                           : null_rule                          ? "variance_z"
                                                                : "normal_var";
  const char *out_names[2] = {"feature", score_name};
  int kept[2] = {0, 0}, replaced[2] = {0, 0};
  size_t n = 0;
  double h = 0;
  bsurf_feature_report rep;
  rc = 1;
  if (plan) {
    features_tiles ft;
    memset(&ft, 0, sizeof ft);
    ft.names[0] = out_names[0];
    ft.names[1] = out_names[1];
    if (fo.method == BSURF_FEATURES_DISTANCE || null_rule
            ? features_distance_tiled(pos[0], output, &fo, &plan, quiet, &ft, &tiles, &n, &h, &rep)
            : features_tiled(pos[0], output, &fo, &plan, quiet, &ft, &tiles, &n, &h, &rep))
      goto done;
    memcpy(kept, ft.kept, sizeof kept);
    memcpy(replaced, ft.replaced, sizeof replaced);
    if (!quiet) features_warn(pos[0], out_names, kept, replaced);
    goto summary;
  }
  if (cli_read_cloud(pos[0], &c)) goto done;
  if (cli_build_neighbors(pos[0], &c, kmax, fo.threads, quiet, &nb)) goto done;
  cli_progress prog;
  bsurf_status st;
  n = c.point_count;
  h = nb.h;
  feat = malloc(n);
  score = malloc(n * sizeof(double));
  if (!feat || !score) {
    cli_error("out of memory");
    goto done;
  }
  fo.progress = cli_progress_cb;
  fo.progress_user = &prog;
  cli_progress_init(&prog, "features", quiet);
  st = bsurf_detect_features(c.xyz, &nb, &fo, feat, score, &rep);
  cli_progress_done(&prog);
  if (st != BSURF_OK) {
    cli_error("%s: %s", pos[0], cli_interrupted() ? "interrupted" : bsurf_strerror(st));
    goto done;
  }
  if (features_fields(&c, out_names, kept, replaced) != BSURF_OK) {
    cli_error("out of memory");
    goto done;
  }
  if (!quiet) features_warn(pos[0], out_names, kept, replaced);
  memcpy(bsurf_cloud_field(&c, score_name)->values, score, n * sizeof(double));
  double *fv = bsurf_cloud_field(&c, "feature")->values;
  for (size_t i = 0; i < n; i++)
    fv[i] = feat[i];
  if (cli_write_cloud(output, &c, ascii)) goto done;
summary:;
  double secs = cli_now() - t0;
  if (json) {
    cli_json j;
    json_begin(&j, stdout);
    json_str(&j, "command", "features");
    json_str(&j, "input", pos[0]);
    json_str(&j, "output", output);
    json_int(&j, "points", (long long)n);
    json_num(&j, "h", h);
    json_str(&j, "method", method);
    json_obj(&j, "parameters");
    if (fo.method == BSURF_FEATURES_DISTANCE) {
      json_int(&j, "k_min", fo.k_min);
      json_int(&j, "k_max", fo.k_max);
      json_int(&j, "k_step", fo.k_step);
      json_num(&j, "ratio_threshold", fo.ratio_threshold);
      json_num(&j, "noise_factor", fo.noise_factor);
      json_num(&j, "ratio_threshold_kmin", rep.ratio_threshold_kmin);
      json_num(&j, "derivative", fo.derivative);
      json_num(&j, "alpha", fo.alpha);
      json_int(&j, "iterations", fo.iterations);
      json_int(&j, "filter_k", fo.filter_k ? fo.filter_k : fo.k_min);
      json_num(&j, "sigma_range", fo.sigma_range);
      json_num(&j, "max_radius", rep.max_radius);
      json_int(&j, "immediate", (long long)rep.immediate);
    } else {
      json_int(&j, "k", fo.normals.k);
      json_int(&j, "bootstrap", fo.normals.bootstrap);
      json_int(&j, "seed", (long long)fo.normals.seed);
      json_str(&j, "tail_rule", tail);
      if (null_rule) {
        json_num(&j, "false_positive_rate", fo.false_positive_rate);
        json_int(&j, "variance_filter_k",
                 fo.variance_filter_k ? fo.variance_filter_k
                                      : (fo.normals.k / 2 > 1 ? fo.normals.k / 2 : 1));
        json_num(&j, "noise_level", rep.noise_level);
      }
    }
    json_str(&j, "threshold_mode", isnan(fo.threshold) ? "auto" : "value");
    json_close_obj(&j);
    json_obj(&j, "kept_input_fields");
    for (int t = 0; t < 2; t++)
      if (kept[t]) {
        char in_name[BSURF_FIELD_NAME_MAX];
        snprintf(in_name, sizeof in_name, "%s_in", out_names[t]);
        json_str(&j, out_names[t], in_name);
      }
    json_close_obj(&j);
    json_arr(&j, "replaced_input_fields");
    for (int t = 0; t < 2; t++)
      if (replaced[t]) json_str(&j, NULL, out_names[t]);
    json_close_arr(&j);
    json_num(&j, "threshold", rep.threshold);
    json_int(&j, "feature_points", (long long)rep.feature_points);
    json_int(&j, "threads", bsurf_threads_resolve(fo.threads));
    if (plan) {
      json_int(&j, "tile_points", (long long)plan);
      json_int(&j, "tiles", (long long)tiles);
      json_int(&j, "ranks", cli_mpi_ranks());
    }
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    printf("features: %zu points, h = %.6g, method %s, %.2f s\n", n, h, method, secs);
    printf("  threshold %.6g on %s (%s): %zu feature points (%.2f%%)\n", rep.threshold, score_name,
           isnan(fo.threshold) ? "auto" : "given", rep.feature_points,
           n ? 100.0 * (double)rep.feature_points / (double)n : 0.0);
    if (fo.method == BSURF_FEATURES_DISTANCE)
      printf("  T_{a/c} %.4g at k_min, max radius %.6g, %zu points stopped at k_min (set to -max "
             "radius)\n",
             rep.ratio_threshold_kmin, rep.max_radius, rep.immediate);
    cli_print_input_report(stdout);
    printf("  -> %s\n", output);
  }
  rc = 0;
done:
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
  free(feat);
  free(score);
  return rc;
}
