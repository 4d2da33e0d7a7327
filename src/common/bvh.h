/* A bounding-volume hierarchy over primitives known by their boxes and
 * centres, with an exact nearest-primitive query. One copy serves the mesh
 * distance of the position error (triangles, src/eval/surface_distance.c)
 * and the distance to the nearest sharp edge of mesh sampling (segments,
 * src/synth/mesh_sample.c).
 *
 * The tree: axis-aligned boxes, median split of the centres along the longest
 * axis of their extent (ties by primitive index, so the tree is a function of
 * the primitives alone, not of their order in memory), leaves of at most
 * BSURF_BVH_LEAF primitives stored contiguously (`order`).
 *
 * The query descends nearest-box-first and skips a box only when its squared
 * distance exceeds the best squared distance found so far by more than a
 * bound on the rounding error of the caller's distance function (1e-9 of the
 * best squared distance plus the squared extent of the largest primitive: the
 * distance functions work on differences no larger than those, so their
 * rounding is a few ulps of that sum, five orders of magnitude below). Equal
 * distances keep the lowest primitive index. So the result is the minimum of
 * the same function over all primitives, bit for bit, whatever order the
 * search takes; the tests compare both users with brute-force loops. */
#ifndef BSURF_BVH_H
#define BSURF_BVH_H

#include "bootsurf.h"

#include <stddef.h>

#define BSURF_BVH_LEAF 4

typedef struct bsurf_bvh_node {
  double lo[3], hi[3];
  size_t first, count; /* leaf: slots [first, first + count) of order */
  size_t left, right;  /* internal (count == 0): children */
} bsurf_bvh_node;

typedef struct bsurf_bvh {
  size_t count;          /* primitives */
  size_t *order;         /* slot -> primitive index, leaves contiguous */
  bsurf_bvh_node *nodes; /* nodes[0] is the root */
  size_t node_count;
  double extent2; /* the largest primitive's box diagonal, squared */
} bsurf_bvh;

/* Builds the tree of `count` >= 1 primitives: box is count x 6 (lo x y z,
 * hi x y z), centre count x 3. Neither is kept. BSURF_ERR_NOMEM leaves `t`
 * empty (bsurf_bvh_free is safe on it). */
bsurf_status bsurf_bvh_build(bsurf_bvh *t, const double *box, const double *center, size_t count);
void bsurf_bvh_free(bsurf_bvh *t);

/* The squared distance from p to the primitive in `slot` (order[slot]). */
typedef double (*bsurf_bvh_dist2_fn)(const void *ctx, size_t slot, const double p[3]);

/* The smallest dist2 over all primitives, and its slot (ties: the lowest
 * primitive index). p must be finite. */
double bsurf_bvh_nearest(const bsurf_bvh *t, const double p[3], bsurf_bvh_dist2_fn dist2,
                         const void *ctx, size_t *slot);

#endif
