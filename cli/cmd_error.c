/* bootsurf error: bootstrap test-error estimates (thesis chapter 4). */
#include "cli.h"

#include <stdlib.h>
#include <string.h>

static const char *const error_fields[] = {"err_train", "err_boot",    "err_loo",
                                           "err_loo_center", "err_632", "err_632plus",
                                           "gamma",     "overfit_rate", "err_test",
                                           "err_test_center"};
#define ERROR_FIELD_COUNT 10

/* ---- tiled runs: the same fields, tile by tile (cli/tiles.c) ---- */

typedef struct error_tiles {
  bsurf_error_options eo;
  int nfields;
} error_tiles;

/* sums: replicates total, skipped, degree reduced, centre unestimated, then
 * the field sums */
#define ERROR_SUMS (4 + ERROR_FIELD_COUNT)

static bsurf_status error_prepare(void *user, bsurf_cloud *c) {
  const error_tiles *et = user;
  for (int f = 0; f < et->nfields; f++)
    if (!bsurf_cloud_add_field(c, error_fields[f], BSURF_FLOAT32)) return BSURF_ERR_NOMEM;
  return BSURF_OK;
}

static bsurf_status error_run(void *user, const bsurf_tile *tile, bsurf_cloud *core, double *sums) {
  const error_tiles *et = user;
  bsurf_error_options eo = et->eo;
  eo.point_index = tile->point_index;
  eo.progress = NULL;
  bsurf_error_fields out;
  memset(&out, 0, sizeof out);
  double **slots[8] = {&out.err_train, &out.err_boot, &out.err_loo, &out.err_loo_center,
                       &out.err_632,   &out.err_632plus, &out.gamma, &out.overfit_rate};
  for (int f = 0; f < et->nfields; f++) *slots[f] = bsurf_cloud_field(core, error_fields[f])->values;
  bsurf_error_report rep;
  bsurf_status st = bsurf_estimate_error(tile->xyz, tile->nb, NULL, &eo, &out, &rep);
  if (st != BSURF_OK) return st;
  sums[0] += (double)rep.replicates_total;
  sums[1] += (double)rep.replicates_skipped;
  sums[2] += (double)rep.degree_reduced;
  sums[3] += (double)rep.center_unestimated;
  for (int f = 0; f < et->nfields; f++) sums[4 + f] += cli_field_mean(bsurf_cloud_field(core, error_fields[f]), core->point_count) * (double)core->point_count;
  return BSURF_OK;
}

int cmd_error(const cli_command *cmd, int argc, char **argv) {
  bsurf_error_options eo = bsurf_error_options_default();
  const char *gamma = "fit", *center = "centroid", *output = NULL, *test_path = NULL;
  const char *memory_limit = "auto";
  size_t tile_points = 0;
  int ascii = 0, json = 0, quiet = 0, force = 0;
  cli_option opts[] = {
      {'k', "neighbors", ARG_INT, &eo.k, "K", "neighbourhood size K, the point included", 2, 65535},
      {'d', "degree", ARG_INT, &eo.degree, "M", "degree of the height polynomial, 1..4", 1, 4},
      {'B', "bootstrap", ARG_INT, &eo.bootstrap, "B", "bootstrap replicates per point (at least 1)", 0, 100000},
      {0, "gamma", ARG_STRING, &gamma, "MODE",
       "no-information rate: fit (Eq. 4.10), mean or max over replicates (4.2.1)", 1, 0},
      {0, "pca-center", ARG_STRING, &center, "C", "PCA about the centroid or the point", 1, 0},
      CLI_OPT_SEED(eo.seed),
      CLI_OPT_THREADS(eo.threads),
      {0, "test-sample", ARG_STRING, &test_path, "FILE",
       "same points with independent noise: also write err_test (validation)", 1, 0},
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
  static const char *const gammas[] = {"fit", "mean", "max"};
  static const char *const centers[] = {"centroid", "point"};
  int g = cli_choice(gamma, gammas, 3), pc = cli_choice(center, centers, 2);
  if (g < 0) return cli_usage_error(cmd, "--gamma must be fit, mean or max, not '%s'", gamma);
  if (pc < 0) return cli_usage_error(cmd, "--pca-center must be centroid or point, not '%s'", center);
  /* -B 0 computes no bootstrap estimator: err_boot, err_loo, err_632 and
   * err_632plus would be err_train under other names (docs/robustness.md) */
  if (eo.bootstrap < 1)
    return cli_usage_error(cmd, "-B 0: the bootstrap estimators need at least one replicate "
                                "(err_boot, err_loo and err_632* would only repeat err_train)");
  eo.gamma = (bsurf_gamma_mode)g;
  eo.pca_center = (bsurf_pca_center)pc;
  int terms = (eo.degree + 1) * (eo.degree + 2) / 2;
  if (eo.k < terms)
    return cli_usage_error(cmd, "K = %d is too small for degree %d: a fit needs at least %d points", eo.k,
                           eo.degree, terms);
  if (output && cli_check_output(output, pos[0], force)) return 1;
  if (output && test_path && cli_check_output(output, test_path, force)) return 1;

  size_t plan = 0, tiles = 0;
  rc = cli_tiles_plan(cmd, pos[0], output, ascii, tile_points, memory_limit, eo.k, 8, &plan);
  if (rc) return rc;
  if (plan && test_path) return cli_error("%s: --test-sample is not available in tiled runs", test_path);

  double t0 = cli_now();
  bsurf_error_report rep;
  double h = 0, means[ERROR_FIELD_COUNT];
  bsurf_cloud c, test;
  bsurf_cloud_init(&c);
  bsurf_cloud_init(&test);
  size_t npoints = 0;
  int nfields = test_path ? ERROR_FIELD_COUNT : ERROR_FIELD_COUNT - 2;
  if (plan) {
    error_tiles et = {eo, nfields};
    double sums[ERROR_SUMS] = {0};
    bsurf_tile_ops ops = {.tile_points = plan, .k = eo.k, .threads = eo.threads, .user = &et,
                          .prepare = error_prepare, .run = error_run, .nsums = ERROR_SUMS};
    bsurf_tile_report tr;
    tr.sums = sums;
    int trc = cli_tiles_run(pos[0], output, &ops, &tr, quiet);
    plan = ops.tile_points;
    tiles = tr.tiles;
    if (trc) return 1;
    npoints = tr.points;
    h = tr.h;
    rep.replicates_total = (size_t)sums[0];
    rep.replicates_skipped = (size_t)sums[1];
    rep.degree_reduced = (size_t)sums[2];
    rep.center_unestimated = (size_t)sums[3];
    for (int f = 0; f < nfields; f++) means[f] = sums[4 + f] / (double)npoints;
    goto summary;
  }

  if (cli_read_cloud(pos[0], &c)) return 1;
  if (test_path) {
    if (cli_read_cloud(test_path, &test)) {
      bsurf_cloud_free(&c);
      return 1;
    }
    if (test.point_count != c.point_count) {
      rc = cli_error("%s: has %zu points but %s has %zu; the test sample must list the same points",
                     test_path, test.point_count, pos[0], c.point_count);
      goto done;
    }
  }
  bsurf_neighbors nb;
  if (cli_build_neighbors(pos[0], &c, eo.k, eo.threads, quiet, &nb)) {
    rc = 1;
    goto done;
  }
  cli_progress prog;
  bsurf_status st;

  bsurf_error_fields out;
  memset(&out, 0, sizeof out);
  double **slots[ERROR_FIELD_COUNT] = {&out.err_train, &out.err_boot,  &out.err_loo,
                                       &out.err_loo_center, &out.err_632, &out.err_632plus,
                                       &out.gamma,     &out.overfit_rate, &out.err_test,
                                       &out.err_test_center};
  for (int f = 0; f < nfields; f++) {
    bsurf_field *fl = bsurf_cloud_add_field(&c, error_fields[f], BSURF_FLOAT32);
    if (!fl) {
      bsurf_neighbors_free(&nb);
      rc = cli_error("out of memory");
      goto done;
    }
  }
  for (int f = 0; f < nfields; f++) *slots[f] = bsurf_cloud_field(&c, error_fields[f])->values;

  eo.progress = cli_progress_cb;
  eo.progress_user = &prog;
  cli_progress_init(&prog, "error", quiet);
  st = bsurf_estimate_error(c.xyz, &nb, test_path ? test.xyz : NULL, &eo, &out, &rep);
  cli_progress_done(&prog);
  h = nb.h;
  bsurf_neighbors_free(&nb);
  if (st != BSURF_OK) {
    rc = cli_error("%s: %s", pos[0], cli_interrupted() ? "interrupted" : bsurf_strerror(st));
    goto done;
  }
  if (output && cli_write_cloud(output, &c, ascii)) {
    rc = 1;
    goto done;
  }
  npoints = c.point_count;
  for (int f = 0; f < nfields; f++) means[f] = cli_field_mean(bsurf_cloud_field(&c, error_fields[f]), npoints);
summary:;
  double secs = cli_now() - t0;
  if (json) {
    cli_json j;
    json_begin(&j, stdout);
    json_str(&j, "command", "error");
    json_str(&j, "input", pos[0]);
    if (output) json_str(&j, "output", output);
    json_int(&j, "points", (long long)npoints);
    json_num(&j, "h", h);
    json_int(&j, "k", eo.k);
    json_int(&j, "degree", eo.degree);
    json_int(&j, "bootstrap", eo.bootstrap);
    json_str(&j, "gamma_mode", gamma);
    json_str(&j, "pca_center", center);
    json_int(&j, "seed", (long long)eo.seed);
    json_int(&j, "threads", bsurf_threads_resolve(eo.threads));
    json_int(&j, "replicates_total", (long long)rep.replicates_total);
    json_int(&j, "replicates_skipped", (long long)rep.replicates_skipped);
    json_int(&j, "degree_reduced", (long long)rep.degree_reduced);
    json_int(&j, "center_unestimated", (long long)rep.center_unestimated);
    if (plan) {
      json_int(&j, "tile_points", (long long)plan);
      json_int(&j, "tiles", (long long)tiles);
      json_int(&j, "ranks", cli_mpi_ranks());
    }
    json_means(&j, error_fields, means, nfields, h);
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    printf("error: %zu points, h = %.6g, K = %d, degree %d, B = %d, gamma %s, %.2f s\n", npoints, h,
           eo.k, eo.degree, eo.bootstrap, gamma, secs);
    print_means(stdout, error_fields, means, nfields, h);
    if (rep.replicates_skipped)
      printf("  %zu of %zu replicate fits were rank-deficient and skipped\n", rep.replicates_skipped,
             rep.replicates_total);
    if (rep.degree_reduced)
      printf("  %zu points had degenerate neighbourhoods and used a lower degree\n", rep.degree_reduced);
    cli_print_input_report(stdout);
    if (output) printf("  -> %s\n", output);
  }
done:
  bsurf_cloud_free(&c);
  bsurf_cloud_free(&test);
  return rc;
}
