/* bootsurf features: feature detection (thesis chapter 7). The library's
 * job (bsurf_features_job, src/jobs/features_job.c) keeps an input field
 * named like an output as NAME_in (or replaces NAME when NAME_in exists);
 * both cases are reported here (stderr, and "kept_input_fields" /
 * "replaced_input_fields" in --json). */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static void features_warn(const char *input, const char *const names[2], const int kept[2],
                          const int replaced[2]) {
  for (int t = 0; t < 2; t++) {
    if (replaced[t])
      cli_warn("%s: replacing the input's %s (%s_in is kept)", input, names[t], names[t]);
    if (kept[t]) cli_warn("%s: the input's %s is kept as %s_in", input, names[t], names[t]);
  }
}

int cmd_features(const cli_command *cmd, int argc, char **argv) {
  bsurf_feature_options fo = bsurf_feature_options_default();
  const char *method = "variance", *output = NULL, *threshold_s = "auto", *tail = "null";
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
       "distance: fraction of max(feature_dist), 0 to 1, or auto; variance: normal_var value "
       "(at least 0) or auto",
       1, 0},
      {0, "tail-rule", ARG_STRING, &tail, "R",
       "variance auto threshold: null (test against a flat patch at the measured noise), otsu "
       "or mad (on log normal_var)",
       1, 0},
      {0, "false-positive-rate", ARG_DOUBLE, &fo.false_positive_rate, "A",
       "variance, rule null: share of a flat area flagged by each of the two tests (the "
       "variance and the border test)",
       1e-9, 0.999999},
      {0, "variance-filter-k", ARG_INT, &fo.variance_filter_k, "K",
       "variance, rule null: neighbours of the median filter (0 = K/2, 1 = none)", 0, 65535},
      {0, "feature-angle", ARG_DOUBLE, &fo.feature_angle, "DEG",
       "variance, rule null: grow -k (x2, up to --variance-k-max) until a simulated edge whose "
       "normals differ by DEG degrees, at the measured noise, passes the test at half its points "
       "(0 = -k always)",
       0, 179.999},
      {0, "variance-k-max", ARG_INT, &fo.variance_k_max, "K",
       "variance, rule null: largest neighbourhood --feature-angle may choose (0 = 8 x -k)", 0,
       65535},
      {0, "quadric-angle", ARG_DOUBLE, &fo.quadric_angle, "DEG",
       "variance, rule null: a flagged point stays a feature only where a quadric of K_q "
       "neighbours does not explain it at the measured noise (a smooth bend is cleared); K_q the "
       "first of K, 2K, 4K keeping 9 in 10 points of a DEG degree crease (0 = off)",
       0, 179.999},
      CLI_OPT_SEED(fo.normals.seed),
      CLI_OPT_THREADS(fo.threads),
      CLI_OPTS_JOB(output, ascii, force, tile_points, memory_limit, json, quiet),
  };
  char *pos[1];
  int rc = cli_parse_input(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos);
  if (rc != CLI_PARSED) return rc;
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
    /* the library's range and words (the same in Python) */
    if (bsurf_feature_threshold_check(fo.method, fo.threshold) != BSURF_OK)
      return cli_usage_error(cmd, "--%s", bsurf_last_message());
  }
  if (fo.k_max < fo.k_min) return cli_usage_error(cmd, "--k-max must be at least --k-min");
  if (fo.filter_k > fo.k_max) return cli_usage_error(cmd, "--filter-k must not exceed --k-max");
  if (!output) return cli_usage_error(cmd, "missing -o OUTPUT");
  if (cli_check_output(output, pos[0], force)) return 1;
  /* the largest neighbourhood the run may need: variance with --feature-angle
   * may grow -k up to --variance-k-max, the quadric check needs its K_q and 80 */
  const int kmax = bsurf_features_job_neighbors(&fo);
  size_t plan = 0;
  rc = cli_tiles_plan(cmd, pos[0], output, ascii, tile_points, memory_limit, kmax, 2, &plan);
  if (rc) return rc;
  double t0 = cli_now();
  bsurf_cloud c;
  bsurf_job_io io;
  cli_progress prog;
  if (cli_job_io(&io, pos[0], output, plan, &c, &prog, "features", quiet)) return 1;
  fo.progress = cli_progress_cb;
  fo.progress_user = &prog;
  bsurf_features_job_summary sum;
  bsurf_failure where = {0, -1, ""};
  bsurf_status st = bsurf_features_job(&io, &fo, &sum, &where);
  rc = 1;
  if (cli_job_done(&prog, pos[0], output, plan, st, &where, sum.duplicates)) goto done;
  const char *const *out_names = sum.field_names;
  const int null_rule = fo.method == BSURF_FEATURES_VARIANCE && isnan(fo.threshold) &&
                        fo.tail_rule == BSURF_TAIL_NULL;
  const char *score_name = out_names[1];
  const int *kept = sum.kept, *replaced = sum.replaced;
  const bsurf_feature_report rep = sum.report;
  const size_t n = sum.points;
  const double h = sum.h;
  if (!quiet) features_warn(pos[0], out_names, kept, replaced);
  if (!plan && cli_write_cloud(output, &c, ascii)) goto done;
  double secs = cli_now() - t0;
  if (json) {
    cli_json j = json_start("features", pos[0], output);
    json_points_h(&j, n, h);
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
      json_int(&j, "k", rep.k);
      json_int(&j, "bootstrap", fo.normals.bootstrap);
      json_int(&j, "seed", (long long)fo.normals.seed);
      json_str(&j, "tail_rule", tail);
      if (null_rule) {
        json_num(&j, "false_positive_rate", fo.false_positive_rate);
        json_int(&j, "variance_filter_k",
                 fo.variance_filter_k ? fo.variance_filter_k : (rep.k / 2 > 1 ? rep.k / 2 : 1));
        json_num(&j, "noise_level", rep.noise_level);
        json_num(&j, "border_threshold", rep.border_threshold);
        json_int(&j, "border_points", (long long)rep.border_points);
        json_num(&j, "feature_angle", fo.feature_angle);
        if (fo.feature_angle > 0) {
          json_int(&j, "k_base", fo.normals.k);
          json_int(&j, "variance_k_max", fo.variance_k_max);
          json_num(&j, "edge_power", rep.edge_power);
        }
        json_num(&j, "quadric_angle", fo.quadric_angle);
        json_int(&j, "quadric_k", rep.quadric_k);
        json_num(&j, "quadric_threshold", rep.quadric_threshold);
        json_num(&j, "quadric_power", rep.quadric_power);
        json_num(&j, "quadric_noise", rep.quadric_noise);
        json_int(&j, "quadric_cleared", (long long)rep.quadric_cleared);
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
    if (plan) json_tiles(&j, sum.tile_points, sum.tiles);
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    printf("features: %zu points, h = %.6g, method %s, %.2f s\n", n, h, method, secs);
    printf("  threshold %.6g on %s (%s): %zu feature points (%.2f%%)\n", rep.threshold, score_name,
           isnan(fo.threshold) ? "auto" : "given", rep.feature_points,
           n ? 100.0 * (double)rep.feature_points / (double)n : 0.0);
    if (null_rule)
      printf("  or border score above %.6g (the border test at the same false-positive rate): "
             "%zu feature points by it alone\n",
             rep.border_threshold, rep.border_points);
    if (null_rule && fo.feature_angle > 0)
      printf("  K %d (from %d: a %g degree edge at this noise passes the test at %.0f%% of its "
             "points)\n",
             rep.k, fo.normals.k, fo.feature_angle, 100 * rep.edge_power);
    if (null_rule && rep.quadric_k > 0)
      printf("  quadric check at K %d (noise %.6g): %zu flagged points a quadric explains "
             "cleared\n",
             rep.quadric_k, rep.quadric_noise, rep.quadric_cleared);
    else if (null_rule && fo.quadric_angle > 0 && !isnan(rep.quadric_power))
      printf("  quadric check not run (a %g degree crease at this noise keeps %.0f%% of its "
             "points at the largest K_q tried)\n",
             fo.quadric_angle, 100 * rep.quadric_power);
    else if (null_rule && fo.quadric_angle > 0)
      printf("  quadric check not run (no noise measured, or 80 points or fewer)\n");
    if (fo.method == BSURF_FEATURES_DISTANCE)
      printf("  T_{a/c} %.4g at k_min, max radius %.6g, %zu points stopped at k_min (set to -max "
             "radius)\n",
             rep.ratio_threshold_kmin, rep.max_radius, rep.immediate);
    cli_print_footer(output);
  }
  rc = 0;
done:
  bsurf_cloud_free(&c);
  return rc;
}
