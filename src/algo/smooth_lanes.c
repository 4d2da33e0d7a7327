/* The multipass passes' arithmetic (smooth_multipass.c): blocks of points
 * with the pairs in vector lanes, and time blocks of several passes per
 * region of points; the output is the point-by-point passes' bit for bit. */
#include "algo/smooth_ctx.h"
#include "search/search.h"
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

double bsurf_smooth_exp(double x) {
  return mp_exp1(x);
}

/* ---- multipass passes in blocks of points, pairs in vector lanes ------
 * The arithmetic of gather_update, operation for operation (no contraction),
 * arranged for throughput: a block's active pairs (p, i) are listed flat;
 * every pair's weight w and target x + delta n are computed four pairs at a
 * time in vector lanes (the exponential by glibc's exp per lane, as in
 * gather_update); then each point sums its pairs in its list's order. A
 * pair without a weight (theta beyond the cut, or p outside fit i's disc)
 * gets w = 0 and target 0: P (1 - 0), S + 0 and T + 0 x 0 leave the sums'
 * bits as they were (T starts at +0 and cannot become -0), so the output is
 * gather_update's, bit for bit. For the bases up to degree 3 (m <= 10) with
 * GCC/clang vector extensions; otherwise the passes use gather_update. */
#ifdef MP_LANES
typedef double mp_v4d __attribute__((vector_size(32)));
typedef long long mp_v4l __attribute__((vector_size(32)));
/* lanes of field k of the four records A[0..3] */
#define MP_GATHER(A, k) ((mp_v4d){(A)[0][k], (A)[1][k], (A)[2][k], (A)[3][k]})
/* mask ? a : b, lane by lane */
#define MP_SELECT(mask, a, b)                                                                      \
  ((mp_v4d)(((mp_v4l)(mask) & (mp_v4l)(a)) | (~(mp_v4l)(mask) & (mp_v4l)(b))))

/* out = mp_exp1(x) in four lanes (a statement: no vector-valued calls) */
#define MP_EXP4(out, x)                                                                            \
  do {                                                                                             \
    const mp_v4d magic_ = {MPX_MAGIC, MPX_MAGIC, MPX_MAGIC, MPX_MAGIC};                            \
    const mp_v4d t_ = (x)*MPX_LOG2E + magic_;                                                      \
    const mp_v4d n_ = t_ - magic_;                                                                 \
    const mp_v4d r_ = ((x)-n_ * MPX_LN2_HI) - n_ * MPX_LN2_LO;                                     \
    mp_v4d p_;                                                                                     \
    MPX_POLY(mp_v4d, p_, r_);                                                                      \
    const mp_v4l bits_ = ((mp_v4l)t_ - (mp_v4l)magic_ + 1023) * ((long long)1 << 52);              \
    (out) = p_ * (mp_v4d)bits_;                                                                    \
  } while (0)

/* w[e] and tg[3e..3e+2] of the pairs e0..e0+3 (lanes past np repeat pair e0
 * and are not stored): pair e is point pp[e] (its row in pos) with the
 * centre pi[e] (its row in pos) and that centre's fit record pf[e]; M = the
 * number of terms, a constant per call site. */
static inline __attribute__((always_inline)) void
mp_pairs4(const smooth_ctx *c, int M, const double *pos, const uint32_t *pi, const uint32_t *pf,
          const uint32_t *pp, size_t e0, size_t np, double *w, double *tg) {
  const double *X[4], *C[4], *F[4];
  const int L = np - e0 < 4 ? (int)(np - e0) : 4;
  for (int l = 0; l < 4; l++) {
    const size_t e = e0 + (size_t)(l < L ? l : 0);
    X[l] = &pos[3 * (size_t)pp[e]];
    C[l] = &pos[3 * (size_t)pi[e]];
    F[l] = &c->fits[(size_t)pf[e] * c->stride];
  }
  const mp_v4d x0 = MP_GATHER(X, 0), x1 = MP_GATHER(X, 1), x2 = MP_GATHER(X, 2);
  const mp_v4d c0 = MP_GATHER(C, 0), c1 = MP_GATHER(C, 1), c2 = MP_GATHER(C, 2);
  const mp_v4d d2 = (x0 - c0) * (x0 - c0) + (x1 - c1) * (x1 - c1) + (x2 - c2) * (x2 - c2);
  const mp_v4d e2 = MP_GATHER(F, FIT_HEAD + M), inv = MP_GATHER(F, FIT_HEAD + M + 1);
  const mp_v4d zero = {0, 0, 0, 0}, inf = {INFINITY, INFINITY, INFINITY, INFINITY};
  /* d > 0: e2 + d^2 / h1^2 (h1 = 0: infinite); d = 0: e2 */
  const mp_v4d ex = MP_SELECT(d2 > zero, MP_SELECT(inv > zero, e2 + d2 * inv, inf), e2);
  /* fit_delta */
  const mp_v4d q0 = x0 - MP_GATHER(F, 0), q1 = x1 - MP_GATHER(F, 1), q2 = x2 - MP_GATHER(F, 2);
  const mp_v4d lx = MP_GATHER(F, 3) * q0 + MP_GATHER(F, 4) * q1 + MP_GATHER(F, 5) * q2;
  const mp_v4d ly = MP_GATHER(F, 6) * q0 + MP_GATHER(F, 7) * q1 + MP_GATHER(F, 8) * q2;
  const mp_v4d n0 = MP_GATHER(F, 9), n1 = MP_GATHER(F, 10), n2 = MP_GATHER(F, 11);
  const mp_v4d lz = n0 * q0 + n1 * q1 + n2 * q2;
  const mp_v4d sc = MP_GATHER(F, 12);
  const mp_v4d u = lx * sc, v = ly * sc;
  const mp_v4d one = {1, 1, 1, 1};
  const mp_v4l outside = u * u + v * v > one;
  const mp_v4d uu = u * u, uv = u * v, vv = v * v;
  mp_v4d f = MP_GATHER(F, FIT_HEAD + 0);
  if (M > 1) f += MP_GATHER(F, FIT_HEAD + 1) * u + MP_GATHER(F, FIT_HEAD + 2) * v;
  if (M > 3)
    f += MP_GATHER(F, FIT_HEAD + 3) * uu + MP_GATHER(F, FIT_HEAD + 4) * uv +
         MP_GATHER(F, FIT_HEAD + 5) * vv;
  if (M > 6)
    f += MP_GATHER(F, FIT_HEAD + 6) * (uu * u) + MP_GATHER(F, FIT_HEAD + 7) * (uu * v) +
         MP_GATHER(F, FIT_HEAD + 8) * (u * vv) + MP_GATHER(F, FIT_HEAD + 9) * (vv * v);
  const mp_v4d delta = f - lz;
  const mp_v4d cut = {GAUSS_CUT, GAUSS_CUT, GAUSS_CUT, GAUSS_CUT};
  const mp_v4d bound = MP_GATHER(F, 13);
  const mp_v4l ok = (ex <= cut) & ~outside & (MP_SELECT(delta < zero, -delta, delta) <= bound);
  const mp_v4d t0 = MP_SELECT(ok, x0 + delta * n0, zero), t1 = MP_SELECT(ok, x1 + delta * n1, zero),
               t2 = MP_SELECT(ok, x2 + delta * n2, zero);
  /* d > 0: e^-ex (1 at ex = 0); d = 0: theta_2, kept in the record */
  const mp_v4d w2 = MP_GATHER(F, FIT_HEAD + M + 2);
  mp_v4d ee;
  MP_EXP4(ee, -ex);
  const mp_v4d we = MP_SELECT(ok, MP_SELECT(ex == zero, one, MP_SELECT(d2 == zero, w2, ee)), zero);
  for (int l = 0; l < L; l++) {
    w[e0 + (size_t)l] = we[l];
    tg[3 * (e0 + (size_t)l)] = t0[l];
    tg[3 * (e0 + (size_t)l) + 1] = t1[l];
    tg[3 * (e0 + (size_t)l) + 2] = t2[l];
  }
}

BSURF_CLONES
static void mp_pairs(const smooth_ctx *c, const double *pos, const uint32_t *pi, const uint32_t *pf,
                     const uint32_t *pp, size_t np, double *w, double *tg) {
#define MP_PAIRS(M)                                                                                \
  for (size_t e0 = 0; e0 < np; e0 += 4)                                                            \
  mp_pairs4(c, M, pos, pi, pf, pp, e0, np, w, tg)
  switch (c->m) {
  case 3: MP_PAIRS(3); break;
  case 6: MP_PAIRS(6); break;
  default: MP_PAIRS(10); break;
  }
#undef MP_PAIRS
}

/* The points of one pass as the blocks see them: the whole cloud (rows =
 * ranks, pairs = the compacted active lists) or a time block's local rows
 * (mp_tblock_task). */
typedef struct mp_view {
  const double *cur;   /* rows read */
  double *next;        /* rows written */
  size_t n;            /* rows computed */
  const size_t *off;   /* row p's pairs: off[p] .. off[p + 1] - 1 */
  const uint32_t *ctr; /* per pair: its centre's row in cur */
  const uint32_t *fit; /* per pair: its centre's fit record (the centre's rank) */
} mp_view;

/* Rows p0..p1-1 of a view, one block of a multipass pass; returns the
 * largest squared move, mx or above. */
static double mp_block(const smooth_ctx *c, const mp_view *v, size_t p0, size_t p1, int thread,
                       double mx) {
  uint32_t *pp = &c->mp_point[(size_t)thread * c->mp_cap];
  double *w = &c->mp_val[(size_t)thread * 4 * c->mp_cap], *tg = w + c->mp_cap;
  const size_t base = v->off[p0], np = v->off[p1] - base; /* the block's pairs, side by side */
  for (size_t p = p0, e = 0; p < p1; p++)
    for (size_t q = v->off[p]; q < v->off[p + 1]; q++)
      pp[e++] = (uint32_t)p;
  {
    /* ask for the records and positions of the next block's pairs now */
    const size_t q1 = p1 + MP_BLOCK < v->n ? p1 + MP_BLOCK : v->n;
    for (size_t e = v->off[p1], e1 = v->off[q1]; e < e1; e++) {
      const double *f = &c->fits[(size_t)v->fit[e] * c->stride];
      __builtin_prefetch(f);
      __builtin_prefetch(f + 8);
      __builtin_prefetch(f + 16);
      __builtin_prefetch(f + c->stride - 1);
      __builtin_prefetch(&v->cur[3 * (size_t)v->ctr[e]]);
    }
  }
  mp_pairs(c, v->cur, &v->ctr[base], &v->fit[base], pp, np, w, tg);
  size_t e = 0;
  for (size_t p = p0; p < p1; p++) {
    double P = 1.0, S = 0.0, T[3] = {0, 0, 0};
    for (size_t q = v->off[p]; q < v->off[p + 1]; q++, e++) {
      const double we = w[e];
      P *= 1.0 - we;
      S += we;
      for (int t = 0; t < 3; t++)
        T[t] += we * tg[3 * e + t];
    }
    double step2 = update_finish(&v->cur[3 * p], P, S, T, &v->next[3 * p]);
    if (step2 > mx) mx = step2;
  }
  return mx;
}

/* One block of points of a multipass pass over the whole cloud. */
void gather_multipass_block(void *vc, int thread, size_t blk) {
  smooth_ctx *c = vc;
  const size_t p0 = blk * MP_BLOCK, p1 = p0 + MP_BLOCK < c->n ? p0 + MP_BLOCK : c->n;
  const mp_view v = {c->cur, c->next, c->n, c->act_off, c->act, c->act};
  c->tmax[8 * thread] = mp_block(c, &v, p0, p1, thread, c->tmax[8 * thread]);
}

/* ---- multipass time blocks: several passes per cache-sized region ------
 * A pass maps the positions x^t to x^(t+1); point p's x^(t+1) reads only
 * x^t at p and at the centres i of p's active pairs (and the fixed records
 * of those i). So s passes over a region R of MP_REGION consecutive ranks
 * (Morton order) need x^(t+s-1) on R, x^(t+s-2) on R and its pairs'
 * centres, and so on: levels of halo, each the centres of the level
 * before's pairs. A block reads x^t of all these rows from the whole
 * cloud's array, computes every pass on its own local rows (the halo rows
 * again, as their owners do: the same inputs give the same bits) while the
 * region's records stay in cache, and writes x^(t+s) of R only. Every row
 * is computed by mp_block with its pairs in its list's order, so the output
 * is the pass-by-pass output bit for bit, for any thread count (regions
 * read x^t and write disjoint rows of x^(t+s)).
 * The active lists must hold every pair with a weight at every pass of a
 * block; the lists are only a superset of those pairs (a listed pair
 * without a weight adds exactly nothing), so rebuilding them earlier than
 * the pass-by-pass loop would does not change the output. A block is
 * therefore run only when the points are expected to stay within the
 * margin, and is discarded and run again after a rebuild if they did not.
 * Blocks are kept to the passes whose halo rows are at most a tenth of the
 * rows computed (mp_regions_build): wide halos cost more than the cache
 * gives. */

/* *a with room for `need` elements of `size` bytes (grown by half); NULL
 * (and *a untouched) when memory is short. */
static void *mp_grow(void *a, size_t *cap, size_t need, size_t size) {
  if (need <= *cap) return a;
  const size_t nc = need + need / 2 + 64;
  void *b = realloc(a, nc * size);
  if (b) *cap = nc;
  return b;
}

/* Region r's rows and pairs for blocks of up to tb_S passes, from the
 * compacted active lists: its own ranks, then the centres of their pairs
 * (the rows pass S - 1 must give), then the centres of those rows' pairs,
 * and so on down to the rows a block reads (level 0). */
static void mp_region_task(void *vc, int thread, size_t r) {
  smooth_ctx *c = vc;
  mp_region *g = &c->reg[r];
  uint32_t *map = &c->lmap[(size_t)thread * c->n];
  const int S = c->tb_S;
  const size_t r0 = r * MP_REGION, r1 = r0 + MP_REGION < c->n ? r0 + MP_REGION : c->n;
  size_t nrow = 0, np = 0;
  void *q;
  g->failed = 1;
  if (!(q = mp_grow(g->row, &g->row_cap, r1 - r0, sizeof *g->row))) return;
  g->row = q;
  for (size_t p = r0; p < r1; p++) {
    map[p] = (uint32_t)nrow;
    g->row[nrow++] = (uint32_t)p;
  }
  g->len[S] = nrow;
  size_t beg = 0;
  for (int j = S - 1; j >= 0; j--) {
    const size_t end = nrow;
    for (size_t l = beg; l < end; l++)
      for (size_t e = c->act_off[g->row[l]]; e < c->act_off[g->row[l] + 1]; e++) {
        const uint32_t i = c->act[e];
        if (map[i] != UINT32_MAX) continue;
        if (!(q = mp_grow(g->row, &g->row_cap, nrow + 1, sizeof *g->row))) goto out;
        g->row = q;
        map[i] = 0; /* seen; its row is set below */
        g->row[nrow++] = i;
      }
    qsort(&g->row[end], nrow - end, sizeof *g->row, bsurf_cmp_u32);
    for (size_t l = end; l < nrow; l++)
      map[g->row[l]] = (uint32_t)l;
    g->len[j] = nrow;
    beg = end;
  }
  const size_t nc = g->len[1];
  for (size_t l = 0; l < nc; l++)
    np += c->act_off[g->row[l] + 1] - c->act_off[g->row[l]];
  if (!(q = mp_grow(g->off, &g->off_cap, nc + 1, sizeof *g->off))) goto out;
  g->off = q;
  /* two capacities: a shared one, reset before growing fit, let a later,
   * larger np skip growing ctr past its real size (found by ASan) */
  if (!(q = mp_grow(g->ctr, &g->ctr_cap, np ? np : 1, sizeof *g->ctr))) goto out;
  g->ctr = q;
  if (!(q = mp_grow(g->fit, &g->fit_cap, np ? np : 1, sizeof *g->fit))) goto out;
  g->fit = q;
  np = 0;
  for (size_t l = 0; l < nc; l++) {
    g->off[l] = np;
    for (size_t e = c->act_off[g->row[l]]; e < c->act_off[g->row[l] + 1]; e++, np++) {
      g->ctr[np] = map[c->act[e]];
      g->fit[np] = c->act[e];
    }
  }
  g->off[nc] = np;
  g->sub_max = 0;
  for (size_t l = 0; l < nc; l += MP_BLOCK) {
    const size_t l1 = l + MP_BLOCK < nc ? l + MP_BLOCK : nc;
    if (g->off[l1] - g->off[l] > g->sub_max) g->sub_max = g->off[l1] - g->off[l];
  }
  g->failed = 0;
out:
  for (size_t l = 0; l < nrow; l++)
    map[g->row[l]] = UINT32_MAX;
}

/* One region's block of tb_s passes (the last tb_s of the tb_S it is built
 * for): x^t of the rows it reads, then pass after pass on the local rows,
 * the last one written to the region's own rows of `next`. */
void mp_tblock_task(void *vc, int thread, size_t r) {
  smooth_ctx *c = vc;
  const mp_region *g = &c->reg[r];
  const int S = c->tb_S, j0 = S - c->tb_s;
  double *a = &c->tb_pos[(size_t)thread * 6 * c->tb_cap], *b = a + 3 * c->tb_cap;
  double *step = &c->tb_step[(size_t)thread * MP_TSTRIDE];
  for (size_t l = 0; l < g->len[j0]; l++)
    memcpy(&a[3 * l], &c->cur[3 * (size_t)g->row[l]], 3 * sizeof(double));
  for (int j = j0 + 1; j <= S; j++) {
    const mp_view v = {
        a, j == S ? &c->next[3 * (size_t)g->row[0]] : b, g->len[j], g->off, g->ctr, g->fit};
    double mx = step[j - j0 - 1];
    for (size_t p0 = 0; p0 < v.n; p0 += MP_BLOCK)
      mx = mp_block(c, &v, p0, p0 + MP_BLOCK < v.n ? p0 + MP_BLOCK : v.n, thread, mx);
    step[j - j0 - 1] = mx;
    double *t = a;
    a = b;
    b = t;
  }
}

/* The regions for the current active lists (after a rebuild); room in the
 * per-thread scratch for their rows and blocks. */
bsurf_status mp_regions_build(smooth_ctx *c, int T) {
  bsurf_status st = bsurf_parallel_sweep_chunk(c->nreg, T, 1, mp_region_task, c);
  size_t rows = 0, sub = c->mp_cap;
  for (size_t r = 0; r < c->nreg && st == BSURF_OK; r++) {
    if (c->reg[r].failed) return BSURF_ERR_NOMEM;
    if (c->reg[r].len[0] > rows) rows = c->reg[r].len[0];
    if (c->reg[r].sub_max > sub) sub = c->reg[r].sub_max;
  }
  if (st != BSURF_OK) return st;
  /* blocks of at most tb_max passes: the halo rows they compute again are
   * at most a tenth of the rows (many pairs per point, as with h2 = 1W,
   * give wide halos: there the blocks would cost more than the cache gives) */
  c->tb_max = 1;
  for (int s = 2; s <= c->tb_S; s++) {
    size_t rows_s = 0;
    for (size_t r = 0; r < c->nreg; r++)
      for (int j = c->tb_S - s + 1; j <= c->tb_S; j++)
        rows_s += c->reg[r].len[j];
    if (!c->tune.any_halo && (double)rows_s > 1.1 * (double)s * (double)c->n) break;
    c->tb_max = s;
  }
  if (sub > c->mp_cap) {
    free(c->mp_point);
    free(c->mp_val);
    c->mp_cap = sub;
    c->mp_point = bsurf_alloc_array((size_t)T * sub, sizeof(uint32_t));
    c->mp_val = bsurf_alloc_array((size_t)T * 4 * sub, sizeof(double));
    if (!c->mp_point || !c->mp_val) return BSURF_ERR_NOMEM;
  }
  if (rows > c->tb_cap) {
    free(c->tb_pos);
    c->tb_cap = rows;
    c->tb_pos = bsurf_alloc_array((size_t)T * 6 * rows, sizeof(double));
    if (!c->tb_pos) return BSURF_ERR_NOMEM;
  }
  return BSURF_OK;
}
#endif
