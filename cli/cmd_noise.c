/* bootsurf noise: synthetic normal-direction noise of the thesis (4.2), or
 * PCPNet's protocol (--sigma-diag: Gaussian with sigma = s x the bounding-box
 * diagonal; PCPNet uses s = 0.00125, 0.006 and 0.012). */
#include "cli.h"

#include <math.h>
#include <string.h>

/* 1 if option --NAME was given (as "--NAME V" or "--NAME=V"), up to a "--". */
static int option_given(int argc, char **argv, const char *name) {
  size_t len = strlen(name);
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    if (strcmp(a, "--") == 0) return 0;
    if (a[0] == '-' && a[1] == '-' && strncmp(a + 2, name, len) == 0 &&
        (a[2 + len] == 0 || a[2 + len] == '='))
      return 1;
  }
  return 0;
}

int cmd_noise(const cli_command *cmd, int argc, char **argv) {
  double level = 0.5, sigma_diag = 0;
  uint64_t seed = 1;
  const char *model = "gaussian", *output = NULL;
  int threads = 0, ascii = 0, json = 0, quiet = 0, force = 0;
  cli_option opts[] = {
      {0, "level", ARG_DOUBLE, &level, "XI", "noise level xi in units of h", 0, 1e300},
      {0, "sigma-diag", ARG_DOUBLE, &sigma_diag, "S",
       "instead of --level: gaussian, sigma = S x bbox diagonal (PCPNet 0.00125-0.012)", 0, 1e300},
      {0, "model", ARG_STRING, &model, "M", "gaussian: t ~ N(0, xi^2); uniform: t ~ U[-xi, xi]", 1,
       0},
      CLI_OPT_SEED(seed),
      {'j', "threads", ARG_INT, &threads, "N",
       "threads for measuring h, 0 = $OMP_NUM_THREADS if set, else all cores", 0, 4096},
      CLI_OPTS_OUTPUT(output, ascii, force),
      CLI_OPT_DROP_INVALID,
      CLI_OPTS_REPORT(json, quiet),
  };
  char *pos[1];
  int rc = cli_parse_input(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos);
  if (rc != CLI_PARSED) return rc;
  static const char *const models[] = {"gaussian", "uniform"};
  int m = cli_choice(model, models, 2);
  if (m < 0) return cli_usage_error(cmd, "--model must be gaussian or uniform, not '%s'", model);
  int by_diag = option_given(argc, argv, "sigma-diag");
  if (by_diag && option_given(argc, argv, "level"))
    return cli_usage_error(
        cmd, "--level and --sigma-diag are exclusive (noise in units of h or of the diagonal)");
  if (by_diag && m != BSURF_NOISE_GAUSSIAN)
    return cli_usage_error(cmd, "--sigma-diag is gaussian noise; it cannot be used with --model %s",
                           model);
  if (!output) return cli_usage_error(cmd, "missing -o OUTPUT");
  if (cli_check_output(output, pos[0], force)) return 1;
  double t0 = cli_now();
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  if (cli_read_cloud(pos[0], &c)) return 1;
  /* an earlier noise output: its exact normals are its true_* fields */
  if (!c.normals && bsurf_cloud_field(&c, "true_nx") && cli_truth_from_fields(&c)) {
    bsurf_cloud_free(&c);
    return 1;
  }
  if (!c.normals) {
    bsurf_cloud_free(&c);
    return cli_error("%s: the input has no normals (nx ny nz); noise moves points along them",
                     pos[0]);
  }
  if (c.point_count < 2) {
    bsurf_cloud_free(&c);
    return cli_error("%s: needs at least 2 points to measure the spacing h", pos[0]);
  }
  bsurf_noise_options no = bsurf_noise_options_default();
  no.model = (bsurf_noise_model)m;
  no.level = by_diag && sigma_diag == 0 ? 0.0 : level; /* --sigma-diag 0: no noise */
  no.sigma_diag = by_diag ? sigma_diag : 0.0;
  no.seed = seed;
  no.threads = threads;
  cli_progress prog;
  cli_progress_init(&prog, "spacing", quiet);
  no.progress = cli_progress_cb;
  no.progress_user = &prog;
  bsurf_noise_report nr = {0, 0, 0, 0};
  bsurf_status st = bsurf_noise_points(c.xyz, c.normals, c.point_count, &no, &nr);
  cli_progress_done(&prog);
  double h = nr.h, diag = nr.diagonal, use_level = nr.level, scale = nr.scale;
  if (st == BSURF_ERR_INVALID_VALUE) {
    bsurf_cloud_free(&c);
    return cli_error("%s: some normals have zero length", pos[0]);
  }
  if (st != BSURF_OK) {
    bsurf_cloud_free(&c);
    return cli_error("noise: %s", bsurf_strerror(st));
  }
  /* The exact normals and feature labels no longer belong to the moved
   * points as results would: they go on as ground truth under names eval
   * never scores (true_nx true_ny true_nz, true_feature, true_feature_dist) */
  if (cli_truth_to_fields(&c)) {
    bsurf_cloud_free(&c);
    return 1;
  }
  rc = cli_write_cloud(output, &c, ascii);
  if (rc == 0 && !quiet) {
    double secs = cli_now() - t0;
    if (json) {
      cli_json j = json_start("noise", pos[0], output);
      json_points_h(&j, c.point_count, h);
      if (by_diag) {
        json_num(&j, "sigma_diag", sigma_diag);
        json_num(&j, "diagonal", diag);
      } else {
        json_num(&j, "level", level);
      }
      if (m == BSURF_NOISE_GAUSSIAN) json_num(&j, "sigma", use_level * scale);
      json_str(&j, "model", model);
      json_int(&j, "seed", (long long)seed);
      json_int(&j, "threads", bsurf_threads_resolve(threads));
      json_num(&j, "seconds", secs);
      json_end(&j);
    } else {
      if (by_diag)
        printf("noise gaussian sigma %g x diagonal %.6g = %.6g (%.4g h) on %zu points -> %s\n",
               sigma_diag, diag, scale, h > 0 ? scale / h : NAN, c.point_count, output);
      else
        printf("noise %s level %g (x h = %.6g) on %zu points -> %s\n", model, level, h,
               c.point_count, output);
      cli_print_input_report(stdout);
    }
  }
  bsurf_cloud_free(&c);
  return rc;
}
