/* Smoothing driven by the bootstrap test error (thesis chapter 6).
 *
 * Every method starts with the bootstrap pass of chapter 4 (Algorithm 1,
 * the same per-point fits as bsurf_estimate_error, algo/algo.h), which gives
 * each point i its error W_i and its fits. Then:
 *
 * naive (6.2, Eq. 6.1): (x_i, y_i) -> (x_i, (1/B) sum_b f*b(x_i)) in point
 *   i's local frame, i.e. the point moves along the frame normal to the mean
 *   of the replicates' predictions at it, only where W_i (.632+ by default)
 *   is below the threshold.
 *
 * bilateral (6.3, Algorithm 4, Eq. 6.2): the fit f_i of neighbourhood i moves
 *   every neighbour z_ij towards its projection z*_ij onto the fitted surface
 *   (along the frame normal: z*_ij = z_ij + (f_i(x_j, y_j) - y_j) n_i):
 *       z_ij -> (1 - w_ij) z_ij + w_ij z*_ij,
 *       w_ij = theta_1(|z_ij - z_i0|) theta_2(W_i),  theta_k(x) = G(x, h_k),
 *   with G(a, b) = exp(-a^2/b^2) (Eq. 5.7).
 *   order sequential: the thesis's sweep i = 1..N in place; each fit (frame
 *     and polynomial) is made from the current positions, so earlier moves
 *     feed later fits (6.4's remark on Algorithm 4). One thread.
 *   order parallel: every fit from the input positions; a point p that lies
 *     in the neighbourhoods i_1 < i_2 < ... receives the moves of all of them
 *     at once as
 *         p' = P p + (1 - P) sum_i w_i z*_i / sum_i w_i,  P = prod_i (1 - w_i),
 *     which is what the sequential composition gives when the targets agree,
 *     and does not depend on the order (sums run in increasing i).
 *
 * multipass (6.4, Algorithm 5, Eqs. 6.3-6.5): per point, K_i = max{k_min, y}
 *   with y = (k_min - K) / k_error * W_i + K (Eq. 6.4, k_error = 3 mean W by
 *   default (the thesis: mean W), or a multiple of it, y rounded to the nearest integer); d_L, the
 * local average distance between points, taken as the mean distance from the point to the other K_i
 * - 1 (for a uniformly sampled disc the mean over all pairs is about 1.36 times this; it would cost
 * K_i^2 instead of K_i); the frame and polynomial of the K_i neighbourhood, computed once
 * (Algorithm 5's second loop), of the asked degree or lower so that there are at least two points
 *   per coefficient (K_i = 10 would otherwise make a cubic interpolate).
 *   A fit moves only points inside the disc its neighbourhood spans. Then `iterations` passes of
 * Eq. 6.2 with h1 = a d_L (Eq. 6.5): each pass projects the current positions onto the fixed fitted
 * surfaces, with weights from the current distances. The passes combine as the bilateral orders
 * above.
 *
 * Every method's fits pass the guard (guard_fit below, docs/smoothing.md "The
 * guard"): a fit of the centre's own sheet, moving only that sheet's points.
 *
 * Gaussian weights below 2^-54 are taken as 0: 1 - w rounds to 1 there, so
 * such a weight cannot move a point by itself; this cut (a^2/b^2 > 54 ln 2)
 * lets the passes skip far neighbours after one distance test.
 *
 * All of it is deterministic for a given seed, whatever the thread count:
 * every point is updated by gathering its contributions in a fixed order.
 * The multipass's parallel passes run over the points in Morton order (cache
 * locality; the order of a point's sums follows it), several passes at a
 * time per region of points (time blocks, mp_tblock_task: the same bits). */
#include "algo/smooth_ctx.h"
#include "search/search.h"
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

bsurf_smooth_options bsurf_smooth_options_default(void) {
  /* every member not named is zero */
  bsurf_smooth_options o = {
      .method = BSURF_SMOOTH_AUTO,
      .error = bsurf_error_options_default(),
      .estimator = BSURF_SMOOTH_EST_DEFAULT,
      .threshold = NAN,
      .order = BSURF_ORDER_PARALLEL,
      .a = -1,          /* multipass: h1 = the local spacing (smooth_multipass.c) */
      .iterations = -1, /* multipass: until the stop rule */
      .k_min = 10,
      .guard = 1,
      .degree_test = -1,
  };
  return o;
}

/* Full-rank fit of the highest degree <= `degree` (down to a constant), as
 * the error pass does for degenerate neighbourhoods; coef zero-padded to m. */
int solve_with_fallback(const bsurf_localfit *lf, int degree, int m, double *coef) {
  int d = degree;
  while (d > 0 && bsurf_localfit_solve(lf, d, NULL, coef) != 0)
    d--;
  if (d == 0) bsurf_localfit_solve(lf, 0, NULL, coef);
  for (int a = bsurf_poly_terms(d); a < m; a++)
    coef[a] = 0.0;
  return d;
}

enum { STAGE_PER = 1000 }; /* a stage's share of the caller's progress */

int staged_cb(void *u, size_t done, size_t total) {
  staged_progress *s = u;
  if (!s->fn) return 0;
  size_t d = total ? (size_t)((double)done / (double)total * STAGE_PER) : STAGE_PER;
  return s->fn(s->user, (size_t)s->stage * STAGE_PER + d, (size_t)s->stages * STAGE_PER);
}

/* Stage 1: Algorithm 1 at every point (and the naive projection). */
void boot_task(void *vc, int thread, size_t i) {
  smooth_ctx *c = vc;
  bsurf_error_fields ef;
  memset(&ef, 0, sizeof ef);
  ef.err_632 = c->err_632;
  ef.err_632plus = c->err_632plus;
  bsurf_error_fit fit;
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  bsurf_error_point(c->xyz, idx, NULL, &c->o.error, i, &c->scr[thread], &ef, &fit);
  const double *p = &c->xyz[3 * (size_t)idx[0]]; /* row i's point (i itself in a whole cloud) */
  if (c->o.method == BSURF_SMOOTH_NAIVE) {
    /* Eq. 6.1: the centre has local coordinates (0, 0, 0) (the frame's
     * origin is the point), so it moves by boot_center along n. */
    double height = fit.boot_center, *n = fit.frame.rot[2];
    double F[FIT_HEAD + BSURF_TERMS_MAX]; /* n may point into it below */
    if (c->o.guard) {
      /* a biased fit: the height of the guard's smaller fit at the point
       * (no bootstrap mean there), or no move */
      int deg = fit.degree;
      fit_store(F, &fit.frame, fit.inv_scale, fit.coef, c->m);
      int kg = guard_fit(c, &c->scr[thread], GCOUNT(c, thread), c->xyz, idx, c->k, F, &deg,
                         c->svar ? &c->svar[BSURF_SMOOTH_SV * i] : NULL);
      if (kg == 0)
        height = 0;
      else if (kg != c->k) {
        height = fit_delta(F, deg, c->m, p);
        if (isnan(height)) height = 0;
        n = &F[9];
      }
    }
    for (int t = 0; t < 3; t++)
      c->out[3 * i + t] = p[t] + height * n[t];
  } else if (c->fits) {
    double *F = &c->fits[i * (size_t)c->stride];
    fit_store(F, &fit.frame, fit.inv_scale, fit.coef, c->m);
    int deg = c->degree;
    if (c->o.guard) {
      deg = fit.degree;
      guard_fit(c, &c->scr[thread], GCOUNT(c, thread), c->xyz, idx, c->k, F, &deg,
                c->svar ? &c->svar[BSURF_SMOOTH_SV * i] : NULL);
    }
    if (c->fit_degree) c->fit_degree[i] = deg;
  } else if (c->svar) {
    /* the sequential sweep makes its fits as it goes: the guard's fit of the
     * input positions here only gives the noise estimate (guard_noise) */
    double F[FIT_HEAD + BSURF_TERMS_MAX];
    fit_store(F, &fit.frame, fit.inv_scale, fit.coef, c->m);
    int deg = fit.degree;
    guard_fit(c, &c->scr[thread], GCOUNT(c, thread), c->xyz, idx, c->k, F, &deg,
              &c->svar[BSURF_SMOOTH_SV * i]);
  }
}

/* theta_2(W_i) = G(W_i, h2) of Eq. 6.2: its exponent and its value. sv
 * (NULL: no test): the fit's (s^2, nu) for the guard's misfit test against
 * c->noise; a fit with more misfit than noise gets theta_2 = 0 (moves
 * nothing). */
void set_theta2(smooth_ctx *c, size_t i, double W, const double *sv) {
  if (sv && guard_misfit(sv, c->noise)) {
    c->e2[i] = INFINITY, c->w2[i] = 0;
    return;
  }
  c->e2[i] = gauss_exponent(W, c->h2);
  c->w2[i] = c->e2[i] == 0 ? 1.0 : exp(-c->e2[i]);
}

/* Naive (6.2): Eq. 6.1's projection stands where W_i < threshold; elsewhere
 * the point stays at x. 1 when projected. */
int naive_select(double W, double threshold, const double *x, double *out) {
  if (W < threshold) return 1;
  for (int t = 0; t < 3; t++)
    out[t] = x[t];
  return 0;
}

double moved_of(const double *a, const double *b) {
  return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
              (a[2] - b[2]) * (a[2] - b[2]));
}

/* One point's gathered update (parallel order): the moves of every
 * neighbourhood i that contains p, from the positions `cur`. */
double gather_update(const smooth_ctx *c, size_t p, int multipass) {
  const double *x = &c->cur[3 * (c->self ? (size_t)c->self[p] : p)];
  double P = 1.0, S = 0.0, T[3] = {0, 0, 0};
  const uint32_t *list = multipass ? &c->act[c->rev_off[p]] : &c->rev[c->rev_off[p]];
  const size_t count = multipass ? c->act_n[p] : c->rev_off[p + 1] - c->rev_off[p];
  for (size_t e = 0; e < count; e++) {
    const uint32_t i = list[e];
    const double *ci = &c->cur[3 * (size_t)i];
    double d2 = (x[0] - ci[0]) * (x[0] - ci[0]) + (x[1] - ci[1]) * (x[1] - ci[1]) +
                (x[2] - ci[2]) * (x[2] - ci[2]);
    /* w = theta_1 theta_2 = exp(-(d^2/h1^2 + W_i^2/h2^2)) */
    double ex = c->e2[i], w;
    if (d2 > 0) {
      double inv = multipass ? c->inv_h1sq[i] : c->inv_h1sq_global;
      ex = inv > 0 ? ex + d2 * inv : INFINITY; /* h1 = 0: only the point itself */
      if (!(ex <= GAUSS_CUT)) continue;
      w = ex == 0 ? 1.0 : (multipass ? mp_exp1(-ex) : exp(-ex));
    } else { /* the point itself (or a duplicate): theta_1 = 1, precomputed */
      if (!(ex <= GAUSS_CUT)) continue;
      w = c->w2[i];
    }
    const double *F = &c->fits[(size_t)i * c->stride];
    double delta = fit_delta(F, c->fit_degree ? c->fit_degree[i] : c->degree, c->m, x);
    if (isnan(delta)) continue;
    P *= 1.0 - w;
    S += w;
    for (int t = 0; t < 3; t++)
      T[t] += w * (x[t] + delta * F[9 + t]);
  }
  return update_finish(x, P, S, T, &c->next[3 * p]);
}

void gather_bilateral_task(void *vc, int thread, size_t p) {
  (void)thread;
  gather_update(vc, p, 0);
}

/* The reverse lists: for every p, the i (ascending) whose first size(i)
 * neighbours contain p. size = NULL: all k. With a spatial order (perm[i'] =
 * i, rank[i] = i'), the lists are built in that order's indices: list rank[p]
 * holds the ranks of the neighbourhoods that contain p. */
bsurf_status build_reverse(smooth_ctx *c, const int *size, const uint32_t *perm,
                           const uint32_t *rank) {
  const size_t n = c->n;
  const int stride = c->nb->k;
  size_t *rev_off = bsurf_calloc_array(n + 1, sizeof(size_t));
  c->rev_off = rev_off;
  if (!rev_off) return BSURF_ERR_NOMEM;
  for (size_t r = 0; r < n; r++) {
    const size_t i = perm ? perm[r] : r;
    int kk = size ? size[i] : c->k;
    const uint32_t *idx = &c->nb->idx[i * (size_t)stride];
    for (int j = 0; j < kk; j++)
      rev_off[(rank ? rank[idx[j]] : idx[j]) + 1]++;
  }
  for (size_t p = 0; p < n; p++)
    rev_off[p + 1] += rev_off[p];
  uint32_t *rev = bsurf_alloc_array(rev_off[n] ? rev_off[n] : 1, sizeof(uint32_t));
  c->rev = rev;
  size_t *pos = bsurf_alloc_array(n ? n : 1, sizeof(size_t));
  if (!rev || !pos) {
    free(pos);
    return BSURF_ERR_NOMEM;
  }
  memcpy(pos, rev_off, n * sizeof(size_t));
  for (size_t r = 0; r < n; r++) {
    const size_t i = perm ? perm[r] : r;
    int kk = size ? size[i] : c->k;
    const uint32_t *idx = &c->nb->idx[i * (size_t)stride];
    for (int j = 0; j < kk; j++)
      rev[pos[rank ? rank[idx[j]] : idx[j]]++] = (uint32_t)r;
  }
  free(pos);
  return BSURF_OK;
}

/* ---- a spatially coherent order for the passes ------------------------ */
/* The passes read the positions of every point's neighbourhoods; in input
 * order (often random) each read is a cache miss, so they run in Morton
 * order (bsurf_spatial_order). */

/* a[r] = old a[perm[r]] for rows of `width` elements of `size` bytes */
bsurf_status permute_rows(void **array, size_t n, size_t row_bytes, const uint32_t *perm) {
  unsigned char *src = *array, *dst = bsurf_alloc_array(n ? n : 1, row_bytes);
  if (!dst) return BSURF_ERR_NOMEM;
  for (size_t r = 0; r < n; r++)
    memcpy(dst + r * row_bytes, src + (size_t)perm[r] * row_bytes, row_bytes);
  free(src);
  *array = dst;
  return BSURF_OK;
}

/* Algorithm 4 step 3 in the thesis's order: for i = 1..N, the frame and fit
 * of neighbourhood i from the current positions, then Eq. 6.2 in place. */
static void bilateral_sequential(smooth_ctx *c) {
  bsurf_localfit *lf = &c->scr[0].lf;
  double *pred = c->scr[0].pred_full;
  double *w = c->scr[0].est_scratch; /* >= k doubles */
  const int k = c->k;
  for (size_t i = 0; i < c->n; i++) {
    const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
    const double e2 = c->e2[i];
    if (!(e2 <= GAUSS_CUT)) continue;
    bsurf_frame fr;
    bsurf_local_frame(c->out, idx, k, c->o.error.pca_center, &fr);
    bsurf_localfit_setup(lf, c->out, idx, k, &fr, c->degree);
    double coef[BSURF_TERMS_MAX];
    int d = solve_with_fallback(lf, c->degree, c->m, coef);
    bsurf_localfit_predict(lf, d, 1, coef, NULL, pred);
    double F[FIT_HEAD + BSURF_TERMS_MAX];
    if (c->o.guard) {
      double sv[BSURF_SMOOTH_SV];
      fit_store(F, &fr, 1.0 / lf->scale, coef, c->m);
      guard_fit(c, &c->scr[0], GCOUNT(c, 0), c->out, idx, k, F, &d, sv);
      if (guard_misfit(sv, c->noise)) continue; /* moves nothing */
    }
    const double *z0 = &c->out[3 * (size_t)idx[0]];
    for (int j = 0; j < k; j++) {
      const double *z = &c->out[3 * (size_t)idx[j]];
      double dist = sqrt((z[0] - z0[0]) * (z[0] - z0[0]) + (z[1] - z0[1]) * (z[1] - z0[1]) +
                         (z[2] - z0[2]) * (z[2] - z0[2]));
      w[j] = weight_of(gauss_exponent(dist, c->h1) + e2);
    }
    for (int j = 0; j < k; j++) {
      if (w[j] < 0x1p-54) continue;
      double *z = &c->out[3 * (size_t)idx[j]];
      if (c->o.guard) { /* the guard's fit (or none: NAN) and its bound */
        double delta = fit_delta(F, d, c->m, z);
        if (isnan(delta)) continue;
        for (int t = 0; t < 3; t++)
          z[t] = (1.0 - w[j]) * z[t] + w[j] * (z[t] + delta * F[9 + t]);
        continue;
      }
      double delta = pred[j] - lf->z[j];
      for (int t = 0; t < 3; t++)
        z[t] = (1.0 - w[j]) * z[t] + w[j] * (z[t] + delta * fr.rot[2][t]);
    }
  }
}

void ctx_init(smooth_ctx *c, const double *xyz, const bsurf_neighbors *nb,
              const bsurf_smooth_options *o) {
  memset(c, 0, sizeof *c);
  c->xyz = xyz;
  c->nb = nb;
  c->n = nb ? nb->point_count : 0;
  c->k = o->error.k;
  c->degree = o->error.degree;
  c->m = bsurf_poly_terms(c->degree);
  c->stride = FIT_HEAD + c->m;
  c->tune = bsurf_smooth_tuning_defaults();
  c->noise = c->noise_fits = c->noise_select[0] = NAN;
  c->noise_select[1] = 0;
}

void ctx_free(smooth_ctx *c, int T) {
  if (c->scr)
    for (int t = 0; t < T; t++)
      bsurf_error_scratch_free(&c->scr[t]);
  free(c->scr);
  free(c->fits);
  free(c->fit_degree);
  free(c->khat);
  free(c->dl);
  free(c->e2);
  free(c->w2);
  free(c->inv_h1sq);
  free((void *)c->rev_off);
  free((void *)c->rev);
  free(c->act);
  free(c->act_n);
  free(c->reach2);
  free(c->tmax);
  free(c->mp_point);
  free(c->act_off);
  free(c->mp_val);
  for (size_t r = 0; c->reg && r < c->nreg; r++) {
    free(c->reg[r].row);
    free(c->reg[r].off);
    free(c->reg[r].ctr);
    free(c->reg[r].fit);
  }
  free(c->reg);
  free(c->lmap);
  free(c->tb_pos);
  free(c->tb_step);
  free(c->gcount);
  free(c->svar);
}

/* The scale rule's K for multipass (docs/smoothing.md, "The
 * neighbourhood's scale"): t0 = R / sigma, R the median radius of the
 * K-balls, sigma the guard's noise estimate; p the coefficients of the
 * asked degree; at most k_max (0: 8 K), 65535 and the points. */
static bsurf_status scale_k(const smooth_ctx *c, const bsurf_smooth_options *o, int *K) {
  double R = 0;
  bsurf_status st = bsurf_ball_radius(c->xyz, c->nb, c->k, &R);
  if (st != BSURF_OK) return st;
  long cap = o->k_max > 0 ? o->k_max : 8L * c->k;
  if (cap > 65535) cap = 65535;
  if ((size_t)cap > c->n) cap = (long)c->n;
  *K = bsurf_scale_k(R / sqrt(c->noise_fits), c->k, c->m, (int)cap, NULL);
  return BSURF_OK;
}

/* The selection's reading of the cloud's noise variance (docs/smoothing.md,
 * "The noise estimate", *Two readings*): the level `normals --select-k
 * 10:80:5` reads with its defaults (kselect_noise.c: a local quadric's
 * residual variance at a scale chosen per point, its misfit extrapolated
 * away, pooled over the 80 nearest and the cloud; where the neighbourhoods
 * are cross-sections, Taubin's conic within their plane), on the cloud's
 * 80-neighbourhoods: level[0], and level[1] the share of the points whose
 * neighbourhoods it found section-sampled. NAN, 0 where the cloud has no
 * more than 80 points; NAN and an upper bound of the share, at most
 * BSURF_SMOOTH_SECTION_SHARE, where the section test alone shows the rule
 * needs no level (bsurf_ksel_section_bound: about a tenth of the passes'
 * cost). */
/* A progress callback for the steps between stage 1 and the next (the
 * tables they build, the selection's passes): it reports stage 1's end
 * after every chunk, so that Ctrl-C (Python's KeyboardInterrupt through the
 * callback) stops them too; h filled, NULL where the caller gave none. */
static bsurf_progress_fn stage_end_hold(staged_progress *sp, bsurf_progress_hold *h) {
  *h = (bsurf_progress_hold){staged_cb, sp, 1, 1, 0};
  return sp->fn ? bsurf_progress_hold_cb : NULL;
}

static bsurf_status select_noise(const double *xyz, size_t n, int T, staged_progress *sp,
                                 double level[2]) {
  level[0] = NAN, level[1] = 0;
  if (n <= BSURF_SMOOTH_SELECT_K) return BSURF_OK;
  bsurf_progress_hold hold;
  bsurf_kselect_options ko;
  bsurf_smooth_select_options(T, &ko);
  ko.progress = stage_end_hold(sp, &hold);
  ko.progress_user = &hold;
  bsurf_neighbors nb;
  bsurf_status st =
      bsurf_neighbors_build(&nb, xyz, n, BSURF_SMOOTH_SELECT_K, T, ko.progress, ko.progress_user);
  if (st != BSURF_OK) return st;
  /* first the section test alone: where even its superset of the
   * section-sampled points is at most the rule's share, the rule keeps the
   * fits' reading whatever the selection's, which is then not read (NAN;
   * level[1] the bound) */
  size_t ns = 0;
  st = bsurf_ksel_section_bound(xyz, &nb, &ko, &ns);
  level[1] = (double)ns / (double)n;
  if (st == BSURF_OK && level[1] > BSURF_SMOOTH_SECTION_SHARE) {
    st = bsurf_ksel_cloud_noise(xyz, &nb, &ko, &level[0], &ns);
    level[1] = (double)ns / (double)n;
  }
  bsurf_neighbors_free(&nb);
  return st;
}

/* bsurf_smooth_tuned, with the selection's noise reading given (sel_given:
 * the scale rule's second run on wider neighbourhoods reads the same cloud)
 * or NULL (read here) */
static bsurf_status smooth_run(const double *xyz, const bsurf_neighbors *nb,
                               const bsurf_smooth_options *opts, const bsurf_smooth_tuning *tune,
                               const double *sel_given, double *out_xyz,
                               bsurf_smooth_fields *fields, bsurf_smooth_report *report);

/* (its messages name bsurf_smooth, the public function) */
bsurf_status bsurf_smooth_tuned(const double *xyz, const bsurf_neighbors *nb,
                                const bsurf_smooth_options *opts, const bsurf_smooth_tuning *tune,
                                double *out_xyz, bsurf_smooth_fields *fields,
                                bsurf_smooth_report *report) {
  return smooth_run(xyz, nb, opts, tune, NULL, out_xyz, fields, report);
}

static bsurf_status smooth_run(const double *xyz, const bsurf_neighbors *nb,
                               const bsurf_smooth_options *opts, const bsurf_smooth_tuning *tune,
                               const double *sel_given, double *out_xyz,
                               bsurf_smooth_fields *fields, bsurf_smooth_report *report) {
  bsurf_smooth_options o = opts ? *opts : bsurf_smooth_options_default();
  if (o.method == BSURF_SMOOTH_AUTO) o.method = BSURF_SMOOTH_MULTIPASS; /* in memory */
  if (report) memset(report, 0, sizeof *report);
  BSURF_REQUIRE_IN("bsurf_smooth", xyz, "xyz is NULL");
  BSURF_REQUIRE_IN("bsurf_smooth", out_xyz, "out_xyz is NULL");
  BSURF_REQUIRE_IN("bsurf_smooth", out_xyz != xyz,
                   "out_xyz is xyz: the output may not alias the input");
  bsurf_status st = bsurf_error_check(&o.error, nb);
  if (st != BSURF_OK) return st;
  BSURF_REQUIRE_IN(
      "bsurf_smooth", o.method >= BSURF_SMOOTH_NAIVE && o.method <= BSURF_SMOOTH_MULTIPASS,
      "method = %d: must be BSURF_SMOOTH_NAIVE, _BILATERAL or _MULTIPASS", (int)o.method);
  BSURF_REQUIRE_IN("bsurf_smooth",
                   o.order == BSURF_ORDER_PARALLEL || o.order == BSURF_ORDER_SEQUENTIAL,
                   "order = %d: must be BSURF_ORDER_PARALLEL or _SEQUENTIAL", (int)o.order);
  BSURF_REQUIRE_IN("bsurf_smooth", (unsigned)o.estimator <= BSURF_SMOOTH_EST_632PLUS,
                   "estimator = %d: must be BSURF_SMOOTH_EST_DEFAULT, _632 or _632PLUS",
                   (int)o.estimator);
  BSURF_REQUIRE_IN(
      "bsurf_smooth", !isnan(o.h1) && !isnan(o.h2) && !isnan(o.h2_fraction),
      "h1 = %g, h2 = %g, h2_fraction = %g: NaN is not allowed (<= 0 selects the default)", o.h1,
      o.h2, o.h2_fraction);
  BSURF_REQUIRE_IN("bsurf_smooth", !isnan(o.k_error) && !isnan(o.k_error_fraction),
                   "k_error = %g, k_error_fraction = %g: NaN is not allowed", o.k_error,
                   o.k_error_fraction);
  if (o.method == BSURF_SMOOTH_MULTIPASS) {
    BSURF_REQUIRE_IN("bsurf_smooth", isfinite(o.a), "a = %g: must be finite (< 0: auto)", o.a);
    BSURF_REQUIRE_IN("bsurf_smooth", o.iterations >= -1,
                     "iterations = %d: must be >= 0, or -1 (auto)", o.iterations);
    /* K_i = k_min points carry a fit of at least a plane (multipass_fit_task
     * lowers the degree no further): its frame and its 3 coefficients need
     * 3 points, bsurf_poly_terms(1); 1 or 2 points fit nothing */
    BSURF_REQUIRE_IN("bsurf_smooth", o.k_min >= bsurf_poly_terms(1) && o.k_min <= o.error.k,
                     "k_min = %d: must be in [%d (a plane's points), error.k = %d]", o.k_min,
                     bsurf_poly_terms(1), o.error.k);
    BSURF_REQUIRE_IN("bsurf_smooth", o.k_max == 0 || (o.k_max >= o.error.k && o.k_max <= 65535),
                     "k_max = %d: must be 0 (auto) or in [error.k = %d, 65535]", o.k_max,
                     o.error.k);
  }

  BSURF_REQUIRE_IN("bsurf_smooth", o.degree_test >= -1 && o.degree_test <= 1,
                   "degree_test = %d: must be -1 (auto), 0 (off) or 1 (on)", o.degree_test);
  o.degree_test = bsurf_smooth_degree_test(&o);

  smooth_ctx c;
  ctx_init(&c, xyz, nb, &o);
  if (tune) {
    c.tune = *tune;
    c.tune.tblock_passes = tune->tblock_passes < 1
                               ? 1
                               : (tune->tblock_passes > MP_SMAX ? MP_SMAX : tune->tblock_passes);
  }
  c.out = out_xyz;
  const size_t n = c.n;
  const int T = bsurf_threads_resolve(o.error.threads);
  const int seq = o.order == BSURF_ORDER_SEQUENTIAL;
  const int stages =
      o.method == BSURF_SMOOTH_NAIVE ? 1 : (o.method == BSURF_SMOOTH_BILATERAL ? 2 : 3);
  staged_progress sp = {o.error.progress, o.error.progress_user, 0, stages};
  o.error.progress = NULL;
  o.error.progress_user = NULL;

  double *own632 = NULL, *own632p = NULL, *own_moved = NULL;
  uint32_t *visit_owned = NULL;
  c.err_632 =
      fields && fields->err_632 ? fields->err_632 : (own632 = bsurf_alloc_array(n, sizeof(double)));
  c.err_632plus = fields && fields->err_632plus ? fields->err_632plus
                                                : (own632p = bsurf_alloc_array(n, sizeof(double)));
  c.scr = calloc((size_t)T, sizeof *c.scr);
  if (!c.err_632 || !c.err_632plus || !c.scr) {
    st = BSURF_ERR_NOMEM;
    goto done;
  }
  for (int t = 0; t < T && st == BSURF_OK; t++)
    st = bsurf_error_scratch_alloc(&c.scr[t], c.k, o.error.bootstrap, c.degree);
  if (st != BSURF_OK) goto done;
  if (o.guard && !(c.gcount = bsurf_alloc_array((size_t)T * (size_t)c.k, sizeof(uint32_t)))) {
    st = BSURF_ERR_NOMEM;
    goto done;
  }
  if (o.guard && !(c.svar = bsurf_alloc_array(n ? n : 1, BSURF_SMOOTH_SV * sizeof(double)))) {
    st = BSURF_ERR_NOMEM;
    goto done;
  }
  if ((o.method == BSURF_SMOOTH_BILATERAL && !seq) || o.method == BSURF_SMOOTH_MULTIPASS) {
    /* multipass: each fit also carries its point's e2, 1 / h1^2 and w2 (one
     * record per neighbourhood for the passes to read) */
    if (o.method == BSURF_SMOOTH_MULTIPASS) c.stride += MP_EXTRA;
    c.fits = bsurf_alloc_array(n * (size_t)c.stride, sizeof(double));
    c.fit_degree = bsurf_alloc_array(n, sizeof(int));
    if (!c.fits || !c.fit_degree) {
      st = BSURF_ERR_NOMEM;
      goto done;
    }
  }
  c.o = o;

  /* ---- stage 1: the bootstrap pass (Algorithm 4 step 1, Algorithm 5's
   * first loop) ---- */
  /* per-point stages visit the points in k-d tree order (cache locality;
   * each point writes only its own outputs, so no result depends on it) */
  const uint32_t *visit = bsurf_visit_order(nb, xyz, &visit_owned);
  if (!visit) {
    st = BSURF_ERR_NOMEM;
    goto done;
  }
  st = bsurf_parallel_points_ordered(n, visit, T, boot_task, &c, staged_cb, &sp);
  if (st != BSURF_OK) goto done;
  if (report) {
    report->error.replicates_total = n * (size_t)o.error.bootstrap;
    for (int t = 0; t < T; t++) {
      report->error.replicates_skipped += c.scr[t].skipped;
      report->error.degree_reduced += c.scr[t].reduced;
      report->error.center_unestimated += c.scr[t].center_unestimated;
    }
  }
  size_t misfit = 0;
  if (c.svar) {
    /* the guard's misfit test (smooth_guard.c): the cloud's noise from the
     * sheet fits of stage 1; a fit with more misfit than noise moves nothing
     * (naive: the point stays; bilateral: theta_2 = 0 below; multipass: its
     * K_i fit, smooth_multipass.c; sequential: each fit of the sweep) */
    double *scratch = bsurf_alloc_array(n ? n : 1, sizeof(double));
    if (!scratch) {
      st = BSURF_ERR_NOMEM;
      goto done;
    }
    c.noise_fits = guard_noise(c.svar, n, BSURF_SMOOTH_SV, scratch);
    free(scratch);
    if (sel_given)
      c.noise_select[0] = sel_given[0], c.noise_select[1] = sel_given[1];
    else if ((st = select_noise(xyz, n, T, &sp, c.noise_select)) != BSURF_OK)
      goto done;
    c.noise = bsurf_smooth_noise_level(c.noise_fits, c.noise_select[0], c.noise_select[1]);
    for (size_t i = 0; i < n; i++)
      if (guard_misfit(&c.svar[BSURF_SMOOTH_SV * i], c.noise)) {
        misfit++;
        if (o.method == BSURF_SMOOTH_NAIVE)
          memcpy(&out_xyz[3 * i], &xyz[3 * i], 3 * sizeof(double));
      }
  }
  if (o.method == BSURF_SMOOTH_MULTIPASS && c.noise_fits > 0 && o.k_max != c.k) {
    /* the scale rule (ball_scale.c): where the noise is heavy against the
     * K-ball, the method runs again on wider neighbourhoods */
    int K = c.k;
    st = scale_k(&c, &o, &K);
    if (st == BSURF_OK && K > c.k) {
      bsurf_smooth_options o2 = opts ? *opts : bsurf_smooth_options_default();
      o2.method = o.method;
      o2.error.k = o2.k_max = K;
      /* the wider table's build holds stage 1's end; the run on it reports
       * within the rest of this run's range, from there to the last stage's
       * end, so the caller's progress never steps back */
      bsurf_progress_hold rest = {sp.fn, sp.user, (size_t)(sp.stage + 1) * STAGE_PER,
                                  (size_t)sp.stages * STAGE_PER,
                                  (size_t)(sp.stages - sp.stage - 1) * STAGE_PER};
      o2.error.progress = sp.fn ? bsurf_progress_hold_cb : NULL;
      o2.error.progress_user = &rest;
      bsurf_neighbors nb2;
      bsurf_progress_hold hold;
      st = bsurf_neighbors_build(&nb2, xyz, n, K, T, stage_end_hold(&sp, &hold), &hold);
      if (st == BSURF_OK) {
        st = smooth_run(xyz, &nb2, &o2, tune, c.noise_select, out_xyz, fields, report);
        bsurf_neighbors_free(&nb2);
      }
      goto done;
    }
    if (st != BSURF_OK) goto done;
  }
  c.W = bsurf_smooth_w_column(&o) ? c.err_632plus : c.err_632;
  double sumW = 0;
  for (size_t i = 0; i < n; i++)
    sumW += c.W[i];
  const double meanW = n ? sumW / (double)n : 0.0; /* |W| (Algorithm 4 step 2) */
  bsurf_smooth_options ro = o;
  bsurf_smooth_resolve(&ro, nb->h, meanW, c.noise);
  c.h1 = ro.h1;
  c.h2 = ro.h2;
  if (report) {
    report->h = nb->h;
    report->mean_error = meanW;
    report->noise = c.svar ? sqrt(c.noise) : NAN;
    report->noise_fits = c.svar ? sqrt(c.noise_fits) : NAN;
    report->noise_select = c.svar ? sqrt(c.noise_select[0]) : NAN;
    report->section_share = c.svar ? c.noise_select[1] : NAN;
    report->misfit_fits = misfit;
    report->k = c.k;
  }

  if (o.method == BSURF_SMOOTH_NAIVE) {
    /* Eq. 6.1 only where W_i < threshold (6.2, Figs. 6.2-6.3) */
    double thr = ro.threshold;
    size_t projected = 0;
    for (size_t i = 0; i < n; i++)
      projected += naive_select(c.W[i], thr, &xyz[3 * i], &out_xyz[3 * i]);
    if (report) {
      report->threshold = thr;
      report->projected = projected;
    }
  } else if (o.method == BSURF_SMOOTH_BILATERAL) {
    c.e2 = bsurf_alloc_array(n, sizeof(double));
    c.w2 = bsurf_alloc_array(n, sizeof(double));
    if (!c.e2 || !c.w2) {
      st = BSURF_ERR_NOMEM;
      goto done;
    }
    for (size_t i = 0; i < n; i++)
      set_theta2(&c, i, c.W[i], !seq && c.svar ? &c.svar[BSURF_SMOOTH_SV * i] : NULL);
    c.inv_h1sq_global = 1.0 / (c.h1 * c.h1);
    sp.stage = 1;
    if (seq) {
      memcpy(out_xyz, xyz, n * 3 * sizeof(double));
      bilateral_sequential(&c);
      if (sp.fn && staged_cb(&sp, 1, 1)) st = BSURF_ERR_CANCELLED;
    } else {
      st = build_reverse(&c, NULL, NULL, NULL);
      if (st != BSURF_OK) goto done;
      c.cur = xyz;
      c.next = out_xyz;
      st = bsurf_parallel_points_ordered(n, visit, T, gather_bilateral_task, &c, staged_cb, &sp);
    }
    if (report) {
      report->h1 = c.h1;
      report->h2 = c.h2;
    }
  } else {
    st = smooth_multipass_run(&c, &o, visit, T, &sp, meanW, fields, report);
  }
  if (st != BSURF_OK) goto done;

  /* ---- how far the points moved ---- */
  {
    double *moved = fields && fields->moved ? fields->moved
                                            : (own_moved = bsurf_alloc_array(n, sizeof(double)));
    if (!moved) {
      st = BSURF_ERR_NOMEM;
      goto done;
    }
    double sum = 0, mx = 0;
    size_t count = 0;
    for (size_t i = 0; i < n; i++) {
      double d = moved_of(&xyz[3 * i], &out_xyz[3 * i]);
      moved[i] = d;
      sum += d;
      if (d > mx) mx = d;
      count += d > 0;
    }
    if (report) {
      report->moved_points = count;
      report->moved_mean = n ? sum / (double)n : 0;
      report->moved_max = mx;
    }
  }

done:
  ctx_free(&c, T);
  free(own632);
  free(own632p);
  free(own_moved);
  free(visit_owned);
  return st;
}

bsurf_status bsurf_smooth(const double *xyz, const bsurf_neighbors *nb,
                          const bsurf_smooth_options *opts, double *out_xyz,
                          bsurf_smooth_fields *fields, bsurf_smooth_report *report) {
  return bsurf_smooth_tuned(xyz, nb, opts, NULL, out_xyz, fields, report);
}
