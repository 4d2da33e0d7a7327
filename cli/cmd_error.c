/* bootsurf error: bootstrap test-error estimates (thesis chapter 4). */
#include "cli.h"

#include <stdlib.h>
#include <string.h>

int cmd_error(const cli_command *cmd, int argc, char **argv) {
  bsurf_error_options eo = bsurf_error_options_default();
  const char *gamma = "fit", *center = "centroid", *output = NULL, *test_path = NULL;
  const char *memory_limit = "auto";
  size_t tile_points = 0;
  int ascii = 0, json = 0, quiet = 0, force = 0;
  cli_option opts[] = {
      {'k', "neighbors", ARG_INT, &eo.k, "K", "neighbourhood size K, the point included", 2, 65535},
      {'d', "degree", ARG_INT, &eo.degree, "M", "degree of the height polynomial, 1..4", 1, 4},
      {'B', "bootstrap", ARG_INT, &eo.bootstrap, "B", "bootstrap replicates per point (at least 1)",
       0, 100000},
      {0, "gamma", ARG_STRING, &gamma, "MODE",
       "no-information rate: fit (Eq. 4.10), mean or max over replicates (4.2.1)", 1, 0},
      {0, "pca-center", ARG_STRING, &center, "C", "PCA about the centroid or the point", 1, 0},
      CLI_OPT_SEED(eo.seed),
      CLI_OPT_THREADS(eo.threads),
      {0, "test-sample", ARG_STRING, &test_path, "FILE",
       "same points with independent noise: also write err_test (validation)", 1, 0},
      CLI_OPTS_JOB(output, ascii, force, tile_points, memory_limit, json, quiet),
  };
  char *pos[1];
  int rc = cli_parse_input(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos);
  if (rc != CLI_PARSED) return rc;
  if (cli_gamma(cmd, gamma, &eo.gamma) || cli_pca_center(cmd, center, &eo.pca_center))
    return CLI_USAGE;
  /* -B 0 computes no bootstrap estimator: err_boot, err_loo, err_632 and
   * err_632plus would be err_train under other names (docs/robustness.md) */
  if (eo.bootstrap < 1)
    return cli_usage_error(cmd, "-B 0: the bootstrap estimators need at least one replicate "
                                "(err_boot, err_loo and err_632* would only repeat err_train)");
  if (cli_check_terms(cmd, eo.k, eo.degree)) return CLI_USAGE;
  if (output && cli_check_output(output, pos[0], force)) return 1;
  if (output && test_path && cli_check_output(output, test_path, force)) return 1;

  size_t plan = 0;
  rc = cli_tiles_plan(cmd, pos[0], output, ascii, tile_points, memory_limit, eo.k, 8, &plan);
  if (rc) return rc;
  if (plan && test_path)
    return cli_error("%s: --test-sample is not available in tiled runs", test_path);

  double t0 = cli_now();
  bsurf_cloud c, test;
  bsurf_cloud_init(&c);
  bsurf_cloud_init(&test);
  bsurf_job_io io;
  bsurf_error_job_summary sum;
  bsurf_failure where = {0, -1, ""};
  cli_progress prog;
  eo.progress = cli_progress_cb;
  eo.progress_user = &prog;
  if (cli_job_io(&io, pos[0], output, plan, &c, &prog, "error", quiet)) return 1;
  if (test_path) {
    if (cli_read_cloud(test_path, &test)) {
      rc = 1;
      goto done;
    }
    if (test.point_count != c.point_count) {
      rc = cli_error("%s: has %zu points but %s has %zu; the test sample must list the same points",
                     test_path, test.point_count, pos[0], c.point_count);
      goto done;
    }
    io.test = &test;
  }
  bsurf_status st = bsurf_error_job(&io, &eo, &sum, &where);
  if (plan) plan = sum.tile_points;
  if ((rc = cli_job_done(&prog, pos[0], output, plan, st, &where, sum.duplicates))) goto done;
  if (!plan && output && cli_write_cloud(output, &c, ascii)) {
    rc = 1;
    goto done;
  }

  double secs = cli_now() - t0;
  if (json) {
    cli_json j = json_start("error", pos[0], output);
    json_points_h(&j, sum.points, sum.h);
    json_int(&j, "k", eo.k);
    json_int(&j, "degree", eo.degree);
    json_int(&j, "bootstrap", eo.bootstrap);
    json_str(&j, "gamma_mode", gamma);
    json_str(&j, "pca_center", center);
    json_int(&j, "seed", (long long)eo.seed);
    json_int(&j, "threads", bsurf_threads_resolve(eo.threads));
    json_int(&j, "replicates_total", (long long)sum.report.replicates_total);
    json_int(&j, "replicates_skipped", (long long)sum.report.replicates_skipped);
    json_int(&j, "degree_reduced", (long long)sum.report.degree_reduced);
    json_int(&j, "center_unestimated", (long long)sum.report.center_unestimated);
    if (plan) json_tiles(&j, plan, sum.tiles);
    json_means(&j, sum.field_names, sum.means, sum.field_count, sum.h);
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    printf("error: %zu points, h = %.6g, K = %d, degree %d, B = %d, gamma %s, %.2f s\n", sum.points,
           sum.h, eo.k, eo.degree, eo.bootstrap, gamma, secs);
    print_means(stdout, sum.field_names, sum.means, sum.field_count, sum.h);
    if (sum.report.replicates_skipped)
      printf("  %zu of %zu replicate fits were rank-deficient and skipped\n",
             sum.report.replicates_skipped, sum.report.replicates_total);
    if (sum.report.degree_reduced)
      printf("  %zu points had degenerate neighbourhoods and used a lower degree\n",
             sum.report.degree_reduced);
    cli_print_footer(output);
  }
done:
  bsurf_cloud_free(&c);
  bsurf_cloud_free(&test);
  return rc;
}
