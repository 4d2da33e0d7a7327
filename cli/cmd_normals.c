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
  for (int k = a; k <= b && n < max; k += step) ks[n++] = k;
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
    if (*end == ',') end++;
    else if (*end) return -1;
    p = end;
  }
  return n > 0 ? n : -1;
}

int cmd_normals(const cli_command *cmd, int argc, char **argv) {
  bsurf_normal_options no = bsurf_normal_options_default();
  const char *fit = "pca", *center = "centroid", *output = NULL, *select_k = NULL, *select_degree = NULL;
  const char *curve = NULL, *truth_path = NULL, *sigma_nu_s = "auto", *orient = "none";
  int k_ref = 0, test_error = 0, iterations = 0, ascii = 0, json = 0, quiet = 0, force = 0;
  double alpha = 0.1, sigma_d = 0;
  cli_option opts[] = {
      {'k', "neighbors", ARG_INT, &no.k, "K", "neighbourhood size K, the point included", 3, 65535},
      {0, "fit", ARG_STRING, &fit, "F", "pca (plane) or poly (height polynomial, Eq. 5.9)", 1, 0},
      {'d', "degree", ARG_INT, &no.degree, "M", "degree of the polynomial for --fit poly, 1..4", 1, 4},
      {0, "pca-center", ARG_STRING, &center, "C", "PCA about the centroid or the point (Eq. 2.1)", 1, 0},
      {'B', "bootstrap", ARG_INT, &no.bootstrap, "B", "bootstrap replicates; 0 = a single fit", 0, 100000},
      CLI_OPT_SEED(no.seed),
      CLI_OPT_THREADS(no.threads),
      {0, "test-error", ARG_FLAG, &test_error, "", "write normal_err, the bootstrap test error (Eq. 5.10)", 1, 0},
      {0, "k-ref", ARG_INT, &k_ref, "K", "neighbourhood of the reference PCA normals of Eq. 5.10 (0 = -k)", 0,
       65535},
      {0, "select-k", ARG_STRING, &select_k, "A:B:STEP", "per point, the K with the smallest normal_err", 1, 0},
      {0, "select-degree", ARG_STRING, &select_degree, "LIST", "with --fit poly: also choose the degree, e.g. 1,2,3",
       1, 0},
      {0, "curve", ARG_STRING, &curve, "FILE.csv", "with --select-k: mean errors against K (figs. 5.6-5.11)", 1, 0},
      {0, "truth", ARG_STRING, &truth_path, "FILE", "ground-truth normals (same points) for --curve", 1, 0},
      {0, "smooth-iterations", ARG_INT, &iterations, "N", "bilateral normal smoothing passes (Eq. 5.6)", 0,
       100000},
      {0, "alpha", ARG_DOUBLE, &alpha, "A", "strength of one smoothing pass", 0, 1},
      {0, "sigma-d", ARG_DOUBLE, &sigma_d, "S", "spatial sigma of the smoothing (0 = h)", 0, 1e300},
      {0, "sigma-nu", ARG_STRING, &sigma_nu_s, "S",
       "variance sigma: a value, auto (85th percentile of normal_var) or inf (single Gaussian)", 1, 0},
      {0, "orient", ARG_STRING, &orient, "MODE", "none or mst (consistent orientation, Hoppe 1992)", 1, 0},
      CLI_OPTS_OUTPUT(output, ascii, force),
      CLI_OPT_DROP_INVALID,
      CLI_OPTS_REPORT(json, quiet),
  };
  char *pos[1];
  int npos;
  int rc = cli_parse(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos, 1, &npos);
  if (rc != CLI_PARSED) return rc;
  if (npos != 1) return cli_usage_error(cmd, "expected one INPUT file");
  static const char *const fits[] = {"pca", "poly"}, *const centers[] = {"centroid", "point"};
  static const char *const orients[] = {"none", "mst"};
  int f = cli_choice(fit, fits, 2), pc = cli_choice(center, centers, 2), om = cli_choice(orient, orients, 2);
  if (f < 0) return cli_usage_error(cmd, "--fit must be pca or poly, not '%s'", fit);
  if (pc < 0) return cli_usage_error(cmd, "--pca-center must be centroid or point, not '%s'", center);
  if (om < 0) return cli_usage_error(cmd, "--orient must be none or mst, not '%s'", orient);
  no.fit = (bsurf_normal_fit)f;
  no.pca_center = (bsurf_pca_center)pc;
  double sigma_nu = NAN; /* NAN = auto */
  if (strcmp(sigma_nu_s, "inf") == 0) {
    sigma_nu = INFINITY;
  } else if (strcmp(sigma_nu_s, "auto") != 0) {
    char *end;
    sigma_nu = strtod(sigma_nu_s, &end);
    if (*end || !(sigma_nu > 0)) return cli_usage_error(cmd, "--sigma-nu must be a positive number, auto or inf");
  }
  int ks[MAX_CANDIDATES], ds[4], nk = 1, nd = 1;
  ks[0] = no.k;
  ds[0] = no.degree;
  if (select_k && (nk = parse_range(select_k, ks, MAX_CANDIDATES)) < 1)
    return cli_usage_error(cmd, "--select-k needs A:B:STEP with 3 <= A <= B and STEP >= 1, not '%s'", select_k);
  if (select_degree) {
    if (no.fit != BSURF_NORMAL_POLY) return cli_usage_error(cmd, "--select-degree needs --fit poly");
    if ((nd = parse_degrees(select_degree, ds, 4)) < 1)
      return cli_usage_error(cmd, "--select-degree needs a list of degrees 1..4 like 1,2,3");
  }
  if (curve && !select_k) return cli_usage_error(cmd, "--curve needs --select-k");
  if (truth_path && !curve) return cli_usage_error(cmd, "--truth is used by --curve");
  const int selecting = select_k || select_degree;
  if (selecting) test_error = 1;
  if (k_ref == 0) k_ref = no.k;
  if (k_ref < 3) return cli_usage_error(cmd, "--k-ref must be at least 3");
  int kmax = k_ref > no.k ? k_ref : no.k;
  for (int a = 0; a < nk; a++) {
    if (ks[a] > kmax) kmax = ks[a];
    for (int b = 0; b < nd; b++)
      if (no.fit == BSURF_NORMAL_POLY && ks[a] < (ds[b] + 1) * (ds[b] + 2) / 2)
        return cli_usage_error(cmd, "K = %d is too small for degree %d", ks[a], ds[b]);
  }
  if (!output) return cli_usage_error(cmd, "missing -o OUTPUT");
  if (cli_check_output(output, pos[0], force)) return 1;
  if (truth_path && cli_check_output(output, truth_path, force)) return 1;
  if (curve && cli_check_writable(curve, pos[0], force)) return 1;

  double t0 = cli_now();
  bsurf_cloud c, truth;
  bsurf_cloud_init(&c);
  bsurf_cloud_init(&truth);
  bsurf_neighbors nb;
  memset(&nb, 0, sizeof nb);
  double *ref = NULL, *cand_n = NULL, *cand_v = NULL, *cand_e = NULL, *best_e = NULL;
  double *normals = NULL, *var = NULL, *err = NULL;
  double *ksel = NULL, *dsel = NULL;
  FILE *cf = NULL;
  char curve_tmp[4200] = "";
  bsurf_normal_report rep, total;
  memset(&total, 0, sizeof total);
  rc = 1;
  if (cli_read_cloud(pos[0], &c)) goto done;
  if (truth_path) {
    if (cli_read_cloud(truth_path, &truth)) goto done;
    if (truth.point_count != c.point_count || !truth.normals) {
      cli_error("%s: the truth needs normals and the same %zu points as %s", truth_path, c.point_count, pos[0]);
      goto done;
    }
  }
  if (cli_build_neighbors(pos[0], &c, kmax, no.threads, quiet, &nb)) goto done;
  cli_progress prog;
  bsurf_status st;
  const size_t n = c.point_count;
  normals = malloc(n * 3 * sizeof(double));
  var = calloc(n, sizeof(double));
  err = calloc(n, sizeof(double));
  if (!normals || !var || !err) {
    cli_error("out of memory");
    goto done;
  }
  no.progress = cli_progress_cb;
  no.progress_user = &prog;
  if (test_error) {
    /* reference normals n_j of Eq. 5.10: single PCA fits on a fixed K */
    bsurf_normal_options ro = no;
    ro.fit = BSURF_NORMAL_PCA;
    ro.k = k_ref;
    ro.bootstrap = 0;
    ref = malloc(n * 3 * sizeof(double));
    if (!ref) {
      cli_error("out of memory");
      goto done;
    }
    bsurf_normal_fields rf = {ref, NULL, NULL};
    cli_progress_init(&prog, "reference", quiet);
    st = bsurf_estimate_normals(c.xyz, &nb, NULL, &ro, &rf, NULL);
    cli_progress_done(&prog);
    if (st != BSURF_OK) {
      cli_error("%s: %s", pos[0], cli_interrupted() ? "interrupted" : bsurf_strerror(st));
      goto done;
    }
  }
  if (selecting) {
    cand_n = malloc(n * 3 * sizeof(double));
    cand_v = calloc(n, sizeof(double));
    cand_e = calloc(n, sizeof(double));
    best_e = malloc(n * sizeof(double));
    ksel = calloc(n, sizeof(double));
    dsel = calloc(n, sizeof(double));
    if (!cand_n || !cand_v || !cand_e || !best_e || !ksel || !dsel) {
      cli_error("out of memory");
      goto done;
    }
    for (size_t i = 0; i < n; i++) best_e[i] = INFINITY;
    if (curve) {
      snprintf(curve_tmp, sizeof curve_tmp, "%s.tmp", curve);
      cf = fopen(curve_tmp, "w");
      if (!cf) {
        cli_error("%s: cannot write", curve_tmp);
        goto done;
      }
      fprintf(cf, "k,degree,mean_normal_err,mean_normal_var%s\n", truth_path ? ",mean_angle_err" : "");
    }
  }
  for (int a = 0; a < nk; a++) {
    for (int b = 0; b < nd; b++) {
      bsurf_normal_options o = no;
      o.k = ks[a];
      o.degree = ds[b];
      bsurf_normal_fields out = {selecting ? cand_n : normals, selecting ? cand_v : var,
                                 test_error ? (selecting ? cand_e : err) : NULL};
      char label[32];
      snprintf(label, sizeof label, selecting ? "K=%d" : "normals", o.k);
      cli_progress_init(&prog, label, quiet);
      st = bsurf_estimate_normals(c.xyz, &nb, ref, &o, &out, &rep);
      cli_progress_done(&prog);
      if (st != BSURF_OK) {
        cli_error("%s: %s", pos[0], cli_interrupted() ? "interrupted" : bsurf_strerror(st));
        goto done;
      }
      total.replicates_total += rep.replicates_total;
      total.replicates_skipped += rep.replicates_skipped;
      total.degree_reduced += rep.degree_reduced;
      total.degenerate += rep.degenerate;
      if (!selecting) continue;
      double se = 0, sv = 0, sa = 0;
      for (size_t i = 0; i < n; i++) {
        se += cand_e[i];
        sv += cand_v[i];
        if (truth_path) sa += bsurf_normal_angle(&cand_n[3 * i], &truth.normals[3 * i]);
        if (cand_e[i] < best_e[i]) { /* ties keep the smaller K, then degree */
          best_e[i] = cand_e[i];
          memcpy(&normals[3 * i], &cand_n[3 * i], 3 * sizeof(double));
          var[i] = cand_v[i];
          err[i] = cand_e[i];
          ksel[i] = o.k;
          dsel[i] = o.degree;
        }
      }
      if (cf) {
        fprintf(cf, "%d,%d,%.10g,%.10g", o.k, no.fit == BSURF_NORMAL_POLY ? o.degree : 1, se / n, sv / n);
        if (truth_path) fprintf(cf, ",%.10g", sa / n);
        fprintf(cf, "\n");
      }
    }
  }
  double h = nb.h;
  if (iterations > 0) {
    /* auto: the threshold of the top 15% of normal_var (Table 5.2's split) */
    if (isnan(sigma_nu) && (no.bootstrap < 2 || bsurf_quantile_split(var, n, 0.85, NULL, &sigma_nu, NULL, NULL) != BSURF_OK))
      sigma_nu = INFINITY;
    if (!(sigma_nu > 0)) sigma_nu = INFINITY; /* all variances 0: nothing to weigh */
    st = bsurf_smooth_normals(c.xyz, &nb, no.k, normals, no.bootstrap >= 2 ? var : NULL, iterations, alpha,
                              sigma_d > 0 ? sigma_d : h, sigma_nu, no.threads);
    if (st != BSURF_OK) {
      cli_error("smoothing: %s", bsurf_strerror(st));
      goto done;
    }
  }
  if (om == 1 && (st = bsurf_orient_normals(c.xyz, &nb, no.k, normals)) != BSURF_OK) {
    cli_error("orientation: %s", bsurf_strerror(st));
    goto done;
  }
  /* outputs: normals replaced, confidence and error fields added */
  if (!c.normals) {
    c.normals = normals;
    c.normal_type = BSURF_FLOAT32;
    normals = NULL;
  } else {
    memcpy(c.normals, normals, n * 3 * sizeof(double));
  }
  const char *names[4];
  const double *vals[4];
  bsurf_type types[4];
  int nf = 0;
  if (no.bootstrap >= 2) {
    names[nf] = "normal_var";
    vals[nf] = var;
    types[nf++] = BSURF_FLOAT32;
  }
  if (test_error) {
    names[nf] = "normal_err";
    vals[nf] = err;
    types[nf++] = BSURF_FLOAT32;
  }
  if (select_k) {
    names[nf] = "k_selected";
    vals[nf] = ksel;
    types[nf++] = BSURF_UINT16;
  }
  if (select_degree) {
    names[nf] = "degree_selected";
    vals[nf] = dsel;
    types[nf++] = BSURF_UINT8;
  }
  for (int t = 0; t < nf; t++) {
    bsurf_field *fl = bsurf_cloud_add_field(&c, names[t], types[t]);
    if (!fl) {
      cli_error("out of memory");
      goto done;
    }
    memcpy(fl->values, vals[t], n * sizeof(double));
  }
  if (cli_write_cloud(output, &c, ascii)) goto done;
  if (cf) {
    int bad = fclose(cf) != 0;
    cf = NULL;
    if (bad || rename(curve_tmp, curve) != 0) {
      cli_error("%s: cannot write", curve);
      goto done;
    }
    curve_tmp[0] = 0;
  }
  double secs = cli_now() - t0;
  if (json) {
    cli_json j;
    json_begin(&j, stdout);
    json_str(&j, "command", "normals");
    json_str(&j, "input", pos[0]);
    json_str(&j, "output", output);
    json_int(&j, "points", (long long)n);
    json_num(&j, "h", h);
    json_int(&j, "k", no.k);
    json_str(&j, "fit", fit);
    if (no.fit == BSURF_NORMAL_POLY) json_int(&j, "degree", no.degree);
    json_str(&j, "pca_center", center);
    json_int(&j, "bootstrap", no.bootstrap);
    json_int(&j, "seed", (long long)no.seed);
    json_int(&j, "threads", bsurf_threads_resolve(no.threads));
    if (test_error) json_int(&j, "k_ref", k_ref);
    if (select_k) json_str(&j, "select_k", select_k);
    if (select_degree) json_str(&j, "select_degree", select_degree);
    if (iterations > 0) {
      json_int(&j, "smooth_iterations", iterations);
      json_num(&j, "alpha", alpha);
      json_num(&j, "sigma_d", sigma_d > 0 ? sigma_d : h);
      json_num(&j, "sigma_nu", isfinite(sigma_nu) ? sigma_nu : -1);
    }
    json_str(&j, "orient", orient);
    json_int(&j, "replicates_total", (long long)total.replicates_total);
    json_int(&j, "replicates_skipped", (long long)total.replicates_skipped);
    json_int(&j, "degree_reduced", (long long)total.degree_reduced);
    json_int(&j, "degenerate", (long long)total.degenerate);
    json_field_means(&j, &c, names, nf, h);
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    printf("normals: %zu points, h = %.6g, K = %d, %s%s, B = %d, %.2f s\n", n, h, no.k, fit,
           no.fit == BSURF_NORMAL_POLY ? " (poly)" : "", no.bootstrap, secs);
    print_field_means(stdout, &c, names, nf, h);
    if (total.degenerate) printf("  %zu points have degenerate neighbourhoods\n", total.degenerate);
    cli_print_input_report(stdout);
    printf("  -> %s\n", output);
  }
  rc = 0;
done:
  if (cf) fclose(cf);
  if (curve_tmp[0]) remove(curve_tmp);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
  bsurf_cloud_free(&truth);
  free(ref);
  free(cand_n);
  free(cand_v);
  free(cand_e);
  free(best_e);
  free(normals);
  free(var);
  free(err);
  free(ksel);
  free(dsel);
  return rc;
}
