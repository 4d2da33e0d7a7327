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
 * on grids with many equal coordinates. Deterministic. */
static void select_nth(double *const c[3], uint32_t *ids, int64_t lo, int64_t hi, int64_t nth,
                       int dim) {
  const double *key = c[dim];
  while (lo < hi) {
    const int64_t mid = lo + (hi - lo) / 2;
    /* Median of three into position nth (the pivot). */
    if (coord_less(key[mid], key[lo])) swap_points(c, ids, (size_t)mid, (size_t)lo);
    if (coord_less(key[hi], key[lo])) swap_points(c, ids, (size_t)hi, (size_t)lo);
    if (coord_less(key[hi], key[mid])) swap_points(c, ids, (size_t)hi, (size_t)mid);
    if (mid != nth) swap_points(c, ids, (size_t)mid, (size_t)nth);
    {
      const double x = key[nth];
      int64_t i = lo, j = hi;
      do {
        while (coord_less(key[i], x))
          i++;
        while (coord_less(x, key[j]))
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

/* Upper bound of the number of nodes for n points (exact when no node stops
 * early because its points coincide). */
static size_t count_nodes(size_t n) {
  if (n <= KNN_LEAF_MAX) return 1;
  return 1 + count_nodes(n / 2) + count_nodes(n - n / 2);
}

typedef struct knn_builder {
  double *c[3];
  uint32_t *ids;
  knn_node *nodes;
  size_t count;
} knn_builder;

static uint32_t build_node(knn_builder *b, size_t begin, size_t end) {
  const uint32_t id = (uint32_t)b->count++;
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
  if (end - begin <= KNN_LEAF_MAX) return id;

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
  if (dim < 0) return id; /* all points coincide (or have no finite extent) */

  mid = begin + (end - begin) / 2;
  select_nth(b->c, b->ids, (int64_t)begin, (int64_t)end - 1, (int64_t)mid, dim);
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
  build_node(b, begin, mid); /* = id + 1 */
  /* `nd` stays valid: the node array is allocated once, never moved. */
  nd->right = build_node(b, mid, end);
  return id;
}

size_t bsurf_knn_point_count(const bsurf_knn_index *index) {
  return index ? index->n : 0;
}

bsurf_status bsurf_knn_build(bsurf_knn_index **index, const double *xyz, size_t point_count) {
  bsurf_knn_index *ix;
  knn_builder b;
  size_t max_nodes;

  BSURF_REQUIRE(index, "index is NULL");
  *index = NULL;
  if (point_count == 0)
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS, "bsurf_knn_build: no points");
  BSURF_REQUIRE(xyz, "xyz is NULL");
  BSURF_REQUIRE(point_count <= UINT32_MAX, "point_count = %zu: at most 2^32 - 1 points",
                point_count);

  ix = calloc(1, sizeof *ix);
  if (!ix) return BSURF_ERR_NOMEM;
  max_nodes = count_nodes(point_count);
  ix->n = point_count;
  ix->xyz[0] = bsurf_calloc_array(point_count + KNN_PAD, 3 * sizeof(double));
  ix->ids = bsurf_alloc_array(point_count, sizeof(uint32_t));
  ix->nodes = bsurf_alloc_array(max_nodes, sizeof(knn_node));
  if (!ix->xyz[0] || !ix->ids || !ix->nodes) {
    bsurf_knn_free(ix);
    return BSURF_ERR_NOMEM;
  }
  ix->xyz[1] = ix->xyz[0] + (point_count + KNN_PAD);
  ix->xyz[2] = ix->xyz[1] + (point_count + KNN_PAD);
  for (size_t i = 0; i < point_count; i++) {
    for (int d = 0; d < 3; d++)
      ix->xyz[d][i] = xyz[3 * i + d];
    ix->ids[i] = (uint32_t)i;
  }

  for (int d = 0; d < 3; d++) {
    ix->box_lo[d] = INFINITY;
    ix->box_hi[d] = -INFINITY;
  }
  for (size_t i = 0; i < point_count; i++)
    for (int d = 0; d < 3; d++) {
      const double v = xyz[3 * i + d];
      if (v < ix->box_lo[d]) ix->box_lo[d] = v;
      if (v > ix->box_hi[d]) ix->box_hi[d] = v;
    }

  for (int d = 0; d < 3; d++)
    b.c[d] = ix->xyz[d];
  b.ids = ix->ids;
  b.nodes = ix->nodes;
  b.count = 0;
  build_node(&b, 0, point_count);
  ix->node_count = b.count;
  if (b.count < max_nodes) { /* coincident points stopped some splits */
    knn_node *shrunk = realloc(ix->nodes, b.count * sizeof(knn_node));
    if (shrunk) ix->nodes = shrunk;
  }
  *index = ix;
  return BSURF_OK;
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
