/* Smoothing in two stages for the tiled runs (smooth_stages.h). */
#include "algo/smooth_ctx.h"
#include "algo/smooth_stages.h"
#include "search/search.h"
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- tiled smoothing: the two stages (src/tile/tiles.c, docs/scaling.md) ----
 * bsurf_smooth above is stage 1 (boot_task at every point), the mean |W|
 * (an index-order sum) and stage 2 (naive_select, or gather_update over the
 * reverse neighbourhoods). A tiled run makes the same calls on pieces: stage 1
 * per tile, |W| summed in index order from the values kept by the engine,
 * stage 2 per tile (bilateral: with the reverse neighbours' stage 1 values)
 * or per range of points (naive). Sequential order and multipass are not
 * offered: the sweep makes each fit depend on the moves of every earlier
 * neighbourhood of the whole cloud (a chain as long as the cloud), and the
 * multipass runs `iterations` passes, each one ring further. */

size_t bsurf_smooth_stage_values(const bsurf_smooth_options *o) {
  if (!o || o->method == BSURF_SMOOTH_MULTIPASS) return 0;
  /* W (2), the naive position (3) or the fit record, the guard's record of
   * its sheet fit for the misfit test (BSURF_SMOOTH_SV) */
  if (o->method == BSURF_SMOOTH_NAIVE) return 2 + 3 + BSURF_SMOOTH_SV;
  if (o->order != BSURF_ORDER_PARALLEL) return 0;
  return 2 + FIT_HEAD + (size_t)bsurf_poly_terms(o->error.degree) + BSURF_SMOOTH_SV;
}

double bsurf_smooth_stage1_bytes(const bsurf_smooth_options *o) {
  /* smooth.c: the guard's records (svar, BSURF_SMOOTH_SV doubles); the fits
   * of bilateral in parallel order and of multipass (FIT_HEAD + m doubles,
   * multipass MP_EXTRA more) and their degrees (an int) */
  const double m = bsurf_poly_terms(o->error.degree);
  double b = o->guard ? 8.0 * BSURF_SMOOTH_SV : 0;
  if (o->method == BSURF_SMOOTH_MULTIPASS)
    b += 8.0 * (FIT_HEAD + m + MP_EXTRA) + 4;
  else if (o->method == BSURF_SMOOTH_BILATERAL && o->order == BSURF_ORDER_PARALLEL)
    b += 8.0 * (FIT_HEAD + m) + 4;
  return b;
}

double bsurf_smooth_passes_bytes(const bsurf_smooth_options *o, int k, int T, double *per_k) {
  const int seq = o->order == BSURF_ORDER_SEQUENTIAL;
  double b = 0, pk = 0;
  if (o->method == BSURF_SMOOTH_BILATERAL) {
    /* smooth.c: e2 and w2; in parallel order the reverse lists (offsets
     * 8, at most k entries of 4) */
    b = 16;
    if (!seq) b += 8, pk = 4;
  } else if (o->method == BSURF_SMOOTH_MULTIPASS) {
    /* smooth_multipass.c: K_i (int), d_L, e2, w2, 1 / h1^2 */
    b = 4 + 8 + 8 + 8 + 8;
    if (seq) {
      b += o->iterations < 0 ? 24 : 0; /* the stop rule's positions before a pass */
    } else {
      /* the spatial order (perm, rank), the positions read and written
       * (pos, buf), the reverse lists (offsets 8, at most K_i <= k entries
       * of 4) and the active pairs (as many, their counts, offsets and
       * reach); with a fixed pass count, the time blocks' local maps (an
       * int per point per thread) */
      b += 8 + 24 + 24 + 8 + 4 + 8 + 8;
      pk = 4 + 4;
      if (o->iterations > 1) b += 4.0 * T;
    }
  }
  if (per_k) *per_k = pk;
  return b + pk * k;
}

double bsurf_smooth_noise(const double *sv, size_t n, size_t stride, double *scratch) {
  return guard_noise(sv, n, stride, scratch);
}

void bsurf_smooth_select_options(int T, bsurf_kselect_options *ko) {
  static const int ks[] = {10, 15, 20, 25, 30, 35, 40, 45, 50, 55, 60, 65, 70, 75, 80};
  *ko = bsurf_kselect_options_default();
  ko->ks = ks;
  ko->nk = (int)(sizeof ks / sizeof ks[0]);
  ko->noise_pool = BSURF_NOISE_POOL_GLOBAL;
  ko->threads = T;
}

double bsurf_smooth_noise_level(double fits, double select, double section_share) {
  /* the sheet fits' reading, but where the cloud holds cross-sections the
   * larger of the two. A sheet fit is a height over the plane of its
   * centre's nearest points; where those are a cross-section of the surface
   * (a CAD mesh's vertices on rings, the plane holding the normal and with
   * it the noise) its heights hold none of the noise, and where a tenth of
   * the fits are such their lower decile reads none either (a turned
   * part's vertices: 0.004 sigma; a joint's: 0.05 sigma). The sign: the
   * selection found more than 5% of the points' neighbourhoods
   * section-sampled (kselect_noise.c, pool_point: more of the 80 nearest
   * thin, curved within their plane and holding the normal than its
   * per-point test, at its level SECT_ALPHA = 5%, passes by chance, and the
   * quadric's level significantly below the conic's). Each flag already
   * corrects for chance, so on a surface far fewer than 5% are flagged
   * (none on the development set's organic and generated clouds, at most
   * 0.13% on camel's vertices): the 5% of its level is a conservative line.
   * Elsewhere the fits' reading stands: where both read above the noise
   * (light noise on a coarse mesh, misfit taken for noise) the larger is
   * the worse, and the moves it admits end farther than the input
   * (docs/smoothing.md, "Two readings of the noise"). Exact data (a tenth
   * of the fits leave no residual, to rounding: at most 1e-12 of the
   * selection's level) stay exact: the selection reads their misfit. */
  if (!(fits > 1e-12 * select) || !(select > fits)) return fits;
  return section_share > BSURF_SMOOTH_SECTION_SHARE ? select : fits;
}

int bsurf_smooth_misfit(const double *sv, double noise) {
  return guard_misfit(sv, noise);
}

int bsurf_smooth_degree_test(const bsurf_smooth_options *o) {
  /* auto: bilateral and multipass. Their moves average the fits of many
   * neighbourhoods (multipass with h1 the local spacing), where the variance
   * a lower degree saves adds up and its bias is small; naive (the bootstrap
   * mean of the full-degree fit, the guard's fit only at two sheets) ended
   * farther from the surface with it on coarse meshes of the development set
   * (docs/smoothing.md, "The degree test") */
  return o->degree_test < 0 ? o->method != BSURF_SMOOTH_NAIVE : o->degree_test;
}

int bsurf_smooth_w_column(const bsurf_smooth_options *o) {
  bsurf_smooth_estimator est = o->estimator;
  if (est == BSURF_SMOOTH_EST_DEFAULT)
    est = o->method == BSURF_SMOOTH_NAIVE ? BSURF_SMOOTH_EST_632PLUS : BSURF_SMOOTH_EST_632;
  return est == BSURF_SMOOTH_EST_632PLUS;
}

void bsurf_smooth_resolve(bsurf_smooth_options *o, double h, double mean_w, double noise) {
  /* h2 default: 2 |W|. Bilateral: the thesis shows 0.5-1 |W| (Figs.
   * 6.4-6.6), but on fandisk and the cube at noise 0.25 and 0.5 the distance
   * to the true surface keeps falling up to about 2 |W|, feature points
   * included. Multipass: the thesis's 0.3 |W| (6.4.1) gives a point at the
   * mean error theta_2 = e^-11 per pass, so 300 passes move it 0.5% of the
   * way to its fit (docs/smoothing.md, "Why the thesis's multipass barely
   * moves points") */
  double frac = o->h2_fraction > 0 ? o->h2_fraction : 2.0;
  /* h1 default: the typical distance from a neighbourhood's centre to a
   * neighbour of its sheet one spacing away, each displaced by the noise
   * along the normal: sqrt(h^2 + 2 sigma^2), sigma^2 the guard's noise
   * variance (h without the guard). h alone (the thesis's Fig. 6.5: h1 = d)
   * gives the points the noise displaced farthest, the ones a move helps
   * most, the least weight once sigma nears h (docs/smoothing.md, "The
   * distance sigma") */
  o->h1 = o->h1 > 0 ? o->h1 : sqrt(h * h + (noise > 0 ? 2.0 * noise : 0.0));
  o->h2 = o->h2 > 0 ? o->h2 : frac * mean_w;
  /* naive: Eq. 6.1 only where W_i < threshold (6.2, Figs. 6.2-6.3) */
  if (isnan(o->threshold)) o->threshold = mean_w;
}

bsurf_status bsurf_smooth_stage1(const double *xyz, const bsurf_neighbors *nb,
                                 const bsurf_smooth_options *opts, double *values,
                                 bsurf_error_report *report) {
  if (report) memset(report, 0, sizeof *report);
  const size_t nv = bsurf_smooth_stage_values(opts);
  BSURF_REQUIRE(xyz && values, "xyz or values is NULL");
  BSURF_REQUIRE(nv, "method %d in order %d is not tiled (stage values 0)",
                opts ? (int)opts->method : -1, opts ? (int)opts->order : -1);
  bsurf_smooth_options o = *opts;
  o.degree_test = bsurf_smooth_degree_test(&o);
  bsurf_status st = bsurf_error_check(&o.error, nb);
  if (st != BSURF_OK) return st;
  smooth_ctx c;
  ctx_init(&c, xyz, nb, &o);
  o.error.progress = NULL;
  c.o = o;
  const size_t n = c.n;
  const int T = bsurf_threads_resolve(o.error.threads);
  c.err_632 = bsurf_alloc_array(n, sizeof(double));
  c.err_632plus = bsurf_alloc_array(n, sizeof(double));
  c.scr = calloc((size_t)T, sizeof *c.scr);
  if (o.method == BSURF_SMOOTH_NAIVE)
    c.out = bsurf_alloc_array(n, 3 * sizeof(double));
  else
    c.fits = bsurf_alloc_array(n, (size_t)c.stride * sizeof(double));
  if (o.guard) {
    c.gcount = bsurf_alloc_array((size_t)T * (size_t)c.k, sizeof(uint32_t));
    c.svar = bsurf_alloc_array(n ? n : 1, BSURF_SMOOTH_SV * sizeof(double));
  }
  if (!c.err_632 || !c.err_632plus || !c.scr || !(c.out || c.fits) ||
      (o.guard && (!c.gcount || !c.svar)))
    st = BSURF_ERR_NOMEM;
  for (int t = 0; t < T && st == BSURF_OK; t++)
    st = bsurf_error_scratch_alloc(&c.scr[t], c.k, o.error.bootstrap, c.degree);
  if (st == BSURF_OK) st = bsurf_parallel_sweep(n, T, boot_task, &c);
  if (st == BSURF_OK) {
    const double *rest = c.out ? c.out : c.fits;
    const size_t w = nv - 2 - BSURF_SMOOTH_SV;
    for (size_t i = 0; i < n; i++) {
      values[i * nv] = c.err_632[i];
      values[i * nv + 1] = c.err_632plus[i];
      memcpy(&values[i * nv + 2], &rest[i * w], w * sizeof(double));
      double *sv = &values[i * nv + nv - BSURF_SMOOTH_SV];
      if (c.svar)
        memcpy(sv, &c.svar[BSURF_SMOOTH_SV * i], BSURF_SMOOTH_SV * sizeof(double));
      else
        sv[0] = NAN, sv[1] = 0, sv[2] = NAN;
    }
    if (report) {
      report->replicates_total = n * (size_t)o.error.bootstrap;
      for (int t = 0; t < T; t++) {
        report->replicates_skipped += c.scr[t].skipped;
        report->degree_reduced += c.scr[t].reduced;
        report->center_unestimated += c.scr[t].center_unestimated;
      }
    }
  }
  free(c.err_632);
  free(c.err_632plus);
  free(c.out);
  ctx_free(&c, c.scr ? T : 0);
  return st;
}

bsurf_status bsurf_smooth_stage2(const double *xyz, size_t local_count, const double *values,
                                 size_t count, const uint32_t *point, const size_t *rev_off,
                                 const uint32_t *rev, const bsurf_smooth_options *o, double noise,
                                 double *out_xyz, double *moved) {
  const size_t nv = bsurf_smooth_stage_values(o);
  BSURF_REQUIRE(xyz && values && o && out_xyz && moved,
                "xyz, values, opts, out_xyz or moved is NULL");
  BSURF_REQUIRE(nv, "method %d in order %d is not tiled (stage values 0)", (int)o->method,
                (int)o->order);
  BSURF_REQUIRE(o->method != BSURF_SMOOTH_BILATERAL || rev_off,
                "rev_off is NULL (bilateral needs it)");
  const int wc = bsurf_smooth_w_column(o);
  bsurf_status st = BSURF_OK;
  if (o->method == BSURF_SMOOTH_NAIVE) {
    for (size_t r = 0; r < count; r++) {
      const size_t p = point ? point[r] : r;
      const double *v = &values[p * nv];
      memcpy(&out_xyz[3 * r], &v[2], 3 * sizeof(double));
      if (guard_misfit(&v[nv - BSURF_SMOOTH_SV], noise)) /* the point stays, as in bsurf_smooth */
        memcpy(&out_xyz[3 * r], &xyz[3 * p], 3 * sizeof(double));
      naive_select(v[wc], o->threshold, &xyz[3 * p], &out_xyz[3 * r]);
    }
  } else {
    smooth_ctx c;
    ctx_init(&c, xyz, NULL, o);
    c.n = count;
    c.stride = (int)nv;
    c.fits = (double *)values + 2; /* read only */
    c.h1 = o->h1;
    c.h2 = o->h2;
    c.inv_h1sq_global = 1.0 / (c.h1 * c.h1);
    c.rev_off = rev_off;
    c.rev = rev;
    c.self = point;
    c.cur = xyz;
    c.next = out_xyz;
    c.e2 = bsurf_alloc_array(local_count ? local_count : 1, sizeof(double));
    c.w2 = bsurf_alloc_array(local_count ? local_count : 1, sizeof(double));
    if (!c.e2 || !c.w2) st = BSURF_ERR_NOMEM;
    c.noise = noise;
    for (size_t i = 0; i < local_count && st == BSURF_OK; i++)
      set_theta2(&c, i, values[i * nv + (size_t)wc], &values[i * nv + nv - BSURF_SMOOTH_SV]);
    if (st == BSURF_OK)
      st = bsurf_parallel_sweep(count, bsurf_threads_resolve(o->error.threads),
                                gather_bilateral_task, &c);
    c.fits = NULL;
    c.rev_off = NULL;
    c.rev = NULL;
    ctx_free(&c, 0);
  }
  for (size_t r = 0; r < count && st == BSURF_OK; r++)
    moved[r] = moved_of(&xyz[3 * (point ? (size_t)point[r] : r)], &out_xyz[3 * r]);
  return st;
}
