/* kdtree.h -- the k-d tree's layout, shared by its build (kdtree_build.c)
 * and its queries (kdtree.c). Private to src/search. The design is described
 * at the top of kdtree.c. */
#ifndef BSURF_SEARCH_KDTREE_H
#define BSURF_SEARCH_KDTREE_H

#include "search/search.h"

#include <stddef.h>
#include <stdint.h>

/* A node with more points than this is split: leaves hold 8..16 points (more
 * only when they all coincide). */
#define KNN_LEAF_MAX 16

typedef struct knn_node {
  double lo;      /* inner: largest coordinate of the left child along dim */
  double hi;      /* inner: smallest coordinate of the right child along dim */
  uint32_t begin; /* points [begin, end) in tree order */
  uint32_t end;
  uint32_t right; /* inner: the right child (the left child is this + 1) */
  int32_t dim;    /* inner: split dimension 0..2; leaf: -1 */
} knn_node;

/* The coordinates are stored as three arrays (x, y, z in tree order, each
 * padded with KNN_PAD zeros): a leaf's x, y and z are each contiguous, so a
 * leaf's distances are computed KNN_LANES at a time (knn_scan_leaf). */
#define KNN_LANES 4
#define KNN_PAD (KNN_LANES - 1)

struct bsurf_knn_index {
  size_t n;
  double *xyz[3]; /* x, y, z: n (+ KNN_PAD) each, tree order; one block at xyz[0] */
  uint32_t *ids;  /* n: original index of each tree position */
  knn_node *nodes;
  size_t node_count;
  double box_lo[3], box_hi[3]; /* bounding box of the non-NaN coordinates */
};

#endif
