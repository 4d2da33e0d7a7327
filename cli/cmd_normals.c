/* bootsurf normals: normals with bootstrap confidence (thesis chapter 5). */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAX_CANDIDATES 1024

/* "A:B:STEP" -> list of K values */
static int parse_range(const char *s, int *ks, int max) {
  int a, b, step, n = 0;
  char extra;
  if (sscanf(s, "%d:%d:%d%c", &a, &b, &step, &extra) != 3 || a < 3 || b < a || step < 1) return -1;
  for (int k = a; k <= b && n < max; k += step)
    ks[n++] = k;
  return n;
}

/* "1,2,3" -> list of degrees 1..4 */
static int parse_degrees(const char *s, int *ds, int max) {
  int n = 0;
  const char *p = s;
  while (*p && n < max) {
    char *end;
    long d = strtol(p, &end, 10);
    if (end == p || d < 1 || d > 4) return -1;
    ds[n++] = (int)d;
    if (*end == ',')
      end++;
    else if (*end)
      return -1;
    p = end;
  }
  return n > 0 ? n : -1;
}

/* The --curve file: each candidate's means (figs. 5.6-5.11), written
 * atomically. 0 or 1 (printed). */
static int write_curve(const char *path, const bsurf_normals_curve_row *rows, size_t count,
                       int truth) {
  char tmp[4200];
  snprintf(tmp, sizeof tmp, "%s.tmp", path);
  FILE *f = fopen(tmp, "w");
  if (!f) return cli_error("%s: cannot write", tmp);
  fprintf(f, "k,degree,mean_normal_err,mean_normal_var%s\n", truth ? ",mean_angle_err" : "");
  for (size_t r = 0; r < count; r++) {
    fprintf(f, "%d,%d,%.10g,%.10g", rows[r].k, rows[r].degree, rows[r].mean_normal_err,
            rows[r].mean_normal_var);
    if (truth) fprintf(f, ",%.10g", rows[r].mean_angle_err);
    fprintf(f, "\n");
  }
  if (fclose(f) != 0 || rename(tmp, path) != 0) {
    remove(tmp);
    return cli_error("%s: cannot write", path);
  }
  return 0;
}

int cmd_normals(const cli_command *cmd, int argc, char **argv) {
  bsurf_normal_options no = bsurf_normal_options_default();
  const char *fit = "pca", *center = "centroid", *output = NULL, *select_k = NULL,
             *select_degree = NULL;
  const char *curve = NULL, *truth_path = NULL, *sigma_nu_s = "auto", *orient = "none";
  const char *select_rule = "auto", *noise_pool = "global";
  bsurf_kselect_options ksel = bsurf_kselect_options_default();
  int k_ref = 0, test_error = 0, iterations = 0, ascii = 0, json = 0, quiet = 0, force = 0;
  double alpha = 0.1, sigma_d = 0;
  const char *memory_limit = "auto";
  size_t tile_points = 0;
  cli_option opts[] = {
      {'k', "neighbors", ARG_INT, &no.k, "K", "neighbourhood size K, the point included", 3, 65535},
      {0, "fit", ARG_STRING, &fit, "F", "pca (plane) or poly (height polynomial, Eq. 5.9)", 1, 0},
      {'d', "degree", ARG_INT, &no.degree, "M", "degree of the polynomial for --fit poly, 1..4", 1,
       4},
      {0, "pca-center", ARG_STRING, &center, "C", "PCA about the centroid or the point (Eq. 2.1)",
       1, 0},
      {'B', "bootstrap", ARG_INT, &no.bootstrap, "B", "bootstrap replicates; 0 = a single fit", 0,
       100000},
      CLI_OPT_SEED(no.seed),
      CLI_OPT_THREADS(no.threads),
      {0, "test-error", ARG_FLAG, &test_error, "",
       "write normal_err, the bootstrap test error (Eq. 5.10)", 1, 0},
      {0, "k-ref", ARG_INT, &k_ref, "K",
       "neighbourhood of the reference PCA normals of Eq. 5.10 (0 = -k)", 0, 65535},
      {0, "select-k", ARG_STRING, &select_k, "A:B:STEP", "per point, the K chosen by --select-rule",
       1, 0},
      {0, "select-rule", ARG_STRING, &select_rule, "R",
       "mse (estimated variance + bias^2 of the normal: the PCA plane's, or with --fit poly "
       "the fit's over K and --select-degree), test-error (Eq. 5.10) or auto (mse where it "
       "applies: no --curve, K >= 7; else test-error)",
       1, 0},
      {0, "noise-k", ARG_INT, &ksel.noise_k, "K",
       "with --select-rule mse: neighbourhood of the noise estimate", 12, 65535},
      {0, "noise-pool", ARG_STRING, &noise_pool, "P",
       "with --select-rule mse: one noise level for the cloud (global) or per point (local)", 1, 0},
      {0, "select-degree", ARG_STRING, &select_degree, "LIST",
       "with --fit poly: also choose the degree, e.g. 1,2,3", 1, 0},
      {0, "curve", ARG_STRING, &curve, "FILE.csv",
       "with --select-k: mean errors against K (figs. 5.6-5.11)", 1, 0},
      {0, "truth", ARG_STRING, &truth_path, "FILE",
       "ground-truth normals (same points) for --curve", 1, 0},
      {0, "smooth-iterations", ARG_INT, &iterations, "N",
       "bilateral normal smoothing passes (Eq. 5.6)", 0, 100000},
      {0, "alpha", ARG_DOUBLE, &alpha, "A", "strength of one smoothing pass", 0, 1},
      {0, "sigma-d", ARG_DOUBLE, &sigma_d, "S", "spatial sigma of the smoothing (0 = h)", 0, 1e300},
      {0, "sigma-nu", ARG_STRING, &sigma_nu_s, "S",
       "variance sigma: a value, auto (85th percentile of normal_var) or inf (single Gaussian)", 1,
       0},
      {0, "orient", ARG_STRING, &orient, "MODE", "none or mst (consistent orientation, Hoppe 1992)",
       1, 0},
      CLI_OPTS_JOB(output, ascii, force, tile_points, memory_limit, json, quiet),
  };
  char *pos[1];
  int rc = cli_parse_input(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos);
  if (rc != CLI_PARSED) return rc;
  static const char *const fits[] = {"pca", "poly"}, *const orients[] = {"none", "mst"};
  int f = cli_choice(fit, fits, 2), om = cli_choice(orient, orients, 2);
  if (f < 0) return cli_usage_error(cmd, "--fit must be pca or poly, not '%s'", fit);
  if (cli_pca_center(cmd, center, &no.pca_center)) return CLI_USAGE;
  if (om < 0) return cli_usage_error(cmd, "--orient must be none or mst, not '%s'", orient);
  no.fit = (bsurf_normal_fit)f;
  double sigma_nu = NAN; /* NAN = auto */
  if (strcmp(sigma_nu_s, "inf") == 0) {
    sigma_nu = INFINITY;
  } else if (strcmp(sigma_nu_s, "auto") != 0) {
    char *end;
    sigma_nu = strtod(sigma_nu_s, &end);
    if (*end || !(sigma_nu > 0))
      return cli_usage_error(cmd, "--sigma-nu must be a positive number, auto or inf");
  }
  int ks[MAX_CANDIDATES], ds[4], nk = 1, nd = 1;
  ks[0] = no.k;
  ds[0] = no.degree;
  if (select_k && (nk = parse_range(select_k, ks, MAX_CANDIDATES)) < 1)
    return cli_usage_error(
        cmd, "--select-k needs A:B:STEP with 3 <= A <= B and STEP >= 1, not '%s'", select_k);
  if (select_degree) {
    if (no.fit != BSURF_NORMAL_POLY)
      return cli_usage_error(cmd, "--select-degree needs --fit poly");
    if ((nd = parse_degrees(select_degree, ds, 4)) < 1)
      return cli_usage_error(cmd, "--select-degree needs a list of degrees 1..4 like 1,2,3");
  }
  if (curve && !select_k) return cli_usage_error(cmd, "--curve needs --select-k");
  static const char *const rules[] = {"test-error", "mse", "auto"};
  int sr = cli_choice(select_rule, rules, 3);
  if (sr < 0)
    return cli_usage_error(cmd, "--select-rule must be test-error, mse or auto, not '%s'",
                           select_rule);
  ksel.rule = (bsurf_kselect_rule)sr;
  static const char *const pools[] = {"global", "local"};
  int np = cli_choice(noise_pool, pools, 2);
  if (np < 0)
    return cli_usage_error(cmd, "--noise-pool must be global or local, not '%s'", noise_pool);
  ksel.noise_pool = (bsurf_noise_pool)np;
  if (ksel.rule == BSURF_KSELECT_MSE) {
    if (!select_k && !select_degree)
      return cli_usage_error(cmd, "--select-rule mse needs --select-k or --select-degree");
    if (curve) return cli_usage_error(cmd, "--curve needs --select-rule test-error");
    if (ks[0] < 7)
      return cli_usage_error(
          cmd, "--select-rule mse needs candidates K >= 7 (a quadric per K), not %d", ks[0]);
  }
  if (truth_path && !curve) return cli_usage_error(cmd, "--truth is used by --curve");
  const int selecting = select_k || select_degree;
  if (selecting) test_error = 1;
  if (k_ref == 0) k_ref = no.k;
  if (k_ref < 3) return cli_usage_error(cmd, "--k-ref must be at least 3");
  for (int a = 0; a < nk; a++) {
    for (int b = 0; b < nd; b++)
      if (no.fit == BSURF_NORMAL_POLY && ks[a] < (ds[b] + 1) * (ds[b] + 2) / 2)
        return cli_usage_error(cmd, "K = %d is too small for degree %d", ks[a], ds[b]);
  }
  if (!output) return cli_usage_error(cmd, "missing -o OUTPUT");
  if (cli_check_output(output, pos[0], force)) return 1;
  if (truth_path && cli_check_output(output, truth_path, force)) return 1;
  if (curve && cli_check_writable(curve, pos[0], force)) return 1;

  bsurf_normals_job_options jo = bsurf_normals_job_options_default();
  jo.normals = no;
  jo.test_error = test_error;
  jo.k_ref = k_ref;
  if (select_k) jo.select_k = ks, jo.select_k_count = nk;
  if (select_degree) jo.select_degree = ds, jo.select_degree_count = nd;
  jo.select_rule = ksel.rule;
  jo.noise_k = ksel.noise_k;
  jo.noise_pool = ksel.noise_pool;
  jo.smooth_iterations = iterations;
  jo.alpha = alpha;
  jo.sigma_d = sigma_d;
  jo.sigma_nu = sigma_nu;
  jo.orient = om == 1 ? BSURF_ORIENT_MST : BSURF_ORIENT_NONE;
  size_t plan = 0;
  /* the rule the job applies, its K_max and its arrays' bytes per point
   * (upper bounds: bootsurf.h, bsurf_normals_job_memory) */
  bsurf_normals_job_plan jp;
  if (bsurf_normals_job_memory(&jo, &jp) != BSURF_OK) return cli_error("%s", bsurf_last_message());
  rc = cli_tiles_plan_bytes(cmd, pos[0], output, ascii, tile_points, memory_limit, jp.k_max,
                            jp.field_count, jp.point_bytes, jp.cloud_bytes, &plan);
  if (rc) return rc;
  /* smoothing passes reach beyond the K-neighbourhood; orientation is
   * global (normal_err's reference normals: a first tiled stage) */
  if (plan && curve)
    return cli_error(
        "%s: --curve keeps every candidate's values of every point: not available in tiled runs",
        pos[0]);
  if (plan && (iterations > 0 || om == 1))
    return cli_error(
        "%s: --smooth-iterations and --orient mst use more than each point's K-neighbourhood: "
        "not available in tiled runs",
        pos[0]);

  double t0 = cli_now();
  bsurf_cloud c, truth;
  bsurf_cloud_init(&c);
  bsurf_cloud_init(&truth);
  bsurf_normals_curve_row *rows = NULL;
  bsurf_job_io io = {0};
  cli_progress prog;
  rc = 1;
  if (cli_job_io(&io, pos[0], output, plan, &c, &prog, "normals", quiet)) goto done;
  if (truth_path) {
    if (cli_read_cloud(truth_path, &truth)) goto done;
    if (truth.point_count != c.point_count || !truth.normals) {
      cli_error("%s: the truth needs normals and the same %zu points as %s", truth_path,
                c.point_count, pos[0]);
      goto done;
    }
    jo.curve_truth = truth.normals;
  }
  if (curve && !(jo.curve = rows = calloc((size_t)nk * (size_t)nd, sizeof *rows))) {
    cli_error("out of memory");
    goto done;
  }
  jo.normals.progress = cli_progress_cb;
  jo.normals.progress_user = &prog;
  bsurf_normals_job_summary sum;
  bsurf_failure where = {0, -1, ""};
  bsurf_status st = bsurf_normals_job(&io, &jo, &sum, &where);
  if (cli_job_done(&prog, pos[0], output, plan, st, &where, sum.duplicates)) goto done;
  if (!plan && cli_write_cloud(output, &c, ascii)) goto done;
  if (curve && write_curve(curve, rows, sum.curve_rows, truth_path != NULL)) goto done;
  double secs = cli_now() - t0;
  if (json) {
    cli_json j = json_start("normals", pos[0], output);
    json_points_h(&j, sum.points, sum.h);
    json_int(&j, "k", no.k);
    json_str(&j, "fit", fit);
    if (no.fit == BSURF_NORMAL_POLY) json_int(&j, "degree", no.degree);
    json_str(&j, "pca_center", center);
    json_int(&j, "bootstrap", no.bootstrap);
    json_int(&j, "seed", (long long)no.seed);
    json_int(&j, "threads", bsurf_threads_resolve(no.threads));
    if (test_error) json_int(&j, "k_ref", k_ref);
    if (select_k) json_str(&j, "select_k", select_k);
    const int mse = sum.select_rule == BSURF_KSELECT_MSE; /* auto resolved */
    if (select_k || select_degree) json_str(&j, "select_rule", mse ? "mse" : "test-error");
    if (mse) json_int(&j, "noise_k", ksel.noise_k);
    if (mse) json_str(&j, "noise_pool", noise_pool);
    if (select_degree) json_str(&j, "select_degree", select_degree);
    if (iterations > 0) {
      json_int(&j, "smooth_iterations", iterations);
      json_num(&j, "alpha", alpha);
      json_num(&j, "sigma_d", sum.sigma_d);
      json_num(&j, "sigma_nu", isfinite(sum.sigma_nu) ? sum.sigma_nu : -1);
    }
    json_str(&j, "orient", orient);
    json_int(&j, "replicates_total", (long long)sum.report.replicates_total);
    json_int(&j, "replicates_skipped", (long long)sum.report.replicates_skipped);
    json_int(&j, "degree_reduced", (long long)sum.report.degree_reduced);
    json_int(&j, "degenerate", (long long)sum.report.degenerate);
    if (plan) json_tiles(&j, sum.tile_points, sum.tiles);
    json_means(&j, sum.field_names, sum.means, sum.field_count, sum.h);
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    char kdesc[96];
    const char *rule = sum.select_rule == BSURF_KSELECT_MSE ? "mse" : "test-error"; /* resolved */
    if (select_k)
      snprintf(kdesc, sizeof kdesc, "K per point in %d..%d%s by the %s rule", ks[0], ks[nk - 1],
               select_degree ? " and the degree" : "", rule);
    else if (select_degree)
      snprintf(kdesc, sizeof kdesc, "K = %d, the degree per point by the %s rule", no.k, rule);
    else
      snprintf(kdesc, sizeof kdesc, "K = %d", no.k);
    char fdesc[48]; /* the fit, and a fixed polynomial's degree */
    if (no.fit == BSURF_NORMAL_POLY && !select_degree)
      snprintf(fdesc, sizeof fdesc, "poly, degree %d", no.degree);
    else
      snprintf(fdesc, sizeof fdesc, "%s", fit);
    printf("normals: %zu points, h = %.6g, %s, %s, B = %d, %.2f s\n", sum.points, sum.h, kdesc,
           fdesc, no.bootstrap, secs);
    print_means(stdout, sum.field_names, sum.means, sum.field_count, sum.h);
    if (sum.report.degenerate)
      printf("  %zu points have degenerate neighbourhoods\n", sum.report.degenerate);
    cli_print_footer(output);
  }
  rc = 0;
done:
  bsurf_cloud_free(&c);
  bsurf_cloud_free(&truth);
  free(rows);
  return rc;
}
