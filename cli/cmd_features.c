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

int cmd_features(const cli_command *cmd, int argc, char **argv) {
  bsurf_feature_options fo = bsurf_feature_options_default();
  const char *method = "distance", *output = NULL, *threshold_s = "auto", *tail = "otsu";
  int ascii = 0, json = 0, quiet = 0, force = 0;
  cli_option opts[] = {
      {0, "method", ARG_STRING, &method, "M", "distance (PCA distance map, 7.1) or variance (7.2)", 1, 0},
      {'k', "neighbors", ARG_INT, &fo.normals.k, "K", "variance: neighbourhood of the normals", 3, 65535},
      {'B', "bootstrap", ARG_INT, &fo.normals.bootstrap, "B", "variance: bootstrap replicates (>= 2)", 2, 100000},
      {0, "k-min", ARG_INT, &fo.k_min, "K", "distance: smallest neighbourhood", 3, 65535},
      {0, "k-max", ARG_INT, &fo.k_max, "K", "distance: largest neighbourhood", 3, 65535},
      {0, "k-step", ARG_INT, &fo.k_step, "S", "distance: growth step of the neighbourhood", 1, 65535},
      {0, "ratio-threshold", ARG_DOUBLE, &fo.ratio_threshold, "T", "distance: T_{a/c} on lambda0/lambda2", 0,
       1},
      {0, "noise-factor", ARG_DOUBLE, &fo.noise_factor, "C",
       "distance: T_{a/c} of size K = max(T, C x median f(K)) (0 = T alone)", 0, 1e6},
      {0, "derivative", ARG_DOUBLE, &fo.derivative, "D", "distance: threshold f + D f' instead of f (0 = off)", 0,
       1e6},
      {0, "alpha", ARG_DOUBLE, &fo.alpha, "A", "distance: bilateral filter strength (Eq. 7.1)", 0, 1},
      {0, "iterations", ARG_INT, &fo.iterations, "N", "distance: bilateral filter passes", 0, 100000},
      {0, "filter-k", ARG_INT, &fo.filter_k, "K", "distance: neighbours of the filter (0 = --k-min)", 0, 65535},
      {0, "sigma-range", ARG_DOUBLE, &fo.sigma_range, "S",
       "distance: range sigma of the filter, fraction of max radius", 1e-12, 1e6},
      {0, "threshold", ARG_STRING, &threshold_s, "T",
       "distance: fraction of max(feature_dist) or auto; variance: normal_var value or auto", 1, 0},
      {0, "tail-rule", ARG_STRING, &tail, "R", "variance auto threshold: otsu or mad", 1, 0},
      CLI_OPT_SEED(fo.normals.seed),
      CLI_OPT_THREADS(fo.threads),
      CLI_OPTS_OUTPUT(output, ascii, force),
      CLI_OPT_DROP_INVALID,
      CLI_OPTS_REPORT(json, quiet),
  };
  char *pos[1];
  int npos;
  int rc = cli_parse(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos, 1, &npos);
  if (rc != CLI_PARSED) return rc;
  if (npos != 1) return cli_usage_error(cmd, "expected one INPUT file");
  static const char *const methods[] = {"distance", "variance"}, *const tails[] = {"otsu", "mad"};
  int m = cli_choice(method, methods, 2), tr = cli_choice(tail, tails, 2);
  if (m < 0) return cli_usage_error(cmd, "--method must be distance or variance, not '%s'", method);
  if (tr < 0) return cli_usage_error(cmd, "--tail-rule must be otsu or mad, not '%s'", tail);
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

  double t0 = cli_now();
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  bsurf_neighbors nb;
  memset(&nb, 0, sizeof nb);
  uint8_t *feat = NULL;
  double *score = NULL;
  rc = 1;
  if (cli_read_cloud(pos[0], &c)) goto done;
  if (cli_build_neighbors(pos[0], &c, kmax, fo.threads, quiet, &nb)) goto done;
  cli_progress prog;
  bsurf_status st;
  const size_t n = c.point_count;
  feat = malloc(n);
  score = malloc(n * sizeof(double));
  if (!feat || !score) {
    cli_error("out of memory");
    goto done;
  }
  fo.progress = cli_progress_cb;
  fo.progress_user = &prog;
  bsurf_feature_report rep;
  cli_progress_init(&prog, "features", quiet);
  st = bsurf_detect_features(c.xyz, &nb, &fo, feat, score, &rep);
  cli_progress_done(&prog);
  if (st != BSURF_OK) {
    cli_error("%s: %s", pos[0], cli_interrupted() ? "interrupted" : bsurf_strerror(st));
    goto done;
  }
  const char *score_name = fo.method == BSURF_FEATURES_DISTANCE ? "feature_dist" : "normal_var";
  const char *out_names[2] = {"feature", score_name};
  int kept[2] = {0, 0}, replaced[2] = {0, 0};
  for (int t = 0; t < 2; t++) {
    bsurf_field *old = bsurf_cloud_field(&c, out_names[t]);
    if (!old) continue;
    char in_name[BSURF_FIELD_NAME_MAX];
    snprintf(in_name, sizeof in_name, "%s_in", out_names[t]);
    if (bsurf_cloud_field(&c, in_name)) {
      replaced[t] = 1;
      if (!quiet)
        cli_warn("%s: replacing the input's %s (%s is kept)", pos[0], out_names[t], in_name);
    } else {
      strcpy(old->name, in_name);
      kept[t] = 1;
      if (!quiet) cli_warn("%s: the input's %s is kept as %s", pos[0], out_names[t], in_name);
    }
  }
  /* adding a field may move the field array: look both up once both exist */
  bsurf_field *fs = bsurf_cloud_add_field(&c, score_name, BSURF_FLOAT32);
  bsurf_field *ff = fs ? bsurf_cloud_add_field(&c, "feature", BSURF_UINT8) : NULL;
  if (ff) fs = bsurf_cloud_field(&c, score_name);
  if (!fs || !ff) {
    cli_error("out of memory");
    goto done;
  }
  memcpy(fs->values, score, n * sizeof(double));
  for (size_t i = 0; i < n; i++) ff->values[i] = feat[i];
  if (cli_write_cloud(output, &c, ascii)) goto done;
  double secs = cli_now() - t0;
  if (json) {
    cli_json j;
    json_begin(&j, stdout);
    json_str(&j, "command", "features");
    json_str(&j, "input", pos[0]);
    json_str(&j, "output", output);
    json_int(&j, "points", (long long)n);
    json_num(&j, "h", nb.h);
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
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    printf("features: %zu points, h = %.6g, method %s, %.2f s\n", n, nb.h, method, secs);
    printf("  threshold %.6g on %s (%s): %zu feature points (%.2f%%)\n", rep.threshold, score_name,
           isnan(fo.threshold) ? "auto" : "given", rep.feature_points,
           n ? 100.0 * (double)rep.feature_points / (double)n : 0.0);
    if (fo.method == BSURF_FEATURES_DISTANCE)
      printf("  T_{a/c} %.4g at k_min, max radius %.6g, %zu points stopped at k_min (set to -max radius)\n",
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
