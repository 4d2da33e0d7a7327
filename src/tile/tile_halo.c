/* One tile of the tile engine (src/tile/tiles.c): its points and the
 * halo that proves their K-neighbourhoods, the reverse neighbours of a
 * second stage, the run of the command's computation. */
#define _DEFAULT_SOURCE /* madvise */

#include "tile/tile_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- one tile ------------------------------------------------------------------- */

size_t find_u64(const uint64_t *v, size_t n, uint64_t x) {
  size_t lo = 0, hi = n;
  while (lo < hi) {
    size_t mid = lo + (hi - lo) / 2;
    if (v[mid] < x)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo;
}

typedef struct u64vec {
  uint64_t *v;
  size_t n, cap;
} u64vec;

static int u64_push(u64vec *a, uint64_t x) {
  if (a->n == a->cap) {
    size_t nc = a->cap ? 2 * a->cap : 1024;
    uint64_t *nv = realloc(a->v, nc * sizeof *nv);
    if (!nv) return -1;
    a->v = nv;
    a->cap = nc;
  }
  a->v[a->n++] = x;
  return 0;
}

typedef struct search_ctx {
  const tiles_ctx *c;
  const uint64_t *G; /* loaded points, increasing global index */
  const double *gx;  /* their coordinates */
  size_t m;
  const bsurf_knn_index *index;
  const uint64_t *core; /* the points searched (the tile's, and in reverse mode its candidates) */
  size_t *pending;      /* their positions to search */
  double rlo[3], rhi[3];
  int complete;   /* the region holds the whole cloud */
  uint32_t *rows; /* core x k positions in G (remapped when G grows) */
  double *nn2;    /* core */
  double *kth2;   /* core: squared distance to the K-th (the row's last) */
  uint8_t *done, *dup;
  uint32_t *qidx; /* threads x k */
  double *qd2;    /* threads x k */
} search_ctx;

/* The row of one pending core point, kept when its ball is inside R. */
static void search_point(void *vctx, int thread, size_t t) {
  search_ctx *s = vctx;
  const int k = s->c->k;
  size_t j = s->pending[t];
  size_t self = find_u64(s->G, s->m, s->core[j]);
  if (self >= s->m || s->G[self] != s->core[j]) return; /* not loaded yet: a wider region */
  const double *p = s->gx + 3 * self;
  uint32_t *qi = s->qidx + (size_t)thread * (size_t)k;
  double *qd = s->qd2 + (size_t)thread * (size_t)k;
  bsurf_knn_query(s->index, p, k, qi, qd);
  /* the all-kNN row: the point, then the k - 1 nearest others (the query
   * returns the k nearest of all; the point itself is among them unless k
   * of its duplicates have smaller indices) */
  uint32_t *row = s->rows + j * (size_t)k;
  double r2 = 0, first = 0;
  int c = 1, seen_self = 0;
  row[0] = (uint32_t)self;
  for (int q = 0; q < k && c < k; q++) {
    if (!seen_self && qi[q] == self) {
      seen_self = 1;
      continue;
    }
    if (c == 1) first = qd[q];
    row[c++] = qi[q];
    r2 = qd[q];
  }
  int ok = s->complete;
  if (!ok) {
    ok = 1;
    double need = r2 * (1 + 1e-9);
    for (int a = 0; a < 3 && ok; a++) {
      double g1 = p[a] - s->rlo[a], g2 = s->rhi[a] - p[a];
      ok = g1 >= 0 && g2 >= 0 && g1 * g1 >= need && g2 * g2 >= need;
    }
  }
  if (!ok) return;
  s->done[j] = 1;
  s->nn2[j] = k > 1 ? first : 0.0;
  s->kth2[j] = r2;
  if (k > 1) {
    const double *q = s->gx + 3 * (size_t)row[1];
    s->dup[j] = p[0] == q[0] && p[1] == q[1] && p[2] == q[2];
  }
}

/* Loads every point inside R (closed) or in the tile's cells, in increasing
 * index order. */
static bsurf_status gather(const tiles_ctx *c, const tile_box *b, const double rlo[3],
                           const double rhi[3], u64vec *G) {
  uint32_t clo[3], chi[3];
  for (int a = 0; a < 3; a++) {
    double tl = floor((rlo[a] - c->origin[a]) / c->cell) - 1,
           th = floor((rhi[a] - c->origin[a]) / c->cell) + 2;
    clo[a] = !(tl > 0) ? 0 : tl >= c->dim[a] ? c->dim[a] : (uint32_t)tl;
    chi[a] = !(th > 0) ? 0 : th >= c->dim[a] ? c->dim[a] : (uint32_t)th;
    if (clo[a] > b->lo[a]) clo[a] = b->lo[a];
    if (chi[a] < b->hi[a]) chi[a] = b->hi[a];
  }
  const uint64_t *sorted = (const uint64_t *)c->sorted.data;
  G->n = 0;
  u64vec cand = {NULL, 0, 0}; /* points of the cells around the tile */
  double p[3];
  for (uint32_t z = clo[2]; z < chi[2]; z++)
    for (uint32_t y = clo[1]; y < chi[1]; y++)
      for (uint32_t x = clo[0]; x < chi[0]; x++) {
        uint32_t cc[3] = {x, y, z};
        size_t j = cell_id(c, cc);
        int in_tile = x >= b->lo[0] && x < b->hi[0] && y >= b->lo[1] && y < b->hi[1] &&
                      z >= b->lo[2] && z < b->hi[2];
        for (uint64_t s = c->cell_start[j]; s < c->cell_start[j + 1]; s++) {
          if (u64_push(in_tile ? G : &cand, sorted[s])) {
            free(cand.v);
            return BSURF_ERR_NOMEM;
          }
        }
      }
  /* those inside R, read in file order */
  if (cand.n > 1) qsort(cand.v, cand.n, sizeof *cand.v, bsurf_cmp_u64);
  sweep sw = {&c->in, 0};
  for (size_t j = 0; j < cand.n; j++) {
    uint64_t i = cand.v[j];
    xyz_of(c, i, p);
    sweep_at(&sw, c->layout.body + (size_t)i * c->layout.record);
    if (p[0] >= rlo[0] && p[0] <= rhi[0] && p[1] >= rlo[1] && p[1] <= rhi[1] && p[2] >= rlo[2] &&
        p[2] <= rhi[2] && u64_push(G, i)) {
      free(cand.v);
      return BSURF_ERR_NOMEM;
    }
  }
  free(cand.v);
  drop_pages(&c->in, 0, c->in.size);
  if (G->n > 1) qsort(G->v, G->n, sizeof *G->v, bsurf_cmp_u64);
  return BSURF_OK;
}

typedef struct tile_work {
  u64vec core, G;
  u64vec cand, S; /* reverse mode: candidates; the points searched (core + candidates) */
  double *gx;
  uint32_t *rows; /* S x k positions in G */
  double *nn2, *kth2;
  size_t *cpos; /* core j -> its position in S */
  size_t *rev_off;
  uint32_t *rev;
  double *lvals, *vout, *vblock; /* values_in of the local points; values_out; the block's */
  uint8_t *done, *dup, *mark;
  size_t *pending;
  uint32_t *qidx;
  double *qd2;
  uint32_t *local;  /* G position -> local index */
  uint32_t *coreof; /* reverse: G position -> core index, or UINT32_MAX */
  double *lxyz;
  uint32_t *idx;
  unsigned char *enc;
  bsurf_knn_index *index; /* the last region's tree, between searches */
  size_t nring;           /* ring points: S's last, after the core's (and candidates') */
} tile_work;

static void work_free(tile_work *w) {
  free(w->core.v);
  free(w->G.v);
  free(w->cand.v);
  free(w->S.v);
  free(w->gx);
  free(w->rows);
  free(w->nn2);
  free(w->kth2);
  free(w->cpos);
  free(w->rev_off);
  free(w->rev);
  free(w->lvals);
  free(w->vout);
  free(w->vblock);
  free(w->done);
  free(w->dup);
  free(w->mark);
  free(w->pending);
  free(w->qidx);
  free(w->qd2);
  free(w->local);
  free(w->coreof);
  free(w->lxyz);
  free(w->idx);
  free(w->enc);
  bsurf_knn_free(w->index);
  memset(w, 0, sizeof *w);
}

/* ---- reverse neighbours (the second stage of a two-stage run) ------------- */

/* A bound on how far a point can lie outside the box of its cell (the
 * rounding of floor((p - origin) / cell)), used with a relative margin of
 * 1e-9 on the distances. */
static double cell_slack(const tiles_ctx *c) {
  double m = 0;
  for (int a = 0; a < 3; a++)
    m = fmax(m, fmax(fabs(c->lo[a]), fabs(c->hi[a])));
  return 1e-9 * c->cell + 1e-12 * m;
}

/* The extent on axis a of the cells [lo, hi), widened by slack; the outer
 * cells reach to infinity (the grid clamps points beyond it into them). */
static void cells_span(const tiles_ctx *c, int a, uint32_t lo, uint32_t hi, double slack,
                       double *blo, double *bhi) {
  *blo = lo == 0 ? -INFINITY : c->origin[a] + c->cell * lo - slack;
  *bhi = hi >= c->dim[a] ? INFINITY : c->origin[a] + c->cell * hi + slack;
}

/* Squared distance from p to a box (0 inside). */
static double box_dist2(const double p[3], const double lo[3], const double hi[3]) {
  double d2 = 0;
  for (int a = 0; a < 3; a++) {
    double g = fmax(0.0, fmax(lo[a] - p[a], p[a] - hi[a]));
    d2 += g * g;
  }
  return d2;
}

static double values_kth2(const tiles_ctx *c, uint64_t i) {
  const double *v = (const double *)c->vin.data;
  return v[(size_t)i * c->vin_cols + c->vin_cols - 1];
}

/* Before the tiles of a reverse run: per cell, the largest squared distance
 * r_i^2 from a point i to its K-th neighbour (the first stage's last
 * column), streaming the input and the values in index order. */
bsurf_status cell_maxima(tiles_ctx *c) {
  c->cellmax = bsurf_calloc_array(c->cells, sizeof *c->cellmax);
  if (!c->cellmax) return BSURF_ERR_NOMEM;
  double p[3];
  uint32_t cc[3];
  bsurf_status st = BSURF_OK;
  for (size_t i = 0; i < c->n && st == BSURF_OK; i++) {
    double r2 = values_kth2(c, i);
    xyz_of(c, i, p);
    cell_coords(c, p, cc);
    size_t j = cell_id(c, cc);
    if (!(r2 >= 0)) st = BSURF_ERR_INVALID_VALUE; /* not a first stage of this input */
    if (r2 > c->cellmax[j]) c->cellmax[j] = r2;
    if (r2 > c->rmax2) c->rmax2 = r2;
    if ((i + 1) % PASS_DROP == 0) {
      drop_pages(&c->in, 0, c->in.size);
      drop_pages(&c->vin, 0, c->vin.size);
      if (pass_cancelled(c)) st = BSURF_ERR_CANCELLED;
    }
  }
  drop_pages(&c->in, 0, c->in.size);
  drop_pages(&c->vin, 0, c->vin.size);
  return st;
}

/* The points outside tile b whose K-neighbourhood can contain a point of
 * the tile: p in N_K(i) gives |p - i| <= r_i, and p lies in the tile's
 * cells, so dist(i, tile) <= r_i. Cells farther from the tile than the
 * largest r_i of their points are skipped, then every point of the others
 * is tested with its own r_i. A superset (margins for rounding): the exact
 * K-neighbourhoods of the candidates, searched with the tile's, decide.
 * *r2max: the candidates' largest r_i^2. */
static bsurf_status reverse_candidates(const tiles_ctx *c, const tile_box *b, u64vec *cand,
                                       double *r2max) {
  const double slack = cell_slack(c), reach = sqrt(c->rmax2) * (1 + 1e-9) + 2 * slack;
  double blo[3], bhi[3];
  uint32_t clo[3], chi[3];
  for (int a = 0; a < 3; a++) {
    cells_span(c, a, b->lo[a], b->hi[a], slack, &blo[a], &bhi[a]);
    double w = ceil(reach / c->cell) + 1, l = (double)b->lo[a] - w, h = (double)b->hi[a] + w;
    clo[a] = l > 0 ? (uint32_t)l : 0;
    chi[a] = h < (double)c->dim[a] ? (uint32_t)h : c->dim[a];
  }
  const uint64_t *sorted = (const uint64_t *)c->sorted.data;
  cand->n = 0;
  *r2max = 0;
  for (uint32_t z = clo[2]; z < chi[2]; z++)
    for (uint32_t y = clo[1]; y < chi[1]; y++)
      for (uint32_t x = clo[0]; x < chi[0]; x++) {
        uint32_t cc[3] = {x, y, z};
        size_t j = cell_id(c, cc);
        if (c->cell_start[j] == c->cell_start[j + 1]) continue;
        if (x >= b->lo[0] && x < b->hi[0] && y >= b->lo[1] && y < b->hi[1] && z >= b->lo[2] &&
            z < b->hi[2])
          continue; /* the tile's own */
        double d2 = 0;
        for (int a = 0; a < 3; a++) {
          double lo, hi;
          cells_span(c, a, cc[a], cc[a] + 1, slack, &lo, &hi);
          double g = fmax(0.0, fmax(lo - bhi[a], blo[a] - hi));
          d2 += g * g;
        }
        double r = sqrt(c->cellmax[j]) * (1 + 1e-9) + slack;
        if (d2 > r * r) continue;
        for (uint64_t s = c->cell_start[j]; s < c->cell_start[j + 1]; s++)
          if (u64_push(cand, sorted[s])) return BSURF_ERR_NOMEM;
      }
  if (cand->n > 1) qsort(cand->v, cand->n, sizeof *cand->v, bsurf_cmp_u64);
  sweep sw = {&c->in, 0}, sv = {&c->vin, 0};
  size_t kept = 0;
  for (size_t q = 0; q < cand->n; q++) {
    uint64_t i = cand->v[q];
    double p[3], r2 = values_kth2(c, i);
    xyz_of(c, i, p);
    sweep_at(&sw, c->layout.body + (size_t)i * c->layout.record);
    sweep_at(&sv, (size_t)i * c->vin_cols * sizeof(double));
    double r = sqrt(r2) * (1 + 1e-9) + slack;
    if (box_dist2(p, blo, bhi) <= r * r) {
      cand->v[kept++] = i;
      if (r2 > *r2max) *r2max = r2;
    }
  }
  cand->n = kept;
  drop_pages(&c->vin, 0, c->vin.size);
  return BSURF_OK;
}

/* The rows found so far, from positions in w->G to positions in G (a
 * region that holds w->G's: both in increasing index, merged), and G made
 * w->G (G emptied). */
static bsurf_status remap_rows(const tiles_ctx *c, tile_work *w, u64vec *G) {
  const size_t k = (size_t)c->k;
  uint32_t *to = NULL;
  if (w->G.n) {
    if (!(to = bsurf_alloc_array(w->G.n, sizeof *to))) return BSURF_ERR_NOMEM;
    for (size_t i = 0, p = 0; i < w->G.n; i++) {
      while (p < G->n && G->v[p] < w->G.v[i])
        p++;
      assert(p < G->n && G->v[p] == w->G.v[i]);
      to[i] = (uint32_t)p;
    }
    for (size_t q = 0; q < w->S.n; q++)
      if (w->done[q])
        for (size_t e = 0; e < k; e++)
          w->rows[q * k + e] = to[w->rows[q * k + e]];
  }
  free(to);
  free(w->G.v);
  w->G = *G;
  memset(G, 0, sizeof *G);
  return BSURF_OK;
}

/* Searches the points of w->S at w->pending[0 .. npend) in regions of
 * growing halo (doubled from *halo) until every row is proven. The last
 * region's points, coordinates and tree stay in w; a next call (the ring)
 * searches in them first. *grown: 1 if the halo had to widen. */
static bsurf_status search_rounds(const tiles_ctx *c, const tile_box *b, tile_work *w, size_t npend,
                                  const double box_lo[3], const double box_hi[3], double *halo,
                                  int T, int *grown) {
  *grown = 0;
  for (;;) {
    search_ctx s;
    memset(&s, 0, sizeof s);
    s.complete = 1;
    for (int a = 0; a < 3; a++) {
      s.rlo[a] = box_lo[a] - *halo;
      s.rhi[a] = box_hi[a] + *halo;
      if (s.rlo[a] > c->lo[a] || s.rhi[a] < c->hi[a]) s.complete = 0;
    }
    if (!w->index) { /* the region's points and their tree */
      u64vec G = {NULL, 0, 0};
      bsurf_status st = gather(c, b, s.rlo, s.rhi, &G);
      if (st == BSURF_OK) st = remap_rows(c, w, &G);
      free(G.v);
      if (st != BSURF_OK) return st;
      free(w->gx);
      w->gx = bsurf_alloc_array(w->G.n, 3 * sizeof *w->gx);
      if (!w->gx) return BSURF_ERR_NOMEM;
      sweep sw = {&c->in, 0};
      for (size_t j = 0; j < w->G.n; j++) {
        xyz_of(c, w->G.v[j], w->gx + 3 * j);
        sweep_at(&sw, c->layout.body + (size_t)w->G.v[j] * c->layout.record);
      }
      drop_pages(&c->in, 0, c->in.size);
      st = bsurf_knn_build(&w->index, w->gx, w->G.n);
      if (st != BSURF_OK) return st;
    }
    s.c = c;
    s.G = w->G.v;
    s.gx = w->gx;
    s.m = w->G.n;
    s.index = w->index;
    s.core = w->S.v;
    s.pending = w->pending;
    s.rows = w->rows;
    s.nn2 = w->nn2;
    s.kth2 = w->kth2;
    s.done = w->done;
    s.dup = w->dup;
    s.qidx = w->qidx;
    s.qd2 = w->qd2;
    bsurf_parallel_sweep(npend, T, search_point, &s);
    size_t left = 0;
    for (size_t q = 0; q < npend; q++)
      if (!w->done[w->pending[q]]) w->pending[left++] = w->pending[q];
    npend = left;
    if (npend == 0) return BSURF_OK;
    assert(!s.complete);
    *grown = 1;
    *halo *= 2;
    bsurf_knn_free(w->index);
    w->index = NULL;
  }
}

static int u64_grow(void **p, size_t n, size_t size) {
  void *q = realloc(*p, (n ? n : 1) * size);
  if (!q) return -1;
  *p = q;
  return 0;
}

/* A ring of ops->ring_k: the distinct points outside the tile and the
 * rings so far (w->S from ns on) among the first ring_k entries of the rows
 * of the points whose ring it is (the core's, or S's [from, to): the
 * previous ring's), appended to w->S in increasing index, with room for
 * their rows and pending (their positions) to search them. *added: how many. */
static bsurf_status ring_points(const tiles_ctx *c, tile_work *w, size_t nc, size_t ns, size_t from,
                                size_t to, size_t *added) {
  const size_t k = (size_t)c->k, rk = (size_t)(c->ops->ring_k < c->k ? c->ops->ring_k : c->k);
  const size_t m = w->G.n, have = w->S.n;
  u64vec ring = {NULL, 0, 0}; /* positions in G */
  uint8_t *seen = bsurf_calloc_array(m ? m : 1, 1);
  if (!seen) return BSURF_ERR_NOMEM;
  for (size_t j = 0; j < nc; j++) /* a row's point is its first entry */
    seen[w->rows[w->cpos[j] * k]] = 1;
  for (size_t q = ns; q < have; q++)
    seen[w->rows[q * k]] = 1;
  const size_t nsrc = from < to ? to - from : nc;
  for (size_t j = 0; j < nsrc; j++) {
    const uint32_t *row = &w->rows[(from < to ? from + j : w->cpos[j]) * k];
    for (size_t e = 1; e < rk; e++) {
      if (seen[row[e]]) continue;
      seen[row[e]] = 1;
      if (u64_push(&ring, row[e])) {
        free(seen);
        free(ring.v);
        return BSURF_ERR_NOMEM;
      }
    }
  }
  free(seen);
  if (ring.n > 1) qsort(ring.v, ring.n, sizeof *ring.v, bsurf_cmp_u64); /* = index order */
  const size_t nr = ring.n, all = have + nr;
  if (u64_grow((void **)&w->S.v, all, sizeof *w->S.v) ||
      u64_grow((void **)&w->rows, all, k * sizeof *w->rows) ||
      u64_grow((void **)&w->nn2, all, sizeof *w->nn2) ||
      u64_grow((void **)&w->kth2, all, sizeof *w->kth2) || u64_grow((void **)&w->done, all, 1) ||
      u64_grow((void **)&w->dup, all, 1) ||
      u64_grow((void **)&w->pending, all, sizeof *w->pending)) {
    free(ring.v);
    return BSURF_ERR_NOMEM;
  }
  for (size_t q = 0; q < nr; q++) {
    w->S.v[have + q] = w->G.v[ring.v[q]];
    w->done[have + q] = w->dup[have + q] = 0;
    w->pending[q] = have + q;
  }
  w->S.n = w->S.cap = all;
  w->nring += nr;
  *added = nr;
  free(ring.v);
  return BSURF_OK;
}

/* The exact K-neighbourhoods of a tile's points (growing the halo until they
 * are proven), then the command's run and the output rows. In reverse mode
 * the candidates of reverse_candidates are searched with them, and the
 * reverse lists follow from their exact rows. */
bsurf_status do_tile(tiles_ctx *c, size_t t, bsurf_tile_report *rep, bsurf_failure *err) {
  const tile_box *b = &c->tiles[t];
  const int k = c->k;
  const int T = bsurf_threads_resolve(c->ops->threads);
  const uint64_t *sorted = (const uint64_t *)c->sorted.data;
  tile_work w;
  memset(&w, 0, sizeof w);
  bsurf_status st = BSURF_OK;
  bsurf_cloud core;
  bsurf_cloud_init(&core);

  for (uint32_t z = b->lo[2]; z < b->hi[2] && st == BSURF_OK; z++)
    for (uint32_t y = b->lo[1]; y < b->hi[1] && st == BSURF_OK; y++)
      for (uint32_t x = b->lo[0]; x < b->hi[0] && st == BSURF_OK; x++) {
        uint32_t cc[3] = {x, y, z};
        size_t j = cell_id(c, cc);
        for (uint64_t s = c->cell_start[j]; s < c->cell_start[j + 1]; s++)
          if (u64_push(&w.core, sorted[s])) st = BSURF_ERR_NOMEM;
      }
  double r2cand = 0;
  if (st == BSURF_OK && c->ops->reverse) st = reverse_candidates(c, b, &w.cand, &r2cand);
  if (st != BSURF_OK) goto out;
  /* searched in cell order (neighbouring queries share the tree's leaves),
   * stored in index order */
  uint64_t *by_cell = bsurf_alloc_array(w.core.n, sizeof *by_cell);
  if (!by_cell) {
    st = BSURF_ERR_NOMEM;
    goto out;
  }
  if (w.core.n) memcpy(by_cell, w.core.v, w.core.n * sizeof *by_cell);
  if (w.core.n > 1) qsort(w.core.v, w.core.n, sizeof *w.core.v, bsurf_cmp_u64);
  const size_t nc = w.core.n, ns = nc + w.cand.n;
  /* the points searched: the core and the candidates (outside the tile's
   * cells: disjoint), in increasing index */
  w.S.v = bsurf_alloc_array(ns, sizeof *w.S.v);
  w.rows = bsurf_alloc_array(ns, (size_t)k * sizeof *w.rows);
  w.nn2 = bsurf_alloc_array(ns, sizeof *w.nn2);
  w.kth2 = bsurf_alloc_array(ns, sizeof *w.kth2);
  w.done = bsurf_calloc_array(ns, 1);
  w.dup = bsurf_calloc_array(ns, 1);
  w.pending = bsurf_alloc_array(ns, sizeof *w.pending);
  w.cpos = bsurf_alloc_array(nc, sizeof *w.cpos);
  w.qidx = bsurf_alloc_array((size_t)T, (size_t)k * sizeof *w.qidx);
  w.qd2 = bsurf_alloc_array((size_t)T, (size_t)k * sizeof *w.qd2);
  if (!w.S.v || !w.rows || !w.nn2 || !w.kth2 || !w.done || !w.dup || !w.pending || !w.cpos ||
      !w.qidx || !w.qd2) {
    free(by_cell);
    st = BSURF_ERR_NOMEM;
    goto out;
  }
  for (size_t q = 0, a = 0, e = 0; q < ns; q++)
    w.S.v[q] =
        e >= w.cand.n || (a < nc && w.core.v[a] < w.cand.v[e]) ? w.core.v[a++] : w.cand.v[e++];
  w.S.n = w.S.cap = ns;
  size_t npend = ns;
  for (size_t j = 0; j < nc; j++)
    w.pending[j] = find_u64(w.S.v, ns, by_cell[j]);
  for (size_t q = 0; q < w.cand.n; q++)
    w.pending[nc + q] = find_u64(w.S.v, ns, w.cand.v[q]);
  for (size_t j = 0; j < nc; j++)
    w.cpos[j] = find_u64(w.S.v, ns, w.core.v[j]);
  free(by_cell);

  /* the candidates lie within r_i of the tile and their balls within 2 r_i:
   * a halo that holds them at once (a narrower one is only slower) */
  double halo = c->cell, box_lo[3], box_hi[3];
  if (w.cand.n) halo = fmax(halo, 2 * sqrt(r2cand) * (1 + 1e-6) + 4 * cell_slack(c));
  for (int a = 0; a < 3; a++) {
    box_lo[a] = c->origin[a] + c->cell * b->lo[a];
    box_hi[a] = c->origin[a] + c->cell * b->hi[a];
  }
  int grown = 0;
  st = search_rounds(c, b, &w, npend, box_lo, box_hi, &halo, T, &grown);
  if (st != BSURF_OK) goto out;
  if (grown) rep->halo_grown++;
  /* the ring (ops->ring_k): the points outside the tile among the first
   * ring_k of the core's rows, searched after the core (the region and
   * tree of its last round first), their rows after the core's */
  size_t inner = 0, last = 0; /* the first ring's points, the last ring's */
  for (int d = 0, rings = c->ops->rings > 1 ? c->ops->rings : 1; c->ops->ring_k > 0 && d < rings;
       d++) {
    if (d && !last) break; /* no ring beyond an empty one */
    const size_t to = ns + w.nring, from = to - last;
    st = ring_points(c, &w, nc, ns, from, to, &last);
    if (st == BSURF_OK && last)
      st = search_rounds(c, b, &w, last, box_lo, box_hi, &halo, T, &grown);
    if (st != BSURF_OK) goto out;
    if (d == 0) inner = last;
  }
  bsurf_knn_free(w.index);
  w.index = NULL;
  const size_t nr = w.nring;

  /* The tile's cloud: its points, every neighbour they use and, in reverse
   * mode, every point whose row contains one of them, in increasing global
   * index (a subset of the last region's points). */
  const size_t m = w.G.n;
  w.mark = bsurf_calloc_array(m, 1);
  w.local = bsurf_alloc_array(m, sizeof *w.local);
  w.idx = bsurf_alloc_array(nc + nr, (size_t)k * sizeof *w.idx);
  if (c->ops->reverse) w.rev_off = bsurf_calloc_array(nc + 1, sizeof *w.rev_off);
  if (!w.mark || !w.local || !w.idx || (c->ops->reverse && !w.rev_off)) {
    st = BSURF_ERR_NOMEM;
    goto out;
  }
  for (size_t j = 0; j < nc; j++)
    for (int e = 0; e < k; e++) {
      size_t pos = w.rows[w.cpos[j] * (size_t)k + (size_t)e];
      w.idx[j * (size_t)k + (size_t)e] = (uint32_t)pos;
      w.mark[pos] = 1;
    }
  for (size_t q = 0; q < nr; q++) /* the ring's rows after the core's */
    for (int e = 0; e < k; e++) {
      size_t pos = w.rows[(ns + q) * (size_t)k + (size_t)e];
      w.idx[(nc + q) * (size_t)k + (size_t)e] = (uint32_t)pos;
      w.mark[pos] = 1;
    }
  if (c->ops->reverse) { /* how many rows contain each core point */
    if (!(w.coreof = bsurf_alloc_array(m ? m : 1, sizeof *w.coreof))) {
      st = BSURF_ERR_NOMEM;
      goto out;
    }
    for (size_t j = 0; j < m; j++)
      w.coreof[j] = UINT32_MAX;
    for (size_t j = 0; j < nc; j++) /* a row's point is its first entry */
      w.coreof[w.rows[w.cpos[j] * (size_t)k]] = (uint32_t)j;
    for (size_t q = 0; q < ns; q++)
      for (int e = 0; e < k; e++) {
        uint32_t j = w.coreof[w.rows[q * (size_t)k + (size_t)e]];
        if (j != UINT32_MAX) {
          w.rev_off[j + 1]++;
          w.mark[w.rows[q * (size_t)k]] = 1;
        }
      }
    for (size_t j = 0; j < nc; j++)
      w.rev_off[j + 1] += w.rev_off[j];
  }
  size_t nl = 0;
  for (size_t j = 0; j < m; j++)
    if (w.mark[j]) w.local[j] = (uint32_t)nl++;
  w.lxyz = bsurf_alloc_array(nl, 3 * sizeof *w.lxyz);
  if (!w.lxyz) {
    st = BSURF_ERR_NOMEM;
    goto out;
  }
  for (size_t j = 0; j < m; j++)
    if (w.mark[j]) memcpy(w.lxyz + 3 * (size_t)w.local[j], w.gx + 3 * j, 3 * sizeof(double));
  for (size_t e = 0; e < (nc + nr) * (size_t)k; e++)
    w.idx[e] = w.local[w.idx[e]];
  if (c->ops->reverse) { /* the lists, each in increasing index (S is) */
    size_t *fill = bsurf_alloc_array(nc + 1, sizeof *fill);
    w.rev = bsurf_alloc_array(w.rev_off[nc] + 1, sizeof *w.rev);
    if (!fill || !w.rev) {
      free(fill);
      st = BSURF_ERR_NOMEM;
      goto out;
    }
    memcpy(fill, w.rev_off, (nc + 1) * sizeof *fill);
    for (size_t q = 0; q < ns; q++) {
      uint32_t lq = w.local[w.rows[q * (size_t)k]];
      for (int e = 0; e < k; e++) {
        uint32_t j = w.coreof[w.rows[q * (size_t)k + (size_t)e]];
        if (j != UINT32_MAX) w.rev[fill[j]++] = lq;
      }
    }
    free(fill);
  }
  if (c->ops->values_in) { /* the first stage's values of every local point */
    const size_t nv = c->vin_cols - 1;
    w.lvals = bsurf_alloc_array(nl ? nl : 1, (nv ? nv : 1) * sizeof(double));
    if (!w.lvals) {
      st = BSURF_ERR_NOMEM;
      goto out;
    }
    sweep sv = {&c->vin, 0};
    for (size_t j = 0; j < m; j++)
      if (w.mark[j]) {
        size_t off = (size_t)w.G.v[j] * c->vin_cols * sizeof(double);
        memcpy(w.lvals + (size_t)w.local[j] * nv, c->vin.data + off, nv * sizeof(double));
        sweep_at(&sv, off);
      }
    drop_pages(&c->vin, 0, c->vin.size);
  }
  free(w.rows);
  w.rows = NULL;
  free(w.gx);
  w.gx = NULL;
  /* the core's entries of S, in place (cpos increases, cpos[j] >= j) */
  for (size_t j = 0; j < nc; j++) {
    w.nn2[j] = w.nn2[w.cpos[j]];
    w.kth2[j] = w.kth2[w.cpos[j]];
    w.dup[j] = w.dup[w.cpos[j]];
  }

  /* the core points with every input property, prepared by the command */
  st = cloud_like(&c->schema, nc, &core);
  if (st != BSURF_OK) goto out;
  sweep sw = {&c->in, 0};
  for (size_t j = 0; j < nc; j++) {
    io_ply_decode(&c->layout, c->in.data, w.core.v[j], &core, j);
    sweep_at(&sw, c->layout.body + (size_t)w.core.v[j] * c->layout.record);
  }
  drop_pages(&c->in, 0, c->in.size);
  if (c->ops->prepare) st = c->ops->prepare(c->ops->user, &core);
  if (st != BSURF_OK) goto out;
  if (c->ops->nvalues && !(w.vout = bsurf_calloc_array(nc, c->ops->nvalues * sizeof(double)))) {
    st = BSURF_ERR_NOMEM;
    goto out;
  }

  bsurf_neighbors nb = {nc + nr, k, w.idx, 0.0, NULL};
  bsurf_tile tile = {t,    c->ntiles, nc,     nl,        w.lxyz, w.core.v, &nb,
                     halo, w.lvals,   w.vout, w.rev_off, w.rev,  nr,       inner};
  double *sums = c->tile_sums + t * (c->ops->nsums + 1);
  st = c->ops->run(c->ops->user, &tile, &core, sums);
  if (st != BSURF_OK) goto out;
  size_t dups = 0;
  for (size_t j = 0; j < nc; j++)
    dups += w.dup[j];
  sums[c->ops->nsums] = (double)dups;

  /* the rows, values and squared nearest distances (for h) to the block */
  if (c->record) {
    w.enc = bsurf_alloc_array(nc, c->record);
    if (!w.enc) {
      st = BSURF_ERR_NOMEM;
      goto out;
    }
    st = io_ply_encode(&core, w.enc);
    if (st != BSURF_OK) goto out;
  }
  if (c->vcols) {
    const size_t nv = c->ops->nvalues;
    w.vblock = bsurf_alloc_array(nc, c->vcols * sizeof(double));
    if (!w.vblock) {
      st = BSURF_ERR_NOMEM;
      goto out;
    }
    for (size_t j = 0; j < nc; j++) {
      memcpy(w.vblock + j * c->vcols, w.vout + j * nv, nv * sizeof(double));
      w.vblock[j * c->vcols + nv] = w.kth2[j];
    }
  }
  st = write_block(c, t, w.core.v, w.nn2, w.vblock, w.enc, nc, err);
  if (st != BSURF_OK) goto out;
  if (nc > rep->max_tile_points) rep->max_tile_points = nc;
  if (nl > rep->max_local_points) rep->max_local_points = nl;
out:
  bsurf_cloud_free(&core);
  work_free(&w);
  /* nothing of the files stays resident between tiles */
  drop_pages(&c->in, 0, c->in.size);
  drop_pages(&c->sorted, 0, c->sorted.size);
  return st;
}
