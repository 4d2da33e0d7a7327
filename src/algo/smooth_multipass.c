/* Multipass smoothing (thesis 6.4, Algorithm 5, Eqs. 6.3-6.5): per point K_i
 * and d_L, a fit of the K_i points made once, then passes of Eq. 6.2 with
 * h1 = a d_L (see smooth.c for the whole chapter and docs/smoothing.md). The
 * passes' arithmetic in blocks and lanes: smooth_lanes.c. */
#include "algo/smooth_ctx.h"
#include "search/search.h"
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* the most passes of the stop rule (the thesis's count, 6.4.1) */
#define MP_PASSES_MAX 300

/* Multipass stage 2: K_i (Eqs. 6.3-6.4), d_L and the fit of the K_i points. */
static void multipass_fit_task(void *vc, int thread, size_t i) {
  smooth_ctx *c = vc;
  const int K = c->k, kmin = c->o.k_min;
  double y = (double)K;
  if (c->k_error > 0) y = (double)(kmin - K) / c->k_error * c->W[i] + (double)K;
  int kh = kmin;
  if (y > kmin) kh = y >= K ? K : (int)floor(y + 0.5);
  if (kh < kmin) kh = kmin;
  if (kh > K) kh = K;
  c->khat[i] = kh;
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  const double *p0 = &c->xyz[3 * i];
  double s = 0;
  for (int j = 1; j < kh; j++) {
    const double *q = &c->xyz[3 * (size_t)idx[j]];
    s += sqrt((q[0] - p0[0]) * (q[0] - p0[0]) + (q[1] - p0[1]) * (q[1] - p0[1]) +
              (q[2] - p0[2]) * (q[2] - p0[2]));
  }
  c->dl[i] = kh > 1 ? s / (kh - 1) : 0.0;

  bsurf_frame fr;
  bsurf_local_frame(c->xyz, idx, kh, c->o.error.pca_center, &fr);
  bsurf_localfit *lf = &c->scr[thread].lf;
  /* least squares with at least two points per term: a fit that (nearly)
   * interpolates K_i noisy points follows the noise and swings between them */
  int deg = c->degree;
  while (deg > 1 && 2 * bsurf_poly_terms(deg) > kh)
    deg--;
  bsurf_localfit_setup(lf, c->xyz, idx, kh, &fr, deg);
  double coef[BSURF_TERMS_MAX];
  c->fit_degree[i] = solve_with_fallback(lf, deg, c->m, coef);
  fit_store(&c->fits[i * (size_t)c->stride], &fr, 1.0 / lf->scale, coef, c->m);
  /* the misfit test of the neighbourhood's whole-K fit (stage 1, more
   * degrees of freedom) holds for its K_i fit too */
  const int misfit_k = c->svar && guard_misfit(&c->svar[BSURF_SMOOTH_SV * i], c->noise);
  if (c->o.guard)
    guard_fit(c, &c->scr[thread], GCOUNT(c, thread), c->xyz, idx, kh,
              &c->fits[i * (size_t)c->stride], &c->fit_degree[i],
              c->svar ? &c->svar[BSURF_SMOOTH_SV * i] : NULL);
  /* the guard's misfit test of the K_i fit (smooth_guard.c) */
  if (misfit_k || (c->svar && guard_misfit(&c->svar[BSURF_SMOOTH_SV * i], c->noise)))
    c->fits[i * (size_t)c->stride + 12] = NAN;

  /* h1 = a d_L (Eq. 6.5); by default (a < 0) the local spacing, d_L
   * 1.5 sqrt(pi / K_i): on a uniform sample the K_i nearest points fill a
   * disc of area K_i h^2, radius R = h sqrt(K_i / pi), whose points lie at
   * 2R/3 on average. The thesis's a = 0.1 cuts every neighbour's weight
   * (docs/smoothing.md, "Why the thesis's multipass barely moves points") */
  const double a = c->o.a >= 0 ? c->o.a : 1.5 * sqrt(3.14159265358979323846 / (double)kh);
  double h1 = a * c->dl[i];
  /* with the guard's noise estimate, by default: h1 = sqrt((a d_L)^2 + 2
   * sigma^2), bilateral's rule (smooth.c, bsurf_smooth_resolve): two points
   * a d_L apart on the surface are, with noise sigma along the normal at
   * each, sqrt((a d_L)^2 + 2 sigma^2) apart on average, and a d_L alone
   * gives the points the noise displaced farthest, those a move helps most,
   * the least weight (d_L, a mean over K_i neighbours mostly several
   * spacings away, hardly grows with the noise). An explicit a keeps Eq.
   * 6.5 as written */
  if (c->o.a < 0 && c->noise > 0) h1 = sqrt(h1 * h1 + 2.0 * c->noise);
  c->inv_h1sq[i] = h1 > 0 ? 1.0 / (h1 * h1) : 0.0;
  set_theta2(c, i, c->W[i], NULL); /* misfit: the fit is NAN above */
  double *rec = &c->fits[i * (size_t)c->stride + FIT_HEAD + (size_t)c->m];
  rec[0] = c->e2[i];
  rec[1] = c->inv_h1sq[i];
  rec[2] = c->w2[i];
}

static void gather_multipass_task(void *vc, int thread, size_t p) {
  smooth_ctx *c = vc;
  double step2 = gather_update(c, p, 1);
  if (step2 > c->tmax[8 * thread]) c->tmax[8 * thread] = step2;
}

/* The pairs (p, i) of the multipass that can carry a weight while no point
 * moves by more than the margin: i = p, or |p - i| < cut_i + 2 margin at the
 * positions `cur` (a pair further apart stays beyond theta_1's cut). Keeps
 * the order of the reverse list. */
static void active_task(void *vc, int thread, size_t p) {
  (void)thread;
  smooth_ctx *c = vc;
  const double *x = &c->cur[3 * p];
  uint32_t *act = &c->act[c->rev_off[p]];
  uint32_t cnt = 0;
  for (size_t e = c->rev_off[p]; e < c->rev_off[p + 1]; e++) {
    const uint32_t i = c->rev[e];
    if (!(c->e2[i] <= GAUSS_CUT)) continue; /* theta_2 alone is below the cut */
    if (i != p) {
      const double *ci = &c->cur[3 * (size_t)i];
      double d2 = (x[0] - ci[0]) * (x[0] - ci[0]) + (x[1] - ci[1]) * (x[1] - ci[1]) +
                  (x[2] - ci[2]) * (x[2] - ci[2]);
      if (!(d2 < c->reach2[i])) continue;
    }
    act[cnt++] = i;
  }
  c->act_n[p] = cnt;
}

/* One multipass pass in the thesis's order (in place, one thread). */
static void multipass_sequential_pass(smooth_ctx *c) {
  double *w = c->scr[0].est_scratch;
  for (size_t i = 0; i < c->n; i++) {
    const double e2 = c->e2[i];
    if (!(e2 <= GAUSS_CUT)) continue;
    const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
    const int kh = c->khat[i];
    const double *z0 = &c->out[3 * i];
    for (int j = 0; j < kh; j++) {
      const double *z = &c->out[3 * (size_t)idx[j]];
      double d2 = (z[0] - z0[0]) * (z[0] - z0[0]) + (z[1] - z0[1]) * (z[1] - z0[1]) +
                  (z[2] - z0[2]) * (z[2] - z0[2]);
      double e1 = d2 == 0 ? 0 : (c->inv_h1sq[i] > 0 ? d2 * c->inv_h1sq[i] : INFINITY);
      w[j] = weight_of(e1 + e2);
    }
    const double *F = &c->fits[i * (size_t)c->stride];
    for (int j = 0; j < kh; j++) {
      if (w[j] < 0x1p-54) continue;
      double *z = &c->out[3 * (size_t)idx[j]];
      double delta = fit_delta(F, c->fit_degree[i], c->m, z);
      if (isnan(delta)) continue;
      for (int t = 0; t < 3; t++)
        z[t] = (1.0 - w[j]) * z[t] + w[j] * (z[t] + delta * F[9 + t]);
    }
  }
}

/* The mean squared move of a pass from a to b (n x 3), summed in point
 * order (the same bits for any thread count). */
static double mean_sq_move(const double *a, const double *b, size_t n) {
  double s = 0;
  for (size_t i = 0; i < 3 * n; i++)
    s += (b[i] - a[i]) * (b[i] - a[i]);
  return n ? s / (double)n : 0.0;
}

/* Algorithm 5 after the bootstrap pass: K_i, d_L and the fits of the K_i
 * points once, then o->iterations passes of Eq. 6.2 (in the thesis's order,
 * or in parallel in Morton order, in blocks of points and of passes). */
bsurf_status smooth_multipass_run(smooth_ctx *c, const bsurf_smooth_options *o,
                                  const uint32_t *visit, int T, staged_progress *sp, double meanW,
                                  bsurf_smooth_fields *fields, bsurf_smooth_report *report) {
  const size_t n = c->n;
  const int seq = o->order == BSURF_ORDER_SEQUENTIAL;
  bsurf_status st = BSURF_OK;
  /* ---- multipass: K_i, d_L and the fits, once ---- */
  /* Eq. 6.4 only when asked for (--k-error; the thesis's is |W|): by
   * default K_i = K and the guard's t test halves a neighbourhood whose fit
   * is biased at its centre (no shrinking by the error level paid on the
   * development set: docs/smoothing.md). Errors below 1e-9 h are rounding,
   * not noise, and their ratios carry no information (exact data keeps
   * K_i = K) */
  const double kf = o->k_error_fraction > 0 ? o->k_error_fraction : 0.0;
  c->k_error = o->k_error > 0 ? o->k_error : (kf > 0 ? fmax(kf * meanW, 1e-9 * c->nb->h) : 0.0);
  /* h2 by default: 2 W_n, W_n the median W_i (the error of a fit that
   * follows the surface: the noise level). W^2 = W_n^2 + b^2 reaches 2 W_n^2
   * where a fit's misfit b^2 equals the noise, the break-even of a move (the
   * guard's misfit test); G(W, 2 W_n) has its inflection, where it falls
   * fastest, there (theta_2 = e^-1/2). A length or a multiple of |W| (the
   * mean) when asked for (the thesis: 0.3 |W|) */
  double wn = 0;
  if (n) {
    double *srt = bsurf_alloc_array(n, sizeof(double));
    if (!srt) return BSURF_ERR_NOMEM;
    memcpy(srt, c->W, n * sizeof(double));
    wn = bsurf_median(srt, n);
    free(srt);
  }
  if (!(o->h2 > 0) && !(o->h2_fraction > 0)) c->h2 = 2.0 * wn;
  /* the passes: o->iterations of them, or (iterations < 0, the default)
   * until the stop rule, at most MP_PASSES_MAX */
  const int autostop = o->iterations < 0;
  const int maxit = autostop ? MP_PASSES_MAX : o->iterations;
  c->khat = bsurf_alloc_array(n, sizeof(int));
  c->dl = bsurf_alloc_array(n, sizeof(double));
  c->e2 = bsurf_alloc_array(n, sizeof(double));
  c->w2 = bsurf_alloc_array(n, sizeof(double));
  c->inv_h1sq = bsurf_alloc_array(n, sizeof(double));
  if (!c->khat || !c->dl || !c->e2 || !c->w2 || !c->inv_h1sq) {
    st = BSURF_ERR_NOMEM;
    return st;
  }
  sp->stage = 1;
  st = bsurf_parallel_points_ordered(n, visit, T, multipass_fit_task, c, staged_cb, sp);
  if (st != BSURF_OK) return st;
  sp->stage = 2;
  /* the stop rule's level: a fit of p coefficients to K_i points predicts
   * its own points with variance sigma^2 p / K_i on average (the mean
   * leverage), so a pass whose mean squared move is below sigma^2 mean(p_i /
   * K_i) moves points by less than the fits' own error: further passes only
   * carry each fit's error and bias into its neighbours. sigma^2: the
   * guard's noise estimate, else W_n^2; the variance a fit's points show is
   * sigma^2 kappa_i, the share its ball keeps (guard_ball_share: at heavy
   * noise a ball holds only the points whose heights are near its
   * centre's), so the level is sigma^2 mean(kappa_i p_i / K_i) */
  double stop2 = 0;
  if (autostop && n) {
    double sum = 0;
    const double inv = c->noise > 0 ? 1.0 / sqrt(c->noise) : 0.0;
    for (size_t i = 0; i < n; i++) {
      const double R = c->svar ? c->svar[BSURF_SMOOTH_SV * i + 3] : NAN;
      const double kap = inv > 0 && R > 0 ? guard_ball_share(R * inv) : 1.0;
      sum += kap * (double)bsurf_poly_terms(c->fit_degree[i]) / (double)c->khat[i];
    }
    const double s2 = c->noise > 0 ? c->noise : wn * wn;
    stop2 = s2 * sum / (double)n;
  }
  double *prev = NULL; /* the sequential sweep's positions before a pass */
  if (autostop && seq && !(prev = bsurf_alloc_array(n * 3, sizeof(double)))) return BSURF_ERR_NOMEM;
  double *buf = NULL, *pos = c->out;
  uint32_t *perm = NULL, *rank = NULL;
  memcpy(c->out, c->xyz, n * 3 * sizeof(double));
  /* the margin of the active pairs: a tenth of the mean spacing */
  const double margin = 0.1 * c->nb->h;
  double drift = INFINITY; /* how far points may have moved since the pairs were listed */
  if (!seq) {
    /* the passes run in a spatial order: every per-point array is permuted
     * (rank r holds point perm[r]) and the result is put back at the end */
    st = bsurf_spatial_order(c->xyz, n, &perm, &rank);
    if (st == BSURF_OK)
      st = permute_rows((void **)&c->fits, n, (size_t)c->stride * sizeof(double), perm);
    if (st == BSURF_OK) st = permute_rows((void **)&c->fit_degree, n, sizeof(int), perm);
    if (st == BSURF_OK) st = permute_rows((void **)&c->e2, n, sizeof(double), perm);
    if (st == BSURF_OK) st = permute_rows((void **)&c->w2, n, sizeof(double), perm);
    if (st == BSURF_OK) st = permute_rows((void **)&c->inv_h1sq, n, sizeof(double), perm);
    if (st == BSURF_OK) {
      pos = bsurf_alloc_array(n * 3, sizeof(double));
      if (!pos)
        st = BSURF_ERR_NOMEM;
      else
        for (size_t r = 0; r < n; r++)
          memcpy(&pos[3 * r], &c->xyz[3 * (size_t)perm[r]], 3 * sizeof(double));
    }
    if (st == BSURF_OK) st = build_reverse(c, c->khat, perm, rank);
    buf = bsurf_alloc_array(n * 3, sizeof(double));
    c->act =
        bsurf_alloc_array(c->rev_off ? (c->rev_off[n] ? c->rev_off[n] : 1) : 1, sizeof(uint32_t));
    c->act_n = bsurf_alloc_array(n, sizeof(uint32_t));
    c->reach2 = bsurf_alloc_array(n, sizeof(double));
    c->tmax = bsurf_calloc_array((size_t)T * 8, sizeof(double));
    if (st == BSURF_OK && (!buf || !c->act || !c->act_n || !c->reach2 || !c->tmax))
      st = BSURF_ERR_NOMEM;
    if (st == BSURF_OK)
      for (size_t i = 0; i < n; i++) {
        /* theta_1 theta_2 >= 2^-54 needs d^2 / h1^2 <= GAUSS_CUT - e2 */
        double room = GAUSS_CUT - c->e2[i];
        double r = c->inv_h1sq[i] > 0 && room > 0 ? sqrt(room / c->inv_h1sq[i]) + 2 * margin : 0.0;
        c->reach2[i] = r * r;
      }
#ifdef MP_LANES
    if (st == BSURF_OK && c->m <= 10 && c->tune.lanes) {
      for (size_t p0 = 0; p0 < n; p0 += MP_BLOCK) {
        const size_t p1 = p0 + MP_BLOCK < n ? p0 + MP_BLOCK : n;
        if (c->rev_off[p1] - c->rev_off[p0] > c->mp_cap)
          c->mp_cap = c->rev_off[p1] - c->rev_off[p0];
      }
      c->mp_point = bsurf_alloc_array((size_t)T * (c->mp_cap ? c->mp_cap : 1), sizeof(uint32_t));
      c->mp_val = bsurf_alloc_array((size_t)T * 4 * (c->mp_cap ? c->mp_cap : 1), sizeof(double));
      c->act_off = bsurf_alloc_array(n + 1, sizeof(size_t));
      if (!c->mp_point || !c->mp_val || !c->act_off) st = BSURF_ERR_NOMEM;
      if (st == BSURF_OK && c->tune.tblock_passes > 1 && maxit > 1 && !autostop) {
        c->tb_S = c->tune.tblock_passes;
        c->nreg = (n + MP_REGION - 1) / MP_REGION;
        c->reg = bsurf_calloc_array(c->nreg ? c->nreg : 1, sizeof *c->reg);
        c->lmap = bsurf_alloc_array((size_t)T * (n ? n : 1), sizeof(uint32_t));
        c->tb_step = bsurf_alloc_array((size_t)T * MP_TSTRIDE, sizeof(double));
        if (!c->reg || !c->lmap || !c->tb_step)
          st = BSURF_ERR_NOMEM;
        else
          memset(c->lmap, 0xff, (size_t)T * n * sizeof(uint32_t));
      }
    }
#endif
  }
  int it = 0;
  double *from = pos, *to = buf; /* the passes read from and write to; swapped after each */
  double last = INFINITY;        /* the largest move of the last pass (none yet) */
  int stop = 0;
  while (st == BSURF_OK && it < maxit && !stop) {
    int s = 1; /* passes done in this round */
    if (seq) {
      if (prev) memcpy(prev, c->out, n * 3 * sizeof(double));
      multipass_sequential_pass(c);
      if (prev) stop = mean_sq_move(prev, c->out, n) < stop2;
    } else {
      c->cur = from;
      c->next = to;
      if (drift > margin) {
        st = bsurf_parallel_sweep(n, T, active_task, c);
        drift = 0;
        if (c->act_off) {
          /* the lists side by side, for the block passes: each moves down
           * (its start is at most its slot range's) */
          size_t off = 0;
          for (size_t p = 0; p < n; p++) {
            c->act_off[p] = off;
            memmove(&c->act[off], &c->act[c->rev_off[p]], c->act_n[p] * sizeof(uint32_t));
            off += c->act_n[p];
          }
          c->act_off[n] = off;
        }
        if (st == BSURF_OK && c->reg) st = mp_regions_build(c, T);
      }
      /* a time block of tb passes: only as long as every point is
       * expected to stay within the margin until its last pass starts (at
       * most tb - 1 more moves of 1.5 times the last pass's largest);
       * else pass by pass, up to the rebuild */
      int tb = c->reg ? (maxit - it < c->tb_max ? maxit - it : c->tb_max) : 1;
      while (tb > 1 && !(drift + (tb - 1) * 1.5 * last <= margin))
        tb--;
      if (st == BSURF_OK && tb > 1) {
        c->tb_s = tb;
        for (int t = 0; t < T; t++)
          for (int j = 0; j < tb; j++)
            c->tb_step[(size_t)t * MP_TSTRIDE + (size_t)j] = 0;
        st = bsurf_parallel_sweep_chunk(c->nreg, T, 1, mp_tblock_task, c);
        /* the lists held every weighted pair if no pass of the block
         * started beyond the margin */
        double d = drift, mx = 0;
        int ok = 1;
        for (int j = 0; j < tb && st == BSURF_OK; j++) {
          double m = 0;
          for (int t = 0; t < T; t++)
            if (c->tb_step[(size_t)t * MP_TSTRIDE + (size_t)j] > m)
              m = c->tb_step[(size_t)t * MP_TSTRIDE + (size_t)j];
          if (d > margin) ok = 0;
          d += sqrt(m);
          if (m > mx) mx = m;
        }
        last = sqrt(mx);
        if (!ok) { /* discarded: run again after a rebuild, in fewer passes */
          drift = INFINITY;
          continue;
        }
        drift = d;
        s = tb;
      } else if (st == BSURF_OK) {
        for (int t = 0; t < T; t++)
          c->tmax[8 * t] = 0;
#ifdef MP_LANES
        if (c->mp_point)
          st = bsurf_parallel_sweep_chunk((n + MP_BLOCK - 1) / MP_BLOCK, T, 16,
                                          gather_multipass_block, c);
        else
#endif
          st = bsurf_parallel_sweep(n, T, gather_multipass_task, c);
        double mx = 0;
        for (int t = 0; t < T; t++)
          if (c->tmax[8 * t] > mx) mx = c->tmax[8 * t];
        last = sqrt(mx);
        drift += last;
      }
      double *t = from;
      from = to;
      to = t;
      if (autostop && st == BSURF_OK) stop = mean_sq_move(to, from, n) < stop2;
    }
    it += s;
    if (st == BSURF_OK && sp->fn && staged_cb(sp, (size_t)it, (size_t)maxit))
      st = BSURF_ERR_CANCELLED;
  }
  /* a run that stopped early (the stop rule) has done its stage: the
   * caller's progress ends at its total */
  if (st == BSURF_OK && it < maxit && sp->fn && staged_cb(sp, 1, 1)) st = BSURF_ERR_CANCELLED;
  if (st == BSURF_OK && !seq) {
    for (size_t r = 0; r < n; r++)
      memcpy(&c->out[3 * (size_t)perm[r]], &from[3 * r], 3 * sizeof(double));
  }
  free(buf);
  free(prev);
  if (pos != c->out) free(pos);
  free(perm);
  free(rank);
  if (st != BSURF_OK) return st;
  if (report) {
    report->h1 = 0;
    report->h2 = c->h2;
    report->k_error = c->k_error;
    report->iterations = it;
  }
  if (fields && fields->k_hat)
    for (size_t i = 0; i < n; i++)
      fields->k_hat[i] = c->khat[i];
  if (fields && fields->d_local) memcpy(fields->d_local, c->dl, n * sizeof(double));
  return st;
}
