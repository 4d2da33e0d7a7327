/*
 * kdtree.c — exact K-nearest-neighbour search: a k-d tree, single queries,
 * the all-kNN's per-query search, and the brute-force reference (the
 * all-K-nearest neighbours of a cloud, batch by batch, are in knn_all.c).
 *
 * What it is for: every local analysis of the thesis works on the
 * K-nearest neighbourhood of each point (thesis 3.3: "we search for K-nearest
 * neighbourhood for each point, such that for d_i, we obtain a neighbourhood
 * P_i = {p_1^i, ..., p_K^i}"), which gives the local frame (Eq. 3.4), the
 * polynomial fits and the bootstrap of chapter 4. The neighbourhoods are
 * computed once per cloud (bsurf_neighbors_build, neighbors.c) and shared.
 *
 * Why our own: it is the hot path of every command (a million points with
 * K = 50 is 50 million neighbours), and we need guarantees no C library in
 * Debian gives together: exact results (no approximate search), a total and
 * documented order (squared distance, then smaller index — so ties between
 * equidistant points, common on scanner grids and generated shapes, never
 * depend on the tree or the thread schedule), each point first in its own row
 * even when it has exact duplicates, and bit-identical output for any thread
 * count. nanoflann, which this follows, is C++ (and FLANN is approximate).
 *
 * Design (after nanoflann and Arya & Mount, "Algorithms for fast vector
 * quantization", 1993; the build is in kdtree_build.c, the layout in
 * kdtree.h):
 *  - Build: the points are copied into tree order (x, y and z as three
 *    arrays, so that a leaf's distances are computed in vector lanes); a node with more than
 *    KNN_LEAF_MAX points is split on the dimension of widest extent at the
 *    median position (an in-place nth_element, Hoare/Wirth selection with a
 *    median-of-three pivot, deterministic). Nodes are stored in preorder, the
 *    left child right after its parent. A node whose points all coincide (zero
 *    extent) or have no finite extent (all NaN) is a leaf, so the build always
 *    terminates; the median split also halves the count at every level, so the
 *    depth is at most ~log2(N).
 *  - Every inner node keeps the largest coordinate of its left child and the
 *    smallest of its right child along its split dimension (nanoflann's
 *    divlow/divhigh), which give exact distances to the children's boxes.
 *  - Query: descend into the nearer child first; before visiting the farther
 *    one compute a lower bound of the squared distance from the query to its
 *    box from per-dimension offsets off[d] (Arya-Mount incremental distance:
 *    only off[split] changes). The usual update rd - off[d]^2 + cut^2 can round
 *    above the true bound and prune a box that holds an equidistant point with
 *    a smaller index; we recompute rd = off0^2 + off1^2 + off2^2 with the same
 *    expression and order as the point distance instead (3 multiplies, just as
 *    cheap in 3D). Rounding is monotone, so this bound never exceeds the
 *    computed distance of any point in the box, and a box is skipped only if
 *    its bound is strictly greater than the current k-th distance: the result
 *    is the exact top k under the total order, i.e. identical to brute force.
 *  - Results: a single query (and the brute force) keeps a sorted array of k
 *    (distance, index) pairs with insertion from the end (k is typically
 *    10..100, up to ~500). The all-kNN appends every candidate within the
 *    bound to an unsorted buffer instead and sorts it (buckets by distance,
 *    then an insertion sort of the first buckets by the exact order) when it
 *    fills and at the end: the same k, in the same order (knn_all.c's
 *    batches use the same buffer).
 *  - The order is total even with NaN: a NaN distance sorts after every number
 *    (then by index), and NaN bounds never prune. So NaN or infinite input
 *    gives the same answer as brute force instead of a crash or a hang
 *    (rejecting them is the caller's job: bsurf_cloud_check_finite).
 *  - All-kNN (knn_all.c) visits the points in tree order, a batch of
 *    neighbouring queries at a time, in parallel with OpenMP; the tree
 *    search here (bsurf_knn_i_search) answers the queries its batches'
 *    candidates cannot.
 *
 * Memory of an index: 24 bytes/point (tree-ordered coordinates) + 4 bytes/point
 * (original index of each tree position) + 32 bytes per node; leaves hold 8..16
 * points, so there are N/8 to N/4 nodes: 32 to 36 bytes/point in total (32 MB
 * for a million points). Build: O(N log N) time, no memory beyond the index.
 * All-kNN: per thread, a buffer of 2(k - 1) + 16 16-byte entries (at least
 * 80), twice, 12 bytes per entry of bucket counts and keys, and the
 * batches' candidates (32 bytes each, 8(k + 16) + 256 of them).
 */
#include "search/kdtree.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------ */
/* Distances and the result list, shared by the tree and the brute force      */
/* ------------------------------------------------------------------------ */

/* The one squared-distance expression of this file: query minus point, x then
 * y then z, summed left to right. Both searches and the box bound use it, so
 * equal distances are bit-identical and the bound is consistent with it. */
static inline double knn_dist2(const double *q, const double *p) {
  const double dx = q[0] - p[0];
  const double dy = q[1] - p[1];
  const double dz = q[2] - p[2];
  return dx * dx + dy * dy + dz * dz;
}

/* Squared distance to a box from its per-dimension offsets (same expression). */
static inline double knn_box_dist2(const double *off) {
  return off[0] * off[0] + off[1] * off[1] + off[2] * off[2];
}

/* Total order of candidates: (d1, i1) before (d2, i2). Numbers by value, a NaN
 * after every number, ties by index. */
static inline int knn_before(double d1, uint32_t i1, double d2, uint32_t i2) {
  if (d1 < d2) return 1;
  if (d1 > d2) return 0;
  if (d1 == d2) return i1 < i2;
  {
    const int nan1 = isnan(d1), nan2 = isnan(d2);
    if (nan1 != nan2) return nan2;
    return i1 < i2;
  }
}

typedef struct knn_list {
  knn_entry *e; /* k */
  int k;
  int count;
  int nan_count; /* entries with a NaN distance: then the slow path */
  double worst;
} knn_list;

static void knn_list_reset(knn_list *l) {
  l->count = 0;
  l->nan_count = 0;
  l->worst = NAN;
}

/* Inserts (d, id) if it is among the k best so far. Insertion from the end:
 * the shift loop is branch-predictable, which measured faster (K = 10..100)
 * than a binary search + memmove and than a max-heap sorted at the end. */
static inline void knn_list_insert(knn_list *l, double d, uint32_t id, uint32_t pos) {
  knn_entry *e = l->e;
  int j;
  if (l->nan_count == 0 && !isnan(d)) {
    /* Fast path, numbers only: shift the larger distances, then the equal
     * distances with larger indices. */
    if (l->count == l->k) {
      const knn_entry *w = &e[l->k - 1];
      if (!(d < w->d || (d == w->d && id < w->i))) return;
      j = l->k - 1;
    } else {
      j = l->count++;
    }
    while (j > 0 && e[j - 1].d > d) {
      e[j] = e[j - 1];
      j--;
    }
    while (j > 0 && e[j - 1].d == d && e[j - 1].i > id) {
      e[j] = e[j - 1];
      j--;
    }
  } else {
    /* NaN somewhere: the general total order. */
    if (l->count == l->k) {
      const knn_entry *w = &e[l->k - 1];
      if (!knn_before(d, id, w->d, w->i)) return;
      if (isnan(w->d)) l->nan_count--;
      j = l->k - 1;
    } else {
      j = l->count++;
    }
    while (j > 0 && knn_before(d, id, e[j - 1].d, e[j - 1].i)) {
      e[j] = e[j - 1];
      j--;
    }
    if (isnan(d)) l->nan_count++;
  }
  e[j].d = d;
  e[j].i = id;
  e[j].pos = pos;
  if (l->count == l->k) l->worst = e[l->k - 1].d;
}

/* Sorts e[0, n) by knn_before (ties by index, NaN last) by insertion. */
static void knn_insertion_sort(knn_entry *e, int n) {
  for (int i = 1; i < n; i++) {
    const knn_entry x = e[i];
    int j = i;
    while (j > 0 && knn_before(x.d, x.i, e[j - 1].d, e[j - 1].i)) {
      e[j] = e[j - 1];
      j--;
    }
    e[j] = x;
  }
}

/* Sorts the buffer by knn_before and keeps its first k entries (all when
 * fewer); returns the k-th distance then, NaN when fewer than k are left.
 * A counting pass first puts the entries in KNN_SPREAD * n buckets of equal
 * width between the smallest and the largest distance: the bucket of d is
 * (uint32_t)((d - lo) * scale), which never decreases as d grows (each step
 * rounds monotonically) and is the same for equal distances, so every entry
 * of a bucket comes before every entry of a later bucket in the exact order.
 * Only the buckets that hold the first k entries are then sorted, by an
 * insertion sort that has little to move and predictable branches. With a
 * NaN, an infinite distance or a zero range, the insertion sort alone (same
 * result, slower). */
double bsurf_knn_i_buffer_sort(knn_buffer *b) {
  const int n = b->count, k = b->k;
  knn_entry *e = b->e;
  double lo = INFINITY, hi = -INFINITY;
  int nan = 0, keep = n;
  if (b->ranged) { /* from the scan's registers: reading the entries just stored stalled */
    lo = b->lo;
    hi = b->hi;
    b->ranged = 0;
  } else {
    for (int i = 0; i < n; i++) {
      const double d = e[i].d;
      lo = d < lo ? d : lo;
      hi = d > hi ? d : hi;
      nan |= isnan(d);
    }
  }
  /* KNN_SPREAD buckets per entry: fewer entries share a bucket, so fewer
   * are out of order for the insertion sort. */
  const uint32_t nb = KNN_SPREAD * (uint32_t)n;
  const double range = hi - lo, scale = (double)nb / range;
  /* A finite range (an infinite distance would make a bucket of inf * 0)
   * and a finite scale (not so for a zero range, or a subnormal one): every
   * bucket is then a number in [0, nb] up to rounding, converted without
   * overflow and clamped to the last bucket. */
  if (!nan && n > 1 && range < INFINITY && scale < INFINITY) {
    uint32_t *hist = b->hist, *key = b->key;
    knn_entry *t = b->tmp;
    const uint32_t top = nb - 1u;
    memset(hist, 0, (size_t)nb * sizeof *hist);
    for (int i = 0; i < n; i++) {
      const uint32_t c = (uint32_t)((e[i].d - lo) * scale);
      key[i] = c < top ? c : top;
      hist[key[i]]++;
    }
    /* hist[c] becomes the start of bucket c (the running sum in a register:
     * through memory, each step waited for the previous store); keep, the
     * end of the first bucket that completes k entries: only [0, keep) needs
     * sorting. */
    keep = 0;
    for (uint32_t c = 0, run = 0; c < nb; c++) {
      const uint32_t count = hist[c];
      hist[c] = run;
      run += count;
      keep = keep == 0 && run >= (uint32_t)k ? (int)run : keep;
    }
    if (keep == 0) keep = n;
    for (int i = 0; i < n; i++)
      t[hist[key[i]]++] = e[i];
    /* Insertion sort of the nearly sorted first buckets, numbers only:
     * distance, then index. */
    for (int i = 1; i < keep; i++) {
      const knn_entry x = t[i];
      int j = i;
      while (j > 0 && (t[j - 1].d > x.d || (t[j - 1].d == x.d && t[j - 1].i > x.i))) {
        t[j] = t[j - 1];
        j--;
      }
      t[j] = x;
    }
    b->tmp = e;
    b->e = t;
  } else {
    knn_insertion_sort(e, n);
  }
  b->count = keep < k ? keep : k;
  return b->count == k ? b->e[k - 1].d : NAN;
}

/* ------------------------------------------------------------------------ */
/* Queries                                                                    */
/* ------------------------------------------------------------------------ */

typedef struct knn_search {
  const double *c[3]; /* the index's coordinate arrays */
  const uint32_t *ids;
  const knn_node *nodes;
  double q[3];
  double off[3];   /* per-dimension offset from q to the current node's box */
  size_t skip;     /* tree position to leave out (the query itself), or SIZE_MAX */
  knn_list list;   /* the candidates; with buf, only list.worst (the bound) */
  knn_buffer *buf; /* all-kNN: the candidates buffered (NULL: in list) */
} knn_search;

/* Offers the points [begin, end) of a leaf to the list. The distances of a
 * block are computed KNN_LANES at a time (GCC vector types: SSE2 pairs or
 * AVX2), lane by lane the same operations in the same order as knn_dist2, so
 * the same bits; the lanes are then tested against the bound of the block's
 * start into a bit mask, and only the points left in it are looked at one by
 * one: about half the points scanned in an all-kNN are rejected, and
 * rejecting them in lanes saves the mispredicted branches of a point-by-point
 * test. A point kept by the mask is tested again against the current bound
 * (it may have tightened since), so the list sees exactly the candidates the
 * point-by-point loop gave it, in the same order. */
static inline void knn_scan_leaf(knn_search *s, uint32_t begin, uint32_t end) {
#ifdef KNN_HAVE_V4D
  const knn_v4d qx = {s->q[0], s->q[0], s->q[0], s->q[0]};
  const knn_v4d qy = {s->q[1], s->q[1], s->q[1], s->q[1]};
  const knn_v4d qz = {s->q[2], s->q[2], s->q[2], s->q[2]};
  for (uint32_t b = begin; b < end; b += KNN_BLOCK) {
    const uint32_t cnt = end - b < KNN_BLOCK ? end - b : KNN_BLOCK;
    knn_buffer *buf = s->buf;
    if (buf && buf->count > buf->cap - KNN_BLOCK) s->list.worst = bsurf_knn_i_buffer_sort(buf);
    const double worst = s->list.worst;
    const knn_v4d w = {worst, worst, worst, worst};
    double dd[KNN_BLOCK];
    unsigned keep = 0;
    /* Lanes past `end` read the next leaf or the arrays' padding: masked. */
    for (uint32_t t = 0; t < cnt; t += KNN_LANES) {
      knn_v4d x, y, z, d;
      knn_v4l gt;
      memcpy(&x, s->c[0] + b + t, sizeof x);
      memcpy(&y, s->c[1] + b + t, sizeof y);
      memcpy(&z, s->c[2] + b + t, sizeof z);
      x = qx - x;
      y = qy - y;
      z = qz - z;
      d = x * x + y * y + z * z;
      memcpy(dd + t, &d, sizeof d);
      gt = d > w; /* -1 where rejected; false for NaN (kept, like the scalar test) */
      keep |= (unsigned)((gt[0] + 1) | (gt[1] + 1) << 1 | (gt[2] + 1) << 2 | (gt[3] + 1) << 3) << t;
    }
    keep &= (1u << cnt) - 1u;
    if (s->skip - b < cnt) keep &= ~(1u << (s->skip - b));
    if (buf) {
      knn_entry *e = buf->e + buf->count;
      while (keep) {
        const unsigned t = (unsigned)__builtin_ctz(keep);
        keep &= keep - 1u;
        e->d = dd[t];
        e->i = s->ids[b + t];
        e->pos = b + t;
        e++;
      }
      buf->count = (int)(e - buf->e);
      continue;
    }
    while (keep) {
      const unsigned t = (unsigned)__builtin_ctz(keep);
      const double d = dd[t];
      keep &= keep - 1u;
      if (d > s->list.worst) continue;
      knn_list_insert(&s->list, d, s->ids[b + t], b + t);
    }
  }
#else
  for (uint32_t j = begin; j < end; j++) {
    const double d = knn_dist2_at(s->q, s->c, j);
    if (d > s->list.worst || j == s->skip) continue;
    if (s->buf) {
      knn_buffer *buf = s->buf;
      if (buf->count == buf->cap) {
        s->list.worst = bsurf_knn_i_buffer_sort(buf);
        if (d > s->list.worst) continue;
      }
      buf->e[buf->count].d = d;
      buf->e[buf->count].i = s->ids[j];
      buf->e[buf->count].pos = j;
      buf->count++;
    } else {
      knn_list_insert(&s->list, d, s->ids[j], j);
    }
  }
#endif
}

static void knn_visit(knn_search *s, uint32_t node) {
  const knn_node *nd = &s->nodes[node];
  if (nd->dim < 0) {
    knn_scan_leaf(s, nd->begin, nd->end);
    return;
  }
  {
    const int dim = nd->dim;
    const double q = s->q[dim];
    const double diff_lo = q - nd->lo; /* >= 0 when q is right of the left box */
    const double diff_hi = q - nd->hi; /* <= 0 when q is left of the right box */
    uint32_t near_child, far_child;
    double cut, saved, bound;
    /* Nearer child first. When the left child is chosen, q < nd->hi, so
     * |diff_hi| is the exact offset to the right box along dim; symmetrically
     * q >= nd->lo when the right one is chosen. NaN sends us right with a NaN
     * bound, which never prunes. */
    if (diff_lo + diff_hi < 0) {
      near_child = node + 1;
      far_child = nd->right;
      cut = diff_hi;
    } else {
      near_child = nd->right;
      far_child = node + 1;
      cut = diff_lo;
    }
    knn_visit(s, near_child);
    saved = s->off[dim];
    s->off[dim] = cut;
    bound = knn_box_dist2(s->off);
    /* Visit on equality: the box may hold an equidistant point with a smaller
     * index. */
    if (!(bound > s->list.worst)) knn_visit(s, far_child);
    s->off[dim] = saved;
  }
}

bsurf_status bsurf_knn_query(const bsurf_knn_index *index, const double query[3], int k,
                             uint32_t *idx, double *dist2) {
  knn_entry buf[128];
  knn_search s;

  s.buf = NULL;
  BSURF_REQUIRE(index && query && idx, "index, query or idx is NULL");
  BSURF_REQUIRE(k >= 1 && (size_t)k <= index->n, "k = %d: must be in [1, %zu] (the indexed points)",
                k, index->n);

  for (int d = 0; d < 3; d++)
    s.c[d] = index->xyz[d];
  s.ids = index->ids;
  s.nodes = index->nodes;
  s.skip = SIZE_MAX;
  for (int d = 0; d < 3; d++) {
    const double q = query[d];
    s.q[d] = q;
    /* Offset to the root box (0 inside it, and for NaN). */
    s.off[d] = q < index->box_lo[d]   ? q - index->box_lo[d]
               : q > index->box_hi[d] ? q - index->box_hi[d]
                                      : 0.0;
  }
  s.list.k = k;
  if ((size_t)k <= sizeof buf / sizeof buf[0]) {
    s.list.e = buf;
  } else {
    s.list.e = bsurf_alloc_array((size_t)k, sizeof *s.list.e);
    if (!s.list.e) return BSURF_ERR_NOMEM;
  }
  knn_list_reset(&s.list);
  knn_visit(&s, 0);
  for (int c = 0; c < k; c++) {
    idx[c] = s.list.e[c].i;
    if (dist2) dist2[c] = s.list.e[c].d;
  }
  if (s.list.e != buf) free(s.list.e);
  return BSURF_OK;
}

/* The all-kNN's search for the point at tree position j (knn_all.c): its
 * k - 1 = buf->k nearest others into buf (the first buf->k entries of buf->e
 * in order, pos their tree positions), starting from the bound `warm` (an
 * upper bound on the (k - 1)-th distance, or NaN for none). */
void bsurf_knn_i_search(const bsurf_knn_index *ix, size_t j, knn_buffer *buf, double warm) {
  knn_search s;
  for (int d = 0; d < 3; d++)
    s.c[d] = ix->xyz[d];
  s.ids = ix->ids;
  s.nodes = ix->nodes;
  s.skip = j;
  for (int d = 0; d < 3; d++)
    s.q[d] = ix->xyz[d][j];
  s.off[0] = s.off[1] = s.off[2] = 0.0; /* the query is inside the root box */
  s.list.e = NULL;
  s.list.k = buf->k;
  knn_list_reset(&s.list);
  s.list.worst = warm;
  s.buf = buf;
  buf->count = 0;
  knn_visit(&s, 0);
  bsurf_knn_i_buffer_sort(buf);
}

/* ------------------------------------------------------------------------ */
/* Brute force (the reference of the differential tests)                     */
/* ------------------------------------------------------------------------ */

bsurf_status bsurf_knn_all_brute(const double *xyz, size_t point_count, int k, uint32_t *idx,
                                 double *dist2) {
  knn_list l;
  const int m = k - 1;

  if (point_count == 0)
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS, "bsurf_knn_all_brute: no points");
  BSURF_REQUIRE(xyz && idx, "xyz or idx is NULL");
  BSURF_REQUIRE(point_count <= UINT32_MAX, "point_count = %zu: at most 2^32 - 1 points",
                point_count);
  BSURF_REQUIRE(k >= 1 && (size_t)k <= point_count, "k = %d: must be in [1, %zu] (the points)", k,
                point_count);

  l.k = m;
  l.e = bsurf_alloc_array(m > 0 ? (size_t)m : 1, sizeof *l.e);
  if (!l.e) return BSURF_ERR_NOMEM;
  for (size_t i = 0; i < point_count; i++) {
    const size_t row = i * (size_t)k;
    knn_list_reset(&l);
    if (m > 0)
      for (size_t j = 0; j < point_count; j++) {
        double d;
        if (j == i) continue;
        d = knn_dist2(xyz + 3 * i, xyz + 3 * j);
        if (d > l.worst) continue;
        knn_list_insert(&l, d, (uint32_t)j, (uint32_t)j);
      }
    idx[row] = (uint32_t)i;
    if (dist2) dist2[row] = 0.0;
    for (int c = 0; c < m; c++) {
      idx[row + 1 + (size_t)c] = l.e[c].i;
      if (dist2) dist2[row + 1 + (size_t)c] = l.e[c].d;
    }
  }
  free(l.e);
  return BSURF_OK;
}
