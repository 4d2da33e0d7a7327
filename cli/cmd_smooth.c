/* bootsurf smooth: denoising driven by the bootstrap error (thesis chapter 6). */
#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A length given as a number (model units) or "<x>h" (x times the mean
 * spacing h); with allow_w also "<x>W" (x times the mean error |W|, returned
 * in *fraction with *value = 0). Returns 0, or -1 when the text is not one. */
static int parse_length(const char *text, double h, int allow_w, double *value, double *fraction) {
  errno = 0;
  char *end = NULL;
  double x = strtod(text, &end);
  if (end == text && (text[0] == 'h' || text[0] == 'W'))
    x = 1.0; /* "h" = 1h */
  else if (end == text || errno || !isfinite(x) || x < 0)
    return -1;
  if (*end == 0) {
    *value = x;
    return 0;
  }
  if (strcmp(end, "h") == 0) {
    *value = x * h;
    return 0;
  }
  if (allow_w && strcmp(end, "W") == 0 && x > 0) {
    *value = 0;
    *fraction = x;
    return 0;
  }
  return -1;
}

static const char *const smooth_fields_all[] = {"err_632", "err_632plus", "moved", "k_hat",
                                                "d_local"};

/* ---- tiled runs (cli/tiles.c, docs/scaling.md) ----
 * Stage 1 (tiles): W_i and the naive projection or the bilateral fit of
 * every point, kept by index. |W| is then summed in index order from them,
 * as bsurf_smooth sums it. Stage 2: naive streams the points with their
 * values (bsurf_tiles_map); bilateral runs tiles again with the halo of
 * reverse neighbours (every neighbourhood that contains a tile point). */

typedef struct smooth_tiles {
  bsurf_smooth_options so; /* resolved for stage 2 */
  size_t nv;               /* stage 1 values per point */
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
  bsurf_error_report rep;
  bsurf_status st = bsurf_smooth_stage1(tile->xyz, tile->nb, &so, tile->values_out, &rep);
  sums[0] += (double)rep.replicates_skipped;
  sums[1] += (double)rep.degree_reduced;
  sums[2] += (double)rep.center_unestimated;
  return st;
}

/* The input's normals belong to the points before they moved: the output
 * has none (docs/robustness.md, "Honest truth"). */
static void drop_normals(bsurf_cloud *c) {
  free(c->normals);
  c->normals = NULL;
}

static bsurf_status smooth_prepare(void *user, bsurf_cloud *c) {
  (void)user;
  drop_normals(c);
  for (int f = 0; f < 3; f++)
    if (!bsurf_cloud_add_field(c, smooth_fields_all[f], BSURF_FLOAT32)) return BSURF_ERR_NOMEM;
  return BSURF_OK;
}

/* The smoothed positions and the fields of `count` points (local indices
 * point[], NULL: 0..) into c. */
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
                             tile->rev, &t->so, out, tile->values_out);
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
    st = bsurf_smooth_stage2(c->xyz, n, values, n, NULL, NULL, NULL, &t->so, out, moved);
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

/* The lengths given as text, converted with h (the mean spacing). */
static void smooth_lengths(bsurf_smooth_options *so, double h, const char *threshold,
                           const char *h1_text, const char *h2_text, const char *kerr_text) {
  double frac = 0;
  if (!strcmp(threshold, "auto"))
    so->threshold = NAN;
  else if (!strcmp(threshold, "none"))
    so->threshold = INFINITY;
  else
    parse_length(threshold, h, 0, &so->threshold, &frac);
  parse_length(h1_text, h, 0, &so->h1, &frac);
  if (strcmp(h2_text, "auto")) parse_length(h2_text, h, 1, &so->h2, &so->h2_fraction);
  if (strcmp(kerr_text, "auto")) parse_length(kerr_text, h, 1, &so->k_error, &so->k_error_fraction);
}

/* Sums over a values file in index order (the order of the in-memory loops):
 * sum[c] of column c, and of `moved` columns the count > 0 and the maximum. */
static int values_sums(const char *input, const bsurf_tile_values *v, double *sum, size_t *positive,
                       double *max) {
  const size_t per = 1 << 16, nv = v->nvalues;
  double *buf = malloc(per * nv * sizeof(double));
  if (!buf) return cli_error("out of memory");
  for (size_t c = 0; c < nv; c++)
    sum[c] = 0;
  *positive = 0;
  *max = 0;
  for (size_t i = 0; i < v->count; i += per) {
    size_t m = v->count - i < per ? v->count - i : per;
    if (bsurf_tile_values_read(v, i, m, buf) != BSURF_OK) {
      free(buf);
      return cli_error("%s: cannot read the scratch file of the first stage", input);
    }
    for (size_t r = 0; r < m; r++)
      for (size_t c = 0; c < nv; c++) {
        double x = buf[r * nv + c];
        sum[c] += x;
        if (c == 0) *positive += x > 0, *max = x > *max ? x : *max;
      }
  }
  free(buf);
  return 0;
}

int cmd_smooth(const cli_command *cmd, int argc, char **argv) {
  bsurf_smooth_options so = bsurf_smooth_options_default();
  const char *method = "bilateral", *order = "parallel", *estimator = "auto", *gamma = "fit",
             *center = "centroid", *threshold = "auto", *h1_text = "h", *h2_text = "auto",
             *kerr_text = "auto", *guard = "on", *output = NULL, *memory_limit = "auto";
  size_t tile_points = 0;
  int ascii = 0, json = 0, quiet = 0, force = 0;
  cli_option opts[] = {
      {0, "method", ARG_STRING, &method, "M",
       "naive (Eq. 6.1), bilateral (Algorithm 4, Eq. 6.2) or multipass (Algorithm 5; not tiled: "
       "--iterations passes reach as many rings)",
       1, 0},
      {'k', "neighbors", ARG_INT, &so.error.k, "K", "neighbourhood size K, the point included", 2,
       65535},
      {'d', "degree", ARG_INT, &so.error.degree, "M", "degree of the height polynomial, 1..4", 1,
       4},
      {'B', "bootstrap", ARG_INT, &so.error.bootstrap, "B", "bootstrap replicates per point", 0,
       100000},
      {0, "gamma", ARG_STRING, &gamma, "MODE", "no-information rate of .632+: fit, mean or max", 1,
       0},
      {0, "pca-center", ARG_STRING, &center, "C", "PCA about the centroid or the point", 1, 0},
      {0, "estimator", ARG_STRING, &estimator, "E",
       "the error W_i that weights the moves: 632, 632plus or auto (.632+ for naive, .632 "
       "otherwise)",
       1, 0},
      {0, "threshold", ARG_STRING, &threshold, "T",
       "naive: project only where W_i < T; a length (model units, or 0.5h = 0.5 x h), auto (the "
       "mean "
       "W_i) or none (every point)",
       1, 0},
      {0, "h1", ARG_STRING, &h1_text, "X",
       "bilateral: distance sigma of Eq. 6.2 (a length; h = the mean spacing)", 1, 0},
      {0, "h2", ARG_STRING, &h2_text, "X",
       "bilateral, multipass: error sigma of Eq. 6.2: a length, a multiple of |W| (e.g. 1W) or "
       "auto "
       "(2W; the thesis's multipass setting is 0.3W)",
       1, 0},
      {0, "order", ARG_STRING, &order, "O",
       "bilateral, multipass: parallel (order-independent; tiled with a halo of reverse "
       "neighbours) or "
       "sequential (the thesis's in-place sweep, one thread; not tiled: a chain over the whole "
       "cloud)",
       1, 0},
      {0, "a", ARG_DOUBLE, &so.a, "A",
       "multipass: h1 = A x d_L, the mean distance to the K_i neighbours (Eq. 6.5)", 0, 1e6},
      {0, "iterations", ARG_INT, &so.iterations, "N", "multipass: smoothing passes", 0, 1000000},
      {0, "k-min", ARG_INT, &so.k_min, "K", "multipass: the smallest neighbourhood (Eq. 6.3)", 1,
       65535},
      {0, "k-error", ARG_STRING, &kerr_text, "X",
       "multipass: the error at which K_i reaches --k-min (Eq. 6.4): a length, a multiple of |W| "
       "(e.g. "
       "2W) or auto (3W; the thesis's is 1W)",
       1, 0},
      {0, "guard", ARG_STRING, &guard, "G",
       "every method: on (two sheets split at a gap between their residuals are fitted apart; a "
       "fit biased at its centre by a second sheet or an edge, by a t test on its nearest "
       "points' residuals, is made again from fewer points, or moves nothing) or off (the "
       "thesis's methods as written)",
       1, 0},
      CLI_OPT_SEED(so.error.seed),
      CLI_OPT_THREADS(so.error.threads),
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
  if (!output) return cli_usage_error(cmd, "-o OUTPUT is required");
  static const char *const methods[] = {"naive", "bilateral", "multipass"};
  static const char *const orders[] = {"parallel", "sequential"};
  static const char *const estimators[] = {"auto", "632", "632plus"};
  static const char *const gammas[] = {"fit", "mean", "max"};
  static const char *const centers[] = {"centroid", "point"};
  int mi = cli_choice(method, methods, 3), oi = cli_choice(order, orders, 2);
  int ei = cli_choice(estimator, estimators, 3), g = cli_choice(gamma, gammas, 3);
  int pc = cli_choice(center, centers, 2);
  static const char *const onoff[] = {"off", "on"};
  int gi = cli_choice(guard, onoff, 2);
  if (gi < 0) return cli_usage_error(cmd, "--guard must be on or off, not '%s'", guard);
  so.guard = gi;
  if (mi < 0)
    return cli_usage_error(cmd, "--method must be naive, bilateral or multipass, not '%s'", method);
  if (oi < 0)
    return cli_usage_error(cmd, "--order must be parallel or sequential, not '%s'", order);
  if (ei < 0)
    return cli_usage_error(cmd, "--estimator must be auto, 632 or 632plus, not '%s'", estimator);
  if (g < 0) return cli_usage_error(cmd, "--gamma must be fit, mean or max, not '%s'", gamma);
  if (pc < 0)
    return cli_usage_error(cmd, "--pca-center must be centroid or point, not '%s'", center);
  so.method = (bsurf_smooth_method)mi;
  so.order = (bsurf_smooth_order)oi;
  so.estimator = (bsurf_smooth_estimator)ei;
  so.error.gamma = (bsurf_gamma_mode)g;
  so.error.pca_center = (bsurf_pca_center)pc;
  int terms = (so.error.degree + 1) * (so.error.degree + 2) / 2;
  if (so.error.k < terms)
    return cli_usage_error(cmd, "K = %d is too small for degree %d: a fit needs at least %d points",
                           so.error.k, so.error.degree, terms);
  if (so.k_min > so.error.k)
    return cli_usage_error(cmd, "--k-min %d is larger than K = %d", so.k_min, so.error.k);
  /* Lengths are checked now (with h = 1) and converted once h is known. */
  double dummy, frac;
  if (strcmp(threshold, "auto") && strcmp(threshold, "none") &&
      parse_length(threshold, 1, 0, &dummy, &frac))
    return cli_usage_error(
        cmd, "--threshold must be a length (e.g. 0.01 or 0.5h), auto or none, not '%s'", threshold);
  if (parse_length(h1_text, 1, 0, &dummy, &frac) || dummy <= 0)
    return cli_usage_error(cmd, "--h1 must be a positive length (e.g. 0.01 or 1.5h), not '%s'",
                           h1_text);
  if (strcmp(h2_text, "auto") &&
      (parse_length(h2_text, 1, 1, &dummy, &frac) || (dummy <= 0 && frac <= 0)))
    return cli_usage_error(
        cmd, "--h2 must be a positive length, a multiple of |W| (e.g. 1W) or auto, not '%s'",
        h2_text);
  if (strcmp(kerr_text, "auto") &&
      (parse_length(kerr_text, 1, 1, &dummy, &frac) || (dummy <= 0 && frac <= 0)))
    return cli_usage_error(
        cmd, "--k-error must be a positive length, a multiple of |W| or auto, not '%s'", kerr_text);
  if (cli_check_output(output, pos[0], force)) return 1;
  size_t plan = 0, tiles = 0;
  const size_t nv = bsurf_smooth_stage_values(&so);
  /* in memory: the cloud, its fields, and per point the fits (bilateral) */
  rc = cli_tiles_plan(cmd, pos[0], output, ascii, tile_points, memory_limit, so.error.k,
                      (int)(6 + nv), &plan);
  if (rc) return rc;
  if (plan && so.method == BSURF_SMOOTH_MULTIPASS)
    return cli_error(
        "%s: smooth --method multipass is not available in tiled runs: it runs --iterations passes "
        "(300), each reaching one neighbourhood ring further, so a tile would need a halo of "
        "that many rings",
        pos[0]);
  if (plan && !nv)
    return cli_error(
        "%s: smooth --order sequential is not available in tiled runs: its sweep fits each "
        "neighbourhood to the points every earlier neighbourhood of the whole cloud has moved, "
        "a chain as long as the cloud (--order parallel is tiled)",
        pos[0]);

  double t0 = cli_now(), compute = 0;
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  double *smoothed = NULL, h = 0, means[5];
  size_t npoints = 0;
  int nfields = so.method == BSURF_SMOOTH_MULTIPASS ? 5 : 3;
  bsurf_smooth_report rep;
  memset(&rep, 0, sizeof rep);
  if (plan) {
    smooth_tiles st1;
    memset(&st1, 0, sizeof st1);
    st1.so = so;
    st1.nv = nv;
    bsurf_tile_values vals = {-1, 0, 0}, moved = {-1, 0, 0};
    double sums[SMOOTH_SUMS] = {0}, vs[64];
    bsurf_tile_ops ops = {.tile_points = plan,
                          .k = so.error.k,
                          .threads = so.error.threads,
                          .user = &st1,
                          .run = smooth_stage1_run,
                          .nsums = SMOOTH_SUMS,
                          .nvalues = nv,
                          .values_out = &vals};
    bsurf_tile_report tr;
    tr.sums = sums;
    size_t positive;
    double mx;
    /* stage 1, then |W| and the fields' means in index order */
    rc = cli_tiles_run(pos[0], output, &ops, &tr, quiet) ||
         values_sums(pos[0], &vals, vs, &positive, &mx);
    plan = ops.tile_points;
    tiles = tr.tiles;
    if (rc) goto tiled_done;
    npoints = tr.points;
    h = tr.h;
    rep.error.replicates_total = npoints * (size_t)so.error.bootstrap;
    rep.error.replicates_skipped = (size_t)sums[0];
    rep.error.degree_reduced = (size_t)sums[1];
    rep.error.center_unestimated = (size_t)sums[2];
    means[0] = vs[0] / (double)npoints;
    means[1] = vs[1] / (double)npoints;
    rep.mean_error = vs[bsurf_smooth_w_column(&so)] / (double)npoints;
    smooth_lengths(&st1.so, h, threshold, h1_text, h2_text, kerr_text);
    bsurf_smooth_resolve(&st1.so, h, rep.mean_error);
    rep.h = h;
    rep.threshold = st1.so.threshold;
    rep.h1 = st1.so.h1;
    rep.h2 = st1.so.h2;
    /* stage 2: the output */
    if (so.method == BSURF_SMOOTH_NAIVE) {
      ops.prepare = smooth_prepare;
      rc = cli_tiles_map(pos[0], output, &ops, &vals, smooth_map, "smooth", quiet);
      if (rc) goto tiled_done;
      rep.projected = st1.projected;
    } else {
      bsurf_tile_ops ops2 = {.tile_points = plan,
                             .k = so.error.k,
                             .threads = so.error.threads,
                             .user = &st1,
                             .prepare = smooth_prepare,
                             .run = smooth_stage2_run,
                             .nvalues = 1,
                             .values_out = &moved,
                             .values_in = &vals,
                             .reverse = 1};
      bsurf_tile_report tr2;
      tr2.sums = NULL;
      rc = cli_tiles_run(pos[0], output, &ops2, &tr2, quiet);
      if (rc) goto tiled_done;
    }
    /* how far the points moved, in index order: naive's map ran in it;
     * bilateral's second stage kept them by index */
    if (so.method == BSURF_SMOOTH_NAIVE) {
      rep.moved_points = st1.moved_points;
      rep.moved_max = st1.moved_max;
      means[2] = st1.moved_sum / (double)npoints;
    } else {
      double ms;
      rc = values_sums(pos[0], &moved, &ms, &rep.moved_points, &rep.moved_max);
      means[2] = ms / (double)npoints;
    }
    rep.moved_mean = means[2];
  tiled_done:
    bsurf_tile_values_close(&vals);
    bsurf_tile_values_close(&moved);
    if (rc) return 1;
    compute = cli_now() - t0;
    goto summary;
  }
  if (cli_read_cloud(pos[0], &c)) return 1;
  bsurf_neighbors nb;
  if (cli_build_neighbors(pos[0], &c, so.error.k, so.error.threads, quiet, &nb)) {
    rc = 1;
    goto done;
  }
  h = nb.h;
  smooth_lengths(&so, h, threshold, h1_text, h2_text, kerr_text);
  for (int f = 0; f < nfields; f++) {
    if (!bsurf_cloud_add_field(&c, smooth_fields_all[f], BSURF_FLOAT32)) {
      bsurf_neighbors_free(&nb);
      rc = cli_error("out of memory");
      goto done;
    }
  }
  bsurf_smooth_fields sf;
  memset(&sf, 0, sizeof sf);
  sf.err_632 = bsurf_cloud_field(&c, "err_632")->values;
  sf.err_632plus = bsurf_cloud_field(&c, "err_632plus")->values;
  sf.moved = bsurf_cloud_field(&c, "moved")->values;
  if (nfields == 5) {
    sf.k_hat = bsurf_cloud_field(&c, "k_hat")->values;
    sf.d_local = bsurf_cloud_field(&c, "d_local")->values;
  }
  smoothed = malloc(c.point_count * 3 * sizeof(double));
  if (!smoothed) {
    bsurf_neighbors_free(&nb);
    rc = cli_error("out of memory");
    goto done;
  }
  cli_progress prog;
  cli_progress_init(&prog, "smooth", quiet);
  so.error.progress = cli_progress_cb;
  so.error.progress_user = &prog;
  double tc = cli_now();
  bsurf_status st = bsurf_smooth(c.xyz, &nb, &so, smoothed, &sf, &rep);
  compute = cli_now() - tc;
  cli_progress_done(&prog);
  bsurf_neighbors_free(&nb);
  if (st != BSURF_OK) {
    rc = cli_error("%s: %s", pos[0], cli_interrupted() ? "interrupted" : bsurf_strerror(st));
    goto done;
  }
  memcpy(c.xyz, smoothed, c.point_count * 3 * sizeof(double));
  drop_normals(&c);
  if (cli_write_cloud(output, &c, ascii)) {
    rc = 1;
    goto done;
  }
  npoints = c.point_count;
  for (int f = 0; f < nfields; f++)
    means[f] = cli_field_mean(bsurf_cloud_field(&c, smooth_fields_all[f]), npoints);
summary:;
  double secs = cli_now() - t0;
  const char *est_used =
      so.estimator == BSURF_SMOOTH_EST_632PLUS ||
              (so.estimator == BSURF_SMOOTH_EST_DEFAULT && so.method == BSURF_SMOOTH_NAIVE)
          ? "err_632plus"
          : "err_632";
  double hh = h > 0 ? h : 1;
  if (json) {
    cli_json j;
    json_begin(&j, stdout);
    json_str(&j, "command", "smooth");
    json_str(&j, "input", pos[0]);
    json_str(&j, "output", output);
    json_str(&j, "method", method);
    json_int(&j, "points", (long long)npoints);
    json_num(&j, "h", h);
    json_int(&j, "k", so.error.k);
    json_int(&j, "degree", so.error.degree);
    json_int(&j, "bootstrap", so.error.bootstrap);
    json_int(&j, "seed", (long long)so.error.seed);
    json_int(&j, "threads", bsurf_threads_resolve(so.error.threads));
    json_str(&j, "estimator", est_used);
    json_num(&j, "mean_error", rep.mean_error);
    json_num(&j, "mean_error_h", rep.mean_error / hh);
    if (so.method == BSURF_SMOOTH_NAIVE) {
      json_num(&j, "threshold", rep.threshold);
      json_num(&j, "threshold_h", rep.threshold / hh);
      json_int(&j, "projected", (long long)rep.projected);
    } else {
      json_str(&j, "order", order);
      json_num(&j, "h2", rep.h2);
      json_num(&j, "h2_h", rep.h2 / hh);
    }
    if (so.method == BSURF_SMOOTH_BILATERAL) {
      json_num(&j, "h1", rep.h1);
      json_num(&j, "h1_h", rep.h1 / hh);
    }
    if (so.method == BSURF_SMOOTH_MULTIPASS) {
      json_num(&j, "a", so.a);
      json_int(&j, "iterations", rep.iterations);
      json_int(&j, "k_min", so.k_min);
      json_num(&j, "k_error", rep.k_error);
    }
    json_int(&j, "replicates_skipped", (long long)rep.error.replicates_skipped);
    json_int(&j, "degree_reduced", (long long)rep.error.degree_reduced);
    json_int(&j, "moved_points", (long long)rep.moved_points);
    json_num(&j, "moved_mean", rep.moved_mean);
    json_num(&j, "moved_max", rep.moved_max);
    json_num(&j, "moved_mean_h", rep.moved_mean / hh);
    json_num(&j, "moved_max_h", rep.moved_max / hh);
    /* lengths only (mean and mean / h); K_i is a count */
    static const char *const length_fields[] = {"err_632", "err_632plus", "moved", "d_local"};
    double lmeans[4] = {means[0], means[1], means[2], nfields == 5 ? means[4] : NAN};
    json_means(&j, length_fields, lmeans, nfields == 5 ? 4 : 3, h);
    if (nfields == 5) json_num(&j, "k_hat_mean", means[3]);
    if (plan) {
      json_int(&j, "tile_points", (long long)plan);
      json_int(&j, "tiles", (long long)tiles);
      json_int(&j, "ranks", cli_mpi_ranks());
    }
    json_num(&j, "compute_seconds", compute);
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    printf("smooth: %s, %zu points, h = %.6g, K = %d, degree %d, B = %d, %.2f s\n", method, npoints,
           h, so.error.k, so.error.degree, so.error.bootstrap, secs);
    printf("  W = %s, mean %.6g (%.4g h)\n", est_used, rep.mean_error, rep.mean_error / hh);
    if (so.method == BSURF_SMOOTH_NAIVE)
      printf("  threshold %.6g (%.4g h): %zu of %zu points projected\n", rep.threshold,
             rep.threshold / hh, rep.projected, npoints);
    else if (so.method == BSURF_SMOOTH_BILATERAL)
      printf("  order %s, h1 = %.6g (%.4g h), h2 = %.6g (%.4g h)\n", order, rep.h1, rep.h1 / hh,
             rep.h2, rep.h2 / hh);
    else
      printf("  order %s, %d passes, h1 = %g d_L, h2 = %.6g (%.4g h), K_i from %d to %d\n", order,
             rep.iterations, so.a, rep.h2, rep.h2 / hh, so.k_min, so.error.k);
    printf("  moved %zu points: mean %.4g h, max %.4g h\n", rep.moved_points, rep.moved_mean / hh,
           rep.moved_max / hh);
    cli_print_input_report(stdout);
    printf("  -> %s\n", output);
  }
done:
  free(smoothed);
  bsurf_cloud_free(&c);
  return rc;
}
