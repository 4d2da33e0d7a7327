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
  if (end == text && (text[0] == 'h' || text[0] == 'W')) x = 1.0; /* "h" = 1h */
  else if (end == text || errno || !isfinite(x) || x < 0) return -1;
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

static const char *const smooth_fields_all[] = {"err_632", "err_632plus", "moved", "k_hat", "d_local"};

int cmd_smooth(const cli_command *cmd, int argc, char **argv) {
  bsurf_smooth_options so = bsurf_smooth_options_default();
  const char *method = "bilateral", *order = "parallel", *estimator = "auto", *gamma = "fit",
             *center = "centroid", *threshold = "auto", *h1_text = "h", *h2_text = "auto",
             *kerr_text = "auto", *output = NULL;
  int ascii = 0, json = 0, quiet = 0, force = 0;
  cli_option opts[] = {
      {0, "method", ARG_STRING, &method, "M",
       "naive (Eq. 6.1), bilateral (Algorithm 4, Eq. 6.2) or multipass (Algorithm 5)", 1, 0},
      {'k', "neighbors", ARG_INT, &so.error.k, "K", "neighbourhood size K, the point included", 2, 65535},
      {'d', "degree", ARG_INT, &so.error.degree, "M", "degree of the height polynomial, 1..4", 1, 4},
      {'B', "bootstrap", ARG_INT, &so.error.bootstrap, "B", "bootstrap replicates per point", 0, 100000},
      {0, "gamma", ARG_STRING, &gamma, "MODE", "no-information rate of .632+: fit, mean or max", 1, 0},
      {0, "pca-center", ARG_STRING, &center, "C", "PCA about the centroid or the point", 1, 0},
      {0, "estimator", ARG_STRING, &estimator, "E",
       "the error W_i that weights the moves: 632, 632plus or auto (.632+ for naive, .632 otherwise)", 1, 0},
      {0, "threshold", ARG_STRING, &threshold, "T",
       "naive: project only where W_i < T; a length (model units, or 0.5h = 0.5 x h), auto (the mean "
       "W_i) or none (every point)",
       1, 0},
      {0, "h1", ARG_STRING, &h1_text, "X", "bilateral: distance sigma of Eq. 6.2 (a length; h = the mean spacing)", 1,
       0},
      {0, "h2", ARG_STRING, &h2_text, "X",
       "bilateral, multipass: error sigma of Eq. 6.2: a length, a multiple of |W| (e.g. 1W) or auto "
       "(2W bilateral, 0.3W multipass)",
       1, 0},
      {0, "order", ARG_STRING, &order, "O",
       "bilateral, multipass: parallel (order-independent) or sequential (the thesis's in-place sweep, one "
       "thread)",
       1, 0},
      {0, "a", ARG_DOUBLE, &so.a, "A", "multipass: h1 = A x d_L, the mean distance to the K_i neighbours (Eq. 6.5)", 0, 1e6},
      {0, "iterations", ARG_INT, &so.iterations, "N", "multipass: smoothing passes", 0, 1000000},
      {0, "k-min", ARG_INT, &so.k_min, "K", "multipass: the smallest neighbourhood (Eq. 6.3)", 1, 65535},
      {0, "k-error", ARG_STRING, &kerr_text, "X",
       "multipass: the error at which K_i reaches --k-min (Eq. 6.4): a length, a multiple of |W| (e.g. "
       "2W) or auto (1W)",
       1, 0},
      CLI_OPT_SEED(so.error.seed),
      CLI_OPT_THREADS(so.error.threads),
      CLI_OPTS_OUTPUT(output, ascii, force),
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
  if (mi < 0) return cli_usage_error(cmd, "--method must be naive, bilateral or multipass, not '%s'", method);
  if (oi < 0) return cli_usage_error(cmd, "--order must be parallel or sequential, not '%s'", order);
  if (ei < 0) return cli_usage_error(cmd, "--estimator must be auto, 632 or 632plus, not '%s'", estimator);
  if (g < 0) return cli_usage_error(cmd, "--gamma must be fit, mean or max, not '%s'", gamma);
  if (pc < 0) return cli_usage_error(cmd, "--pca-center must be centroid or point, not '%s'", center);
  so.method = (bsurf_smooth_method)mi;
  so.order = (bsurf_smooth_order)oi;
  so.estimator = (bsurf_smooth_estimator)ei;
  so.error.gamma = (bsurf_gamma_mode)g;
  so.error.pca_center = (bsurf_pca_center)pc;
  int terms = (so.error.degree + 1) * (so.error.degree + 2) / 2;
  if (so.error.k < terms)
    return cli_usage_error(cmd, "K = %d is too small for degree %d: a fit needs at least %d points", so.error.k,
                           so.error.degree, terms);
  if (so.k_min > so.error.k)
    return cli_usage_error(cmd, "--k-min %d is larger than K = %d", so.k_min, so.error.k);
  /* Lengths are checked now (with h = 1) and converted once h is known. */
  double dummy, frac;
  if (strcmp(threshold, "auto") && strcmp(threshold, "none") && parse_length(threshold, 1, 0, &dummy, &frac))
    return cli_usage_error(cmd, "--threshold must be a length (e.g. 0.01 or 0.5h), auto or none, not '%s'",
                           threshold);
  if (parse_length(h1_text, 1, 0, &dummy, &frac) || dummy <= 0)
    return cli_usage_error(cmd, "--h1 must be a positive length (e.g. 0.01 or 1.5h), not '%s'", h1_text);
  if (strcmp(h2_text, "auto") && (parse_length(h2_text, 1, 1, &dummy, &frac) || (dummy <= 0 && frac <= 0)))
    return cli_usage_error(cmd, "--h2 must be a positive length, a multiple of |W| (e.g. 1W) or auto, not '%s'",
                           h2_text);
  if (strcmp(kerr_text, "auto") && (parse_length(kerr_text, 1, 1, &dummy, &frac) || (dummy <= 0 && frac <= 0)))
    return cli_usage_error(cmd, "--k-error must be a positive length, a multiple of |W| or auto, not '%s'",
                           kerr_text);
  if (cli_check_output(output, pos[0], force)) return 1;

  double t0 = cli_now();
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  if (cli_read_cloud(pos[0], &c)) return 1;
  double *smoothed = NULL;
  bsurf_neighbors nb;
  if (cli_build_neighbors(pos[0], &c, so.error.k, so.error.threads, quiet, &nb)) {
    rc = 1;
    goto done;
  }
  const double h = nb.h;
  frac = 0;
  if (!strcmp(threshold, "auto")) so.threshold = NAN;
  else if (!strcmp(threshold, "none")) so.threshold = INFINITY;
  else parse_length(threshold, h, 0, &so.threshold, &frac);
  parse_length(h1_text, h, 0, &so.h1, &frac);
  if (strcmp(h2_text, "auto")) parse_length(h2_text, h, 1, &so.h2, &so.h2_fraction);
  if (strcmp(kerr_text, "auto")) parse_length(kerr_text, h, 1, &so.k_error, &so.k_error_fraction);

  int nfields = so.method == BSURF_SMOOTH_MULTIPASS ? 5 : 3;
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
  bsurf_smooth_report rep;
  bsurf_status st = bsurf_smooth(c.xyz, &nb, &so, smoothed, &sf, &rep);
  double compute = cli_now() - tc;
  cli_progress_done(&prog);
  bsurf_neighbors_free(&nb);
  if (st != BSURF_OK) {
    rc = cli_error("%s: %s", pos[0], cli_interrupted() ? "interrupted" : bsurf_strerror(st));
    goto done;
  }
  memcpy(c.xyz, smoothed, c.point_count * 3 * sizeof(double));
  if (cli_write_cloud(output, &c, ascii)) {
    rc = 1;
    goto done;
  }
  double secs = cli_now() - t0;
  const char *est_used = so.estimator == BSURF_SMOOTH_EST_632PLUS ||
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
    json_int(&j, "points", (long long)c.point_count);
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
    json_field_means(&j, &c, length_fields, nfields == 5 ? 4 : 3, h);
    if (nfields == 5) json_num(&j, "k_hat_mean", cli_field_mean(bsurf_cloud_field(&c, "k_hat"), c.point_count));
    json_num(&j, "compute_seconds", compute);
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    printf("smooth: %s, %zu points, h = %.6g, K = %d, degree %d, B = %d, %.2f s\n", method, c.point_count, h,
           so.error.k, so.error.degree, so.error.bootstrap, secs);
    printf("  W = %s, mean %.6g (%.4g h)\n", est_used, rep.mean_error, rep.mean_error / hh);
    if (so.method == BSURF_SMOOTH_NAIVE)
      printf("  threshold %.6g (%.4g h): %zu of %zu points projected\n", rep.threshold, rep.threshold / hh,
             rep.projected, c.point_count);
    else if (so.method == BSURF_SMOOTH_BILATERAL)
      printf("  order %s, h1 = %.6g (%.4g h), h2 = %.6g (%.4g h)\n", order, rep.h1, rep.h1 / hh, rep.h2,
             rep.h2 / hh);
    else
      printf("  order %s, %d passes, h1 = %g d_L, h2 = %.6g (%.4g h), K_i from %d to %d\n", order, rep.iterations,
             so.a, rep.h2, rep.h2 / hh, so.k_min, so.error.k);
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
