/*
 * knn_all.c -- the all-K-nearest neighbours of an indexed cloud (each point's
 * row: itself, then its k - 1 nearest others by (squared distance, index)),
 * stored (bsurf_knn_all, bsurf_knn_all_ex) or handed row by row to a caller
 * (bsurf_knn_stream). The tree and the single-query search are in kdtree.c,
 * the build in kdtree_build.c.
 *
 * Batches of queries. The points are visited in tree order, a batch at a
 * time: the points of one node of at most KNN_BATCH_MAX points (a leaf, or
 * a node over a few leaves). For a batch, one descent of the tree gathers
 * into the thread's candidate arrays (x, y, z, index, tree position) every
 * point whose lower bound of distance to the batch's bounding box is at most
 * r2, a guess of the batches' largest (k - 1)-th distance (the thread's
 * previous batch's largest, times KNN_SLACK). Each query of the batch then
 * scans only these candidates, in vector lanes, into the same buffer as the
 * tree search (bsurf_knn_i_buffer_sort), instead of descending the tree
 * itself (about 40 node visits and 13 leaves a query at 1M points, K = 30).
 *
 * Exactness. Every point left out of the candidates is at a distance
 * strictly greater than r2 from every point of the batch: the bound used
 * (per dimension the gap between the batch's box and a node's extent or a
 * point, squared and summed in the order of knn_dist2) never exceeds the
 * computed distance, since each step (a subtraction of ordered operands, a
 * square, a sum of non-negative terms) rounds monotonically. So when a
 * query finds at least k - 1 candidates within r2, its k - 1 nearest are
 * among them and the buffer's sort gives them in the exact order (ties by
 * index), the same row as the tree search and the brute force. When it
 * finds fewer (the guess was small for this query: density changes), its
 * (k - 1)-th distance among all the candidates bounds its row, and the
 * batch's queries in that case share a second gather within the largest of
 * these bounds, which holds their rows. A gather whose candidates would not
 * fit in the thread's arrays (a guess far too large, coincident points), a
 * thread's first batch and an index with a non-finite coordinate use the
 * tree search (kdtree.c) instead, warm-started with the best bound at hand.
 *
 * Output. Rows go to idx and dist2 at the point's index (rows are in input
 * order, queries in tree order: the next query's rows are prefetched), or,
 * streamed, to the caller's function from a per-thread array. Queries run in
 * parallel over batches (OpenMP threads taking chunks of KNN_DYNAMIC_BATCHES
 * batches), each writing only its own row: the result is the same for any
 * thread count.
 */
#include "search/kdtree.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A batch: the points of a node of at most this many points (a leaf holds
 * 8..16). */
#define KNN_BATCH_MAX 32
/* r2 = the previous batch's largest (k - 1)-th distance times this. */
#define KNN_SLACK 1.25
/* Queries of a batch that may wait for its second gather. */
#define KNN_WAITING 64
/* Batches handed to a thread at a time (dynamic schedule). */
#define KNN_DYNAMIC_BATCHES 8

/* A warm start: an upper bound on the m-th smallest distance from the point
 * at tree position j to the others, from the m results of the same thread's
 * previous query (tree position prev, usually j's neighbour in tree order):
 * those points, with prev itself standing in for j when j is among them, are
 * m candidates, so the largest of their distances (knn_dist2, the search's
 * own expression) is at least the m-th smallest. The search then starts with
 * this bound instead of none and prunes from its first leaf; the k nearest
 * and their order are the same, since no candidate within the bound (ties
 * included: the tests are d > bound) is skipped. NaN when it cannot help. */
static double knn_warm_bound(const bsurf_knn_index *ix, size_t j, size_t prev, const knn_entry *e,
                             int m) {
  const double *const *xyz = (const double *const *)ix->xyz;
  const double q[3] = {xyz[0][j], xyz[1][j], xyz[2][j]};
  double bound = -INFINITY;
  int used = 0;
  for (int c = 0; c < m; c++) {
    if (e[c].pos == j) continue;
    const double d = knn_dist2_at(q, xyz, e[c].pos);
    if (d > bound) bound = d;
    used++;
    if (isnan(d)) return NAN;
  }
  if (used < m) {
    const double d = knn_dist2_at(q, xyz, prev);
    if (d > bound) bound = d;
    if (isnan(d)) return NAN;
  }
  return bound;
}

/* Fetches len bytes at p into the cache ahead of their writes. GCC 12 sees
 * no effect in a loop of prefetches and drops it once inlined, or the whole
 * call once it has found the function const: hence noipa (a call per query
 * costs nothing here). */
#if defined(__GNUC__) && !defined(__clang__)
#define KNN_NOIPA __attribute__((noipa))
#else
#define KNN_NOIPA
#endif
#if defined(__GNUC__)
KNN_NOIPA static void knn_prefetch(const void *p, size_t len) {
  const char *c = p;
  for (size_t o = 0; o < len; o += 64)
    __builtin_prefetch(c + o, 1);
  __builtin_prefetch(c + len - 1, 1);
}
#endif

/* Fetches the output rows of the point at tree position j. The rows are in
 * input order, so consecutive queries (tree order) write far apart: without
 * this, the first writes of a row missed the cache and filled the store
 * buffer (about 12% of the all-kNN's time at 1M points, K = 50, in perf). */
static inline void knn_prefetch_row(const bsurf_knn_index *ix, size_t j, int k, const uint32_t *idx,
                                    const double *dist2) {
#if defined(__GNUC__)
  const size_t row = (size_t)ix->ids[j] * (size_t)k;
  if (idx) knn_prefetch(idx + row, (size_t)k * sizeof *idx);
  if (dist2) knn_prefetch(dist2 + row, (size_t)k * sizeof *dist2);
#else
  (void)ix, (void)j, (void)k, (void)idx, (void)dist2;
#endif
}

/* One thread's state: the buffer of the search, the previous query (the
 * tree search's warm start) and batch (the guess), the candidate arrays and,
 * streamed, the row handed out. */
typedef struct knn_thread {
  knn_buffer buf;
  size_t prev;  /* tree position of the query whose results buf holds, or SIZE_MAX */
  double guess; /* the previous batch's largest (k - 1)-th distance, NaN for none */
  double *cx, *cy, *cz;
  uint64_t *cip; /* the candidates' index | tree position << 32 (a knn_entry's i and pos) */
  int cn, ccap;
  uint32_t *own;              /* streamed: the row (k) */
  double *own_xyz;            /* streamed: its coordinates (k x 3) */
  void *block;                /* everything above, one allocation */
  size_t counts[4];           /* bsurf_knn_path_counts */
  uint32_t wait[KNN_WAITING]; /* the batch's queries waiting for its second gather */
  char pad[64];               /* threads' states a cache line apart */
} knn_thread;

/* The batch's gathering: its box, r2 and the thread's candidate arrays. */
typedef struct knn_gather {
  const knn_node *nodes;
  const double *c[3];
  const uint32_t *ids;
  double lo[3], hi[3]; /* the batch's bounding box */
  double r2;
  uint32_t self; /* the batch's node (its points are gathered first) */
  knn_thread *t;
  int full; /* the candidates did not fit */
} knn_gather;

static inline double knn_max(double a, double b) {
  return a > b ? a : b;
}

/* Appends the points [begin, end) whose bound to the box is at most r2 (all
 * with `all`). The bound: per dimension the gap from the point to the box
 * (0 inside), squared and summed as in knn_dist2. */
static void gather_points(knn_gather *g, uint32_t begin, uint32_t end, int all) {
  knn_thread *t = g->t;
  int cn = t->cn;
  if (cn + (int)(end - begin) > t->ccap) {
    g->full = 1;
    return;
  }
  for (uint32_t p = begin; p < end; p++) {
    const double x = g->c[0][p], y = g->c[1][p], z = g->c[2][p];
    const double gx = knn_max(knn_max(g->lo[0] - x, x - g->hi[0]), 0.0);
    const double gy = knn_max(knn_max(g->lo[1] - y, y - g->hi[1]), 0.0);
    const double gz = knn_max(knn_max(g->lo[2] - z, z - g->hi[2]), 0.0);
    t->cx[cn] = x;
    t->cy[cn] = y;
    t->cz[cn] = z;
    t->cip[cn] = (uint64_t)g->ids[p] | (uint64_t)p << 32;
    cn += all | !(gx * gx + gy * gy + gz * gz > g->r2);
  }
  t->cn = cn;
}

/* The descent: off[d] is a lower bound of the gap along d between the box
 * and the node's points. A child's gap along the split dimension is the
 * box's distance to the child's side of the split (nd->lo, nd->hi), or the
 * parent's when larger (both are bounds). A node is skipped when its bound
 * is greater than r2. */
static void gather_visit(knn_gather *g, uint32_t node, double *off) {
  if (g->full || node == g->self) return;
  const knn_node *nd = &g->nodes[node];
  if (nd->dim < 0) {
    gather_points(g, nd->begin, nd->end, 0);
    return;
  }
  const int dim = nd->dim;
  const double saved = off[dim];
  const double gl = g->lo[dim] - nd->lo; /* > 0: the box is right of the left child */
  const double gr = nd->hi - g->hi[dim]; /* > 0: the box is left of the right child */
  off[dim] = gl > saved ? gl : saved;
  if (!(off[0] * off[0] + off[1] * off[1] + off[2] * off[2] > g->r2))
    gather_visit(g, node + 1, off);
  off[dim] = gr > saved ? gr : saved;
  if (!(off[0] * off[0] + off[1] * off[1] + off[2] * off[2] > g->r2))
    gather_visit(g, nd->right, off);
  off[dim] = saved;
}

/* Gathers the candidates of the batch `node` within r2; 0 when they do not
 * fit. */
static int knn_gather_batch(const bsurf_knn_index *ix, uint32_t node, double r2, knn_thread *t) {
  const knn_node *nd = &ix->nodes[node];
  knn_gather g;
  g.nodes = ix->nodes;
  for (int d = 0; d < 3; d++) {
    g.c[d] = ix->xyz[d];
    g.lo[d] = INFINITY;
    g.hi[d] = -INFINITY;
  }
  for (uint32_t p = nd->begin; p < nd->end; p++)
    for (int d = 0; d < 3; d++) {
      const double v = g.c[d][p];
      g.lo[d] = v < g.lo[d] ? v : g.lo[d];
      g.hi[d] = v > g.hi[d] ? v : g.hi[d];
    }
  g.ids = ix->ids;
  g.r2 = r2;
  g.self = node;
  g.t = t;
  g.full = 0;
  t->cn = 0;
  gather_points(&g, nd->begin, nd->end, 1);
  double off[3] = {0.0, 0.0, 0.0};
  gather_visit(&g, 0, off);
  if (g.full) return 0;
  /* the lanes past the last candidate read these (masked) */
  for (int p = t->cn; p < t->cn + KNN_BLOCK; p++) {
    t->cx[p] = t->cy[p] = t->cz[p] = 0.0;
    t->cip[p] = 0;
  }
  return 1;
}

/* The query q (candidate self) against the candidates: those within `bound`
 * into the buffer (sorted when it fills, which tightens the bound), then
 * sorted. 1 when k - 1 were found: then buf->e[0, k - 1) is the row, with
 * tree positions. The distances of a block are computed KNN_LANES at a time
 * with the operations and order of knn_dist2 (the same bits), as in
 * kdtree.c's knn_scan_leaf. */
#if defined(__GNUC__)
#define KNN_INLINE __attribute__((always_inline)) inline
#else
#define KNN_INLINE inline
#endif
static KNN_INLINE int knn_scan_cands(knn_thread *t, uint32_t self, const double *q, double bound) {
  knn_buffer *buf = &t->buf;
  buf->count = 0;
  for (int b = 0; b < t->cn; b += KNN_BLOCK) {
    const unsigned cnt = (unsigned)(t->cn - b < KNN_BLOCK ? t->cn - b : KNN_BLOCK);
    if (buf->count > buf->cap - KNN_BLOCK) bound = bsurf_knn_i_buffer_sort(buf);
    double dd[KNN_BLOCK];
    unsigned keep = 0;
#ifdef KNN_HAVE_V4D
    const knn_v4d qx = {q[0], q[0], q[0], q[0]};
    const knn_v4d qy = {q[1], q[1], q[1], q[1]};
    const knn_v4d qz = {q[2], q[2], q[2], q[2]};
    const knn_v4d w = {bound, bound, bound, bound};
    for (unsigned l = 0; l < KNN_BLOCK; l += KNN_LANES) {
      knn_v4d x, y, z, d;
      knn_v4l gt;
      memcpy(&x, t->cx + b + l, sizeof x);
      memcpy(&y, t->cy + b + l, sizeof y);
      memcpy(&z, t->cz + b + l, sizeof z);
      x = qx - x;
      y = qy - y;
      z = qz - z;
      d = x * x + y * y + z * z;
      memcpy(dd + l, &d, sizeof d);
      gt = d > w;
      keep |= (unsigned)((gt[0] + 1) | (gt[1] + 1) << 1 | (gt[2] + 1) << 2 | (gt[3] + 1) << 3) << l;
    }
#else
    for (unsigned l = 0; l < KNN_BLOCK; l++) {
      const double dx = q[0] - t->cx[b + l], dy = q[1] - t->cy[b + l], dz = q[2] - t->cz[b + l];
      dd[l] = dx * dx + dy * dy + dz * dz;
      keep |= (unsigned)!(dd[l] > bound) << l;
    }
#endif
    keep &= (1u << cnt) - 1u;
    if (self - (unsigned)b < cnt) keep &= ~(1u << (self - (unsigned)b));
    knn_entry *e = buf->e + buf->count;
    while (keep) {
      const unsigned l = (unsigned)__builtin_ctz(keep);
      keep &= keep - 1u;
      e->d = dd[l];
      e->i = (uint32_t)t->cip[b + l];
      e->pos = (uint32_t)(t->cip[b + l] >> 32);
      e++;
    }
    buf->count = (int)(e - buf->e);
  }
  bsurf_knn_i_buffer_sort(buf);
  return buf->count == buf->k;
}

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define KNN_HAVE_AVX512 1
/* The smallest and largest distance kept (their lanes), for the sort. A
 * NaN distance (not with finite coordinates, which the batches need) would
 * be left out of both: then the sort's own pass. */
__attribute__((target("avx512f"))) static inline void knn_buffer_range(knn_buffer *buf, __m512d lo,
                                                                       __m512d hi) {
  buf->lo = _mm512_reduce_min_pd(lo);
  buf->hi = _mm512_reduce_max_pd(hi);
  buf->ranged = 1;
}

/* knn_scan_cands in AVX-512 (eight lanes; the same operations in the same
 * order, so the same distances, and the same entries in the same order):
 * the lanes kept are compressed, and each (distance, index | position << 32)
 * pair interleaved into knn_entry layout, without a branch per candidate. */
__attribute__((target("avx512f"))) static int knn_scan_cands_avx512(knn_thread *t, uint32_t self,
                                                                    const double *q, double bound) {
  knn_buffer *buf = &t->buf;
  const __m512d qx = _mm512_set1_pd(q[0]), qy = _mm512_set1_pd(q[1]), qz = _mm512_set1_pd(q[2]);
  const __m512i first = _mm512_set_epi64(11, 3, 10, 2, 9, 1, 8, 0);
  const __m512i second = _mm512_set_epi64(15, 7, 14, 6, 13, 5, 12, 4);
  __m512d lo = _mm512_set1_pd(INFINITY), hi = _mm512_set1_pd(-INFINITY);
  buf->count = 0;
  for (unsigned b = 0; b < (unsigned)t->cn; b += 8) {
    if (buf->count > buf->cap - KNN_BLOCK) {
      knn_buffer_range(buf, lo, hi);
      bound = bsurf_knn_i_buffer_sort(buf);
    }
    const __m512d x = _mm512_sub_pd(qx, _mm512_loadu_pd(t->cx + b));
    const __m512d y = _mm512_sub_pd(qy, _mm512_loadu_pd(t->cy + b));
    const __m512d z = _mm512_sub_pd(qz, _mm512_loadu_pd(t->cz + b));
    const __m512d d =
        _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(x, x), _mm512_mul_pd(y, y)), _mm512_mul_pd(z, z));
    /* not greater than the bound (NaN kept, as in the scalar test) */
    unsigned keep = _mm512_cmp_pd_mask(d, _mm512_set1_pd(bound), _CMP_NGT_UQ);
    if ((unsigned)t->cn - b < 8) keep &= (1u << ((unsigned)t->cn - b)) - 1u;
    if (self - b < 8) keep &= ~(1u << (self - b));
    const __m512d dc = _mm512_maskz_compress_pd((__mmask8)keep, d);
    const __m512d ic = _mm512_castsi512_pd(
        _mm512_maskz_compress_epi64((__mmask8)keep, _mm512_loadu_si512(t->cip + b)));
    double *out = (double *)(void *)(buf->e + buf->count);
    _mm512_storeu_pd(out, _mm512_permutex2var_pd(dc, first, ic));
    _mm512_storeu_pd(out + 8, _mm512_permutex2var_pd(dc, second, ic));
    buf->count += __builtin_popcount(keep);
    lo = _mm512_mask_min_pd(lo, (__mmask8)keep, lo, d);
    hi = _mm512_mask_max_pd(hi, (__mmask8)keep, hi, d);
  }
  knn_buffer_range(buf, lo, hi);
  bsurf_knn_i_buffer_sort(buf);
  return buf->count == buf->k;
}
#endif

#if defined(__GNUC__) && defined(__x86_64__)
#define KNN_HAVE_AVX2 1
/* The portable scan compiled for AVX2 (a lane block of four doubles is one
 * register; the same operations, so the same bits): processors without
 * AVX-512. */
__attribute__((target("avx2"))) static int knn_scan_cands_avx2(knn_thread *t, uint32_t self,
                                                               const double *q, double bound) {
  return knn_scan_cands(t, self, q, bound);
}
#endif

static int knn_scan_plain(knn_thread *t, uint32_t self, const double *q, double bound) {
  return knn_scan_cands(t, self, q, bound);
}

/* Which scan the batches use: 2 AVX-512, 1 AVX2, 0 the portable one (the
 * best the processor has, at most bsurf_knn_set_paths's simd), -1 not
 * decided yet. */
static int knn_simd = -1;
static int knn_use_batches = 1;

void bsurf_knn_set_paths(int batches, int simd) {
  knn_use_batches = batches;
  knn_simd = 0;
#ifdef KNN_HAVE_AVX2
  if (simd >= 1 && __builtin_cpu_supports("avx2")) knn_simd = 1;
#endif
#ifdef KNN_HAVE_AVX512
  if (simd >= 2 && __builtin_cpu_supports("avx512f")) knn_simd = 2;
#endif
}

int bsurf_knn_simd(void) {
  if (knn_simd < 0) bsurf_knn_set_paths(knn_use_batches, 2);
  return knn_simd;
}

/* The last all-kNN's counts (bsurf_knn_path_counts). */
static size_t knn_counts[4];

void bsurf_knn_path_counts(size_t counts[4]) {
  for (int c = 0; c < 4; c++)
    counts[c] = __atomic_load_n(&knn_counts[c], __ATOMIC_RELAXED);
}

static int knn_scan(knn_thread *t, uint32_t self, const double *q, double bound) {
#ifdef KNN_HAVE_AVX512
  if (knn_simd == 2) return knn_scan_cands_avx512(t, self, q, bound);
#endif
#ifdef KNN_HAVE_AVX2
  if (knn_simd == 1) return knn_scan_cands_avx2(t, self, q, bound);
#endif
  return knn_scan_plain(t, self, q, bound);
}

/* Writes the row of the point at tree position j from the buffer (its
 * first k - 1 entries): to idx and dist2 at the point's index, or, streamed,
 * to the thread's own arrays; and nn_dist2. */
static void knn_put_row(const bsurf_knn_index *ix, size_t j, int k, const knn_thread *t,
                        uint32_t *idx, double *dist2, double *nn_dist2) {
  const uint32_t self = ix->ids[j];
  const size_t row = t->own ? 0 : (size_t)self * (size_t)k;
  const int m = k - 1;
  const knn_entry *e = t->buf.e;
  if (t->own) idx = t->own;
  if (idx) {
    idx[row] = self;
    for (int c = 0; c < m; c++)
      idx[row + 1 + (size_t)c] = e[c].i;
  }
  if (dist2) {
    dist2[row] = 0.0;
    for (int c = 0; c < m; c++)
      dist2[row + 1 + (size_t)c] = e[c].d;
  }
  if (nn_dist2) nn_dist2[self] = m > 0 ? e[0].d : 0.0;
  if (t->own_xyz) /* the row's coordinates, from the tree's arrays the search just read */
    for (int d = 0; d < 3; d++) {
      const double *c = ix->xyz[d];
      t->own_xyz[d] = c[j];
      for (int a = 0; a < m; a++)
        t->own_xyz[3 * (size_t)(a + 1) + (size_t)d] = c[e[a].pos];
    }
}

/* The rows of the batch `node` (see the top of this file). A query that
 * finds fewer than k - 1 candidates within r2 waits, with an upper bound of
 * its (k - 1)-th distance (the (k - 1)-th among all the candidates); the
 * waiting queries then share a second gather within the largest of their
 * bounds, which holds their rows (the tree search where it does not fit). */
static void knn_batch(const bsurf_knn_index *ix, uint32_t node, int k, knn_thread *t, int tid,
                      uint32_t *idx, double *dist2, double *nn_dist2, bsurf_knn_row_fn row,
                      void *row_user) {
  const knn_node *nd = &ix->nodes[node];
  const int m = k - 1;
  const double r2 = t->guess * KNN_SLACK;
  const int gathered = m > 0 && knn_use_batches && ix->finite && !isnan(t->guess) &&
                       knn_gather_batch(ix, node, r2, t);
  t->counts[gathered ? 0 : 1]++;
  double worst = -INFINITY, r2b = -INFINITY;
  int waiting = 0;
  for (uint32_t j = nd->begin; j < nd->end; j++) {
    if (j + 1 < ix->n) knn_prefetch_row(ix, j + 1, k, idx, dist2);
    if (m > 0) {
      const double q[3] = {ix->xyz[0][j], ix->xyz[1][j], ix->xyz[2][j]};
      if (gathered) {
        if (knn_scan(t, j - nd->begin, q, r2)) {
          t->counts[2]++;
        } else {
          t->counts[3]++;
          const int bounded = knn_scan(t, j - nd->begin, q, INFINITY);
          if (bounded && waiting < KNN_WAITING) {
            t->wait[waiting++] = j;
            r2b = t->buf.e[m - 1].d > r2b ? t->buf.e[m - 1].d : r2b;
            continue; /* its row after the second gather */
          }
          bsurf_knn_i_search(ix, j, &t->buf, bounded ? t->buf.e[m - 1].d : NAN);
        }
      } else {
        const double warm = t->prev != SIZE_MAX ? knn_warm_bound(ix, j, t->prev, t->buf.e, m) : NAN;
        bsurf_knn_i_search(ix, j, &t->buf, warm);
      }
      t->prev = j;
      worst = t->buf.e[m - 1].d > worst ? t->buf.e[m - 1].d : worst;
    }
    knn_put_row(ix, j, k, t, idx, dist2, nn_dist2);
    if (row) row(row_user, tid, ix->ids[j], t->own, t->own_xyz);
  }
  if (waiting) {
    const int again = knn_gather_batch(ix, node, r2b, t);
    for (int w = 0; w < waiting; w++) {
      const uint32_t j = t->wait[w];
      const double q[3] = {ix->xyz[0][j], ix->xyz[1][j], ix->xyz[2][j]};
      /* r2b is at least this query's (k - 1)-th distance: a valid warm start */
      if (!(again && knn_scan(t, j - nd->begin, q, r2b))) bsurf_knn_i_search(ix, j, &t->buf, r2b);
      t->prev = j;
      worst = t->buf.e[m - 1].d > worst ? t->buf.e[m - 1].d : worst;
      knn_put_row(ix, j, k, t, idx, dist2, nn_dist2);
      if (row) row(row_user, tid, ix->ids[j], t->own, t->own_xyz);
    }
  }
  t->guess = m > 0 ? worst : NAN;
}

/* The batches (node ids), in tree order: the nodes of at most KNN_BATCH_MAX
 * points and the leaves above it, found from the root (unused node places
 * are never reached). */
static size_t knn_batches(const bsurf_knn_index *ix, uint32_t *out) {
  uint32_t stack[128];
  size_t top = 0, count = 0;
  stack[top++] = 0;
  while (top) {
    const uint32_t node = stack[--top];
    const knn_node *nd = &ix->nodes[node];
    if (nd->dim < 0 || nd->end - nd->begin <= KNN_BATCH_MAX) {
      out[count++] = node;
    } else {
      stack[top++] = nd->right;
      stack[top++] = node + 1;
    }
  }
  return count;
}

static void knn_threads_free(knn_thread *ts, int nt) {
  if (!ts) return;
  for (int t = 0; t < nt; t++)
    free(ts[t].block);
  free(ts);
}

/* nt threads' states for k; NULL when memory runs out. */
static knn_thread *knn_threads_alloc(int nt, int k, int streamed) {
  knn_thread *ts = calloc((size_t)nt, sizeof *ts);
  if (!ts) return NULL;
  /* The buffer: room for twice the k - 1 results (at least 64) beside a
   * block, within L1 for K = 50 (1.8 KB, twice for the sort's copy): a tree
   * search at 1M points, K = 50, appends about 91 candidates and sorts 1.5
   * times; three times the results (one sort) measured the same. The
   * candidates: room for the neighbourhoods of a batch several times over. */
  const size_t m = k > 1 ? (size_t)(k - 1) : 1;
  const size_t cap = (m > 32 ? 2 * m : 64) + KNN_BLOCK;
  const size_t hist = (KNN_SPREAD + 1) * cap + 1;
  const size_t ccap = 8 * ((size_t)k + KNN_BATCH_MAX) + 256;
  const size_t own = streamed ? ((size_t)k + 15) & ~(size_t)15 : 0;
  const size_t bytes = 2 * cap * sizeof(knn_entry) + (ccap + KNN_BLOCK) * 4 * sizeof(double) +
                       4 * own * sizeof(double) + hist * sizeof(uint32_t);
  for (int i = 0; i < nt; i++) {
    knn_thread *t = &ts[i];
    char *p = t->block = bsurf_alloc_array(1, bytes);
    if (!p) {
      knn_threads_free(ts, nt);
      return NULL;
    }
    /* 8-byte items first, then 4-byte ones: each aligned */
    t->buf.e = (knn_entry *)(void *)p;
    t->buf.tmp = t->buf.e + cap;
    p += 2 * cap * sizeof(knn_entry);
    t->cx = (double *)(void *)p;
    t->cy = t->cx + ccap + KNN_BLOCK;
    t->cz = t->cy + ccap + KNN_BLOCK;
    t->cip = (uint64_t *)(void *)(t->cz + ccap + KNN_BLOCK);
    p += (ccap + KNN_BLOCK) * 4 * sizeof(double);
    t->own_xyz = own ? (double *)(void *)p : NULL;
    p += 3 * own * sizeof(double);
    t->own = own ? (uint32_t *)(void *)p : NULL;
    p += own * sizeof(double);
    t->buf.hist = (uint32_t *)(void *)p;
    t->buf.key = t->buf.hist + KNN_SPREAD * cap + 1;
    p += hist * sizeof(uint32_t);
    t->buf.cap = (int)cap;
    t->buf.k = (int)m;
    t->buf.count = 0;
    t->ccap = (int)ccap;
    t->prev = SIZE_MAX;
    t->guess = NAN;
  }
  return ts;
}

/* bsurf_knn_all_ex and bsurf_knn_stream: with `row` set (and idx NULL),
 * each point's row handed to it in a per-thread array instead of stored. */
static bsurf_status knn_all_run(const bsurf_knn_index *index, int k, int threads, uint32_t *idx,
                                double *dist2, double *nn_dist2, bsurf_knn_row_fn row,
                                void *row_user, bsurf_progress_fn progress, void *progress_user) {
  BSURF_REQUIRE(index, "index is NULL");
  const size_t n = index->n;
  BSURF_REQUIRE(k >= 1 && (size_t)k <= n, "k = %d: must be in [1, %zu] (the indexed points)", k, n);
  BSURF_REQUIRE(!nn_dist2 || k >= 2, "k = %d: the spacing needs k >= 2", k);

  bsurf_knn_simd(); /* decided before the threads start */
  uint32_t *bat = bsurf_alloc_array(n / 8 + 2, sizeof *bat);
  if (!bat) return BSURF_ERR_NOMEM;
  const size_t nbat = knn_batches(index, bat);
  int nt = bsurf_threads_resolve(threads);
  if (nt < 1) nt = 1;
  /* No more threads than dynamic chunks (small inputs; does not change the
   * result). */
  if ((size_t)nt > (nbat + KNN_DYNAMIC_BATCHES - 1) / KNN_DYNAMIC_BATCHES)
    nt = (int)((nbat + KNN_DYNAMIC_BATCHES - 1) / KNN_DYNAMIC_BATCHES);
  knn_thread *ts = knn_threads_alloc(nt, k, row != NULL);
  if (!ts) {
    free(bat);
    return BSURF_ERR_NOMEM;
  }
  bsurf_status st = BSURF_OK;
  const knn_node *nodes = index->nodes;
  /* One parallel region: the threads take KNN_DYNAMIC_BATCHES batches at a
   * time from a shared counter, and the calling thread (OpenMP's thread 0)
   * reports progress between its chunks, every BSURF_PROGRESS_CHUNK points
   * or more; a cancellation stops every thread before its next chunk. (A
   * region per BSURF_PROGRESS_CHUNK points ended in 244 barriers at 1M
   * points, each waiting for the slower thread: costly on a loaded machine.) */
  const size_t chunks = (nbat + KNN_DYNAMIC_BATCHES - 1) / KNN_DYNAMIC_BATCHES;
  size_t next = 0, done = 0;
  int cancel = 0;
#ifdef _OPENMP
#pragma omp parallel num_threads(nt)
#endif
  {
#ifdef _OPENMP
    const int t = omp_get_thread_num();
#else
    const int t = 0;
#endif
    size_t reported = 0;
    while (!__atomic_load_n(&cancel, __ATOMIC_RELAXED)) {
      const size_t c = __atomic_fetch_add(&next, 1, __ATOMIC_RELAXED);
      if (c >= chunks) break;
      const size_t b1 = (c + 1) * KNN_DYNAMIC_BATCHES < nbat ? (c + 1) * KNN_DYNAMIC_BATCHES : nbat;
      size_t points = 0;
      for (size_t b = c * KNN_DYNAMIC_BATCHES; b < b1; b++) {
        knn_batch(index, bat[b], k, &ts[t], t, idx, dist2, nn_dist2, row, row_user);
        points += nodes[bat[b]].end - nodes[bat[b]].begin;
      }
      const size_t now = __atomic_add_fetch(&done, points, __ATOMIC_RELAXED);
      if (t == 0 && progress && now < n && now - reported >= BSURF_PROGRESS_CHUNK) {
        reported = now;
        if (progress(progress_user, now, n)) __atomic_store_n(&cancel, 1, __ATOMIC_RELAXED);
      }
    }
  }
  if (cancel || (progress && progress(progress_user, n, n))) st = BSURF_ERR_CANCELLED;
  for (int c = 0; c < 4; c++) {
    size_t sum = 0;
    for (int t = 0; t < nt; t++)
      sum += ts[t].counts[c];
    __atomic_store_n(&knn_counts[c], sum, __ATOMIC_RELAXED);
  }
  knn_threads_free(ts, nt);
  free(bat);
  return st;
}

bsurf_status bsurf_knn_all_ex(const bsurf_knn_index *index, int k, int threads, uint32_t *idx,
                              double *dist2, double *nn_dist2, bsurf_progress_fn progress,
                              void *progress_user) {
  return knn_all_run(index, k, threads, idx, dist2, nn_dist2, NULL, NULL, progress, progress_user);
}

bsurf_status bsurf_knn_stream(const bsurf_knn_index *index, int k, int threads,
                              bsurf_knn_row_fn row, void *row_user, double *nn_dist2,
                              bsurf_progress_fn progress, void *progress_user) {
  BSURF_REQUIRE(row, "row is NULL");
  return knn_all_run(index, k, threads, NULL, NULL, nn_dist2, row, row_user, progress,
                     progress_user);
}

bsurf_status bsurf_knn_all(const bsurf_knn_index *index, int k, int threads, uint32_t *idx,
                           double *dist2, bsurf_progress_fn progress, void *progress_user) {
  BSURF_REQUIRE(idx, "idx is NULL");
  return bsurf_knn_all_ex(index, k, threads, idx, dist2, NULL, progress, progress_user);
}
