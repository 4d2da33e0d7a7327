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
  int finite;                  /* 1 when every coordinate is finite (knn_all.c's batches) */
};

/* knn_dist2 (kdtree.c) to the point at tree position j of the coordinate arrays c. */
static inline double knn_dist2_at(const double *q, const double *const c[3], size_t j) {
  const double dx = q[0] - c[0][j];
  const double dy = q[1] - c[1][j];
  const double dz = q[2] - c[2][j];
  return dx * dx + dy * dy + dz * dz;
}

/* The k best candidates so far, sorted by knn_before. `worst` is the k-th
 * distance once the list is full and NaN before, so that `d > worst` (cheap
 * rejection) and `bound > worst` (pruning) are both false until then. */
typedef struct knn_entry {
  double d;
  uint32_t i;
  uint32_t pos; /* the point's position in the tree's arrays (a warm start's candidates) */
} knn_entry;

/* The all-kNN's candidates (buffered selection): every point within the
 * bound is appended, unsorted, and the buffer is sorted only when it fills
 * and at the end of the query, where the list above shifts its tail at every
 * insertion (at 1M points, K = 50: 72 insertions and about 800 shifts per
 * query, each insertion ending in a mispredicted branch). The bound is then
 * looser between sorts (the warm start's, or the k-th distance of the last
 * sort), so more points are appended than the list would take, but an append
 * costs a few stores. */
/* Buckets per entry in knn_buffer_sort (1, 2 and 4 measured alike). */
#define KNN_SPREAD 2

typedef struct knn_buffer {
  knn_entry *e;   /* cap entries; after knn_buffer_sort, the first min(count, k) in order */
  knn_entry *tmp; /* cap: the bucket pass's output */
  uint32_t *hist; /* KNN_SPREAD * cap + 1 bucket counts */
  uint32_t *key;  /* cap: each entry's bucket */
  int cap;
  int k;
  int count;
  int ranged;    /* 1: lo and hi bound the entries' distances (none NaN), set by the scan */
  double lo, hi; /* (the sort then skips its own pass over them) */
} knn_buffer;

#if defined(__GNUC__)
typedef double knn_v4d __attribute__((vector_size(KNN_LANES * sizeof(double))));
typedef long long knn_v4l __attribute__((vector_size(KNN_LANES * sizeof(double))));
#define KNN_HAVE_V4D 1
#endif

/* Points per block of knn_scan_leaf: a leaf holds at most KNN_LEAF_MAX
 * points unless they all coincide (then it takes several blocks). */
#define KNN_BLOCK 16

/* kdtree.c, for the all-kNN (knn_all.c). bsurf_knn_i_buffer_sort: sorts the
 * buffer by (distance, index) and keeps its first k entries; returns the
 * k-th distance then, NaN when fewer are left. */
double bsurf_knn_i_buffer_sort(knn_buffer *b);
void bsurf_knn_i_search(const bsurf_knn_index *ix, size_t j, knn_buffer *buf, double warm);

#endif
