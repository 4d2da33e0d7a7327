/* Bootstrap test-error estimation of local polynomial fits (thesis chapter 4,
 * Algorithm 1; localisation of 3.3).
 *
 * For every point d_i with neighbourhood P_i (K points, d_i first):
 *   1. PCA frame of P_i and local coordinates (x_j, y_j) (3.3, Eqs. 3.4-3.5);
 *   2. the degree-M least-squares fit f on P_i: err_train (Eq. 4.6) and the
 *      no-information rate gamma (Eq. 4.10);
 *   3. B bootstrap samples S_b (4.1.1), drawn from the stream keyed by
 *      (seed, i, b), a fit f*b on each, and its predictions on all of P_i;
 *   4. the estimators err_boot, err_loo, err_loo_center, .632, .632+ (Eqs.
 *      4.3-4.5, 4.7-4.9, 4.11), in src/bootstrap/estimators.c.
 * A replicate whose fit is rank-deficient is skipped and counted. If the fit
 * to the whole neighbourhood is rank-deficient at degree M (degenerate
 * neighbourhood: collinear or repeated points) the highest lower degree that
 * is full rank is used for that point, down to a constant, and the point is
 * counted in degree_reduced, so no output is ever NaN.
 *
 * The normal equations of every fit are sums of per-neighbour products that
 * are computed once per point (src/local/poly.c); those of all B replicates
 * are one B x K by K x (p + m) matrix product, then an LDL^T solve each. Points are
 * independent, so the loop is parallel; results do not depend on threads. */
#include "algo/algo.h"
#include "common/common.h"
#include "search/search.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

bsurf_error_options bsurf_error_options_default(void) {
  bsurf_error_options o = {.k = 50,
                           .degree = 3,
                           .bootstrap = 50,
                           .seed = 1,
                           .gamma = BSURF_GAMMA_FIT,
                           .pca_center = BSURF_PCA_CENTROID};
  return o;
}

void bsurf_error_scratch_free(bsurf_error_scratch *s) {
  bsurf_localfit_free(&s->lf);
  bsurf_blocks_free(&s->mem);
  memset(s, 0, sizeof *s);
}

bsurf_status bsurf_error_scratch_alloc(bsurf_error_scratch *s, int k, int B, int degree) {
  memset(s, 0, sizeof *s);
  bsurf_status st = bsurf_localfit_alloc(&s->lf, k, degree);
  if (st != BSURF_OK) return st;
  size_t nb = B > 0 ? (size_t)B : 1;
  /* B replicates and the full fit, padded to whole groups of four */
  size_t nr = (size_t)bsurf_boot_rows(B);
  bsurf_blocks *m = &s->mem;
  s->pred_full = bsurf_blocks_array(m, (size_t)k, sizeof(double));
  s->pred_boot = bsurf_blocks_array(m, nb * k, sizeof(double));
  s->counts = bsurf_blocks_array(m, nb * k, sizeof(uint16_t));
  s->missing = bsurf_blocks_array(m, nb * k, sizeof(double));
  s->draws = bsurf_blocks_array(m, nb * k, sizeof(uint16_t));
  s->rows = bsurf_blocks_aligned(m, nr * BSURF_NCOLS_MAX, sizeof(double));
  s->coefs = bsurf_blocks_aligned(m, nb * BSURF_TERMS_MAX, sizeof(double));
  s->valid = bsurf_blocks_array(m, nb, 1);
  s->est_scratch = bsurf_blocks_array(m, 6 * (size_t)k + 1, sizeof(double));
  st = bsurf_blocks_status(m);
  if (st != BSURF_OK) bsurf_error_scratch_free(s);
  return st;
}

static void put(double *field, size_t i, double v) {
  if (field) field[i] = v;
}

void bsurf_error_point(const double *xyz, const uint32_t *idx, const double *test_xyz,
                       const bsurf_error_options *o, size_t i, bsurf_error_scratch *s,
                       bsurf_error_fields *out, bsurf_error_fit *fit) {
  const int k = o->k, B = o->bootstrap;
  bsurf_frame frame;
  bsurf_local_frame(xyz, idx, k, o->pca_center, &frame);
  bsurf_localfit *lf = &s->lf;
  bsurf_localfit_setup(lf, xyz, idx, k, &frame, o->degree);

  /* The normal equations of the B resamples (4.1.1) and of the fit to the
   * whole neighbourhood (row B, every weight 1): sums of the per-neighbour
   * terms picked by each replicate's draws; then one small solve each. */
  /* fewer distinct points than terms: singular */
  bsurf_boot_draw_rows(o->seed, o->point_index ? o->point_index[i] : i, B, k,
                       bsurf_poly_terms(o->degree), s->counts, s->draws, s->valid);
  bsurf_localfit_normal_eq_draws(lf, B, s->draws, s->rows);

  double coef[BSURF_TERMS_MAX], row[BSURF_NCOLS_MAX];
  bsurf_lanes_row(lf->ncols, s->rows, B, row);
  int degree = o->degree;
  while (degree > 0 && bsurf_localfit_solve_row(lf, degree, row, coef) != 0)
    degree--;
  if (degree == 0) bsurf_localfit_solve_row(lf, 0, row, coef); /* constant: never singular */
  if (degree != o->degree) s->reduced++;
  bsurf_localfit_predict(lf, degree, 1, coef, NULL, s->pred_full);

  const int m = bsurf_poly_terms(degree);
  if (degree != o->degree) /* a lower degree needs fewer distinct points */
    for (int b = 0; b < B; b++)
      s->valid[b] = bsurf_boot_distinct(k, &s->counts[(size_t)b * k]) >= m;
  bsurf_localfit_solve_lanes(lf, degree, B, s->rows, s->valid, s->coefs);
  for (int b = 0; b < B; b++)
    s->skipped += !s->valid[b];

  bsurf_boot_result r;
  if (o->gamma == BSURF_GAMMA_FIT) {
    /* the estimators need only per-point sums of the replicates' residuals
     * (Eqs. 4.3, 4.4): summed as the predictions are made, never stored */
    double *sums = s->est_scratch + 3 * (size_t)k + 1;
    double *boot_j = sums, *loo_sum = sums + k, *loo_cnt = sums + 2 * (size_t)k;
    bsurf_localfit_residual_sums(lf, degree, B, s->coefs, s->valid, s->counts, boot_j, loo_sum,
                                 loo_cnt);
    int nvalid = 0;
    for (int b = 0; b < B; b++)
      nvalid += s->valid[b];
    bsurf_boot_estimate_sums(k, nvalid, lf->z, s->pred_full, boot_j, loo_sum, loo_cnt, 0, 0,
                             o->gamma, s->est_scratch, &r);
  } else {
    /* mean or max of Eq. 4.10 over the replicates: every prediction, and
     * the rows of points left out (b in C_j) as an array */
    for (size_t t = 0; t < (size_t)B * k; t++)
      s->missing[t] = s->counts[t] == 0;
    bsurf_localfit_predict(lf, degree, B, s->coefs, s->valid, s->pred_boot);
    bsurf_boot_estimate(k, B, lf->z, s->pred_full, s->pred_boot, s->missing, s->valid, o->gamma,
                        s->est_scratch, &r);
  }
  if (r.center_unestimated) s->center_unestimated++;
  put(out->err_train, i, r.err_train);
  put(out->err_boot, i, r.err_boot);
  put(out->err_loo, i, r.err_loo);
  put(out->err_loo_center, i, r.err_loo_center);
  put(out->err_632, i, r.err_632);
  put(out->err_632plus, i, r.err_632plus);
  put(out->gamma, i, r.gamma);
  put(out->overfit_rate, i, r.overfit_rate);

  if (fit) {
    fit->frame = frame;
    fit->inv_scale = 1.0 / lf->scale;
    fit->degree = degree;
    const int mfull = bsurf_poly_terms(o->degree);
    for (int a = 0; a < mfull; a++)
      fit->coef[a] = a < m ? coef[a] : 0.0;
    /* Eq. 6.1: the mean of the valid replicates' predictions at the centre
     * (each as bsurf_localfit_predict makes it: terms in order from 0) */
    double sum = 0;
    int used = 0;
    for (int b = 0; b < B; b++)
      if (s->valid[b]) {
        double pc = 0;
        for (int a = 0; a < m; a++)
          pc += s->coefs[(size_t)b * m + a] * lf->phit[(size_t)a * lf->kp];
        sum += pc;
        used++;
      }
    fit->boot_center = used ? sum / used : s->pred_full[0];
    fit->r = r;
  }

  if (test_xyz && (out->err_test || out->err_test_center)) {
    /* The true test error of this fit: the same surface points with
     * independent noise, localised in the same frame (validation only). */
    double sum = 0, center = 0;
    for (int j = 0; j < k; j++) {
      double q[3];
      bsurf_frame_to_local(&frame, &test_xyz[3 * (size_t)idx[j]], q);
      double e = fabs(bsurf_localfit_eval(lf, degree, coef, q[0], q[1]) - q[2]);
      sum += e;
      if (j == 0) center = e;
    }
    put(out->err_test, i, sum / k);
    put(out->err_test_center, i, center);
  }
}

bsurf_status bsurf_error_check(const bsurf_error_options *o, const bsurf_neighbors *nb) {
  BSURF_REQUIRE_IN("error options", o, "no options given");
  BSURF_REQUIRE_IN("error options", nb && nb->idx, "nb is %s: build it with bsurf_neighbors_build",
                   nb ? "empty" : "NULL");
  BSURF_REQUIRE_IN("error options", o->degree >= 1 && o->degree <= BSURF_DEGREE_MAX,
                   "degree = %d: must be in [1, %d]", o->degree, BSURF_DEGREE_MAX);
  BSURF_REQUIRE_IN("error options", o->bootstrap >= 0 && o->bootstrap <= 100000,
                   "bootstrap (B) = %d: must be in [0, 100000]", o->bootstrap);
  BSURF_REQUIRE_IN("error options", o->k >= 2 && o->k <= 65535, "k = %d: must be in [2, 65535]",
                   o->k);
  BSURF_REQUIRE_IN("error options", o->k <= nb->k,
                   "k = %d exceeds the neighbourhoods' nb->k = %d: must be in [2, %d]", o->k, nb->k,
                   nb->k);
  if ((size_t)o->k > nb->point_count)
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS, "k = %d exceeds the %zu points", o->k,
                             nb->point_count);
  if (o->k < bsurf_poly_terms(o->degree))
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS,
                             "k = %d is too small for degree %d: a fit needs %d points", o->k,
                             o->degree, bsurf_poly_terms(o->degree));
  BSURF_REQUIRE_IN("error options", (unsigned)o->gamma <= BSURF_GAMMA_MAX,
                   "gamma = %d: must be BSURF_GAMMA_FIT, _MEAN or _MAX", (int)o->gamma);
  BSURF_REQUIRE_IN("error options", (unsigned)o->pca_center <= BSURF_PCA_POINT,
                   "pca_center = %d: must be BSURF_PCA_CENTROID or BSURF_PCA_POINT",
                   (int)o->pca_center);
  return BSURF_OK;
}

typedef struct error_ctx {
  const double *xyz;
  const bsurf_neighbors *nb;
  const double *test_xyz;
  const bsurf_error_options *o;
  bsurf_error_fields *out;
  bsurf_error_report *report;
} error_ctx;

static void error_point_task(void *vctx, void *scratch, size_t i) {
  error_ctx *c = vctx;
  bsurf_error_point(c->xyz, &c->nb->idx[i * (size_t)c->nb->k], c->test_xyz, c->o, i, scratch,
                    c->out, NULL);
}

static bsurf_status error_scratch_alloc(void *scratch, const void *opts) {
  const bsurf_error_options *o = opts;
  return bsurf_error_scratch_alloc(scratch, o->k, o->bootstrap, o->degree);
}

static void error_scratch_free(void *scratch) {
  bsurf_error_scratch_free(scratch);
}

static void error_tally(void *vctx, const void *scratch) {
  const error_ctx *c = vctx;
  const bsurf_error_scratch *s = scratch;
  if (!c->report) return;
  c->report->replicates_skipped += s->skipped;
  c->report->degree_reduced += s->reduced;
  c->report->center_unestimated += s->center_unestimated;
}

bsurf_status bsurf_estimate_error(const double *xyz, const bsurf_neighbors *nb,
                                  const double *test_xyz, const bsurf_error_options *opts,
                                  bsurf_error_fields *out, bsurf_error_report *report) {
  bsurf_error_options o = opts ? *opts : bsurf_error_options_default();
  if (report) memset(report, 0, sizeof *report);
  BSURF_REQUIRE(xyz, "xyz is NULL");
  BSURF_REQUIRE(out, "out is NULL (give a bsurf_error_fields, its unwanted outputs NULL)");
  bsurf_status st = bsurf_error_check(&o, nb);
  if (st != BSURF_OK) return st;

  static const bsurf_point_loop loop = {sizeof(bsurf_error_scratch), error_scratch_alloc,
                                        error_scratch_free, error_point_task, error_tally};
  error_ctx ctx = {xyz, nb, test_xyz, &o, out, report};
  const double work = (double)o.k * (o.bootstrap + 1) * bsurf_poly_terms(o.degree);
  st = bsurf_point_loop_run(&loop, &o, &ctx, nb, xyz, work, o.threads, o.progress, o.progress_user);
  if (report && st == BSURF_OK) report->replicates_total = nb->point_count * (size_t)o.bootstrap;
  return st;
}
