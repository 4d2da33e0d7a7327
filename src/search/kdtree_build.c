/* kdtree_build.c -- building the k-d tree of kdtree.c (the design, the
 * memory and the cost are described at the top of that file): the points
 * copied into tree order, split at the median of the widest dimension by an
 * in-place selection, nodes in preorder. Split from kdtree.c (issue 19). */
#include "search/kdtree.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Strict weak order of coordinates used by the selection: numbers by value,
 * NaN after all numbers (all NaN equivalent). Keeps the selection well-defined
 * (and in bounds) with NaN input. */
static inline int coord_less(double a, double b) {
  return a < b || (isnan(b) && !isnan(a));
}

static inline void swap_points(double *const c[3], uint32_t *ids, size_t a, size_t b) {
  for (int d = 0; d < 3; d++) {
    const double t = c[d][a];
    c[d][a] = c[d][b];
    c[d][b] = t;
  }
  {
    const uint32_t ti = ids[a];
    ids[a] = ids[b];
    ids[b] = ti;
  }
}

/* Rearranges points [lo, hi] (inclusive) so that position nth holds the point
 * that would be there if they were sorted along `dim`, with no larger one
 * before it and no smaller one after (nth_element). Wirth's variant of Hoare's
 * selection; the scans stop on equal keys, which keeps the partitions balanced
 * on grids with many equal coordinates. Deterministic. With `finite` (no
 * NaN among the coordinates) the order is the plain <, which coord_less is
 * then: the same swaps, without the NaN tests. */
#define LESS(a, b) (finite ? (a) < (b) : coord_less(a, b))
static inline void select_nth_order(double *const c[3], uint32_t *ids, int64_t lo, int64_t hi,
                                    int64_t nth, int dim, int finite) {
  const double *key = c[dim];
  while (lo < hi) {
    const int64_t mid = lo + (hi - lo) / 2;
    /* Median of three into position nth (the pivot). */
    if (LESS(key[mid], key[lo])) swap_points(c, ids, (size_t)mid, (size_t)lo);
    if (LESS(key[hi], key[lo])) swap_points(c, ids, (size_t)hi, (size_t)lo);
    if (LESS(key[hi], key[mid])) swap_points(c, ids, (size_t)hi, (size_t)mid);
    if (mid != nth) swap_points(c, ids, (size_t)mid, (size_t)nth);
    {
      const double x = key[nth];
      int64_t i = lo, j = hi;
      do {
        while (LESS(key[i], x))
          i++;
        while (LESS(x, key[j]))
          j--;
        if (i <= j) {
          if (i != j) swap_points(c, ids, (size_t)i, (size_t)j);
          i++;
          j--;
        }
      } while (i <= j);
      /* Now [lo, j] <= x <= [i, hi] and j < i. */
      if (j < nth) lo = i;
      if (nth < i) hi = j;
    }
  }
}

#undef LESS

static void select_nth(double *const c[3], uint32_t *ids, int64_t lo, int64_t hi, int64_t nth,
                       int dim, int finite) {
  if (finite)
    select_nth_order(c, ids, lo, hi, nth, dim, 1);
  else
    select_nth_order(c, ids, lo, hi, nth, dim, 0);
}

/* The number of nodes of the tree of n points when no node stops early
 * because its points coincide (an upper bound otherwise): nodes(n) = 1 for
 * n <= KNN_LEAF_MAX, else 1 + nodes(floor(n / 2)) + nodes(ceil(n / 2)).
 * The halves of n and n + 1 are m and m + 1 (m = floor(n / 2)), so the pair
 * (nodes(n), nodes(n + 1)) follows from the pair of m: O(log n) steps. */
static void count_nodes_pair(size_t n, size_t *a, size_t *b) {
  if (n + 1 <= KNN_LEAF_MAX) {
    *a = *b = 1;
    return;
  }
  size_t m0, m1;
  count_nodes_pair(n / 2, &m0, &m1); /* nodes(m), nodes(m + 1) */
  if (n % 2 == 0) {
    *a = n <= KNN_LEAF_MAX ? 1 : 1 + 2 * m0;
    *b = 1 + m0 + m1;
  } else {
    *a = n <= KNN_LEAF_MAX ? 1 : 1 + m0 + m1;
    *b = 1 + 2 * m1;
  }
}

static size_t count_nodes(size_t n) {
  size_t a, b;
  count_nodes_pair(n, &a, &b);
  return a;
}

/* Subtrees of at least this many points are built as OpenMP tasks. */
#define BUILD_TASK_MIN 32768

typedef struct knn_builder {
  int finite; /* no NaN coordinate */
  double *c[3];
  uint32_t *ids;
  knn_node *nodes;
} knn_builder;

/* The node `id` over the points [begin, end) and its subtree, in preorder:
 * the left child is id + 1, the right one id + 1 + count_nodes(left's
 * points), so that the two subtrees can be built at once (as tasks) into
 * places fixed in advance. Where coincident points stop a split, the
 * places the full subtree would have taken stay unused (never visited). The
 * tree is the same for any thread count. */
static void build_node(knn_builder *b, size_t begin, size_t end, uint32_t id) {
  knn_node *nd = &b->nodes[id];
  double lo[3] = {INFINITY, INFINITY, INFINITY};
  double hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  double best = 0.0;
  int dim = -1;
  size_t mid, j;

  nd->begin = (uint32_t)begin;
  nd->end = (uint32_t)end;
  nd->right = 0;
  nd->dim = -1;
  nd->lo = nd->hi = 0.0;
  if (end - begin <= KNN_LEAF_MAX) return;

  /* Widest dimension; NaN coordinates are ignored (comparisons are false). */
  for (j = begin; j < end; j++)
    for (int d = 0; d < 3; d++) {
      const double v = b->c[d][j];
      if (v < lo[d]) lo[d] = v;
      if (v > hi[d]) hi[d] = v;
    }
  for (int d = 0; d < 3; d++) {
    const double extent = hi[d] - lo[d]; /* NaN for inf - inf: never chosen */
    if (extent > best) {
      best = extent;
      dim = d;
    }
  }
  if (dim < 0) return; /* all points coincide (or have no finite extent) */

  mid = begin + (end - begin) / 2;
  select_nth(b->c, b->ids, (int64_t)begin, (int64_t)end - 1, (int64_t)mid, dim, b->finite);
  {
    double lmax = -INFINITY, rmin = INFINITY;
    const double *key = b->c[dim];
    for (j = begin; j < mid; j++)
      if (key[j] > lmax) lmax = key[j];
    for (j = mid; j < end; j++)
      if (key[j] < rmin) rmin = key[j];
    nd->lo = lmax;
    nd->hi = rmin;
  }
  nd->dim = dim;
  const uint32_t right = id + 1 + (uint32_t)count_nodes(mid - begin);
  nd->right = right;
  if (end - begin >= BUILD_TASK_MIN) {
#ifdef _OPENMP
#pragma omp task default(none) firstprivate(b, begin, mid, id)
#endif
    build_node(b, begin, mid, id + 1);
    build_node(b, mid, end, right);
  } else {
    build_node(b, begin, mid, id + 1);
    build_node(b, mid, end, right);
  }
}

size_t bsurf_knn_point_count(const bsurf_knn_index *index) {
  return index ? index->n : 0;
}

/* bsurf_knn_build(_threads); messages name `who`. */
static bsurf_status knn_build(const char *who, bsurf_knn_index **index, const double *xyz,
                              size_t point_count, int threads) {
  bsurf_knn_index *ix;
  knn_builder b;
  size_t max_nodes;

  BSURF_REQUIRE_IN(who, index, "index is NULL");
  *index = NULL;
  if (point_count == 0) return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS, "%s: no points", who);
  BSURF_REQUIRE_IN(who, xyz, "xyz is NULL");
  BSURF_REQUIRE_IN(who, point_count <= UINT32_MAX, "point_count = %zu: at most 2^32 - 1 points",
                   point_count);

  ix = calloc(1, sizeof *ix);
  if (!ix) return BSURF_ERR_NOMEM;
  max_nodes = count_nodes(point_count);
  ix->n = point_count;
  ix->xyz[0] = bsurf_alloc_array(point_count + KNN_PAD, 3 * sizeof(double));
  ix->ids = bsurf_alloc_array(point_count, sizeof(uint32_t));
  ix->nodes = bsurf_alloc_array(max_nodes, sizeof(knn_node));
  if (!ix->xyz[0] || !ix->ids || !ix->nodes) {
    bsurf_knn_free(ix);
    return BSURF_ERR_NOMEM;
  }
  ix->xyz[1] = ix->xyz[0] + (point_count + KNN_PAD);
  ix->xyz[2] = ix->xyz[1] + (point_count + KNN_PAD);
  /* the padding zeroed, the points written below (a calloc's memset of the
   * whole was a second pass over 24 MB at 1M points) */
  for (int d = 0; d < 3; d++)
    memset(ix->xyz[d] + point_count, 0, KNN_PAD * sizeof(double));
  int nt = bsurf_threads_resolve(threads);
  if (nt < 1 || point_count < 2 * BUILD_TASK_MIN) nt = 1;
  const int64_t np = (int64_t)point_count;
#ifdef _OPENMP
#pragma omp parallel for num_threads(nt) schedule(static)
#endif
  for (int64_t i = 0; i < np; i++) {
    for (int d = 0; d < 3; d++)
      ix->xyz[d][i] = xyz[3 * i + d];
    ix->ids[i] = (uint32_t)i;
  }

  for (int d = 0; d < 3; d++) {
    ix->box_lo[d] = INFINITY;
    ix->box_hi[d] = -INFINITY;
  }
  int finite = 1;
  for (size_t i = 0; i < point_count; i++)
    for (int d = 0; d < 3; d++) {
      const double v = xyz[3 * i + d];
      if (v < ix->box_lo[d]) ix->box_lo[d] = v;
      if (v > ix->box_hi[d]) ix->box_hi[d] = v;
      finite &= isfinite(v) != 0;
    }
  ix->finite = finite;

  for (int d = 0; d < 3; d++)
    b.c[d] = ix->xyz[d];
  b.ids = ix->ids;
  b.nodes = ix->nodes;
  b.finite = finite;
  /* the subtrees of the top levels as tasks (the tree does not depend on
   * nt: build_node's places are fixed in advance) */
#ifdef _OPENMP
#pragma omp parallel num_threads(nt)
#pragma omp single
#endif
  build_node(&b, 0, point_count, 0);
  ix->node_count = max_nodes;
  *index = ix;
  return BSURF_OK;
}

bsurf_status bsurf_knn_build(bsurf_knn_index **index, const double *xyz, size_t point_count) {
  return knn_build("bsurf_knn_build", index, xyz, point_count, 1);
}

bsurf_status bsurf_knn_build_threads(bsurf_knn_index **index, const double *xyz, size_t point_count,
                                     int threads) {
  return knn_build("bsurf_knn_build_threads", index, xyz, point_count, threads);
}

const uint32_t *bsurf_knn_tree_ids(const bsurf_knn_index *index) {
  return index->ids;
}

void bsurf_knn_free(bsurf_knn_index *index) {
  if (!index) return;
  free(index->xyz[0]);
  free(index->ids);
  free(index->nodes);
  free(index);
}
