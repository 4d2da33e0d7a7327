/* bootsurf smooth: denoising driven by the bootstrap error (thesis chapter 6). */
#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A length given as a number (model units) or "<x>h" (x times the mean
 * spacing h, which the job knows: *in_h = 1); with allow_w also "<x>W" (x
 * times the mean error |W|, returned in *fraction with *value = 0). Returns
 * 0, or -1 when the text is not one. */
static int parse_length(const char *text, int allow_w, double *value, int *in_h, double *fraction) {
  errno = 0;
  char *end = NULL;
  double x = strtod(text, &end);
  if (end == text && (text[0] == 'h' || text[0] == 'W'))
    x = 1.0; /* "h" = 1h */
  else if (end == text || errno || !isfinite(x) || x < 0)
    return -1;
  *in_h = 0;
  if (*end == 0) {
    *value = x;
    return 0;
  }
  if (strcmp(end, "h") == 0) {
    *value = x;
    *in_h = 1;
    return 0;
  }
  if (allow_w && strcmp(end, "W") == 0 && x > 0) {
    *value = 0;
    *fraction = x;
    return 0;
  }
  return -1;
}

/* The scale rule's cap under the memory limit (docs/smoothing.md,
 * "Memory"): where the cloud fits in memory with neighbourhoods of K but
 * not of the cap K_max, an explicit --k-max is refused (naming --k-max and
 * --memory-limit), the default one (8 K) is lowered to the widest K that
 * fits, with a warning; jo->smooth.k_max and *sp are then of that K. Tiled
 * runs (--tile-points, several ranks, or too little memory for K itself)
 * are left to cli_tiles_plan_bytes. 0, or the error printed (1, or 2). */
static int smooth_scale_cap(const cli_command *cmd, const char *input, bsurf_smooth_job_options *jo,
                            bsurf_smooth_job_plan *sp, int nfields, size_t tile_points,
                            const char *memory_limit) {
  if (sp->k_max <= sp->k || tile_points || cli_mpi_ranks() > 1) return 0;
  double limit = 0;
  uint64_t n = 0;
  if (cli_memory_limit(cmd, memory_limit, &limit)) return CLI_USAGE;
  if (!(limit > 0)) return 0;
  if (cli_read_header(input, &n)) return 1;
  const double need = cli_memory_need(input, n, sp->k, nfields, sp->point_bytes);
  if (need <= limit || n == 0) return 0;
  /* the widest K whose run fits: point_bytes falls by k_max_bytes a unit */
  const double over = (need - limit) / ((double)n * sp->k_max_bytes);
  const int fits = sp->k_max - (int)ceil(over);
  const double at_k = need - (double)n * sp->k_max_bytes * (sp->k_max - sp->k);
  if (fits < sp->k && at_k > limit) return 0; /* not even K: tiles */
  if (jo->smooth.k_max > 0)
    return cli_error("%s: smooth --k-max %d needs about %.3g GB in memory (the scale rule's "
                     "neighbourhoods of up to %d points), more than --memory-limit %.3g GB: give "
                     "--k-max %d or less, or a larger --memory-limit",
                     input, jo->smooth.k_max, need / 1e9, sp->k_max, limit / 1e9,
                     fits > sp->k ? fits : sp->k);
  const int cap = fits > sp->k ? fits : sp->k;
  cli_warn("%s: the scale rule's K is capped at %d by --memory-limit %.3g GB (its default cap, "
           "8 K = %d, needs about %.3g GB; --k-max or --memory-limit change it)",
           input, cap, limit / 1e9, sp->k_max, need / 1e9);
  jo->smooth.k_max = cap;
  if (bsurf_smooth_job_memory(jo, sp) != BSURF_OK) return cli_error("%s", bsurf_last_message());
  return 0;
}

int cmd_smooth(const cli_command *cmd, int argc, char **argv) {
  bsurf_smooth_options so = bsurf_smooth_options_default();
  const char *method = "auto", *order = "parallel", *estimator = "auto", *gamma = "fit",
             *center = "centroid", *threshold = "auto", *h1_text = "auto", *h2_text = "auto",
             *kerr_text = "none", *guard = "on", *dtest = "auto", *output = NULL,
             *memory_limit = "auto", *a_text = "auto", *iter_text = "auto";
  size_t tile_points = 0;
  int ascii = 0, json = 0, quiet = 0, force = 0;
  cli_option opts[] = {
      {0, "method", ARG_STRING, &method, "M",
       "naive (Eq. 6.1), bilateral (Algorithm 4, Eq. 6.2), multipass (Algorithm 5; not tiled: "
       "--iterations passes reach as many rings) or auto (multipass in memory, bilateral in "
       "tiled runs)",
       1, 0},
      {'k', "neighbors", ARG_INT, &so.error.k, "K", "neighbourhood size K, the point included", 2,
       65535},
      {'d', "degree", ARG_INT, &so.error.degree, "M", "degree of the height polynomial, 1..4", 1,
       4},
      {'B', "bootstrap", ARG_INT, &so.error.bootstrap, "B",
       "bootstrap replicates per point (at least 1: W_i is a bootstrap error)", 1, 100000},
      {0, "gamma", ARG_STRING, &gamma, "MODE", "no-information rate of .632+: fit, mean or max", 1,
       0},
      {0, "pca-center", ARG_STRING, &center, "C", "PCA about the centroid or the point", 1, 0},
      {0, "estimator", ARG_STRING, &estimator, "E",
       "the error W_i that weights the moves: 632, 632plus or auto (.632+ for naive, .632 "
       "otherwise)",
       1, 0},
      {0, "threshold", ARG_STRING, &threshold, "T",
       "naive: project only where W_i < T; a length (model units, or 0.5h = 0.5 x h), "
       "auto (the mean W_i) or none (every point)",
       1, 0},
      {0, "h1", ARG_STRING, &h1_text, "X",
       "bilateral: distance sigma of Eq. 6.2: a length (h = the mean spacing) or auto "
       "(sqrt(h^2 + 2 sigma^2), sigma the guard's noise estimate; h with --guard off)",
       1, 0},
      {0, "h2", ARG_STRING, &h2_text, "X",
       "bilateral, multipass: error sigma of Eq. 6.2: a length, a multiple of |W| (e.g. 1W) "
       "or auto (bilateral 2W; multipass 2 W_n, W_n the median W_i, which puts G's "
       "inflection where a fit's misfit equals the noise; the thesis's multipass setting is "
       "0.3W)",
       1, 0},
      {0, "order", ARG_STRING, &order, "O",
       "bilateral, multipass: parallel (order-independent; tiled with a halo of reverse "
       "neighbours) or sequential (the thesis's in-place sweep, one thread; not tiled: a "
       "chain over the whole cloud)",
       1, 0},
      {0, "a", ARG_STRING, &a_text, "A",
       "multipass: h1 = A x d_L, the mean distance to the K_i neighbours (Eq. 6.5), or auto "
       "(A = 1.5 sqrt(pi / K_i): h1 = sqrt((A d_L)^2 + 2 noise^2), the local spacing widened "
       "by the guard's noise estimate; the thesis's A is 0.1)",
       1, 0},
      {0, "iterations", ARG_STRING, &iter_text, "N",
       "multipass: N smoothing passes (the thesis: 300), or auto (stop after the first pass "
       "whose mean squared move is below the fits' own prediction variance, sigma^2 mean(kappa_i "
       "p_i / K_i), sigma the guard's noise, kappa_i the share of it fit i's K-ball keeps; at "
       "most 300)",
       1, 0},
      {0, "k-min", ARG_INT, &so.k_min, "K",
       "multipass: the smallest neighbourhood (Eq. 6.3), at least 3 (the points of a plane fit)", 3,
       65535},
      {0, "k-max", ARG_INT, &so.k_max, "K",
       "multipass with the guard: the largest K the noise may widen the neighbourhood to: where "
       "the guard's noise is heavy against the K-ball (which then holds only the points near "
       "its centre's height, and its fit keeps the centre's own noise), K grows to the smallest "
       "size whose ball drops no more of the noise variance (1 - kappa) than its fit's own "
       "prediction variance holds (p / K), and multipass runs on those neighbourhoods (0 = 8 K, "
       "lowered to what --memory-limit holds; K = K stays fixed)",
       0, 65535},
      {0, "k-error", ARG_STRING, &kerr_text, "X",
       "multipass: the error at which K_i reaches --k-min (Eq. 6.4): a length, a multiple "
       "of |W| (e.g. 2W; the thesis's is 1W) or none (K_i = K; the guard halves a neighbourhood "
       "whose fit is biased at its centre)",
       1, 0},
      {0, "guard", ARG_STRING, &guard, "G",
       "every method: on (two sheets split at a gap between their residuals, or where the "
       "residuals fall in two groups tighter than any unimodal noise leaves them, are fitted "
       "apart; a "
       "fit biased at its centre by a second sheet or an edge, by a t test on its nearest "
       "points' residuals, is made again from fewer points, or moves nothing; a fit whose "
       "residual variance shows more misfit than noise -- above twice the cloud's noise "
       "variance, the lower decile over the fits (each scaled by the share of the noise its "
       "interval and its K-ball keep), or the larger of that and the level normals --select-k "
       "reads where the fits are blind to the noise (more than 5% of the points' 80 nearest "
       "cross-sections of the surface, as a CAD mesh's vertices on rings), at the 5% level -- "
       "moves nothing) or off "
       "(the thesis's methods as written)",
       1, 0},
      {0, "degree-test", ARG_STRING, &dtest, "T",
       "with the guard: on (each sheet's fit takes the degree, from -d down to a plane, of "
       "least estimated prediction error, Mallows' Cp), off (the degree of -d) or auto (on for "
       "bilateral and multipass, off for naive)",
       1, 0},
      CLI_OPT_SEED(so.error.seed),
      CLI_OPT_THREADS(so.error.threads),
      CLI_OPTS_JOB(output, ascii, force, tile_points, memory_limit, json, quiet),
  };
  char *pos[1];
  int rc = cli_parse_input(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos);
  if (rc != CLI_PARSED) return rc;
  if (!output) return cli_usage_error(cmd, "missing -o OUTPUT");
  static const char *const methods[] = {"naive", "bilateral", "multipass", "auto"};
  static const char *const orders[] = {"parallel", "sequential"};
  static const char *const estimators[] = {"auto", "632", "632plus"};
  int mi = cli_choice(method, methods, 4), oi = cli_choice(order, orders, 2);
  int ei = cli_choice(estimator, estimators, 3);
  static const char *const onoff[] = {"off", "on"};
  int gi = cli_choice(guard, onoff, 2);
  if (gi < 0) return cli_usage_error(cmd, "--guard must be on or off, not '%s'", guard);
  so.guard = gi;
  static const char *const offonauto[] = {"off", "on", "auto"};
  int di = cli_choice(dtest, offonauto, 3);
  if (di < 0) return cli_usage_error(cmd, "--degree-test must be auto, on or off, not '%s'", dtest);
  so.degree_test = di == 2 ? -1 : di;
  if (mi < 0)
    return cli_usage_error(cmd, "--method must be naive, bilateral, multipass or auto, not '%s'",
                           method);
  if (oi < 0)
    return cli_usage_error(cmd, "--order must be parallel or sequential, not '%s'", order);
  if (ei < 0)
    return cli_usage_error(cmd, "--estimator must be auto, 632 or 632plus, not '%s'", estimator);
  if (cli_gamma(cmd, gamma, &so.error.gamma) || cli_pca_center(cmd, center, &so.error.pca_center))
    return CLI_USAGE;
  so.method = (bsurf_smooth_method)mi;
  so.order = (bsurf_smooth_order)oi;
  so.estimator = (bsurf_smooth_estimator)ei;
  if (cli_check_terms(cmd, so.error.k, so.error.degree)) return CLI_USAGE;
  if (so.k_min > so.error.k)
    return cli_usage_error(cmd, "--k-min %d is larger than K = %d", so.k_min, so.error.k);
  if (so.k_max && so.k_max < so.error.k)
    return cli_usage_error(cmd, "--k-max %d is smaller than K = %d", so.k_max, so.error.k);
  /* Lengths: in model units, or in units of h, which the job knows. */
  bsurf_smooth_job_options jo = bsurf_smooth_job_options_default();
  double frac = 0;
  if (!strcmp(threshold, "none"))
    so.threshold = INFINITY;
  else if (strcmp(threshold, "auto") &&
           parse_length(threshold, 0, &so.threshold, &jo.threshold_in_h, &frac))
    return cli_usage_error(
        cmd, "--threshold must be a length (e.g. 0.01 or 0.5h), auto or none, not '%s'", threshold);
  if (strcmp(h1_text, "auto") &&
      (parse_length(h1_text, 0, &so.h1, &jo.h1_in_h, &frac) || so.h1 <= 0))
    return cli_usage_error(
        cmd, "--h1 must be a positive length (e.g. 0.01 or 1.5h) or auto, not '%s'", h1_text);
  frac = 0;
  if (strcmp(h2_text, "auto") &&
      (parse_length(h2_text, 1, &so.h2, &jo.h2_in_h, &frac) || (so.h2 <= 0 && frac <= 0)))
    return cli_usage_error(
        cmd, "--h2 must be a positive length, a multiple of |W| (e.g. 1W) or auto, not '%s'",
        h2_text);
  if (frac > 0) so.h2_fraction = frac;
  frac = 0;
  if (strcmp(kerr_text, "none") && strcmp(kerr_text, "auto") &&
      (parse_length(kerr_text, 1, &so.k_error, &jo.k_error_in_h, &frac) ||
       (so.k_error <= 0 && frac <= 0)))
    return cli_usage_error(
        cmd, "--k-error must be a positive length, a multiple of |W| or none, not '%s'", kerr_text);
  if (frac > 0) so.k_error_fraction = frac;
  if (strcmp(a_text, "auto")) {
    char *end = NULL;
    errno = 0;
    so.a = strtod(a_text, &end);
    /* A = 0 would make h1 = 0: every point moved by its own fit alone */
    if (end == a_text || *end || errno || !isfinite(so.a) || so.a <= 0)
      return cli_usage_error(cmd, "--a must be a positive number or auto, not '%s'", a_text);
  }
  if (strcmp(iter_text, "auto")) {
    char *end = NULL;
    errno = 0;
    long v = strtol(iter_text, &end, 10);
    if (end == iter_text || *end || errno || v < 0 || v > 1000000)
      return cli_usage_error(cmd, "--iterations must be 0..1000000 or auto, not '%s'", iter_text);
    so.iterations = (int)v;
  }
  if (cli_check_output(output, pos[0], force)) return 1;
  jo.smooth = so;
  size_t plan = 0;
  const size_t nv = bsurf_smooth_job_point_values(&jo);
  /* in memory: the cloud, its fields and the job's arrays, counting the
   * widest neighbourhoods the scale rule may search (bsurf_smooth_job_memory);
   * a tile: its fields and the first stage's values */
  bsurf_smooth_job_plan sp;
  if (bsurf_smooth_job_memory(&jo, &sp) != BSURF_OK) return cli_error("%s", bsurf_last_message());
  const int nf = sp.field_count + (int)nv;
  rc = smooth_scale_cap(cmd, pos[0], &jo, &sp, nf, tile_points, memory_limit);
  if (rc) return rc;
  /* a tiled run of auto runs bilateral: its stage values and arrays */
  bsurf_smooth_job_options tj = jo;
  if (tj.smooth.method == BSURF_SMOOTH_AUTO) tj.smooth.method = BSURF_SMOOTH_BILATERAL;
  bsurf_smooth_job_plan tp;
  if (bsurf_smooth_job_memory(&tj, &tp) != BSURF_OK) return cli_error("%s", bsurf_last_message());
  rc = cli_tiles_plan_split(
      cmd, pos[0], output, ascii, tile_points, memory_limit, so.error.k, nf, sp.point_bytes,
      tp.field_count + (int)bsurf_smooth_job_point_values(&tj), tp.point_bytes, 0, &plan);
  if (rc) return rc;
  if (plan && so.method == BSURF_SMOOTH_MULTIPASS)
    return cli_error(
        "%s: smooth --method multipass is not available in tiled runs: it runs --iterations "
        "passes, "
        "each reaching one neighbourhood ring further, so a tile would need a halo of that many "
        "rings (--method auto, the default, runs bilateral in tiles)",
        pos[0]);
  if (plan && !nv)
    return cli_error(
        "%s: smooth --order sequential is not available in tiled runs: its sweep fits each "
        "neighbourhood to the points every earlier neighbourhood of the whole cloud has moved, "
        "a chain as long as the cloud (--order parallel is tiled)",
        pos[0]);

  double t0 = cli_now();
  bsurf_cloud c;
  bsurf_job_io io;
  cli_progress prog;
  if (cli_job_io(&io, pos[0], output, plan, &c, &prog, "smooth", quiet)) return 1;
  jo.smooth.error.progress = cli_progress_cb;
  jo.smooth.error.progress_user = &prog;
  bsurf_smooth_job_summary sum;
  bsurf_failure where = {0, -1, ""};
  double tc = cli_now();
  bsurf_status st = bsurf_smooth_job(&io, &jo, &sum, &where);
  double compute = cli_now() - tc;
  rc = 1;
  if (cli_job_done(&prog, pos[0], output, plan, st, &where, sum.duplicates)) goto done;
  if (!plan && cli_write_cloud(output, &c, ascii)) goto done;
  const bsurf_smooth_report rep = sum.report;
  const size_t npoints = sum.points;
  const double h = sum.h, *means = sum.means;
  const int nfields = sum.field_count;
  const char *est_used = sum.estimator;
  so.method = sum.method; /* auto resolved: what ran */
  method = methods[sum.method];
  double secs = cli_now() - t0;
  double hh = h > 0 ? h : 1;
  if (json) {
    cli_json j = json_start("smooth", pos[0], output);
    json_str(&j, "method", method);
    json_points_h(&j, npoints, h);
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
      if (so.a >= 0)
        json_num(&j, "a", so.a);
      else
        json_str(&j, "a", "auto");
      json_int(&j, "iterations", rep.iterations);
      json_int(&j, "k_used", rep.k);
      json_int(&j, "k_min", so.k_min);
      json_int(&j, "k_max", sp.k_max); /* the scale rule's cap, as the memory plan left it */
      json_num(&j, "k_error", rep.k_error);
    }
    if (so.guard) {
      json_num(&j, "noise", rep.noise);
      json_num(&j, "noise_h", rep.noise / hh);
      json_num(&j, "noise_fits", rep.noise_fits);
      json_num(&j, "noise_select", rep.noise_select);
      json_num(&j, "section_share", rep.section_share);
      json_int(&j, "misfit_fits", (long long)rep.misfit_fits);
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
    if (plan) json_tiles(&j, sum.tile_points, sum.tiles);
    json_num(&j, "compute_seconds", compute);
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    printf("smooth: %s, %zu points, h = %.6g, K = %d, degree %d, B = %d, %.2f s\n", method, npoints,
           h, rep.k > 0 ? rep.k : so.error.k, so.error.degree, so.error.bootstrap, secs);
    printf("  W = %s, mean %.6g (%.4g h)\n", est_used, rep.mean_error, rep.mean_error / hh);
    if (so.method == BSURF_SMOOTH_NAIVE)
      printf("  threshold %.6g (%.4g h): %zu of %zu points projected\n", rep.threshold,
             rep.threshold / hh, rep.projected, npoints);
    else if (so.method == BSURF_SMOOTH_BILATERAL)
      printf("  order %s, h1 = %.6g (%.4g h), h2 = %.6g (%.4g h)\n", order, rep.h1, rep.h1 / hh,
             rep.h2, rep.h2 / hh);
    else
      printf("  order %s, %d pass%s, h1 = %s d_L, h2 = %.6g (%.4g h), K_i from %d to %d\n", order,
             rep.iterations, rep.iterations == 1 ? "" : "es",
             strcmp(a_text, "auto") ? a_text : "(1.5 sqrt(pi / K_i))", rep.h2, rep.h2 / hh,
             so.k_min, rep.k > 0 ? rep.k : so.error.k);
    if (so.guard) {
      char sel[128];
      if (isnan(rep.noise_select) && npoints <= 80)
        snprintf(sel, sizeof sel, "the K selection none (80 points or fewer)");
      else if (isnan(rep.noise_select))
        snprintf(sel, sizeof sel,
                 "the K selection not needed: at most %.1f%% of the points on cross-sections",
                 100 * rep.section_share);
      else
        snprintf(sel, sizeof sel, "the K selection %.4g h, %.1f%% of the points on cross-sections",
                 rep.noise_select / hh, 100 * rep.section_share);
      printf("  guard: noise %.6g (%.4g h; the fits read %.4g h, %s), %zu fits with more misfit "
             "than noise moved nothing\n",
             rep.noise, rep.noise / hh, rep.noise_fits / hh, sel, rep.misfit_fits);
    }
    printf("  moved %zu points: mean %.4g h, max %.4g h\n", rep.moved_points, rep.moved_mean / hh,
           rep.moved_max / hh);
    cli_print_footer(output);
  }
  rc = 0;
done:
  bsurf_cloud_free(&c);
  return rc;
}
