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

/* What one normals run computes (every candidate K and degree), shared by the
 * in-memory run and the tiles. */
typedef struct normals_job {
  bsurf_normal_options no;
  int test_error, selecting, select_k, select_degree, k_ref;
  bsurf_kselect_options ksel; /* rule MSE: bsurf_select_k chooses K */
  int ks[MAX_CANDIDATES], nk, ds[4], nd;
  int quiet;
} normals_job;

/* Per-point results (n long, x 3 for vectors). */
typedef struct normals_bufs {
  double *normals, *var, *err, *ref, *cand_n, *cand_v, *cand_e, *best_e, *ksel, *dsel;
} normals_bufs;

static void normals_bufs_free(normals_bufs *b) {
  free(b->normals);
  free(b->var);
  free(b->err);
  free(b->ref);
  free(b->cand_n);
  free(b->cand_v);
  free(b->cand_e);
  free(b->best_e);
  free(b->ksel);
  free(b->dsel);
  memset(b, 0, sizeof *b);
}

static int normals_bufs_alloc(normals_bufs *b, const normals_job *job, size_t n) {
  memset(b, 0, sizeof *b);
  b->normals = malloc(n * 3 * sizeof(double));
  b->var = calloc(n, sizeof(double));
  b->err = calloc(n, sizeof(double));
  int ok = b->normals && b->var && b->err;
  if (job->test_error && job->ksel.rule != BSURF_KSELECT_MSE)
    ok = ok && (b->ref = malloc(n * 3 * sizeof(double)));
  if (job->selecting) {
    b->cand_n = malloc(n * 3 * sizeof(double));
    b->cand_v = calloc(n, sizeof(double));
    b->cand_e = calloc(n, sizeof(double));
    b->best_e = malloc(n * sizeof(double));
    b->ksel = calloc(n, sizeof(double));
    b->dsel = calloc(n, sizeof(double));
    ok = ok && b->cand_n && b->cand_v && b->cand_e && b->best_e && b->ksel && b->dsel;
    for (size_t i = 0; ok && i < n; i++)
      b->best_e[i] = INFINITY;
  }
  if (!ok) normals_bufs_free(b);
  return ok ? 0 : cli_error("out of memory");
}

/* --select-k with PCA: every candidate in one pass (bsurf_select_normals_k);
 * with --curve each candidate's means, summed in point order. */
static bsurf_status normals_select_pca(const normals_job *job, const double *xyz,
                                       const bsurf_neighbors *nb, const bsurf_normal_options *no,
                                       const double *ref, normals_bufs *b,
                                       bsurf_normal_report *total, FILE *cf,
                                       const bsurf_cloud *truth, cli_progress *prog) {
  const size_t n = nb->point_count;
  const int nk = job->nk;
  int *ksel = malloc(n * sizeof *ksel);
  double *ce = NULL, *cv = NULL, *cn = NULL;
  if (cf) {
    ce = malloc(n * (size_t)nk * sizeof *ce);
    cv = malloc(n * (size_t)nk * sizeof *cv);
    cn = truth ? malloc(n * (size_t)nk * 3 * sizeof *cn) : NULL;
  }
  bsurf_status st = BSURF_ERR_NOMEM;
  if (ksel && (!cf || (ce && cv && (!truth || cn)))) {
    bsurf_normal_select_fields out = {b->normals, b->var, b->err, ksel, ce, cv, cn};
    char label[48];
    snprintf(label, sizeof label, "K=%d..%d", job->ks[0], job->ks[nk - 1]);
    if (prog) cli_progress_init(prog, label, job->quiet);
    st = bsurf_select_normals_k(xyz, nb, ref, no, job->ks, nk, &out, total);
    if (prog) cli_progress_done(prog);
  }
  if (st == BSURF_OK) {
    for (size_t i = 0; i < n; i++) {
      b->ksel[i] = ksel[i];
      b->dsel[i] = no->degree;
      b->best_e[i] = b->err[i];
    }
    for (int a = 0; cf && a < nk; a++) {
      double se = 0, sv = 0, sa = 0;
      for (size_t i = 0; i < n; i++) {
        se += ce[i * nk + a];
        sv += cv[i * nk + a];
        if (truth) sa += bsurf_normal_angle(&cn[(i * nk + a) * 3], &truth->normals[3 * i]);
      }
      fprintf(cf, "%d,1,%.10g,%.10g", job->ks[a], se / n, sv / n);
      if (truth) fprintf(cf, ",%.10g", sa / n);
      fprintf(cf, "\n");
    }
  }
  free(ksel);
  free(ce);
  free(cv);
  free(cn);
  return st;
}

/* The reference normals (or ref_in, the first stage's of a tiled run: one
 * per point of xyz), then every candidate (K, degree), keeping per point
 * the one with the smallest normal_err. cf / truth: the --curve file and its
 * ground truth, or NULL. Progress bars unless prog is NULL. */
static bsurf_status normals_compute(const normals_job *job, const double *xyz,
                                    const bsurf_neighbors *nb, const uint64_t *point_index,
                                    const double *ref_in, normals_bufs *b,
                                    bsurf_normal_report *total, FILE *cf, const bsurf_cloud *truth,
                                    cli_progress *prog) {
  const size_t n = nb->point_count;
  bsurf_normal_options no = job->no;
  no.point_index = point_index;
  no.progress = prog ? cli_progress_cb : NULL;
  no.progress_user = prog;
  bsurf_normal_report rep;
  bsurf_status st;
  memset(total, 0, sizeof *total);
  const double *ref = ref_in ? ref_in : b->ref;
  if (b->ref && !ref_in) { /* NULL with --select-rule mse: it needs no reference */
    /* reference normals n_j of Eq. 5.10: single PCA fits on a fixed K */
    bsurf_normal_options ro = no;
    ro.fit = BSURF_NORMAL_PCA;
    ro.k = job->k_ref;
    ro.bootstrap = 0;
    bsurf_normal_fields rf = {b->ref, NULL, NULL};
    if (prog) cli_progress_init(prog, "reference", job->quiet);
    st = bsurf_estimate_normals(xyz, nb, NULL, &ro, &rf, NULL);
    if (prog) cli_progress_done(prog);
    if (st != BSURF_OK) return st;
  }
  const int selecting = job->selecting;
  if (selecting && no.fit == BSURF_NORMAL_PCA &&
      job->ksel.rule != BSURF_KSELECT_MSE) /* nested candidates, one pass */
    return normals_select_pca(job, xyz, nb, &no, ref, b, total, cf, truth, prog);
  int *kmse = NULL; /* rule MSE: the chosen K; the candidates' loop below then keeps it */
  if (job->ksel.rule == BSURF_KSELECT_MSE) {
    bsurf_kselect_options ko = job->ksel;
    ko.progress = no.progress;
    ko.progress_user = prog;
    int bootstrap = no.bootstrap >= 2;
    if (!(kmse = malloc(n * sizeof(int)))) return BSURF_ERR_NOMEM;
    bsurf_kselect_fields kf = {bootstrap ? NULL : b->normals, kmse, b->err, NULL};
    if (prog) cli_progress_init(prog, "select K", job->quiet);
    st = bsurf_select_k(xyz, nb, &ko, &kf, NULL);
    if (prog) cli_progress_done(prog);
    for (size_t i = 0; i < n; i++)
      b->ksel[i] = kmse[i];
    if (st != BSURF_OK || !bootstrap) {
      free(kmse);
      return st;
    }
  }
  for (int a = 0; a < job->nk; a++) {
    for (int d = 0; d < job->nd; d++) {
      bsurf_normal_options o = no;
      o.k = job->ks[a];
      o.degree = job->ds[d];
      bsurf_normal_fields out = {selecting ? b->cand_n : b->normals, selecting ? b->cand_v : b->var,
                                 job->test_error ? (selecting ? b->cand_e : b->err) : NULL};
      char label[32];
      snprintf(label, sizeof label, selecting ? "K=%d" : "normals", o.k);
      if (prog) cli_progress_init(prog, label, job->quiet);
      st = bsurf_estimate_normals(xyz, nb, ref, &o, &out, &rep);
      if (prog) cli_progress_done(prog);
      if (st != BSURF_OK) {
        free(kmse);
        return st;
      }
      total->replicates_total += rep.replicates_total;
      total->replicates_skipped += rep.replicates_skipped;
      total->degree_reduced += rep.degree_reduced;
      total->degenerate += rep.degenerate;
      if (!selecting) continue;
      double se = 0, sv = 0, sa = 0;
      for (size_t i = 0; i < n; i++) {
        if (kmse) { /* rule MSE: the normal (and variance) of the chosen K */
          if (kmse[i] == o.k) {
            memcpy(&b->normals[3 * i], &b->cand_n[3 * i], 3 * sizeof(double));
            b->var[i] = b->cand_v[i];
          }
          continue;
        }
        se += b->cand_e[i];
        sv += b->cand_v[i];
        if (truth) sa += bsurf_normal_angle(&b->cand_n[3 * i], &truth->normals[3 * i]);
        if (b->cand_e[i] < b->best_e[i]) { /* ties keep the smaller K, then degree */
          b->best_e[i] = b->cand_e[i];
          memcpy(&b->normals[3 * i], &b->cand_n[3 * i], 3 * sizeof(double));
          b->var[i] = b->cand_v[i];
          b->err[i] = b->cand_e[i];
          b->ksel[i] = o.k;
          b->dsel[i] = o.degree;
        }
      }
      if (cf && !kmse) {
        fprintf(cf, "%d,%d,%.10g,%.10g", o.k, no.fit == BSURF_NORMAL_POLY ? o.degree : 1, se / n,
                sv / n);
        if (truth) fprintf(cf, ",%.10g", sa / n);
        fprintf(cf, "\n");
      }
    }
  }
  free(kmse);
  return BSURF_OK;
}

/* The output fields of a run, in the order they are added to the cloud. */
static int normals_field_names(const normals_job *job, const char **names, bsurf_type *types) {
  int nf = 0;
  if (job->no.bootstrap >= 2) names[nf] = "normal_var", types[nf++] = BSURF_FLOAT32;
  if (job->test_error) names[nf] = "normal_err", types[nf++] = BSURF_FLOAT32;
  if (job->select_k) names[nf] = "k_selected", types[nf++] = BSURF_UINT16;
  if (job->select_degree) names[nf] = "degree_selected", types[nf++] = BSURF_UINT8;
  return nf;
}

/* Normals replaced (FLOAT32 when the input had none), fields added; with b,
 * the values copied in. */
static bsurf_status normals_store(const normals_job *job, bsurf_cloud *c, const normals_bufs *b) {
  const size_t n = c->point_count;
  if (!c->normals) {
    c->normals = calloc(n * 3, sizeof(double));
    c->normal_type = BSURF_FLOAT32;
    if (!c->normals) return BSURF_ERR_NOMEM;
  }
  if (b) memcpy(c->normals, b->normals, n * 3 * sizeof(double));
  const char *names[4];
  bsurf_type types[4];
  const double *vals[4] = {b ? b->var : NULL, b ? b->err : NULL, b ? b->ksel : NULL,
                           b ? b->dsel : NULL};
  int nf = normals_field_names(job, names, types), v = 0;
  for (int t = 0; t < nf; t++) {
    bsurf_field *fl = bsurf_cloud_add_field(c, names[t], types[t]);
    if (!fl) return BSURF_ERR_NOMEM;
    /* which buffer: var, err, ksel, dsel in that order, skipping absent ones */
    while (v < 4 && !((v == 0 && job->no.bootstrap >= 2) || (v == 1 && job->test_error) ||
                      (v == 2 && job->select_k) || (v == 3 && job->select_degree)))
      v++;
    if (b) memcpy(fl->values, vals[v], n * sizeof(double));
    v++;
  }
  return BSURF_OK;
}

/* ---- tiles (cli/tiles.c) ---- */

#define NORMALS_SUMS 8 /* replicates total, skipped, degree reduced, degenerate, 4 field sums */

static bsurf_status normals_prepare(void *user, bsurf_cloud *c) {
  return normals_store(user, c, NULL);
}

static bsurf_status normals_run(void *user, const bsurf_tile *tile, bsurf_cloud *core,
                                double *sums) {
  const normals_job *job = user;
  normals_bufs b;
  if (normals_bufs_alloc(&b, job, tile->core_count)) return BSURF_ERR_NOMEM;
  bsurf_normal_report total;
  /* with normal_err: the reference normals of every local point, from the
   * first stage (normals_ref_run) */
  bsurf_status st =
      normals_compute(job, tile->xyz, tile->nb, tile->point_index,
                      job->test_error ? tile->values : NULL, &b, &total, NULL, NULL, NULL);
  if (st == BSURF_OK) st = normals_store(job, core, &b);
  if (st == BSURF_OK) {
    sums[0] += (double)total.replicates_total;
    sums[1] += (double)total.replicates_skipped;
    sums[2] += (double)total.degree_reduced;
    sums[3] += (double)total.degenerate;
    const char *names[4];
    bsurf_type types[4];
    int nf = normals_field_names(job, names, types);
    for (int t = 0; t < nf; t++)
      sums[4 + t] += cli_field_mean(bsurf_cloud_field(core, names[t]), core->point_count) *
                     (double)core->point_count;
  }
  normals_bufs_free(&b);
  return st;
}

/* The first stage of a tiled run with normal_err: the reference normals of
 * Eq. 5.10 (the in-memory run's: single PCA fits on the first k_ref
 * neighbours) of every point, kept by the engine for the second stage's
 * halos (docs/scaling.md). */
static bsurf_status normals_ref_run(void *user, const bsurf_tile *tile, bsurf_cloud *core,
                                    double *sums) {
  (void)core;
  (void)sums;
  const normals_job *job = user;
  bsurf_normal_options ro = job->no;
  ro.fit = BSURF_NORMAL_PCA;
  ro.k = job->k_ref;
  ro.bootstrap = 0;
  ro.point_index = tile->point_index;
  bsurf_normal_fields rf = {tile->values_out, NULL, NULL};
  return bsurf_estimate_normals(tile->xyz, tile->nb, NULL, &ro, &rf, NULL);
}

int cmd_normals(const cli_command *cmd, int argc, char **argv) {
  bsurf_normal_options no = bsurf_normal_options_default();
  const char *fit = "pca", *center = "centroid", *output = NULL, *select_k = NULL,
             *select_degree = NULL;
  const char *curve = NULL, *truth_path = NULL, *sigma_nu_s = "auto", *orient = "none";
  const char *select_rule = "test-error";
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
       "test-error (Eq. 5.10) or mse (estimated variance + bias^2 of the PCA normal)", 1, 0},
      {0, "noise-k", ARG_INT, &ksel.noise_k, "K",
       "with --select-rule mse: neighbourhood of the noise estimate and of the bias pooling", 12,
       65535},
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
  static const char *const fits[] = {"pca", "poly"}, *const centers[] = {"centroid", "point"};
  static const char *const orients[] = {"none", "mst"};
  int f = cli_choice(fit, fits, 2), pc = cli_choice(center, centers, 2),
      om = cli_choice(orient, orients, 2);
  if (f < 0) return cli_usage_error(cmd, "--fit must be pca or poly, not '%s'", fit);
  if (pc < 0)
    return cli_usage_error(cmd, "--pca-center must be centroid or point, not '%s'", center);
  if (om < 0) return cli_usage_error(cmd, "--orient must be none or mst, not '%s'", orient);
  no.fit = (bsurf_normal_fit)f;
  no.pca_center = (bsurf_pca_center)pc;
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
  static const char *const rules[] = {"test-error", "mse"};
  int sr = cli_choice(select_rule, rules, 2);
  if (sr < 0)
    return cli_usage_error(cmd, "--select-rule must be test-error or mse, not '%s'", select_rule);
  ksel.rule = (bsurf_kselect_rule)sr;
  if (ksel.rule == BSURF_KSELECT_MSE) {
    if (!select_k) return cli_usage_error(cmd, "--select-rule mse needs --select-k");
    if (no.fit != BSURF_NORMAL_PCA || select_degree)
      return cli_usage_error(
          cmd,
          "--select-rule mse chooses K for PCA normals: not with --fit poly or --select-degree");
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
  int kmax = k_ref > no.k ? k_ref : no.k;
  if (ksel.rule == BSURF_KSELECT_MSE && ksel.noise_k > kmax) kmax = ksel.noise_k;
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

  normals_job job;
  memset(&job, 0, sizeof job);
  job.no = no;
  job.test_error = test_error;
  job.selecting = selecting;
  job.select_k = select_k != NULL;
  job.select_degree = select_degree != NULL;
  job.k_ref = k_ref;
  memcpy(job.ks, ks, sizeof ks);
  memcpy(job.ds, ds, sizeof ds);
  job.nk = nk;
  job.nd = nd;
  job.ksel = ksel;
  job.ksel.ks = job.ks;
  job.ksel.nk = nk;
  job.ksel.threads = no.threads;
  job.quiet = quiet;
  size_t plan = 0, tiles = 0;
  rc = cli_tiles_plan(cmd, pos[0], output, ascii, tile_points, memory_limit, kmax, 4, &plan);
  if (rc) return rc;
  /* smoothing passes reach beyond the K-neighbourhood; orientation is
   * global (normal_err's reference normals: a first tiled stage) */
  if (plan && curve)
    return cli_error(
        "%s: --curve keeps every candidate's values of every point: not available in tiled runs",
        pos[0]);
  if (plan && job.ksel.rule == BSURF_KSELECT_MSE)
    return cli_error("%s: --select-rule mse grows its noise fits beyond the K_max-neighbourhood: "
                     "not available in tiled runs",
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
  bsurf_neighbors nb;
  memset(&nb, 0, sizeof nb);
  normals_bufs b;
  memset(&b, 0, sizeof b);
  FILE *cf = NULL;
  char curve_tmp[4200] = "";
  bsurf_normal_report total;
  memset(&total, 0, sizeof total);
  const char *names[4];
  bsurf_type types[4];
  int nf = normals_field_names(&job, names, types);
  double means[4], h = 0;
  size_t n = 0;
  rc = 1;
  if (plan) {
    double sums[NORMALS_SUMS] = {0};
    /* with normal_err, two stages: the reference normals of every point,
     * then the tiles with those of their halos */
    bsurf_tile_values refs = {-1, 0, 0};
    if (test_error) {
      bsurf_tile_ops ops1 = {.tile_points = plan,
                             .k = k_ref,
                             .threads = no.threads,
                             .user = &job,
                             .run = normals_ref_run,
                             .nvalues = 3,
                             .values_out = &refs};
      bsurf_tile_report tr1;
      tr1.sums = NULL;
      if (cli_tiles_run(pos[0], output, &ops1, &tr1, quiet)) goto done;
    }
    bsurf_tile_ops ops = {.tile_points = plan,
                          .k = kmax,
                          .threads = no.threads,
                          .user = &job,
                          .prepare = normals_prepare,
                          .run = normals_run,
                          .nsums = NORMALS_SUMS,
                          .values_in = test_error ? &refs : NULL};
    bsurf_tile_report tr;
    tr.sums = sums;
    int trc = cli_tiles_run(pos[0], output, &ops, &tr, quiet);
    bsurf_tile_values_close(&refs);
    plan = ops.tile_points;
    tiles = tr.tiles;
    if (trc) goto done;
    n = tr.points;
    h = tr.h;
    total.replicates_total = (size_t)sums[0];
    total.replicates_skipped = (size_t)sums[1];
    total.degree_reduced = (size_t)sums[2];
    total.degenerate = (size_t)sums[3];
    for (int t = 0; t < nf; t++)
      means[t] = sums[4 + t] / (double)n;
    goto summary;
  }
  if (cli_read_cloud(pos[0], &c)) goto done;
  if (truth_path) {
    if (cli_read_cloud(truth_path, &truth)) goto done;
    if (truth.point_count != c.point_count || !truth.normals) {
      cli_error("%s: the truth needs normals and the same %zu points as %s", truth_path,
                c.point_count, pos[0]);
      goto done;
    }
  }
  if (cli_build_neighbors(pos[0], &c, kmax, no.threads, quiet, &nb)) goto done;
  cli_progress prog;
  bsurf_status st;
  n = c.point_count;
  if (normals_bufs_alloc(&b, &job, n)) goto done;
  if (curve) {
    snprintf(curve_tmp, sizeof curve_tmp, "%s.tmp", curve);
    cf = fopen(curve_tmp, "w");
    if (!cf) {
      cli_error("%s: cannot write", curve_tmp);
      goto done;
    }
    fprintf(cf, "k,degree,mean_normal_err,mean_normal_var%s\n",
            truth_path ? ",mean_angle_err" : "");
  }
  st = normals_compute(&job, c.xyz, &nb, NULL, NULL, &b, &total, cf, truth_path ? &truth : NULL,
                       &prog);
  if (st != BSURF_OK) {
    cli_error("%s: %s", pos[0], cli_interrupted() ? "interrupted" : bsurf_strerror(st));
    goto done;
  }
  h = nb.h;
  if (iterations > 0) {
    /* auto: the threshold of the top 15% of normal_var (Table 5.2's split) */
    if (isnan(sigma_nu) &&
        (no.bootstrap < 2 ||
         bsurf_quantile_split(b.var, n, 0.85, NULL, &sigma_nu, NULL, NULL) != BSURF_OK))
      sigma_nu = INFINITY;
    if (!(sigma_nu > 0)) sigma_nu = INFINITY; /* all variances 0: nothing to weigh */
    st = bsurf_smooth_normals(c.xyz, &nb, no.k, b.normals, no.bootstrap >= 2 ? b.var : NULL,
                              iterations, alpha, sigma_d > 0 ? sigma_d : h, sigma_nu, no.threads);
    if (st != BSURF_OK) {
      cli_error("smoothing: %s", bsurf_strerror(st));
      goto done;
    }
  }
  if (om == 1 && (st = bsurf_orient_normals(c.xyz, &nb, no.k, b.normals)) != BSURF_OK) {
    cli_error("orientation: %s", bsurf_strerror(st));
    goto done;
  }
  /* outputs: normals replaced, confidence and error fields added */
  if (normals_store(&job, &c, &b) != BSURF_OK) {
    cli_error("out of memory");
    goto done;
  }
  if (cli_write_cloud(output, &c, ascii)) goto done;
  for (int t = 0; t < nf; t++)
    means[t] = cli_field_mean(bsurf_cloud_field(&c, names[t]), n);
  if (cf) {
    int bad = fclose(cf) != 0;
    cf = NULL;
    if (bad || rename(curve_tmp, curve) != 0) {
      cli_error("%s: cannot write", curve);
      goto done;
    }
    curve_tmp[0] = 0;
  }
summary:;
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
    if (select_k) json_str(&j, "select_rule", select_rule);
    if (ksel.rule == BSURF_KSELECT_MSE) json_int(&j, "noise_k", ksel.noise_k);
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
    if (plan) {
      json_int(&j, "tile_points", (long long)plan);
      json_int(&j, "tiles", (long long)tiles);
      json_int(&j, "ranks", cli_mpi_ranks());
    }
    json_means(&j, names, means, nf, h);
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    printf("normals: %zu points, h = %.6g, K = %d, %s%s, B = %d, %.2f s\n", n, h, no.k, fit,
           no.fit == BSURF_NORMAL_POLY ? " (poly)" : "", no.bootstrap, secs);
    print_means(stdout, names, means, nf, h);
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
  normals_bufs_free(&b);
  return rc;
}
